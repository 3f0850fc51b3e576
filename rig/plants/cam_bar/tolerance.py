"""Precision of the slider stroke: full deviated chain and linear sensitivities (MODELS §3.5).

The cam is made for the nominal chain: its pitch radius r(φ) = |B_R(ψ(s(φ))) − A0| is fixed. A machine with
parameters q = (x_A0, y_A0, l3, r, s0, L3, l4, e_sk) + Δq finds its follower angle ψ' from the cam side
``G = 2x_A0 l3 cosψ + 2y_A0 l3 sinψ + r² − x_A0² − y_A0² − l3² = 0`` (root nearest the nominal ψ) and its
slider stroke s' from the bar side ``s² + D_s s + E_s = 0`` (root with the rod on the nominal side);
Δs(φ) = s' − s. The linear method uses the corrected sensitivities of §3.5. All lengths in m.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import degrees
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import numpy as np

from rig.plants.cam_bar.chain import SingularPositionError
from rig.scene import Field, SceneError, load_scene

if TYPE_CHECKING:
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism

PARAMS = ("x_A0", "y_A0", "l3", "r", "s0", "L3", "l4", "e_sk")
CAM_SIDE = ("x_A0", "y_A0", "l3", "r")
DEFAULT_TOLERANCES = Path(__file__).resolve().parents[3] / "data" / "cam_bar" / "tolerances.toml"
SINGULAR_TOL = 1e-9  # |∂G/∂ψ| / (2 l3 |A0|) below this: the cam side cannot fix ψ


@dataclass(frozen=True)
class ToleranceSet:
    """Symmetric tolerances ±T_k (m) of the chain parameters (T = 3σ) and the rate λ (1/m) of the exponential
    clearance law (``None``: no clearance in the Monte-Carlo run)."""

    T: Mapping[str, float]
    clearance_lambda: float | None = None

    def __post_init__(self) -> None:
        missing = [k for k in PARAMS if k not in self.T]
        if missing:
            raise ValueError(f"tolerance set lacks {', '.join(missing)}")
        bad = [k for k, v in self.T.items() if k not in PARAMS or not v >= 0.0]
        if bad:
            raise ValueError(f"tolerance set: unknown parameter or negative tolerance for {', '.join(bad)}")
        if self.clearance_lambda is not None and not self.clearance_lambda > 0.0:
            raise ValueError(f"clearance rate λ must be positive, got {self.clearance_lambda!r} 1/m")

    def scaled(self, factor: float) -> "ToleranceSet":
        """All tolerances times ``factor`` (clearance law unchanged)."""
        return ToleranceSet({k: v * factor for k, v in self.T.items()}, self.clearance_lambda)


TOL_SCHEMA = {k: Field("m", doc=f"±tolerance of {k} (3σ)") for k in PARAMS}
CLEARANCE_SCHEMA = {"lambda": Field("1/m", None, "rate of the exponential clearance law f(x) = λ·exp(−λx)")}


def load_tolerances(path: str | Path = DEFAULT_TOLERANCES) -> ToleranceSet:
    """Read ``[tolerances]`` (quantities with units) and optional ``[clearance] lambda`` from a TOML file."""
    doc = load_scene(path)
    for name in doc.data:
        if name not in ("tolerances", "clearance"):
            raise SceneError(f"{path}: unknown section [{name}] (known: [tolerances], [clearance])")
    tol = doc.read("tolerances", TOL_SCHEMA)
    lam = doc.read("clearance", CLEARANCE_SCHEMA, required=False)["lambda"]
    try:
        return ToleranceSet(tol, lam)
    except ValueError as exc:
        raise SceneError(f"{path}: {exc}") from None


def _wrap(a: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * a))


@dataclass(frozen=True)
class CamChain:
    """The nominal chain at cam angles ``phi`` (rad): stroke ``s``, follower angle ``psi``, pitch radius ``r``,
    the parameters ``q`` (m), the cam-side root (``cam_branch`` ±1 per angle) and the rod side (±1)."""

    phi: np.ndarray
    s: np.ndarray
    psi: np.ndarray
    r: np.ndarray
    q: Mapping[str, float]
    cam_branch: np.ndarray
    rod_side: float

    @classmethod
    def from_mechanism(cls, mech: "PinInsertionMechanism", phi: np.ndarray,
                       known: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> "CamChain":
        """The nominal chain of ``mech`` at cam angles ``phi`` (rad); ``known`` = its level-0 (s, ψ, r) there when
        the caller has them already."""
        phi = np.asarray(phi, dtype=float)
        if known is None:
            s = mech.program.evaluate(phi).s
            pos = mech.kinematics(s)
            psi, r = pos.psi, pos.r
        else:
            s, psi, r = known
        q = {"x_A0": mech.x_A0, "y_A0": mech.y_A0, "l3": mech.l3, "s0": mech.s0, "L3": mech.L3, "l4": mech.l4,
             "e_sk": mech.e_sk}
        side = np.sign(_wrap(psi - np.arctan2(mech.y_A0, mech.x_A0)))
        chain = cls(phi, s, psi, r, q, np.where(side == 0.0, 1.0, side), mech.chain.rod_side)
        chain._check(chain.psi, chain.q)
        return chain

    def _where(self, i: int) -> str:
        return f"cam angle φ = {degrees(float(self.phi.flat[i % self.phi.size])):.4g}°"

    def _check(self, psi: np.ndarray, q: Mapping[str, np.ndarray | float]) -> None:
        g_psi = -q["x_A0"] * np.sin(psi) + q["y_A0"] * np.cos(psi)
        bad = np.abs(g_psi) < SINGULAR_TOL * np.hypot(q["x_A0"], q["y_A0"])
        if np.any(bad):
            raise SingularPositionError(f"cam side singular (∂G/∂ψ = 0: roller centre, pivot and cam centre "
                                        f"collinear) at {self._where(int(np.argmax(bad)))}")

    def stroke(self, dq: Mapping[str, np.ndarray | float]) -> np.ndarray:
        """Slider stroke s' (m) of the deviated chain, shape (samples, angles): ``dq`` maps parameter names to
        deviations (m), scalars or 1-D arrays over samples; missing names are zero."""
        return self.evaluate(self.deviation_rows(dq), np.zeros_like(self.s))

    def deviation(self, dq: Mapping[str, np.ndarray | float]) -> np.ndarray:
        """Δs(φ) = s' − s (m), shape (samples, angles)."""
        return self.evaluate(self.deviation_rows(dq), self.s)

    @staticmethod
    def deviation_rows(dq: Mapping[str, np.ndarray | float]) -> np.ndarray:
        """``dq`` (names → deviations, m) as rows in the order of ``PARAMS``, shape (8, samples)."""
        unknown = set(dq) - set(PARAMS)
        if unknown:
            raise ValueError(f"unknown chain parameter(s) {', '.join(sorted(unknown))} (known: {', '.join(PARAMS)})")
        cols = [np.atleast_1d(np.asarray(dq.get(k, 0.0), dtype=float)) for k in PARAMS]
        return np.stack(np.broadcast_arrays(*cols))

    def evaluate(self, rows: np.ndarray, offset: np.ndarray) -> np.ndarray:
        """s' − ``offset`` (m) per machine and angle for deviation rows as :meth:`deviation_rows` gives them
        (compiled: :func:`rig.plants.cam_bar.tolerance_kernel.strokes`)."""
        from rig.plants.cam_bar import tolerance_kernel as kernel
        q = np.array([self.q.get(k, 0.0) for k in PARAMS])
        out = np.empty((rows.shape[1], self.phi.size))
        code, _, j = kernel.strokes(np.ascontiguousarray(rows, dtype=float), q, self.r, self.cam_branch,
                                    float(self.rod_side), np.ascontiguousarray(offset, dtype=float), out)
        if code == kernel.CAM_UNREACHABLE:
            raise SingularPositionError(f"deviated cam side cannot be assembled (pitch radius out of reach of the "
                                        f"roller arm) at {self._where(j)}")
        if code == kernel.ROD_UNREACHABLE:
            raise SingularPositionError(f"deviated rod does not reach the slider line at {self._where(j)}")
        return out

    def buildable(self, rows: np.ndarray) -> np.ndarray:
        """Per machine (columns of deviation ``rows``): whether its deviated chain can be assembled at every angle."""
        from rig.plants.cam_bar import tolerance_kernel as kernel
        q = np.array([self.q.get(k, 0.0) for k in PARAMS])
        rows = np.ascontiguousarray(rows, dtype=float)
        zero, out = np.zeros(self.phi.size), np.empty((1, self.phi.size))
        return np.array([kernel.strokes(np.ascontiguousarray(rows[:, i:i + 1]), q, self.r, self.cam_branch,
                                        float(self.rod_side), zero, out)[0] == kernel.OK for i in range(rows.shape[1])])

    def sensitivities(self) -> dict[str, np.ndarray]:
        """∂s/∂q_k (m/m) at each angle, corrected formulas of MODELS §3.5."""
        q, s, r = self.q, self.s, self.r
        cp, sp = np.cos(self.psi), np.sin(self.psi)
        x, y, l3, s0, L3, l4, e = (q[k] for k in ("x_A0", "y_A0", "l3", "s0", "L3", "l4", "e_sk"))
        ds_dpsi = L3 * ((s - s0) * sp + e * cp) / ((s - s0) + L3 * cp)
        g_psi = 2.0 * l3 * (-x * sp + y * cp)
        g_q = {"x_A0": 2.0 * (l3 * cp - x), "y_A0": 2.0 * (l3 * sp - y),
               "l3": 2.0 * (x * cp + y * sp - l3), "r": 2.0 * r}
        out = {k: ds_dpsi * (-g_q[k]) / g_psi for k in CAM_SIDE}
        d_s = 2.0 * L3 * cp - 2.0 * s0
        dd = {"s0": (-2.0, 2.0 * (s0 - L3 * cp)), "L3": (2.0 * cp, 2.0 * (L3 - e * sp - s0 * cp)),
              "l4": (0.0, -2.0 * l4), "e_sk": (0.0, 2.0 * (e - L3 * sp))}
        for k, (dd_k, de_k) in dd.items():
            out[k] = -(dd_k * s + de_k) / (2.0 * s + d_s)
        return {k: np.broadcast_to(out[k], s.shape).copy() for k in PARAMS}


@dataclass(frozen=True)
class LinearResult:
    """Linear tolerance analysis per cam angle (m): sensitivities, contributions ∂s/∂q_k·T_k, their signed sum
    (all parameters at +T), worst case Σ|·| and root sum of squares."""

    phi: np.ndarray
    sensitivity: dict[str, np.ndarray]
    contribution: dict[str, np.ndarray]
    signed: np.ndarray
    worst: np.ndarray
    rss: np.ndarray


def linear_analysis(chain: CamChain, tol: ToleranceSet) -> LinearResult:
    """Deterministic method: Δs = Σ ∂s/∂q_k·Δq_k with Δq_k = ±T_k."""
    sens = chain.sensitivities()
    contrib = {k: sens[k] * tol.T[k] for k in PARAMS}
    stack = np.stack([contrib[k] for k in PARAMS])
    return LinearResult(chain.phi, sens, contrib, stack.sum(axis=0), np.abs(stack).sum(axis=0),
                        np.sqrt((stack ** 2).sum(axis=0)))

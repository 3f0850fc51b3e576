"""Other clutch variants as static torque–angle characteristics (MODELS.md §4.2, §4.5).

Every variant is a :class:`StaticCharacteristic`: ``torque(phi, direction)`` on its engaged range
``[phi_min, apex]`` (rad → N·m), ``angle(torque, direction)`` its inverse on the rising branch,
``disengagement_angle`` / ``peak_torque`` (maximum of the loading branch) and ``period`` (lobe period,
rad). ``direction`` is +1 while the relative angle grows (loading: friction adds), −1 while it falls
(unloading: friction subtracts) and 0 for the frictionless elastic curve; variants without friction in
the source (rollers, rubber, tables) ignore it. :meth:`StaticCharacteristic.loop_torque` turns an angle
history into the torque of the loading/unloading hysteresis loop.
"""
from __future__ import annotations

import csv
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.optimize import minimize_scalar

from rig.plants.clutch.flat_tappet import FlatTappetClutch
from rig.plants.clutch.geometry import APEX, LOBE, GeometryError
from rig.scene import Field
from rig.units import UnitError, to_si

DATA_DIR = Path(__file__).resolve().parents[3] / "data" / "clutch"
_BISECTION_STEPS = 64
_PEAK_GRID = 2001


class StaticCharacteristic(ABC):
    """A clutch variant's static characteristic T(φ) on ``[phi_min, apex]`` (rad → N·m)."""

    phi_min: float = 0.0
    apex: float
    period: float
    has_friction: ClassVar[bool] = False

    @abstractmethod
    def _torque(self, phi: np.ndarray, direction: float) -> np.ndarray:
        """T(φ) for validated angles (N·m)."""

    def torque(self, phi: np.ndarray | float, direction: float = 0.0) -> np.ndarray:
        """Static torque (N·m) at relative angles φ (rad) inside the engaged range."""
        phi = np.asarray(phi, dtype=float)
        if direction not in (-1, 0, 1):
            raise ValueError(f"{self.name}: direction must be +1 (loading), -1 (unloading) or 0, got {direction!r}")
        bad = ~((phi >= self.phi_min - 1e-12) & (phi <= self.apex + 1e-12))
        if np.any(bad):
            worst = float(np.asarray(phi)[bad].flat[0])
            raise ValueError(f"{self.name}: relative angle {math.degrees(worst):.6g} deg is outside the engaged "
                             f"range [{math.degrees(self.phi_min):.6g}, {math.degrees(self.apex):.6g}] deg")
        return self._torque(np.clip(phi, self.phi_min, self.apex), direction)

    @property
    def name(self) -> str:
        return type(self).__name__

    def branch_peak(self, direction: float = 1.0) -> tuple[float, float]:
        """(angle rad, torque N·m) of the maximum of one branch on the engaged range."""
        key = float(direction) if self.has_friction else 0.0
        cache = self.__dict__.setdefault("_peaks", {})
        if key not in cache:
            grid = np.linspace(self.phi_min, self.apex, _PEAK_GRID)
            values = self._torque(grid, key)
            i = int(np.argmax(values))
            if i == grid.size - 1:
                cache[key] = (self.apex, float(values[i]))
            else:
                lo, hi = grid[max(i - 1, 0)], grid[i + 1]
                res = minimize_scalar(lambda p: -float(self._torque(np.array(p), key)), bounds=(lo, hi),
                                      method="bounded", options={"xatol": 1e-12})
                cache[key] = (float(res.x), float(-res.fun)) if -res.fun >= values[i] else (float(grid[i]),
                                                                                           float(values[i]))
        return cache[key]

    @property
    def disengagement_angle(self) -> float:
        """Angle (rad) of the maximum loading torque: beyond it the clutch slips to the next lobe."""
        return self.branch_peak(1.0)[0]

    @property
    def peak_torque(self) -> float:
        """Maximum loading torque (N·m) = disengagement torque."""
        return self.branch_peak(1.0)[1]

    def angle(self, torque: np.ndarray | float, direction: float = 0.0, clip_low: bool = False) -> np.ndarray:
        """Inverse of the rising branch: φ (rad) with T(φ, direction) = torque (N·m), by bisection.

        Torques above the branch peak raise ``ValueError`` (the clutch would disengage); torques below
        T(phi_min) raise too unless ``clip_low`` (then φ = phi_min: friction holds the clutch closed).
        """
        target = np.asarray(torque, dtype=float)
        phi_peak, t_peak = self.branch_peak(direction)
        t_low = float(self._torque(np.array(self.phi_min), direction if self.has_friction else 0.0))
        if np.any(~np.isfinite(target)) or np.any(target > t_peak + 1e-12 * abs(t_peak)):
            raise ValueError(f"{self.name}: torque {np.max(target):.6g} N*m exceeds the peak "
                             f"{t_peak:.6g} N*m of the branch (direction {direction:+g}); the clutch disengages")
        if not clip_low and np.any(target < t_low - 1e-12 * max(abs(t_low), 1.0)):
            raise ValueError(f"{self.name}: torque {np.min(target):.6g} N*m is below the start of the "
                             f"characteristic T({math.degrees(self.phi_min):.4g} deg) = {t_low:.6g} N*m")
        lo = np.full(target.shape, self.phi_min)
        hi = np.full(target.shape, phi_peak)
        for _ in range(_BISECTION_STEPS):
            mid = 0.5 * (lo + hi)
            above = self._torque(mid, direction) >= target
            hi = np.where(above, mid, hi)
            lo = np.where(above, lo, mid)
        return np.where(target <= t_low, self.phi_min, 0.5 * (lo + hi))

    def loop_torque(self, phi_history: np.ndarray) -> np.ndarray:
        """Torque (N·m) along an angle history (rad) under angle control, friction opposing the motion.

        The direction of each sample is the sign of the next angle step (the last sample keeps the
        previous one; pauses keep the last direction), so the torque jumps between the loading and
        the unloading branch where the motion reverses — the static hysteresis loop. Repeat the
        reversal angle in the history to get the vertical jump as its own path segment.
        """
        phi = np.asarray(phi_history, dtype=float)
        if phi.ndim != 1 or phi.size < 2:
            raise ValueError(f"{self.name}: angle history must be 1-D with at least 2 samples")
        step = np.sign(np.diff(phi))
        if not np.any(step):
            raise ValueError(f"{self.name}: angle history never moves; the friction direction is undefined")
        idx = np.where(step != 0, np.arange(step.size), -1)
        idx = np.maximum.accumulate(idx)
        first = int(np.flatnonzero(step)[0])
        direction = np.where(idx >= 0, step[np.maximum(idx, 0)], step[first])
        direction = np.append(direction, direction[-1])
        return np.where(direction > 0, self.torque(phi, 1.0), self.torque(phi, -1.0))


def _positive(owner: str, **values: float) -> None:
    for key, v in values.items():
        if not (math.isfinite(v) and v > 0):
            raise GeometryError(f"{owner}: {key} = {v!r} must be a positive finite number (SI)")


def _check_apex(owner: str, apex: float, limit: float) -> None:
    if not 0 < apex <= limit:
        raise GeometryError(f"{owner}: apex {math.degrees(apex):.6g} deg must lie in (0, {math.degrees(limit):.6g}] deg")


def _check_lobes(owner: str, apex: float, n: int, what: str) -> float:
    """The apex (rad) at exactly 180°/lobes, or a GeometryError unless the lobe period 2·apex divides the turn into a
    whole number of lobes (within 1e-5: an apex typed to six digits, 25.7143° for 7), a multiple of the ``n`` equally
    spaced tappets (``what``), which then all sit at the same phase of their lobes (T = n·one)."""
    lobes = math.pi / apex
    k = round(lobes)
    if abs(lobes - k) > 1e-5 * k or k % n:
        fits = [180 / m for m in range(n, 4 * n + 1, n)]
        raise GeometryError(f"{owner}: apex {math.degrees(apex):.6g} deg gives a lobe period of "
                            f"{2 * math.degrees(apex):.6g} deg, {lobes:.6g} lobes per turn: a cam has a whole number "
                            f"of lobes, and its n = {n} {what} sit in phase (torque n times one) only on a multiple of "
                            f"{n} lobes - use apex = 180 deg / lobes, e.g. "
                            f"{', '.join(f'{a:.8g} deg' for a in fits)}")
    return math.pi / k


@dataclass
class FlatTappetCharacteristic(StaticCharacteristic):
    """The primary flat-tappet clutch (§4.2): T = n F_a (k1 ± μ_B k2) on [0, 60°], period 120°."""

    clutch: FlatTappetClutch
    apex: float = field(default=APEX, init=False)
    period: float = field(default=LOBE, init=False)
    has_friction: ClassVar[bool] = True

    def _torque(self, phi: np.ndarray, direction: float) -> np.ndarray:
        return self.clutch.static_torque(phi, friction=direction != 0, direction=direction)

    def spring_force(self, phi: np.ndarray | float) -> np.ndarray:
        """Force of one tappet spring (N)."""
        return self.clutch.spring_force(phi)


@dataclass
class RollerTappetClutch(StaticCharacteristic):
    """Roller tappets on circular-arc lobes (§4.5), frictionless (rolling contact).

    ρ = sqrt(r1² − a1² sin²φ) − a1 cosφ (m), s = ρ − r0, sinβ = (a1/r1) sinφ, spring F = k_a (s + δ).
    ``form="source"``: T = ½ n k_a (s + δ)(s + r0) sin 2β = n F ρ sinβ cosβ (the thesis' expression);
    ``form="textbook"``: T = n F ρ tanβ (normal force N = F/cosβ from the radial tappet balance).
    The two differ by the factor cos²β: equal at small pressure angles, relative gap ≈ β² otherwise.
    """

    r0: float
    r1: float
    a1: float
    k_a: float
    delta: float
    n: int = 3
    apex: float = APEX
    form: str = "source"
    SCHEMA: ClassVar[dict[str, Field]] = {
        "r0": Field("m", doc="base radius (tappet roller centre at φ = 0 sits at ρ = r1 − a1)"),
        "r1": Field("m", doc="lobe arc radius (including the roller radius)"),
        "a1": Field("m", doc="eccentricity of the lobe arc centre"),
        "k_a": Field("N/m", doc="tappet spring rate"),
        "delta": Field("m", doc="initial spring deflection"),
        "n": Field("1", 3, "number of tappets"),
        "apex": Field("rad", APEX, "end of the engaged range (lobe apex)"),
        "form": Field(None, "source", "torque formula: 'source' or 'textbook'"),
    }

    def __post_init__(self) -> None:
        _positive(self.name, r0=self.r0, r1=self.r1, a1=self.a1, k_a=self.k_a)
        if not self.delta >= 0:
            raise GeometryError(f"{self.name}: initial deflection delta = {self.delta!r} m must be >= 0")
        if self.a1 >= self.r1:
            raise GeometryError(f"{self.name}: eccentricity a1 = {self.a1} m must be smaller than r1 = {self.r1} m")
        if self.form not in ("source", "textbook"):
            raise ValueError(f"{self.name}: form must be 'source' or 'textbook', got {self.form!r}")
        _check_apex(self.name, self.apex, math.pi / 2)
        self.n = int(self.n)
        self.apex = _check_lobes(self.name, self.apex, self.n, "tappets")
        self.period = 2.0 * self.apex

    def radius(self, phi: np.ndarray | float) -> np.ndarray:
        """Roller-centre radius ρ (m)."""
        phi = np.asarray(phi, dtype=float)
        return np.sqrt(self.r1 ** 2 - (self.a1 * np.sin(phi)) ** 2) - self.a1 * np.cos(phi)

    def pressure_angle(self, phi: np.ndarray | float) -> np.ndarray:
        """β (rad), sinβ = (a1/r1) sinφ."""
        return np.arcsin(self.a1 / self.r1 * np.sin(np.asarray(phi, dtype=float)))

    def _torque(self, phi: np.ndarray, direction: float) -> np.ndarray:
        rho = self.radius(phi)
        s = rho - self.r0
        beta = self.pressure_angle(phi)
        if self.form == "source":
            return 0.5 * self.n * self.k_a * (s + self.delta) * (s + self.r0) * np.sin(2.0 * beta)
        return self.n * self.k_a * (s + self.delta) * rho * np.tan(beta)


@dataclass
class LeafSpringClutch(StaticCharacteristic):
    """Tappet degenerated into a simply supported leaf of span l (§4.5).

    Contact at x = a1 sinφ from mid-span, leaf deflection y = r1 − r0 − a1 cosφ (m);
    leaf force F_v = 3EI·l·y/((l/2 − x)²(l/2 + x)²) (N); T = factor·n F_v [x ± μ (r1 − a1 cosφ)].
    ``factor`` = 1 for leaf springs, 2 for rubber shoes (:class:`RubberShoeClutch`).
    """

    width: float
    thickness: float
    span: float
    r0: float
    r1: float
    a1: float
    E: float = 206e9
    mu: float = 0.1
    n: int = 4
    apex: float = math.radians(45.0)
    factor: float = 1.0
    has_friction: ClassVar[bool] = True
    PARTS: ClassVar[str] = "leaves"
    SCHEMA: ClassVar[dict[str, Field]] = {
        "E": Field("Pa", 206e9, "Young's modulus of the leaf"),
        "width": Field("m", doc="leaf width"),
        "thickness": Field("m", doc="leaf thickness"),
        "span": Field("m", doc="distance between the leaf supports"),
        "r0": Field("m", doc="radius of the undeflected leaf contact line"),
        "r1": Field("m", doc="lobe arc radius"),
        "a1": Field("m", doc="eccentricity of the lobe arc centre"),
        "mu": Field("1", 0.1, "friction coefficient lobe / leaf"),
        "n": Field("1", 4, "number of leaves (a multiple of them fills the turn's lobes: 4 on the 45 deg cam)"),
        "apex": Field("rad", math.radians(45.0), "disengagement angle, the lobe apex (source: about 45 deg; a lobe "
                      "period 2*apex dividing the turn)"),
    }

    def __post_init__(self) -> None:
        _positive(self.name, E=self.E, width=self.width, thickness=self.thickness, span=self.span,
                  r0=self.r0, r1=self.r1, a1=self.a1)
        if not self.mu >= 0:
            raise GeometryError(f"{self.name}: friction coefficient mu = {self.mu!r} must be >= 0")
        _check_apex(self.name, self.apex, math.pi / 2)
        if self.r1 - self.r0 - self.a1 < 0:
            raise GeometryError(f"{self.name}: r1 - r0 - a1 = {self.r1 - self.r0 - self.a1:.6g} m < 0: the leaf "
                                f"would lose contact at phi = 0")
        if self.a1 * math.sin(self.apex) >= 0.5 * self.span:
            raise GeometryError(f"{self.name}: contact x = a1 sin(apex) = {self.a1 * math.sin(self.apex):.6g} m "
                                f"reaches the leaf support at span/2 = {0.5 * self.span:.6g} m")
        self.n = int(self.n)
        self.apex = _check_lobes(self.name, self.apex, self.n, self.PARTS)
        self.period = 2.0 * self.apex

    @property
    def second_moment(self) -> float:
        """I = b t³/12 (m⁴)."""
        return self.width * self.thickness ** 3 / 12.0

    def contact(self, phi: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Contact position x (m, from mid-span) and leaf deflection y (m) there."""
        phi = np.asarray(phi, dtype=float)
        return self.a1 * np.sin(phi), self.r1 - self.r0 - self.a1 * np.cos(phi)

    def leaf_force(self, phi: np.ndarray | float) -> np.ndarray:
        """Force between lobe and one leaf F_v (N)."""
        x, y = self.contact(phi)
        half = 0.5 * self.span
        return 3.0 * self.E * self.second_moment * self.span * y / ((half - x) ** 2 * (half + x) ** 2)

    def leaf_strain(self, phi: np.ndarray | float, gauge_offset: float = 0.0) -> np.ndarray:
        """Surface bending strain (m/m, positive = tension side) of a leaf at ``gauge_offset`` (m) from mid-span.

        Simply supported beam, point load F_v at a = l/2 + x from the left support: bending moment
        M(u) = F_v (l − a) u / l left of the load and F_v a (l − u)/l right of it; ε = M (t/2)/(E I).
        """
        if not abs(gauge_offset) < 0.5 * self.span:
            raise GeometryError(f"{self.name}: strain gauge offset {gauge_offset} m lies outside the span")
        x, _ = self.contact(phi)
        force = self.leaf_force(phi)
        a = 0.5 * self.span + x
        u = 0.5 * self.span + gauge_offset
        moment = np.where(u <= a, force * (self.span - a) * u, force * a * (self.span - u)) / self.span
        return moment * 0.5 * self.thickness / (self.E * self.second_moment)

    def _torque(self, phi: np.ndarray, direction: float) -> np.ndarray:
        x, _ = self.contact(phi)
        arm = x + direction * self.mu * (self.r1 - self.a1 * np.cos(phi))
        return self.factor * self.n * self.leaf_force(phi) * arm


@dataclass
class RubberShoeClutch(LeafSpringClutch):
    """Rubber shoes pressed by leaves: twice the leaf-spring torque (§4.5). The source's disengagement at ≈ 55°
    lies between the apexes of whole-lobe cams, 45° (4 lobes) and 60° (3 lobes): the default is 3 shoes on 3 lobes,
    apex 60° (a 110° lobe period would give 3.27 lobes per turn)."""

    n: int = 3
    apex: float = math.radians(60.0)
    factor: float = 2.0
    PARTS: ClassVar[str] = "shoes"
    SCHEMA: ClassVar[dict[str, Field]] = {**LeafSpringClutch.SCHEMA,
                                          "n": Field("1", 3, "number of shoes (a multiple of them fills the lobes)"),
                                          "apex": Field("rad", math.radians(60.0), "disengagement angle, the lobe "
                                                        "apex (source: about 55 deg; 60 deg: 3 lobes per turn)")}


@dataclass
class RubberRollerClutch(StaticCharacteristic):
    """Rubber rollers squeezed between the halves (§4.5), closed form.

    φ = 2 M h / (D0 (M + ½ D0 z A0 E1)) and its inverse M = ½ D0 z A0 E1 · φ / (2h/D0 − φ);
    D0 roller-circle diameter (m), h rubber height (m), z number of rollers, A0 loaded area of one
    roller (m²), E1 rubber modulus (Pa). The angle saturates at 2h/D0; ``apex`` (< 2h/D0) ends the
    engaged range (an assumption: the source gives no disengagement angle for this variant).
    """

    D0: float
    h: float
    z: int
    A0: float
    E1: float
    apex: float
    SCHEMA: ClassVar[dict[str, Field]] = {
        "D0": Field("m", doc="diameter of the roller circle"),
        "h": Field("m", doc="rubber height"),
        "z": Field("1", doc="number of rollers"),
        "A0": Field("m^2", doc="loaded area of one roller"),
        "E1": Field("Pa", doc="rubber modulus"),
        "apex": Field("rad", doc="end of the engaged range (assumption, < 2h/D0)"),
    }

    def __post_init__(self) -> None:
        _positive(self.name, D0=self.D0, h=self.h, z=self.z, A0=self.A0, E1=self.E1)
        _check_apex(self.name, self.apex, self.saturation_angle * (1 - 1e-9))
        self.period = 2.0 * self.apex

    @property
    def saturation_angle(self) -> float:
        """2h/D0 (rad): the angle approached as M → ∞."""
        return 2.0 * self.h / self.D0

    @property
    def torque_scale(self) -> float:
        """½ D0 z A0 E1 (N·m)."""
        return 0.5 * self.D0 * self.z * self.A0 * self.E1

    def _torque(self, phi: np.ndarray, direction: float) -> np.ndarray:
        return self.torque_scale * phi / (self.saturation_angle - phi)

    def angle(self, torque: np.ndarray | float, direction: float = 0.0, clip_low: bool = False) -> np.ndarray:
        """Closed form φ = 2 M h / (D0 (M + ½ D0 z A0 E1)) (rad), M in [0, peak_torque] (N·m)."""
        m = np.asarray(torque, dtype=float)
        bad = ~((m >= 0) | clip_low) | ~(m <= self.peak_torque * (1 + 1e-12))
        if np.any(bad):
            raise ValueError(f"{self.name}: torque {float(m[bad].flat[0]):.6g} N*m outside [0, "
                             f"{self.peak_torque:.6g}] N*m")
        m = np.maximum(m, 0.0)
        return 2.0 * m * self.h / (self.D0 * (m + self.torque_scale))


@dataclass
class TabulatedClutch(StaticCharacteristic):
    """Data-driven variant: a measured static table, monotone (PCHIP) interpolation T(φ) (rad → N·m).

    Defined only between the first and last measured angle (outside raises); ``angle`` is the exact
    inverse of the interpolant, so the table points are reproduced both ways. ``through_origin``
    prepends the unmeasured point (0, 0) (an assumption: no preload, as for the rubber rollers).
    """

    angles: np.ndarray
    torques: np.ndarray
    label: str = "table"
    through_origin: bool = False
    _curve: PchipInterpolator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.angles = np.asarray(self.angles, dtype=float)
        self.torques = np.asarray(self.torques, dtype=float)
        if self.through_origin:
            self.angles = np.concatenate(([0.0], self.angles))
            self.torques = np.concatenate(([0.0], self.torques))
        if self.angles.ndim != 1 or self.angles.shape != self.torques.shape or self.angles.size < 2:
            raise ValueError(f"{self.label}: need matching 1-D angle and torque columns with >= 2 rows")
        for what, col in (("angle", self.angles), ("torque", self.torques)):
            if np.any(np.diff(col) <= 0):
                i = int(np.flatnonzero(np.diff(col) <= 0)[0])
                raise ValueError(f"{self.label}: {what} column is not strictly increasing at row {i + 2}")
        self.phi_min = float(self.angles[0])
        self.apex = float(self.angles[-1])
        self.period = 2.0 * self.apex
        self._curve = PchipInterpolator(self.angles, self.torques, extrapolate=False)

    @property
    def name(self) -> str:
        return f"TabulatedClutch({self.label})"

    def _torque(self, phi: np.ndarray, direction: float) -> np.ndarray:
        return self._curve(phi)

    @classmethod
    def from_file(cls, path: str | Path, through_origin: bool = False) -> "TabulatedClutch":
        """Read a CSV table with header ``torque_<unit>,angle_<unit>`` (``#`` lines are comments)."""
        path = Path(path)
        try:
            lines = [ln for ln in path.read_text(encoding="utf-8").splitlines()
                     if ln.strip() and not ln.lstrip().startswith("#")]
        except OSError as exc:
            raise ValueError(f"cannot read clutch table {path}: {exc.strerror}") from None
        rows = list(csv.reader(lines))
        if not rows:
            raise ValueError(f"{path}: empty clutch table")
        header = [h.strip() for h in rows[0]]
        units: dict[str, str] = {}
        for h in header:
            quantity, _, unit = h.partition("_")
            if quantity not in ("torque", "angle") or not unit or quantity in units:
                raise ValueError(f"{path}: header must be torque_<unit>,angle_<unit>, got {','.join(header)!r}")
            units[quantity] = unit
        if len(units) != 2:
            raise ValueError(f"{path}: header must name both torque and angle columns, got {header}")
        si = {"torque": "N*m", "angle": "rad"}
        cols: dict[str, list[float]] = {"torque": [], "angle": []}
        for line_no, row in enumerate(rows[1:], start=2):
            if len(row) != 2:
                raise ValueError(f"{path}: data row {line_no} has {len(row)} fields, expected 2")
            for h, cell in zip(header, row):
                q = h.partition("_")[0]
                try:
                    value = float(cell)
                    cols[q].append(to_si(value, si[q], units[q], what=f"{path}: row {line_no} {h}"))
                except ValueError as exc:
                    if isinstance(exc, UnitError):
                        raise
                    raise ValueError(f"{path}: data row {line_no}: {h} = {cell!r} is not a number") from None
        return cls(angles=np.array(cols["angle"]), torques=np.array(cols["torque"]), label=path.stem,
                   through_origin=through_origin)


MEASURED_TABLES = ("rubber_d25_rubber_d20", "rubber_d25_pu_d20")


def measured_table(name: str, through_origin: bool = False) -> TabulatedClutch:
    """One of the measured rubber-roller tables of §4.5 (``MEASURED_TABLES``) as a data-driven plant."""
    if name not in MEASURED_TABLES:
        raise ValueError(f"unknown measured clutch table {name!r}; known: {', '.join(MEASURED_TABLES)}")
    return TabulatedClutch.from_file(DATA_DIR / f"{name}.csv", through_origin)


@dataclass
class ShearPin:
    """Shear-pin safety coupling: rigid until |M| reaches M_lim = factor·M_tc, then broken for good.

    ``idle_torque`` M_tc (N·m); ``limit_factor`` 1.15…1.2 in the source. A broken pin transmits
    nothing until :meth:`replace` fits a new one.
    """

    idle_torque: float
    limit_factor: float = 1.2
    broken: bool = field(default=False, init=False)
    break_time: float | None = field(default=None, init=False)
    break_torque: float | None = field(default=None, init=False)
    breaks: int = field(default=0, init=False)
    SCHEMA: ClassVar[dict[str, Field]] = {
        "idle_torque": Field("N*m", doc="idle (working) torque M_tc"),
        "limit_factor": Field("1", 1.2, "M_lim / M_tc, 1.15...1.2 in the source"),
    }

    def __post_init__(self) -> None:
        _positive("ShearPin", idle_torque=self.idle_torque)
        if not 1.0 < self.limit_factor <= 2.0:
            raise ValueError(f"ShearPin: limit_factor = {self.limit_factor!r} must lie in (1, 2] "
                             f"(the source uses 1.15...1.2 x idle torque)")

    @property
    def limit_torque(self) -> float:
        """Breaking torque M_lim (N·m)."""
        return self.limit_factor * self.idle_torque

    def transmit(self, t: np.ndarray, torque: np.ndarray) -> np.ndarray:
        """Torque (N·m) passed on for a demanded torque history at increasing times t (s).

        The demand is passed unchanged up to the first sample with |M| >= M_lim; from that sample on
        (and in every later call) the pin is broken and transmits 0.
        """
        t = np.asarray(t, dtype=float)
        torque = np.asarray(torque, dtype=float)
        if t.shape != torque.shape or t.ndim != 1:
            raise ValueError(f"ShearPin: t and torque must be matching 1-D arrays, got {t.shape}, {torque.shape}")
        if self.broken:
            return np.zeros_like(torque)
        over = np.flatnonzero(np.abs(torque) >= self.limit_torque)
        out = torque.copy()
        if over.size:
            i = int(over[0])
            self.broken, self.break_time, self.break_torque = True, float(t[i]), float(torque[i])
            self.breaks += 1
            out[i:] = 0.0
        return out

    def replace(self) -> None:
        """Fit a new pin (the only way back to a transmitting coupling)."""
        self.broken, self.break_time, self.break_torque = False, None, None

"""2-DOF Lagrange dynamics of the flat-tappet clutch on a stand (MODELS.md §4.3).

State y = (φr, ωr, φ3, ω3, *load states) in rad, rad/s, with φr = φ1 − φ3 and ωr = ω1 − ω3 the relative
angle and speed (integrated directly so that error control acts on them, not on absolute angles of tens of
rad whose difference they would be). With M = n·m_t, k3 = 2·k1·dk1/dφ:

    (J1 + M k1²) φ̈1 − M k1² φ̈3 = M1 − T_c − ½M k3 ωr² + M k1 k2 ω3²
    (J3 + M k1² + M k2²) φ̈3 − M k1² φ̈1 = −M3 + T_c + ½M k3 ωr² − M k1 k2 ω3² − 2M k1 k2 ωr ω3

T_c = n[(F_a + F_fC) k1 + F_fB k2] is the torque the tappets pass to the driven half. Friction is signed
Coulomb: F_fB = μ_B N_B sB at the cam face (v21 = k2 ωr), F_fC = μ_C (|R1| + |R2|) sC in the guide
(v23 = k1 ωr). Quasi-static tappet balance (docs/clutch.md): N_B = F_a + F_fC + m_t (dk1 ωr² − k2 ω3²),
guide reactions R1 = N_B (k1 + (k2 − L2) μ_B sB)/(L2 − L1), R2 = −N_B (k1 + (k2 − L1) μ_B sB)/(L2 − L1),
solved in closed form for N_B. Two friction models (docs/clutch.md):

* ``"stick_slip"`` (default): switched model with a discrete mode: slipping (sB = σ, sC = σ·sgn k1 with
  sC = +1 at k1 = 0, σ = ±1 fixed while ωr keeps its sign) or stuck (ωr ≡ 0, the halves move together and T_c is the
  torque needed for that, admissible while it lies in the static band [T_c(σ=−1), T_c(σ=+1)]).
  Transitions are located as events (ωr = 0; T_c reaching a band edge) — no stiffness. While stuck the
  halves are one rotor, (J1 + J3')ω̇ = M1 − M3 with J3' = J3 + n m_t k2² constant (φ_r is frozen); for a
  linear motor and loads affine in speed this is solved in closed form (:meth:`ClutchDynamics.stuck_flow`),
  the band edges being quadratics in ω whose roots bound the steps, so no Runge–Kutta step is spent.
* ``"tanh"``: sgn(v) ≈ tanh(v/v_s); smooth but stiff when sticking (time constant ≈ J v_s/(n μ_B N_B k2²)).
"""
from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Callable

import numpy as np
from scipy.optimize import brentq

from rig.plants.clutch import kernel
from rig.plants.clutch.flat_tappet import FlatTappetClutch
from rig.plants.clutch.geometry import APEX, LOBE
from rig.plants.clutch.kernel import locate_segment
from rig.plants.clutch.loads import LinearMotor, Load, LoadSum
from rig.solvers import AffineRotor, Event, EventRecord, Problem
from rig.solvers.compiled import JitRhs

FRICTION_MODELS = ("stick_slip", "tanh")


def positions(n: int) -> tuple[int, ...]:
    """Indices of the positions in a stand state of ``n`` components (φr, ωr, φ3, ω3, *load states): φr, φ3 and the
    load states (symplectic Euler's kick–drift split; ωr, ω3 are the rates)."""
    return (0, 2, *range(4, n))


class ClutchDynamics:
    """Equations of motion of clutch + motor + load; ``blocked=True`` clamps the driven half (ω3 ≡ 0).

    ``friction`` is "stick_slip" (switched Coulomb model, discrete ``mode`` = +1/−1 slipping with
    sgn ωr, 0 stuck) or "tanh" (regularised with velocity scale ``v_s``, m/s). ``J_down`` (kg·m²) is the
    part of J3 downstream of the torque meter (flywheel, brake drum), used for the meter reading.
    """

    def __init__(self, clutch: FlatTappetClutch, motor: LinearMotor, load: Load, v_s: float = 0.01,
                 blocked: bool = False, J_down: float = 0.0, friction: str = "stick_slip"):
        if friction not in FRICTION_MODELS:
            raise ValueError(f"ClutchDynamics: friction = {friction!r} is not one of {FRICTION_MODELS}")
        if not v_s > 0:
            raise ValueError(f"ClutchDynamics: friction velocity scale v_s = {v_s!r} m/s must be positive")
        if not 0 <= J_down <= clutch.J3:
            raise ValueError(f"ClutchDynamics: J_down = {J_down} kg*m^2 must lie in [0, J3 = {clutch.J3}]")
        self.clutch, self.motor, self.load = clutch, motor, load
        self.v_s, self.blocked, self.J_down, self.friction = v_s, blocked, J_down, friction
        program = (load if isinstance(load, LoadSum) else LoadSum([load])).program()
        self._p = kernel.pack(clutch, motor, program, v_s, blocked, friction == "tanh")
        self._p[kernel.HELD] = float(friction == "stick_slip")     # stick–slip holds the cam segment
        if len(kernel._switched_brakes(self._p)) > 1:
            raise ValueError("ClutchDynamics: at most one stick-slip brake (the driven half is held by one brake)")
        self._brake = int(self._p[kernel.BRAKE_AT])     # mode slot of the stick–slip brake, −1 if none
        self._p = kernel.with_events(self._p, [row for _, row, _ in self._event_specs()])
        self.mode = 1                                   # stick_slip: +1/−1 slipping, 0 stuck
        self._log_t: list[float] = []                   # mode history (for outputs at past samples)
        self._log_mode: list[int] = []
        self._log_brake: list[int] = []
        self.rhs = JitRhs(kernel.rhs, self._sync, self._diagnose, kernel.event_value, kernel.event_action)

    @property
    def brake_mode(self) -> int:
        """Stick–slip brake: +1/−1 slipping with sgn ω3, 0 holding the driven half (1 without such a brake)."""
        return int(self._p[self._brake]) if self._brake >= 0 else 1

    @brake_mode.setter
    def brake_mode(self, value: int) -> None:
        self._p[self._brake] = value

    @property
    def mode(self) -> int:
        """Friction mode (stick–slip): +1/−1 slipping with sgn ωr, 0 stuck."""
        return int(self._p[kernel.MODE])

    @mode.setter
    def mode(self, value: int) -> None:
        self._p[kernel.MODE] = value

    def _sync(self) -> np.ndarray:
        """The kernel's parameter vector with the motor's trip state; clears the self-lock record."""
        p = self._p
        p[kernel.TRIP_AT], p[kernel.LOCKED_AT] = self.motor.trip_at, math.nan
        return p

    def _diagnose(self) -> str | None:
        at = self._p[kernel.LOCKED_AT]
        if math.isnan(at):
            return None
        return f"tappet self-locks in its guide (mu_C*(|R1|+|R2|)/N_B >= 1 at relative angle {math.degrees(at):.4g} deg)"

    def core(self, t: float, y: tuple, mode: int, held: bool = False) -> tuple:
        """(ω̇1, ω̇3, M1, M3, T_c, F_a, N_B) at (t, y) in friction ``mode`` (true cam segment unless ``held``)."""
        return kernel.core(t, np.asarray(y, dtype=float), mode, self._sync(), held)

    def band(self, t: float, y: tuple, held: bool = False) -> tuple:
        """Static friction band at ωr = 0: (T_c required, T_c at σ = ±1, N_B at σ = ±1, F_a, M1, M3, a)."""
        out = kernel.band(t, np.asarray(y, dtype=float), self._sync(), held)
        if math.isnan(out[1]) or math.isnan(out[2]):
            self._p[kernel.LOCKED_AT] = y[0]
            self.rhs.fail(t, y, "static friction band undefined")
        return out

    def _J3p(self, k2: float) -> float:
        return self.clutch.J3 + self.clutch.n * self.clutch.m_t * k2 * k2

    # -- stick–slip mode logic --------------------------------------------------------------------
    def _stuck_state(self, y: tuple) -> tuple:
        """Project onto ωr = 0 conserving the angular momentum of the two halves (held driven half: at rest)."""
        if self.blocked or self.brake_mode == 0:
            return (y[0], 0.0, *y[2:])
        J1, J3p = self.clutch.J1, self._J3p(kernel.geometry(y[0], self._p, False)[1])
        return (y[0], 0.0, y[2], y[3] + J1 * y[1] / (J1 + J3p), *y[4:])

    def _pick_at_rest(self, t: float, y: tuple) -> int:
        """Mode for ωr = 0: stuck if the needed torque lies inside the static band, else slip towards it."""
        tc, tp, tm = self.band(t, y)[:3]
        if tm < tp and tm <= tc <= tp:
            return 0
        return 1 if tc > 0.5 * (tp + tm) else -1

    def _set_mode(self, t: float, mode: int, brake: bool = False) -> bool:
        """Set the clutch's (or with ``brake`` the brake's) mode from t on; True if it changed."""
        if mode == (self.brake_mode if brake else self.mode):
            return False
        if brake:
            self.brake_mode = mode
        else:
            self.mode = mode
        self._log_t.append(t)
        self._log_mode.append(self.mode)
        self._log_brake.append(self.brake_mode)
        return True

    # -- stick–slip brake ---------------------------------------------------------------------------
    def _brake_need(self, t: float, y: tuple) -> tuple[float, float]:
        """(torque the brake must react to hold the drum, its capacity gain·F_b), N·m, at ω3 = 0."""
        return kernel.brake_need(t, np.asarray(y, dtype=float), self._sync())

    def _pick_brake_at_rest(self, t: float, y: tuple) -> int:
        need, cap = self._brake_need(t, y)
        return 0 if abs(need) <= cap else 1 if need > 0 else -1

    def _on_brake(self, rec: EventRecord) -> tuple:
        """Event action: the drum stops (ω3 = 0, ω1 kept) and is held or slips on; a held drum breaks loose
        when the needed torque reaches the capacity. Returns the new state."""
        y = rec.y
        if self.brake_mode:
            y = (y[0], y[1] + y[3] if self.mode else 0.0, y[2], 0.0, *y[4:])
            self._set_mode(rec.t, self._pick_brake_at_rest(rec.t, y), brake=True)
            return y
        need = self._brake_need(rec.t, y)[0]
        self._set_mode(rec.t, 1 if need > 0 else -1, brake=True)
        return y

    def _reset_brake(self, t: float, y: tuple) -> bool:
        if self._brake < 0:
            return False
        if y[3] != 0.0:
            return self._set_mode(t, 1 if y[3] > 0 else -1, brake=True)
        if self.brake_mode == 0:
            need, cap = self._brake_need(t, y)
            if abs(need) <= cap:
                return False
        return self._set_mode(t, self._pick_brake_at_rest(t, y), brake=True)

    def _on_switch(self, rec: EventRecord) -> tuple:
        """Event action: slip → stick/reverse at ωr = 0, stick → slip at a band edge; returns the new state
        (the driven half held by the brake or clamped: the driving half stops with the clutch)."""
        if self.mode:
            y = self._stuck_state(rec.y)
            self._set_mode(rec.t, self._pick_at_rest(rec.t, y))
            return y
        tc, tp, tm = self.band(rec.t, rec.y)[:3]
        self._set_mode(rec.t, 1 if tp - tc < tc - tm else -1)
        return rec.y

    def reset(self, t: float, y: tuple) -> bool:
        """Re-select the modes (brake, then clutch) and the cam segment at t (integration start, after load
        jumps/restarts); True if a mode changed."""
        self._truncate_log(t)
        changed = self._reset_brake(t, y)
        if self.friction != "stick_slip":
            return changed
        changed |= self._reset_mode(t, y)
        wr = y[1]
        p = self._p
        p[kernel.BASE], p[kernel.SEG] = locate_segment(y[0], wr if wr != 0.0 else self.mode, p[kernel.PM])
        return changed

    def _truncate_log(self, t: float) -> None:
        """Forget modes logged at or after t (a run restarted there) and log the current ones at t."""
        i = bisect.bisect_left(self._log_t, t) if self._log_t and t > self._log_t[0] else 0
        del self._log_t[i:], self._log_mode[i:], self._log_brake[i:]
        self._log_t.append(t)
        self._log_mode.append(self.mode)
        self._log_brake.append(self.brake_mode)

    def _reset_mode(self, t: float, y: tuple) -> bool:
        wr = y[1]
        if wr != 0.0:
            return self._set_mode(t, 1 if wr > 0 else -1)
        if self.mode == 0:
            tc, tp, tm = self.band(t, y)[:3]
            if tm <= tc <= tp:
                return False
        return self._set_mode(t, self._pick_at_rest(t, y))

    def modes_at(self, t: np.ndarray, brake: bool = False) -> np.ndarray:
        """Clutch (or with ``brake`` the stick–slip brake's) mode in effect at times ``t``, from the mode
        history (tanh clutch: sgn ωr irrelevant → 1; no such brake → 1)."""
        if (self._brake < 0 if brake else self.friction != "stick_slip") or not self._log_t:
            return np.ones(len(t), dtype=int)
        i = np.searchsorted(np.asarray(self._log_t), t, side="right") - 1
        return np.asarray(self._log_brake if brake else self._log_mode)[np.maximum(i, 0)]

    def stuck_flow(self, t: float, y: tuple, t_bound: float) -> StuckFlow | None:
        """Closed-form motion of the stuck halves from (t, y) up to ``t_bound`` (s), or None when the mode
        is slipping or the loads have no closed form (angle zones, brake actuator, centrifugal unloading).

        Common rotor (J1 + J3')ω̇ = (A − α) − (B + β)ω for M1 = A − Bω, M3 = α + βω (blocked: at rest). The
        band margins T_c(σ=±1) − T_req are quadratic in ω (centrifugal terms) while N_B > 0; their roots
        inside the segment are mapped to times and the flow's steps end between them, so each step holds
        at most one stick → slip crossing for the driver to locate."""
        if self.mode != 0:
            return None
        t_mid = 0.5 * (t + t_bound)               # inside the time-break interval: loads are fixed there
        z = tuple(y[4:])
        if any(self.load.rates(t_mid, y[2], y[3], z)):
            return None
        c = self.clutch
        if self.blocked or self.brake_mode == 0:   # all at rest; band margins constant till the next break
            return StuckFlow(AffineRotor(t, 0.0, 0.0, 0.0, 0.0, c.J1), y[0], y[2], [], z)
        load = self.load.affine(t_mid, z, y[3], y[3])
        if load is None:
            return None
        A, B = self.motor.affine(t_mid)
        J = c.J1 + self._J3p(kernel.geometry(y[0], self._p, False)[1])
        rotor = AffineRotor(t, 0.0, y[3], A - load[0], B + load[1], J)
        w0, we = rotor.omega0, rotor.state(t_bound)[1]
        if self.load.affine(t_mid, z, min(w0, we), max(w0, we)) != load:
            return None                            # the load leaves its affine range on the way (monotone ω)
        flow = StuckFlow(rotor, y[0], y[2], [], z)
        if we == w0:
            return flow
        ws = (w0, 0.5 * (w0 + we), we)
        margins = []
        for w in ws:
            tc, tp, tm, nbp, nbm = self.band(t_mid, (y[0], 0.0, y[2], w, *z))[:5]
            if w != ws[1] and min(nbp, nbm) <= 0.0:
                return None                        # N_B clipped at 0: margins not quadratic
            margins.append((tp - tc, tc - tm))
        roots = []
        for f in zip(*margins):
            roots += [rotor.time_of_speed(w0 + s) for s in _quadratic_roots(f, we - w0)]
        roots = sorted(r for r in roots if t < r <= t_bound)
        flow.stops = [0.5 * (a + b) for a, b in itertools.pairwise(roots) if b > a]
        return flow

    # -- problem assembly ---------------------------------------------------------------------------
    def initial_state(self, omega: float = 0.0, phi_r: float = 0.0) -> tuple:
        """Both halves at speed ``omega`` (rad/s), relative angle ``phi_r`` (rad), loads at rest."""
        if self.blocked:
            return (phi_r, omega, 0.0, 0.0, *self.load.initial_state())
        return (phi_r, 0.0, 0.0, omega, *self.load.initial_state())

    def equilibrium_angle(self, omega: float) -> float:
        """Relative angle (rad) on the rising flank where the frictionless static torque n·F_a·k1 carries
        the load torque at t = 0 and speed ``omega`` (rad/s); 0 for no load. Raises ValueError when the
        load exceeds the elastic peak (the coupling cannot run in equilibrium)."""
        m3 = self.load.torque(0.0, 0.0, omega, tuple(self.load.initial_state()))
        if m3 <= 0.0:
            return 0.0
        c = self.clutch
        peak = c.limits.phi_maxI
        elastic = lambda phi: float(c.static_torque(phi, friction=False)) - m3
        if elastic(peak) <= 0.0:
            raise ValueError(f"load torque {m3:.4g} N*m at start exceeds the elastic peak "
                             f"{float(c.static_torque(peak, friction=False)):.4g} N*m: no running equilibrium")
        return float(brentq(elastic, 0.0, peak, xtol=1e-12))

    def energy(self, y) -> float:
        """Kinetic energy + spring energy (J) for a state (used to check conservation)."""
        c = self.clutch
        g = c.geometry(y[0])
        k1, k2, s = float(g["k1"]), float(g["k2"]), float(g["s"])
        wr, w3 = y[1], y[3]
        kin = 0.5 * c.J1 * (wr + w3) ** 2 + 0.5 * c.n * c.m_t * (k1 ** 2 * wr ** 2 + k2 ** 2 * w3 ** 2) + 0.5 * c.J3 * w3 ** 2
        return kin + c.n * (c.F_a1 * s + 0.5 * c.k_a * s * s)

    def _event_specs(self) -> list[tuple[str, tuple[int, int, float, float], dict]]:
        """(name, table row (kind, state index, angle, period), Event options) of every event, in order."""
        lim, per = self.clutch.limits, kernel.PERIODIC
        switched = self.friction == "stick_slip"       # guide friction flips where k1 = 0 (wrap, apex)
        segment = int(switched)                         # held-segment boundaries: compiled restarts allowed
        specs = [("phase_boundary", (per, 0, b, LOBE, segment), {"restart": True})
                 for b in (lim.phi_maxI, LOBE - lim.phi_maxI)]
        specs += [("lobe_wrap", (per, 0, 0.0, LOBE, segment), {"restart": switched}),
                  ("apex", (per, 0, APEX, LOBE, 0), {"restart": switched})]
        specs += [("load_zone", (per, 2, a, T, 0), {"restart": True}) for a, T in self.load.angle_breaks()]
        if switched:
            specs.append(("stick_slip", (kernel.CLUTCH_SWITCH, 0, 0.0, 1.0, 0),
                          {"direction": -1.0, "action": self._on_switch, "mode_dependent": True}))
        if self._brake >= 0:
            specs.append(("brake_stick_slip", (kernel.BRAKE_SWITCH, 0, 0.0, 1.0, 0),
                          {"direction": -1.0, "action": self._on_brake, "mode_dependent": True}))
        return specs

    def events(self, on_apex: Callable[[EventRecord], bool] | None = None) -> list[Event]:
        """Phase boundaries (restart), lobe wrap and apex (recorded; ``on_apex`` is the apex event's
        action), load angle switches (restart) and, for stick–slip, the mode switches of clutch and brake
        — all evaluated by the compiled event table (:func:`rig.plants.clutch.kernel.event_value`)."""
        out = []
        for k, (name, _, opts) in enumerate(self._event_specs()):
            if name == "apex":
                opts = dict(opts, action=on_apex)
            out.append(Event(kernel.event_function(self._p, k), name, **opts))
        return out

    def problem(self, y0: tuple, on_apex: Callable[[EventRecord], bool] | None = None) -> Problem:
        """Problem for :func:`rig.solvers.integrate` with all events, time breaks and the mode reset."""
        breaks = sorted(set(self.load.time_breaks()) | set(self.motor.time_breaks()))
        flow = self.stuck_flow if self.friction == "stick_slip" else None
        return Problem(self.rhs, y0, self.events(on_apex), breaks, reset=self.reset, flow=flow,
                       positions=positions(len(y0)))

    def outputs(self, t: np.ndarray, Y: np.ndarray) -> dict[str, np.ndarray]:
        """Physical truth at samples: angles, speeds, φ_r, ω_r, M1, M3, torque meter M_t, T_c, F_a, N_B.

        Stuck samples report the transmitted T_c and N_B interpolated in the static band (the split of
        static friction between cam face and guide is indeterminate)."""
        modes, brakes, current = self.modes_at(t), self.modes_at(t, brake=True), self.brake_mode
        t = np.asarray(t, dtype=float)
        try:
            vals = kernel.samples(t, np.ascontiguousarray(Y, dtype=float), np.asarray(modes, dtype=np.int64),
                                  np.asarray(brakes, dtype=float), self._sync(), self._brake)
            bad = np.flatnonzero((np.asarray(modes) == 0) & np.isnan(vals[:, 5]))
            if bad.size:                         # the band is undefined there: the Python path names it
                k = int(bad[0])
                if self._brake >= 0:
                    self.brake_mode = int(brakes[k])
                self.band(float(t[k]), tuple(Y[:, k]))
        finally:
            if self._brake >= 0:
                self.brake_mode = current
        a3 = vals[:, 1]
        out = {"phi1": Y[0] + Y[2], "omega1": Y[1] + Y[3], "phi3": Y[2], "omega3": Y[3], "phi_r": Y[0],
               "omega_r": Y[1], "M1": vals[:, 2], "M3": vals[:, 3], "T_c": vals[:, 4],
               "F_a": vals[:, 5], "N_B": vals[:, 6]}
        out["M_t"] = vals[:, 4] if self.blocked else vals[:, 3] + self.J_down * a3
        return out


class StuckFlow:
    """Stuck halves turning together along ``rotor`` (:class:`rig.solvers.AffineRotor`) at the frozen
    relative angle ``phi_r`` from φ3 = ``phi3``, load states ``z`` at rest; state (φr, 0, φ3, ω, *z) at a
    float time (tuple) or times (array, one row per state)."""

    def __init__(self, rotor: AffineRotor, phi_r: float, phi3: float, stops: list[float], z: tuple = ()):
        self.rotor, self.phi_r, self.phi3, self.stops, self.z = rotor, phi_r, phi3, stops, z

    def __call__(self, t):
        if isinstance(t, float):
            d, w = self.rotor.state(t)
            return (self.phi_r, 0.0, self.phi3 + d, w, *self.z)
        d, w = self.rotor.states(t)
        return np.vstack((np.full_like(d, self.phi_r), np.zeros_like(d), self.phi3 + d, w,
                          *(np.full_like(d, v) for v in self.z)))


def _quadratic_roots(f: tuple[float, float, float], span: float) -> list[float]:
    """Real roots s with 0 < s/span ≤ 1 of the quadratic through (0, f0), (span/2, f1), (span, f2)."""
    f0, f1, f2 = f
    h = 0.5 * span
    d01, d12 = (f1 - f0) / h, (f2 - f1) / h
    c2 = (d12 - d01) / span
    c1 = d01 - c2 * h
    if c2 == 0.0:
        roots = [-f0 / c1] if c1 != 0.0 else []
    else:
        disc = c1 * c1 - 4.0 * c2 * f0
        if disc < 0.0:
            return []
        q = -0.5 * (c1 + math.copysign(math.sqrt(disc), c1))
        roots = [q / c2] + ([f0 / q] if q != 0.0 else [])
    return [s for s in roots if 0.0 < s / span <= 1.0]

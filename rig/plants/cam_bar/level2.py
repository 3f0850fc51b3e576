"""Level-2 dynamics of the pin-insertion mechanism (MODELS §3.4): the follower as a DOF in a groove with clearance.

The roller centre B_R sits between two flanks. Its offset from the level-0 pitch curve along the contact
normal n (oriented as in level 1, B_R × n = ℓ > 0) is u = ℓ(φ)·e with e = ψ − ψ_k(φ) the follower's deviation
from the level-0 law ψ_k (first order in e: |e| ≲ 1e-3 rad, curvature terms ~ c²/ρ are dropped). The working
flank (pushes towards larger ψ) sits at u = 0, the other one at u = c; penetrations are δ_w = −u and
δ_o = u − c, each with the compliant contact of :class:`ContactLaw`. The rod and slider follow ψ through the
level-0 chain (with the rod's pin clearances the slider is a body of its own: :mod:`.joints`); spring, gravity,
guide friction, insertion force and the inertia of all links come from the level-1 free-body diagrams
(:mod:`rig.plants.cam_bar.kinetostatics`) on the *actual* motion, which give the cam moment M_Σ needed for an
acceleration ψ̈. It is affine in ψ̈ on each friction branch, so M_Σ(ψ̈) = ℓ·(F_w − F_o)
is solved in closed form. The cam turns by the given speed profile, or, with a cam drive
(:mod:`.drive`), as a state driven by a motor through a compliant shaft. The insertion force follows the pin's
force–travel law (:mod:`.insertion`) and the slider guide's friction its model (:mod:`.guide_friction`).

The right-hand side, the events and the quantities the outputs are built from are compiled
(:mod:`rig.plants.cam_bar.level2_kernel`, parameters in one vector); the outputs' joint reactions come from the
level-1 :func:`~rig.plants.cam_bar.kinetostatics.solve` on the integrated motion.

State ``y = (e, τ·ė)`` (rad, τ = 1 ms so both components are angles and the error control sees the small
deviation, not ψ ≈ 1.5 rad), with a cam drive followed by (φ, ω, φ_m, ω_m), with the rod's pin clearances
(:mod:`.joints`) by the slider's (z, τ·ż) (m: its stroke against the rigid chain's at the actual ψ), optionally
followed by the work of the cam drive, of the insertion force and guide friction, and the energy dissipated in
the contacts (J).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from rig.plants.cam_bar import level2_kernel as kernel
from rig.plants.cam_bar.chain import Angles
from rig.plants.cam_bar.kinetostatics import Kinetostatics, solve
from rig.plants.cam_bar.level2_model import Level2Model
from rig.plants.events import Event
from rig.solvers import Event as SolverEvent
from rig.solvers import JitRhs, OdeSolver, Problem, Solution, SolverDivergence, integrate

if TYPE_CHECKING:
    from rig.motion.speed import SpeedProfile
    from rig.plants.cam_bar.drive import CamDrive
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism, State

TAU = kernel.TAU  # s, scale of the velocity state
METHOD = "DP45"  # default method of Level2.simulate: the fastest at 1e-6 (docs/cam-bar.md, benchmarks/bench_level2.py)
PALMGREN = 3.84e-5  # steel line contact, approach δ = 3.84e-5·Q^0.9/l^0.8 (δ, l in mm, Q in N)


@dataclass(frozen=True)
class ContactLaw:
    """Roller–flank contact force F = K·δ^p·(1 + α·δ̇) ≥ 0 for penetration δ > 0 (m), rate δ̇ (m/s).

    ``stiffness`` K (N/m^p), ``exponent`` p, ``damping`` α (s/m; Hunt–Crossley, dissipation ∝ δ^p so the
    force is continuous at touch-down)."""

    stiffness: float
    exponent: float = 10.0 / 9.0
    damping: float = 20.0

    def __post_init__(self) -> None:
        if not (self.stiffness > 0.0 and self.exponent >= 1.0 and self.damping >= 0.0):
            raise ValueError(f"contact law needs stiffness > 0, exponent >= 1 and damping >= 0, got "
                             f"K = {self.stiffness!r}, p = {self.exponent!r}, alpha = {self.damping!r}")

    @classmethod
    def steel_line(cls, width: float, damping: float = 20.0) -> "ContactLaw":
        """Steel roller on a steel flank over contact length ``width`` (m): Palmgren's line-contact approach
        δ = 3.84e-5·Q^0.9/l^0.8 (mm, N) inverted, i.e. p = 10/9 (Harris, *Rolling Bearing Analysis*)."""
        if not width > 0.0:
            raise ValueError(f"roller contact width must be positive, got {width!r} m")
        return cls((1e3 * (width * 1e3) ** 0.8 / PALMGREN) ** (10.0 / 9.0), 10.0 / 9.0, damping)

    def elastic(self, delta: np.ndarray) -> np.ndarray:
        """K·δ^p for δ > 0, else 0 (N)."""
        return self.stiffness * np.maximum(delta, 0.0) ** self.exponent

    def force(self, delta: np.ndarray, rate: np.ndarray) -> np.ndarray:
        """Contact force (N), never pulling."""
        return np.maximum(self.elastic(delta) * (1.0 + self.damping * rate), 0.0)

    def energy(self, delta: np.ndarray) -> np.ndarray:
        """Elastic energy stored in the contact (J)."""
        return self.elastic(delta) * np.maximum(delta, 0.0) / (self.exponent + 1.0)

    def penetration(self, force: np.ndarray) -> np.ndarray:
        """Static penetration (m) under a force ≥ 0 (N)."""
        return (np.maximum(force, 0.0) / self.stiffness) ** (1.0 / self.exponent)


class Groove(NamedTuple):
    """Level-0 follower law ψ_k(φ) and its φ-derivatives (rad, per rad), lever ℓ = B_R × n (m) and dℓ/dφ."""

    psi: np.ndarray
    psi_p: np.ndarray
    psi_pp: np.ndarray
    lever: np.ndarray
    lever_p: np.ndarray
    rising: np.ndarray  # the cam program is in a rise (s' > 0): the insertion window may be open


def groove(mech: "PinInsertionMechanism", phi: np.ndarray) -> Groove:
    """Pitch-curve geometry at cam angles ``phi``: the contact normal n is that of the relative path of B_R on
    the cam, tangent t = dB_R/dφ − d·J·w (w = B_R − A0), as in level 1; ℓ = |B_R·t|/|t| and dℓ/dφ exactly
    (:func:`rig.plants.cam_bar.level2_kernel.groove`)."""
    rows = kernel.grooves(np.asarray(phi, dtype=float).ravel(), kernel.pack(mech))
    shape = np.shape(phi)
    return Groove(*(r.reshape(shape) for r in rows[:5]), rows[5].reshape(shape) != 0.0)


class _LoadView:
    """The mechanism as the level-1 free-body solution sees it in level 2: the guide friction as the kernel had it
    (per sample an effective coefficient: μ·tanh(|ṡ|/v_s) regularised, or the held / slipping force of the
    stick–slip guide) and the insertion force of the kernel (the law of the actual stroke while the cam is in its
    rise; level 1 keys it on the prescribed s' > 0, which the vibrating gripper would toggle)."""

    def __init__(self, mech: "PinInsertionMechanism", mu: np.ndarray, f_c: np.ndarray):
        self._mech, self.mu, self._f_c = mech, mu, f_c

    def __getattr__(self, name: str):
        return getattr(self._mech, name)

    def insertion_force(self, s: np.ndarray, s_p: np.ndarray) -> np.ndarray:
        return self._f_c


class Dynamics(NamedTuple):
    """Everything the model computes at some samples (SI): the kernel's quantities
    (:data:`rig.plants.cam_bar.level2_kernel.OUTPUTS`) and the level-1 loads and state of the actual motion."""

    phi: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    psi: np.ndarray
    psi_d: np.ndarray
    psi_dd: np.ndarray
    e_dd: np.ndarray
    F_w: np.ndarray
    F_o: np.ndarray
    drive_torque: np.ndarray
    p_dissipated: np.ndarray
    delta_w: np.ndarray
    delta_o: np.ndarray
    omega_m: np.ndarray
    shaft_torque: np.ndarray
    loads: Kinetostatics
    state: "State"


@dataclass
class Level2Run:
    """An integration of level 2: the solver's solution, the flank switches (``Event`` kind "flank_switch",
    data ``phi`` (rad, wrapped), ``to``: contact arrives on the other flank than the last one), the contact
    onsets on either flank (``impacts``, times in s), the contact losses (``releases``: (time, flank)), the flank
    last in contact and the bounces (``Event`` kind "flank_bounce", data ``phi``, ``flank``, ``left_phi``,
    ``flight``: the roller left its flank and struck the same one again, a jump without a switch) and, with a cam
    drive, the cam's stalls (:func:`stalls`, at the solution's samples)."""

    solution: Solution
    switches: list[Event]
    impacts: list[float]
    releases: list[tuple[float, str]]
    flank: str
    bounces: list[Event] = field(default_factory=list)
    stalls: list[Event] = field(default_factory=list)

    @property
    def events(self) -> list[Event]:
        """Switches, bounces and cam stalls in time order."""
        return sorted(self.switches + self.bounces + self.stalls, key=lambda e: e.time)


def stalls(t: np.ndarray, omega: np.ndarray, phi: np.ndarray, before: float) -> list[Event]:
    """A ``cam_stalled`` event (data ``phi`` rad, ``omega`` rad/s) at each sample ``t`` (s) where a driven cam, having
    turned forwards (``before``: its speed at the sample before the first), stops or turns back, or, at rest, starts
    turning back (a motor that cannot start it: the mechanism's torque drives it backwards from its start, an audit's
    drive of 0.05 N·m at 100°): the motor cannot carry the mechanism over its peak drive torque (its pull-out torque,
    or the start-up's, too low) — the run goes on, but not at the speed its scene says."""
    prev = np.r_[before, omega][:-1]
    return [Event(float(t[k]), "cam_stalled", {"phi": float(phi[k]), "omega": float(omega[k])})
            for k in np.flatnonzero(((prev > 0.0) & (omega <= 0.0)) | ((prev == 0.0) & (omega < 0.0)))]


@dataclass
class Level2:
    """Follower dynamics of a :class:`PinInsertionMechanism` with groove clearance ``mech.clearance``, its cam
    turned by ``speed`` (:mod:`rig.motion.speed`).

    ``model`` holds the level's assumptions that are not the machine (:mod:`.level2_model`: contact damping,
    slider-guide friction model); ``contact`` defaults to :meth:`ContactLaw.steel_line` (``mech.roller_width``,
    ``model.contact_damping``);
    ``energy`` appends the work/dissipation quadratures to the state; ``friction_speed`` v_s (m/s) regularises the
    guide friction (Coulomb friction would chatter while the gripper rings at rest); a penetration beyond
    ``max_penetration`` (m) raises :class:`SolverDivergence` naming time, cam angle and state.

    ``cam_drive`` (default ``mech.cam_drive``) makes the cam angle and speed states driven by a motor through a
    compliant shaft (:mod:`rig.plants.cam_bar.drive`): y = (e, τ·ė, φ, ω, φ_m, ω_m[, work quadratures]); without
    it the cam turns by the speed profile.

    ``rhs`` is the compiled right-hand side (:class:`~rig.solvers.JitRhs`: callable as ``rhs(t, y) -> tuple``,
    e.g. for scipy) with its event kernel; ``params`` its parameter vector.
    """

    mech: "PinInsertionMechanism"
    speed: "SpeedProfile"
    contact: ContactLaw | None = None
    energy: bool = False
    max_penetration: float = 1e-4
    friction_speed: float = 1e-3
    cam_drive: "CamDrive | None" = None
    model: Level2Model = field(default_factory=Level2Model)

    def __post_init__(self) -> None:
        mech = self.mech
        if self.cam_drive is None:
            self.cam_drive = mech.cam_drive
        if self.contact is None:
            self.contact = ContactLaw.steel_line(mech.roller_width, self.model.contact_damping)
        if not self.friction_speed > 0.0:
            raise ValueError(f"friction_speed must be positive, got {self.friction_speed!r} m/s")
        law = self.contact
        self.params = kernel.pack(mech, self.speed, law.stiffness, law.exponent, law.damping, self.max_penetration,
                                  self.friction_speed, self.cam_drive, self.model.guide)
        self.rhs = JitRhs(kernel.rhs, self._sync, self._diagnose, kernel.event_value, kernel.event_action)

    def _sync(self) -> np.ndarray:
        """The parameter vector with the jam record (the latest NaN's, when it was a jam) cleared."""
        self.params[kernel.JAM_T] = math.nan
        return self.params

    def _diagnose(self) -> str | None:
        """Why the kernel returned NaN, when it knows: a jammed slider guide."""
        t, phi = self.params[kernel.JAM_T], self.params[kernel.JAM_PHI]
        if math.isnan(t):
            return None
        return (f"no consistent friction state in the slider guide at t = {t:.9g} s, cam angle "
                f"φ = {math.degrees(phi):.6g}° (μ = {self.mech.mu:g}: the slider self-locks)")

    def _event(self, k: int):
        """Event function k of the compiled event kernel."""
        value, p = kernel.event_value, self.params
        return lambda t, y: value(t, np.asarray(y, dtype=float), p, k)

    # ---- ODE -----------------------------------------------------------------------------------------------
    def initial_state(self, t0: float) -> tuple:
        """Quasi-static start at ``t0``: the roller pressed into the flank that carries the level-1 contact
        force (penetration from the contact law), moving with the level-0 law (ė = 0). With a cam drive the cam
        starts at the speed profile's φ0, at rest or at its nominal speed (``start``), the shaft twisted by the
        quasi-static drive torque."""
        drive = self.cam_drive
        if drive is None:
            phi, omega, alpha = kernel.drive(t0, self.params)
        else:
            phi, alpha = self.speed.phi0, 0.0
            omega = 0.0 if drive.start == "rest" else self.speed.nominal_omega
        mech = self.mech
        ks = mech.kinetostatics(np.array([phi]), omega, alpha)
        force = float(ks.R23n[0])
        lever = kernel.groove(phi, self.params)[3]
        delta = float(self.contact.penetration(abs(force)))
        e = -delta / lever if force >= 0.0 else (mech.clearance + delta) / lever
        y = (e, 0.0)
        if drive is not None:
            torque = float(ks.drive_torque[0])
            y += (phi, omega, phi + torque / drive.shaft_stiffness, omega)
        if mech.joints is not None:           # the pins bear as the level-1 rod force says: |CD| − l4 ≈ −z·cos ϑ
            ct = float(mech.state(np.array([phi])).trig.ct[0])
            y += (-mech.joints.stretch(float(ks.rod_tension[0])) / ct, 0.0)
        return y + (0.0, 0.0, 0.0) if self.energy else y

    def cam_angle(self, t: float, y: tuple) -> float:
        """Cam angle φ (rad) at time ``t`` and state ``y``."""
        return kernel.cam_angle(t, np.asarray(y, dtype=float), self.params)

    def flank_of(self, t: float, y: tuple) -> str:
        """Flank the roller is nearer to."""
        lever = kernel.geometry_at(t, np.asarray(y, dtype=float), self.params)[0]
        return "working" if y[0] * lever < 0.5 * self.mech.clearance else "other"

    def overload(self, t: float, y: tuple) -> str:
        """What the terminal "overload" event at (t, y) means: where, and the likely causes with the fix."""
        if self.mech.joints is not None:
            yy = np.asarray(y, dtype=float)
            psi = kernel.geometry_at(t, yy, self.params)[1] + yy[0]
            pins = kernel.pin_penetration(psi, yy[kernel.joint_index(self.params)], self.params)
            if pins > self.max_penetration:
                phi = math.degrees(self.cam_angle(t, y))
                return (f"the rod's pins penetrate their bores by {pins * 1e3:.3g} mm (more than "
                        f"{self.max_penetration * 1e3:g} mm) at cam angle φ = {phi:.6g}° (pin stiffness too low, or "
                        f"the solution diverged: with a fixed-step explicit method reduce h or use Rodas4)")
        return (f"roller penetrates a flank by more than {self.max_penetration * 1e3:g} mm at cam angle "
                f"φ = {math.degrees(self.cam_angle(t, y)):.6g}° (contact stiffness too low, or the solution diverged: "
                f"with a fixed-step explicit method reduce h or use Rodas4)")

    def _diverged(self, t: float, y: tuple) -> SolverDivergence:
        return SolverDivergence(self.overload(t, y), t, y)

    def problem(self, y0: tuple) -> Problem:
        """The ODE with contact events "working" / "other" (penetration of that flank changes sign: sign +1 onset,
        −1 release; restarts, since the contact force's derivatives jump there), a terminal "overload" (penetration
        beyond ``max_penetration``), "insertion" (F_c switches: restart) and, with the pin joints, "pins" (the
        pins start or stop bearing: restart), in the order of the event kernel."""
        events = [SolverEvent(self._event(kernel.WORKING), "working", restart=True),
                  SolverEvent(self._event(kernel.OTHER), "other", restart=True),
                  SolverEvent(self._event(kernel.OVERLOAD), "overload", direction=1.0, terminal=True),
                  SolverEvent(self._event(kernel.INSERTION), "insertion", restart=True, mode_dependent=True)]
        if self.mech.joints is not None:
            events.append(SolverEvent(self._event(kernel.PINS), "pins", restart=True))
        return Problem(self.rhs, y0, events, time_breaks=self.program_breaks, positions=self.positions(len(y0)))

    def positions(self, n: int) -> tuple[int, ...]:
        """Indices of the positions in a state of ``n`` components (:meth:`initial_state`'s layout): e, the cam's and
        the motor's angles, the slider's z; the energy integrals drift with them (symplectic Euler's kick–drift
        split; the others are rates)."""
        q = [0]
        k = 2
        if self.cam_drive is not None:
            q += [2, 4]
            k = 6
        if self.mech.joints is not None:
            q.append(k)
            k += 2
        return tuple(q + list(range(k, n)))

    def program_breaks(self, t0: float, tf: float) -> list[float]:
        """Times in (t0, tf) (s) at which a cam turned at constant speed passes a boundary of its program's
        segments or motion-law pieces — where ψ_k'' and so the RHS's derivatives jump: the solvers restart
        there instead of rejecting steps across it. None for other speed profiles or a driven cam (the
        boundaries then depend on the state)."""
        p = self.params
        if self.cam_drive is not None or p[kernel.SPEED] != kernel.CONSTANT or not p[kernel.SP1] > 0.0:
            return []
        phi0, omega = p[kernel.PHI0], p[kernel.SP1]
        first, last = math.floor((phi0 + omega * t0) / math.tau), math.ceil((phi0 + omega * tf) / math.tau)
        angles = np.add.outer(math.tau * np.arange(first, last + 1), self._boundaries).ravel()
        times = (angles - phi0) / omega
        return times[(times > t0) & (times < tf)].tolist()

    @cached_property
    def _boundaries(self) -> np.ndarray:
        """Cam angles in [0, 2π) of the program's segment and law-piece boundaries (rad)."""
        p, out = self.params, []
        for i in range(int(p[kernel.NSEG])):
            r = kernel.PROGRAM + kernel.SEG_ROW * i
            start, angle, at = p[r], p[r + 1], int(p[r + 4])
            out.append(start)
            if p[at] == kernel.SINE_PIECES:
                out += [start + angle * p[at + 2 + kernel.PIECE * k] for k in range(1, int(p[at + 1]))]
        return np.unique(np.mod(out, math.tau))

    def simulate(self, t_span: tuple[float, float], y0: tuple | None = None, flank: str | None = None,
                 method: str | type[OdeSolver] = METHOD, t_eval=None, **options) -> Level2Run:
        """Integrate over ``t_span`` (s) from ``y0`` (default: :meth:`initial_state`) with ``method`` (a name of
        :data:`rig.solvers.METHODS` or a solver class; compiled steps); ``flank`` is the flank in contact at the
        start (default: nearer). ``options`` go to the solver (rtol, atol or h, ...). The stiffness report of the
        explicit 5(4) pairs (DP45, Tsit5) is off unless asked for (``stiffness="warn"``): on the contact they are
        stability-limited (h·|λ| ≈ 3.3–3.5) and still the fastest methods at 1e-6 (docs/cam-bar.md)."""
        if method in ("DP45", "Tsit5"):
            options.setdefault("stiffness", "ignore")
        t0 = float(t_span[0])
        y0 = self.initial_state(t0) if y0 is None else tuple(y0)
        flank = self.flank_of(t0, y0) if flank is None else flank
        if self._event(kernel.OVERLOAD)(t0, y0) > 0.0:
            raise self._diverged(t0, y0)
        sol = integrate(self.problem(y0), (t0, float(t_span[1])), method=method, t_eval=t_eval, **options)
        if sol.status == "terminated":
            raise self._diverged(sol.t_final, sol.y_final)
        switches, impacts, releases, bounces = [], [], [], []
        left: dict[str, Any] = {}               # the latest release of each flank (the roller leaving it)
        for rec in sol.events:
            if rec.name not in ("working", "other"):
                continue
            if rec.sign < 0.0:
                releases.append((rec.t, rec.name))
                left[rec.name] = rec
                continue
            impacts.append(rec.t)
            off = left.pop(flank, None) if flank is not None else None    # its flight began there
            data = {"phi": self.cam_angle(rec.t, rec.y) % math.tau}
            if off is not None:                 # where it left the flank it was on: level 1's sign change
                data.update(left_phi=self.cam_angle(off.t, off.y) % math.tau, flight=rec.t - off.t)
            if rec.name != flank:
                flank = rec.name
                switches.append(Event(rec.t, "flank_switch", {**data, "to": rec.name}))
            else:                               # back on the flank it left (in this run or an earlier chunk)
                bounces.append(Event(rec.t, "flank_bounce", {**data, "flank": rec.name}))
        stalled = [] if self.cam_drive is None else stalls(sol.t, sol.y[3], sol.y[2], float(y0[3]))
        return Level2Run(sol, switches, impacts, releases, flank, bounces, stalled)

    # ---- outputs -------------------------------------------------------------------------------------------
    def evaluate(self, t: np.ndarray, y: np.ndarray) -> Dynamics:
        """All dynamic quantities at times ``t`` (s) for states ``y`` (rows as in the ODE state): the kernel's
        (:func:`rig.plants.cam_bar.level2_kernel.evaluate`) and the level-1 free-body solution of the actual
        motion (the insertion force and regularised guide friction as in the kernel)."""
        t = np.asarray(t, dtype=float)
        y = np.asarray(y, dtype=float)
        y = y if y.ndim == 2 else y.reshape(-1, 1)
        out = dict(zip(kernel.OUTPUTS, kernel.evaluate(t, y, self.params)))
        mech = self.mech
        from rig.plants.cam_bar.mechanism import State
        phi = out["phi"]
        w = np.where(np.abs(out["omega"]) < 1e-6, 1e-6, out["omega"])   # cam at rest (drive start-up): φ-rates
        a = mech.chain.angles(out["s"], phi) if mech.joints is None else self._rod_angles(out["psi"], out["s"])
        nan = np.full_like(phi, np.nan)       # r', r'' are not used by the kinetostatics
        st = State(phi, w, np.zeros_like(w), out["s"], out["s_d"] / w, out["s_dd"] / w ** 2, a.psi, out["psi_d"] / w,
                   out["psi_dd"] / w ** 2, a.theta, out["theta_d"] / w, out["theta_dd"] / w ** 2,
                   np.hypot(*mech._pitch(a.psi)), nan, nan, a)
        loads = solve(_LoadView(mech, out["mu"], out["F_c"]), st, mech.k)
        if mech.joints is not None:           # the rod force is the pins', the cam moment the contacts'
            tension, m_sigma = out["rod_tension"], out["cam_moment"]
            loads = replace(loads, rod_tension=tension, F_rod=tension + mech.sensor_preload, M_sigma=m_sigma,
                            M23=m_sigma - loads.M_e)
        return Dynamics(*(out[k] for k in Dynamics._fields[:13]), out["omega_m"], out["shaft_torque"], loads, st)

    def _rod_angles(self, psi: np.ndarray, s: np.ndarray) -> "Angles":
        """ψ and the rod's angle ϑ from the pins' actual places (follower at ψ, slider at stroke s: the rod
        through its clearances, not the rigid chain)."""
        mech = self.mech
        cp, sp = np.cos(psi), np.sin(psi)
        theta = np.arctan2(mech.e_sk - mech.L3 * sp, mech.s0 - s - mech.L3 * cp)
        ct, st = np.cos(theta), np.sin(theta)
        return Angles(psi, theta, cp, sp, ct, st, st * cp - ct * sp)

    def signals(self, t: np.ndarray, y: np.ndarray) -> dict[str, np.ndarray]:
        """Truth signals (SI) with the keys of level 1; ``R23`` = F_w − F_o (N, > 0 on the working flank);
        extra: ``psi_kin`` (level-0 ψ), ``delta_w``/``delta_o`` (penetrations, m, negative = gap), ``motor_speed``
        (rad/s, cam-shaft referred; the cam speed without a drive) and ``shaft_torque`` (N·m; 0 without a drive).
        With rod pin clearances (``mech.joints``, :mod:`.joints`) ``s``, ``v``, ``a`` and ``x_gripper`` are the slider's
        own motion and ``rod_tension``/``F_rod`` the pins' force."""
        dy = self.evaluate(t, y)
        st, ks = dy.state, dy.loads
        mech = self.mech
        m_e = mech.spring_moment(dy.psi)
        m_sigma = ks.M_sigma
        s = st.s
        return {"t": np.asarray(t, float), "phi": dy.phi, "cam_angle": np.mod(dy.phi, math.tau), "omega": dy.omega,
                "alpha": dy.alpha, "s": s, "v": st.s_d, "a": st.s_dd, "x_gripper": mech.s0 - s,
                "psi": dy.psi, "theta": st.theta, "r": st.r, "F_rod": ks.F_rod, "rod_tension": ks.rod_tension,
                "R23": dy.F_w - dy.F_o, "M23": m_sigma - m_e, "M_e": m_e, "M_sigma": m_sigma,
                "drive_torque": dy.drive_torque, "F_c": ks.F_c, "pressure_angle": ks.pressure_angle,
                "psi_kin": dy.psi - np.asarray(y[0], float), "delta_w": dy.delta_w, "delta_o": dy.delta_o,
                "motor_speed": dy.omega_m, "shaft_torque": dy.shaft_torque}

    def energies(self, t: np.ndarray, y: np.ndarray) -> dict[str, np.ndarray]:
        """Kinetic energy of follower, rod and slider, potentials of gravity, spring and contacts (J); with the
        rod's pin joints the rod's halves move with the follower and the slider (:mod:`.joints`) and the pins'
        elastic energy is part of ``contact``."""
        mech = self.mech
        dy = self.evaluate(t, y)
        st = dy.state
        a = st.trig
        psi_d, th_d = dy.psi_d, st.theta_d
        dpsi = dy.psi - mech.psi0
        spring = mech.Me_0 * dpsi + 0.5 * mech.k * mech.l_F ** 2 * dpsi ** 2
        contact = self.contact.energy(dy.delta_w) + self.contact.energy(dy.delta_o)
        joints = mech.joints
        if joints is not None:
            half = 0.5 * mech.m4
            kinetic = 0.5 * ((mech.J3 + half * mech.L3 ** 2) * psi_d ** 2 + (mech.m5 + half) * st.s_d ** 2)
            gravity = mech.g * (mech.m3 * mech.a3 + half * mech.L3) * a.sp
            z = np.asarray(y, dtype=float)[kernel.joint_index(self.params)]
            beyond = np.array([kernel.pin_penetration(float(psi), float(zi), self.params)   # the kernel's own δ
                               for psi, zi in zip(dy.psi, z)])
            pins = 0.5 * joints.stiffness * np.maximum(beyond, 0.0) ** 2
            return {"kinetic": kinetic, "gravity": gravity, "spring": spring, "contact": contact + pins}
        vcx, vcy = -mech.L3 * a.sp * psi_d, mech.L3 * a.cp * psi_d
        vgx = vcx + 0.5 * (-st.s_d - vcx)
        vgy = 0.5 * vcy
        kinetic = 0.5 * (mech.J3 * psi_d ** 2 + mech.m4 * (vgx ** 2 + vgy ** 2) + mech.J4 * th_d ** 2
                         + mech.m5 * st.s_d ** 2)
        gravity = mech.g * (mech.m3 * mech.a3 * a.sp + mech.m4 * (mech.L3 * a.sp + 0.5 * mech.l4 * a.st))
        return {"kinetic": kinetic, "gravity": gravity, "spring": spring, "contact": contact}

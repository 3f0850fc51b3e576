"""Level-2 dynamics of the pin-insertion mechanism (MODELS §3.4): the follower as a DOF in a groove with clearance.

The roller centre B_R sits between two flanks. Its offset from the level-0 pitch curve along the contact
normal n (oriented as in level 1, B_R × n = ℓ > 0) is u = ℓ(φ)·e with e = ψ − ψ_k(φ) the follower's deviation
from the level-0 law ψ_k (first order in e: |e| ≲ 1e-3 rad, curvature terms ~ c²/ρ are dropped). The working
flank (pushes towards larger ψ) sits at u = 0, the other one at u = c; penetrations are δ_w = −u and
δ_o = u − c, each with the compliant contact of :class:`ContactLaw`. The rod and slider follow ψ through the
level-0 chain; spring, gravity, guide friction, insertion force and the inertia of all links come from the
level-1 free-body solution (:func:`rig.plants.cam_bar.kinetostatics.solve`) evaluated on the *actual* motion,
which gives the cam moment M_Σ needed for an acceleration ψ̈. It is affine in ψ̈ on each friction branch,
so M_Σ(ψ̈) = ℓ·(F_w − F_o) is solved exactly. The cam turns by the mechanism's speed profile.

State ``y = (e, τ·ė)`` (rad, τ = 1 ms so both components are angles and the error control sees the small
deviation, not ψ ≈ 1.5 rad), optionally followed by the work of the cam drive, of the insertion force and
guide friction, and the energy dissipated in the contacts (J).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from rig.plants.cam_bar.chain import SingularPositionError
from rig.plants.cam_bar.kinetostatics import JammingError, Kinetostatics, solve
from rig.plants.events import Event
from rig.solvers import Event as SolverEvent
from rig.solvers import Problem, Rosenbrock23, Solution, SolverDivergence, integrate

if TYPE_CHECKING:
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism, State

TAU = 1e-3  # s, scale of the velocity state
PALMGREN = 3.84e-5  # steel line contact, approach δ = 3.84e-5·Q^0.9/l^0.8 (δ, l in mm, Q in N)
MAX_BRANCH_ITER = 4


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
    the cam, tangent t = dB_R/dφ − d·J·w (w = B_R − A0), as in level 1; ℓ = |B_R·t|/|t| and dℓ/dφ exactly."""
    st = mech.state(phi)
    cp, sp, pp, ppp = st.trig.cp, st.trig.sp, st.psi_p, st.psi_pp
    d, l3 = mech.cam_direction, mech.l3
    bx, by = l3 * cp, l3 * sp
    wx, wy = bx - mech.x_A0, by - mech.y_A0
    dbx, dby = -l3 * sp * pp, l3 * cp * pp
    tx, ty = dbx + d * wy, dby - d * wx
    dtx = -l3 * (cp * pp ** 2 + sp * ppp) + d * dby
    dty = l3 * (cp * ppp - sp * pp ** 2) - d * dbx
    lev = bx * tx + by * ty
    dlev = dbx * tx + dby * ty + bx * dtx + by * dty
    tn = np.hypot(tx, ty)
    dtn = (tx * dtx + ty * dty) / tn
    sgn = np.sign(lev)
    return Groove(st.psi, pp, ppp, sgn * lev / tn, sgn * (dlev / tn - lev * dtn / tn ** 2), st.s_p > 0.0)


class _LoadView:
    """The mechanism as the level-1 free-body solution sees it in level 2: guide friction regularised to
    μ·tanh(|ṡ|/v_s) (per sample) and the insertion force acting while the cam is in its rise and the actual
    stroke is within ``F_c_travel`` of the top (level 1 keys it on the prescribed s' > 0, which the vibrating
    gripper would toggle)."""

    def __init__(self, mech: "PinInsertionMechanism", mu: np.ndarray, f_c: np.ndarray):
        self._mech, self.mu, self._f_c = mech, mu, f_c

    def __getattr__(self, name: str):
        return getattr(self._mech, name)

    def insertion_force(self, s: np.ndarray, s_p: np.ndarray) -> np.ndarray:
        return self._f_c


class Dynamics(NamedTuple):
    """Everything the right-hand side computes at some samples (SI)."""

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
    loads: Kinetostatics | None
    state: "State | None"


@dataclass
class Level2Run:
    """An integration of level 2: the solver's solution, the flank switches (``Event`` kind "flank_switch",
    data ``phi`` (rad, wrapped), ``to``: contact arrives on the other flank than the last one), the contact
    onsets on either flank (``impacts``, times in s), the contact losses (``releases``: (time, flank)) and the
    flank last in contact."""

    solution: Solution
    switches: list[Event]
    impacts: list[float]
    releases: list[tuple[float, str]]
    flank: str


@dataclass
class Level2:
    """Follower dynamics of a :class:`PinInsertionMechanism` with groove clearance ``mech.clearance``.

    ``contact`` defaults to :meth:`ContactLaw.steel_line` (``mech.roller_width``, ``mech.contact_damping``);
    ``energy`` appends the work/dissipation quadratures to the state; ``friction_speed`` v_s (m/s) regularises the
    guide friction (Coulomb friction would chatter while the gripper rings at rest); a penetration beyond
    ``max_penetration`` (m) raises :class:`SolverDivergence` naming time, cam angle and state.
    """

    mech: "PinInsertionMechanism"
    contact: ContactLaw | None = None
    energy: bool = False
    max_penetration: float = 1e-4
    friction_speed: float = 1e-3
    _cache: tuple = field(default=(math.nan, None), init=False, repr=False)

    def __post_init__(self) -> None:
        mech = self.mech
        if self.contact is None:
            self.contact = ContactLaw.steel_line(mech.roller_width, mech.contact_damping)
        if not self.friction_speed > 0.0:
            raise ValueError(f"friction_speed must be positive, got {self.friction_speed!r} m/s")
        ends = mech.program.starts + [seg.angle for seg in mech.program.segments]
        self._rises = [(a, b) for a, b, seg in zip(mech.program.starts, ends, mech.program.segments)
                       if seg.kind == "rise"]
        self._psi_pierce = float(mech.kinematics(mech.program.levels[1] - mech.F_c_travel).psi)

    def _window(self, t: float, y: tuple) -> float:
        """> 0 while the insertion force acts (cam in a rise, ψ past the pierce point), < 0 otherwise (rad)."""
        phi, _, _, geo = self._groove_at(t)
        phi_m = float(phi[0]) % math.tau
        inside = max((min(phi_m - a, b - phi_m) for a, b in self._rises), default=-1.0)
        return min(inside, float(geo.psi[0]) + y[0] - self._psi_pierce)

    # ---- geometry and loads ----------------------------------------------------------------------------------
    def _groove_at(self, t: float) -> tuple:
        """(φ, ω, α, Groove) at one time, cached for the last time asked (RHS and events share it)."""
        if self._cache[0] != t:
            dr = self.mech.speed.drive(np.array([t]))
            self._cache = (t, (dr.phi, dr.omega, dr.alpha, groove(self.mech, dr.phi)))
        return self._cache[1]

    def _state(self, phi, omega, psi, psi_d, psi_dd) -> "State":
        """Level-1 :class:`State` of the actual motion (derivatives w.r.t. cam angle = time rates / ω)."""
        from rig.plants.cam_bar.mechanism import State
        mech = self.mech
        s = mech.chain.slider(psi)
        a = mech.chain.angles(s, phi)
        one = np.ones_like(s)
        psi_s, psi_ss, th_s, th_ss = mech.chain.derivatives(a, one, np.zeros_like(s))   # d/ds
        s_psi = 1.0 / psi_s
        s_d = s_psi * psi_d
        s_dd = s_psi * psi_dd - psi_ss * s_psi ** 3 * psi_d ** 2
        th_d, th_dd = th_s * s_d, th_ss * s_d ** 2 + th_s * s_dd
        w, w2 = omega, omega ** 2
        r = np.hypot(*mech._pitch(a.psi))
        nan = np.full_like(s, np.nan)  # r', r'' are not used by the kinetostatics
        return State(phi, w, np.zeros_like(w), s, s_d / w, s_dd / w2, a.psi, psi_d / w, psi_dd / w2, a.theta, th_d / w,
                     th_dd / w2, r, nan, nan, a)

    def _loads(self, st: "State", rising: np.ndarray) -> Kinetostatics:
        """Level-1 free-body solution of the motion ``st`` (see :class:`_LoadView`)."""
        mech = self.mech
        mu = mech.mu * np.tanh(np.abs(st.s_d) / self.friction_speed)
        f_c = np.where(rising & (st.s >= mech.program.levels[1] - mech.F_c_travel), mech.F_c, 0.0)
        return solve(_LoadView(mech, mu, f_c), st, mech.k)

    def _acceleration(self, phi, omega, psi, psi_d, rising, moment) -> np.ndarray:
        """ψ̈ with M_Σ(ψ̈) = ``moment``: two trial accelerations per sample, exact on a friction branch; repeated
        from the solution where the guide normal force changed sign in between."""
        guess = np.zeros_like(psi)
        rep = lambda v: np.concatenate([v, v])  # noqa: E731
        for _ in range(MAX_BRANCH_ITER):
            trial = np.concatenate([guess, guess + 1.0])
            ks = self._loads(self._state(rep(phi), rep(omega), rep(psi), rep(psi_d), trial), rep(rising))
            n = psi.size
            m0, m1 = ks.M_sigma[:n], ks.M_sigma[n:]
            n0, n1 = ks.R15.y[:n], ks.R15.y[n:]
            acc = guess + (moment - m0) / (m1 - m0)
            n_acc = n0 + (n1 - n0) * (acc - guess)
            same = (np.sign(n0) == np.sign(n1)) & (np.sign(n_acc) == np.sign(n0))
            if same.all():
                return acc
            guess = np.where(same, guess, acc)
        i = int(np.argmin(same))
        raise JammingError(f"no consistent friction state in the slider guide at cam angle "
                           f"φ = {math.degrees(float(phi[i])):.4g}° (ψ = {math.degrees(float(psi[i])):.6g}°)")

    def dynamics(self, phi, omega, alpha, geo: Groove, e, e_d, loads: bool = True) -> Dynamics:
        """All dynamic quantities for deviations ``e`` (rad), ``e_d`` (rad/s) at cam angles ``phi``; without
        ``loads`` the final level-1 evaluation at the found ψ̈ is skipped (``loads``, ``state`` are None)."""
        mech, law = self.mech, self.contact
        psi = geo.psi + e
        psi_d = omega * geo.psi_p + e_d
        u = geo.lever * e
        u_d = geo.lever_p * omega * e + geo.lever * e_d
        d_w, d_o = -u, u - mech.clearance
        f_w, f_o = law.force(d_w, -u_d), law.force(d_o, u_d)
        psi_dd = self._acceleration(phi, omega, psi, psi_d, geo.rising, geo.lever * (f_w - f_o))
        e_dd = psi_dd - omega ** 2 * geo.psi_pp - alpha * geo.psi_p
        dd_w = -geo.lever_p * e + geo.lever * geo.psi_p  # ∂δ_w/∂φ at fixed ψ; ∂δ_o/∂φ = −that
        drive = (f_w - f_o) * dd_w
        p_diss = (f_w - law.elastic(d_w)) * -u_d + (f_o - law.elastic(d_o)) * u_d
        st = self._state(phi, omega, psi, psi_d, psi_dd) if loads else None
        return Dynamics(phi, omega, alpha, psi, psi_d, psi_dd, e_dd, f_w, f_o, drive, p_diss, d_w, d_o,
                        self._loads(st, geo.rising) if loads else None, st)

    # ---- ODE -----------------------------------------------------------------------------------------------
    def _derivatives(self, phi, omega, alpha, geo: Groove, y: np.ndarray) -> np.ndarray:
        """d/dt of the state columns ``y`` (n × m) at m samples."""
        dy = self.dynamics(phi, omega, alpha, geo, y[0], y[1] / TAU, self.energy)
        rows = [y[1] / TAU, TAU * dy.e_dd]
        if self.energy:
            rows += [dy.drive_torque * omega, -(dy.loads.F_c + dy.loads.friction) * dy.state.s_d, dy.p_dissipated]
        return np.array(rows)

    def rhs(self, t: float, y: tuple) -> tuple:
        """d/dt of (e, τ·ė[, W_drive, W_load, E_dissipated]); NaN for a non-finite state or one the chain cannot
        assemble (a solver's trial stage far off: the step is rejected; a solution that goes there ends in a
        step-size underflow, reported as :class:`SolverDivergence`). A jammed slider guide raises
        :class:`SolverDivergence` naming time and state."""
        if not math.isfinite(sum(y)):
            return (math.nan,) * len(y)
        phi, omega, alpha, geo = self._groove_at(t)
        try:
            return tuple(self._derivatives(phi, omega, alpha, geo, np.array(y)[:, None])[:, 0].tolist())
        except SingularPositionError:
            return (math.nan,) * len(y)
        except JammingError as exc:
            raise SolverDivergence(str(exc), t, y) from None

    def jacobian(self, t: float, y: tuple, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """∂f/∂y and ∂f/∂t by forward differences, all perturbed states in one vectorised evaluation
        (the ``jac`` option of :class:`~rig.solvers.implicit.Rosenbrock23`)."""
        n = len(y)
        base = np.array(y)
        step = np.sqrt(np.finfo(float).eps) * np.maximum(np.abs(base), 1e-5)
        cols = np.repeat(base[:, None], n + 1, axis=1)
        cols[np.arange(n), np.arange(n)] += step
        dt = 1e-8 * max(1.0, abs(t))
        ts = np.full(n + 1, t)
        ts[n] += dt
        dr = self.mech.speed.drive(ts)
        out = self._derivatives(dr.phi, dr.omega, dr.alpha, groove(self.mech, dr.phi), cols)
        return (out[:, :n] - f[:, None]) / step, (out[:, n] - f) / dt

    def initial_state(self, t0: float) -> tuple:
        """Quasi-static start at ``t0``: the roller pressed into the flank that carries the level-1 contact
        force (penetration from the contact law), moving with the level-0 law (ė = 0)."""
        phi, omega, alpha, geo = self._groove_at(t0)
        force = float(self.mech.kinetostatics(phi, omega, alpha).R23n[0])
        lever = float(geo.lever[0])
        delta = float(self.contact.penetration(abs(force)))
        e = -delta / lever if force >= 0.0 else (self.mech.clearance + delta) / lever
        return (e, 0.0, 0.0, 0.0, 0.0) if self.energy else (e, 0.0)

    def flank_of(self, t: float, y: tuple) -> str:
        """Flank the roller is nearer to."""
        lever = float(self._groove_at(t)[3].lever[0])
        return "working" if y[0] * lever < 0.5 * self.mech.clearance else "other"

    def _overload(self, t: float, y: tuple) -> float:
        """Penetration of either flank minus ``max_penetration`` (m)."""
        u = y[0] * float(self._groove_at(t)[3].lever[0])
        return max(-u, u - self.mech.clearance) - self.max_penetration

    def _diverged(self, t: float, y: tuple) -> SolverDivergence:
        phi = float(self.mech.speed.drive(np.array([t])).phi[0])
        return SolverDivergence(f"roller penetrates a flank by more than {self.max_penetration * 1e3:g} mm at cam "
                                f"angle φ = {math.degrees(phi):.6g}° (contact stiffness too low or the solution "
                                f"diverged)", t, y)

    def problem(self, y0: tuple) -> Problem:
        """The ODE with contact events "working" / "other" (penetration of that flank changes sign: sign +1 onset,
        −1 release),
        a terminal "overload" (penetration beyond ``max_penetration``) and "insertion" (F_c switches: restart)."""
        def other(t: float, y: tuple) -> float:
            return y[0] - self.mech.clearance / float(self._groove_at(t)[3].lever[0])

        events = [SolverEvent(lambda t, y: -y[0], "working"), SolverEvent(other, "other"),
                  SolverEvent(self._overload, "overload", direction=1.0, terminal=True),
                  SolverEvent(self._window, "insertion", restart=True)]
        return Problem(self.rhs, y0, events)

    def simulate(self, t_span: tuple[float, float], y0: tuple | None = None, flank: str | None = None,
                 method=Rosenbrock23, t_eval=None, **options) -> Level2Run:
        """Integrate over ``t_span`` (s) from ``y0`` (default: :meth:`initial_state`) with ``method``
        (a solver class or "DP45"/"RK4"); ``flank`` is the flank in contact at the start (default: nearer)."""
        t0 = float(t_span[0])
        y0 = self.initial_state(t0) if y0 is None else tuple(y0)
        flank = self.flank_of(t0, y0) if flank is None else flank
        if self._overload(t0, y0) > 0.0:
            raise self._diverged(t0, y0)
        if method is Rosenbrock23:
            options.setdefault("jac", self.jacobian)
        sol = integrate(self.problem(y0), (t0, float(t_span[1])), method=method, t_eval=t_eval, **options)
        if sol.status == "terminated":
            raise self._diverged(sol.t_final, sol.y_final)
        switches, impacts, releases = [], [], []
        for rec in sol.events:
            if rec.name not in ("working", "other"):
                continue
            if rec.sign < 0.0:
                releases.append((rec.t, rec.name))
                continue
            impacts.append(rec.t)
            if rec.name != flank:
                flank = rec.name
                phi = float(self.mech.speed.drive(np.array([rec.t])).phi[0])
                switches.append(Event(rec.t, "flank_switch", {"phi": phi % math.tau, "to": flank}))
        return Level2Run(sol, switches, impacts, releases, flank)

    # ---- outputs -------------------------------------------------------------------------------------------
    def evaluate(self, t: np.ndarray, y: np.ndarray) -> Dynamics:
        """Vectorised :meth:`dynamics` at times ``t`` (s) for states ``y`` (rows as in the ODE state)."""
        t = np.asarray(t, dtype=float)
        dr = self.mech.speed.drive(t)
        geo = groove(self.mech, dr.phi)
        return self.dynamics(dr.phi, dr.omega, dr.alpha, geo, np.asarray(y[0], float), np.asarray(y[1], float) / TAU)

    def signals(self, t: np.ndarray, y: np.ndarray) -> dict[str, np.ndarray]:
        """Truth signals (SI) with the keys of level 1; ``R23`` = F_w − F_o (N, > 0 on the working flank);
        extra: ``psi_kin`` (level-0 ψ), ``delta_w``/``delta_o`` (penetrations, m, negative = gap)."""
        dy = self.evaluate(t, y)
        st, ks = dy.state, dy.loads
        mech = self.mech
        m_e = mech.spring_moment(dy.psi)
        m_sigma = ks.M_sigma
        return {"t": np.asarray(t, float), "phi": dy.phi, "cam_angle": np.mod(dy.phi, math.tau), "omega": dy.omega,
                "alpha": dy.alpha, "s": st.s, "v": st.s_d, "a": st.s_dd, "x_gripper": mech.s0 - st.s,
                "psi": dy.psi, "theta": st.theta, "r": st.r, "F_rod": ks.F_rod, "rod_tension": ks.rod_tension,
                "R23": dy.F_w - dy.F_o, "M23": m_sigma - m_e, "M_e": m_e, "M_sigma": m_sigma,
                "drive_torque": dy.drive_torque, "F_c": ks.F_c, "pressure_angle": ks.pressure_angle,
                "psi_kin": dy.psi - np.asarray(y[0], float), "delta_w": dy.delta_w, "delta_o": dy.delta_o}

    def energies(self, t: np.ndarray, y: np.ndarray) -> dict[str, np.ndarray]:
        """Kinetic energy of follower, rod and slider, potentials of gravity, spring and contacts (J)."""
        mech = self.mech
        dy = self.evaluate(t, y)
        st = dy.state
        a = st.trig
        psi_d, th_d = dy.psi_d, st.theta_d
        vcx, vcy = -mech.L3 * a.sp * psi_d, mech.L3 * a.cp * psi_d
        vgx = vcx + 0.5 * (-st.s_d - vcx)
        vgy = 0.5 * vcy
        kinetic = 0.5 * (mech.J3 * psi_d ** 2 + mech.m4 * (vgx ** 2 + vgy ** 2) + mech.J4 * th_d ** 2
                         + mech.m5 * st.s_d ** 2)
        gravity = mech.g * (mech.m3 * mech.a3 * a.sp + mech.m4 * (mech.L3 * a.sp + 0.5 * mech.l4 * a.st))
        dpsi = dy.psi - mech.psi0
        spring = mech.Me_0 * dpsi + 0.5 * mech.k * mech.l_F ** 2 * dpsi ** 2
        contact = self.contact.energy(dy.delta_w) + self.contact.energy(dy.delta_o)
        return {"kinetic": kinetic, "gravity": gravity, "spring": spring, "contact": contact}

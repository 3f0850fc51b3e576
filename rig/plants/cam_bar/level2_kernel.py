"""Compiled (numba) groove dynamics of the pin-insertion mechanism at level 2 (MODELS §3.4) — the one
implementation behind :class:`rig.plants.cam_bar.level2.Level2`: its right-hand side, its events and the
quantities its outputs are built from (:func:`evaluate`). Physics, symbols and sign conventions: the module
docstring of :mod:`rig.plants.cam_bar.level2`.

Everything the kernels need travels in one float64 vector ``p`` (indices below): chain geometry, masses,
spring, guide friction, insertion force, contact law, the cam-speed profile, the cam program as a segment
table with the motion laws' coefficients, one-entry caches of the groove geometry and of the distance into a rise
(keyed on the cam angle: a step's last stages, its end and the events share one cam angle), the first jam of the slider guide (for the diagnosis), and the optional models of issue 14: the pin's
force–travel law (:mod:`.insertion`), the stick–slip guide (:mod:`.guide_friction`) and the motor-driven cam
(:mod:`.drive`, states (φ, ω, φ_m, ω_m) after (e, τ·ė)) and the rod's pin clearances (:mod:`.joints`, the slider's
state (z, τ·ż) after those, solved by :func:`joint_body` instead of :func:`free_body`).

The free-body solution is in closed form: on the actual motion (ψ, ψ̇, ψ̈) the rod and slider follow ψ
through the level-0 chain, and every force of the level-1 free-body diagrams
(:mod:`rig.plants.cam_bar.kinetostatics`) is affine in ψ̈ on a friction branch of the slider guide (normal
force N ≥ 0 or N < 0). The cam moment is M_Σ(ψ̈) = M0 + M1·ψ̈; ℓ·(F_w − F_o) = M_Σ(ψ̈) gives ψ̈ directly. The
branch N ≥ 0 is taken when consistent, else N < 0; neither is a jam (self-locking guide).

The entry points the compiled solvers call (:func:`rhs`, :func:`event_value`, :func:`event_action`) are compiled
without numba's runtime (``_nrt=False``: no reference counts on their arrays, ≈ 5 % of a level-2 run; they allocate
nothing; see :mod:`rig.solvers.templates.runs`).

All compiled code of level 2 lives in this one module (numba's disk cache is invalidated by changes to a
function's own file only, not to the files of the functions it calls).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from rig.motion.laws import PiecewiseSineLaw, PolynomialLaw
from rig.motion.registry import get_law
from rig.motion.speed import ConstantSpeed, RampSpeed, SinusoidalSpeed
from rig.plants.cam_bar.guide_friction import GuideFriction

if TYPE_CHECKING:
    from rig.motion.speed import SpeedProfile
    from rig.plants.cam_bar.drive import CamDrive
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism

TAU = 1e-3              # s, scale of the velocity state: y = (e, τ·ė)
INV_TAU = 1.0 / TAU
TWO_PI = 2.0 * math.pi
INV_TWO_PI = 1.0 / TWO_PI
DEAD_CENTRE_TOL = 1e-6  # |sin(ϑ − ψ)| below this: follower and rod collinear (as rig.plants.cam_bar.chain)

# p layout: chain, masses, loads, contact, speed profile, event cache, diagnosis, cam program
(L3, LR, L4, E_SK, S0, X_A0, Y_A0, BRANCH, ROD_SIDE, CAM_DIR,
 M3, M4, M5, J3, J4, A3, G,
 MU, V_S, K_SPRING, L_F, ME0, PSI0, F_C, S_PIERCE, PSI_PIERCE,
 CLEARANCE, K_C, EXPONENT, DAMPING, MAX_PEN,
 SPEED, PHI0, SP1, SP2, SP3, SP4,
 GC_PHI, GC_PSI, GC_PP, GC_PPP, GC_LEV, GC_LEVP, GC_RISE, GC_COS, GC_SIN, IR_PHI, IR_VALUE,
 JAM_T, JAM_PHI,
 INS_LAW, INS_UP, INS_DOWN, S_TOP,
 GUIDE_MODEL, MU_S, V_STICK, T_STICK,
 DRIVE_ON, W_SYNC, B_MOTOR, M_MAX, J_MOTOR, J_CAM, K_SHAFT, C_SHAFT,
 JOINTS_ON, J_PLAY, J_K, J_ALPHA,
 COS_PSI0, SIN_PSI0,
 INV_L3, INV_L4, INV_V_S, SPRING0,
 NSEG) = range(77)
PROGRAM = NSEG + 1      # segment table: rows of SEG_ROW = (start, angle, level, signed stroke, law offset)
SEG_ROW = 5
#: speed profiles (p[SPEED]); parameters SP1..SP4: constant ω; ramp ω0, ω1, t_ramp, t_start; sinusoidal
#: ω_mean, amplitude, 2πf
CONSTANT, RAMP, SINUSOIDAL = 0, 1, 2
#: motion-law codes at a segment's law offset: DWELL (no law); POLYNOMIAL n, c0..c_{n−1};
#: SINE_PIECES n, then per piece x_start, c0, c1, w, θ, y_start, y'_start (scaled, as PiecewiseSineLaw)
DWELL, POLYNOMIAL, SINE_PIECES = 0, 1, 2
PIECE = 7
#: events, in the order of :meth:`rig.plants.cam_bar.level2.Level2.problem`
WORKING, OTHER, OVERLOAD, INSERTION, PINS = range(5)
#: rows of :func:`evaluate`
OUTPUTS = ("phi", "omega", "alpha", "psi", "psi_d", "psi_dd", "e_dd", "F_w", "F_o", "drive_torque",
           "p_dissipated", "delta_w", "delta_o", "s", "s_d", "s_dd", "theta_d", "theta_dd", "mu", "F_c",
           "friction", "omega_m", "shaft_torque", "z_dd", "rod_tension", "cam_moment")
N_OUT = len(OUTPUTS)


def pack(mech: "PinInsertionMechanism", speed: "SpeedProfile | None" = None, stiffness: float = 0.0,
         exponent: float = 1.0, damping: float = 0.0, max_penetration: float = math.inf, friction_speed: float = 1e-3,
         cam_drive: "CamDrive | None" = None, guide: GuideFriction = GuideFriction()) -> np.ndarray:
    """Parameter vector of ``mech`` turned by ``speed`` (``None``: at rest, for the geometry alone) with the
    contact law K·δ^p·(1 + α·δ̇) (``stiffness`` K in N/m^p, ``exponent`` p, ``damping`` α in s/m),
    ``max_penetration`` (m), the friction regularisation speed ``friction_speed`` (m/s), the cam drive
    (``None``: the speed profile turns the cam; else it starts from the profile's φ0 and nominal speed) and the
    slider-guide friction model ``guide``. Raises
    ValueError for a speed profile or motion law the kernel does not know."""
    d = cam_drive
    if d is not None and speed is None:
        raise ValueError("level 2: a cam drive needs the speed profile it starts from")
    ch = mech.chain
    top = mech.program.levels[1]
    s_pierce = top - mech.F_c_travel
    head = [mech.L3, mech.l3, mech.l4, mech.e_sk, mech.s0, mech.x_A0, mech.y_A0, ch.branch, ch.rod_side,
            float(mech.cam_direction),
            mech.m3, mech.m4, mech.m5, mech.J3, mech.J4, mech.a3, mech.g,
            mech.mu, friction_speed, mech.k, mech.l_F, mech.Me_0, mech.psi0, mech.F_c, s_pierce,
            float(mech.kinematics(s_pierce).psi),
            mech.clearance, stiffness, exponent, damping, max_penetration,
            *_speed(speed),
            math.nan, *[0.0] * 8, math.nan, 0.0,
            math.nan, math.nan,
            float(mech.insertion.code), mech.insertion.build_up, mech.insertion.release, top,
            float(guide.code), guide.static_coefficient(mech.mu), guide.stick_speed, guide.relax_time,
            0.0 if d is None else 1.0, *([0.0] * 7 if d is None else
                                         [d.synchronous(speed.nominal_omega), d.slope, d.max_torque,
                                          d.motor_inertia, d.cam_inertia, d.shaft_stiffness, d.shaft_damping]),
            *_joints(mech.joints),
            math.cos(mech.psi0), math.sin(mech.psi0),
            1.0 / mech.L3, 1.0 / mech.l4, 1.0 / friction_speed, mech.Me_0 / mech.l_F,
            float(len(mech.program.segments))]
    assert len(head) == PROGRAM
    table, laws = [], []
    at = PROGRAM + SEG_ROW * len(mech.program.segments)
    level = 0.0
    for start, seg in zip(mech.program.starts, mech.program.segments):
        h = {"rise": seg.stroke, "return": -seg.stroke}.get(seg.kind, 0.0)
        code = [float(DWELL)] if seg.kind == "dwell" else _law(seg.law)
        table += [float(start), seg.angle, level, h, float(at)]
        laws += code
        at += len(code)
        level += h
    return np.array(head + table + laws, dtype=float)


def _joints(joints) -> list[float]:
    """(on, half free play, stiffness, damping) of the rod's pin joints (``None``: rigid, level 2 without the
    slider's state)."""
    if joints is None:
        return [0.0, 0.0, 0.0, 0.0]
    return [1.0, joints.play, joints.stiffness, joints.damping]


def _speed(speed) -> list[float]:
    """(kind, φ0, SP1..SP4) of a speed profile (``None``: at rest at φ = 0)."""
    if speed is None:
        return [CONSTANT, 0.0, 0.0, 0.0, 0.0, 0.0]
    if isinstance(speed, ConstantSpeed):
        return [CONSTANT, speed.phi0, speed.omega, 0.0, 0.0, 0.0]
    if isinstance(speed, RampSpeed):
        return [RAMP, speed.phi0, speed.omega0, speed.omega1, speed.t_ramp, speed.t_start]
    if isinstance(speed, SinusoidalSpeed):
        f = speed.frequency if speed.frequency is not None else speed.omega_mean / TWO_PI
        return [SINUSOIDAL, speed.phi0, speed.omega_mean, speed.amplitude, 2.0 * math.pi * f, 0.0]
    raise ValueError(f"level 2: speed profile {type(speed).__name__} is not supported by the compiled kernel "
                     f"(constant, ramp, sinusoidal)")


def _law(name: str) -> list[float]:
    """Kernel code of a motion law."""
    law = get_law(name)
    if isinstance(law, PolynomialLaw):
        c = law.power_coefficients.tolist()
        return [float(POLYNOMIAL), float(len(c)), *c]
    if isinstance(law, PiecewiseSineLaw):
        rows = np.column_stack([law._xa, law._c0, law._c1, law._w, law._th, law._ya, law._va])
        return [float(SINE_PIECES), float(len(rows)), *rows.ravel().tolist()]
    raise ValueError(f"level 2: motion law {name!r} ({type(law).__name__}) is not supported by the compiled "
                     f"kernel (polynomial and piecewise-sine laws)")


# ---- cam speed and program ---------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", inline="always")
def drive(t, p):
    """(φ, ω, ω̇) of the speed profile at time t (rad, rad/s, rad/s²), as :mod:`rig.motion.speed`."""
    kind = p[SPEED]
    if kind == CONSTANT:
        return p[PHI0] + p[SP1] * t, p[SP1], 0.0
    if kind == RAMP:
        w0, w1, t_ramp, t_start = p[SP1], p[SP2], p[SP3], p[SP4]
        rate = (w1 - w0) / t_ramp
        u = min(max(t - t_start, 0.0), t_ramp)
        after = max(t - t_start - t_ramp, 0.0)
        before = min(t, t_start)
        phi = p[PHI0] + w0 * before + w0 * u + 0.5 * rate * u * u + w1 * after
        return phi, w0 + rate * u, rate if t_start < t < t_start + t_ramp else 0.0
    mean, amp, w = p[SP1], p[SP2], p[SP3]
    return p[PHI0] + mean * t + amp / w * (1.0 - math.cos(w * t)), mean + amp * math.sin(w * t), \
        amp * w * math.cos(w * t)


@njit(cache=True, error_model="numpy", inline="always")
def law(p, at, x):
    """(y, y', y'') of the motion law coded at p[at] at x ∈ [0, 1] (as :mod:`rig.motion.laws`)."""
    n = int(p[at + 1])
    if p[at] == POLYNOMIAL:
        y = p[at + 1 + n]
        d1 = d2 = 0.0
        for k in range(n - 2, -1, -1):                # Horner with the first two derivatives
            d2 = d2 * x + d1
            d1 = d1 * x + y
            y = y * x + p[at + 2 + k]
        return y, d1, 2.0 * d2
    i = 0
    while i + 1 < n and p[at + 2 + PIECE * (i + 1)] <= x:
        i += 1
    r = at + 2 + PIECE * i
    xa, c0, c1, w, th, ya, va = p[r], p[r + 1], p[r + 2], p[r + 3], p[r + 4], p[r + 5], p[r + 6]
    u = x - xa
    arg = w * u + th
    v = va + c0 * u - (c1 / w) * (math.cos(arg) - math.cos(th))
    y = ya + va * u + 0.5 * c0 * u * u - (c1 / w) * ((math.sin(arg) - math.sin(th)) / w - math.cos(th) * u)
    return y, v, c0 + c1 * math.sin(arg)


@njit(cache=True, error_model="numpy", inline="always")
def wrap(phi):
    """φ mod 2π in [0, 2π) (rad; by floor, cheaper than the float modulo, equal to it within an ulp)."""
    x = phi - TWO_PI * math.floor(phi * INV_TWO_PI)
    if x < 0.0:                                   # the reciprocal's rounding put the floor one turn high
        x += TWO_PI
    return x if x < TWO_PI else 0.0


@njit(cache=True, error_model="numpy", inline="always")
def program(phi, p):
    """(s, s', s'', rise) of the cam program at cam angle φ (m, per rad; as
    :meth:`rig.motion.program.CamProgram.evaluate`); ``rise``: φ lies in a rise segment (exact, unlike the sign of
    s' evaluated near the segment's ends)."""
    x = wrap(phi)
    n = int(p[NSEG])
    i = 0
    while i + 1 < n and p[PROGRAM + SEG_ROW * (i + 1)] <= x:
        i += 1
    r = PROGRAM + SEG_ROW * i
    h = p[r + 3]
    if h == 0.0:
        return p[r + 2], 0.0, 0.0, False
    inv = 1.0 / p[r + 1]
    y, y1, y2 = law(p, int(p[r + 4]), (x - p[r]) * inv)
    return p[r + 2] + h * y, h * inv * y1, h * inv * inv * y2, h > 0.0


@njit(cache=True, error_model="numpy", inline="always")
def in_rise(phi, p):
    """Distance (rad) of φ into the nearest rise segment (> 0 inside, < 0 outside; −1 without rises)."""
    x = wrap(phi)
    best = -1.0
    found = False
    for i in range(int(p[NSEG])):
        r = PROGRAM + SEG_ROW * i
        if p[r + 3] > 0.0:
            d = min(x - p[r], p[r] + p[r + 1] - x)
            best = d if not found else max(best, d)
            found = True
    return best


# ---- level-0 chain ----------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", inline="always")
def chain_angles(s, p):
    """(ψ, cos ψ, sin ψ, cos ϑ, sin ϑ, sin(ϑ − ψ)) for slider stroke s (as :meth:`Chain.angles`); ψ = NaN when
    the chain cannot be assembled or sits at a dead centre."""
    u = p[S0] - s
    rho2 = u * u + p[E_SK] ** 2
    rho = math.sqrt(rho2)
    inv_rho = 1.0 / rho
    cos_g = (p[L3] ** 2 - p[L4] ** 2 + rho2) * (0.5 * p[INV_L3]) * inv_rho
    if abs(cos_g) > 1.0:
        return math.nan, 0.0, 0.0, 0.0, 0.0, 0.0
    sin_g = p[BRANCH] * math.sqrt((1.0 - cos_g) * (1.0 + cos_g))     # ψ = atan2(e, u) − branch·γ, by identities
    cp, sp = (u * cos_g + p[E_SK] * sin_g) * inv_rho, (p[E_SK] * cos_g - u * sin_g) * inv_rho
    c0, s0 = p[COS_PSI0], p[SIN_PSI0]                                 # ψ on its branch: ψ0 + (ψ − ψ0), |ψ − ψ0| < π
    psi = p[PSI0] + math.atan2(sp * c0 - cp * s0, cp * c0 + sp * s0)    # (one atan2 instead of atan2 and acos)
    ct, st = (u - p[L3] * cp) * p[INV_L4], (p[E_SK] - p[L3] * sp) * p[INV_L4]
    sin_rel = st * cp - ct * sp
    if abs(sin_rel) < DEAD_CENTRE_TOL:
        return math.nan, cp, sp, ct, st, sin_rel
    return psi, cp, sp, ct, st, sin_rel


@njit(cache=True, error_model="numpy", inline="always")
def chain_derivatives(cp, sp, ct, st, sin_rel, s_p, s_pp, p):
    """ψ', ψ'', ϑ', ϑ'' from the loop closure for ds/dq = s_p, d²s/dq² = s_pp (as :meth:`Chain.derivatives`)."""
    inv = 1.0 / sin_rel                           # one division (its latency is the kernel's critical path)
    over_l3, over_l4 = p[INV_L3] * inv, p[INV_L4] * inv     # 1/(L3·sin), 1/(l4·sin)
    psi_p = -s_p * ct * over_l3
    th_p = s_p * cp * over_l4
    b1 = -s_pp + p[L3] * psi_p ** 2 * cp + p[L4] * th_p ** 2 * ct
    b2 = p[L3] * psi_p ** 2 * sp + p[L4] * th_p ** 2 * st
    return psi_p, (b1 * ct + b2 * st) * over_l3, th_p, -(b2 * sp + b1 * cp) * over_l4


@njit(cache=True, error_model="numpy", inline="always")
def groove_at(phi, p):
    """:func:`groove` through the one-entry cache in p (keyed on φ)."""
    if p[GC_PHI] != phi:
        g = groove(phi, p)
        p[GC_PSI], p[GC_PP], p[GC_PPP], p[GC_LEV], p[GC_LEVP] = g[0], g[1], g[2], g[3], g[4]
        p[GC_RISE] = 1.0 if g[5] else 0.0
        p[GC_COS], p[GC_SIN] = g[6], g[7]
        p[GC_PHI] = phi
    return p[GC_PSI], p[GC_PP], p[GC_PPP], p[GC_LEV], p[GC_LEVP], p[GC_RISE] != 0.0, p[GC_COS], p[GC_SIN]


@njit(cache=True, error_model="numpy", inline="always")
def groove(phi, p):
    """Level-0 follower law and pitch-curve geometry at cam angle φ: (ψ_k, ψ_k', ψ_k'', ℓ, dℓ/dφ, rising, cos ψ_k,
    sin ψ_k)
    with the lever ℓ = |B_R·t|/|t| of the contact normal about B0, t = dB_R/dφ − d·J·(B_R − A0) the tangent
    of the relative path, and ``rising``: φ in a rise segment (rad, per rad, m, m/rad; NaN where the chain
    fails). The insertion force acts only while ``rising`` — the exact form of level 1's s' > 0, whose sign
    flickers with rounding in the last nanoseconds of a rise and would switch F_c on and off there."""
    s, s_p, s_pp, rise = program(phi, p)
    psi, cp, sp, ct, st, sin_rel = chain_angles(s, p)
    pp, ppp, _, _ = chain_derivatives(cp, sp, ct, st, sin_rel, s_p, s_pp, p)
    d, lr = p[CAM_DIR], p[LR]
    bx, by = lr * cp, lr * sp
    wx, wy = bx - p[X_A0], by - p[Y_A0]
    dbx, dby = -lr * sp * pp, lr * cp * pp
    tx, ty = dbx + d * wy, dby - d * wx
    dtx = -lr * (cp * pp ** 2 + sp * ppp) + d * dby
    dty = lr * (cp * ppp - sp * pp ** 2) - d * dbx
    lev = bx * tx + by * ty
    dlev = dbx * tx + dby * ty + bx * dtx + by * dty
    inv_tn = 1.0 / math.sqrt(tx * tx + ty * ty)
    dtn = (tx * dtx + ty * dty) * inv_tn
    sgn = 1.0 if lev > 0.0 else -1.0 if lev < 0.0 else 0.0
    return psi, pp, ppp, sgn * lev * inv_tn, sgn * (dlev - lev * dtn * inv_tn) * inv_tn, rise, cp, sp


# ---- contact and free body ----------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", inline="always")
def elastic(delta, p):
    """K·δ^p for penetration δ > 0, else 0 (N)."""
    return p[K_C] * delta ** p[EXPONENT] if delta > 0.0 else 0.0


@njit(cache=True, error_model="numpy", inline="always")
def contact_force(spring, rate, p):
    """Hunt–Crossley contact force K·δ^p·(1 + α·δ̇) ≥ 0 (N) from its elastic part ``spring`` = K·δ^p
    (:func:`elastic`, N) and the penetration rate δ̇ (m/s)."""
    return max(spring * (1.0 + p[DAMPING] * rate), 0.0)


@njit(cache=True, error_model="numpy", inline="always")
def smoothstep(u):
    """3-4-5 step clipped to [0, 1] (as :func:`rig.plants.cam_bar.insertion.smoothstep`)."""
    u = min(max(u, 0.0), 1.0)
    return u * u * u * (10.0 + u * (-15.0 + 6.0 * u))


@njit(cache=True, error_model="numpy", inline="always")
def insertion_force(s, p):
    """The pin's force–travel law at stroke s with the cam in a rise (N; :mod:`rig.plants.cam_bar.insertion`)."""
    x = s - p[S_PIERCE]
    if x < 0.0:
        return 0.0
    if p[INS_LAW] == 1.0:
        return p[F_C]
    travel = p[S_TOP] - p[S_PIERCE]
    return p[F_C] * smoothstep(x / (p[INS_UP] * travel)) * smoothstep((travel - x) / (p[INS_DOWN] * travel))


@njit(cache=True, error_model="numpy", inline="always")
def _mu_seen(friction, normal, sv):
    """The coefficient μ' with friction = −μ'·|N|·sv for the slider-velocity sign sv of the state, so that the
    level-1 free body (which takes the friction direction from ṡ) reproduces a held or band-slipping guide."""
    den = abs(normal) * sv
    return -friction / den if den != 0.0 else 0.0


@njit(cache=True, error_model="numpy", inline="always")
def cos_sin(x):
    """(cos x, sin x): Taylor polynomials for |x| < 1e-2 (x is the small deviation e; their remainders are
    below 1e-21, far under an ulp), else the library functions."""
    if abs(x) >= 1e-2:
        return math.cos(x), math.sin(x)
    x2 = x * x
    return 1.0 - x2 * (0.5 - x2 * (1.0 / 24.0 - x2 * (1.0 / 720.0 - x2 / 40320.0))), \
        x * (1.0 - x2 * (1.0 / 6.0 - x2 * (1.0 / 120.0 - x2 * (1.0 / 5040.0 - x2 / 362880.0))))


@njit(cache=True, error_model="numpy", inline="always")
def rigid_rod(cp, sp, p):
    """(s, cos ϑ, sin ϑ, sin(ϑ − ψ), ok) of the rigid rod at follower angle ψ (cos, sin): the stroke s (m) the
    level-0 chain gives; ``ok`` False when the chain cannot be assembled or sits at a dead centre."""
    l3_, l4_, esk = p[L3], p[L4], p[E_SK]
    rad = l4_ * l4_ - (esk - l3_ * sp) ** 2
    if rad < 0.0:
        return math.nan, 0.0, 0.0, 0.0, False
    root = p[ROD_SIDE] * math.sqrt(rad)
    ct, st = root * p[INV_L4], (esk - l3_ * sp) * p[INV_L4]
    sin_rel = st * cp - ct * sp
    return p[S0] - (l3_ * cp + root), ct, st, sin_rel, abs(sin_rel) >= DEAD_CENTRE_TOL


@njit(cache=True, error_model="numpy", inline="always")
def spring_moment(psi, p):
    """Moment of the follower's spring at ψ (N·m, towards smaller ψ)."""
    return (p[SPRING0] + p[K_SPRING] * p[L_F] * (psi - p[PSI0])) * p[L_F]


@njit(cache=True, error_model="numpy", inline="always")
def slider_sign(s_d):
    """Sign of the slider velocity ẋ_D = −ṡ for stroke rate ṡ (0 at rest)."""
    return -1.0 if s_d > 0.0 else 1.0 if s_d < 0.0 else 0.0


@njit(cache=True, error_model="numpy", inline="always")
def regularised_mu(s_d, p):
    """The regularised guide's coefficient μ·tanh(|ṡ|/v_s) (tanh rounds to 1 beyond 19: μ itself past 20)."""
    x = abs(s_d) * p[INV_V_S]
    return p[MU] if x > 20.0 else p[MU] * math.tanh(x)


@njit(cache=True, error_model="numpy", inline="always")
def rod_span(cp, sp, s, p):
    """(x, y, length) of D − C (m) with the follower at ψ (cos, sin) and the slider at stroke s."""
    dx, dy = p[S0] - s - p[L3] * cp, p[E_SK] - p[L3] * sp
    return dx, dy, math.sqrt(dx * dx + dy * dy)


@njit(cache=True, error_model="numpy", inline="always")
def free_body(psi, cp, sp, psi_d, rising, moment, p):
    """ψ̈ (rad/s²) at which the cam moment of the free bodies on the actual motion (ψ, ψ̇) equals ``moment``
    (N·m), and the motion and loads there: (ψ̈, s, ṡ, s̈, ϑ̇, ϑ̈, μ_eff, F_c, friction, status) with status 0,
    1 (chain cannot be assembled) or 2 (jammed guide). Each force is a pair (value at ψ̈ = 0, slope)."""
    nan = math.nan
    l3_, l4_ = p[L3], p[L4]
    s, ct, st, sin_rel, ok = rigid_rod(cp, sp, p)
    if not ok:
        return nan, nan, nan, nan, nan, nan, nan, nan, nan, 1
    psi_s, psi_ss, th_s, th_ss = chain_derivatives(cp, sp, ct, st, sin_rel, 1.0, 0.0, p)   # d/ds
    s_psi = 1.0 / psi_s
    s_d = s_psi * psi_d
    s0_, s1_ = -psi_ss * s_psi ** 3 * psi_d * psi_d, s_psi                  # s̈ = s0_ + s1_·ψ̈
    th_d = th_s * s_d
    t0_, t1_ = th_ss * s_d * s_d + th_s * s0_, th_s * s1_                  # ϑ̈
    g, m4, m5 = p[G], p[M4], p[M5]
    ax0, ax1 = -l3_ * psi_d * psi_d * cp, -l3_ * sp                           # a_C
    ay0, ay1 = -l3_ * psi_d * psi_d * sp, l3_ * cp
    dx0, dx1 = l4_ * (-t0_ * st - th_d * th_d * ct), -l4_ * t1_ * st          # a_D − a_C
    dy0, dy1 = l4_ * (t0_ * ct - th_d * th_d * st), l4_ * t1_ * ct
    f4x0, f4x1 = -m4 * (ax0 + 0.5 * dx0), -m4 * (ax1 + 0.5 * dx1)
    f4y0, f4y1 = -m4 * (g + ay0 + 0.5 * dy0), -m4 * (ay1 + 0.5 * dy1)
    lx, ly = l4_ * ct, l4_ * st
    m40 = 0.5 * (lx * f4y0 - ly * f4x0) - p[J4] * t0_                       # rod moment about C
    m41 = 0.5 * (lx * f4y1 - ly * f4x1) - p[J4] * t1_
    f_c = insertion_force(s, p) if rising else 0.0
    q0, q1 = f_c + m5 * s0_, m5 * s1_
    sv = slider_sign(s_d)
    w5 = m5 * g
    spring = spring_moment(psi, p)
    if p[GUIDE_MODEL] == 0.0:
        mu = regularised_mu(s_d, p)
    else:                                             # Karnopp stick-slip (rig.plants.cam_bar.guide_friction)
        mu = p[MU]
        if abs(s_d) <= p[V_STICK]:                    # may hold: friction F_f (x54 = q + F_f) with s̈ = −ṡ/T
            acc = (-s_d / p[T_STICK] - s0_) / s1_
            ratio = ly / lx                               # R54y = (ly·R54x − M4)/lx
            x = q0 + q1 * acc
            y = ratio * x - (m40 + m41 * acc) / lx
            r34x, r34y = -x - (f4x0 + f4x1 * acc), -y - (f4y0 + f4y1 * acc)
            m_free = l3_ * (cp * r34y - sp * r34x) + p[M3] * g * p[A3] * cp + spring + p[J3] * acc
            f_hold = (moment - m_free) / (l3_ * (sp - cp * ratio))
            normal = y + ratio * f_hold + w5
            if abs(f_hold) <= p[MU_S] * abs(normal):
                return acc, s, s_d, s0_ + s1_ * acc, th_d, t0_ + t1_ * acc, _mu_seen(f_hold, normal, sv), f_c, \
                    f_hold, 0
            sv = -1.0 if f_hold > 0.0 else 1.0        # slips the way it is pushed: friction against that
    for branch in (1.0, -1.0):                        # guide normal force N ≥ 0 first, as kinetostatics._guide
        c = mu * sv * branch
        den = lx + c * ly
        inv = 1.0 / den
        y0, y1 = (ly * (q0 - c * w5) - m40) * inv, (ly * q1 - m41) * inv     # R54 = (x54, y)
        x0, x1 = q0 - c * (y0 + w5), q1 - c * y1
        r34x0, r34x1 = -x0 - f4x0, -x1 - f4x1
        r34y0, r34y1 = -y0 - f4y0, -y1 - f4y1
        m0 = l3_ * (cp * r34y0 - sp * r34x0) + p[M3] * g * p[A3] * cp + spring   # M_Σ = J3·ψ̈ − M_other + M_e
        m1 = p[J3] + l3_ * (cp * r34y1 - sp * r34x1)
        acc = (moment - m0) / m1
        normal = y0 + y1 * acc + w5
        if c == 0.0 or ((normal >= 0.0) if branch > 0.0 else (normal <= 0.0)):
            friction = -mu * abs(normal) * sv
            seen = mu if p[GUIDE_MODEL] == 0.0 else _mu_seen(friction, normal, -1.0 if s_d > 0.0 else 1.0)
            return acc, s, s_d, s0_ + s1_ * acc, th_d, t0_ + t1_ * acc, seen, f_c, friction, 0
    return nan, s, s_d, nan, th_d, nan, mu, f_c, nan, 2


@njit(cache=True, error_model="numpy", inline="always")
def guide_force(push, normal, s_d, m_s, p):
    """Friction of the slider guide along x (N) for the other x-forces ``push`` = m_s·s̈ without friction (N), guide
    normal force ``normal`` (N), stroke rate ṡ (m/s) and slider mass ``m_s`` (kg), with the guide's model: the
    regularised μ·tanh(|ṡ|/v_s), or stick–slip (held within μ_s·|N| to s̈ = −ṡ/T inside the stick band, else
    slipping the way it is pushed); and the sign of the slider velocity ẋ_D it was taken for."""
    sv = slider_sign(s_d)
    mu = p[MU]
    if p[GUIDE_MODEL] == 0.0:
        mu = regularised_mu(s_d, p)
    elif abs(s_d) <= p[V_STICK]:
        f_hold = push + m_s * s_d / p[T_STICK]
        if abs(f_hold) <= p[MU_S] * abs(normal):
            return f_hold, sv
        sv = -1.0 if f_hold > 0.0 else 1.0
    return -mu * abs(normal) * sv, sv


@njit(cache=True, error_model="numpy", inline="always")
def joint_body(psi, cp, sp, psi_d, z, z_d, rising, moment, p):
    """Follower and slider as two bodies joined by the rod through its pin clearances (:mod:`.joints`): ψ̈
    (rad/s²) of the follower under the cam moment ``moment`` (N·m), the slider's stroke deviation rate z̈ (m/s²)
    for z = s − s_r(ψ), ż, and the motion and loads: (ψ̈, s, ṡ, s̈, ϑ̇, ϑ̈, μ_eff, F_c, friction, z̈, rod tension
    T, power dissipated in the pins, status) with status 0 or 1 (no rigid chain at ψ to refer z to)."""
    nan = math.nan
    s_r, ct, st, sin_rel, ok = rigid_rod(cp, sp, p)
    if not ok:
        return nan, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan, 1
    psi_s, psi_ss, _, _ = chain_derivatives(cp, sp, ct, st, sin_rel, 1.0, 0.0, p)    # d/ds of the rigid chain
    s_psi = 1.0 / psi_s
    s_psipsi = -psi_ss * s_psi ** 3                                         # d²s_r/dψ²
    s, s_d = s_r + z, s_psi * psi_d + z_d
    l3_, g, half = p[L3], p[G], 0.5 * p[M4]
    dx, dy, length = rod_span(cp, sp, s, p)                                 # D − C
    nx, ny = dx / length, dy / length
    vx, vy = -s_d + l3_ * sp * psi_d, -l3_ * cp * psi_d                    # v_D − v_C
    rate = nx * vx + ny * vy
    stretch, play = length - p[L4], p[J_PLAY]
    elastic_t = tension = 0.0
    if stretch > play:                                                       # pins bear: rod in tension
        elastic_t = p[J_K] * (stretch - play)
        tension = max(elastic_t * (1.0 + p[J_ALPHA] * rate), 0.0)
    elif stretch < -play:                                                    # in compression
        elastic_t = -p[J_K] * (-play - stretch)
        tension = min(elastic_t * (1.0 - p[J_ALPHA] * rate), 0.0)
    m_s = p[M5] + half
    f_c = insertion_force(s, p) if rising else 0.0
    normal = tension * ny + m_s * g                                          # R54 = T·n, guide N = R54y + W
    push = tension * nx - f_c                                               # m_s·s̈ = T·n_x − F_c − F_f
    friction, sv = guide_force(push, normal, s_d, m_s, p)
    s_dd = (push - friction) / m_s
    m_other = l3_ * tension * (cp * ny - sp * nx) - (p[M3] * p[A3] + half * l3_) * g * cp - spring_moment(psi, p)
    acc = (moment + m_other) / (p[J3] + half * l3_ * l3_)
    z_dd = s_dd - (s_psipsi * psi_d * psi_d + s_psi * acc)
    th_d = (dx * vy - dy * vx) / (length * length)
    ax = -s_dd + l3_ * (cp * psi_d * psi_d + sp * acc)                      # a_D − a_C
    ay = l3_ * (sp * psi_d * psi_d - cp * acc)
    th_dd = (dx * ay - dy * ax) / (length * length) - 2.0 * rate * th_d / length
    return acc, s, s_d, s_dd, th_d, th_dd, _mu_seen(friction, normal, sv), f_c, friction, z_dd, tension, \
        (tension - elastic_t) * rate, 0


@njit(cache=True, error_model="numpy", inline="always")
def cam_state(t, y, p):
    """(φ, ω, ω̇ of the speed profile, ω_m, shaft torque) at time t and state y: from the speed profile (ω_m = ω,
    torque 0), or with the cam drive on from the states (φ, ω, φ_m, ω_m) = y[2:6] (ω̇ then follows from the drive
    torque in :func:`dynamics`)."""
    if p[DRIVE_ON] == 0.0:
        phi, omega, alpha = drive(t, p)
        return phi, omega, alpha, omega, 0.0
    return y[2], y[3], 0.0, y[5], p[K_SHAFT] * (y[4] - y[2]) + p[C_SHAFT] * (y[5] - y[3])


@njit(cache=True, error_model="numpy", inline="always")
def joint_index(p):
    """Index of the slider's state z in y (after (e, τ·ė) and the cam drive's states)."""
    return 2 if p[DRIVE_ON] == 0.0 else 6


# Called, not inlined (its helpers are): rhs and evaluate share one compilation of it — a first run compiles the
# level-2 kernel in about half the time, and a level-2 integration runs within 3 % of the inlined one.
@njit(cache=True, error_model="numpy")
def dynamics(e, e_d, z, z_d, phi, omega, alpha, omega_m, shaft, p):
    """Everything for deviation e (rad) and rate ė (rad/s) with the cam at φ, ω (rad, rad/s), in the
    order of :data:`OUTPUTS`, and a status (0, 1 chain cannot be assembled, 2 jammed guide: the values are then
    NaN). ``alpha`` ω̇ of the speed profile; with the cam drive on ω̇ = (``shaft`` torque − drive torque)/J_cam
    instead (the drive torque depends on the contact forces only, not on ω̇). With the rod's pin joints
    (p[JOINTS_ON]) z, ż (m, m/s) are the slider's deviation from the rigid chain (else unused, z̈ = 0 and the
    rod tension NaN: level 1's free body gives it)."""
    psi_k, psi_p, psi_pp, lever, lever_p, rising, ck, sk = groove_at(phi, p)
    psi = psi_k + e
    ce, se = cos_sin(e)
    cp, sp = ck * ce - sk * se, sk * ce + ck * se                   # cos, sin of ψ = ψ_k + e
    psi_d = omega * psi_p + e_d
    u = lever * e
    u_d = lever_p * omega * e + lever * e_d
    d_w, d_o = -u, u - p[CLEARANCE]
    el_w, el_o = elastic(d_w, p), elastic(d_o, p)
    f_w, f_o = contact_force(el_w, -u_d, p), contact_force(el_o, u_d, p)
    moment = lever * (f_w - f_o)
    if p[JOINTS_ON] == 0.0:
        acc, s, s_d, s_dd, th_d, th_dd, mu, f_c, friction, status = free_body(psi, cp, sp, psi_d, rising, moment, p)
        z_dd, tension, p_joint = 0.0, math.nan, 0.0
    else:
        acc, s, s_d, s_dd, th_d, th_dd, mu, f_c, friction, z_dd, tension, p_joint, status = joint_body(
            psi, cp, sp, psi_d, z, z_d, rising, moment, p)
    drive_torque = (f_w - f_o) * (-lever_p * e + lever * psi_p)     # (F_w − F_o)·∂δ_w/∂φ at fixed ψ
    if p[DRIVE_ON] != 0.0:
        alpha = (shaft - drive_torque) / p[J_CAM]
    e_dd = acc - omega * omega * psi_pp - alpha * psi_p
    p_diss = (f_w - el_w) * -u_d + (f_o - el_o) * u_d + p_joint
    return (phi, omega, alpha, psi, psi_d, acc, e_dd, f_w, f_o, drive_torque, p_diss, d_w, d_o, s, s_d, s_dd,
            th_d, th_dd, mu, f_c, friction, omega_m, shaft, z_dd, tension, moment), status


@njit(cache=True, error_model="numpy", _nrt=False)
def rhs(t, y, p, out):
    """d/dt of (e, τ·ė[, φ, ω, φ_m, ω_m][, z, τ·ż][, W_drive, W_load, E_dissipated]) into ``out`` (the cam-drive states
    when p[DRIVE_ON], the slider's when p[JOINTS_ON]); NaN where the chain cannot be assembled or the guide jams (then
    p[JAM_T], p[JAM_PHI] record where; they describe the latest evaluation at a finite state, NaN unless it jammed:
    the one a failing solver gave up on, not a jam some rejected trial step met earlier)."""
    if not math.isfinite(y.sum()):               # a stage after a NaN stage: the NaN's cause stays recorded
        out[:] = math.nan
        return
    phi, omega, alpha, omega_m, shaft = cam_state(t, y, p)
    j = joint_index(p)
    joints = p[JOINTS_ON] != 0.0
    z, z_d = (y[j], y[j + 1] * INV_TAU) if joints else (0.0, 0.0)
    r, status = dynamics(y[0], y[1] * INV_TAU, z, z_d, phi, omega, alpha, omega_m, shaft, p)
    if status:
        out[:] = math.nan
        p[JAM_T], p[JAM_PHI] = (t, r[0]) if status == 2 else (math.nan, math.nan)
        return
    p[JAM_T] = math.nan
    out[0] = y[1] * INV_TAU
    out[1] = TAU * r[6]
    k = 2
    if p[DRIVE_ON] != 0.0:
        out[2] = omega
        out[3] = r[2]
        out[4] = omega_m
        motor = min(max(p[B_MOTOR] * (p[W_SYNC] - omega_m), -p[M_MAX]), p[M_MAX])
        out[5] = (motor - shaft) / p[J_MOTOR]
        k = 6
    if joints:
        out[k] = z_d
        out[k + 1] = TAU * r[23]
        k += 2
    if y.size > k:
        out[k] = r[9] * r[1]                       # drive torque · ω
        out[k + 1] = -(r[19] + r[20]) * r[14]      # −(F_c + friction)·ṡ
        out[k + 2] = r[10]


@njit(cache=True, error_model="numpy", inline="always")
def cam_angle(t, y, p):
    """Cam angle φ (rad) at time t and state y (speed profile, or the drive state)."""
    return drive(t, p)[0] if p[DRIVE_ON] == 0.0 else y[2]


@njit(cache=True, error_model="numpy", inline="always")
def geometry_at(t, y, p):
    """(ℓ, ψ_k, distance into a rise) at time t and state y (cached in p for the last cam angle)."""
    phi = cam_angle(t, y, p)
    g = groove_at(phi, p)
    if p[IR_PHI] != phi:
        p[IR_PHI], p[IR_VALUE] = phi, in_rise(phi, p)
    return g[3], g[0], p[IR_VALUE]


@njit(cache=True, error_model="numpy", _nrt=False)
def event_value(t, y, p, k):
    """Event k: WORKING −e (< 0 while pressed into the working flank), OTHER e − c/ℓ (> 0 while pressed into
    the other flank), OVERLOAD max penetration (of a flank, or of the rod's pins) − p[MAX_PEN] (m), INSERTION > 0
    while F_c acts (cam in a rise and ψ past the pierce point, rad; with the pin joints the slider's stroke past it
    over L3), PINS > 0 while the rod's pins bear (:func:`pin_penetration`, m; −1 without the pin joints)."""
    if k == WORKING:
        return -y[0]
    if k == PINS and p[JOINTS_ON] == 0.0:
        return -1.0
    lever, psi_k, inside = geometry_at(t, y, p)
    if k == PINS:
        return pin_penetration(psi_k + y[0], y[joint_index(p)], p)
    if k == OTHER:
        return y[0] - p[CLEARANCE] / lever
    if k == OVERLOAD:
        u = y[0] * lever
        worst = max(-u, u - p[CLEARANCE])
        if p[JOINTS_ON] != 0.0:
            worst = max(worst, pin_penetration(psi_k + y[0], y[joint_index(p)], p))
        return worst - p[MAX_PEN]
    if p[JOINTS_ON] == 0.0:
        return min(inside, psi_k + y[0] - p[PSI_PIERCE])
    c, s = cos_sin(psi_k + y[0])                   # with the pin joints: the slider's own stroke past the point
    return min(inside, (rigid_rod(c, s, p)[0] + y[joint_index(p)] - p[S_PIERCE]) / p[L3])


@njit(cache=True, error_model="numpy")
def pin_penetration(psi, z, p):
    """How far |CD| lies beyond the pins' free play (m; < 0 inside it) with the follower at ψ and the slider at
    z past the rigid chain's stroke."""
    c, s = cos_sin(psi)
    s_r = rigid_rod(c, s, p)[0]
    return abs(rod_span(c, s, s_r + z, p)[2] - p[L4]) - p[J_PLAY]


@njit(cache=True, error_model="numpy", _nrt=False)
def event_action(t, y, p, k, apply):
    """Whether event k is a restart the compiled solver run may take itself: a contact onset or release on either
    flank or in the rod's pins (the contact force's derivatives jump there; nothing in p changes), and the insertion
    switch under the smooth force–travel law (the bump starts from zero force with zero slope and curvature: a restart
    for smoothness, like a contact onset). Not the step law's switch (F_c jumps: its mode-dependent root is placed by
    the Python driver) nor the terminal overload."""
    return k == WORKING or k == OTHER or k == PINS or (k == INSERTION and p[INS_LAW] != 1.0)


@njit(cache=True, error_model="numpy")
def evaluate(t, y, p):
    """:func:`dynamics` at many samples (states in the columns of ``y``): rows of :data:`OUTPUTS` (NaN where
    the status is not 0)."""
    out = np.empty((N_OUT, t.size))
    j = joint_index(p)
    for m in range(t.size):
        ym = y[:, m]
        phi, omega, alpha, omega_m, shaft = cam_state(t[m], ym, p)
        z, z_d = (ym[j], ym[j + 1] * INV_TAU) if p[JOINTS_ON] != 0.0 else (0.0, 0.0)
        r, _ = dynamics(ym[0], ym[1] * INV_TAU, z, z_d, phi, omega, alpha, omega_m, shaft, p)
        for i in range(N_OUT):
            out[i, m] = r[i]
    return out


@njit(cache=True, error_model="numpy")
def grooves(phi, p):
    """:func:`groove` at many cam angles: rows ψ_k, ψ_k', ψ_k'', ℓ, dℓ/dφ, rising (1.0 / 0.0)."""
    out = np.empty((6, phi.size))
    for m in range(phi.size):
        out[0, m], out[1, m], out[2, m], out[3, m], out[4, m], rising, _, _ = groove(phi[m], p)
        out[5, m] = 1.0 if rising else 0.0
    return out

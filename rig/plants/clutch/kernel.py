"""Compiled (numba) equations of motion of the clutch stand — the one implementation behind
:class:`rig.plants.clutch.dynamics.ClutchDynamics`, used by the compiled DP45 stepper's inner loop and,
through thin wrappers, by the host side (static band, outputs, scipy baselines).

Everything the right-hand side needs travels in one float64 vector ``p`` (indices below): clutch
constants, friction model, the discrete state (friction mode, held cam segment, motor trip), the motor
line and the loads as a program of codes (:meth:`rig.plants.clutch.loads.Load.program`). The state is
y = (φr, ωr, φ3, ω3, *load states), rad and rad/s. Physics, symbols and sign conventions: the module
docstring of :mod:`rig.plants.clutch.dynamics`.

The entry points the compiled solvers call (:func:`rhs`, :func:`leaf_rhs`, :func:`event_value`,
:func:`event_action`) are compiled without numba's runtime (``_nrt=False``: no reference counts on their arrays;
they allocate nothing; see :mod:`rig.solvers.templates.runs`).

All compiled code of the clutch lives in this one module (numba's disk cache is invalidated by changes
to a function's own file only, not to the files of the functions it calls); it imports only the
constants LOBE and APEX.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from rig.plants.clutch.geometry import APEX, LOBE

# p layout: clutch constants, friction model, discrete state, motor line, self-lock flag, load program
(N, M, MT, J1, J3, FA1, KA, R0, MUB, MUC, L1, L2, C1, A2, R1, R2, PM, INV_VS, SMOOTH, BLOCKED,
 MODE, BASE, SEG, HELD, A0, B0, RATIO, T_OFF, TRIP_AT, LOCKED_AT, BRAKE_AT, EVENTS, LOADS) = range(33)
#: event kinds of the event table at p[EVENTS] (count, then per event: kind, state index, angle, period,
#: compiled flag — 1 for cam-segment boundaries that :func:`event_action` may handle in compiled code)
PERIODIC, CLUTCH_SWITCH, BRAKE_SWITCH = 0, 1, 2
ROW = 5
#: offsets in a brake's program from its mode slot (p[BRAKE_AT]): gain, actuator state index
BRAKE_GAIN, BRAKE_Z = -4, -1
#: load codes of :meth:`rig.plants.clutch.loads.Load.program` (interpreted by :func:`load_torque`)
STEPS, ZONE, LINEAR, BRAKE = 1, 2, 3, 4

#: how far (rad) a held segment's formula is continued past its ends before the true segment is used
HOLD_MARGIN = 0.1


@njit(cache=True)
def locate_segment(phi: float, direction: float, phi_maxI: float) -> tuple[float, int]:
    """φ, direction ↦ (lobe start angle, segment 0..3) with segments [0, φ_maxI], [φ_maxI, apex],
    [apex, lobe − φ_maxI], [lobe − φ_maxI, lobe]; on a boundary, ``direction`` > 0 picks the segment
    ahead, < 0 the one behind, 0 the one starting there (1e-9 rad resolves restarts at located events)."""
    probe = phi + (1e-9 if direction > 0 else -1e-9 if direction < 0 else 0.0)
    base = math.floor(probe / LOBE) * LOBE
    psi = probe - base
    return base, int(psi >= phi_maxI) + int(psi >= APEX) + int(psi >= LOBE - phi_maxI)


@njit(cache=True)
def segment_geometry(phi: float, base: float, seg: int, c1: float, a2: float, r1: float, r2: float,
                     phi_maxI: float) -> tuple[float, float, float, float]:
    """(k1, k2, dk1/dφ, flank) at φ by the formula of segment ``seg`` of the lobe starting at ``base``
    (c1 = r1 − r0), continued analytically up to HOLD_MARGIN past the segment's ends — so a solver step
    that overshoots a phase boundary sees a smooth right-hand side until the boundary event restarts it
    in the next segment; farther out (a trial step) the true segment is used."""
    psi = phi - base
    lo = (0.0, phi_maxI, APEX, LOBE - phi_maxI)[seg]
    hi = (phi_maxI, APEX, LOBE - phi_maxI, LOBE)[seg]
    if not lo - HOLD_MARGIN <= psi <= hi + HOLD_MARGIN:
        base, seg = locate_segment(phi, 0.0, phi_maxI)
        psi = phi - base
    flank = 1.0
    if seg >= 2:
        psi, flank = LOBE - psi, -1.0
    if seg == 0 or seg == 3:
        return flank * c1 * math.sin(psi), r1 - c1 * math.cos(psi), c1 * math.cos(psi), flank
    u = APEX - psi
    return flank * a2 * math.sin(u), r2 + a2 * math.cos(u), -a2 * math.cos(u), flank


def pack(clutch, motor, load_program: list[float], v_s: float, blocked: bool, smooth: bool) -> np.ndarray:
    """Parameter vector for the kernel (discrete state: slipping forward, segment found per call)."""
    c = clutch
    head = [c.n, c.n * c.m_t, c.m_t, c.J1, c.J3, c.F_a1, c.k_a, c.r0, c.mu_B, c.mu_C, c.L1, c.L2, c.r1 - c.r0,
            c.limits.a2, c.r1, c.r2, c.limits.phi_maxI, 1.0 / v_s, float(smooth), float(blocked),
            1.0, 0.0, 0, 0.0, motor.a0, motor.b0, motor.ratio, motor.t_off, motor.trip_at, math.nan, -1.0,
            0.0]
    assert len(head) == LOADS
    p = np.array(head + list(load_program), dtype=float)
    p[BRAKE_AT] = _switched_brakes(p)[0] if _switched_brakes(p) else -1.0
    return p


def with_events(p: np.ndarray, table: list[tuple[int, int, float, float, int]]) -> np.ndarray:
    """p with the event table appended: (kind, state index, angle, period, compiled flag) per event, in
    problem order."""
    q = np.concatenate([p, [len(table)], np.ravel(np.array(table, dtype=float).reshape(-1, ROW))])
    q[EVENTS] = len(p)
    return q


def _switched_brakes(p: np.ndarray) -> list[int]:
    """Indices of the mode slots of the stick–slip brakes in the load program of p."""
    out, i = [], LOADS + 1
    for _ in range(int(p[LOADS])):
        if int(p[i]) == BRAKE and not math.isnan(p[i + 5]):
            out.append(i + 5)
        i = _load_end(p, i)
    return out


@njit(cache=True)
def _load_end(p, i):
    """Index after the load record starting at p[i] (code, parameters, step tables: count, times, values)."""
    code = int(p[i])
    if code == STEPS:
        return i + 3 + 2 * int(p[i + 1])
    if code == ZONE:
        return i + 5
    if code == LINEAR:
        return i + 3
    return i + 8 + 2 * int(p[i + 6])                    # BRAKE


@njit(cache=True)
def geometry(phi, p, held):
    """(k1, k2, dk1/dφ, flank) at φr: in the held cam segment (``held`` and p[HELD]) or the true one."""
    if held and p[HELD] != 0.0:
        base, seg = p[BASE], int(p[SEG])
    else:
        base, seg = locate_segment(phi, 0.0, p[PM])
    return segment_geometry(phi, base, seg, p[C1], p[A2], p[R1], p[R2], p[PM])


@njit(cache=True)
def _steps(p, i, t):
    """Value at t of the left-continuous step table at p[i] = count, times, values."""
    n = int(p[i])
    k = 0
    while k < n and p[i + 1 + k] < t:
        k += 1
    return p[i + 1 + n + k]


@njit(cache=True)
def load_torque(t, phi3, w3, y, p):
    """M3 (N·m) of the load program at p[LOADS]."""
    m = 0.0
    i = LOADS + 1
    for _ in range(int(p[LOADS])):
        code = int(p[i])
        if code == STEPS:
            m += _steps(p, i + 1, t)
        elif code == ZONE:
            if p[i + 2] <= phi3 % p[i + 4] < p[i + 3]:
                m += p[i + 1]
        elif code == LINEAR:
            m += p[i + 1] + p[i + 2] * w3
        else:                                           # BRAKE: gain·F_b·tanh(ω3/ω_s) or gain·F_b·mode
            b = p[i + 5]
            m += p[i + 1] * y[4 + int(p[i + 4])] * (math.tanh(w3 / p[i + 3]) if math.isnan(b) else b)
        i = _load_end(p, i)
    return m


@njit(cache=True)
def load_rates(t, y, p, out):
    """Rates of the load states into out[4:] (brake actuators τ·dF_b/dt = F_cmd(t) − F_b)."""
    i = LOADS + 1
    for _ in range(int(p[LOADS])):
        if int(p[i]) == BRAKE:
            k = 4 + int(p[i + 4])
            out[k] = (_steps(p, i + 6, t) - y[k]) / p[i + 2]
        i = _load_end(p, i)


@njit(cache=True)
def driven_held(p):
    """True while the driven half is at rest: clamped (blocked stand) or held by a stick–slip brake."""
    return p[BLOCKED] != 0.0 or (p[BRAKE_AT] >= 0.0 and p[int(p[BRAKE_AT])] == 0.0)


@njit(cache=True)
def motor_torque(t, w1, p):
    """M1 = i·(a0 − b0·i·ω1) (N·m), 0 from the trip time on or after t_off (as LinearMotor.off)."""
    if t >= p[TRIP_AT] or t > p[T_OFF]:
        return 0.0
    return p[RATIO] * (p[A0] - p[B0] * p[RATIO] * w1)


@njit(cache=True)
def transmit(p, k1, k2, dk1, wr, w3, sb, sc):
    """(T_c, F_a, N_B) for friction signs sB, sC; T_c = N_B = NaN when the tappet self-locks in its guide
    (μ_C(|R1| + |R2|)/N_B ≥ 1)."""
    fa = p[FA1] + p[KA] * (k2 - p[R0])
    fb_rel = p[MUB] * sb
    g = p[MUC] * sc * (abs(k1 + (k2 - p[L2]) * fb_rel) + abs(k1 + (k2 - p[L1]) * fb_rel)) / (p[L2] - p[L1])
    if g >= 1.0:
        return math.nan, fa, math.nan
    nb = (fa + p[MT] * (dk1 * wr * wr - k2 * w3 * w3)) / (1.0 - g)
    nb = max(nb, 0.0)
    return p[N] * ((fa + g * nb) * k1 + fb_rel * nb * k2), fa, nb


@njit(cache=True)
def required(t, y, p, k1, k2):
    """Stuck halves: (T_c needed for ω̇r = 0, common acceleration, M1, M3)."""
    w3 = y[3]
    m1 = motor_torque(t, y[1] + w3, p)
    m3 = load_torque(t, y[2], w3, y, p)
    x = p[M] * k1 * k2 * w3 * w3
    if p[BLOCKED] != 0.0:
        return m1 + x, 0.0, m1, m3
    if driven_held(p):                                  # all at rest: the brake reacts what passes the clutch
        return m1 + x, 0.0, m1, m1 + x
    J3p = p[J3] + p[M] * k2 * k2
    tc = (J3p * (m1 + x) + p[J1] * (m3 + x)) / (p[J1] + J3p)
    return tc, (m1 - tc + x) / p[J1], m1, m3


@njit(cache=True)
def band(t, y, p, held):
    """At ωr = 0: (T_c required, T_c at σ = +1, T_c at σ = −1, N_B at +1, N_B at −1, F_a, M1, M3, a);
    the guide friction sign is sC = σ·flank (sgn v23 = sgn(k1·ωr)), +1 at k1 = 0."""
    k1, k2, dk1, flank = geometry(y[0], p, held)
    tc, a, m1, m3 = required(t, y, p, k1, k2)
    sc = flank if k1 != 0.0 else 1.0
    tp, fa, nbp = transmit(p, k1, k2, dk1, 0.0, y[3], 1.0, sc)
    tm, _, nbm = transmit(p, k1, k2, dk1, 0.0, y[3], -1.0, -sc if k1 != 0.0 else 1.0)
    return tc, tp, tm, nbp, nbm, fa, m1, m3, a


@njit(cache=True)
def core(t, y, mode, p, held):
    """(ω̇1, ω̇3, M1, M3, T_c, F_a, N_B) in friction ``mode`` (+1/−1 slipping, 0 stuck; ignored by tanh);
    a self-locking tappet gives NaN and records the first such φr in p[LOCKED_AT]."""
    phi_r, wr, w3 = y[0], y[1], y[3]
    k1, k2, dk1, flank = geometry(phi_r, p, held)
    if p[SMOOTH] != 0.0:
        sb, sc = math.tanh(k2 * wr * p[INV_VS]), math.tanh(k1 * wr * p[INV_VS])
    elif mode == 0:
        tc, a, m1, m3 = required(t, y, p, k1, k2)
        return a, a, m1, m3, tc, math.nan, math.nan
    else:
        sb, sc = float(mode), (mode * flank if k1 != 0.0 else 1.0)
    tc, fa, nb = transmit(p, k1, k2, dk1, wr, w3, sb, sc)
    if math.isnan(tc) and math.isnan(p[LOCKED_AT]):
        p[LOCKED_AT] = phi_r
    m1 = motor_torque(t, wr + w3, p)
    m3 = load_torque(t, y[2], w3, y, p)
    mm = p[M]
    k1s = mm * k1 * k1
    k3h = mm * k1 * dk1 * wr * wr                        # ½·M·k3·ωr²
    b1 = m1 - tc - k3h + mm * k1 * k2 * w3 * w3
    a11 = p[J1] + k1s
    if p[BLOCKED] != 0.0:
        return b1 / a11, 0.0, m1, m3, tc, fa, nb
    if driven_held(p):                                  # M3 = the load reaction that keeps ω̇3 = 0
        a1 = b1 / a11
        return a1, 0.0, m1, tc + k3h + k1s * a1, tc, fa, nb
    b3 = -m3 + tc + k3h - mm * k1 * k2 * w3 * (w3 + 2.0 * wr)
    a22 = p[J3] + k1s + mm * k2 * k2
    det = a11 * a22 - k1s * k1s
    return (b1 * a22 + k1s * b3) / det, (a11 * b3 + k1s * b1) / det, m1, m3, tc, fa, nb


@njit(cache=True)
def brake_need(t, y, p):
    """(brake torque needed to hold the driven half at rest, brake capacity gain·F_b) in N·m, at a state
    with ω3 = 0 and the current clutch mode (stick–slip brake at p[BRAKE_AT])."""
    s = int(p[BRAKE_AT])
    b = p[s]
    p[s] = 0.0
    m3 = core(t, y, int(p[MODE]), p, True)[3]
    other = load_torque(t, y[2], y[3], y, p)             # the held brake contributes nothing here
    p[s] = b
    return m3 - other, p[s + BRAKE_GAIN] * y[4 + int(p[s + BRAKE_Z])]


@njit(cache=True, _nrt=False)
def event_value(t, y, p, k):
    """Value of event k of the table: sin(π(y[i] − angle)/period) (phase boundaries, wrap, apex, load
    zones); clutch stick–slip: σ·ωr slipping, distance to the static band edges stuck; brake: b·ω3
    slipping, capacity − |needed torque| holding. Positive while the current mode is valid."""
    j = int(p[EVENTS]) + 1 + ROW * k
    kind = int(p[j])
    if kind == PERIODIC:
        return math.sin(math.pi / p[j + 3] * (y[int(p[j + 1])] - p[j + 2]))
    if kind == CLUTCH_SWITCH:
        if p[MODE] != 0.0:
            return p[MODE] * y[1]
        r = band(t, y, p, True)
        return min(r[1] - r[0], r[0] - r[2])
    b = p[int(p[BRAKE_AT])]
    if b != 0.0:
        return b * y[3]
    need, cap = brake_need(t, y, p)
    return cap - abs(need)


def event_function(p: np.ndarray, k: int):
    """Event k of the table in ``p`` as a Python ``g(t, y)`` (for :class:`rig.solvers.Event`)."""
    return lambda t, y: event_value(t, np.asarray(y, dtype=float), p, k)


@njit(cache=True, _nrt=False)
def event_action(t, y, p, k, apply):
    """Whether event k at (t, y) can be acted on in compiled code — a cam-segment boundary (phase
    boundary, lobe wrap) passed while slipping consistently with the mode (and the brake's mode still
    valid), where the Python reset would only re-select the held segment; with ``apply``, do that."""
    j = int(p[EVENTS]) + 1 + ROW * k
    wr = y[1]
    if p[j + 4] == 0.0 or wr == 0.0 or p[MODE] * wr <= 0.0:
        return False
    if p[BRAKE_AT] >= 0.0:
        b = p[int(p[BRAKE_AT])]
        if b != 0.0:
            if b * y[3] <= 0.0:
                return False
        else:
            need, cap = brake_need(t, y, p)
            if abs(need) > cap:
                return False
    if apply:
        base, seg = locate_segment(y[0], wr, p[PM])
        p[BASE], p[SEG] = base, seg
    return True


@njit(cache=True, _nrt=False)
def rhs(t, y, p, out):
    """dy/dt into ``out`` in the current friction mode and held cam segment (p[MODE], p[BASE], p[SEG])."""
    r = core(t, y, int(p[MODE]), p, True)
    out[0] = y[1]
    out[1] = r[0] - r[1]
    out[2] = y[3]
    out[3] = r[1]
    if y.size > 4:
        load_rates(t, y, p, out)


# ---- the leaf-spring coupling (rig.plants.clutch.leaf_dynamics) -------------------------------------------------
#: its constants in the same vector, in slots of flat-tappet constants it does not use; N = factor·n, J1, J3, R1
#: (lobe arc radius) and INV_VS (1/ω_s of its tanh friction) keep their meaning; motor, loads and events as above
LEAF_A1, LEAF_DR, LEAF_HALF, LEAF_K, LEAF_MU, LEAF_PERIOD = C1, R0, L1, KA, MUB, A2
J1_SLOT, J3_SLOT = J1, J3         # pack_leaf's arguments J1, J3 shadow the slot names


def pack_leaf(leaf, motor, load_program: list[float], J1: float, J3: float, omega_s: float) -> np.ndarray:
    """Parameter vector of the leaf coupling's kernel (:func:`leaf_rhs`); no stick–slip brake (a smooth ODE)."""
    head = [0.0] * LOADS
    values = {N: leaf.factor * leaf.n, J1_SLOT: J1, J3_SLOT: J3, LEAF_A1: leaf.a1, LEAF_DR: leaf.r1 - leaf.r0,
              LEAF_HALF: 0.5 * leaf.span, LEAF_K: 3.0 * leaf.E * leaf.second_moment * leaf.span, LEAF_MU: leaf.mu,
              LEAF_PERIOD: leaf.period, R1: leaf.r1, INV_VS: 1.0 / omega_s, A0: motor.a0, B0: motor.b0,
              RATIO: motor.ratio, T_OFF: motor.t_off, TRIP_AT: motor.trip_at, LOCKED_AT: math.nan,
              BRAKE_AT: -1.0}
    for slot, value in values.items():
        head[slot] = value
    p = np.array(head + list(load_program), dtype=float)
    if _switched_brakes(p):
        raise ValueError("the leaf-spring stand is integrated as a smooth ODE: its brake needs friction = \"tanh\", "
                         "not \"stick_slip\"")
    return p


@njit(cache=True)
def leaf_coupling(phi_r, wr, p):
    """(T_c N·m, leaf force F_v N) at relative angle and speed: φ_r reduced into a leaf's period, contact x = a1 sinφ
    from mid-span, deflection y = (r1 − r0) − a1 cosφ, F_v = 3EI·l·y/((l/2 − x)²(l/2 + x)²),
    T_c = factor·n·F_v·[x + μ (r1 − a1 cosφ) tanh(ωr/ω_s)]."""
    period = p[LEAF_PERIOD]
    phi = phi_r - period * np.round(phi_r / period)
    a1 = p[LEAF_A1]
    x, c = a1 * math.sin(phi), a1 * math.cos(phi)
    half = p[LEAF_HALF]
    force = p[LEAF_K] * (p[LEAF_DR] - c) / ((half - x) ** 2 * (half + x) ** 2)
    arm = x + p[LEAF_MU] * (p[R1] - c) * math.tanh(wr * p[INV_VS])
    return p[N] * force * arm, force


@njit(cache=True)
def samples(t, Y, modes, brakes, p, brake_at):
    """Per sample (columns of ``Y``, friction mode ``modes``, stick–slip brake mode ``brakes`` written into
    p[brake_at] when ≥ 0): (ω̇1, ω̇3, M1, M3, T_c, F_a, N_B) rows; a stuck sample's F_a and N_B from the static band,
    N_B interpolated where the required T_c lies in it (the split of static friction is indeterminate). A row whose
    band is undefined is NaN in F_a (the caller reports it)."""
    n = t.size
    vals = np.empty((n, 7))
    y = np.empty(Y.shape[0])
    for k in range(n):
        y[:] = Y[:, k]
        if brake_at >= 0:
            p[brake_at] = brakes[k]
        c = core(t[k], y, modes[k], p, False)
        for j in range(7):
            vals[k, j] = c[j]
        if modes[k] == 0:
            tc, tp, tm, nbp, nbm, fa = band(t[k], y, p, False)[:6]
            if math.isnan(tp) or math.isnan(tm):
                vals[k, 5] = math.nan
                continue
            w = 0.5 if tp == tm else (tc - tm) / (tp - tm)
            vals[k, 5], vals[k, 6] = fa, nbm + w * (nbp - nbm)
    return vals


@njit(cache=True, _nrt=False)
def leaf_rhs(t, y, p, out):
    """dy/dt of the leaf-spring stand into ``out``: J1 ω̇1 = M1 − T_c, J3 ω̇3 = T_c − M3 (state as :func:`rhs`)."""
    tc = leaf_coupling(y[0], y[1], p)[0]
    a1 = (motor_torque(t, y[1] + y[3], p) - tc) / p[J1]
    a3 = (tc - load_torque(t, y[2], y[3], y, p)) / p[J3]
    out[0] = y[1]
    out[1] = a1 - a3
    out[2] = y[3]
    out[3] = a3
    if y.size > 4:
        load_rates(t, y, p, out)


@njit(cache=True)
def leaf_outputs(t, Y, p):
    """Per sample (columns of ``Y``): M1, M3, T_c, F_v and ω̇3 (N·m, N, rad/s²)."""
    n = t.size
    out = np.empty((5, n))
    for k in range(n):
        y = Y[:, k]                   # read only: no per-sample copy
        tc, force = leaf_coupling(y[0], y[1], p)
        m1 = motor_torque(t[k], y[1] + y[3], p)
        m3 = load_torque(t[k], y[2], y[3], y, p)
        out[0, k], out[1, k], out[2, k], out[3, k], out[4, k] = m1, m3, tc, force, (tc - m3) / p[J3]
    return out

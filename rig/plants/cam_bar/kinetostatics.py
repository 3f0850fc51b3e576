"""Level-1 kinetostatics of the pin-insertion mechanism (MODELS §3.3), link by link, compiled point by point.

Notation: ``R_ij`` is the force link i exerts on link j (1 frame, 2 cam, 3 follower, 4 rod, 5 slider),
components in the fixed frame (N); moments are counter-clockwise positive (N·m). Free-body diagrams
(d'Alembert: inertia forces −m·a_G and moments −J·ε added to the applied loads):

* slider 5 (translates along y = e_sk, x_D = s0 − s): −R54 + R15 + (F_c, −m5·g) − m5·(ẍ_D, 0) = 0 with
  R15 = (friction, N), friction = −μ·|N|·sign(ẋ_D) (zero at rest);
* rod 4 (C→D, CoG at mid-link, J4 about the CoG): moment about C: (D − C) × R54 + (G4 − C) × F4 − J4·ϑ̈ = 0,
  forces: R34 + R54 + F4 = 0, F4 = m4·(g − a_G4);
* follower 3 (pivot B0, J3 about B0, CoG at a3 along the arm): moment about B0:
  B_R × R23 + C × (−R34) + G3 × m3·g − M_e = J3·ψ̈, forces: R13 + R23 − R34 + m3·g = m3·a_G3.

R23 acts through the roller centre B_R along the normal n of the relative path of B_R on the cam, oriented
so that it turns the follower towards larger ψ (against the spring): its scalar ``R23n`` > 0 means the
working flank carries the load, < 0 the other flank (a flank switch). The cam drive torque follows from
the cam's moment balance about A0 (cam inertia and bearing friction neglected).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from math import degrees
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

if TYPE_CHECKING:
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism, State

TRANSMISSION_TOL = 1e-6  # |lever of the contact normal about B0| / |B_R| below this: cam cannot drive


class JammingError(ValueError):
    """No consistent Coulomb friction state in the slider guide (self-locking)."""


@dataclass(frozen=True)
class Vec:
    """A planar force (N): components and magnitude."""

    x: np.ndarray
    y: np.ndarray

    @property
    def mag(self) -> np.ndarray:
        return np.hypot(self.x, self.y)


@dataclass(frozen=True)
class Kinetostatics:
    """Results at each cam angle (SI). ``M23``: cam moment on the follower about B0 without the spring;
    ``M_e``: spring moment (acting towards smaller ψ); ``M_sigma`` = M23 + M_e: cam moment with the spring;
    ``R23n``: signed contact force (> 0 working flank); ``drive_torque``: on the cam shaft, positive when
    the drive delivers power; ``F_rod``: axial rod force at the sensor (tension > 0) plus the sensor preload;
    ``b_min``: minimum slider guide length against self-locking, 2μ·|M_D|/P (m; nan at rest)."""

    R34: Vec
    R54: Vec
    R15: Vec
    R23: Vec
    R13: Vec
    R23n: np.ndarray
    M23: np.ndarray
    M_e: np.ndarray
    M_sigma: np.ndarray
    drive_torque: np.ndarray
    rod_tension: np.ndarray
    F_rod: np.ndarray
    F_c: np.ndarray
    friction: np.ndarray
    pressure_angle: np.ndarray
    b_min: np.ndarray


# per-point results of the compiled solve, in this order (rows of its output)
_ROWS = ("r34x", "r34y", "r54x", "r54y", "friction", "normal", "r23x", "r23y", "r13x", "r13y", "lam", "m23",
         "m_sigma", "drive", "tension", "pressure", "b_min")


@njit(cache=True, error_model="numpy")
def _solve_points(omega, alpha, s_p, s_pp, psi_p, psi_pp, theta_p, theta_pp, cp, sp, ct, st, f_c, m_e, mu_, prm):
    """The free bodies of the module docstring at each point (1-D arrays; ``f_c`` insertion force, ``m_e`` spring
    moment, ``mu_`` guide friction coefficient). ``prm``: g, L3, l3, l4, a3, m3, m4, m5, J3, J4, x_A0, y_A0, cam
    direction, sensor position ξ, x_s5, e5. Returns (rows :data:`_ROWS` × points, first jammed point, first point
    where the contact normal passes through the follower pivot), −1 where there is none."""
    g, L3, l3, l4, a3, m3, m4, m5, J3, J4, xa0, ya0, d, xi, x_s5, e5 = (
        prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7], prm[8], prm[9], prm[10], prm[11],
        prm[12], prm[13], prm[14], prm[15])
    n = omega.size
    out = np.empty((17, n))
    jam, bad = -1, -1
    w5 = m5 * g
    frac = 0.5 * (1.0 + xi)
    seg = m4 * (1.0 - xi)
    for i in range(n):
        w, mu = omega[i], mu_[i]
        w2 = w ** 2
        psi_d, theta_d = w * psi_p[i], w * theta_p[i]
        psi_dd = w2 * psi_pp[i] + alpha[i] * psi_p[i]
        theta_dd = w2 * theta_pp[i] + alpha[i] * theta_p[i]
        s_d = w * s_p[i]
        s_dd = w2 * s_pp[i] + alpha[i] * s_p[i]
        c_p, s_p_, c_t, s_t = cp[i], sp[i], ct[i], st[i]
        # accelerations of the rod joint C and the rod CoG G4
        acx = L3 * (-psi_dd * s_p_ - psi_d ** 2 * c_p)
        acy = L3 * (psi_dd * c_p - psi_d ** 2 * s_p_)
        adc_x = l4 * (-theta_dd * s_t - theta_d ** 2 * c_t)  # a_D − a_C
        adc_y = l4 * (theta_dd * c_t - theta_d ** 2 * s_t)
        f4x = -m4 * (acx + 0.5 * adc_x)
        f4y = -m4 * (g + acy + 0.5 * adc_y)
        dx, dy = l4 * c_t, l4 * s_t
        m4_moment = 0.5 * (dx * f4y - dy * f4x) - J4 * theta_dd
        # slider 5 + rod moment about C → R54 with Coulomb friction μ|N| (N = Y + m5 g): first N ≥ 0, else N < 0
        q = f_c[i] + m5 * s_dd  # F_c − m5·ẍ_D with ẍ_D = −s̈
        sv = -1.0 if s_d > 0.0 else 1.0 if s_d < 0.0 else 0.0 * s_d     # −sign(ṡ): sign of ẋ_D (NaN kept)
        c = mu * sv
        y = (dy * (q - c * w5) - m4_moment) / (dx + c * dy)
        if y + w5 < 0.0 and c != 0.0:
            y = (dy * (q + c * w5) - m4_moment) / (dx - c * dy)
            if y + w5 > 0.0 and jam < 0:
                jam = i
        normal = y + w5
        friction = -mu * abs(normal) * sv
        x = q + friction
        r34x, r34y = -x - f4x, -y - f4y
        # follower 3: moment about B0 without the cam → M23, then the contact force along the normal
        cx, cy = L3 * c_p, L3 * s_p_
        m_other = -(cx * r34y - cy * r34x) - m3 * g * a3 * c_p
        m23 = J3 * psi_dd - m_other
        m_sigma = m23 + m_e[i]
        bx, by = l3 * c_p, l3 * s_p_
        wx, wy = bx - xa0, by - ya0
        tx = l3 * psi_p[i] * -s_p_ + d * wy  # tangent of the relative path: dw/dφ − d·J·w
        ty = l3 * psi_p[i] * c_p - d * wx
        lever_raw = bx * tx + by * ty  # B_R × (J t) = B_R · t
        t_norm = math.hypot(tx, ty)
        if abs(lever_raw) < TRANSMISSION_TOL * l3 * t_norm and bad < 0:
            bad = i
        sgn = 1.0 if lever_raw > 0.0 else -1.0 if lever_raw < 0.0 else 0.0
        nx, ny = -ty * sgn / t_norm, tx * sgn / t_norm
        lam = m_sigma / (abs(lever_raw) / t_norm)
        r23x, r23y = lam * nx, lam * ny
        a3x, a3y = a3 * (-psi_dd * s_p_ - psi_d ** 2 * c_p), a3 * (psi_dd * c_p - psi_d ** 2 * s_p_)
        # axial rod force at the sensor section ξ (uniform slender rod) and the guide length against self-locking
        # (drawer rule b > 2μ·h, h = load moment about D / driving force); the slider is driven along its motion
        # by the rod's push and, when it decelerates, by its own inertia force (+m5·s̈ along x)
        moment_d = m5 * g * x_s5 + f_c[i] * e5  # load moments about D, levers taken to add
        push = max(-x * sv, 0.0) + max(m5 * s_dd * sv, 0.0)
        out[0, i], out[1, i], out[2, i], out[3, i], out[4, i], out[5, i] = r34x, r34y, x, y, friction, normal
        out[6, i], out[7, i] = r23x, r23y
        out[8, i] = m3 * a3x - r23x + r34x
        out[9, i] = m3 * (a3y + g) - r23y + r34y
        out[10, i], out[11, i], out[12, i] = lam, m23, m_sigma
        out[13, i] = d * lam * (wx * ny - wy * nx)
        out[14, i] = x * c_t + y * s_t - seg * ((acx + frac * adc_x) * c_t + (g + acy + frac * adc_y) * s_t)
        out[15, i] = math.acos(min(max(abs(-s_p_ * nx + c_p * ny), 0.0), 1.0))
        out[16, i] = math.nan if sv == 0.0 else 2.0 * mu * moment_d / push if push > 0.0 else math.inf
    return out, jam, bad


def solve(mech: "PinInsertionMechanism", st: "State", k: float) -> Kinetostatics:
    """Kinetostatics for the prescribed motion ``st`` with spring rate ``k`` (N/m) (compiled, point by point:
    :func:`_solve_points`). Raises :class:`JammingError` at the first angle where the slider guide self-locks
    and ValueError at the first where the cam cannot drive the follower."""
    f_c = mech.insertion_force(st.s, st.s_p)
    m_e = mech.spring_moment(st.psi, k)
    arrays = (st.omega, st.alpha, st.s_p, st.s_pp, st.psi_p, st.psi_pp, st.theta_p, st.theta_pp, st.trig.cp,
              st.trig.sp, st.trig.ct, st.trig.st, f_c, m_e, mech.mu)
    shape = np.broadcast_shapes(*(np.shape(a) for a in arrays))
    flat = [_column(a, shape) for a in arrays]
    prm = np.array([mech.g, mech.L3, mech.l3, mech.l4, mech.a3, mech.m3, mech.m4, mech.m5, mech.J3, mech.J4,
                    mech.x_A0, mech.y_A0, float(mech.cam_direction), mech.sensor_position, mech.x_s5, mech.e5])
    out, jam, bad = _solve_points(*flat, prm)
    phi = np.broadcast_to(st.phi, shape).ravel() if max(jam, bad) >= 0 else None   # only to name the angle
    if jam >= 0:
        raise JammingError(f"slider self-locks in its guide at cam angle φ = {degrees(float(phi[jam])):.4g}° "
                           f"(μ = {float(flat[-1][jam]):g}): no Coulomb friction state balances the rod")
    if bad >= 0:
        raise ValueError(f"cam cannot drive the follower at φ = {degrees(float(phi[bad])):.4g}°: the contact "
                         f"normal passes through the follower pivot (x_A0 = {mech.x_A0 * 1e3:g} mm, "
                         f"y_A0 = {mech.y_A0 * 1e3:g} mm, l3 = {mech.l3 * 1e3:g} mm)")
    r = dict(zip(_ROWS, (row.reshape(shape) for row in out)))
    return Kinetostatics(Vec(r["r34x"], r["r34y"]), Vec(r["r54x"], r["r54y"]), Vec(r["friction"], r["normal"]),
                         Vec(r["r23x"], r["r23y"]), Vec(r["r13x"], r["r13y"]), r["lam"], r["m23"], _full(m_e, shape),
                         r["m_sigma"], r["drive"], r["tension"], r["tension"] + mech.sensor_preload, _full(f_c, shape),
                         r["friction"], r["pressure"], r["b_min"])


def _column(a: np.ndarray | float, shape: tuple[int, ...]) -> np.ndarray:
    """``a`` broadcast to ``shape`` as a flat, contiguous, writeable float64 array (the one kind the kernel is
    compiled for; copied only when ``a`` is not one already)."""
    a = np.asarray(a, dtype=np.float64)
    if a.shape == shape and a.flags.c_contiguous and a.flags.writeable:
        return a.reshape(-1)
    return np.broadcast_to(a, shape).flatten()


def _full(a: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``a`` as an array of ``shape`` (its own when it has it)."""
    return a if np.shape(a) == shape else np.broadcast_to(a, shape).copy()

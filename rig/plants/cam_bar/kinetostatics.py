"""Level-1 kinetostatics of the pin-insertion mechanism (MODELS §3.3), link by link, vectorised.

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

from dataclasses import dataclass
from math import degrees
from typing import TYPE_CHECKING

import numpy as np

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


def _guide(mech: "PinInsertionMechanism", dy: np.ndarray, dx: np.ndarray, q: np.ndarray, m4_moment: np.ndarray,
           sv: np.ndarray, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve slider + rod moment for R54 = (X, Y) with Coulomb friction μ|N| (N = Y + m5 g)."""
    w5 = mech.m5 * mech.g
    c = mech.mu * sv  # first assume N ≥ 0, then redo the angles where that is inconsistent with N < 0
    y_sol = (dy * (q - c * w5) - m4_moment) / (dx + c * dy)
    flip = (y_sol + w5 < 0.0) & (c != 0.0)
    if flip.any():
        cf = -c[flip]
        y_neg = (dy[flip] * (q[flip] - cf * w5) - m4_moment[flip]) / (dx[flip] + cf * dy[flip])
        if np.any(y_neg + w5 > 0.0):
            i = int(np.flatnonzero(flip)[np.argmax(y_neg + w5 > 0.0)])
            raise JammingError(f"slider self-locks in its guide at cam angle φ = {degrees(float(phi.flat[i])):.4g}° "
                               f"(μ = {mech.mu:g}): no Coulomb friction state balances the rod")
        y_sol[flip] = y_neg
    n = y_sol + w5
    x_sol = q - mech.mu * np.abs(n) * sv
    return x_sol, y_sol


def solve(mech: "PinInsertionMechanism", st: "State", k: float) -> Kinetostatics:
    """Kinetostatics for the prescribed motion ``st`` with spring rate ``k`` (N/m)."""
    g, L3, l4, a3 = mech.g, mech.L3, mech.l4, mech.a3
    cp, sp, ct, st_ = st.trig.cp, st.trig.sp, st.trig.ct, st.trig.st
    w2 = st.omega ** 2
    psi_d, theta_d = st.omega * st.psi_p, st.omega * st.theta_p
    psi_dd = w2 * st.psi_pp + st.alpha * st.psi_p
    theta_dd = w2 * st.theta_pp + st.alpha * st.theta_p
    s_d = st.omega * st.s_p
    s_dd = w2 * st.s_pp + st.alpha * st.s_p

    # accelerations of the rod joint C and the rod CoG G4
    acx = L3 * (-psi_dd * sp - psi_d ** 2 * cp)
    acy = L3 * (psi_dd * cp - psi_d ** 2 * sp)
    adc_x = l4 * (-theta_dd * st_ - theta_d ** 2 * ct)  # a_D − a_C
    adc_y = l4 * (theta_dd * ct - theta_d ** 2 * st_)
    f4x = -mech.m4 * (acx + 0.5 * adc_x)
    f4y = -mech.m4 * (g + acy + 0.5 * adc_y)
    dx, dy = l4 * ct, l4 * st_
    m4_moment = 0.5 * (dx * f4y - dy * f4x) - mech.J4 * theta_dd

    # slider 5 + rod moment about C → R54
    f_c = mech.insertion_force(st.s, st.s_p)
    q = f_c + mech.m5 * s_dd  # F_c − m5·ẍ_D with ẍ_D = −s̈
    sv = -np.sign(s_d)  # sign of the slider velocity ẋ_D
    r54x, r54y = _guide(mech, dy, dx, q, m4_moment, sv, st.phi)
    normal = r54y + mech.m5 * g
    friction = -mech.mu * np.abs(normal) * sv
    r34x, r34y = -r54x - f4x, -r54y - f4y

    # follower 3: moment about B0 without the cam → M23, then the contact force along the normal
    cx, cy = L3 * cp, L3 * sp
    m_other = -(cx * r34y - cy * r34x) - mech.m3 * g * a3 * cp
    m23 = mech.J3 * psi_dd - m_other
    m_e = mech.spring_moment(st.psi, k)
    m_sigma = m23 + m_e
    bx, by = mech.l3 * cp, mech.l3 * sp
    wx, wy = bx - mech.x_A0, by - mech.y_A0
    d = mech.cam_direction
    tx = mech.l3 * st.psi_p * -sp + d * wy  # tangent of the relative path: dw/dφ − d·J·w
    ty = mech.l3 * st.psi_p * cp - d * wx
    lever_raw = bx * tx + by * ty  # B_R × (J t) = B_R · t
    t_norm = np.hypot(tx, ty)
    bad = np.abs(lever_raw) < TRANSMISSION_TOL * mech.l3 * t_norm
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"cam cannot drive the follower at φ = {degrees(float(st.phi.flat[i])):.4g}°: the contact "
                         f"normal passes through the follower pivot (x_A0 = {mech.x_A0 * 1e3:g} mm, "
                         f"y_A0 = {mech.y_A0 * 1e3:g} mm, l3 = {mech.l3 * 1e3:g} mm)")
    sgn = np.sign(lever_raw)
    nx, ny = -ty * sgn / t_norm, tx * sgn / t_norm
    lam = m_sigma / (np.abs(lever_raw) / t_norm)
    r23x, r23y = lam * nx, lam * ny
    a3x, a3y = a3 * (-psi_dd * sp - psi_d ** 2 * cp), a3 * (psi_dd * cp - psi_d ** 2 * sp)
    r13x = mech.m3 * a3x - r23x + r34x
    r13y = mech.m3 * (a3y + g) - r23y + r34y
    drive = d * lam * (wx * ny - wy * nx)
    pressure = np.arccos(np.clip(np.abs(-sp * nx + cp * ny), 0.0, 1.0))

    # axial rod force at the sensor section ξ (uniform slender rod) and the guide length
    xi = mech.sensor_position
    ex, ey = ct, st_
    frac = 0.5 * (1.0 + xi)
    seg = mech.m4 * (1.0 - xi)
    tension = r54x * ex + r54y * ey - seg * ((acx + frac * adc_x) * ex + (g + acy + frac * adc_y) * ey)
    # guide length against self-locking (drawer rule b > 2μ·h, h = load moment about D / driving force); the
    # slider is driven along its motion by the rod's push and, when it decelerates, by its own inertia force
    moment_d = mech.m5 * g * mech.x_s5 + f_c * mech.e5  # load moments about D, levers taken to add
    push = np.maximum(-r54x * sv, 0.0) + np.maximum(mech.m5 * s_dd * sv, 0.0)  # inertia force is +m5·s̈ along x
    b_min = np.full_like(push, np.nan)
    moving = sv != 0.0
    b_min[moving] = np.inf
    np.divide(2.0 * mech.mu * moment_d, push, out=b_min, where=moving & (push > 0.0))
    return Kinetostatics(Vec(r34x, r34y), Vec(r54x, r54y), Vec(friction, normal), Vec(r23x, r23y), Vec(r13x, r13y),
                         lam, m23, m_e, m_sigma, drive, tension, tension + mech.sensor_preload, f_c, friction,
                         pressure, b_min)

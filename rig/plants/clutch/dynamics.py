"""2-DOF Lagrange dynamics of the flat-tappet clutch on a stand (MODELS.md §4.3).

State y = (φ1, ω1, φ3, ω3, *load states) in rad, rad/s. With M = n·m_t, k3 = 2·k1·dk1/dφ:

    (J1 + M k1²) φ̈1 − M k1² φ̈3 = M1 − T_c − ½M k3 ωr² + M k1 k2 ω3²
    (J3 + M k1² + M k2²) φ̈3 − M k1² φ̈1 = −M3 + T_c + ½M k3 ωr² − M k1 k2 ω3² − 2M k1 k2 ωr ω3

T_c = n[(F_a + F_fC) k1 + F_fB k2] is the torque the tappets pass to the driven half. Friction (signed
Coulomb, regularised sgn(v) ≈ tanh(v/v_s)): F_fB = μ_B N_B sB at the cam face (v21 = k2 ωr),
F_fC = μ_C (|R1| + |R2|) sC in the guide (v23 = k1 ωr). Quasi-static tappet balance (docs/clutch.md):
N_B = F_a + F_fC + m_t (dk1 ωr² − k2 ω3²), guide reactions R1 = N_B (k1 + (k2 − L2) μ_B sB)/(L2 − L1),
R2 = −N_B (k1 + (k2 − L1) μ_B sB)/(L2 − L1), solved in closed form for N_B.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from rig.plants.clutch.flat_tappet import FlatTappetClutch
from rig.plants.clutch.geometry import APEX, LOBE
from rig.plants.clutch.loads import Load, LinearMotor
from rig.solvers import Event, EventRecord, Problem, SolverDivergence


class ClutchDynamics:
    """Equations of motion of clutch + motor + load; ``blocked=True`` clamps the driven half (ω3 ≡ 0).

    ``v_s`` (m/s) is the velocity scale of the tanh friction regularisation; ``J_down`` (kg·m²) is the
    part of J3 downstream of the torque meter (flywheel, brake drum), used for the meter reading.
    """

    def __init__(self, clutch: FlatTappetClutch, motor: LinearMotor, load: Load, v_s: float = 0.01,
                 blocked: bool = False, J_down: float = 0.0):
        if not v_s > 0:
            raise ValueError(f"ClutchDynamics: friction velocity scale v_s = {v_s!r} m/s must be positive")
        if not 0 <= J_down <= clutch.J3:
            raise ValueError(f"ClutchDynamics: J_down = {J_down} kg*m^2 must lie in [0, J3 = {clutch.J3}]")
        self.clutch, self.motor, self.load = clutch, motor, load
        self.v_s, self.blocked, self.J_down = v_s, blocked, J_down
        self.core = self._make_core()

    def _make_core(self) -> Callable[[float, tuple], tuple]:
        c = self.clutch
        geom = c.scalar_geometry()
        n, m, J1, J3 = c.n, c.m_t, c.J1, c.J3
        M = n * m
        Fa1, ka, r0, muB, muC, L1, L2 = c.F_a1, c.k_a, c.r0, c.mu_B, c.mu_C, c.L1, c.L2
        L = L2 - L1
        inv_vs = 1.0 / self.v_s
        motor, load, blocked = self.motor, self.load, self.blocked
        tanh = math.tanh

        def core(t: float, y: tuple) -> tuple:
            phi1, w1, phi3, w3 = y[0], y[1], y[2], y[3]
            z = y[4:]
            wr = w1 - w3
            k1, k2, dk1 = geom(phi1 - phi3)
            fa = Fa1 + ka * (k2 - r0)
            sb = tanh(k2 * wr * inv_vs)
            sc = tanh(k1 * wr * inv_vs)
            fb_rel = muB * sb
            rsum = abs(k1 + (k2 - L2) * fb_rel) + abs(k1 + (k2 - L1) * fb_rel)
            den = 1.0 - muC * sc * rsum / L
            if den <= 0.0:
                raise SolverDivergence(f"tappet self-locks in its guide (mu_C*(|R1|+|R2|)/N_B >= 1 at "
                                       f"relative angle {math.degrees(phi1 - phi3):.4g} deg)", t, y)
            nb = (fa + m * (dk1 * wr * wr - k2 * w3 * w3)) / den
            if nb < 0.0:
                nb = 0.0
            ffc = muC * sc * rsum / L * nb
            tc = n * ((fa + ffc) * k1 + fb_rel * nb * k2)
            m1 = motor.torque(t, w1)
            m3 = load.torque(t, phi3, w3, z)
            k1s = M * k1 * k1
            k3h = M * k1 * dk1 * wr * wr            # ½·M·k3·ωr²
            b1 = m1 - tc - k3h + M * k1 * k2 * w3 * w3
            if blocked:
                return b1 / (J1 + k1s), 0.0, m1, m3, tc, fa, nb
            b3 = -m3 + tc + k3h - M * k1 * k2 * w3 * (w3 + 2.0 * wr)
            a11, a22 = J1 + k1s, J3 + k1s + M * k2 * k2
            det = a11 * a22 - k1s * k1s
            return (b1 * a22 + k1s * b3) / det, (a11 * b3 + k1s * b1) / det, m1, m3, tc, fa, nb

        return core

    def rhs(self, t: float, y: tuple) -> tuple:
        """dy/dt for the solvers (tuple in, tuple out)."""
        a1, a3 = self.core(t, y)[:2]
        z = y[4:]
        if not z:
            return (y[1], a1, y[3], a3)
        return (y[1], a1, y[3], a3, *self.load.rates(t, y[2], y[3], z))

    def initial_state(self, omega: float = 0.0, phi_r: float = 0.0) -> tuple:
        """Both halves at speed ``omega`` (rad/s), relative angle ``phi_r`` (rad), loads at rest."""
        return (phi_r, omega, 0.0, 0.0 if self.blocked else omega, *self.load.initial_state())

    def energy(self, y) -> float:
        """Kinetic energy + spring energy (J) for a state (used to check conservation)."""
        c = self.clutch
        g = c.geometry(y[0] - y[2])
        k1, k2, s = float(g["k1"]), float(g["k2"]), float(g["s"])
        wr, w3 = y[1] - y[3], y[3]
        kin = 0.5 * c.J1 * y[1] ** 2 + 0.5 * c.n * c.m_t * (k1 ** 2 * wr ** 2 + k2 ** 2 * w3 ** 2) + 0.5 * c.J3 * w3 ** 2
        return kin + c.n * (c.F_a1 * s + 0.5 * c.k_a * s * s)

    def events(self, on_apex: Callable[[EventRecord], bool] | None = None) -> list[Event]:
        """Phase boundaries (restart), lobe wrap and apex (recorded; ``on_apex`` is the apex event's
        action), load angle switches (restart)."""
        lim = self.clutch.limits
        out = [Event(_periodic(b, LOBE, 0, 2), "phase_boundary", restart=True)
               for b in (lim.phi_maxI, LOBE - lim.phi_maxI)]
        out.append(Event(_periodic(0.0, LOBE, 0, 2), "lobe_wrap"))
        out.append(Event(_periodic(APEX, LOBE, 0, 2), "apex", action=on_apex))
        out += [Event(_periodic(a, p, 2, None), "load_zone", restart=True) for a, p in self.load.angle_breaks()]
        return out

    def problem(self, y0: tuple, on_apex: Callable[[EventRecord], bool] | None = None) -> Problem:
        """Problem for :func:`rig.solvers.integrate` with all events and time breaks."""
        breaks = sorted(set(self.load.time_breaks()) | set(self.motor.time_breaks()))
        return Problem(self.rhs, y0, self.events(on_apex), breaks)

    def outputs(self, t: np.ndarray, Y: np.ndarray) -> dict[str, np.ndarray]:
        """Physical truth at samples: angles, speeds, φ_r, ω_r, M1, M3, torque meter M_t, T_c, F_a, N_B."""
        vals = np.array([self.core(ti, tuple(yi)) for ti, yi in zip(t, Y.T)]).reshape(len(t), 7)
        a3 = vals[:, 1]
        out = {"phi1": Y[0], "omega1": Y[1], "phi3": Y[2], "omega3": Y[3], "phi_r": Y[0] - Y[2],
               "omega_r": Y[1] - Y[3], "M1": vals[:, 2], "M3": vals[:, 3], "T_c": vals[:, 4],
               "F_a": vals[:, 5], "N_B": vals[:, 6]}
        out["M_t"] = vals[:, 4] if self.blocked else vals[:, 3] + self.J_down * a3
        return out


def _periodic(angle: float, period: float, i: int, j: int | None) -> Callable[[float, tuple], float]:
    """g = sin(π(θ − angle)/period) with θ = y[i] − y[j] (or y[i]); zero at angle + k·period."""
    k = math.pi / period
    sin = math.sin
    if j is None:
        return lambda t, y: sin(k * (y[i] - angle))
    return lambda t, y: sin(k * (y[i] - y[j] - angle))

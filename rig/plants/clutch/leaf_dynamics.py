"""2-DOF dynamics of the leaf-spring coupling on the dynamic stand (MODELS §4.4–4.5).

The coupling the thesis ran on the dynamic stand had tappets degenerated into multi-leaf springs: each leaf a
simply supported beam of span l, deflected by a lobe (:class:`rig.plants.clutch.variants.LeafSpringClutch`):
contact x = a1 sinφ from mid-span, deflection y = r1 − r0 − a1 cosφ, force F_v = 3EI·l·y/((l/2 − x)²(l/2 + x)²),
torque T = n F_v [x + μ (r1 − a1 cosφ)·s]. It carries torque up to the disengagement angle φ_d (≈ 45°, the
source's value), where the lobe slides off the leaf end and meets the next leaf at −φ_d: the characteristic is
periodic in φ_r with period 2φ_d and jumps from +T(φ_d) to −T(φ_d) there (a restart of the solver; each crossing
is a disengagement).

Same 2-DOF model as the flat-tappet coupling (MODELS §4.3) with massless leaves (the leaf's own inertia is
neglected, m_t → 0: the source gives no leaf mass): J1 ω̇1 = M1 − T_c, J3 ω̇3 = T_c − M3. Friction between lobe
and leaf is regularised, s = tanh(ω_r/ω_s) (``omega_s``; MODELS: "regularise sgn or implement stick–slip, and say
which" — regularised here). State y = (φr, ωr, φ3, ω3, *load states) as :class:`ClutchDynamics`, whose stand
(:class:`rig.plants.clutch.stand.ClutchStand`) drives this model too.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from rig.plants.clutch.loads import LinearMotor, Load, LoadSum
from rig.plants.clutch.variants import LeafSpringClutch
from rig.solvers import Event, Problem


class LeafDynamics:
    """Leaf-spring coupling ``leaf`` between motor (inertia ``J1`` with the driving half) and load (``J3`` with
    the driven half, ``J_down`` of it behind the torque meter), friction regularised with ``omega_s`` (rad/s)."""

    blocked = False

    def __init__(self, leaf: LeafSpringClutch, motor: LinearMotor, load: Load, J1: float, J3: float,
                 J_down: float = 0.0, omega_s: float = 1.0):
        if not (J1 > 0.0 and J3 > 0.0 and omega_s > 0.0):
            raise ValueError(f"leaf coupling: need J1 > 0, J3 > 0, omega_s > 0 (J1 = {J1}, J3 = {J3}, "
                             f"omega_s = {omega_s})")
        if not 0.0 <= J_down <= J3:
            raise ValueError(f"leaf coupling: J_down = {J_down} kg*m^2 must lie in [0, J3 = {J3}]")
        self.leaf, self.motor = leaf, motor
        self.load = load if isinstance(load, LoadSum) else LoadSum([load])
        self.J1, self.J3, self.J_down, self.omega_s = J1, J3, J_down, omega_s

    # ---- coupling ------------------------------------------------------------------------------------
    def reduced(self, phi_r: float | np.ndarray) -> float | np.ndarray:
        """φ_r reduced into (−φ_d, φ_d] (rad)."""
        period = self.leaf.period
        return phi_r - period * np.round(phi_r / period)

    def coupling(self, phi_r: float, omega_r: float) -> tuple[float, float]:
        """(T_c N·m, leaf force F_v N) at relative angle and speed."""
        leaf, phi = self.leaf, float(self.reduced(phi_r))
        x, y = leaf.a1 * math.sin(phi), leaf.r1 - leaf.r0 - leaf.a1 * math.cos(phi)
        half = 0.5 * leaf.span
        force = 3.0 * leaf.E * leaf.second_moment * leaf.span * y / ((half - x) ** 2 * (half + x) ** 2)
        arm = x + leaf.mu * (leaf.r1 - leaf.a1 * math.cos(phi)) * math.tanh(omega_r / self.omega_s)
        return leaf.factor * leaf.n * force * arm, force

    def _accelerations(self, t: float, y) -> tuple[float, float, float, float, float, float]:
        """(ω̇1, ω̇3, M1, M3, T_c, F_v)."""
        omega1 = y[1] + y[3]
        tc, force = self.coupling(y[0], y[1])
        m1 = self.motor.torque(t, omega1)
        z = tuple(y[4:])
        m3 = self.load.torque(t, y[2], y[3], z)
        return (m1 - tc) / self.J1, (tc - m3) / self.J3, m1, m3, tc, force

    def rhs(self, t: float, y) -> tuple:
        a1, a3, *_ = self._accelerations(t, y)
        z = tuple(y[4:])
        return (y[1], a1 - a3, y[3], a3, *self.load.rates(t, y[2], y[3], z))

    # ---- stand interface (as ClutchDynamics) -----------------------------------------------------------
    def initial_state(self, omega0: float, phi_r0: float) -> tuple:
        return (phi_r0, 0.0, 0.0, omega0, *self.load.initial_state())

    def equilibrium_angle(self, omega0: float) -> float:
        """Relative angle in [0, φ_d) whose frictionless leaf torque carries the load at t = 0 and ω3 = omega0."""
        need = self.load.torque(0.0, 0.0, omega0, self.load.initial_state())
        elastic = lambda phi: self.leaf.factor * self.leaf.n * self.leaf.leaf_force(phi) * self.leaf.a1 * math.sin(phi)
        top = self.leaf.apex * (1.0 - 1e-9)
        if not 0.0 <= need < elastic(top):
            raise ValueError(f"the leaf coupling cannot carry the initial load {need:.4g} N*m below its "
                             f"disengagement angle (at most {elastic(top):.4g} N*m)")
        return 0.0 if need == 0.0 else brentq(lambda p: elastic(p) - need, 0.0, top, xtol=1e-13)

    def problem(self, y0: tuple, on_apex) -> Problem:
        """The ODE with "apex" events (φ_r crossing ±φ_d + k·2φ_d: disengagement, restart at the torque jump;
        ``on_apex(record)`` returns True when it changed the problem) and the load/motor time breaks."""
        leaf = self.leaf

        def apex(t, y):
            return math.sin(math.pi * (y[0] - leaf.apex) / leaf.period)

        breaks = sorted(set(self.load.time_breaks()) | set(self.motor.time_breaks()))
        return Problem(self.rhs, y0, [Event(apex, "apex", restart=True, action=on_apex)], breaks)

    def outputs(self, t: np.ndarray, Y: np.ndarray) -> dict[str, np.ndarray]:
        """Truth at samples, with the keys of :meth:`ClutchDynamics.outputs` (``F_a`` and ``N_B``: the leaf force)."""
        vals = np.array([self._accelerations(ti, yi) for ti, yi in zip(t, Y.T)]).reshape(-1, 6)
        out = {"phi1": Y[0] + Y[2], "omega1": Y[1] + Y[3], "phi3": Y[2], "omega3": Y[3], "phi_r": Y[0],
               "omega_r": Y[1], "M1": vals[:, 2], "M3": vals[:, 3], "T_c": vals[:, 4], "F_a": vals[:, 5],
               "N_B": vals[:, 5]}
        out["M_t"] = vals[:, 3] + self.J_down * vals[:, 1]
        return out

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
from collections.abc import Callable

import numpy as np
from scipy.optimize import brentq

from rig.plants.clutch import kernel
from rig.plants.clutch.dynamics import positions
from rig.plants.clutch.loads import LinearMotor, Load, LoadSum
from rig.plants.clutch.variants import LeafSpringClutch
from rig.solvers import Event, EventRecord, Problem
from rig.solvers.compiled import JitRhs


class LeafDynamics:
    """Leaf-spring coupling ``leaf`` between motor (inertia ``J1`` with the driving half) and load (``J3`` with
    the driven half, ``J_down`` of it behind the torque meter), friction regularised with ``omega_s`` (rad/s).
    The equations are compiled (:func:`rig.plants.clutch.kernel.leaf_rhs`, the motor and loads of the flat-tappet
    kernel), so the compiled solvers and the work–precision peers run them as they run the flat-tappet stand."""

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
        # the one event, the apex (disengagement), as row 0 of the compiled event table
        self._p = kernel.with_events(kernel.pack_leaf(leaf, motor, self.load.program(), J1, J3, omega_s),
                                     [(kernel.PERIODIC, 0, leaf.apex, leaf.period, 0)])
        self.rhs = JitRhs(kernel.leaf_rhs, self._sync, event=kernel.event_value, act=kernel.event_action)

    def _sync(self) -> np.ndarray:
        """The kernel's parameter vector with the motor's trip state."""
        self._p[kernel.TRIP_AT] = self.motor.trip_at
        return self._p

    # ---- coupling ------------------------------------------------------------------------------------
    def coupling(self, phi_r: float, omega_r: float) -> tuple[float, float]:
        """(T_c N·m, leaf force F_v N) at relative angle and speed."""
        return kernel.leaf_coupling(float(phi_r), float(omega_r), self._p)

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

    def problem(self, y0: tuple, on_apex: Callable[[EventRecord], bool] | None = None) -> Problem:
        """The ODE with "apex" events (φ_r crossing ±φ_d + k·2φ_d: disengagement, restart at the torque jump;
        ``on_apex(record)`` returns True when it changed the problem) and the load/motor time breaks."""
        breaks = sorted(set(self.load.time_breaks()) | set(self.motor.time_breaks()))
        return Problem(self.rhs, y0, [Event(kernel.event_function(self._p, 0), "apex", restart=True, action=on_apex)],
                       breaks, positions=positions(len(y0)))

    def outputs(self, t: np.ndarray, Y: np.ndarray) -> dict[str, np.ndarray]:
        """Truth at samples, with the keys of :meth:`ClutchDynamics.outputs` (``F_a`` and ``N_B``: the leaf force)."""
        Y = np.ascontiguousarray(Y, dtype=float)
        m1, m3, tc, force, a3 = kernel.leaf_outputs(np.asarray(t, dtype=float), Y, self._sync())
        out = {"phi1": Y[0] + Y[2], "omega1": Y[1] + Y[3], "phi3": Y[2], "omega3": Y[3], "phi_r": Y[0],
               "omega_r": Y[1], "M1": m1, "M3": m3, "T_c": tc, "F_a": force, "N_B": force.copy()}
        out["M_t"] = m3 + self.J_down * a3
        return out

"""The pin-insertion cam-bar mechanism (MODELS §3): its description (geometry, masses, spring, contact, loads,
cam program), level-0 kinematics and level-1 entry points, at whatever cam speed the caller gives. How a run
simulates it (speed profile, level, solver, per-cycle variation) is :class:`rig.plants.cam_bar.plant.Setting`;
the runner's plant is :class:`rig.plants.cam_bar.plant.CamBarPlant`.

Frame: follower pivot B0 at the origin, x to the right, y up, gravity along −y, angles counter-clockwise
from +x. The cam program prescribes the slider stroke s(φ); the follower angle ψ, the rod angle ϑ and
the roller pitch radius r follow from the chain (:mod:`rig.plants.cam_bar.chain`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from math import isfinite, pi, radians
from typing import NamedTuple

import numpy as np

from rig.motion.program import CamProgram, Segment
from rig.plants.cam_bar.chain import Angles, Chain, SingularPositionError
from rig.plants.cam_bar.drive import CamDrive
from rig.plants.cam_bar.insertion import InsertionLaw
from rig.plants.cam_bar.joints import JointClearance
from rig.plants.cam_bar.kinetostatics import Kinetostatics, solve
from rig.plants.cam_bar.switches import flank_switch_angles


#: SI units of the parameters the constructor checks (its messages name them)
#: parameters that must be positive / not negative (also checked on a scene's values, scene_io.PLANT_SCHEMA)
POSITIVE = ("L3", "l3", "m3", "r_R", "l4", "m4", "e_sk", "l5", "m5", "s_H", "l_F", "g", "roller_width")
NON_NEGATIVE = ("F_c", "F_c_travel", "mu", "x_s5", "e5", "Me_0", "k", "clearance")
SI_UNITS = {"L3": "m", "l3": "m", "m3": "kg", "r_R": "m", "l4": "m", "m4": "kg", "e_sk": "m", "l5": "m", "m5": "kg",
            "s_H": "m", "l_F": "m", "g": "m/s^2", "roller_width": "m", "F_c": "N", "F_c_travel": "m", "mu": "",
            "x_s5": "m", "e5": "m", "Me_0": "N*m", "k": "N/m", "clearance": "m"}


def default_program(stroke: float = 0.042) -> CamProgram:
    """The assumed program: dwell 60°, rise 120°, dwell 40°, return 100°, dwell 40°, 3-4-5 law."""
    return CamProgram([Segment("dwell", radians(60)), Segment("rise", radians(120), "3-4-5", stroke),
                       Segment("dwell", radians(40)), Segment("return", radians(100), "3-4-5", stroke),
                       Segment("dwell", radians(40))])


class ChainPosition(NamedTuple):
    """Follower angle ψ (rad), rod angle ϑ (rad), roller pitch radius r about the cam centre (m)."""

    psi: np.ndarray
    theta: np.ndarray
    r: np.ndarray


@dataclass
class State:
    """Prescribed motion at cam angles φ. Suffix ``_p``/``_pp``: 1st/2nd derivative w.r.t. φ (per rad);
    ``_d``/``_dd``: w.r.t. time (per s). Units: s, r in m; ψ, ϑ in rad; ω in rad/s, α = ω̇ in rad/s²."""

    phi: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    s: np.ndarray
    s_p: np.ndarray
    s_pp: np.ndarray
    psi: np.ndarray
    psi_p: np.ndarray
    psi_pp: np.ndarray
    theta: np.ndarray
    theta_p: np.ndarray
    theta_pp: np.ndarray
    r: np.ndarray
    r_p: np.ndarray
    r_pp: np.ndarray
    trig: Angles  # cos/sin of ψ and ϑ, reused by the kinetostatics

    def _d(self, p: np.ndarray) -> np.ndarray:
        return self.omega * p

    def _dd(self, p: np.ndarray, pp: np.ndarray) -> np.ndarray:
        return self.omega ** 2 * pp + self.alpha * p

    @property
    def s_d(self) -> np.ndarray:
        return self._d(self.s_p)

    @property
    def s_dd(self) -> np.ndarray:
        return self._dd(self.s_p, self.s_pp)

    @property
    def psi_d(self) -> np.ndarray:
        return self._d(self.psi_p)

    @property
    def psi_dd(self) -> np.ndarray:
        return self._dd(self.psi_p, self.psi_pp)

    @property
    def theta_d(self) -> np.ndarray:
        return self._d(self.theta_p)

    @property
    def theta_dd(self) -> np.ndarray:
        return self._dd(self.theta_p, self.theta_pp)

    @property
    def r_d(self) -> np.ndarray:
        return self._d(self.r_p)

    @property
    def r_dd(self) -> np.ndarray:
        return self._dd(self.r_p, self.r_pp)


class SpringDesign(NamedTuple):
    """Thesis spring design (N, m, N/m) and the spring-point travel the follower geometry really gives."""

    F_e0: float
    F_eS: float
    travel_thesis: float
    k: float
    travel_geometry: float
    k_geometry: float


@dataclass
class PinInsertionMechanism:
    """Cam → oscillating roller follower (3) → rod (4) → gripper slider (5), spring on the follower.

    Defaults are MODELS §3.1 (SI); the assumptions of §3.1 are parameters too (``J3``/``J4``/``a3``
    ``None`` mean m3·L3²/3 about B0, m4·l4²/12 about the rod centre, follower CoG at L3/2).
    ``cam_direction`` +1: the cam turns counter-clockwise. The insertion force ``F_c`` acts on the slider
    against its motion during the rise once the stroke is within ``F_c_travel`` of the top.
    Level 2 (:mod:`.level2`) models the contact over ``roller_width`` (m), the optional cam drive and rod pin
    clearances; its assumptions that are not the machine (contact damping, guide friction model) are
    :class:`~rig.plants.cam_bar.level2_model.Level2Model`, part of the run's setting.
    """

    L3: float = 0.260
    l3: float = 0.065
    m3: float = 0.910
    x_A0: float = -0.034
    y_A0: float = 0.065
    r_R: float = 0.008
    l4: float = 0.122
    m4: float = 0.090
    e_sk: float = 0.259
    s0: float = -0.101
    l5: float = 0.193
    m5: float = 0.780
    s_H: float = 0.042
    F_c: float = 40.0
    F_c_travel: float = 0.005
    l_F: float = 0.100
    Me_S: float = 25.0
    Me_0: float = 20.0
    s_S: float = 0.042
    s_Srest: float = 0.0
    k: float = 1890.0
    sensor_preload: float = -25.0
    sensor_position: float = 0.5
    clearance: float = 0.05e-3
    roller_width: float = 0.010
    alpha_sk: float = radians(4.65)
    J3: float | None = None
    J4: float | None = None
    a3: float | None = None
    mu: float = 0.1
    g: float = 9.81
    x_s5: float = 0.02
    e5: float = 0.02
    cam_direction: int = 1
    program: CamProgram = field(default_factory=default_program)
    insertion: InsertionLaw = field(default_factory=InsertionLaw)
    cam_drive: CamDrive | None = None                                # level 2: motor + shaft turn the cam
    joints: JointClearance | None = None                             # level 2: rod pin clearances (slider DOF)

    def __post_init__(self) -> None:
        for name, unit in SI_UNITS.items():
            if not isfinite(getattr(self, name)):
                raise ValueError(f"cam-bar parameter {name} must be a finite number, got {getattr(self, name)!r} "
                                 f"{unit}".rstrip())
        for name in POSITIVE:
            if not getattr(self, name) > 0.0:
                raise ValueError(f"cam-bar parameter {name} must be positive, got {getattr(self, name)!r} "
                                 f"{SI_UNITS[name]}")
        for name in NON_NEGATIVE:
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"cam-bar parameter {name} must not be negative, got {getattr(self, name)!r} "
                                 f"{SI_UNITS[name]}".rstrip())
        if not 0.0 <= self.sensor_position <= 1.0:
            raise ValueError(f"sensor_position is the sensor's place along the rod, from 0 at the follower joint C "
                             f"to 1 at the slider joint D, got {self.sensor_position!r}")
        if self.cam_direction not in (1, -1):
            raise ValueError(f"cam_direction must be +1 (counter-clockwise) or -1, got {self.cam_direction!r}")
        j3_given = self.J3 is not None
        if self.J3 is None:
            self.J3 = self.m3 * self.L3 ** 2 / 3.0
        if self.J4 is None:
            self.J4 = self.m4 * self.l4 ** 2 / 12.0
        if self.a3 is None:
            self.a3 = self.L3 / 2.0
        self._check_inertias(j3_given)
        if self.F_c_travel > self.s_H:
            raise ValueError(f"cam-bar parameter F_c_travel ({self.F_c_travel * 1e3:g} mm) is longer than the "
                             f"stroke s_H ({self.s_H * 1e3:g} mm): the insertion force acts over the last F_c_travel "
                             "of the rise")
        if self.joints is not None and self.joints.follower + self.joints.slider >= self.s_H:
            raise ValueError(f"the rod's pin clearances ([plant.joints] follower + slider = "
                             f"{(self.joints.follower + self.joints.slider) * 1e3:g} mm) are not smaller than the "
                             f"stroke s_H ({self.s_H * 1e3:g} mm): the play would swallow the gripper's motion")
        self.chain = self._assemble()
        self.psi0 = float(self.chain.angles(np.array([self.s_Srest])).psi[0])

    def _check_inertias(self, j3_given: bool = True) -> None:
        """J3, J4 positive and a3 not negative, J3 (about the pivot B0) at least m3·a3² (the parallel-axis theorem:
        a body's inertia about a pivot exceeds its mass times the squared distance of its centre of gravity);
        ``j3_given`` False: J3 is the default m3·L3²/3 (the message then asks for J3 with that a3)."""
        for name, unit in (("J3", "kg*m^2"), ("J4", "kg*m^2"), ("a3", "m")):
            value = getattr(self, name)
            if not (isfinite(value) and (value >= 0.0 if name == "a3" else value > 0.0)):
                what = "must not be negative" if name == "a3" else "must be positive"
                raise ValueError(f"cam-bar parameter {name} {what}, got {value!r} {unit}")
        least = self.m3 * self.a3 ** 2
        if self.J3 < least * (1.0 - 1e-12) and not j3_given:
            raise ValueError(f"cam-bar parameter a3 = {self.a3 * 1e3:g} mm puts the follower's centre of gravity where "
                             f"the default J3 = m3·L3²/3 = {self.J3:.6g} kg*m^2 (a uniform bar) is below m3·a3² = "
                             f"{least:.6g} kg*m^2: give J3, the inertia about B0, with that a3")
        if self.J3 < least * (1.0 - 1e-12):
            raise ValueError(f"cam-bar parameter J3 = {self.J3:.6g} kg*m^2 is the follower's inertia about its pivot "
                             f"B0: it cannot be below m3·a3² = {least:.6g} kg*m^2 (m3 = {self.m3:g} kg, "
                             f"a3 = {self.a3 * 1e3:g} mm, the parallel-axis theorem)")

    def _assemble(self) -> Chain:
        """Pick the branch nearest the machine's start angle and check the whole stroke range on it."""
        lo, hi = self.program.levels
        s_range = np.linspace(min(lo, self.s_Srest, 0.0), max(hi, self.s_Srest), 401)
        target = pi / 2 - self.alpha_sk
        best = None
        for branch in (1.0, -1.0):
            try:
                psi = Chain(self.L3, self.l4, self.e_sk, self.s0, branch).angles(np.array([0.0])).psi
            except SingularPositionError as exc:
                raise SingularPositionError(f"impossible cam-bar geometry: {exc}") from None
            miss = abs(np.angle(np.exp(1j * (psi[0] - target))))
            if best is None or miss < best[0]:
                best = (miss, branch)
        chain = Chain(self.L3, self.l4, self.e_sk, self.s0, best[1])
        try:
            ct = chain.angles(s_range).ct
        except SingularPositionError as exc:
            raise SingularPositionError(f"impossible cam-bar geometry over the programmed stroke: {exc}") from None
        if np.ptp(np.sign(ct)) != 0.0:
            raise SingularPositionError("impossible cam-bar geometry: the rod passes vertical within the stroke "
                                        f"{lo * 1e3:g}..{hi * 1e3:g} mm (slider position not unique)")
        return chain

    # ---- level 0 -------------------------------------------------------------------------------------------
    def _pitch(self, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Roller centre minus cam centre, w = B_R − A0 (m), components."""
        return self.l3 * np.cos(psi) - self.x_A0, self.l3 * np.sin(psi) - self.y_A0

    def kinematics(self, s: np.ndarray | float) -> ChainPosition:
        """ψ, ϑ, r for slider stroke(s) ``s`` (m)."""
        s = np.asarray(s, dtype=float)
        a = self.chain.angles(s)
        return ChainPosition(a.psi, a.theta, np.hypot(*self._pitch(a.psi)))

    def slider_from_follower(self, psi: np.ndarray | float) -> np.ndarray:
        """Slider stroke s (m) from follower angle ψ (rad), inverse of :meth:`kinematics` on the same branch."""
        return self.chain.slider(np.asarray(psi, dtype=float))

    def state(self, phi: np.ndarray | float, omega: np.ndarray | float = np.nan,
              alpha: np.ndarray | float = 0.0) -> State:
        """Motion at cam angles ``phi`` (rad) turning at ``omega`` (rad/s) with ``alpha`` = ω̇ (rad/s²); without
        ``omega`` the positions and φ-derivatives only (time derivatives NaN). Raises
        :class:`SingularPositionError` naming the angle at a singular position."""
        phi = np.asarray(phi, dtype=float)
        m = self.program.evaluate(phi)
        a = self.chain.angles(m.s, phi)
        psi_p, psi_pp, theta_p, theta_pp = self.chain.derivatives(a, m.s_p, m.s_pp)
        wx, wy = self.l3 * a.cp - self.x_A0, self.l3 * a.sp - self.y_A0
        r = np.sqrt(wx * wx + wy * wy)
        wdw = self.l3 * (wy * a.cp - wx * a.sp)  # w·dw/dψ
        r_p = wdw * psi_p / r
        w_ppsi = -self.l3 * (wx * a.cp + wy * a.sp)  # w·d²w/dψ²
        r_pp = ((self.l3 ** 2 + w_ppsi) * psi_p ** 2 + wdw * psi_pp - r_p ** 2) / r
        return State(phi, np.broadcast_to(np.asarray(omega, float), phi.shape),
                     np.broadcast_to(np.asarray(alpha, float), phi.shape), m.s, m.s_p, m.s_pp, a.psi, psi_p, psi_pp,
                     a.theta, theta_p, theta_pp, r, r_p, r_pp, a)

    # ---- level 1 -------------------------------------------------------------------------------------------
    def kinetostatics(self, phi: np.ndarray | float, omega: np.ndarray | float,
                      alpha: np.ndarray | float = 0.0, k: float | None = None) -> Kinetostatics:
        """Joint reactions, moments and drive torque at cam angles ``phi`` (rad) turning at ``omega`` (rad/s) with
        ``alpha`` = ω̇ (rad/s²) (see :mod:`.kinetostatics`); ``k`` (N/m) overrides the mounted spring rate."""
        return solve(self, self.state(phi, omega, alpha), self.k if k is None else k)

    def spring_moment(self, psi: np.ndarray, k: float | None = None) -> np.ndarray:
        """M_e = F_e·l_F with F_e = F_e0 + k·l_F·(ψ − ψ0), F_e0 = Me_0/l_F (N·m); it acts towards smaller ψ."""
        k = self.k if k is None else k
        return (self.Me_0 / self.l_F + k * self.l_F * (psi - self.psi0)) * self.l_F

    def flank_switch_angles(self, omega: float, k: float | None = None, spring: bool = True,
                            n: int = 3600) -> np.ndarray:
        """Cam angles (rad, in [0, 2π)) where the cam contact force changes sign over one revolution at the
        constant speed ``omega`` (rad/s)."""
        return flank_switch_angles(self, self.k if k is None else k, spring, omega, n)

    def spring_rate_design(self) -> SpringDesign:
        """Thesis rate k = (F_eS − F_e0)/(s_S − s_0); also the rate that the follower's real spring-point
        travel l_F·(ψ(s_S) − ψ(s_0)) would need for the same two moments."""
        f0, fs = self.Me_0 / self.l_F, self.Me_S / self.l_F
        travel = self.s_S - self.s_Srest
        psi = self.kinematics(np.array([self.s_Srest, self.s_S])).psi
        travel_geo = float(self.l_F * abs(psi[1] - psi[0]))
        return SpringDesign(f0, fs, travel, (fs - f0) / travel, travel_geo, (fs - f0) / travel_geo)

    def insertion_force(self, s: np.ndarray, s_p: np.ndarray) -> np.ndarray:
        """Insertion force (N, on the slider along +x, against the rise): the pin's force–travel law
        ``insertion`` (:mod:`.insertion`) over the last ``F_c_travel`` of the rise while s' > 0, else 0."""
        f = self.insertion.force(s, self.program.levels[1], self.F_c_travel, self.F_c)
        return np.where(np.asarray(s_p) > 0.0, f, 0.0)

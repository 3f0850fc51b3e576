"""Composable drive and load torques for the clutch stand (N·m, positive load torque resists ω3 > 0).

A load has ``n_states`` internal states (e.g. the brake force), ``initial_state()``,
``torque(t, phi3, omega3, z)``, ``rates(t, phi3, omega3, z)``, the times where it jumps
(``time_breaks()``), the driven-half angles where it switches (``angle_breaks()`` → (angle, period))
and, when it is affine in speed between time breaks, ``affine(t, z, w_lo, w_hi)`` → (α, β) with
M = α + β·ω3 for ω3 in [w_lo, w_hi] and its states z at rest (used for the closed-form stuck segments of
the clutch dynamics). ``program(z0)`` encodes the load as numbers for the compiled right-hand side
(:mod:`rig.plants.clutch.kernel`, which interprets the codes below; its states start at z[z0]).
"""
from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from rig.plants.clutch.kernel import BRAKE, LINEAR, STEPS, ZONE


class Load:
    """Base: a memoryless torque with no internal state and no discontinuities."""

    n_states = 0

    def program(self, z0: int = 0) -> list[float]:
        """The load as [code, parameters...] for the compiled right-hand side; its states start at z[z0]."""
        raise NotImplementedError(f"{type(self).__name__} has no compiled form (program())")

    def initial_state(self) -> tuple:
        return ()

    def torque(self, t: float, phi3: float, omega3: float, z: tuple) -> float:
        raise NotImplementedError

    def rates(self, t: float, phi3: float, omega3: float, z: tuple) -> tuple:
        return ()

    def time_breaks(self) -> list[float]:
        return []

    def angle_breaks(self) -> list[tuple[float, float]]:
        return []

    def affine(self, t: float, z: tuple = (), w_lo: float = -math.inf,
               w_hi: float = math.inf) -> tuple[float, float] | None:
        """(α N·m, β N·m·s/rad) with torque = α + β·ω3 on the time-break interval holding t, for ω3 in
        [w_lo, w_hi] (rad/s) with the internal states ``z`` at rest; None when the torque is not of that
        form there (depends on angle, or on states that move)."""
        return None


@dataclass
class Steps(Load):
    """Piecewise-constant torque in time: ``base`` up to ``times[0]``, ``levels[i]`` after ``times[i]``
    (left-continuous, as :func:`rig.solvers.integrate` expects at time breaks)."""

    base: float
    times: Sequence[float] = ()
    levels: Sequence[float] = ()

    def __post_init__(self) -> None:
        if len(self.times) != len(self.levels):
            raise ValueError(f"Steps load: {len(self.times)} times but {len(self.levels)} levels")
        if any(b <= a for a, b in zip(self.times, self.times[1:])):
            raise ValueError(f"Steps load: times {list(self.times)} must increase")
        self._values = [self.base, *self.levels]

    def torque(self, t, phi3, omega3, z):
        return self._values[bisect.bisect_left(self.times, t)]

    def program(self, z0=0):
        return [STEPS, len(self.times), *self.times, *self._values]

    def time_breaks(self):
        return list(self.times)

    def affine(self, t, z=(), w_lo=-math.inf, w_hi=math.inf):
        return self.torque(t, 0.0, 0.0, ()), 0.0


def constant(torque: float) -> Steps:
    """Constant torque M_tc (N·m)."""
    return Steps(torque)


def step(time: float, torque: float) -> Steps:
    """Torque ``torque`` (N·m) added from ``time`` (s) on."""
    return Steps(0.0, (time,), (torque,))


def shock(start: float, duration: float, torque: float) -> Steps:
    """Rectangular shock of ``torque`` (N·m) on [start, start + duration) (s)."""
    if not duration > 0:
        raise ValueError(f"shock load: duration = {duration} s must be positive")
    return Steps(0.0, (start, start + duration), (torque, 0.0))


@dataclass
class Zone(Load):
    """Zone law in angle: ``torque`` while φ3 mod ``period`` lies in [start, end) (rad)."""

    torque_in_zone: float
    start: float
    end: float
    period: float = 2 * math.pi

    def __post_init__(self) -> None:
        if not 0 <= self.start < self.end <= self.period:
            raise ValueError(f"zone load: need 0 <= start < end <= period, got start={self.start}, "
                             f"end={self.end}, period={self.period} rad")

    def torque(self, t, phi3, omega3, z):
        return self.torque_in_zone if self.start <= phi3 % self.period < self.end else 0.0

    def angle_breaks(self):
        return [(self.start, self.period), (self.end, self.period)]

    def program(self, z0=0):
        return [ZONE, self.torque_in_zone, self.start, self.end, self.period]


@dataclass
class LinearInSpeed(Load):
    """M3 = α0 + β0·ω3 (N·m, N·m·s/rad)."""

    alpha0: float
    beta0: float

    def torque(self, t, phi3, omega3, z):
        return self.alpha0 + self.beta0 * omega3

    def program(self, z0=0):
        return [LINEAR, self.alpha0, self.beta0]

    def affine(self, t, z=(), w_lo=-math.inf, w_hi=math.inf):
        return self.alpha0, self.beta0


@dataclass
class ShoeBrake(Load):
    """Shoe brake with actuator τ·dF_b/dt = F_cmd(t) − F_b and Coulomb torque of capacity gain·F_b.

    ``gain`` (N·m/N) = effective friction coefficient × drum radius × number of shoes; the force
    command is piecewise constant (``force`` then ``levels[i]`` from ``times[i]``). ``friction``:
    "tanh" — M = gain·F_b·tanh(ω3/omega_s), ``omega_s`` (rad/s) regularising the sign at standstill
    (stiff while the drum is held: time constant ≈ J3·omega_s/(gain·F_b)); "stick_slip" — M = ±gain·F_b
    while the drum slips, and the drum is held (ω3 ≡ 0) while the torque needed for that stays within
    ±gain·F_b (a discrete mode of :class:`rig.plants.clutch.dynamics.ClutchDynamics`, which allows one
    such brake). Python ``torque`` gives the slipping value gain·F_b·sgn ω3 (0 at rest).
    """

    gain: float
    tau: float
    force: float
    times: Sequence[float] = ()
    levels: Sequence[float] = ()
    omega_s: float = 0.5
    friction: str = "tanh"
    n_states = 1
    _command: Steps = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not (self.gain >= 0 and self.tau > 0 and self.omega_s > 0):
            raise ValueError(f"shoe brake: need gain >= 0, tau > 0, omega_s > 0 "
                             f"(gain={self.gain}, tau={self.tau}, omega_s={self.omega_s})")
        if self.friction not in ("tanh", "stick_slip"):
            raise ValueError(f"shoe brake: friction = {self.friction!r} is not 'tanh' or 'stick_slip'")
        pulled = [(f"from {t:g} s ", f) for t, f in zip(self.times, self.levels) if not f >= 0]
        if not self.force >= 0 or pulled:
            when, f = ("", self.force) if not self.force >= 0 else pulled[0]
            raise ValueError(f"shoe brake: the force command is {f:g} N {when}(force, step_force and force plus "
                             f"pulse_force): shoes press, they cannot pull, so it must be >= 0 N (a brake cannot drive "
                             f"the shaft; a driving load is a [load] of type constant, step or shock)")
        self._command = Steps(self.force, self.times, self.levels)

    def initial_state(self):
        return (self.force,)

    def torque(self, t, phi3, omega3, z):
        if self.friction == "tanh":
            return self.gain * z[0] * math.tanh(omega3 / self.omega_s)
        return math.copysign(self.gain * z[0], omega3) if omega3 else 0.0

    def rates(self, t, phi3, omega3, z):
        return ((self._command.torque(t, 0.0, 0.0, ()) - z[0]) / self.tau,)

    def program(self, z0=0):
        """[BRAKE, gain, τ, ω_s, z0, mode (NaN: tanh; stick–slip: +1/−1 slipping, 0 held), command steps]."""
        mode = math.nan if self.friction == "tanh" else 1.0
        return [BRAKE, self.gain, self.tau, self.omega_s, z0, mode, *self._command.program()[1:]]

    def affine(self, t, z=(), w_lo=-math.inf, w_hi=math.inf):
        """Constant ±gain·F_b while the actuator rests at its command and ω3 keeps one sign (tanh: with
        |ω3| ≥ 19·omega_s, where tanh = ±1 to double precision)."""
        if not z or z[0] != self._command.torque(t, 0.0, 0.0, ()):
            return None
        w_sat = 19.0 * self.omega_s if self.friction == "tanh" else math.ulp(0.0)
        if w_lo >= w_sat:
            return self.gain * z[0], 0.0
        if w_hi <= -w_sat:
            return -self.gain * z[0], 0.0
        return None

    def time_breaks(self):
        return list(self.times)


class LoadSum(Load):
    """Sum of loads; their states are concatenated in order."""

    def __init__(self, loads: Sequence[Load]):
        self.loads = list(loads)
        self.n_states = sum(ld.n_states for ld in self.loads)
        self._slices, i = [], 0
        for ld in self.loads:
            self._slices.append((i, i + ld.n_states))
            i += ld.n_states
        self._stateless = [ld for ld in self.loads if ld.n_states == 0]
        self._stateful = [(ld, a, b) for ld, (a, b) in zip(self.loads, self._slices) if ld.n_states]
        if len(self.loads) == 1:                 # a sum of one load is that load (no per-call loop)
            self.torque, self.rates = self.loads[0].torque, self.loads[0].rates

    def initial_state(self):
        return tuple(v for ld in self.loads for v in ld.initial_state())

    def program(self, z0=0):
        """[number of loads, their programs...] (a single load is also a one-term sum)."""
        return [len(self.loads), *(v for ld, (a, _) in zip(self.loads, self._slices) for v in ld.program(z0 + a))]

    def torque(self, t, phi3, omega3, z):
        m = 0.0
        for ld in self._stateless:
            m += ld.torque(t, phi3, omega3, ())
        for ld, a, b in self._stateful:
            m += ld.torque(t, phi3, omega3, z[a:b])
        return m

    def rates(self, t, phi3, omega3, z):
        return tuple(r for ld, a, b in self._stateful for r in ld.rates(t, phi3, omega3, z[a:b]))

    def time_breaks(self):
        return sorted({b for ld in self.loads for b in ld.time_breaks()})

    def angle_breaks(self):
        return [b for ld in self.loads for b in ld.angle_breaks()]

    def affine(self, t, z=(), w_lo=-math.inf, w_hi=math.inf):
        alpha = beta = 0.0
        k = 0
        for ld in self.loads:
            ab = ld.affine(t, tuple(z[k:k + ld.n_states]), w_lo, w_hi)
            k += ld.n_states
            if ab is None:
                return None
            alpha, beta = alpha + ab[0], beta + ab[1]
        return alpha, beta


@dataclass
class LinearMotor:
    """Linear working part of an asynchronous motor behind a belt of ratio i = ω_motor/ω1:
    M1 = i·(a0 − b0·i·ω1) (N·m at the coupling), switched off (M1 = 0) after ``t_off`` (s) and from ``trip_at``
    (s; a trip by the stand's shutdown — a time, not a flag: samples before it, recorded afterwards, keep the torque
    the motor gave)."""

    a0: float
    b0: float
    ratio: float = 1.0
    t_off: float = math.inf
    trip_at: float = math.inf

    @property
    def tripped(self) -> bool:
        """True once a trip time is set."""
        return self.trip_at < math.inf

    def off(self, t: float) -> bool:
        """True when the motor gives no torque at time t (s)."""
        return t >= self.trip_at or t > self.t_off

    def torque(self, t: float, omega1: float) -> float:
        if self.off(t):
            return 0.0
        return self.ratio * (self.a0 - self.b0 * self.ratio * omega1)

    def time_breaks(self) -> list[float]:
        return [self.t_off] if math.isfinite(self.t_off) else []

    def affine(self, t: float) -> tuple[float, float]:
        """(A N·m, B N·m·s/rad) with M1 = A − B·ω1 at time t."""
        if self.off(t):
            return 0.0, 0.0
        return self.ratio * self.a0, self.ratio * self.ratio * self.b0

"""Geneva (Maltese-cross) drive with ``slots`` z and one pin (MODELS §5): crank radius R1 = L sin(π/z),
λ = R1/L; during engagement tan φ2 = λ sin φ1 / (1 − λ cos φ1), ω2 = ω1 λ (cos φ1 − λ)/(1 − 2λ cos φ1 + λ²),
φ1 measured from the crank's centre-line position (pin deepest in the slot); the wheel dwells outside."""
from __future__ import annotations

from dataclasses import dataclass
from math import isfinite, pi, sin, tau
from typing import NamedTuple

import numpy as np

from rig.mechanisms.checks import finite, finite_array, positive, whole


class GenevaMotion(NamedTuple):
    """Wheel angle φ2 (rad, relative to the slot's centre line; held at the end value in the dwell),
    velocity ω2 (rad/s) and acceleration α2 (rad/s²) at constant crank speed; ``engaged`` where the pin
    drives."""

    angle: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    engaged: np.ndarray


class GenevaTiming(NamedTuple):
    """Times (s) of one crank turn and their ratios: motion + dwell = period, k_m = (z − 2)/(2z)."""

    motion_time: float
    dwell_time: float
    period: float
    motion_ratio: float
    dwell_ratio: float


def crank_turns(phi1: np.ndarray) -> np.ndarray:
    """Whole crank turns k with φ1 − 2πk in (−π, π] (mid-dwell at the turn's ends)."""
    return np.ceil((phi1 - pi) / tau)


@dataclass(frozen=True)
class Geneva:
    """``slots`` z ≥ 3, ``centre_distance`` L (m) between crank and wheel axes."""

    slots: int
    centre_distance: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "slots", whole(self.slots, 3, "Geneva slots (a wheel with fewer cannot index)"))
        L = finite(self.centre_distance, "Geneva centre_distance")
        L = positive(L, "Geneva centre_distance", "m", at_most=5.0,
                     hint=f"it is in metres: did you mean {L:g} mm = {L * 1e-3:g} m?")
        object.__setattr__(self, "centre_distance", L)

    @property
    def crank_radius(self) -> float:
        """R1 = L sin(π/z) (m): the pin enters the slot tangentially."""
        return self.centre_distance * sin(pi / self.slots)

    @property
    def engagement_half_angle(self) -> float:
        """Crank angle (rad) from the centre line to the pin's entry: π/2 − π/z."""
        return pi / 2 - pi / self.slots

    def kinematics(self, phi1: np.ndarray | float, omega1: float = 1.0) -> GenevaMotion:
        """Wheel motion at crank angles ``phi1`` (rad, 0 = centre line) for crank speed ``omega1`` (rad/s). The
        wheel's angle, speed and acceleration are counted positive in the sense opposite to the crank's: an external
        Geneva wheel turns against its crank, so ω2 > 0 for ω1 > 0 means the wheel turns the other way."""
        finite(omega1, "Geneva omega1 (rad/s)")
        phi1 = finite_array(phi1, "Geneva crank angles phi1 (rad)")
        lam = sin(pi / self.slots)
        phi = phi1 - tau * crank_turns(phi1)      # in (−π, π]
        engaged = np.abs(phi) <= self.engagement_half_angle
        c = np.cos(phi)
        den = 1.0 - 2 * lam * c + lam * lam
        angle = np.arctan2(lam * np.sin(phi), 1.0 - lam * c)
        end = pi / self.slots
        angle = np.where(engaged, angle, np.where(phi > 0, end, -end))
        vel = np.where(engaged, omega1 * lam * (c - lam) / den, 0.0)
        acc = np.where(engaged, -omega1 ** 2 * lam * (1 - lam * lam) * np.sin(phi) / den ** 2, 0.0)
        return GenevaMotion(angle, vel, acc, engaged)

    def wheel_angle(self, phi1: np.ndarray | float) -> np.ndarray:
        """The wheel's turned angle (rad) at crank angles ``phi1`` (rad, from 0, any number of turns), 0 in the
        dwell before the first engagement: one step of 2π/z per crank turn, continuous through every dwell (a
        crank angle on an odd multiple of π, mid-dwell, belongs to the same turn here as in :meth:`kinematics`)."""
        phi1 = finite_array(phi1, "Geneva crank angles phi1 (rad)")
        return tau / self.slots * crank_turns(phi1) + self.kinematics(phi1).angle + pi / self.slots

    def timing(self, crank_speed: float) -> GenevaTiming:
        """Motion and dwell times of one crank turn at ``crank_speed`` (rad/s)."""
        positive(crank_speed, "Geneva crank_speed", "rad/s")
        period = tau / crank_speed
        if not isfinite(period):                # (1e-320 rad/s read an infinite motion and a NaN dwell; an audit)
            raise ValueError(f"Geneva crank_speed {crank_speed!r} rad/s is too slow to time: one turn overflows")
        motion = 2 * self.engagement_half_angle / crank_speed
        return GenevaTiming(motion, period - motion, period, motion / period, (period - motion) / period)

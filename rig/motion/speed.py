"""Cam-shaft speed profiles: cam angle φ(t) (rad), speed ω(t) (rad/s), acceleration ω̇(t) (rad/s²).

All profiles start at φ(0) = ``phi0`` and are closed-form, so φ, ω and ω̇ are exactly consistent.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import pi, tau
from typing import NamedTuple

import numpy as np

RPM = tau / 60.0  # rad/s per rpm


class Drive(NamedTuple):
    """Cam angle (rad), speed (rad/s) and angular acceleration (rad/s²) at some times."""

    phi: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray


class SpeedProfile:
    """Base: ``drive(t)`` and the mean speed ``nominal_omega`` used when no speed is given."""

    nominal_omega: float
    phi0: float = 0.0

    def drive(self, t: np.ndarray) -> Drive:
        raise NotImplementedError


def _positive(name: str, value: float) -> None:
    if not value > 0.0:
        raise ValueError(f"speed profile: {name} must be positive, got {value:g}")


@dataclass(frozen=True)
class ConstantSpeed(SpeedProfile):
    """ω = const."""

    omega: float
    phi0: float = 0.0

    def __post_init__(self) -> None:
        _positive("speed", self.omega)

    @property
    def nominal_omega(self) -> float:  # type: ignore[override]
        return self.omega

    def drive(self, t):
        t = np.asarray(t, dtype=float)
        return Drive(self.phi0 + self.omega * t, np.full_like(t, self.omega), np.zeros_like(t))


@dataclass(frozen=True)
class RampSpeed(SpeedProfile):
    """ω = ``omega0`` until ``t_start``, then linear to ``omega1`` over ``t_ramp`` (s), then constant."""

    omega0: float
    omega1: float
    t_ramp: float
    t_start: float = 0.0
    phi0: float = 0.0

    def __post_init__(self) -> None:
        _positive("start speed", self.omega0)
        _positive("end speed", self.omega1)
        _positive("ramp time", self.t_ramp)
        if self.t_start < 0.0:
            raise ValueError(f"speed profile: ramp start must not be negative, got {self.t_start:g} s")

    @property
    def nominal_omega(self) -> float:  # type: ignore[override]
        return self.omega1

    def drive(self, t):
        t = np.asarray(t, dtype=float)
        rate = (self.omega1 - self.omega0) / self.t_ramp
        u = np.clip(t - self.t_start, 0.0, self.t_ramp)  # time spent in the ramp so far
        after = np.maximum(t - self.t_start - self.t_ramp, 0.0)
        before = np.minimum(t, self.t_start)
        phi = self.phi0 + self.omega0 * before + self.omega0 * u + 0.5 * rate * u * u + self.omega1 * after
        in_ramp = (t > self.t_start) & (t < self.t_start + self.t_ramp)
        return Drive(phi, self.omega0 + rate * u, np.where(in_ramp, rate, 0.0))


@dataclass(frozen=True)
class SinusoidalSpeed(SpeedProfile):
    """ω = ``omega_mean`` + ``amplitude``·sin(2π f t); f defaults to once per mean revolution."""

    omega_mean: float
    amplitude: float
    frequency: float | None = None
    phi0: float = 0.0

    def __post_init__(self) -> None:
        _positive("mean speed", self.omega_mean)
        if not 0.0 <= self.amplitude < self.omega_mean:
            raise ValueError(f"speed profile: fluctuation amplitude {self.amplitude:g} rad/s must be in "
                             f"[0, mean speed {self.omega_mean:g} rad/s) so the cam keeps turning forward")
        if self.frequency is not None:
            _positive("fluctuation frequency", self.frequency)

    @property
    def nominal_omega(self) -> float:  # type: ignore[override]
        return self.omega_mean

    def drive(self, t):
        t = np.asarray(t, dtype=float)
        f = self.frequency if self.frequency is not None else self.omega_mean / tau
        w = 2.0 * pi * f
        return Drive(self.phi0 + self.omega_mean * t + self.amplitude / w * (1.0 - np.cos(w * t)),
                     self.omega_mean + self.amplitude * np.sin(w * t),
                     self.amplitude * w * np.cos(w * t))

"""Cardan (Hooke) joint at shaft angle α (MODELS §5): tan φ2 = tan φ1 / cos α,
ω2/ω1 = cos α / (1 − sin²α cos²φ1); and the double joint in Z and W arrangements."""
from __future__ import annotations

from dataclasses import dataclass
from math import cos, pi, sin

import numpy as np

from rig.mechanisms.checks import degrees_hint, finite, finite_array

ArrayLike = np.ndarray | float


def _turns(phi: np.ndarray) -> np.ndarray:
    """2π times the whole turns between ``phi`` and its principal value (keeps angles continuous)."""
    return 2 * pi * np.round((phi - np.arctan2(np.sin(phi), np.cos(phi))) / (2 * pi))


@dataclass(frozen=True)
class Cardan:
    """One joint; ``shaft_angle`` α (rad) between input and output shaft, 0 ≤ α < π/2. φ1 is measured from
    the position where the input yoke lies in the plane of the two shafts."""

    shaft_angle: float

    def __post_init__(self) -> None:
        alpha = finite(self.shaft_angle, "Cardan shaft_angle (rad)")
        if not 0.0 <= alpha < pi / 2:
            raise ValueError(f"Cardan shaft_angle must lie in [0, 90°) (at 90° the output shaft cannot turn), got "
                             f"{alpha:.6g} rad = {np.degrees(alpha):.6g}°" + degrees_hint(alpha))

    def output_angle(self, phi1: ArrayLike) -> np.ndarray:
        """φ2 (rad), continuous in φ1 (the same quadrant: tan φ2 = tan φ1 / cos α)."""
        phi1 = finite_array(phi1, "Cardan phi1 (rad)")
        return np.arctan2(np.sin(phi1), np.cos(phi1) * cos(self.shaft_angle)) + _turns(phi1)

    def input_angle(self, phi2: ArrayLike) -> np.ndarray:
        """φ1 (rad) for an output angle φ2, continuous: tan φ1 = tan φ2 · cos α."""
        phi2 = finite_array(phi2, "Cardan phi2 (rad)")
        return np.arctan2(np.sin(phi2) * cos(self.shaft_angle), np.cos(phi2)) + _turns(phi2)

    def speed_ratio(self, phi1: ArrayLike) -> np.ndarray:
        """ω2/ω1 = cos α / (1 − sin²α cos²φ1): between cos α and 1/cos α."""
        phi1 = finite_array(phi1, "Cardan phi1 (rad)")
        return cos(self.shaft_angle) / self._denominator(phi1)

    def _denominator(self, phi1: np.ndarray) -> np.ndarray:
        """1 − sin²α cos²φ1 written as cos²α cos²φ1 + sin²φ1: no cancellation near α = 90° (the difference read
        1/cos α 37 % high at 89.999999° and divided by zero just below 90°; an audit)."""
        return (cos(self.shaft_angle) * np.cos(phi1)) ** 2 + np.sin(phi1) ** 2

    def acceleration(self, phi1: ArrayLike, omega1: ArrayLike) -> np.ndarray:
        """α2 = dω2/dt (rad/s²) at constant input speed ``omega1`` (rad/s, a scalar or one per φ1):
        ω1² · d(ω2/ω1)/dφ1."""
        phi1 = finite_array(phi1, "Cardan phi1 (rad)")
        omega1 = finite_array(omega1, "Cardan omega1 (rad/s)")
        s2a = sin(self.shaft_angle) ** 2
        return -omega1 ** 2 * cos(self.shaft_angle) * s2a * np.sin(2 * phi1) / self._denominator(phi1) ** 2


@dataclass(frozen=True)
class DoubleCardan:
    """Two joints through an intermediate shaft, in the Z arrangement (input and output shafts parallel) or
    the W arrangement (they meet), shaft angles ``angle1`` and ``angle2`` (rad). With the intermediate shaft's
    two yokes in one plane its second joint works as the first one inverted, tan φ3 = tan φ2 · cos α2, so
    φ3 = φ1 exactly when α1 = α2 (both arrangements: they differ in where the output shaft points, not in
    the angle relation). ``yoke_offset`` δ (rad) turns the second yoke out of that plane (an assembly error):
    tan(φ3 − δ) = tan(φ2 − δ) · cos α2, and the fluctuations no longer cancel."""

    angle1: float
    angle2: float
    arrangement: str = "Z"
    yoke_offset: float = 0.0

    def __post_init__(self) -> None:
        if self.arrangement not in ("Z", "W"):
            raise ValueError(f"DoubleCardan arrangement must be 'Z' or 'W', got {self.arrangement!r}")
        for name in ("angle1", "angle2"):
            try:
                Cardan(getattr(self, name))
            except ValueError as exc:
                raise ValueError(f"DoubleCardan {name}: {exc}") from None
        finite(self.yoke_offset, "DoubleCardan yoke_offset (rad)")

    def output_angle(self, phi1: ArrayLike) -> np.ndarray:
        """φ3 (rad), continuous in φ1."""
        phi2 = Cardan(self.angle1).output_angle(phi1)
        return Cardan(self.angle2).input_angle(phi2 - self.yoke_offset) + self.yoke_offset

    def speed_ratio(self, phi1: ArrayLike) -> np.ndarray:
        """ω3/ω1 = (ω2/ω1) / (ω2/ω3 of the second joint at its angle φ3 − δ)."""
        phi3 = self.output_angle(phi1)
        return Cardan(self.angle1).speed_ratio(phi1) / Cardan(self.angle2).speed_ratio(phi3 - self.yoke_offset)

"""Belt, ratchet and friction-wheel drives (MODELS §5)."""
from __future__ import annotations

from dataclasses import dataclass
from math import expm1, inf, isfinite, pi, radians, tan, tau

from rig.mechanisms.checks import degrees_hint, finite, positive


@dataclass(frozen=True)
class Belt:
    """Flat belt on a pulley: friction coefficient ``mu``, wrap angle ``wrap`` β (rad); ``slip`` (fraction,
    1–3 % for flat belts) lowers the driven speed."""

    mu: float
    wrap: float
    slip: float = 0.02

    def __post_init__(self) -> None:
        positive(self.mu, "Belt mu")
        wrap = finite(self.wrap, "Belt wrap")
        positive(wrap, "Belt wrap", "rad", at_most=tau,
                 hint=f"a belt wraps a pulley by at most one turn; the angle is in radians: did you mean "
                      f"{wrap:g}° = {radians(wrap):.4g} rad?")
        if not 0 <= finite(self.slip, "Belt slip") < 1:
            raise ValueError(f"Belt slip is a fraction in [0, 1), got {self.slip!r}")

    def tensions(self, force: float) -> tuple[float, float]:
        """Tight- and slack-side tensions F1, F2 (N) transmitting the peripheral ``force`` F1 − F2 (N) at the
        limit of sliding: F1 = F2 e^{μβ} (Euler–Eytelwein)."""
        if not finite(force, "Belt peripheral force F1 − F2 (N)") >= 0:
            raise ValueError(f"Belt peripheral force F1 − F2 must not be negative (N), got {force!r}: a belt pulls, "
                             "it cannot push; swap the pulleys' roles instead")
        try:
            grip = expm1(self.mu * self.wrap)             # e^{μβ} − 1, exact for a small μβ
        except OverflowError:                             # a grip beyond any number: no slack tension needed (it
            grip = inf                                    # raised OverflowError, not naming mu; an audit)
        slack = force / grip if grip > 0.0 else inf
        if not isfinite(slack + force):
            raise ValueError(f"Belt mu·wrap = {self.mu * self.wrap:g} (mu = {self.mu!r}, wrap = {self.wrap!r} rad) is too "
                             f"small to carry F1 − F2 = {force!r} N: the slack-side tension F/(e^{{μβ}} − 1) "
                             "overflows")
        return slack + force, slack

    def output_speed(self, input_speed: float, d1: float, d2: float) -> float:
        """Driven pulley speed (rad/s, signed like ``input_speed`` (rad/s): a reversed drive reverses it) for the
        driving and driven pulley diameters ``d1``, ``d2`` (> 0, m; their ratio counts), with slip."""
        speed = finite(input_speed, "Belt input_speed (rad/s)")
        return speed * positive(d1, "Belt d1 (m)") / positive(d2, "Belt d2 (m)") * (1 - self.slip)


@dataclass(frozen=True)
class Ratchet:
    """Pawl on a tooth inclined at ``tooth_angle`` γ (rad) with friction ``mu``: it stays engaged
    (self-locking) when tan γ > μ."""

    tooth_angle: float
    mu: float

    def __post_init__(self) -> None:
        gamma = finite(self.tooth_angle, "Ratchet tooth_angle (rad)")
        if not 0 < gamma < pi / 2:
            raise ValueError(f"Ratchet tooth_angle must lie in (0, 90°), got {gamma!r} rad" + degrees_hint(gamma))
        if not finite(self.mu, "Ratchet mu") >= 0:
            raise ValueError(f"Ratchet mu must not be negative, got {self.mu!r}")

    @property
    def self_locking(self) -> bool:
        return tan(self.tooth_angle) > self.mu


@dataclass(frozen=True)
class FrictionWheels:
    """Friction wheels of diameters ``d1`` (driving), ``d2`` (m), relative slip ``slip`` ξ, friction ``mu`` and
    safety factor ``safety`` c against slipping: ratio i = (D2/D1)/(1 − ξ), pressing force Q = c·F_t/μ."""

    d1: float
    d2: float
    mu: float
    slip: float = 0.0
    safety: float = 1.5

    def __post_init__(self) -> None:
        for name in ("d1", "d2", "mu", "slip", "safety"):
            finite(getattr(self, name), f"FrictionWheels {name}")
        if not (self.d1 > 0 and self.d2 > 0 and self.mu > 0 and self.safety >= 1):
            raise ValueError(f"FrictionWheels: diameters and mu must be positive and safety >= 1, got "
                             f"d1 = {self.d1!r}, d2 = {self.d2!r}, mu = {self.mu!r}, safety = {self.safety!r}")
        if not 0 <= self.slip < 1:
            raise ValueError(f"FrictionWheels slip is a fraction in [0, 1), got {self.slip!r}")

    @property
    def ratio(self) -> float:
        """i = ω1/ω2."""
        return _finite_result(self.d2 / self.d1 / (1 - self.slip), "ratio d2/d1", self)

    def pressing_force(self, tangential_force: float) -> float:
        """Q (N) to carry the peripheral force F_t ≥ 0 (N)."""
        if not finite(tangential_force, "FrictionWheels tangential force F_t (N)") >= 0:
            raise ValueError(f"FrictionWheels tangential force F_t must not be negative (N), got {tangential_force!r}: "
                             "the pressing force carries its magnitude")
        return _finite_result(self.safety * tangential_force / self.mu, "pressing force", self)


def _finite_result(value: float, what: str, drive: object) -> float:
    """``value`` if finite, else a ValueError naming ``what`` of ``drive``: its inputs, finite each, give none (a
    diameter or μ of 1e-320 read inf; an audit)."""
    if not isfinite(value):
        raise ValueError(f"{type(drive).__name__}: the {what} overflows for {drive!r} (a diameter or mu too small)")
    return value

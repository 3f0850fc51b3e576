"""Motion laws looked up by name (like python-can interfaces): built-ins plus :func:`register_law`."""
from __future__ import annotations

from math import pi

from rig.motion.laws import AccelPiece as P
from rig.motion.laws import MotionLaw, PiecewiseSineLaw, PolynomialLaw


class UnknownLawError(KeyError):
    """No motion law is registered under the requested name."""

    def __str__(self) -> str:
        return str(self.args[0])


_LAWS: dict[str, MotionLaw] = {}
_ALIASES = {"sinusoidal": "cycloidal", "cosinusoidal": "harmonic", "simple_harmonic": "harmonic",
            "constant_acceleration": "parabolic", "345": "3-4-5", "4567": "4-5-6-7"}


def register_law(law: MotionLaw, name: str | None = None) -> None:
    """Make ``law`` available as ``name`` (default ``law.name``); re-registering a name is an error."""
    key = (name or law.name).lower()
    if key in _LAWS or key in _ALIASES:
        raise ValueError(f"a motion law named {key!r} is already registered")
    _LAWS[key] = law


def get_law(name: str) -> MotionLaw:
    """The law registered as ``name`` (case-insensitive; source names like "sinusoidal" accepted)."""
    key = str(name).lower()
    key = _ALIASES.get(key, key)
    try:
        return _LAWS[key]
    except KeyError:
        raise UnknownLawError(f"unknown motion law {name!r} (known: {', '.join(available_laws())})") from None


def available_laws() -> list[str]:
    return sorted(_LAWS)


_Q = 4 * pi  # quarter-period sine pieces of the modified laws span 1/8 of x
register_law(PiecewiseSineLaw("parabolic", [P(0.0, c0=1.0), P(0.5, c0=-1.0)]))
register_law(PolynomialLaw("3-4-5", [0, 0, 0, 10, -15, 6]))
register_law(PolynomialLaw("4-5-6-7", [0, 0, 0, 0, 35, -84, 70, -20]))
register_law(PiecewiseSineLaw("cycloidal", [P(0.0, c1=1.0, w=2 * pi)]))
register_law(PiecewiseSineLaw("harmonic", [P(0.0, c1=1.0, w=pi, theta=pi / 2)]))
register_law(PiecewiseSineLaw("modified_trapezoid", [
    P(0.0, c1=1.0, w=_Q), P(1 / 8, c0=1.0), P(3 / 8, c1=1.0, w=_Q, theta=pi / 2),
    P(5 / 8, c0=-1.0), P(7 / 8, c1=-1.0, w=_Q, theta=pi / 2)]))
register_law(PiecewiseSineLaw("modified_sine", [
    P(0.0, c1=1.0, w=_Q), P(1 / 8, c1=1.0, w=_Q / 3, theta=pi / 2), P(7 / 8, c1=-1.0, w=_Q, theta=pi / 2)]))

"""Numbers as a person reads them in tables and console lines: one precision per column or range, no negative zero.

No dependencies (the metrics modules use it as well as the report)."""
from __future__ import annotations

import math


def decimals(magnitude: float, significant: int = 3) -> int:
    """Decimals that give ``magnitude`` ``significant`` digits (0 for a magnitude of 10^significant or more, and for
    0 or a non-finite one): the one precision of a column or a range."""
    magnitude = abs(magnitude)
    if not math.isfinite(magnitude) or magnitude == 0.0:
        return 0
    return max(0, significant - 1 - math.floor(math.log10(magnitude)))


def fixed(v: float | None, places: int, sign: bool = False) -> str:
    """``v`` with ``places`` decimals (``sign``: always signed); a value that rounds to zero is an unsigned zero
    (never "-0.000" or "+0.000"); a dash for None or NaN."""
    if v is None or v != v:
        return "—"
    text = f"{v:+.{places}f}" if sign else f"{v:.{places}f}"
    return text[1:] if float(text) == 0.0 and text[0] in "+-" else text


def row_places(mean: float, std: float) -> int:
    """Decimals of a process value's row (mean, min, max, μ ± 3σ, limits at one precision): three digits of the
    ±3σ band's width, four of the mean when σ = 0 or at rounding level, below 1e-9 of the mean (a row read "-19" for
    a minimum of -19.0023 beside a band in hundredths)."""
    return decimals(6 * std, 3) if std > 1e-9 * abs(mean) else decimals(mean, 4)


def fixed_range(lo: float, hi: float, significant: int = 3, sep: str = "…") -> str:
    """``"1.0…42.3"``: both ends with the decimals that give the larger one ``significant`` digits."""
    places = decimals(max(abs(lo), abs(hi)), significant)
    return f"{fixed(lo, places)}{sep}{fixed(hi, places)}"


def plural(n: int, word: str) -> str:
    """``1 recording``, ``2 recordings`` (regular English plurals only)."""
    return f"{n} {word}{'' if n == 1 else 's'}"

"""Structure of planar mechanisms and gear trains: the lab guide's mobility formula and Willis's formula."""
from __future__ import annotations

from math import isfinite
from numbers import Integral

from rig.mechanisms.checks import finite, whole


def mobility(n: int, c5: int, c4: int, passive: int = 0, redundant: int = 0) -> int:
    """M = 3(n − 1) − 2·c5 − c4 − passive − redundant (the lab guide's convention): ``n`` links counting the
    frame, ``c5`` lower pairs (one degree of freedom each), ``c4`` higher pairs, ``passive`` ΣL_p (degrees of
    freedom of passive chains, may be negative), ``redundant`` ΣL_id (independent motions such as an idle
    roller's spin)."""
    n = whole(n, 1, "mobility: n (links counting the frame)")
    c5, c4 = whole(c5, 0, "mobility: c5"), whole(c4, 0, "mobility: c4")
    redundant = whole(redundant, 0, "mobility: redundant (independent motions)")
    if isinstance(passive, bool) or not isinstance(passive, Integral):
        raise ValueError(f"mobility: passive (degrees of freedom of passive chains) must be a whole number, "
                         f"got {passive!r}")
    return 3 * (n - 1) - 2 * c5 - c4 - int(passive) - redundant


def willis(n1: float | None, n3: float | None, carrier: float | None, ratio: float) -> dict[str, float]:
    """Willis: (n1 − n_H)/(n3 − n_H) = i0, ``ratio`` i0 the train's ratio with the carrier held (negative for
    an external mesh chain that reverses). Give two of the speeds ``n1``, ``n3`` and ``carrier`` (any unit),
    get all three."""
    given = {k: v for k, v in (("n1", n1), ("n3", n3), ("carrier", carrier)) if v is not None}
    if len(given) != 2:
        raise ValueError(f"willis: give exactly two of n1, n3, carrier, got {sorted(given) or 'none'}")
    for name, v in (("ratio i0", ratio), *given.items()):
        finite(v, f"willis {name}")
    if ratio == 1:
        raise ValueError("willis: i0 = 1 locks the train (every member turns with the carrier)")
    if ratio == 0:
        raise ValueError("willis: i0 = 0 is no gear train (member 1 could not turn with the carrier held)")
    if n1 is None:
        n1 = carrier + ratio * (n3 - carrier)
    elif n3 is None:
        n3 = carrier + (n1 - carrier) / ratio
    else:
        carrier = (n1 - ratio * n3) / (1 - ratio)
    speeds = {"n1": n1, "n3": n3, "carrier": carrier}
    if not all(isfinite(v) for v in speeds.values()):      # (i0 = 1e-320 read n3 = −inf; an audit)
        raise ValueError(f"willis: the speeds overflow ({speeds}) for i0 = {ratio!r} and the given {given}")
    return speeds

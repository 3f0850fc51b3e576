"""Structure of planar mechanisms and gear trains: the lab guide's mobility formula and Willis's formula."""
from __future__ import annotations


def mobility(n: int, c5: int, c4: int, passive: int = 0, redundant: int = 0) -> int:
    """M = 3(n − 1) − 2·c5 − c4 − passive − redundant (the lab guide's convention): ``n`` links counting the
    frame, ``c5`` lower pairs (one degree of freedom each), ``c4`` higher pairs, ``passive`` ΣL_p (degrees of
    freedom of passive chains, may be negative), ``redundant`` ΣL_id (independent motions such as an idle
    roller's spin)."""
    for name, v in (("n", n), ("c5", c5), ("c4", c4)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise ValueError(f"mobility: {name} must be a non-negative integer, got {v!r}")
    if n < 1:
        raise ValueError("mobility: n counts the frame, so n >= 1")
    return 3 * (n - 1) - 2 * c5 - c4 - passive - redundant


def willis(n1: float | None, n3: float | None, carrier: float | None, ratio: float) -> dict[str, float]:
    """Willis: (n1 − n_H)/(n3 − n_H) = i0, ``ratio`` i0 the train's ratio with the carrier held (negative for
    an external mesh chain that reverses). Give two of the speeds ``n1``, ``n3`` and ``carrier`` (any unit),
    get all three."""
    given = {k: v for k, v in (("n1", n1), ("n3", n3), ("carrier", carrier)) if v is not None}
    if len(given) != 2:
        raise ValueError(f"willis: give exactly two of n1, n3, carrier, got {sorted(given) or 'none'}")
    if ratio == 1:
        raise ValueError("willis: i0 = 1 locks the train (every member turns with the carrier)")
    if n1 is None:
        n1 = carrier + ratio * (n3 - carrier)
    elif n3 is None:
        n3 = carrier + (n1 - carrier) / ratio
    else:
        carrier = (n1 - ratio * n3) / (1 - ratio)
    return {"n1": n1, "n3": n3, "carrier": carrier}

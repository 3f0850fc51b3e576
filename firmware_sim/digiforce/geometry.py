"""Where a polyline crosses the edges of a closed convex quadrilateral (vectorised Cyrus-Beck clipping).

The curve is the polyline through its stored pairs. A point on an edge is inside (the region is closed).
Each edge has a name (``left``, ``right``, ``bottom``, ``top``); a crossing exactly through a corner
belongs to both edges that meet there.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SIDES = ("left", "right", "bottom", "top")
_TOL = 1e-9  # on the segment parameter, to decide which edges a crossing goes through


@dataclass(frozen=True)
class Crossings:
    """Entries and exits in order along the curve; ``*_sides`` rows are boolean masks over ``SIDES``."""

    starts_inside: bool
    ends_inside: bool
    touched: bool               # some part of the polyline lies in the region
    entry_points: np.ndarray    # (n, 2) x, y where the curve enters
    entry_sides: np.ndarray     # (n, 4)
    exit_points: np.ndarray
    exit_sides: np.ndarray


class ConvexQuad:
    """Closed convex region bounded by four named edges, given as corners (x, y) in the order
    bottom-left, bottom-right, top-right, top-left (edges: bottom, right, top, left)."""

    def __init__(self, corners: np.ndarray) -> None:
        c = np.asarray(corners, dtype=float)
        nxt = np.roll(c, -1, axis=0)
        edge = nxt - c                                   # counter-clockwise edges: bottom, right, top, left
        normals = np.stack([-edge[:, 1], edge[:, 0]], axis=1)   # inward for a counter-clockwise polygon
        following = np.roll(edge, -1, axis=0)
        if np.any(edge[:, 0] * following[:, 1] - edge[:, 1] * following[:, 0] <= 0):
            raise ValueError(f"corners {c.tolist()} do not form a convex counter-clockwise quadrilateral")
        order = [3, 1, 0, 2]                             # to SIDES order: left, right, bottom, top
        self._normals = normals[order]                                        # (4, 2)
        self._offsets = -np.sum(self._normals * c[order], axis=1, keepdims=True)  # (4, 1)

    def _signed(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """(4, n): for each edge, a value >= 0 where the point is on the inner side (linear in x, y)."""
        # elementwise, not a matrix product: BLAS would hand it to its thread pool (slower, and a second core)
        return self._normals[:, :1] * x + self._normals[:, 1:] * y + self._offsets

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Which points (x, y) lie in the closed region."""
        x, y = np.atleast_1d(np.asarray(x, float)), np.atleast_1d(np.asarray(y, float))
        return np.all(self._signed(x, y) >= 0.0, axis=0)

    def crossings(self, x: np.ndarray, y: np.ndarray) -> Crossings:
        """All entries into and exits from the region along the polyline (x, y).

        The edge values are linear along a segment, so a segment from s0 to s1 meets an edge's line at
        t = s0 / (s0 - s1). Only segments that are not wholly inside and not wholly beyond one edge are
        clipped (the rest cannot cross the boundary).
        """
        sv = self._signed(x, y)
        inside = sv.min(axis=0) >= 0.0
        empty = np.zeros((0, 2)), np.zeros((0, 4), bool)
        if x.size < 2:
            return Crossings(bool(inside[0]), bool(inside[-1]), bool(inside.any()), *empty, *empty)
        beyond = np.maximum(sv[:, :-1], sv[:, 1:]).min(axis=0) < 0.0   # both ends outside one edge
        cand = np.flatnonzero(~(inside[:-1] & inside[1:]) & ~beyond)
        s0, s1 = sv[:, cand].T, sv[:, cand + 1].T
        den = s1 - s0
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -s0 / den
        t_enter = np.where(den > 0, t, -np.inf)
        t_leave = np.where(den < 0, t, np.inf)
        t_in = np.maximum(t_enter.max(axis=1, initial=-np.inf), 0.0)
        t_out = np.minimum(t_leave.min(axis=1, initial=np.inf), 1.0)
        hits = t_in <= t_out
        in0, in1 = inside[cand], inside[cand + 1]
        enter, leave = ~in0 & (in1 | hits), ~in1 & (in0 | hits)
        ie, il = cand[enter], cand[leave]
        ti, to = t_in[enter], t_out[leave]
        entry_pts = np.stack([x[ie] + ti * (x[ie + 1] - x[ie]), y[ie] + ti * (y[ie + 1] - y[ie])], axis=1)
        exit_pts = np.stack([x[il] + to * (x[il + 1] - x[il]), y[il] + to * (y[il + 1] - y[il])], axis=1)
        entry_sides = t_enter[enter] >= ti[:, None] - _TOL
        exit_sides = t_leave[leave] <= to[:, None] + _TOL
        touched = bool(inside.any() or hits.any())
        return Crossings(bool(inside[0]), bool(inside[-1]), touched, entry_pts, entry_sides, exit_pts, exit_sides)

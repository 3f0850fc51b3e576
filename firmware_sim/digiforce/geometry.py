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
        self.points = c[order]
        self.normals = normals[order]

    def _inside(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        px = x[:, None] - self.points[None, :, 0]
        py = y[:, None] - self.points[None, :, 1]
        return np.all(px * self.normals[:, 0] + py * self.normals[:, 1] >= 0.0, axis=1)

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Which points (x, y) lie in the closed region."""
        return self._inside(np.atleast_1d(np.asarray(x, float)), np.atleast_1d(np.asarray(y, float)))

    def crossings(self, x: np.ndarray, y: np.ndarray) -> Crossings:
        """All entries into and exits from the region along the polyline (x, y)."""
        inside = self._inside(x, y)
        empty = np.zeros((0, 2)), np.zeros((0, 4), bool)
        if x.size < 2:
            return Crossings(bool(inside[0]), bool(inside[-1]), bool(inside.any()), *empty, *empty)
        nx, ny = self.normals[:, 0], self.normals[:, 1]
        x0, y0, dx, dy = x[:-1, None], y[:-1, None], np.diff(x)[:, None], np.diff(y)[:, None]
        num = (x0 - self.points[:, 0]) * nx + (y0 - self.points[:, 1]) * ny
        den = dx * nx + dy * ny
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -num / den
        t_enter = np.where(den > 0, t, -np.inf)
        t_leave = np.where(den < 0, t, np.inf)
        t_in = np.maximum(t_enter.max(axis=1), 0.0)
        t_out = np.minimum(t_leave.min(axis=1), 1.0)
        parallel_out = np.any((den == 0) & (num < 0), axis=1)
        hits = (t_in <= t_out) & ~parallel_out
        in0, in1 = inside[:-1], inside[1:]
        enter = ~in0 & (in1 | hits)
        leave = ~in1 & (in0 | hits)
        ie, il = np.nonzero(enter)[0], np.nonzero(leave)[0]
        entry_pts = np.stack([x[ie] + t_in[ie] * dx[ie, 0], y[ie] + t_in[ie] * dy[ie, 0]], axis=1)
        exit_pts = np.stack([x[il] + t_out[il] * dx[il, 0], y[il] + t_out[il] * dy[il, 0]], axis=1)
        entry_sides = t_enter[ie] >= t_in[ie, None] - _TOL
        exit_sides = t_leave[il] <= t_out[il, None] + _TOL
        touched = bool(inside.any() or hits.any())
        return Crossings(bool(inside[0]), bool(inside[-1]), touched, entry_pts, entry_sides, exit_pts, exit_sides)

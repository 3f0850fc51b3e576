"""Series synthesis (MODELS §3.6): a cam drives the input angle q of a linkage whose output o must follow a
required law o(φ). Each linkage states its loop as A(o)·cos q + B(o)·sin q + C(o) = 0; the input follows from
the tangent-half-angle solution q = 2·atan((B ± sqrt(A² + B² − C²))/(A − C)), the root picked by continuity
from the assembly the linkage starts in, and q', q'' by implicit differentiation. ``forward(q)`` runs the
linkage the ordinary way (independent of the inversion) so a synthesis can be checked end to end.
Lengths in m, angles in rad; derivatives w.r.t. the cam angle φ.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from math import degrees
from typing import NamedTuple

import numpy as np

from rig.plants.cam_bar.chain import SingularPositionError
from rig.plants.cam_bar.fourbar import rocker_angle

Coeffs = tuple[np.ndarray, np.ndarray, np.ndarray]


def _positive(**lengths: float) -> None:
    for name, v in lengths.items():
        if not 0.0 < v < np.inf:
            raise ValueError(f"linkage length {name} must be positive and finite, got {v!r} m")


def _sign(name: str, value: float) -> None:
    """An assembly choice must be +1 or −1 (``side = 0`` or ``5`` read a wrong position silently; an audit)."""
    if value not in (1.0, -1.0):
        raise ValueError(f"linkage {name} is an assembly choice, +1 or -1, got {value!r}")


class Linkage(ABC):
    """A one-loop linkage with input angle q and output o; ``angular_output``: o is an angle (compare mod 2π)."""

    angular_output: bool = True

    @abstractmethod
    def coefficients(self, o: np.ndarray) -> tuple[Coeffs, Coeffs, Coeffs]:
        """(A, B, C) and their first and second derivatives w.r.t. o."""

    @abstractmethod
    def forward(self, q: np.ndarray) -> np.ndarray:
        """Output o for input angles q (rad), computed directly from the linkage geometry."""


@dataclass(frozen=True)
class SliderCrank(Linkage):
    """Crank r (the cam follower, pivot at the origin, angle q), rod l, slider joint on the line y = e at
    x = r cos q + side·sqrt(l² − (r sin q − e)²); output o = x (m)."""

    r: float
    l: float
    e: float = 0.0
    side: float = 1.0
    angular_output = False

    def __post_init__(self) -> None:
        _positive(r=self.r, l=self.l)
        _sign("side", self.side)
        if not np.isfinite(self.e):
            raise ValueError(f"slider offset e must be a finite length, got {self.e!r} m")

    def coefficients(self, o):
        z, one = np.zeros_like(o), np.ones_like(o)
        r, e = self.r, self.e
        return ((-2 * r * o, -2 * r * e + z, o * o + r * r + e * e - self.l ** 2),
                (-2 * r * one, z, 2 * o), (z, z, 2 * one))

    def forward(self, q):
        rad = self.l ** 2 - (self.r * np.sin(q) - self.e) ** 2
        if np.any(rad < 0.0):
            raise SingularPositionError("slider-crank cannot be assembled: the rod does not reach the slider line")
        return self.r * np.cos(q) + self.side * np.sqrt(rad)


@dataclass(frozen=True)
class FourBar(Linkage):
    """Frame l1 (input pivot at the origin, output pivot at (l1, 0)), input crank l2 at q, coupler l3,
    output rocker l4 at o; ``branch`` ±1 the assembly of :func:`rig.plants.cam_bar.fourbar.rocker_angle`."""

    l1: float
    l2: float
    l3: float
    l4: float
    branch: float = 1.0

    def __post_init__(self) -> None:
        _positive(l1=self.l1, l2=self.l2, l3=self.l3, l4=self.l4)
        _sign("branch", self.branch)

    def coefficients(self, o):
        l1, l2, l3, l4 = self.l1, self.l2, self.l3, self.l4
        co, so = np.cos(o), np.sin(o)
        k = 2 * l2 * l4
        return ((-2 * l2 * (l1 + l4 * co), -k * so, l1 ** 2 + l2 ** 2 + l4 ** 2 - l3 ** 2 + 2 * l1 * l4 * co),
                (k * so, -k * co, -2 * l1 * l4 * so), (k * co, k * so, -2 * l1 * l4 * co))

    def forward(self, q):
        return rocker_angle((self.l1, self.l2, self.l3, self.l4), q, self.branch)


@dataclass(frozen=True)
class SlottedLink(Linkage):
    """Crank r (input, pivot at the origin, angle q) whose pin slides in a lever pivoted at (−d, 0);
    output o = lever angle = atan2(r sin q, d + r cos q)."""

    r: float
    d: float

    def __post_init__(self) -> None:
        _positive(r=self.r, d=self.d)

    def coefficients(self, o):
        r, d = self.r, self.d
        co, so = np.cos(o), np.sin(o)
        return ((-r * so, r * co, -d * so), (-r * co, -r * so, -d * co), (r * so, -r * co, d * so))

    def forward(self, q):
        return np.arctan2(self.r * np.sin(q), self.d + self.r * np.cos(q))


@dataclass(frozen=True)
class DoubleSlider(Linkage):
    """Double-slider (Scotch-yoke) chain: crank r at angle q drives a yoke along x; output o = x = r cos q (m)."""

    r: float
    angular_output = False

    def __post_init__(self) -> None:
        _positive(r=self.r)

    def coefficients(self, o):
        z, one = np.zeros_like(o), np.ones_like(o)
        return ((self.r * one, z, -o), (z, z, -one), (z, z, z))

    def forward(self, q):
        return self.r * np.cos(q)


class FollowerLaw(NamedTuple):
    """Input (follower) angle q (rad) and its derivatives q' (rad/rad), q'' (rad/rad²) at the cam angles."""

    q: np.ndarray
    q_p: np.ndarray
    q_pp: np.ndarray


def _mismatch(linkage: Linkage, q: float, o: float) -> float:
    d = float(linkage.forward(np.array([q]))[0]) - o
    return abs(np.angle(np.exp(1j * d))) if linkage.angular_output else abs(d)


def synthesize(linkage: Linkage, o: np.ndarray, o_p: np.ndarray, o_pp: np.ndarray,
               q_start: float | None = None) -> FollowerLaw:
    """Follower law q(φ) making ``linkage`` output ``o`` (with o', o'' w.r.t. φ), in cam-angle order.

    At the first point the root is one whose forward run reproduces o (the linkage's assembly), the one
    nearest ``q_start`` if both do; after that, the root nearest the previous one (continuity). Raises
    :class:`SingularPositionError` where o cannot be reached or the linkage is at a dead centre (F_q = 0).
    """
    o, o_p, o_pp = (np.asarray(v, dtype=float) for v in (o, o_p, o_pp))
    if o.ndim != 1 or o.size == 0 or o_p.shape != o.shape or o_pp.shape != o.shape:
        raise ValueError(f"synthesize needs the output law o, o', o'' as 1-D arrays of one length, got shapes "
                         f"{o.shape}, {o_p.shape}, {o_pp.shape}")
    if not (np.isfinite(o).all() and np.isfinite(o_p).all() and np.isfinite(o_pp).all()):
        raise ValueError("synthesize needs finite output values o, o', o'' (NaN or inf found)")
    (a, b, c), (a1, b1, c1), (a2, b2, c2) = linkage.coefficients(o)
    disc = a * a + b * b - c * c
    if np.any(disc < 0.0):
        i = int(np.argmax(disc < 0.0))
        raise SingularPositionError(f"{type(linkage).__name__} cannot reach the output {o[i]:.6g} at point {i}")
    root = np.sqrt(disc)
    roots = np.stack([2 * np.arctan2(b + root, a - c), 2 * np.arctan2(b - root, a - c)])
    fits = [k for k in (0, 1) if _mismatch(linkage, roots[k, 0], o[0]) < 1e-8 * (1.0 + abs(o[0]))]
    if not fits:
        raise SingularPositionError(f"no root of {type(linkage).__name__} reproduces the first output {o[0]:.6g}")
    ref = roots[fits[0], 0] if q_start is None else q_start
    q = np.empty_like(o)
    prev = min((roots[k, 0] for k in fits), key=lambda v: abs(np.angle(np.exp(1j * (v - ref)))))
    for i in range(o.size):
        steps = np.angle(np.exp(1j * (roots[:, i] - prev)))
        prev = prev + steps[np.argmin(np.abs(steps))]
        q[i] = prev
    _through_dead_centre(linkage, roots, q)
    cq, sq = np.cos(q), np.sin(q)
    f_q = -a * sq + b * cq
    if np.any(np.abs(f_q) < 1e-12 * np.hypot(a, b)):
        i = int(np.argmax(np.abs(f_q) < 1e-12 * np.hypot(a, b)))
        raise SingularPositionError(f"{type(linkage).__name__} at a dead centre at q = {degrees(q[i]):.4g}° "
                                    f"(point {i})")
    f_o = a1 * cq + b1 * sq + c1
    q_p = -f_o * o_p / f_q
    f_qq = -a * cq - b * sq
    f_qo = -a1 * sq + b1 * cq
    f_oo = a2 * cq + b2 * sq + c2
    q_pp = -(f_qq * q_p ** 2 + 2 * f_qo * q_p * o_p + f_oo * o_p ** 2 + f_o * o_pp) / f_q
    return FollowerLaw(q, q_p, q_pp)


def _through_dead_centre(linkage: Linkage, roots: np.ndarray, q: np.ndarray) -> None:
    """Raise :class:`SingularPositionError` where the two roots (the linkage's two assemblies) lie within two of the
    law's steps in q of each other: the output passes (or nearly passes) the extreme it has at a dead centre (F_q = 0)
    between two samples, where continuity cannot tell which assembly the input goes on in — it would bounce off the
    dead centre (a velocity step) or give a q' of 0/0. A law sampled on a grid rarely lands on F_q = 0 exactly."""
    if q.size < 2:
        return
    gap = np.abs(np.angle(np.exp(1j * (roots[0] - roots[1]))))
    dq = np.abs(np.diff(q))
    near = np.maximum(np.r_[dq[0], dq], np.r_[dq, dq[-1]])      # the larger of the steps beside each point
    close = gap < 2.0 * near
    if np.any(close):
        i = int(np.argmax(close))
        raise SingularPositionError(
            f"{type(linkage).__name__} passes a dead centre near point {i} (q = {degrees(q[i]):.4g}°): its two "
            f"assemblies are {degrees(gap[i]):.3g}° apart there, within two steps of the law "
            f"({degrees(near[i]):.3g}° each): the output reaches the extreme the linkage has at a dead centre, "
            f"where the input's motion cannot be inverted (q' = 0/0); keep the required output short of it")


def round_trip_error(linkage: Linkage, law: FollowerLaw, o: np.ndarray) -> float:
    """Largest |forward(q) − o| (angles compared modulo 2π) for a synthesized law: the end-to-end check."""
    d = linkage.forward(law.q) - np.asarray(o, dtype=float)
    return float(np.max(np.abs(np.angle(np.exp(1j * d)) if linkage.angular_output else d)))

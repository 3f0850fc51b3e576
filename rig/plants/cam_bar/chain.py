"""Level-0 kinematic chain of the pin-insertion mechanism (MODELS §3.2), pivot B0 at the origin.

Loop closure ``L3·e^{iψ} + l4·e^{iϑ} = (s0 − s) + i·e_sk``: follower B0→C (angle ψ), rod C→D
(angle ϑ), slider joint D = (s0 − s, e_sk). Of the two assemblies for a given slider position,
``branch`` selects one: ψ = atan2(e_sk, u) − branch·acos((L3² + |B0D|² − l4²)/(2·L3·|B0D|)), i.e.
branch = +1 puts the rod joint C clockwise of the line B0→D (the machine: follower leaning 4.65°
right of vertical, rod pointing back to the slider in −x).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from math import degrees
from typing import NamedTuple

import numpy as np

DEAD_CENTRE_TOL = 1e-6  # |sin(ϑ − ψ)| below this: follower and rod collinear


class SingularPositionError(ValueError):
    """The chain cannot be assembled (no real root) or sits at a dead centre; the message says where."""


class Angles(NamedTuple):
    """ψ, ϑ (rad), their cosines and sines, and sin(ϑ − ψ)."""

    psi: np.ndarray
    theta: np.ndarray
    cp: np.ndarray
    sp: np.ndarray
    ct: np.ndarray
    st: np.ndarray
    sin_rel: np.ndarray


@dataclass(frozen=True)
class Chain:
    """Geometry in SI (m) and the assembly branch (+1 or −1)."""

    L3: float
    l4: float
    e_sk: float
    s0: float
    branch: float

    def _where(self, s: np.ndarray, i: int, phi: np.ndarray | None) -> str:
        at = f"cam angle φ = {degrees(float(phi.flat[i])):.4g}°, " if phi is not None else ""
        return (f"{at}slider stroke s = {float(s.flat[i]) * 1e3:.6g} mm "
                f"(L3 = {self.L3 * 1e3:g} mm, l4 = {self.l4 * 1e3:g} mm, e_sk = {self.e_sk * 1e3:g} mm, "
                f"s0 = {self.s0 * 1e3:g} mm)")

    def angles(self, s: np.ndarray, phi: np.ndarray | None = None) -> "Angles":
        """Follower angle ψ and rod angle ϑ (rad) with their cosines/sines for slider strokes ``s`` (m).

        ``phi`` (the cam angles the strokes belong to) only serves the error message.
        """
        u = self.s0 - s
        rho2 = u * u + self.e_sk ** 2
        rho = np.sqrt(rho2)
        cos_g = (self.L3 ** 2 - self.l4 ** 2 + rho2) / (2.0 * self.L3 * rho)
        if np.any(np.abs(cos_g) > 1.0):
            i = int(np.argmax(np.abs(cos_g) > 1.0))
            raise SingularPositionError(
                f"no real assembly of follower and rod: |B0D| = {rho.flat[i] * 1e3:.6g} mm is outside "
                f"[|L3 − l4|, L3 + l4] = [{abs(self.L3 - self.l4) * 1e3:g}, {(self.L3 + self.l4) * 1e3:g}] mm at "
                + self._where(s, i, phi))
        psi = np.arctan2(self.e_sk, u) - self.branch * np.arccos(cos_g)
        cp, sp = np.cos(psi), np.sin(psi)
        ct, st = (u - self.L3 * cp) / self.l4, (self.e_sk - self.L3 * sp) / self.l4
        sin_rel = st * cp - ct * sp
        if np.any(np.abs(sin_rel) < DEAD_CENTRE_TOL):
            i = int(np.argmax(np.abs(sin_rel) < DEAD_CENTRE_TOL))
            raise SingularPositionError("dead centre (follower and rod collinear) at " + self._where(s, i, phi))
        return Angles(psi, np.arctan2(st, ct), cp, sp, ct, st, sin_rel)

    def slider(self, psi: np.ndarray) -> np.ndarray:
        """Slider stroke s (m) for follower angle ψ (rad): the root of ``s² + D_s s + E_s = 0`` (MODELS §3.2)

        with the rod on the same side of its joint C as at s = 0 (``rod_side``), i.e.
        x_D = L3 cosψ + rod_side·sqrt(l4² − (e_sk − L3 sinψ)²). The mechanism checks at construction that
        the rod never passes vertical over the stroke, so this is the inverse of :meth:`angles`.
        """
        psi = np.asarray(psi, dtype=float)
        rad = self.l4 ** 2 - (self.e_sk - self.L3 * np.sin(psi)) ** 2
        if np.any(rad < 0.0):
            i = int(np.argmax(rad < 0.0))
            raise SingularPositionError(f"follower angle ψ = {degrees(float(psi.flat[i])):.6g}° cannot be reached: "
                                        f"the rod (l4 = {self.l4 * 1e3:g} mm) does not reach the slider line "
                                        f"y = {self.e_sk * 1e3:g} mm")
        x_d = self.L3 * np.cos(psi) + self.rod_side * np.sqrt(rad)
        return self.s0 - x_d

    @cached_property
    def rod_side(self) -> float:
        """sign(cos ϑ) at s = 0 on this branch (−1: slider joint D left of the rod joint C)."""
        return float(np.sign(self.angles(np.array([0.0])).ct[0])) or 1.0

    def derivatives(self, a: "Angles", s_p: np.ndarray, s_pp: np.ndarray):
        """ψ', ψ'', ϑ', ϑ'' from the loop closure differentiated w.r.t. the drive variable.

        ``s_p``, ``s_pp`` are ds/dq, d²s/dq² for any drive variable q (cam angle or time); the 2×2 system's
        determinant is L3·l4·sin(ϑ − ψ).
        """
        det_l = self.L3 * a.sin_rel
        psi_p = -s_p * a.ct / det_l
        theta_p = s_p * a.cp / (self.l4 * a.sin_rel)
        b1 = -s_pp + self.L3 * psi_p ** 2 * a.cp + self.l4 * theta_p ** 2 * a.ct
        b2 = self.L3 * psi_p ** 2 * a.sp + self.l4 * theta_p ** 2 * a.st
        psi_pp = (b1 * a.ct + b2 * a.st) / det_l
        theta_pp = -(b2 * a.sp + b1 * a.cp) / (self.l4 * a.sin_rel)
        return psi_p, psi_pp, theta_p, theta_pp

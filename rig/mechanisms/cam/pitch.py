"""Pitch curve of the pin-insertion cam in the cam frame and its radius of curvature (MODELS §2, §3.2).

The roller centre relative to the cam centre is w(φ) = B_R − A0 in the fixed frame; the cam turns by d·φ
(d = ``cam_direction``), so in the cam frame p = R(−dφ)·w, p' = R(−dφ)(w' − dJw), p'' = R(−dφ)(w'' − 2dJw' − w)
with J the quarter turn. ρ is signed so that a convex stretch (curving round the cam centre) is positive:
on a dwell (ψ constant) the pitch curve is a circle of radius r about the cam centre and ρ = r.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rig.mechanisms.cam.curvature import curvature_radius

if TYPE_CHECKING:
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism


@dataclass(frozen=True)
class PitchCurve:
    """Cam angles φ (rad), pitch points (x, y) in the cam frame (m), signed radius of curvature ρ (m)."""

    phi: np.ndarray
    x: np.ndarray
    y: np.ndarray
    rho: np.ndarray


def pitch_curve(mech: "PinInsertionMechanism", phi: np.ndarray) -> PitchCurve:
    """Pitch curve and ρ(φ) of ``mech``'s cam at cam angles ``phi`` (rad)."""
    phi = np.asarray(phi, dtype=float)
    st = mech.state(phi)
    cp, sp, l3, d = st.trig.cp, st.trig.sp, mech.l3, mech.cam_direction
    wx, wy = l3 * cp - mech.x_A0, l3 * sp - mech.y_A0
    w1x, w1y = -l3 * sp * st.psi_p, l3 * cp * st.psi_p
    w2x = -l3 * (sp * st.psi_pp + cp * st.psi_p ** 2)
    w2y = l3 * (cp * st.psi_pp - sp * st.psi_p ** 2)
    q1x, q1y = w1x + d * wy, w1y - d * wx                     # w' − dJw, J(x, y) = (−y, x)
    q2x, q2y = w2x + 2 * d * w1y - wx, w2y - 2 * d * w1x - wy  # w'' − 2dJw' − w
    rho = -d * curvature_radius(q1x, q1y, q2x, q2y)
    c, s = np.cos(d * phi), np.sin(d * phi)                    # R(−dφ)
    return PitchCurve(phi, c * wx + s * wy, -s * wx + c * wy, rho)


def flank_radius(rho: np.ndarray, roller_radius: float, outer: np.ndarray) -> np.ndarray:
    """Signed profile radius (m, + convex as the roller sees it) of the groove wall the roller touches: the inner
    wall (at r − r_R from the cam centre) ρ − r_R, the outer wall (at r + r_R, ``outer`` True) −(ρ + r_R), for the
    pitch curve's signed radius ρ (+ curving round the cam centre)."""
    return np.where(outer, -(rho + roller_radius), rho - roller_radius)

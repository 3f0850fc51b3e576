"""Flank-switch angles: where the cam contact moment (with or without the spring) changes sign."""
from __future__ import annotations

from math import tau
from typing import TYPE_CHECKING

import numpy as np
from scipy.optimize import brentq

if TYPE_CHECKING:
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism


EDGE = 1e-6          # rad: the scan point just before a program boundary (closer ones evaluate as the next segment)


def contact_moment(mech: "PinInsertionMechanism", phi: np.ndarray, k: float, spring: bool,
                   omega: float) -> np.ndarray:
    """Cam moment on the follower (N·m) at cam speed ``omega`` (rad/s): M_Σ with spring rate ``k`` (N/m), or M23
    without the spring."""
    res = mech.kinetostatics(phi, omega, 0.0, k)
    return res.M_sigma if spring else res.M23


def sign_changes(values: np.ndarray) -> np.ndarray:
    """Indices i where values[i] and values[i+1] lie on different sides of zero (≥ 0 counts as positive)."""
    pos = values >= 0.0
    return np.flatnonzero(pos[:-1] != pos[1:])


def flank_switch_angles(mech: "PinInsertionMechanism", k: float, spring: bool, omega: float,
                        n: int) -> np.ndarray:
    """Angles (rad, [0, 2π)) of contact-force sign changes over one revolution at constant speed.

    Scanned on ``n`` equal steps and on both sides of every cam-program boundary (the acceleration, and with it the
    moment, jumps there: a sign change within a sliver before the boundary and back across it would cancel inside one
    step), each bracket refined with Brent's method to 1e-10 rad.
    """
    starts = np.mod(mech.program.starts, tau)
    grid = np.unique(np.concatenate([np.linspace(0.0, tau, n + 1), starts, np.clip(starts - EDGE, 0.0, tau)]))
    m = contact_moment(mech, grid, k, spring, omega)
    found = []
    for i in sign_changes(m):
        f = lambda x: float(contact_moment(mech, np.array([x]), k, spring, omega)[0])  # noqa: E731
        a, b = grid[i], grid[i + 1]
        fa, fb = f(a), f(b)
        found.append(brentq(f, a, b, xtol=1e-10) if fa * fb < 0.0 else (a if fa == 0.0 else b))
    return np.unique(np.mod(found, tau))

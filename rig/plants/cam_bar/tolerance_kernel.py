"""Compiled full deviated chain of the tolerance analysis (docs/tolerance.md, MODELS §3.5).

One element (machine i, cam angle j): the cam side gives ψ' from ``A cosψ + B sinψ + C = 0`` with
A = 2x_A0 l3, B = 2y_A0 l3, C = r² − x_A0² − y_A0² − l3², i.e. ψ' = θ + β·α with θ = atan2(B, A),
cos α = −C/√(A² + B²) and β the nominal root side; cos ψ' and sin ψ' follow by the angle-addition formulas
(no trigonometric call per element). The bar side gives s' = s0 − (L3 cosψ' + rod_side·√(l4² − (e_sk −
L3 sinψ')²)). Deviations ``dev`` are rows in the order of :data:`rig.plants.cam_bar.tolerance.PARAMS`
(x_A0, y_A0, l3, r, s0, L3, l4, e_sk), lengths in m.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

OK, CAM_UNREACHABLE, ROD_UNREACHABLE = 0, 1, 2  # status codes: (code, machine, angle) of the first failure


@njit(cache=True, nogil=True)
def strokes(dev: np.ndarray, q: np.ndarray, r: np.ndarray, branch: np.ndarray, rod_side: float,
            offset: np.ndarray, out: np.ndarray) -> tuple:
    """Fill ``out[i, j]`` with s'(machine i, angle j) − ``offset[j]`` (m). ``q``: nominal (x_A0, y_A0, l3, 0, s0,
    L3, l4, e_sk) (m); ``r``, ``branch``: nominal pitch radius (m) and cam-side root (±1) per angle. Returns
    (status, i, j): ``OK`` or the first element whose deviated chain cannot be assembled."""
    n, m = dev.shape[1], r.size
    for i in range(n):
        x, y, l3 = q[0] + dev[0, i], q[1] + dev[1, i], q[2] + dev[2, i]
        dr, s0, L3, l4, e = dev[3, i], q[4] + dev[4, i], q[5] + dev[5, i], q[6] + dev[6, i], q[7] + dev[7, i]
        a, b = 2.0 * x * l3, 2.0 * y * l3
        h = math.hypot(a, b)
        ca, sa = a / h, b / h
        c0 = -x * x - y * y - l3 * l3
        l4sq = l4 * l4
        for j in range(m):
            rr = r[j] + dr
            cos_al = -(rr * rr + c0) / h
            if cos_al > 1.0 or cos_al < -1.0:
                return CAM_UNREACHABLE, i, j
            sin_al = branch[j] * math.sqrt(1.0 - cos_al * cos_al)
            cp = ca * cos_al - sa * sin_al
            sp = sa * cos_al + ca * sin_al
            hh = e - L3 * sp
            rad = l4sq - hh * hh
            if rad < 0.0:
                return ROD_UNREACHABLE, i, j
            out[i, j] = s0 - (L3 * cp + rod_side * math.sqrt(rad)) - offset[j]
    return OK, 0, 0

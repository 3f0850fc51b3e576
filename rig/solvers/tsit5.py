"""Tsitouras 5(4) adaptive explicit Runge–Kutta (Ch. Tsitouras, "Runge–Kutta pairs of order 5(4) satisfying only
the first column simplifying assumption", Comput. Math. Appl. 62 (2011) 770–775), compiled for a numba RHS, else
in pure Python floats.

Seven stages with FSAL (six RHS calls per accepted step, as DP45), a fifth-order solution with a smaller principal
error than Dormand–Prince's, an embedded fourth-order estimate and the paper's free quartic interpolant. The
coefficients are the paper's (to double precision); ``tests/solvers`` checks every order condition of the pair and
of the interpolant. Same error norm and controller as :class:`~rig.solvers.dopri.DormandPrince45`; the compiled
step is ``rig/solvers/templates/tsit5.py``.
"""
from __future__ import annotations

import numpy as np

from rig.solvers.dopri import EmbeddedPair, lower_triangle, python_tableau

C = np.array([0.0, 0.161, 0.327, 0.9, 0.98002554090450968573, 1.0])
_ROWS = ((0.161,),
         (-0.008480655492356988544, 0.33548065549235698854),
         (2.8971530571054934321, -6.3594484899750748431, 4.3622954328695814110),
         (5.3258648284392566044, -11.748883564062827878, 7.4955393428898362083, -0.092495066361755249257),
         (5.8614554429464200287, -12.920969317847109292, 8.1593678985761586432, -0.071584973281400997225,
          -0.028269050394068382909))
B = np.array([0.096460766818065229518, 0.01, 0.47988965041449957478, 1.3790085741037418932,
              -3.2900695154360806799, 2.3247105240997739824])
#: b − b̂ (the fourth-order weights b̂ include the FSAL stage: b̂₇ = 1/66)
E = B.tolist() + [0.0] - np.array([0.094680755765839458075, 0.0091835655403432530968, 0.48777052842476157079,
                                    1.2342975669304789857, -2.7077123499835254549, 1.8666284181705870358, 1.0 / 66.0])
#: the quartic interpolant b_i(θ) = Σ_c P[i, c]·θ^(c+1), stage rows, columns θ¹..θ⁴
P = np.array([
    [1.0, -2.7637061972748259113, 2.9132554618219127438, -1.0530884977290216],
    [0.0, 0.13169999999999999727, -0.22339999999999999818, 0.1017],
    [0.0, 3.9302962368947515285, -5.9410338721315047347, 2.4906272856512527930],
    [0.0, -12.411077166933676984, 30.338188630282321598, -16.548102889244902720],
    [0.0, 37.509313416511039195, -88.178904894766401101, 47.379521962819281220],
    [0.0, -27.896526289197287806, 65.091894674793671526, -34.870657861496609740],
    [0.0, 1.5, -4.0, 2.5]])
A = lower_triangle(_ROWS)


class Tsitouras45(EmbeddedPair):
    """Adaptive Tsitouras 5(4) with FSAL, local extrapolation and its quartic dense output; options as
    :class:`~rig.solvers.dopri.DormandPrince45` (``stiffness``: Hairer's test on stages 6 and 7, both at t + h,
    against 3.5, the stability boundary of the fifth-order solution on the negative real axis: −3.507)."""

    method, label, P, limit = "tsit5", "Tsit5", P, 3.5
    tableau = python_tableau(A, B, C, E)

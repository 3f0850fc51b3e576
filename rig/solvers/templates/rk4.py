"""Compiled classical Runge–Kutta 4 step (inserted into :mod:`runs` copies; as :class:`rig.solvers.rk4.RK4`'s
Python step). K rows: k1..k4 and f(t_new, y_new)."""

from numba import njit

from rig.solvers.compiled import T0, T_BOUND
from rig.solvers.rk4 import P

# <kernels>
kernel = lipschitz = fixed_step = min_step = finite = None  # bound in generated copies
UNDERFLOW = NONFINITE = 1
# </kernels>
ADAPTIVE = False  # fixed step: events on re-stepped states in the Python driver (integrate.py)


@njit(cache=True, error_model="numpy")
def one_step(t, h_abs, w, y, y_new, K, p, ws):
    """One fixed step of size h_abs (the last one lands on t_bound; see :mod:`runs`); stage states in ws[0:3]."""
    h, t_new = fixed_step(t, h_abs, w[T_BOUND], w[T0])
    if not h >= min_step(t):
        return UNDERFLOW, t, h, h_abs, 0, 0.0
    n = y.size
    hh = 0.5 * h
    y2, y3, y4 = ws[0], ws[1], ws[2]
    for i in range(n):
        y2[i] = y[i] + hh * K[0, i]
    kernel(t + hh, y2, p, K[1])
    for i in range(n):
        y3[i] = y[i] + hh * K[1, i]
    kernel(t + hh, y3, p, K[2])
    for i in range(n):
        y4[i] = y[i] + h * K[2, i]
    kernel(t + h, y4, p, K[3])
    for i in range(n):
        y_new[i] = y[i] + h / 6 * (K[0, i] + 2 * K[1, i] + 2 * K[2, i] + K[3, i])
    hl = h * lipschitz(K[3], K[2], y4, y3)
    if not finite(y_new):
        return NONFINITE, t_new, h, h_abs, 3, hl
    kernel(t_new, y_new, p, K[4])
    return 0, t_new, h, h_abs, 4, hl

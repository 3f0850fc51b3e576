"""Compiled explicit Euler step (inserted into :mod:`runs` copies; as :class:`rig.solvers.euler.Euler`'s
Python step). K rows: f(t, y) and f(t_new, y_new)."""
import math

from numba import njit

from rig.solvers.compiled import T0, T_BOUND
from rig.solvers.euler import EULER_P as P

# <kernels>
kernel = lipschitz = fixed_step = min_step = finite = None  # bound in generated copies
UNDERFLOW = NONFINITE = 1
# </kernels>
ADAPTIVE = False  # fixed step: events on re-stepped states in the Python driver (integrate.py)


@njit(cache=True, error_model="numpy")
def one_step(t, h_abs, w, y, y_new, K, p, ws):
    """y_new = y + h·f(t, y), fixed h (the last step lands on t_bound; see :mod:`runs`)."""
    h, t_new = fixed_step(t, h_abs, w[T_BOUND], w[T0])
    if not h >= min_step(t):
        return UNDERFLOW, t, h, h_abs, 0, 0.0
    for i in range(y.size):
        y_new[i] = y[i] + h * K[0, i]
    if not finite(y_new):
        return NONFINITE, t_new, h, h_abs, 0, math.nan
    kernel(t_new, y_new, p, K[1])
    return 0, t_new, h, h_abs, 1, h * lipschitz(K[1], K[0], y_new, y)

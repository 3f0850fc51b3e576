"""Compiled semi-implicit (symplectic) Euler step (inserted into :mod:`runs` copies; as
:class:`rig.solvers.euler.SymplecticEuler`'s Python step). The positions q: the components whose bit is set in
w[QMASK], the others v. K rows: f(t, y),
the step's mean slope (y_new − y)/h and f(t_new, y_new)."""
import math

from numba import njit

from rig.solvers.compiled import QMASK, T0, T_BOUND
from rig.solvers.euler import SYMPLECTIC_P as P

# <kernels>
kernel = lipschitz = fixed_step = min_step = finite = None  # bound in generated copies
UNDERFLOW = NONFINITE = 1
# </kernels>
ADAPTIVE = False  # fixed step: events on re-stepped states in the Python driver (integrate.py)


@njit(cache=True, error_model="numpy")
def one_step(t, h_abs, w, y, y_new, K, p, ws):
    """Kick v_new = v + h·f_v(t, q, v), drift q_new = q + h·f_q(t, q, v_new); fixed h (see :mod:`runs`)."""
    h, t_new = fixed_step(t, h_abs, w[T_BOUND], w[T0])
    if not h >= min_step(t):
        return UNDERFLOW, t, h, h_abs, 0, 0.0
    mask = int(w[QMASK])
    for i in range(y.size):
        y_new[i] = y[i] if (mask >> i) & 1 else y[i] + h * K[0, i]
    kernel(t, y_new, p, K[1])
    for i in range(y.size):
        if (mask >> i) & 1:
            y_new[i] = y[i] + h * K[1, i]
        else:
            K[1, i] = K[0, i]
    if not finite(y_new):
        return NONFINITE, t_new, h, h_abs, 1, math.nan
    kernel(t_new, y_new, p, K[2])
    return 0, t_new, h, h_abs, 2, h * lipschitz(K[2], K[0], y_new, y)

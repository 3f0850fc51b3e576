"""The step-size controller of the adaptive methods (scipy's), one function for the Python and the compiled
steps (:mod:`rig.solvers.templates` import it into their generated modules)."""
from numba import njit


@njit(cache=True, error_model="numpy")
def step_factor(err: float, accepted: bool, rejected: bool, exponent: float, safety: float, min_factor: float,
                max_factor: float) -> float:
    """Factor on |h| after a trial step with error norm ``err``: safety·err^exponent, at least ``min_factor`` for a
    rejected step; for an ``accepted`` one at most ``max_factor`` (``max_factor`` for err = 0) and at most 1 when
    an earlier trial of the same step was ``rejected`` (no growth right after a rejection)."""
    if not accepted:
        return max(min_factor, safety * err ** exponent)
    factor = max_factor if err == 0.0 else min(max_factor, safety * err ** exponent)
    return min(1.0, factor) if rejected else factor

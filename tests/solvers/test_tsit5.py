"""The Tsitouras 5(4) pair as published: every order condition of its fifth-order solution, of the embedded fourth-
order estimate and of the quartic interpolant (Butcher's rooted trees), and its stability boundary."""
import math
from functools import cache

import numpy as np
import pytest

from rig.solvers import dopri, tsit5
from rig.solvers.dopri import DormandPrince45
from rig.solvers.tsit5 import Tsitouras45


@cache
def trees(order: int) -> tuple:
    """Rooted trees with ``order`` nodes, each a sorted tuple of its subtrees."""
    if order == 1:
        return ((),)
    found = set()

    def children(left: int, least: tuple) -> list:
        if left == 0:
            return [()]
        out = []
        for k in range(1, left + 1):
            for t in trees(k):
                if (k, t) >= least:
                    out += [((t,) + rest) for rest in children(left - k, (k, t))]
        return out

    for kids in children(order - 1, (0, ())):
        found.add(tuple(sorted(kids)))
    return tuple(sorted(found))


def density(t: tuple) -> float:
    """γ(t) = |t|·Π γ(subtrees)."""
    return size(t) * math.prod(density(s) for s in t)


def size(t: tuple) -> int:
    return 1 + sum(size(s) for s in t)


def stage_weights(t: tuple, A: np.ndarray) -> np.ndarray:
    """φ(t) per stage: the product over the subtrees of A·φ(subtree) (ones for a single node)."""
    out = np.ones(A.shape[0])
    for s in t:
        out = out * (A @ stage_weights(s, A))
    return out


def _full_tableau():
    """The seven stages (the FSAL stage's row is b), b, b̂, the interpolant matrix."""
    A = np.zeros((7, 7))
    A[:6, :6] = tsit5.A
    A[6, :6] = tsit5.B
    b = np.r_[tsit5.B, 0.0]
    return A, b, b - tsit5.E, tsit5.P


def test_the_tree_counts_are_butchers():
    assert [len(trees(k)) for k in range(1, 6)] == [1, 1, 2, 4, 9]


def test_every_order_condition_holds():
    A, b, b_hat, _ = _full_tableau()
    assert np.allclose(A.sum(axis=1), np.r_[tsit5.C, 1.0], atol=1e-15)          # row sums = nodes
    for order, weights in ((5, b), (4, b_hat)):
        for k in range(1, order + 1):
            for t in trees(k):
                assert weights @ stage_weights(t, A) == pytest.approx(1.0 / density(t), abs=5e-14), (order, t)
    # the estimate is of order 4 exactly: some fifth-order condition fails for b̂
    assert max(abs(b_hat @ stage_weights(t, A) - 1.0 / density(t)) for t in trees(5)) > 1e-4


@pytest.mark.parametrize("theta", [0.1, 0.37, 0.5, 0.81, 1.0])
def test_the_interpolant_is_of_order_four_and_ends_on_the_step(theta):
    A, b, _, P = _full_tableau()
    b_theta = P @ theta ** np.arange(1, P.shape[1] + 1)
    for k in range(1, 5):
        for t in trees(k):
            assert b_theta @ stage_weights(t, A) == pytest.approx(theta ** k / density(t), abs=5e-14), (theta, t)
    if theta == 1.0:
        np.testing.assert_allclose(b_theta, b, atol=5e-14)


def _boundary(A: np.ndarray, b: np.ndarray) -> float:
    """Where |R(x)| = 1 first on the negative real axis, R(z) = 1 + z·bᵀ(I − zA)⁻¹·1."""
    def r(x):
        return abs(1.0 + x * b @ np.linalg.solve(np.eye(len(b)) - x * A, np.ones(len(b))))
    lo, hi = -3.0, -4.0
    assert r(lo) < 1.0 < r(hi)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if r(mid) < 1.0 else (lo, mid)
    return -lo


def test_the_stability_limit_is_inside_the_boundary():
    tsit = _boundary(tsit5.A, tsit5.B)
    assert tsit == pytest.approx(3.507, abs=1e-3) and Tsitouras45.limit <= tsit
    assert DormandPrince45.limit < _boundary(dopri.A, dopri.B) == pytest.approx(3.306, abs=1e-3)


def test_the_python_step_stays_in_python_floats():
    """The unrolled Python step took numpy scalars from the tableau: twice DP45's time per step, numpy floats out."""
    from rig.solvers import Problem, integrate
    sol = integrate(Problem(lambda t, y: (y[1], -y[0]), (1.0, 0.0)), (0.0, 1.0), method="Tsit5", rtol=1e-8, atol=1e-10)
    assert all(type(v) is float for v in sol.y_final) and abs(sol.y_final[0] - math.cos(1.0)) < 1e-7
    assert all(type(v) is float for part in Tsitouras45.tableau[1:] for v in part)


def test_on_the_oscillator_at_a_fixed_step_its_error_is_a_sixth_of_dp45s():
    """docs/solvers.md's figure: x'' = −x over one period at h = 0.05 (every step accepted), Tsit5's error 1/6 to 1/7
    of DP45's (8.4e-11 against 5.4e-10)."""
    from rig.solvers import Problem, integrate
    err = {}
    for method in ("DP45", "Tsit5"):
        sol = integrate(Problem(lambda t, y: (y[1], -y[0]), (1.0, 0.0)), (0.0, 2 * math.pi), method=method, rtol=1.0,
                        atol=1.0, first_step=0.05, max_step=0.05)
        err[method] = max(abs(sol.y_final[0] - 1.0), abs(sol.y_final[1]))
    assert err["Tsit5"] == pytest.approx(8.4e-11, rel=0.05) and err["DP45"] == pytest.approx(5.4e-10, rel=0.05)
    assert 6 < err["DP45"] / err["Tsit5"] < 7

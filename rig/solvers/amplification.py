"""Does a fixed-step method amplify what the physics damps? The test behind the fixed-step divergence reports.

Linearised at a state, the ODE is y' = J·y; one step of a method maps y to M(hJ)·y. The method is unstable on
that state when the spectral radius of M exceeds 1 while the exact flow exp(hJ) does not grow (or grows less):
its solution then grows without physical cause. This is independent of how the state is scaled (unlike
Hairer's estimate ‖Δf‖/‖Δy‖, which on a scaled state (x, τ·ẋ) reads τ·ω² for an oscillation of ω) and it
catches the slow growth of explicit Euler on a lightly damped mode just beyond h·ω_n = 2ζ, where the state
stays finite for a long time. J comes from forward differences of the right-hand side (n + 1 calls).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from rig.solvers.base import SolverDivergence

#: stability polynomials R(z) of the one-stage-family methods (M = R(hJ))
POLYNOMIALS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "euler": lambda z: 1.0 + z,
    "rk4": lambda z: 1.0 + z + z * z / 2.0 + z ** 3 / 6.0 + z ** 4 / 24.0,
}


def jacobian(fun: Callable, t: float, y: Sequence[float], h: float = 0.0) -> np.ndarray | None:
    """Forward-difference Jacobian ∂f/∂y at (t, y) (None where the RHS is not finite). Component j is moved by
    1.5e-8 of the largest of |y_j|, 1e-6·max|y| and h·|f_j| (its change over a step of ``h`` s): a velocity that
    is exactly zero at rest is moved enough for its damping term to show above the rounding of a large force."""
    y = np.asarray(y, dtype=float)
    try:
        with np.errstate(all="ignore"):
            f0 = np.asarray(fun(t, tuple(y)), dtype=float)
            if not np.all(np.isfinite(f0)):
                return None
            floor = 1e-6 * max(float(np.max(np.abs(y))), 1e-300)
            J = np.empty((y.size, y.size))
            for j in range(y.size):
                d = 1.5e-8 * max(abs(y[j]), floor, abs(h * f0[j]))
                yj = y.copy()
                yj[j] += d
                J[:, j] = (np.asarray(fun(t, tuple(yj)), dtype=float) - f0) / (yj[j] - y[j])
    except (SolverDivergence, ArithmeticError):      # a state near overflow: no linearisation there
        return None
    return J if np.all(np.isfinite(J)) else None


def step_matrix(method: str, hJ: np.ndarray, positions: Sequence[int] = ()) -> np.ndarray:
    """M of one step of ``method`` on y' = J·y (``positions``: the indices of the positions, for symplectic Euler's
    kick–drift)."""
    n = hJ.shape[0]
    if method == "symplectic_euler":
        q = np.asarray(sorted(positions), dtype=int)
        v = np.setdiff1d(np.arange(n), q)
        M = np.eye(n)
        M[v, :] += hJ[v, :]                                   # kick: v' = v + h·(J_vq q + J_vv v)
        M[q, :] += hJ[np.ix_(q, q)] @ np.eye(n)[q, :] + hJ[np.ix_(q, v)] @ M[v, :]    # drift with the kicked v'
        return M
    z = hJ
    power, M = np.eye(n), np.zeros((n, n))
    coefficients = {"euler": (1.0, 1.0), "rk4": (1.0, 1.0, 1 / 2, 1 / 6, 1 / 24)}[method]
    for c in coefficients:
        M += c * power
        power = power @ z
    return M


def step_eigenvalues(M: np.ndarray) -> np.ndarray | None:
    """Eigenvalues of M; None where M overflowed (h·J of a state near overflow raised to the 4th power for RK4)."""
    return np.linalg.eigvals(M) if np.all(np.isfinite(M)) else None


def spectral_radius(M: np.ndarray) -> float:
    """ρ(M); infinite where M overflowed."""
    eig = step_eigenvalues(M)
    return float(np.max(np.abs(eig))) if eig is not None else math.inf


#: modes the exact flow keeps at least this much of per step count for the accuracy test (a mode that loses more
#: is gone in a few steps, whatever the method leaves of it: the stiff decays an explicit method is stable on)
PERSISTENT = 0.5
#: ... and so does one the method keeps this much of per step (where the exact flow loses it fast: RK4 at hλ = −2.78
#: keeps 0.99, a decay to nothing stepped as a near-constant), or of which this much is left in a run as short as the
#: check has seen (two steps of explicit Euler at hλ = −0.7)
LINGER, LEFT = 0.9, 0.05


def mode_errors(method: str, eig: np.ndarray | None, lam: np.ndarray, h: float,
                steps: float = math.inf) -> tuple[np.ndarray, ...]:
    """Per eigenvalue λ of J whose mode persists in the exact flow (:data:`PERSISTENT` ≤ |e^{hλ}|) or lingers in the
    method (:data:`LINGER` ≤ |μ|), or — in a run of only ``steps`` steps — of which max(|e^{hλ}|, |μ|)^steps, at least
    :data:`LEFT`, is left after them, where the method does not amplify it beyond 1 and the exact flow (growth is the
    amplification test's to report; else zeros): the method's relative error on the mode per step |μ −
    e^{hλ}|/max(|e^{hλ}|, |μ|) (μ = R(hλ) for the methods of :data:`POLYNOMIALS`, else the eigenvalue ``eig`` of the
    step matrix M nearest e^{hλ}: exact for one oscillation, NaN where M overflowed, possibly another mode's in a system
    of close modes) — a fast decay the method keeps alive (explicit Euler at hλ = −1.99: μ = −0.99 against e^{hλ} =
    0.14) and a growth it does not resolve (a finite-time blow-up) count too —, its spurious decay −ln(|μ|/|e^{hλ}|) ≥ 0
    and phase error |arg(μ/e^{hλ})| (rad) per step (of modes that do not grow), its spurious growth ln(|μ|/|e^{hλ}|) ≥ 0
    per step where the method amplifies it but not beyond what the amplification test reports (explicit Euler's slow
    growth of an undamped oscillation), the mode's lifetime in steps 1/(1 − max(|e^{hλ}|, |μ|)) (inf when it does not
    decay), λ, and for a mode the exact flow grows the method's relative error on it per step |ln(μ/e^{hλ})| (modulus and
    phase; it compounds while the mode grows: RK4 at hλ = 1.9 on y' = 10y, 4.5 % per step, is 20 % off after 1 s)."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        exact = np.exp(h * lam)
        if method in POLYNOMIALS:
            mu = POLYNOMIALS[method](h * lam)
        elif eig is None:
            mu = np.full(exact.shape, np.nan)
        else:
            mu = np.array([eig[np.argmin(np.abs(eig - e))] for e in exact], dtype=complex)
        kept = np.maximum(np.abs(exact), np.abs(mu))
        keep = ((np.abs(exact) >= PERSISTENT) | (np.abs(mu) >= LINGER) | (kept ** steps >= LEFT)) & np.isfinite(exact)
        lam, exact, mu, kept = lam[keep], exact[keep], mu[keep], kept[keep]
        lasting = np.abs(exact) <= 1.0 + 1e-3                 # not a growth: its summed faults count
        damps = np.abs(mu) <= np.abs(exact) * (1.0 + 1e-4)
        tested = damps | (np.abs(mu) <= 1.0)
        err = np.where(tested, np.abs(mu - exact) / kept, 0.0)
        decay = np.where(damps & lasting, np.maximum(-np.log(np.abs(mu) / np.abs(exact)), 0.0), 0.0)
        phase = np.where(damps & lasting, np.abs(np.angle(mu / exact)), 0.0)
        growth = np.where(~damps & lasting, np.maximum(np.log(np.abs(mu) / np.abs(exact)), 0.0), 0.0)
        life = np.where(kept < 1.0, 1.0 / (1.0 - kept), np.inf)
        drift = np.where(~lasting & np.isfinite(mu), np.abs(np.log(mu / exact)), 0.0)
    return err, decay, phase, growth, life, lam, drift


class Amplification:
    """The test for one method: ``check(t, y, h)`` → (ρ(M), ρ(exp(hJ)), λ, modes) with λ the eigenvalue of J that
    the method amplifies most and ``modes`` the per-step errors, lifetimes and eigenvalues of its persistent modes
    (:func:`mode_errors`, for the accuracy test), or None where J is not available (n + 1 RHS calls)."""

    def __init__(self, fun: Callable, method: str, positions: Sequence[int] = ()):
        self.fun, self.method, self.positions = fun, method, tuple(positions)

    def check(self, t: float, y: Sequence[float], h: float, steps: float = math.inf
              ) -> tuple[float, float, complex, tuple] | None:
        J = jacobian(self.fun, t, y, h)
        if J is None:
            return None
        lam = np.linalg.eigvals(J)
        with np.errstate(over="ignore", invalid="ignore"):      # an exact growth beyond float range is inf: so said
            exact = float(np.max(np.exp(h * lam.real)))
            eig = step_eigenvalues(step_matrix(self.method, h * J, self.positions))
            rho = float(np.max(np.abs(eig))) if eig is not None else math.inf
        worst = lam[np.argmax(np.abs(POLYNOMIALS[self.method](h * lam)))] if self.method in POLYNOMIALS \
            else lam[np.argmax(np.abs(lam))]
        return rho, exact, complex(worst), mode_errors(self.method, eig, lam, h, steps)

    def largest_stable_step(self, t: float, y: Sequence[float], h: float) -> float:
        """The largest step ≤ h (s) at which the method does not amplify at (t, y) (bisection on ρ(M) ≤ 1)."""
        J = jacobian(self.fun, t, y, h)
        if J is None:
            return math.nan
        lo, hi = 0.0, h
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            with np.errstate(over="ignore", invalid="ignore"):
                rho = spectral_radius(step_matrix(self.method, mid * J, self.positions))
            if rho <= 1.0 + 1e-12:
                lo = mid
            else:
                hi = mid
        return lo

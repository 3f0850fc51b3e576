"""Stateful low-pass filters (unity DC gain) discretised exactly for piecewise-linear input.

The continuous filter ``H(s) = 1/(τs + 1)`` (order 1) or ``ωn²/(s² + 2ζωn s + ωn²)`` (order 2) is
split into first-order modes ``x_i' = λ_i x_i + u``, ``y = Re Σ r_i x_i``. Between two samples the
input is taken as the straight line joining them (first-order hold), for which each mode has a closed
-form update; the result is exact for such inputs at any (also non-uniform) sample spacing. The mode
states carry over between calls, so a signal can be fed in chunks.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter


def natural_frequency(bandwidth: float, damping: float) -> float:
    """ωn [rad/s] of a 2nd-order low pass whose −3 dB point is ``bandwidth`` [Hz] at damping ζ."""
    a = 1.0 - 2.0 * damping ** 2
    r2 = a + math.sqrt(a * a + 1.0)  # (ω_c/ωn)² solving |H(jω_c)|² = 1/2
    return 2.0 * math.pi * bandwidth / math.sqrt(r2)


def frequency_response(f: np.ndarray, bandwidth: float, order: int, damping: float = math.sqrt(0.5)) -> np.ndarray:
    """Analytic complex gain ``H(j2πf)`` of the filter described by the same parameters."""
    s = 2j * np.pi * np.asarray(f, dtype=float)
    if order == 1:
        return 1.0 / (s / (2.0 * math.pi * bandwidth) + 1.0)
    wn = natural_frequency(bandwidth, damping)
    return wn * wn / (s * s + 2.0 * damping * wn * s + wn * wn)


class LowPass:
    """Order-1 or order-2 low pass with −3 dB point ``bandwidth`` [Hz] and damping ``damping`` (order 2)."""

    def __init__(self, bandwidth: float, order: int, damping: float = math.sqrt(0.5)) -> None:
        if not bandwidth > 0.0 or not math.isfinite(bandwidth):
            raise ValueError(f"low-pass bandwidth must be a positive finite frequency, got {bandwidth!r} Hz")
        if order == 1:
            self.poles = np.array([-2.0 * math.pi * bandwidth], dtype=complex)
            self.residues = -self.poles.copy()
        elif order == 2:
            if not damping > 0.0 or abs(damping - 1.0) < 1e-6:
                raise ValueError(f"low-pass damping must be > 0 and not exactly 1 (repeated pole; use 0.999 or "
                                 f"1.001), got {damping!r}")
            wn = natural_frequency(bandwidth, damping)
            root = np.sqrt(complex(damping * damping - 1.0))
            p1, p2 = wn * (-damping + root), wn * (-damping - root)
            self.poles = np.array([p1, p2])
            self.residues = np.array([wn * wn / (p1 - p2), wn * wn / (p2 - p1)])
        else:
            raise ValueError(f"low-pass order must be 1 or 2, got {order!r}")
        self.x: np.ndarray | None = None  # mode states at time self.t_last
        self.t_last = 0.0
        self.u_last = 0.0

    def _coefficients(self, h: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-mode FOH update ``x+ = E x + g0 u0 + g1 u1`` for steps ``h`` (broadcast over modes)."""
        z = np.multiply.outer(np.asarray(h, dtype=float), self.poles)
        phi1 = np.where(np.abs(z) > 1e-8, np.expm1(z) / np.where(z == 0, 1, z), 1.0 + z / 2)  # (e^z − 1)/z
        series = 0.5 + z / 6 + z * z / 24 + z ** 3 / 120
        phi2 = np.where(np.abs(z) > 1e-4, (phi1 - 1.0) / np.where(z == 0, 1, z), series)  # (φ1 − 1)/z
        hh = np.asarray(h, dtype=float)[..., None]
        e = np.exp(z)
        i0 = hh * phi1          # ∫ e^{λ(h−τ)} dτ
        g1 = hh * phi2          # ∫ e^{λ(h−τ)} τ/h dτ
        return e, i0 - g1, g1

    def __call__(self, t: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Filter input samples ``u`` at strictly increasing times ``t`` [s], continuing the state."""
        t = np.asarray(t, dtype=float)
        u = np.asarray(u, dtype=float)
        if t.size == 0:
            return u.copy()
        if self.x is None:
            self.x = -u[0] / self.poles  # steady state: λx + u = 0
            self.t_last, self.u_last = float(t[0]), float(u[0])
            return np.concatenate((u[:1], self(t[1:], u[1:])))
        tt = np.concatenate(([self.t_last], t))
        uu = np.concatenate(([self.u_last], u))
        h = np.diff(tt)
        if np.any(h < 0.0) or not np.all(np.isfinite(h)):
            raise ValueError("low-pass input times must be finite and non-decreasing (continuing from the "
                             f"previous call at t={self.t_last!r} s)")
        states = np.empty((t.size, self.poles.size), dtype=complex)
        uniform = h.size > 2 and np.ptp(h) <= 1e-6 * float(h.max())
        if uniform:
            # the nominal step: the spacings of exact sample times k/rate differ in their last bits, and whichever
            # of them came first must not set the coefficients (samples cut otherwise would filter otherwise)
            e, g0, g1 = self._coefficients(float(f"{np.median(h):.12g}"))
            for i in range(self.poles.size):
                drive = g0[i] * uu[:-1] + g1[i] * uu[1:]
                zi = np.array([e[i] * self.x[i]])
                states[:, i] = lfilter([1.0], [1.0, -e[i]], drive, zi=zi)[0]
        else:
            e, g0, g1 = self._coefficients(h)
            x = self.x.copy()
            for k in range(t.size):
                x = e[k] * x + g0[k] * uu[k] + g1[k] * uu[k + 1]
                states[k] = x
        self.x = states[-1].copy()
        self.t_last, self.u_last = float(t[-1]), float(u[-1])
        # the modes summed column by column, not by a matrix product: BLAS would hand the (n, modes) product to its
        # thread pool, whose start-up costs more than the sum (2-3x the filter's time on a busy machine, and a second
        # core); a sum over the short axis costs ten times the columns' sum
        out = states[:, 0] * self.residues[0]
        for i in range(1, self.poles.size):
            out = out + states[:, i] * self.residues[i]
        return np.real(out)

"""Theory vs measurement: lag by cross-correlation (sub-sample refined), RMS deviation, peak difference.

Convention: ``lag > 0`` means the measurement is late, ``measured(s) ≈ theory(s − lag)``, where ``s`` is
time (s) or cam angle (rad). The real cam-bar experiment saw ≈ 0.1 s ≈ 80–90° at 133–150 rpm.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np
from scipy import fft, interpolate

_RESCAN = 10   # steps around the correlation peak re-examined by RMS
_FINE = 4      # sub-steps per step of the final RMS grid


def _increasing(s: np.ndarray, what: str) -> None:
    if s.ndim != 1 or s.size < 4 or np.any(np.diff(s) <= 0):
        raise ValueError(f"{what}: abscissa must be a strictly increasing 1-D array of >= 4 samples")


def _shifted_rms(s: np.ndarray, meas: np.ndarray, ref: interpolate.CubicSpline, lo: float, hi: float,
                 lag: float) -> float:
    """RMS of meas(s) − ref(s − lag) over the samples where both exist."""
    keep = (s - lag >= lo) & (s - lag <= hi)
    if np.count_nonzero(keep) < 2:
        return np.inf
    return float(np.sqrt(np.mean((meas[keep] - ref(s[keep] - lag)) ** 2)))


def estimate_lag(s_ref: np.ndarray, ref: np.ndarray, s: np.ndarray, meas: np.ndarray,
                 max_lag: float | None = None) -> float:
    """Lag of ``meas(s)`` behind ``ref(s_ref)`` (units of s: seconds or radians).

    Both signals are resampled on a common uniform grid (finest of the two steps) over their common
    range; the integer step of least mean square over the overlap (|lag| ≤ ``max_lag``, default half the
    range; from sums and one FFT correlation) is rescanned by RMS over nearby steps on that grid, then refined
    below one step by minimising
    the RMS of ``meas(s) − ref(s − lag)`` with a cubic spline of the reference (on a grid of a quarter step,
    then the parabola through the lowest point: the mean square is smooth in the lag).
    """
    s_ref, ref, s, meas = (np.asarray(a, dtype=float) for a in (s_ref, ref, s, meas))
    _increasing(s_ref, "theory")
    _increasing(s, "measurement")
    return _lag(s_ref, ref, s, meas, max_lag, interpolate.CubicSpline(s_ref, ref))


def _lag(s_ref: np.ndarray, ref: np.ndarray, s: np.ndarray, meas: np.ndarray, max_lag: float | None,
         spline: interpolate.CubicSpline) -> float:
    """:func:`estimate_lag` on checked arrays, with the reference's spline."""
    lo, hi = max(s_ref[0], s[0]), min(s_ref[-1], s[-1])
    if hi <= lo:
        raise ValueError(f"lag: theory [{s_ref[0]}, {s_ref[-1]}] and measurement [{s[0]}, {s[-1]}] do not overlap")
    step = min(np.median(np.diff(s_ref)), np.median(np.diff(s)))
    grid = np.arange(lo, hi, step)
    a = np.interp(grid, s, meas)
    b = np.interp(grid, s_ref, ref)
    k, msd = _grid_msd_all(a, b)
    limit = (hi - lo) / 2 if max_lag is None else max_lag
    ok = np.abs(k * step) <= limit
    k0 = int(k[ok][np.argmin(msd[ok])])

    # the mean square from sums carries rounding: rescan nearby steps by the RMS of a(i) − b(i − k) on the grid,
    # then refine with the spline
    ks = np.arange(k0 - _RESCAN, k0 + _RESCAN + 1)
    k1 = int(ks[np.argmin([_grid_rms(a, b, int(j)) for j in ks])])
    # below one step: the RMS on a grid of step/_FINE over [k1 − 1, k1 + 1] steps, then the vertex of the
    # parabola through the lowest grid point and its neighbours
    lags = (k1 + np.linspace(-1.0, 1.0, 2 * _FINE + 1)) * step
    rms = _shifted_rms_many(s, meas, spline, s_ref[0], s_ref[-1], lags)
    i = int(np.clip(np.argmin(rms), 1, lags.size - 2))
    y0, y1, y2 = rms[i - 1:i + 2] ** 2
    den = y0 - 2 * y1 + y2
    h = lags[1] - lags[0]
    shift = 0.5 * h * (y0 - y2) / den if den > 0 and np.isfinite(den) else 0.0
    return float(lags[i] + np.clip(shift, -h, h))


def _correlate(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Full cross-correlation c[k] = Σ a[i]·b[i − k], k = −(len(b) − 1) … len(a) − 1, by FFT."""
    n = a.size + b.size - 1
    size = fft.next_fast_len(n, real=True)
    c = fft.irfft(fft.rfft(a, size) * np.conj(fft.rfft(b, size)), size)
    return np.concatenate((c[size - b.size + 1:], c[:a.size]))


def _grid_msd_all(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every lag k = −(len(b) − 1) … len(a) − 1 (steps) and the mean square of a[i] − b[i − k] over the indices
    where both exist: Σa² + Σb² − 2·Σa·b over each overlap, the last term one FFT correlation (O(n log n)). The
    minimum, not the correlation peak: the peak of a finite window of a ramp (the stroke) sits near zero lag
    whatever the delay, which held the displacement's lag at the rescan's edge."""
    k = np.arange(1 - b.size, a.size)
    ca, cb = np.concatenate(([0.0], np.cumsum(a * a))), np.concatenate(([0.0], np.cumsum(b * b)))
    start = np.maximum(k, 0)                           # overlap in a: [start, stop), in b: [start − k, stop − k)
    stop = np.minimum(a.size, b.size + k)
    n = stop - start
    sq = ca[stop] - ca[start] + cb[stop - k] - cb[start - k] - 2.0 * _correlate(a, b)
    return k, np.maximum(sq, 0.0) / n


def _grid_rms(a: np.ndarray, b: np.ndarray, k: int) -> float:
    """RMS of a[i] − b[i − k] over the indices where both exist (a, b on one grid; inf when fewer than 2)."""
    n = a.size - abs(k)
    if n < 2:
        return np.inf
    d = a[k:k + n] - b[:n] if k >= 0 else a[:n] - b[-k:n - k]
    return float(np.sqrt(np.mean(d * d)))


def _shifted_rms_many(s: np.ndarray, meas: np.ndarray, ref: interpolate.CubicSpline, lo: float, hi: float,
                      lags: np.ndarray) -> np.ndarray:
    """:func:`_shifted_rms` for several lags in one spline evaluation (inf where < 2 samples overlap)."""
    shifted = s[None, :] - lags[:, None]
    keep = (shifted >= lo) & (shifted <= hi)
    err = np.where(keep, meas[None, :] - ref(np.clip(shifted, lo, hi)), 0.0)
    n = keep.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n >= 2, np.sqrt(np.sum(err ** 2, axis=1) / np.maximum(n, 1)), np.inf)


def compare_theory(t: np.ndarray, meas: np.ndarray, theory: Mapping[str, np.ndarray], signal_name: str = "y",
                   angle: np.ndarray | None = None, max_lag: float | None = None) -> dict:
    """Compare measured ``meas(t)`` with ``theory[signal_name]`` in time and in cam angle.

    theory: arrays ``t`` (optional; default the measurement's t), ``angle`` (optional), and the
    signal. angle: measured cam angle (rad) per sample. The angle lag is a cross-correlation in the
    angle domain when both angles are known (method ``"xcorr"``), otherwise time lag × mean cam speed
    (method ``"derived"``) if any angle is known, else None. Returns lag_time (s), lag_angle (rad),
    rms_before / rms_after (deviation without / with the time lag removed) and peak difference
    ``max(meas) − max(theory)``.
    """
    t, meas = np.asarray(t, dtype=float), np.asarray(meas, dtype=float)
    if signal_name not in theory:
        raise KeyError(f"theory has no {signal_name!r} signal (has {sorted(theory)})")
    th = np.asarray(theory[signal_name], dtype=float)
    th_t = np.asarray(theory.get("t", t), dtype=float)
    th_angle = theory.get("angle", angle if "t" not in theory else None)
    _increasing(th_t, "theory")
    _increasing(t, "measurement")
    spline = interpolate.CubicSpline(th_t, th)
    lag_t = _lag(th_t, th, t, meas, max_lag, spline)
    out = {"signal": signal_name, "lag_time": lag_t,
           "rms_before": _shifted_rms(t, meas, spline, th_t[0], th_t[-1], 0.0),
           "rms_after": _shifted_rms(t, meas, spline, th_t[0], th_t[-1], lag_t),
           "peak_difference": float(np.max(meas) - np.max(th)), "lag_angle": None, "angle_method": None}
    if angle is not None and th_angle is not None:
        out["lag_angle"] = estimate_lag(np.asarray(th_angle, float), th, np.asarray(angle, float), meas)
        out["angle_method"] = "xcorr"
    elif angle is not None or th_angle is not None:
        a, ta = (np.asarray(angle, float), t) if angle is not None else (np.asarray(th_angle, float), th_t)
        omega = (a[-1] - a[0]) / (ta[-1] - ta[0])
        out["lag_angle"], out["angle_method"] = lag_t * omega, "derived"
    return out

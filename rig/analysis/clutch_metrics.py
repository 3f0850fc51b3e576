"""Clutch metrics: step-response figures of a torque trace, disengagement events, hysteresis loops.

All functions are vectorised: signals are arrays whose *last* axis is time (or the loop path);
leading axes are independent traces. Units follow the inputs (SI: s, N*m, rad, J).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StepMetrics:
    """Overshoot/settling figures of a trace (arrays shaped like the leading axes of the input)."""

    peak: np.ndarray           # extreme value in the direction of the step (signal unit)
    t_peak: np.ndarray         # time of the peak (s)
    overshoot: np.ndarray      # (peak - final) / (final - initial), dimensionless
    settling_time: np.ndarray  # time after which the trace stays within the band, minus t[0] (s)
    final: np.ndarray          # final value used (signal unit)


def _as_trace(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"time axis must be 1-D with at least 2 samples, got shape {t.shape}")
    if y.shape[-1:] != t.shape:
        raise ValueError(f"signal shape {y.shape} does not end with the time-axis length {t.size}")
    if np.any(np.diff(t) <= 0):
        raise ValueError("time axis must be strictly increasing")
    if not np.all(np.isfinite(y)):
        raise ValueError("signal contains NaN or inf")
    return t, y


def step_metrics(t: np.ndarray, y: np.ndarray, band: float = 0.02, final: float | np.ndarray | None = None,
                 absolute_band: float | None = None) -> StepMetrics:
    """Peak, time of peak, overshoot and settling time of a step-like trace ``y(t)``.

    ``final`` defaults to the last sample. The settling band is ``±band·|final − y[0]|`` (relative) or
    ``±absolute_band`` (signal unit). The settling time is the instant, linearly interpolated between
    samples, at which the trace last leaves the band, measured from ``t[0]``; 0 if it never leaves.
    """
    t, y = _as_trace(t, y)
    y0 = y[..., 0]
    yf = y[..., -1] if final is None else np.broadcast_to(np.asarray(final, dtype=float), y0.shape)
    step = yf - y0
    if absolute_band is None:
        if band <= 0:
            raise ValueError(f"relative settling band must be > 0, got {band}")
        half = band * np.abs(step)
        if np.any(half == 0):
            raise ValueError("relative settling band is zero (no step: final value equals initial value); "
                             "give absolute_band")
    else:
        if absolute_band <= 0:
            raise ValueError(f"absolute settling band must be > 0, got {absolute_band}")
        half = np.full(y0.shape, float(absolute_band))
    direction = np.where(step >= 0, 1.0, -1.0)
    i_peak = np.argmax(direction[..., None] * y, axis=-1)
    peak = np.take_along_axis(y, i_peak[..., None], axis=-1)[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        overshoot = np.where(step != 0, (peak - yf) / step, 0.0)
    # settling: last sample outside the band, then interpolate the exit between it and the next one
    err = np.abs(y - yf[..., None]) - half[..., None]
    outside = err > 0
    n = t.size
    last_out = n - 1 - np.argmax(outside[..., ::-1], axis=-1)
    never = ~outside.any(axis=-1)
    nxt = np.minimum(last_out + 1, n - 1)
    e0 = np.take_along_axis(err, last_out[..., None], axis=-1)[..., 0]
    e1 = np.take_along_axis(err, nxt[..., None], axis=-1)[..., 0]
    frac = np.where(nxt > last_out, e0 / np.where(e0 - e1 != 0, e0 - e1, 1.0), 0.0)
    t_exit = t[last_out] + frac * (t[nxt] - t[last_out])
    settling = np.where(never, 0.0, t_exit - t[0])
    return StepMetrics(peak=peak, t_peak=t[i_peak], overshoot=overshoot, settling_time=settling, final=yf)


def apex_crossings(t: np.ndarray, phi: np.ndarray, period: float = 2 * np.pi / 3,
                   apex: float = np.pi / 3) -> np.ndarray:
    """Times (s) at which the relative angle ``phi`` (rad, 1-D) first passes a lobe apex.

    Apexes sit at ``apex + k·period``. Only *new* apexes count (a running maximum/minimum of the lobe
    index), so dithering around an apex is one event; both directions of slip are counted. Crossing
    times are linearly interpolated; several apexes passed within one sample interval each count.
    """
    t, phi = _as_trace(t, phi)
    if phi.ndim != 1:
        raise ValueError("apex_crossings takes a single 1-D angle trace")
    if period <= 0:
        raise ValueError(f"lobe period must be > 0, got {period}")
    level = np.floor((phi - apex) / period)
    events: list[np.ndarray] = []
    for sign in (1.0, -1.0):
        record = sign * np.maximum.accumulate(sign * level)   # furthest lobe index reached so far
        new = (sign * np.diff(record)).astype(int)            # new apexes passed in each interval
        idx = np.repeat(np.arange(new.size), new)
        if idx.size == 0:
            continue
        k = np.arange(idx.size) - np.repeat(np.cumsum(new) - new, new)   # 0 .. new[i]-1 per interval
        # going up, level L is entered at apex + L*period; going down, level L is left at the same angle
        lev = record[idx] + k + 1 if sign > 0 else record[idx] - k
        target = apex + lev * period
        p0, p1 = phi[idx], phi[idx + 1]
        events.append(t[idx] + (target - p0) / (p1 - p0) * (t[idx + 1] - t[idx]))
    return np.sort(np.concatenate(events)) if events else np.empty(0)


@dataclass(frozen=True)
class DisengagementSummary:
    """Disengagement events of a run: how many, when, and whether a shutdown is required."""

    count: int
    times: np.ndarray    # s
    shutdown: bool       # ``repeat`` events fell within ``window`` seconds
    first_shutdown_time: float | None  # s, the event that completed the first such burst


def disengagement_summary(times: np.ndarray, window: float, repeat: int = 2) -> DisengagementSummary:
    """Summarise disengagement times (s): shutdown if ``repeat`` events occur within ``window`` s."""
    times = np.sort(np.asarray(times, dtype=float).ravel())
    if window <= 0:
        raise ValueError(f"shutdown window must be > 0 s, got {window}")
    if repeat < 1:
        raise ValueError(f"repeat count must be >= 1, got {repeat}")
    first = None
    if times.size >= repeat:
        span = times[repeat - 1:] - times[:times.size - repeat + 1]
        hits = np.flatnonzero(span <= window)
        if hits.size:
            first = float(times[hits[0] + repeat - 1])
    return DisengagementSummary(count=int(times.size), times=times, shutdown=first is not None,
                                first_shutdown_time=first)


def signed_loop_area(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Shoelace area of the closed polygon through the points (last axis), positive counter-clockwise."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if x.shape != y.shape or x.shape[-1] < 3:
        raise ValueError(f"loop needs matching x/y with at least 3 points, got {x.shape} and {y.shape}")
    return 0.5 * np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1)


def loop_area(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Unsigned area enclosed by a closed loop (product of the x and y units)."""
    return np.abs(signed_loop_area(x, y))


def loop_energy(phi: np.ndarray, torque: np.ndarray) -> np.ndarray:
    """Work ∮ T dφ (J) done on the clutch along a closed torque–angle path = energy dissipated.

    Equals minus the signed shoelace area in the (φ, T) plane: loading above unloading traverses the
    loop clockwise and gives positive dissipated energy.
    """
    return -signed_loop_area(phi, torque)

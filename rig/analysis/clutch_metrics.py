"""Clutch metrics: step-response figures of a torque trace, disengagement events, hysteresis loops,
and the key results of a dynamic-stand run judged against what the scene did to the stand.

The signal functions are vectorised: signals are arrays whose *last* axis is time (or the loop path);
leading axes are independent traces. Units follow the inputs (SI: s, N*m, rad, J).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from rig.analysis.numbers import fixed
from rig.analysis.report_blocks import fmt
from rig.scene import Scene, read_table

if TYPE_CHECKING:
    from rig.analysis.units import Unit


@dataclass(frozen=True)
class StepMetrics:
    """Step-response figures of a trace (arrays shaped like the leading axes of the input).

    Every figure is relative to the step: ``initial`` (level before it) → ``final`` (level it settles
    at). ``overshoot_pct`` and ``settling_time`` are NaN where the trace does not settle inside the
    record — a final value it never holds cannot be overshot or settled at.
    """

    peak: np.ndarray           # extreme value in the direction of the step (signal unit)
    t_peak: np.ndarray         # time of the peak (s)
    overshoot_pct: np.ndarray  # 100·(peak − final)/(final − initial), ≥ 0 (%); NaN: not settled
    settling_time: np.ndarray  # from t_step until the trace stays within ±half_band of final (s); NaN: not settled
    settled: np.ndarray        # bool: inside the band for at least ``dwell`` before the record ends
    initial: np.ndarray        # level before the step (signal unit)
    final: np.ndarray          # level after it (signal unit)
    half_band: np.ndarray      # settling band half-width (signal unit)


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


def step_metrics(t: np.ndarray, y: np.ndarray, band: float = 0.05, final: float | np.ndarray | None = None,
                 initial: float | np.ndarray | None = None, absolute_band: float | None = None,
                 t_step: float | None = None, dwell: float | None = None) -> StepMetrics:
    """Peak, overshoot and settling time of the response ``y(t)`` to a step at ``t_step`` (default t[0]).

    ``initial`` defaults to the first sample; ``final`` to the mean over the last ``dwell`` seconds
    (default: the last 10 % of the record). The settling band is ``±band·|final − initial|``
    (relative, default 5 %) or ``±absolute_band`` (signal unit). The trace has *settled* if it stays
    inside the band for at least ``dwell`` before the record ends; the settling time is then the
    instant it last entered the band (linearly interpolated between samples) minus ``t_step``, 0 if it
    never left. A trace still outside the band, or inside only for the last moments, has not settled:
    settling time and overshoot are NaN (never the record length).
    """
    t, y = _as_trace(t, y)
    t0 = float(t[0]) if t_step is None else float(t_step)
    dwell = 0.1 * float(t[-1] - t[0]) if dwell is None else float(dwell)
    if not 0.0 < dwell < t[-1] - t[0]:
        raise ValueError(f"settling dwell must be > 0 s and shorter than the record, got {dwell} s")
    tail = t >= t[-1] - dwell
    y0 = y[..., 0] if initial is None else np.broadcast_to(np.asarray(initial, dtype=float), y.shape[:-1])
    yf = (y[..., tail].mean(axis=-1) if final is None
          else np.broadcast_to(np.asarray(final, dtype=float), y.shape[:-1]))
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
    # settling: last sample outside the band, then interpolate the entry between it and the next one
    err = np.abs(y - yf[..., None]) - half[..., None]
    outside = err > 0
    n = t.size
    last_out = n - 1 - np.argmax(outside[..., ::-1], axis=-1)
    never = ~outside.any(axis=-1)
    nxt = np.minimum(last_out + 1, n - 1)
    e0 = np.take_along_axis(err, last_out[..., None], axis=-1)[..., 0]
    e1 = np.take_along_axis(err, nxt[..., None], axis=-1)[..., 0]
    frac = np.where(nxt > last_out, e0 / np.where(e0 - e1 != 0, e0 - e1, 1.0), 0.0)
    t_entry = np.where(never, t0, t[last_out] + frac * (t[nxt] - t[last_out]))
    settled = never | ((last_out < n - 1) & (t[-1] - t_entry >= dwell))
    settling = np.where(settled, np.maximum(t_entry - t0, 0.0), np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        overshoot = np.where(settled & (step != 0), np.maximum(100.0 * (peak - yf) / step, 0.0), np.nan)
    return StepMetrics(peak=peak, t_peak=t[i_peak], overshoot_pct=overshoot, settling_time=settling,
                       settled=settled, initial=y0, final=yf, half_band=half)


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


# ---------------------------------------------------------------------------------------------------
# Key results of a dynamic-stand run, judged against what the scene did to the stand
# ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Stimulus:
    """A change the scene makes to the stand at ``time`` (s): the input the response is judged against.

    ``kind``: ``start`` (motor switched on, stand at rest), ``step`` (sustained load change), ``stop``
    (motor switched off), ``shock`` (load pulse of ``duration`` s that returns to the previous level) or
    ``sweep`` (blocked driven half turned slowly: quasi-static, no step). ``before``/``after``: nominal
    load torque (N·m) before and after a start/step/stop (None: not fixed by the scene, e.g. a stand
    coasting to rest); for a shock ``after`` is the torque the pulse adds.
    """

    time: float
    kind: str
    text: str
    before: float | None = None
    after: float | None = None
    duration: float = 0.0


FLAGS = {"required": 1.0, "not required": 0.0}     # word results read as numbers (Metric.number)


@dataclass(frozen=True)
class Metric:
    """One result: ``value`` in ``unit`` (None: not applicable), ``reference`` says what it is relative
    to or how it is defined — or, when not applicable, why."""

    name: str
    value: float | str | None
    unit: str
    reference: str
    at: float | None = None     # s: when it happened (peaks, events), if that is part of the result
    exceeds: float | None = None    # not reached within the run: the value is known to be above this (in unit)

    def number(self) -> float | None:
        """The result as a number (in ``unit``): a numeric value; a count written with its times ("3, at …") as
        the count; a shutdown flag as 1 ("required") or 0 ("not required"); None otherwise."""
        if self.value is None or not isinstance(self.value, str):
            return None if self.value is None else float(self.value)
        head = re.match(r"\d+", self.value)
        return float(head.group()) if head else FLAGS.get(self.value)

    def value_text(self) -> str:
        if self.value is None:
            return "n/a"
        if isinstance(self.value, str):
            v = self.value
        else:
            v = "0" if self.value == 0.0 else f"{self.value:#.4g}".rstrip(".")   # 4 digits kept: 100.0 rad/s, not
            if "e" in v and abs(self.value) >= 1:                             # "100" beside the table's 100.05
                v = f"{self.value:.0f}"
            v = f"{v}°" if self.unit == "°" else f"{v} {self.unit}".rstrip()
        return v + (f" at {self.at:.4g} s" if self.at is not None else "")


@dataclass(frozen=True)
class StandRecord:
    """Measured signals of a dynamic-stand run (SI)."""

    t: np.ndarray                  # torque-meter sample times (s)
    torque: np.ndarray             # torque meter M_t (N·m)
    t_angle: np.ndarray | None     # times of the relative angle (s)
    rel_angle: np.ndarray | None   # φ1 − φ3 from the encoders, plus the angle at power-on (rad)
    speeds: dict                   # label -> (stamp s, ω rad/s, reading time s, method) of each encoder
                                   # (drivers.encoder.SpeedEstimate; method 3 = standstill bound)
    last_edge: float | None        # time of the last count change on any encoder (s); None: none
    end: float                     # end of the run (s)


LOBE = 2 * np.pi / 3
APEX = np.pi / 3
SLIP_TOLERANCE = np.radians(2.0)   # relative angle within this of its end value: slip over
SPEED_SETTLED = 0.02   # a speed whose trend moves more than this share of it (or of 1 rad/s) over the last readings
                       # is still changing: no final speed


def _window(t: np.ndarray, y: np.ndarray, a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    m = (t >= a) & (t < b)
    return t[m], y[m]


def stimuli(scene: Scene) -> tuple[list[Stimulus], dict[str, Any]]:
    """What the scene does to the stand, in time order, and its shutdown rule (``shutdown_count``,
    ``shutdown_window`` s, ``trip_on_shutdown``). Loads fixed in time (constant, step, shock, brake
    command) give nominal torques; speed- or angle-dependent loads (linear, zone) give none."""
    from rig.plants.clutch.stand import _LOAD_SCHEMAS, MOTOR_SCHEMA, plant_schema
    p = scene.read("plant", plant_schema(scene))
    m = scene.read("motor", MOTOR_SCHEMA)
    rule = {"shutdown_count": int(p["shutdown_count"]), "shutdown_window": float(p["shutdown_window"]),
            "trip_on_shutdown": bool(p["trip_on_shutdown"])}
    steps: list[tuple[float, float]] = []       # (time, torque change) of sustained load changes
    shocks: list[Stimulus] = []
    level: float | None = 0.0                   # nominal load torque at t = 0 (None: not fixed in time)
    for name, table in scene.section("load", required=False).items():
        if not isinstance(table, dict) or not isinstance(table.get("type"), str) or table["type"] not in _LOAD_SCHEMAS:
            continue
        kind = table["type"]
        q = read_table({k: v for k, v in table.items() if k != "type"}, _LOAD_SCHEMAS[kind][0],
                       f"{scene.path} [load.{name}]")
        if kind == "constant":
            level = None if level is None else level + q["torque"]
        elif kind == "step":
            steps.append((q["time"], q["torque"]))
        elif kind == "shock":
            shocks.append(Stimulus(q["start"], "shock", f"shock {q['torque']:+.4g} N·m for "
                                   f"{q['duration'] * 1e3:.4g} ms", after=q["torque"], duration=q["duration"]))
        elif kind == "brake":
            g = q["gain"]
            level = None if level is None else level + g * q["force"]
            if q["step_time"] is not None:
                steps.append((q["step_time"], g * (q["step_force"] - q["force"])))
            if q["pulse_start"] is not None:
                amp = g * q["pulse_force"]
                shocks.append(Stimulus(q["pulse_start"], "shock",
                                       f"brake shock {amp:+.4g} N·m for {q['pulse_duration'] * 1e3:.4g} ms",
                                       after=amp, duration=q["pulse_duration"]))
        else:
            level = None                         # linear in speed, zones in angle: no fixed level

    def load_at(t: float) -> float | None:
        return None if level is None else level + sum(d for ts, d in steps if ts <= t)

    out: list[Stimulus] = []
    if p.get("blocked"):
        out.append(Stimulus(0.0, "sweep", "driven half blocked, driving half turned slowly"))
    elif p["omega0"] == 0.0:
        out.append(Stimulus(0.0, "start", f"motor on, stand at rest, load {fmt(load_at(0.0))} N·m", 0.0,
                            load_at(0.0)))
    t_off = m["t_off"]
    for ts in sorted({ts for ts, _ in steps if ts > 0.0}):
        if math.isfinite(t_off) and abs(ts - t_off) < 1e-9:
            continue
        out.append(Stimulus(ts, "step", f"load {fmt(load_at(ts - 1e-9))} → {fmt(load_at(ts))} N·m",
                            load_at(ts - 1e-9), load_at(ts)))
    if math.isfinite(t_off):
        change = load_at(t_off) != load_at(t_off - 1e-9)
        out.append(Stimulus(t_off, "stop", "motor off" + (f", load {fmt(load_at(t_off - 1e-9))} → "
                                                          f"{fmt(load_at(t_off))} N·m" if change else ""),
                            load_at(t_off - 1e-9), None))
    return sorted(out + shocks, key=lambda s: s.time), rule


def stimulus_label(s: Stimulus) -> str:
    """How results measured from stimulus ``s`` are named: ``"start-up: …"``, ``"shock at 0.3 s: …"``."""
    return "start-up" if s.kind == "start" else f"{s.kind} at {s.time:.4g} s"


#: the results of a run as a whole (:func:`stand_metrics`; ``final speed ω1`` of the driving half, ``ω3`` driven)
RUN_RESULTS = ("torque", "max torque", "min torque", "overshoot", "settling time", "work on the coupling",
               "relative angle at max torque", "disengagements", "shutdown", "relative angle swept", "relative slip",
               "relative angle change", "slip ended", "final speed ω1", "final speed ω3")
#: the results measured from each stimulus, named ``"<stimulus_label>: <result>"``
STIMULUS_RESULTS = ("response", "torque rise", "overshoot", "settling time", "final torque", "peak torque",
                    "recovery time", "standstill")


def result_names(stimuli: Sequence[Stimulus]) -> list[str]:
    """Every name a result of a run with these stimuli can have (which ones a run gives depends on what it does)."""
    return [*RUN_RESULTS, *(f"{stimulus_label(s)}: {r}" for s in sorted(stimuli, key=lambda s: s.time)
                            for r in STIMULUS_RESULTS)]


def _step_metrics(s: Stimulus, rec: StandRecord, seg_end: float, pre_start: float, label: str, band: float,
                  dwell: float, min_step: float, until: str) -> list[Metric]:
    """Peak, overshoot, settling time and final torque after a start, load step or stop."""
    t, y = _window(rec.t, rec.torque, s.time, seg_end)
    if t.size < 5 or t[-1] - t[0] <= dwell:
        return [Metric(f"{label}: response", None, "", f"fewer than {dwell * 1e3:.0f} ms of readings after it")]
    why_unsteady = ""
    if s.kind == "start":
        y0, initial_text = 0.0, "0 N·m (stand at rest before the start)"
    else:
        tp, yp = _window(rec.t, rec.torque, max(pre_start, s.time - dwell), s.time)
        if tp.size < 3:
            y0, why_unsteady = float(y[0]), "no readings just before it"
        else:
            y0 = float(yp.mean())
        initial_text = f"{y0:.4g} N·m (mean of the {dwell * 1e3:.0f} ms before)"
    yf = float(np.mean(y[t >= t[-1] - dwell]))
    step, from_to = yf - y0, f"{y0:.4g} → {yf:.4g} N·m"
    scene_step = s.after - s.before if s.kind != "start" and None not in (s.before, s.after) else None
    if s.kind != "start" and not why_unsteady:      # steady before it: within the band of the step (the scene's if known)
        ref = abs(scene_step if scene_step is not None else step)
        if np.max(np.abs(yp - y0)) > band * ref:
            why_unsteady = (f"the torque was not steady before it (it ranged {yp.min():.4g}…{yp.max():.4g} N·m in the "
                            f"{dwell * 1e3:.0f} ms before, beyond ±{band * ref:.3g} N·m)")
            if scene_step is not None:              # no measured initial level: the scene's step sets size and band
                y0, step = yf - scene_step, scene_step
                from_to = f"of the scene, {s.before:.4g} → {s.after:.4g} N·m"
    final_text = f"mean of the last {dwell * 1e3:.0f} ms {until}"
    nominal = "" if s.after is None else f"; scene load {s.after:.4g} N·m"
    direction = 1.0 if step >= 0 else -1.0
    out = [_peak(t, y, direction, label, f"extreme reading in the direction of the step {from_to}, {until}", dwell,
                 band * abs(step))]
    k = int(np.argmax(-direction * y))
    if s.kind == "stop" and -direction * (y[k] - y0) > band * abs(step):
        out.append(Metric(f"{label}: torque rise", float(y[k]), "N·m",
                          f"extreme reading against the direction of the step ({y[k] - y0:+.4g} N·m from "
                          f"{y0:.4g} N·m), {until}", float(t[k])))
    if abs(step) < min_step:
        why = f"no step in the torque ({y0:.4g} → {yf:.4g} N·m, less than {min_step:g} N·m)"
        return out + [Metric(f"{label}: overshoot", None, "%", why), Metric(f"{label}: settling time", None, "s", why),
                      Metric(f"{label}: final torque", yf, "N·m", final_text + nominal)]
    # The level it settles at: the scene's load where the record's end agrees with it (within the band) — in a steady
    # state the meter carries exactly the load; a record that ends while the stand still accelerates slowly would
    # otherwise move the band, and the settling time with it, with the record's length.
    target, target_text = yf, f"{yf:.4g} N·m"
    if s.kind in ("start", "step") and s.after is not None and abs(yf - s.after) <= band * abs(s.after - y0):
        target, target_text = s.after, f"the scene's load {s.after:.4g} N·m (the record ends at {yf:.4g} N·m)"
    sm = step_metrics(t, y, band=band, initial=y0, final=target, t_step=s.time, dwell=dwell)
    half = float(sm.half_band)
    if not bool(sm.settled):
        why = (f"not settled {until}: the torque does not stay within ±{half:.3g} N·m ({band * 100:g} % of the step) "
               f"of {'its last level ' if target == yf else ''}{target_text} for {dwell * 1e3:.0f} ms")
        out += [Metric(f"{label}: overshoot", None, "%", why), Metric(f"{label}: settling time", None, "s", why)]
    else:
        if why_unsteady:
            out.append(Metric(f"{label}: overshoot", None, "%", f"{why_unsteady}: no initial level to measure a "
                                                                "step from"))
        else:
            out.append(Metric(f"{label}: overshoot", float(sm.overshoot_pct), "%",
                              f"(peak − final)/(final − initial), initial {initial_text}, final {target_text}"))
        out.append(Metric(f"{label}: settling time", float(sm.settling_time), "s",
                          f"from the {s.kind} at {s.time:.4g} s until the torque stays within ±{half:.3g} N·m "
                          f"({band * 100:g} % of the {abs(target - y0):.4g} N·m step) of {target_text}"))
    return out + [Metric(f"{label}: final torque", yf, "N·m", final_text + nominal)]


def _peak(t: np.ndarray, y: np.ndarray, direction: float, label: str, what: str, dwell: float,
          tol: float) -> Metric:
    """The extreme reading in ``direction`` (+1 highest, −1 lowest) as the peak torque; none when it lies within the
    window's last ``dwell`` s and the torque's trend over them (least squares) moved more than ``tol`` (N·m) that way:
    it is still moving when the record (or the segment) ends, and its highest reading so far (the last, or with a noisy
    meter one a few samples before) is no peak — a real peak within the last ``dwell`` has the torque turn back, and
    at the end of a settled record the extreme is only the noise's."""
    k = int(np.argmax(direction * y))
    tail = t >= t[-1] - dwell
    if tail[k] and np.count_nonzero(tail) >= 3 and \
            direction * np.polyfit(t[tail] - t[-1], y[tail], 1)[0] * dwell > tol:
        return Metric(f"{label}: peak torque", None, "N·m",
                      f"still {'rising' if direction > 0 else 'falling'} at the end ({y[k]:.4g} N·m at {t[k]:.4g} s, "
                      "its extreme so far): no peak within the readings")
    return Metric(f"{label}: peak torque", float(y[k]), "N·m", what, float(t[k]))


def _shock_metrics(s: Stimulus, rec: StandRecord, seg_end: float, pre_start: float, label: str, band: float,
                   dwell: float, until: str) -> list[Metric]:
    """Peak over the pre-shock level and the time until the torque is back at it; no overshoot."""
    out = [Metric(f"{label}: overshoot", None, "%",
                  f"a shock is a pulse, not a step: the load returns to its level after {s.duration * 1e3:.4g} ms, "
                  "so there is no new final value to overshoot")]
    t, y = _window(rec.t, rec.torque, s.time, seg_end)
    tp, yp = _window(rec.t, rec.torque, max(pre_start, s.time - dwell), s.time)
    if t.size < 5 or tp.size < 3:
        return out + [Metric(f"{label}: recovery time", None, "s", "too few readings around the shock")]
    y0 = float(yp.mean())
    amp = float(s.after) if s.after else float(np.max(np.abs(y - y0)))
    sign = 1.0 if amp >= 0 else -1.0
    k = int(np.argmax(sign * y))
    out.append(_peak(t, y, sign, label, f"{y[k] - y0:+.4g} N·m over the pre-shock {y0:.4g} N·m (mean of the "
                                        f"{dwell * 1e3:.0f} ms before) = {100 * (y[k] - y0) / amp:.3g} % of the "
                                        f"{amp:+.4g} N·m shock", dwell, band * abs(amp)))
    half = band * abs(amp)
    if t[-1] - t[0] <= dwell:
        return out + [Metric(f"{label}: recovery time", None, "s", f"fewer than {dwell * 1e3:.0f} ms of readings")]
    sm = step_metrics(t, y, initial=y0, final=y0, absolute_band=half, t_step=s.time, dwell=dwell)
    if bool(sm.settled):
        out.append(Metric(f"{label}: recovery time", float(sm.settling_time), "s",
                          f"from the shock at {s.time:.4g} s until the torque stays within ±{half:.3g} N·m "
                          f"({band * 100:g} % of the shock) of the pre-shock {y0:.4g} N·m"))
    else:
        out.append(Metric(f"{label}: recovery time", None, "s",
                          f"not back within ±{half:.3g} N·m ({band * 100:g} % of the shock) of the pre-shock "
                          f"{y0:.4g} N·m {until}"))
    return out


def stand_metrics(rec: StandRecord, stimuli: list[Stimulus], shutdown_count: int | None,
                  shutdown_window: float | None,
                  band: float = 0.05, dwell: float = 0.05, min_step: float = 1.0,
                  model_disengagements: int | None = None, trips_motor: bool = False, lobe: float = LOBE,
                  apex: float = APEX, speed: "Unit | None" = None) -> list[Metric]:
    """Key results of a dynamic-stand run, each relative to a stated reference.

    Per stimulus (segments end at the next one or the end of the run): after a start, step or stop the
    peak, overshoot (%, only when the torque was steady before the step and settles after it),
    settling time (``band`` of the step, held for ``dwell`` s) and final torque; after a shock the peak
    over the pre-shock level and the recovery time (back within ``band`` of the shock amplitude). For
    a stop also the standstill (last encoder edge); for a sweep (blocked half) the work on the coupling.
    Whole run: torque extremes, disengagements (apex passes of the measured relative angle), the
    shutdown rule of the scene, relative slip and when it ended, final speeds. ``lobe`` and ``apex`` (rad): the
    coupling's period in φ_r and its first apex (flat tappets: 120°, 60°; leaf springs: 2φ_d, φ_d). ``speed``: the
    display unit of the final speeds (:class:`rig.analysis.units.Unit`, the scene's; default rad/s).
    """
    from rig.analysis.units import unit
    sp = speed if speed is not None else unit("rad/s", "rad/s")
    lobe_deg, apex_deg = float(np.degrees(lobe)), float(np.degrees(apex))
    t, m = np.asarray(rec.t, float), np.asarray(rec.torque, float)
    out: list[Metric] = []
    if t.size < 2:
        return [Metric("torque", None, "N·m", "fewer than 2 torque readings")]
    i, j = int(np.argmax(m)), int(np.argmin(m))
    out.append(Metric("max torque", float(m[i]), "N·m", "highest torque-meter reading of the run (signed, + = "
                                                          "driving direction)", float(t[i])))
    out.append(Metric("min torque", float(m[j]), "N·m", "lowest torque-meter reading of the run", float(t[j])))
    order = sorted(stimuli, key=lambda s: s.time)
    changes = [s.time for s in order] + [s.time + s.duration for s in order if s.kind == "shock"]
    for n, s in enumerate(order):
        later = [x.time for x in order[n + 1:] if x.time > s.time]
        seg_end = min(later) if later else rec.end + 1e-12
        until = f"before the next change at {seg_end:.4g} s" if later else "within the run"
        earlier = [c for c in changes if c < s.time]
        pre_start = max(earlier) if earlier else -np.inf
        label = stimulus_label(s)
        if s.kind == "sweep":
            why = ("quasi-static sweep, no step: the blocked driven half is turned slowly, the torque follows the "
                   "relative angle (static characteristic) instead of settling")
            out += [Metric("overshoot", None, "%", why), Metric("settling time", None, "s", why)]
            if rec.rel_angle is not None and rec.t_angle is not None and rec.t_angle.size >= 2:
                phi = np.interp(t, rec.t_angle, rec.rel_angle)
                work = float(np.sum(0.5 * (m[1:] + m[:-1]) * np.diff(phi)))
                span = float(np.degrees(phi[-1] - phi[0]))
                out.append(Metric("work on the coupling", work, "J",
                                  f"∫M_t dφ_r over the sweep of {span:.4g}° ({span / lobe_deg:.3g} lobes); over whole "
                                  "lobes the elastic part cancels and this is the friction loss"))
                k = int(np.argmax(m))
                out.append(Metric("relative angle at max torque", float(np.degrees(phi[k]) % lobe_deg), "°",
                                  f"position in the lobe (apex at {apex_deg:.4g}°) where the loading peak was read"))
        elif s.kind == "shock":
            out += _shock_metrics(s, rec, seg_end, pre_start, label, band, dwell, until)
        else:
            out += _step_metrics(s, rec, seg_end, pre_start, label, band, dwell, min_step, until)
            if s.kind == "stop":
                if rec.last_edge is None or rec.last_edge <= s.time:
                    out.append(Metric(f"{label}: standstill", 0.0, "s", "no encoder count changed after the stop "
                                                                        "command"))
                elif rec.end - rec.last_edge >= dwell:
                    out.append(Metric(f"{label}: standstill", rec.last_edge - s.time, "s",
                                      f"after the stop command: the last encoder count change on either half, none in "
                                      f"the remaining {rec.end - rec.last_edge:.3g} s", rec.last_edge))
                else:
                    out.append(Metric(f"{label}: standstill", None, "s", f"still turning at the end of the run, "
                                      f"{rec.end - s.time:.3g} s after the stop command", exceeds=rec.end - s.time))
    sweep = any(s.kind == "sweep" for s in order)
    out += _slip_metrics(rec, shutdown_count, shutdown_window, model_disengagements, trips_motor, sweep, lobe, apex)
    off = [(s.time, "switched off") for s in order if s.kind == "stop" and s.time < rec.end]   # within the run
    off += [(m.at, "tripped by the scene's shutdown rule") for m in out
            if trips_motor and m.name == "shutdown" and m.value == "required" and m.at is not None and m.at < rec.end]
    motor_off = min(off) if off else None          # after it the stand coasts: a speed then is not a final one
    for name, (_, w, tr, method) in rec.speeds.items():
        ok = np.isfinite(w) & (tr >= rec.end - dwell)
        if not ok.any():
            continue
        if np.all(w[ok] == 0.0) and np.all(method[ok] == 3):
            out.append(Metric(f"final speed {name}", 0.0, sp.label, "at rest: the encoder count has not changed "
                                                                     "since power-on"))
        elif np.all(method[ok] == 3):            # no count in the window: only a bound, the shaft is at rest
            out.append(Metric(f"final speed {name}", f"< {np.max(np.abs(sp(w[ok]))):.2g} {sp.label}", sp.label,
                              "at rest: no encoder count in the last readings, so less than one count per time "
                              "since the last one"))
        else:
            mean = float(np.mean(w[ok]))
            change = np.polyfit(tr[ok] - rec.end, w[ok], 1)[0] * dwell if np.count_nonzero(ok) >= 3 else 0.0
            trend = (f"{sp(change):+.3g} {sp.label} over its last {dwell * 1e3:.0f} ms (trend), mean "
                     f"{sp(mean):.4g} {sp.label} — no final speed within the run")
            if motor_off is not None:
                out.append(Metric(f"final speed {name}", None, sp.label,
                                  f"coasting: the motor was {motor_off[1]} at {motor_off[0]:.4g} s and the stand "
                                  f"still turns at the end of the run: {trend}"))
            elif abs(change) > SPEED_SETTLED * max(abs(mean), 1.0):
                out.append(Metric(f"final speed {name}", None, sp.label,
                                  f"still {'speeding up' if change * mean >= 0 else 'slowing down'}"
                                  f"{', turning backwards (reversed),' if mean < 0 else ''} at the end of the "
                                  f"run: {trend}"))
            else:
                out.append(Metric(f"final speed {name}", sp(mean), sp.label,
                                  f"mean of the encoder speeds read in the last {dwell * 1e3:.0f} ms of the run"))
    return out


def _slip_metrics(rec: StandRecord, shutdown_count: int | None, shutdown_window: float | None, model: int | None,
                  trips_motor: bool, sweep: bool, lobe: float = LOBE, apex: float = APEX) -> list[Metric]:
    if rec.rel_angle is None or rec.t_angle is None or rec.t_angle.size < 2:
        return [Metric("disengagements", None, "", "no encoder readings of both halves")]
    ta, phi = rec.t_angle, rec.rel_angle
    times = apex_crossings(ta, phi, lobe, apex)
    model_text = "" if model is None else f"; model: {model}"
    when = ("" if not times.size else ", at " + ", ".join(f"{x:.4g}" for x in times) + " s" if times.size <= 4
            else f", {times[0]:.4g} … {times[-1]:.4g} s")
    out = [Metric("disengagements", f"{times.size}{when}", "",
                  f"apex passes of the measured relative angle φ1 − φ3 (encoders, {fixed(np.degrees(phi[0]), 2)}° at "
                  f"power-on; apexes at {np.degrees(apex):.4g}° + k·{np.degrees(lobe):.4g}°){model_text}")]
    if shutdown_count is None or shutdown_window is None:
        out.append(Metric("shutdown", None, "", "the recording holds no scene with a shutdown rule"))
        return out + _slip_angle(ta, phi, times, sweep, rec.end, lobe)
    summary = disengagement_summary(times, shutdown_window, shutdown_count)
    rule = f"{shutdown_count} disengagements within {shutdown_window * 1e3:.4g} ms"
    if summary.shutdown:
        out.append(Metric("shutdown", "required", "", f"the scene's rule: {rule}" +
                          ("; the scene trips the motor then" if trips_motor else ""), summary.first_shutdown_time))
    else:
        most = 0 if times.size == 0 else int(max(np.searchsorted(times, x + shutdown_window, side="right") - k
                                                 for k, x in enumerate(times)))
        out.append(Metric("shutdown", "not required", "", f"at most {most} disengagement(s) within "
                                                          f"{shutdown_window * 1e3:.4g} ms; the scene's rule: {rule}"))
    return out + _slip_angle(ta, phi, times, sweep, rec.end, lobe)


def _slip_angle(ta: np.ndarray, phi: np.ndarray, times: np.ndarray, sweep: bool, end: float,
                lobe: float = LOBE) -> list[Metric]:
    """Net relative angle change (slip when lobes were passed) and when the slip ended."""
    out: list[Metric] = []
    slip = float(np.degrees(phi[-1] - phi[0]))
    name = "relative angle swept" if sweep else "relative slip" if times.size else "relative angle change"
    out.append(Metric(name, slip, "°", f"net change of φ1 − φ3 from power-on to the end of the run ({slip / np.degrees(lobe):.3g} "
                                       f"lobes of {np.degrees(lobe):.4g}°)" + ("" if times.size or sweep else
                                                           "; no disengagement: elastic deflection only")))
    if times.size and not sweep:
        away = np.flatnonzero(np.abs(phi - phi[-1]) > SLIP_TOLERANCE)
        t_end = float(ta[away[-1] + 1]) if away.size and away[-1] + 1 < ta.size else None
        if t_end is not None and end - t_end >= 0.05:
            out.append(Metric("slip ended", t_end, "s", f"the relative angle stays within "
                                                        f"±{np.degrees(SLIP_TOLERANCE):.3g}° of its final value "
                                                        f"from then on ({t_end - times[-1]:.3g} s after the last "
                                                        "disengagement)"))
        else:
            out.append(Metric("slip ended", None, "s", "still slipping at the end of the run"))
    return out

"""The DigiForce-style acquisition unit: programs, channels, measurement control, curve, evaluation,
statistics. Inputs arrive as electrical samples through :meth:`DigiForce.feed`; commands are methods."""
from __future__ import annotations

import copy
import math
import time
from collections import deque
from typing import Any, Callable

import numpy as np

from . import control
from .channel import InputChain, shunt_ratio
from .curve import Curve, reference_x, turning_index
from .description import Description, load_description
from .elements import Element, build_elements, unit_format
from .errors import DigiForceError
from .evaluation import evaluate_curve, reference_verdict
from .memory import CurveMemory
from .program import check_units, default_program, merge, validate_program
from .results import CurveResult, ElementResult
from .statistics import ProgramStatistics

_UNIFORM_TOL = 1e-6   # relative spread of sample spacing accepted as one fixed rate


def _reason_format(program: dict[str, Any]):
    """The unit writes the numbers of its reasons in the channels' engineering units (SI)."""
    return unit_format({ch: c.get("unit", "") for ch, c in program["channels"].items()})


class DigiForce:
    """Simulated acquisition unit. ``description``: dict, TOML path or None (default unit file);
    ``rng``: source of the unit's own errors and noise (None: an ideal, noise-free unit)."""

    def __init__(self, description: dict | str | None = None, rng: np.random.Generator | None = None) -> None:
        self.desc: Description = load_description(description)
        channels = self.desc.channels()
        self._unit_errors = {ch: (tuple(rng.uniform(-0.5, 0.5, 2)) if rng is not None else None) for ch in channels}
        # one noise stream per channel: the draws do not depend on how the input is cut into chunks
        self._noise_rngs = dict(zip(channels, rng.spawn(len(channels)))) if rng is not None else {}
        self._programs = [default_program(i, self.desc) for i in range(self.desc.programs)]
        self._stats = [ProgramStatistics() for _ in range(self.desc.programs)]
        self.active_program = 0
        self.last_curve: Curve | None = None
        self.last_result: CurveResult | None = None
        self._curve_count = 0
        self._dropped = self._overflow_curves = self._decimated_curves = 0
        self._errors: deque[str] = deque(maxlen=20)
        self._eval_time: float | None = None
        self._ext_level = False
        self._prev_t: float | None = None
        # (time s, measuring, last result) at each curve's start and end: the state at a past time of the
        # latest chunk fed (a status frame due inside a chunk reports the state at its own time)
        self._changes: deque[tuple[float, bool, CurveResult | None]] = deque([(-math.inf, False, None)], maxlen=256)
        self._setup()

    # --- identity and programs --------------------------------------------------------------------
    def identify(self) -> str:
        d = self.desc
        return f"{d.model},{d.serial_number},{d.firmware}"

    @property
    def n_programs(self) -> int:
        return self.desc.programs

    def _check_program(self, n: Any) -> int:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 0 <= n < self.n_programs:
            raise DigiForceError(f"program number must be an integer 0...{self.n_programs - 1}, got {n!r}")
        return int(n)

    def _check_idle(self, what: str) -> None:
        if self._measuring:
            raise DigiForceError(f"{what}: not allowed while a measurement is running")

    def select_program(self, n: int) -> None:
        """Make program ``n`` active (resets filters and tare)."""
        n = self._check_program(n)
        self._check_idle("select_program")
        self.active_program = n
        self._setup()

    def get_program(self, n: int) -> dict[str, Any]:
        """Full, normalised configuration of program ``n`` (JSON-serialisable, SI numbers)."""
        return copy.deepcopy(self._programs[self._check_program(n)])

    def set_program(self, n: int, config: dict[str, Any], units_required: bool = False,
                    fits: Callable[[dict[str, Any]], str | None] | None = None) -> None:
        """Change program ``n``: ``config`` is merged over its current settings (dicts key by key, lists
        replace) and validated as a whole; nothing changes if it is invalid. ``units_required``: ``config``
        was written by a person (a scene) and must give every quantity with its unit (a bare number is an
        error naming its key); otherwise bare numbers are SI, as on the unit's interfaces. ``fits(program)``: why
        the interface it came over could not give the validated program back (None: it can), refused then."""
        n = self._check_program(n)
        if not isinstance(config, dict):
            raise DigiForceError(f"set_program: config must be a dict, got {type(config).__name__}")
        if units_required:
            check_units(self._programs[n], config, self.desc, f"program {n}")
        new = validate_program(merge(self._programs[n], config), self.desc, f"program {n}")
        why = fits(new) if fits is not None else None
        if why:
            raise DigiForceError(f"program {n}: {why}")
        elements = build_elements(new["elements"], _reason_format(new))
        if n == self.active_program:
            self._check_idle("set_program on the active program")
        self._programs[n] = new
        if n == self.active_program:
            self._setup(elements)

    def _setup(self, elements: list[Element] | None = None) -> None:
        """Build the active program's channels, elements and memory; back to idle."""
        prog = self._programs[self.active_program]
        self._prog = prog
        self._elements = elements if elements is not None else build_elements(prog["elements"], _reason_format(prog))
        self._chains = {ch: InputChain(c, self.desc.inputs[c["input"]], self.desc, self._unit_errors[ch],
                                       self._noise_rngs.get(ch)) for ch, c in prog["channels"].items() if c["enabled"]}
        s = prog["sampling"]
        self._memory = CurveMemory(self.desc.curve_memory, s["mode"], s["delta"], s["overflow"])
        self._measuring = False
        self._pending_start: float | None = None
        self._pending_stop: float | None = None
        self._prev: dict[str, float] | None = None
        self._last_chunk: dict[str, np.ndarray] = {}
        self._armed: dict[str, bool] = {}
        self._disarm()

    # --- channel commands -------------------------------------------------------------------------
    def _channels(self, channel: str | None) -> list[str]:
        if channel is None:
            return [c for c in ("x", "y") if c in self._chains]
        if channel not in self._chains:
            raise DigiForceError(f"channel must be one of {sorted(self._chains)}, got {channel!r}")
        return [channel]

    def tare(self, channel: str | None = None) -> None:
        """Zero ``channel`` (x, y, y2; None = x and y) on its latest input sample; not while measuring (the
        curve would jump)."""
        self._check_idle("tare")
        for ch in self._channels(channel):
            if ch not in self._last_chunk:
                raise DigiForceError(f"tare {ch}: no input sample yet; feed the unit first")
            self._chains[ch].tare_value = float(self._last_chunk[ch][-1])
        self._disarm()                                    # re-armed from the values as tared now

    def teach(self, channel: str, point: int, value: float) -> None:
        """Two-point teach: the latest input of ``channel`` shall read ``value`` (engineering units).
        ``point`` 0 or 1 replaces that point of the active program's teach pair (a sensitivity scaling
        first becomes the equivalent pair); the program is validated as with :meth:`set_program`."""
        ch = self._channels(channel)[0]
        if point not in (0, 1):
            raise DigiForceError(f"teach {ch}: point must be 0 or 1, got {point!r}")
        if ch not in self._last_chunk:
            raise DigiForceError(f"teach {ch}: no input sample yet; feed the unit first")
        chain = self._chains[ch]
        sc = self._prog["channels"][ch]["scaling"]
        points = copy.deepcopy(sc["points"]) if sc["mode"] == "teach" else [
            [chain.zero, 0.0], [chain.zero + sc["electrical"], sc["engineering"]]]
        points[point] = [float(self._last_chunk[ch][-1] / chain.scale + chain.zero), value]
        self.set_program(self.active_program, {"channels": {ch: {"scaling": {"mode": "teach", "points": points}}}})

    def shunt_expected(self, channel: str, shunt_resistance: float) -> float:
        """Engineering value a bridge channel should show with ``shunt_resistance`` (ohm) across one arm."""
        ch = self._channels(channel)[0]
        cfg = self._prog["channels"][ch]
        if cfg["input"] != "bridge":
            raise DigiForceError(f"shunt_expected: channel {ch!r} is not a bridge input")
        return float(shunt_ratio(cfg["sensor_resistance"], shunt_resistance) * self._chains[ch].scale)

    def shunt_check(self, channel: str, expected: float, tolerance: float | None = None) -> dict[str, Any]:
        """Compare the tared reading (mean of the latest fed chunk, taken with the shunt switched in) with
        ``expected`` (engineering units). Passes within ``tolerance`` (engineering units; default the
        input's accuracy figure of the range)."""
        ch = self._channels(channel)[0]
        if ch not in self._last_chunk:
            raise DigiForceError(f"shunt_check {ch}: no input sample yet; feed the unit with the shunt switched in")
        if not isinstance(expected, (int, float)) or not math.isfinite(expected) or expected == 0:
            raise DigiForceError(f"shunt_check {ch}: expected must be a finite non-zero number, got {expected!r}")
        chain = self._chains[ch]
        measured = float(np.mean(self._last_chunk[ch]) - chain.tare_value)
        limit = chain.input.accuracy * chain.full_scale if tolerance is None else float(tolerance)
        dev = measured - expected
        return {"channel": ch, "expected": float(expected), "measured": measured, "deviation": dev,
                "relative_deviation": dev / expected, "limit": limit, "ok": abs(dev) <= limit,
                "gain_correction": expected / measured if measured != 0 else None}

    # --- measurement control ----------------------------------------------------------------------
    def start(self, t: float | None = None) -> None:
        """Host start: the measurement begins at the first sample with time >= ``t`` (None: next sample)."""
        if self._measuring or self._pending_start is not None:
            raise DigiForceError("start: a measurement is already running or about to start")
        self._pending_start = -math.inf if t is None else float(t)

    def stop(self, t: float | None = None) -> CurveResult | None:
        """Host stop: end the measurement with the last sample at or before ``t``. ``None`` or a time
        already fed ends it now (at the latest fed sample) and returns the result. Before a pending start
        has begun, ``None`` cancels it and a later ``t`` schedules its end."""
        if not self._measuring:
            if self._pending_start is None:
                raise DigiForceError("stop: no measurement is running")
            if t is not None and t > self._pending_start:
                self._pending_stop = float(t)       # the measurement about to start ends at t
            else:
                self._pending_start = None          # cancelled before it began
            return None
        if t is not None and (self._prev_t is None or t > self._prev_t):
            self._pending_stop = float(t)
            return None
        return self._finish()

    def external_input(self, level: bool, t: float | None = None) -> CurveResult | None:
        """The external start input: a rising edge starts (control.start.mode "external"), a falling edge
        stops (control.stop.mode "external") at time ``t`` (None: now)."""
        rising, falling = level and not self._ext_level, self._ext_level and not level
        self._ext_level = bool(level)
        c = self._prog["control"]
        if rising and c["start"]["mode"] == "external" and not self._measuring and self._pending_start is None:
            self._pending_start = -math.inf if t is None else float(t)
        if falling and c["stop"]["mode"] == "external" and (self._measuring or self._pending_start is not None):
            return self.stop(t)
        return None

    @property
    def state(self) -> str:
        if self._measuring:
            return "measuring"
        armed = self._pending_start is not None or self._prog["control"]["start"]["mode"] in ("x", "y", "external")
        return "armed" if armed else "idle"

    def state_at(self, t: float) -> tuple[str, CurveResult | None]:
        """State and latest result at device time ``t`` (s), which may lie inside the latest chunk fed (any
        time after the 256th latest curve start or end): curves measured after ``t`` do not count yet."""
        for when, measuring, result in reversed(self._changes):
            if when <= t:
                if measuring:
                    return "measuring", result
                return ("idle" if self.state == "idle" else "armed"), result
        return self.state, self.last_result

    # --- acquisition ------------------------------------------------------------------------------
    def _rate(self, t: np.ndarray) -> float | None:
        times = t if self._prev_t is None else np.concatenate([[self._prev_t], t])
        if times.size < 2:
            return None
        dt = np.diff(times)
        if np.any(dt <= 0):
            i = int(np.argmax(dt <= 0))
            raise DigiForceError(f"feed: sample times must increase; t[{i + 1 - (self._prev_t is not None)}] = "
                                 f"{float(times[i + 1])!r} does not follow {float(times[i])!r}")
        step = float(np.median(dt))
        if 1.0 / step > self.desc.max_rate * (1 + 1e-9):
            raise DigiForceError(f"feed: sample rate {1 / step:g} Hz exceeds the unit's {self.desc.max_rate:g} Hz")
        if any(c["cutoff"] > 0 for c in (ch.cfg for ch in self._chains.values())) and \
                np.max(np.abs(dt - step)) > _UNIFORM_TOL * step:
            raise DigiForceError("feed: sample times must be evenly spaced while a low-pass filter is on "
                                 f"(spacing {dt.min():g}...{dt.max():g} s)")
        return 1.0 / step

    @property
    def enabled_channels(self) -> tuple[str, ...]:
        """The input channels the active program has enabled ("x", "y", "y2")."""
        return tuple(self._chains)

    def feed(self, t: np.ndarray, x: np.ndarray, y: np.ndarray, y2: np.ndarray | None = None) -> list[CurveResult]:
        """Electrical input samples (x in V; y, y2 in V/V for bridges or V) at times ``t`` (s, evenly spaced,
        after all earlier ones). Returns the results of curves that ended in this chunk."""
        t = np.asarray(t, dtype=float)
        inputs = {"x": x, "y": y, "y2": y2}
        if "y2" in self._chains and y2 is None:
            raise DigiForceError("feed: channel y2 is enabled in the active program but no y2 samples given")
        arrays = {}
        for ch in self._chains:
            a = np.asarray(inputs[ch], dtype=float)
            if a.shape != t.shape or t.ndim != 1:
                raise DigiForceError(f"feed: {ch} has shape {a.shape}, t has {t.shape}; need equal 1-D arrays")
            if not np.all(np.isfinite(a)):
                raise DigiForceError(f"feed: {ch} has a non-finite value at index {int(np.argmax(~np.isfinite(a)))}")
            arrays[ch] = a
        if t.size == 0:
            return []
        if not np.all(np.isfinite(t)):
            raise DigiForceError("feed: t has non-finite values")
        fs = self._rate(t)
        eng = {ch: self._chains[ch].convert(arrays[ch], fs) for ch in self._chains}
        self._last_chunk = eng
        results = self._run_control(t, eng)
        self._prev = {"t": float(t[-1]), **{ch: float(v[-1]) for ch, v in eng.items()}}
        self._prev_t = float(t[-1])
        return results

    def live_values(self) -> dict[str, np.ndarray]:
        """Tared engineering values (SI) of the last chunk fed, per enabled channel: what the display shows."""
        return self._tared(self._last_chunk)

    def _tared(self, eng: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {ch: v - self._chains[ch].tare_value for ch, v in eng.items()}

    def _find_start(self, t: np.ndarray, val: dict[str, np.ndarray], pos: int) -> int | None:
        cands = []
        if self._pending_start is not None:
            cands.append(control.first_at_or_after(t, self._pending_start, pos))
        trig = self._prog["control"]["start"]
        if trig["mode"] in ("x", "y"):
            cands.append(self._crossing("start", trig, val, pos))
        cands = [c for c in cands if c is not None]
        return min(cands) if cands else None

    def _disarm(self) -> None:
        """x/y triggers re-armed from the values from here on (none carried from an earlier chunk: control.crossing)."""
        self._armed = {"start": False, "stop": False}

    def _crossing(self, which: str, trig: dict[str, Any], val: dict[str, np.ndarray], first: int) -> int | None:
        """Where the ``which`` (start / stop) x/y trigger fires from index ``first`` on; its arming carries over
        to the next chunk while it has not fired (a fire, or a start or stop by other means, re-arms it from the
        values: :meth:`_begin`, :meth:`_finish`)."""
        ch = trig["mode"]
        at, self._armed[which] = control.crossing(val[ch], self._prev_value(ch, val, first), trig["value"],
                                                  trig["direction"], first, trig["hysteresis"], self._armed[which])
        return at

    def _prev_value(self, ch: str, val: dict[str, np.ndarray], pos: int) -> float | None:
        """Value before index 0 of the chunk (tared now) when searching from ``pos`` = 0."""
        if pos > 0 or self._prev is None:
            return None
        return self._prev[ch] - self._chains[ch].tare_value

    def _find_stop(self, t: np.ndarray, val: dict[str, np.ndarray], pos: int, start: int | None) -> int | None:
        cands = []
        if self._pending_stop is not None:
            cands.append(control.last_up_to(t, self._pending_stop))
        trig = self._prog["control"]["stop"]
        if trig["mode"] == "time":
            cands.append(control.last_up_to(t, self._t0 + trig["duration"]))
        elif trig["mode"] in ("x", "y"):
            cands.append(self._crossing("stop", trig, val, pos if start is None else start + 1))
        cands = [c for c in cands if c is not None]
        return max(min(cands), pos - 1) if cands else None

    def _run_control(self, t: np.ndarray, eng: dict[str, np.ndarray]) -> list[CurveResult]:
        results = []
        val = self._tared(eng)
        n, pos = t.size, 0
        while pos < n:
            start = None
            if not self._measuring:
                start = self._find_start(t, val, pos)
                if start is None:
                    break
                self._begin(t, eng, start)
                val = self._tared(eng)
                pos = start
            stop = self._find_stop(t, val, pos, start)
            end = n if stop is None else max(stop + 1, pos + (start is not None))
            rows = np.zeros((end - pos, 4))
            rows[:, 0] = t[pos:end]
            for col, ch in enumerate(("x", "y", "y2"), start=1):
                if ch in val:
                    rows[:, col] = val[ch][pos:end]
            self._memory.add(rows)
            pos = end
            if stop is not None:
                results.append(self._finish())
        return results

    def _begin(self, t: np.ndarray, eng: dict[str, np.ndarray], start: int) -> None:
        self._pending_start = None
        self._disarm()
        for ch, chain in self._chains.items():
            if chain.cfg["tare_at_start"]:
                chain.tare_value = float(eng[ch][start])
        self._measuring = True
        self._t0 = float(t[start])
        self._changes.append((self._t0, True, self.last_result))
        self._memory.begin(self._t0)

    # --- end of a curve: evaluation ---------------------------------------------------------------
    def _finish(self) -> CurveResult:
        rows = self._memory.finish()
        self._measuring = False
        self._pending_stop = None
        self._disarm()
        mem = self._memory
        began = time.perf_counter()
        k = turning_index(rows[:, 1])
        x_ref, ref_problem = reference_x(rows[:, 1], rows[:, 2], k, self._prog["reference"], _reason_format(self._prog))
        curve = Curve(t=rows[:, 0], x=rows[:, 1] - x_ref, y=rows[:, 2],
                      y2=rows[:, 3] if "y2" in self._chains else None, turning_index=k, x_reference=x_ref,
                      overflow=mem.overflow, decimations=mem.decimations, dropped=mem.dropped,
                      sampling={"mode": mem.mode, "delta": mem.delta, "overflow": mem.policy})
        verdicts, values = self.evaluate(curve)
        if ref_problem is not None:
            verdicts[:0] = reference_verdict(ref_problem)
        self._eval_time = time.perf_counter() - began
        self._curve_count += 1
        result = CurveResult(number=self._curve_count, program=self.active_program,
                             ok=all(v.ok for v in verdicts), elements=verdicts, process_values=values,
                             curve=curve, t_start=float(curve.t[0]), t_end=float(curve.t[-1]))
        self._dropped += mem.dropped
        self._overflow_curves += int(mem.overflow)
        self._decimated_curves += int(mem.decimations > 0)
        if mem.overflow:
            self._errors.append(f"curve {result.number}: memory overflow ({mem.policy}: {mem.dropped} pairs dropped, "
                                f"{mem.decimations} decimations)")
        self._stats[self.active_program].add(result)
        self.last_curve, self.last_result = curve, result
        self._changes.append((result.t_end, False, result))
        return result

    def evaluate(self, curve: Curve) -> tuple[list[ElementResult], dict[str, float]]:
        """Verdicts of the active program's enabled elements and all process values for ``curve``."""
        return evaluate_curve(self._elements, curve)

    # --- statistics and status --------------------------------------------------------------------
    def statistics(self, program: int | None = None) -> dict[str, Any]:
        """Counts and per-process-value statistics of ``program`` (None: the active one)."""
        n = self.active_program if program is None else self._check_program(program)
        return {"program": n, **self._stats[n].summary(self._programs[n]["limits"])}

    def reset_statistics(self, program: int | None = None) -> None:
        """Clear the statistics of ``program`` (None: the active one)."""
        self._stats[self.active_program if program is None else self._check_program(program)].reset()

    def status(self) -> dict[str, Any]:
        """State (idle/armed/measuring), time of the latest sample (s), OK/NOK outputs, counters, the running
        measurement's memory (pairs, full and dropping, decimations so far), overflow/ADC/filter flags, recent errors."""
        return {"state": self.state, "program": self.active_program, "time": self._prev_t,
                "curves": self._curve_count,
                "pairs_in_memory": self._memory.count if self._measuring else 0,
                "memory_full": self._measuring and self._memory.overflow,
                "decimations": self._memory.decimations if self._measuring else 0,
                "dropped_pairs": self._dropped, "overflow_curves": self._overflow_curves,
                "decimated_curves": self._decimated_curves,
                "adc_overflows": {ch: c.adc_overflows for ch, c in self._chains.items()},
                "filter_bypassed": sorted(ch for ch, c in self._chains.items() if c.bypassed),
                "external_input": self._ext_level,
                "last_ok": None if self.last_result is None else self.last_result.ok,
                "outputs": {"ok": self.last_result is not None and self.last_result.ok,
                            "nok": self.last_result is not None and not self.last_result.ok},
                "last_evaluation_time": self._eval_time, "errors": list(self._errors)}

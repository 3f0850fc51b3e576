"""Virtual-time soak of the demo scene: memory stays flat and the recording stays consistent over many cycles.

Runs ``run_scene(SCENE, out, cycles=N)`` in this process (N = 10 000 by default, about 4 000 s of simulated
time) while a background thread samples, every ``--interval`` s, the process's current and peak resident
set (``VmRSS``/``VmHWM`` of /proc/self/status) together with the host's progress (curves recorded, frames)
and the machine's simulated time. Reports:

* RSS after warm-up (the first sample at or after ``--warmup`` curves) against RSS at the end, and the
  least-squares slope of RSS after warm-up in MB per 1000 cycles with its ±2σ band (flat: the band below
  +1 MB/1000; growing: above it; undecided: a band across it, too wide for the run's length — run longer);
* the recording's size (and bytes per cycle), the run-phase real-time factor (``RunSummary.run_time``),
  the wall time with serial set-up and the process CPU time (simulated time per CPU second does not depend
  on what else the shared cores run);
* the unit's transmit queue over the run (backlog, curve transfers waiting: a bus that falls behind);
* a consistency check of the recording, streamed (``mcap.reader.NonSeekingReader`` + orjson, never all in
  memory): curve start times strictly increase in file order, every ``/device/result`` is complete with all
  9 process values, finite; curves with sampling gaps (a time step > 1.5x the median) are counted.

A run the runner stops (``RunError``, e.g. ``BusOverload``) is reported with what ran until then and its
recording is checked all the same. ``--fd`` soaks a copy of the scene on CAN FD 1/4 Mbit/s (as
bench_rig.py), where the bus has room to spare.

``--tracemalloc``: start tracing at warm-up, snapshot there and again at 95 % of the cycles, and print the
15 source lines whose live allocations grew most between the two snapshots and the 20 largest growing
allocation sites with the project's innermost frame (the sampler's own lists left out). It slows the run
10-20x; use it with fewer cycles (e.g. ``--cycles 3000 --fd``) to find what grows when RSS is not flat.

The host and machine objects are observed through subclasses patched into ``rig.runner.session`` for the
duration of the run (instrumentation only; nothing they do changes).

Run: ``python benchmarks/bench_soak.py [--cycles 10000] [--warmup 500] [--interval 0.5] [--keep PATH] [--fd]
[--tracemalloc]``. Expect several minutes for 10 000 cycles.
"""
from __future__ import annotations

import argparse
import linecache
import math
import sys
import tempfile
import threading
import time
import tracemalloc
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import orjson
from mcap.reader import NonSeekingReader

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
import rig.runner.session as session  # noqa: E402
from rig.runner import run_scene  # noqa: E402

SCENE = ROOT / "data" / "scenes" / "pin_insertion.toml"
PROCESS_VALUES = ("x_max", "x_min", "y_max", "y_min", "x_at_y_max", "y_at_x_max", "x_end", "y_end", "duration")
MB = 1024 * 1024


def proc_status() -> dict[str, int]:
    """VmRSS and VmHWM (peak RSS) of this process, in bytes."""
    out = {}
    with open("/proc/self/status", encoding="ascii") as f:
        for line in f:
            if line.startswith(("VmRSS:", "VmHWM:")):
                key, value, _unit = line.split()
                out[key[:-1]] = int(value) * 1024
    return out


class Observed:
    """The run's host and machine, captured when the runner builds them."""

    host = None
    machine = None


class _Host(session.Host):
    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        Observed.host = self


class _Machine(session.Machine):
    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        Observed.machine = self


class Sampler(threading.Thread):
    """Samples (wall s, curves recorded, frames, simulated s, RSS, peak RSS) every ``interval`` s; with
    ``trace_at`` = (warm-up curves, late curves) also starts tracemalloc and snapshots at both."""

    def __init__(self, interval: float, trace_at: tuple[int, int] | None = None) -> None:
        super().__init__(daemon=True)
        self.interval, self.trace_at = interval, trace_at
        self.samples: list[tuple[float, int, int, float, int, int]] = []
        self.node: list[tuple[float, float, int, int]] = []     # (simulated s, backlog s, curves pending, live factor)
        self.snapshots: list[tuple[int, tracemalloc.Snapshot]] = []
        self.stop = threading.Event()
        self.t0 = time.perf_counter()

    def sample(self) -> None:
        host, machine = Observed.host, Observed.machine
        curves = host.curves_recorded if host is not None else 0
        frames = host.frames if host is not None else 0
        sim = machine.t if machine is not None else 0.0
        st = proc_status()
        self.samples.append((time.perf_counter() - self.t0, curves, frames, sim, st["VmRSS"], st["VmHWM"]))
        if machine is not None:
            node = machine.node
            self.node.append((sim, node.backlog_time, node.curves_pending, node.live_factor))
        if self.trace_at is not None:
            stage = len(self.snapshots)
            if stage < 2 and curves >= self.trace_at[stage]:
                if stage == 0:
                    tracemalloc.start(25)
                self.snapshots.append((curves, tracemalloc.take_snapshot()))

    def run(self) -> None:
        while not self.stop.wait(self.interval):
            self.sample()


def check_recording(path: Path) -> dict:
    """Stream /device/curve and /device/result: curve start times strictly increasing (file order), results
    complete with all 9 process values."""
    starts, numbers, bad_order, gapped = [], [], [], []
    results = incomplete = missing_pv = nonfinite = 0
    examples: list[str] = []
    with open(path, "rb") as f:
        reader = NonSeekingReader(f)      # make_reader's seeking reader holds every chunk before yielding in file order
        for _schema, channel, message in reader.iter_messages(topics=["/device/curve", "/device/result"],
                                                              log_time_order=False):
            body = orjson.loads(message.data)
            if channel.topic == "/device/curve":
                t = np.asarray(body["t"], float) if isinstance(body["t"], list) else None   # json encoding
                t0 = t[0] if t is not None else float(message.log_time) * 1e-9
                if t is not None and t.size > 2:
                    dt = np.diff(t)
                    if dt.max() > 1.5 * np.median(dt):          # samples missing inside the curve
                        gapped.append((body["number"], t0, t.size, int(np.count_nonzero(dt > 1.5 * np.median(dt)))))
                if starts and not t0 > starts[-1]:
                    bad_order.append((body["number"], starts[-1], t0))
                starts.append(t0)
                numbers.append(body["number"])
            else:
                results += 1
                pv = body.get("process_values", {})
                lacking = [k for k in PROCESS_VALUES if k not in pv]
                if not body.get("complete", False):
                    incomplete += 1
                if lacking:
                    missing_pv += 1
                    if len(examples) < 3:
                        examples.append(f"result {body.get('number')}: missing {lacking}")
                if any(pv.get(k) is None or not math.isfinite(pv[k]) for k in PROCESS_VALUES if k in pv):
                    nonfinite += 1
    return {"curves": len(starts), "results": results, "gapped": gapped, "bad_order": bad_order, "incomplete": incomplete,
            "missing_pv": missing_pv, "nonfinite": nonfinite, "examples": examples,
            "numbers_consecutive": numbers == list(range(numbers[0], numbers[0] + len(numbers))) if numbers else False,
            "first_start": starts[0] if starts else math.nan, "last_start": starts[-1] if starts else math.nan}


def slope_error(x: np.ndarray, resid: np.ndarray) -> float:
    """Standard error of a least-squares slope over ``x`` with residuals ``resid`` correlated from one sample to the
    next (RSS moves in steps the allocator keeps for a while): the plain error σ²/Sxx inflated by (1 + r₁)/(1 − r₁),
    r₁ the residuals' lag-1 correlation (an AR(1) noise's effective sample size)."""
    n = x.size
    sxx = float(((x - x.mean()) ** 2).sum())
    if n < 4 or sxx <= 0.0:
        return math.inf
    r1 = float(np.corrcoef(resid[:-1], resid[1:])[0, 1]) if resid.std() > 0 else 0.0
    r1 = min(max(r1, 0.0), 0.99) if math.isfinite(r1) else 0.0
    return math.sqrt(float((resid ** 2).sum()) / (n - 2) / sxx * (1.0 + r1) / (1.0 - r1))


def report_memory(samples: list, warmup: int, cycles: int) -> None:
    s = np.array(samples, dtype=float)
    after = s[s[:, 1] >= warmup]
    print(f"memory ({len(s)} samples; RSS = VmRSS, peak = VmHWM):")
    if after.shape[0] < 3:
        print(f"  too few samples after the warm-up of {warmup} curves for a slope")
        return
    w, end = after[0], s[-1]
    slope, icept = np.polyfit(after[:, 1], after[:, 4] / MB, 1)
    resid = after[:, 4] / MB - (slope * after[:, 1] + icept)
    print(f"  after warm-up (curve {int(w[1])}, {w[0]:.0f} s): RSS {w[4] / MB:.1f} MB, peak {w[5] / MB:.1f} MB")
    print(f"  at the end    (curve {int(end[1])}, {end[0]:.0f} s): RSS {end[4] / MB:.1f} MB, peak {end[5] / MB:.1f} MB "
          f"(end/warm-up RSS x{end[4] / w[4]:.3f}, {(end[4] - w[4]) / MB:+.1f} MB)")
    print(f"  RSS after warm-up: min {after[:, 4].min() / MB:.1f} MB, max {after[:, 4].max() / MB:.1f} MB; "
          f"slope {slope * 1000:+.3f} MB per 1000 cycles (fit residual sd {resid.std():.2f} MB)")
    half = 2.0 * slope_error(after[:, 1], resid) * 1000          # ±2σ of the slope, MB per 1000 cycles
    lo, hi = slope * 1000 - half, slope * 1000 + half
    grown = (end[4] - w[4]) / MB
    if hi < 1.0 and grown < 10.0:                          # a leak is a growth: falling or level is flat
        verdict = "yes"
    elif lo > 1.0 or grown >= 10.0:
        verdict = "NO (growing)"
    else:
        verdict = "undecided (the RSS noise is too large for this many cycles: run longer)"
    print(f"  slope ±2σ (residuals' lag-1 correlation counted): {lo:+.3f} .. {hi:+.3f} MB per 1000 cycles")
    print(f"  flat after warm-up (the slope's ±2σ band below +1 MB/1000 cycles and < 10 MB growth): {verdict}")
    for q in (0.25, 0.5, 0.75):                         # a few points of the RSS curve
        k = min(range(len(after)), key=lambda i: abs(after[i, 1] - warmup - q * (end[1] - warmup)))
        print(f"    curve {int(after[k, 1]):6d}: RSS {after[k, 4] / MB:7.1f} MB at {after[k, 0]:6.0f} s")


def report_tracemalloc(snapshots: list) -> None:
    if len(snapshots) < 2:
        print("tracemalloc: fewer than 2 snapshots were taken")
        return
    (c0, a), (c1, b) = snapshots
    filters = [tracemalloc.Filter(False, tracemalloc.__file__), tracemalloc.Filter(False, "<frozen importlib._bootstrap>"),
               tracemalloc.Filter(False, __file__)]          # not the sampler's own lists
    a, b = a.filter_traces(filters), b.filter_traces(filters)
    total = sum(st.size_diff for st in b.compare_to(a, "filename"))
    print(f"tracemalloc: live allocations traced since curve {c0}, growth from curve {c0} to {c1}: "
          f"{total / MB:+.2f} MB ({total / max(c1 - c0, 1) * 1000 / MB:+.3f} MB per 1000 cycles)")
    for st in b.compare_to(a, "lineno")[:15]:
        frame = st.traceback[0]
        print(f"  {st.size_diff / 1024:+10.1f} KiB {st.count_diff:+8d} blocks  {frame.filename}:{frame.lineno}")
    print("  largest growth by allocation site: innermost frame <- innermost frame of the project's code")
    for st in b.compare_to(a, "traceback")[:20]:
        frames = list(st.traceback)                  # oldest first
        inner = frames[-1]
        own = [f for f in frames if f.filename.startswith(str(ROOT)) and "/.venv/" not in f.filename]
        where = own[-1] if own else inner
        text = linecache.getline(where.filename, where.lineno).strip()
        print(f"  {st.size_diff / 1024:+9.1f} KiB {st.count_diff:+7d} blocks  {_short(inner)} <- {_short(where)}: {text[:90]}")


def _short(frame) -> str:
    name = frame.filename
    for base in (str(ROOT) + "/", "site-packages/"):
        if base in name:
            name = name.split(base, 1)[1]
    return f"{name}:{frame.lineno}"


def report_backlog(node: list) -> None:
    """The unit's transmit queue over the run: backlog (wire time queued), curve transfers waiting."""
    if not node:
        return
    a = np.array(node, dtype=float)
    print(f"transmit queue ({len(a)} samples): backlog max {a[:, 1].max():.3f} s, curve transfers waiting max "
          f"{int(a[:, 2].max())}; live factor range {int(a[:, 3].min())}..{int(a[:, 3].max())}")
    edges = np.linspace(0.0, a[-1, 0], 6)
    for lo, hi in zip(edges[:-1], edges[1:]):
        part = a[(a[:, 0] >= lo) & (a[:, 0] <= hi)]
        if len(part):
            print(f"    {lo:7.0f}..{hi:7.0f} s simulated: backlog mean {part[:, 1].mean():.3f} s, max {part[:, 1].max():.3f} s; "
                  f"waiting max {int(part[:, 2].max())}")


def scene_copy(tmp: Path, fd: bool) -> Path:
    """The demo scene, or (``fd``) a copy with CAN FD 1/4 Mbit/s, as bench_rig.py uses."""
    if not fd:
        return SCENE
    text = SCENE.read_text()
    if "bitrate = 1000000" not in text:
        raise SystemExit(f"{SCENE}: 'bitrate = 1000000' not found; the CAN FD edit no longer applies")
    path = tmp / "pin_insertion_fd.toml"
    path.write_text(text.replace("bitrate = 1000000", "bitrate = 1000000\nfd = true\ndata_bitrate = 4000000", 1))
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cycles", type=int, default=10_000)
    ap.add_argument("--warmup", type=int, default=500, help="curves before the memory baseline (default 500)")
    ap.add_argument("--interval", type=float, default=0.5, help="s between samples (default 0.5)")
    ap.add_argument("--keep", type=Path, help="write the recording here and keep it (default: a temporary file)")
    ap.add_argument("--fd", action="store_true", help="soak a copy of the scene on CAN FD 1/4 Mbit/s")
    ap.add_argument("--tracemalloc", action="store_true", help="trace allocations from warm-up to 95 %% of the cycles")
    args = ap.parse_args()
    warmup = min(args.warmup, max(args.cycles // 4, 1))
    with tempfile.TemporaryDirectory() as tmp:
        out = args.keep or Path(tmp) / "soak.mcap"
        scene = scene_copy(Path(tmp), args.fd)
        patched = session.Host, session.Machine
        session.Host, session.Machine = _Host, _Machine
        sampler = Sampler(args.interval, (warmup, int(args.cycles * 0.95)) if args.tracemalloc else None)
        print(f"soak: {SCENE.name}{' (copy on CAN FD 1/4 Mbit/s)' if args.fd else ''}, {args.cycles} cycles "
              f"(warm-up {warmup}), sampling every {args.interval:g} s", flush=True)
        sampler.sample()
        sampler.start()
        failure = None
        cpu = time.process_time()
        try:
            s = run_scene(scene, out, cycles=args.cycles)
        except session.RunError as exc:          # report what ran until then, and the recording written
            failure, s = exc, None
        finally:
            sampler.stop.set()
            sampler.join()
            session.Host, session.Machine = patched
        cpu = time.process_time() - cpu
        sampler.sample()
        if tracemalloc.is_tracing():
            tracemalloc.stop()
        size = out.stat().st_size
        if s is None:
            _, curves, frames, sim, *_ = sampler.samples[-1]
            print(f"run FAILED after {curves} curves recorded, {sim:.1f} s simulated, "
                  f"{time.perf_counter() - sampler.t0:.0f} s wall, process CPU {cpu:.1f} s: {failure}")
            s = SimpleNamespace(curves=curves, simulated_time=sim, frames=frames, run_time=math.nan)
        else:
            print(f"run: {s.curves} curves, {s.simulated_time:.1f} s simulated, run phase {s.run_time:.1f} s -> "
                  f"real-time factor {s.realtime_factor:.2f}x (target >= 10x: {'met' if s.realtime_factor >= 10 else 'NOT met'}); "
                  f"wall with serial set-up {s.wall_time:.1f} s; process CPU {cpu:.1f} s ({s.simulated_time / cpu:.2f}x, "
                  f"independent of other jobs); {s.frames:,} frames ({s.frames / s.run_time:,.0f} frames/s)")
        print(f"recording: {size / MB:.1f} MB ({size / max(s.curves, 1) / 1024:.1f} KiB per cycle, "
              f"{size / max(s.simulated_time, 1e-9) / 1024:.1f} KiB per simulated s)")
        report_memory(sampler.samples, warmup, args.cycles)
        report_backlog(sampler.node)
        t = time.perf_counter()
        c = check_recording(out)
        ok = (not c["bad_order"] and c["results"] == c["curves"] >= s.curves and not c["incomplete"]
              and not c["missing_pv"] and not c["nonfinite"])
        order = "strictly increasing" if not c["bad_order"] else f"{len(c['bad_order'])} NOT increasing"
        print(f"recording check ({time.perf_counter() - t:.1f} s, streamed): {c['curves']} curves, start times "
              f"{c['first_start']:.4f} .. {c['last_start']:.4f} s, {order}, numbers consecutive: "
              f"{c['numbers_consecutive']}; {c['results']} results, incomplete {c['incomplete']}, lacking a process "
              f"value {c['missing_pv']}, non-finite values {c['nonfinite']} -> {'OK' if ok else 'FAILED'}")
        if c["gapped"]:
            g = c["gapped"]
            print(f"  {len(g)} curves have sampling gaps (a time step > 1.5x the median step); first: curve {g[0][0]} "
                  f"at {g[0][1]:.4f} s ({g[0][2]} pairs, {g[0][3]} gaps); e.g. curve {g[-1][0]} at {g[-1][1]:.4f} s: "
                  f"{g[-1][2]} pairs, {g[-1][3]} gaps")
        for line in c["examples"] + [f"curve {n}: start {b:.6f} s after {a:.6f} s" for n, a, b in c["bad_order"][:3]]:
            print(f"  {line}")
        if args.tracemalloc:
            report_tracemalloc(sampler.snapshots)


if __name__ == "__main__":
    main()

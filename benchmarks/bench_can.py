"""Host CAN decode throughput (frames/s) against what a 1 Mbit/s bus can carry; target >= 10x the bus limit.

Frames are produced once by the device node (``firmware_sim.can_node.CanNode`` on the in-process ``blockbus``:
curves of 4000 pairs, 2 s of 10 kHz live data per curve, status; the node's transmit policy decimates live data
to fit, curves first) and kept as the blocks the node sent, one per 0.1 s advance. They are then decoded,
best of several interleaved repeats, by:

(a) ``CanHost.receive`` frame by frame (python-can messages) - the per-frame path the target is about - and,
    as baselines in the same run, the same loop over ``CanHost.receive`` of the host at ``60ead5e^`` (before
    the regression) and at ``60ead5e`` (the commit where per-frame receive regressed to 4-6x), loaded from
    git into a private package with their own DBC of that time (they report the frames added since -
    ``TxStatus``, the result end marker - as link events; the curve and live frames are the same);
(b) ``CanHost.receive_block`` on the node's ``FrameBlock``s (per 0.1 s block, and the whole run as one block);
(c) ``CanHost.receive_many`` on python-can message lists (per 0.1 s list).

Each timed run ends with ``take_live()`` (the per-frame path builds its live arrays there). Every path
must give the same curves, live data and link events as (a) (checked). Ratios are to the bus
limit (classic: 8-byte standard frames without stuff bits, 111 bits = 9 009 frames/s; FD: 64-byte frames at
1 Mbit/s + 5 Mbit/s data phase, worst-case stuffing) and between the paths, all measured in this run.

Run: ``python benchmarks/bench_can.py [--repeats 5] [--no-baseline]``.
"""
from __future__ import annotations

import argparse
import importlib
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path
from types import SimpleNamespace

import can
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from drivers.can import CanHost  # noqa: E402
from firmware_sim.can_budget import BusTiming  # noqa: E402
from firmware_sim.can_node import CanNode  # noqa: E402
from rig.blockbus import FrameBlock  # noqa: E402

CURVES, PAIRS = 4, 4000
BASELINES = {"60ead5e^": "before the regression", "60ead5e": "the regressed commit"}


class Device:
    """Minimal device for the producer side: idle, program 1, results set by the benchmark."""

    last_result = None

    def status(self) -> dict:
        return {"state": "idle", "program": 1}

    def state_at(self, t: float) -> tuple[str, object]:
        """The node's heartbeat asks for the state at its own time (DigiForce.state_at): idle, the latest result."""
        return "idle", self.last_result


def produce(fd: bool, curves: int, rng: np.random.Generator) -> list[FrameBlock]:
    """The blocks the node sends (one per 0.1 s advance, then the final flush at ``close``)."""
    channel = f"bench-can-{uuid.uuid4().hex}"
    dev_bus = can.Bus(interface="blockbus", channel=channel)
    sink = can.Bus(interface="blockbus", channel=channel)
    device = Device()
    node = CanNode(dev_bus, device, bitrate=1_000_000, fd=fd, data_bitrate=5_000_000 if fd else None)
    blocks: list[FrameBlock] = []
    t = 0.0
    for k in range(curves):
        x = np.linspace(0, 0.04, PAIRS)
        device.last_result = SimpleNamespace(
            number=k + 1, program=1, ok=True, elements=[],
            process_values={"x_max": 0.04, "y_max": 800.0, "y_min": -1.0, "duration": 0.4},
            curve=SimpleNamespace(t=t + np.arange(PAIRS) * 1e-4, x=x, y=800 * x / 0.04 + rng.normal(0, 1, PAIRS)))
        for _ in range(20):                          # 2 s of live data at 10 kHz per curve
            ts = t + np.arange(1000) * 1e-4
            node.publish_live(ts, np.sin(ts) * 0.01, np.cos(ts) * 100)
            t += 0.1
            node.advance_to(t)
            blocks.extend(sink.recv_blocks())
    node.close(t)
    blocks.extend(sink.recv_blocks())
    dev_bus.shutdown()
    sink.shutdown()
    return [b for b in blocks if len(b)]


def load_host_at(commit: str, tmp: Path):
    """``CanHost`` of ``drivers/can`` at ``commit`` with the DBC of that commit, as a private package."""
    pkg = "mechrig_" + "".join(c if c.isalnum() else "_" for c in commit)
    files = subprocess.run(["git", "ls-tree", "-r", "--name-only", commit, "drivers/can", "data/can/rig.dbc"],
                           cwd=ROOT, check=True, capture_output=True, text=True).stdout.split()
    for sub in ("", "drivers"):
        (tmp / pkg / sub).mkdir(parents=True, exist_ok=True)
        (tmp / pkg / sub / "__init__.py").write_text("")
    for name in files:
        text = subprocess.run(["git", "show", f"{commit}:{name}"], cwd=ROOT, check=True, capture_output=True,
                              text=True).stdout
        if name.endswith(".py"):
            text = text.replace("from drivers.can", f"from {pkg}.drivers.can")
        (tmp / pkg / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp / pkg / name).write_text(text)
    if str(tmp) not in sys.path:
        sys.path.insert(0, str(tmp))
    return importlib.import_module(f"{pkg}.drivers.can.host").CanHost


def new_host(cls):
    return cls(can.Bus(interface="virtual", channel=f"bench-host-{uuid.uuid4().hex}"))


def per_frame(cls, messages):
    host = new_host(cls)
    t0 = time.perf_counter()
    for m in messages:
        host.receive(m)
    live = host.take_live()                 # the per-frame path builds its live arrays here
    return time.perf_counter() - t0, host, live


def per_block(cls, blocks):
    host = new_host(cls)
    t0 = time.perf_counter()
    for b in blocks:
        host.receive_block(b)
    live = host.take_live()                 # the per-frame path builds its live arrays here
    return time.perf_counter() - t0, host, live


def per_list(cls, lists):
    host = new_host(cls)
    t0 = time.perf_counter()
    for msgs in lists:
        host.receive_many(msgs)
    live = host.take_live()                 # the per-frame path builds its live arrays here
    return time.perf_counter() - t0, host, live


def outcome(host, live) -> tuple:
    """What a host made of the frames: curves (number, complete, t, x, y), live pairs, link events."""
    curves = [(c.number, c.complete, c.t.tolist(), c.x.tolist(), c.y.tolist()) for c in host.assembler.done]
    t, x, y = live
    events = [(e.time, e.kind, e.frame_id, e.count, e.detail) for e in host.events]
    return curves, (t.tolist(), x.tolist(), y.tolist()), events


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--no-baseline", action="store_true", help="skip the hosts of 60ead5e^ / 60ead5e")
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    with tempfile.TemporaryDirectory() as tmp:
        old = {} if args.no_baseline else {c: load_host_at(c, Path(tmp)) for c in BASELINES}
        summary = []
        for fd in (False, True):
            blocks = produce(fd, CURVES, rng)
            lists = [b.messages() for b in blocks]
            messages = [m for ms in lists for m in ms]
            whole = [FrameBlock.concat(blocks)]
            n = len(messages)
            timing = BusTiming(1_000_000, fd=fd, data_bitrate=5_000_000 if fd else None)
            if fd:
                limit = 1.0 / timing.frame_time(0x303, bytes(64), is_fd=True)
                label = "CAN FD 64-byte frames, 1 Mbit/s + 5 Mbit/s data phase"
            else:
                limit = 1_000_000 / 111          # 8-byte standard frames with no stuff bits: the most frames/s
                label = "classic 8-byte frames, 1 Mbit/s"
            runs = {"receive (per frame)": (per_frame, CanHost, messages),
                    **{f"receive at {c} ({why})": (per_frame, old[c], messages) for c, why in BASELINES.items()
                       if c in old},
                    "receive_block (0.1 s blocks)": (per_block, CanHost, blocks),
                    "receive_block (one block)": (per_block, CanHost, whole),
                    "receive_many (0.1 s lists)": (per_list, CanHost, lists)}
            best = {name: float("inf") for name in runs}
            hosts = {}
            for _ in range(args.repeats):                     # interleaved: load on the shared cores hits all alike
                for name, (fn, cls, data) in runs.items():
                    dt, host, live = fn(cls, data)
                    if name in hosts:
                        hosts[name][0].bus.shutdown()
                    hosts[name] = (host, live)
                    best[name] = min(best[name], dt)
            outcomes = {name: outcome(host, live) for name, (host, live) in hosts.items()}
            for host, _ in hosts.values():
                host.bus.shutdown()
            ref = outcomes["receive (per frame)"]
            assert len(ref[0]) == CURVES and all(c[1] for c in ref[0]) and ref[2] == [], ref[2][:3]
            for name, got in outcomes.items():
                if name.startswith("receive at"):
                    assert [c[:2] for c in got[0]] == [c[:2] for c in ref[0]], name
                    assert got[0] == ref[0] and got[1] == ref[1], f"{name}: curves or live data differ"
                    kinds = sorted({e[1] for e in got[2]})
                    runs[name] += (f"{len(got[2])} events ({', '.join(kinds)}: frames added since)",)
                else:
                    assert got == ref, f"{name}: outcome differs from per-frame receive"
            kinds = {}
            for b in blocks:
                for fid in b.arbitration_id.tolist():
                    kinds[fid] = kinds.get(fid, 0) + 1
            curve_frames = sum(v for k, v in kinds.items() if k in (0x302, 0x303))
            live_frames = sum(v for k, v in kinds.items() if k in (0x200, 0x201))
            print(f"\n{label}: {n} frames in {len(blocks)} blocks ({curve_frames} curve-block, {live_frames} live, "
                  f"{n - curve_frames - live_frames} other); bus limit {limit:,.0f} frames/s")
            base = n / best["receive (per frame)"]
            for name, (fn, cls, data, *note) in runs.items():
                rate = n / best[name]
                target = f"  [target >= 10x: {'met' if rate >= 10 * limit else 'NOT met'}]" if name.startswith(
                    "receive (per") else ""
                print(f"  {name:52s} {rate:12,.0f} frames/s = {rate / limit:6.1f}x bus limit, "
                      f"{rate / base:5.2f}x per-frame receive{target}" + (f"  ({note[0]})" if note else ""))
            summary.append((label, base / limit))
        print("\nper-frame CanHost.receive vs bus limit: " + "; ".join(f"{lab.split(',')[0]} {r:.1f}x" for lab, r in summary)
              + f" (target >= 10x: {'met' if all(r >= 10 for _, r in summary) else 'NOT met'})")


if __name__ == "__main__":
    main()

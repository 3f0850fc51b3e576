"""The cross-process hardware-in-the-loop path against the in-process run, in one run: ``rig serve`` (the simulated
machine in its own process, CAN over socketcand on 127.0.0.1, serial on a pty) with ``rig record`` (the host,
python-can's socketcand client receiving in blocks), against ``rig run`` of the same scene and cycles.

Prints each side's run-phase real-time factor as the commands print it (``rig record``'s: the served machine and the
host together) and their ratio, and checks that the two recordings hold the same messages in every topic but
``/log`` (bytes and log times relative to the first of each topic). Target: the served path >= 10x real time (the
data path's), as the in-process run.

Run: ``python benchmarks/bench_served.py [--cycles 200] [--repeats 2] [SCENE]`` (default: the demo scene).
"""
from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mcap.reader import make_reader

ROOT = Path(__file__).resolve().parents[1]
RIG = [sys.executable, "-m", "rig.cli"]
FACTOR = re.compile(r"([\d.]+) s simulated[^\n]* in ([\d.]+) s \(([\d.]+)x real time")


def factor(out: str, command: str) -> float:
    m = FACTOR.search(out)
    if m is None:
        raise SystemExit(f"{command}: no real-time factor in its output:\n{out[-1500:]}")
    return float(m[3])


def in_process(scene: Path, cycles: int, out: Path) -> float:
    p = subprocess.run([*RIG, "run", str(scene), "--cycles", str(cycles), "--no-report", "-o", str(out)],
                       cwd=ROOT, capture_output=True, text=True)
    if p.returncode:
        raise SystemExit(f"rig run failed ({p.returncode}):\n{p.stderr[-1500:]}")
    return factor(p.stdout, "rig run")


def served(scene: Path, cycles: int, out: Path) -> float:
    endpoints = out.with_suffix(".json")
    server = subprocess.Popen([*RIG, "serve", str(scene), "--cycles", str(cycles), "--endpoints", str(endpoints)],
                              cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60.0
        while not (endpoints.is_file() and endpoints.stat().st_size) and time.monotonic() < deadline:
            time.sleep(0.05)
        json.loads(endpoints.read_text())                      # whole: the server is up
        p = subprocess.run([*RIG, "record", str(scene), "--endpoints", str(endpoints), "--cycles", str(cycles),
                            "-o", str(out)], cwd=ROOT, capture_output=True, text=True)
        if p.returncode:
            raise SystemExit(f"rig record failed ({p.returncode}):\n{p.stderr[-1500:]}")
        return factor(p.stdout, "rig record")
    finally:
        server.wait(30.0)


def messages(path: Path) -> dict[str, list[tuple[bytes, int]]]:
    out: dict[str, list[tuple[bytes, int]]] = {}
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            out.setdefault(channel.topic, []).append((message.data, message.log_time))
    return {topic: [(d, t - found[0][1]) for d, t in found] for topic, found in out.items() if topic != "/log"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", type=Path, default=ROOT / "data" / "scenes" / "pin_insertion.toml")
    ap.add_argument("--cycles", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=2, help="interleaved pairs of runs (default 2)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        pairs = []
        for k in range(args.repeats):
            here = in_process(args.scene, args.cycles, folder / f"run{k}.mcap")
            there = served(args.scene, args.cycles, folder / f"served{k}.mcap")
            pairs.append((here, there))
            print(f"pair {k + 1}: rig run {here:.1f}x, rig serve + rig record {there:.1f}x (ratio {there / here:.2f})")
        same = messages(folder / "run0.mcap") == messages(folder / "served0.mcap")
    best = max(there for _, there in pairs)
    print(f"served path best {best:.1f}x real time (target >= 10x: {'met' if best >= 10 else 'NOT met'}); "
          f"recordings identical in every topic but /log: {same}")
    if not same:
        raise SystemExit(1)


if __name__ == "__main__":
    main()

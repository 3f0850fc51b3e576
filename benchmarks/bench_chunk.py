"""The runner's chunk against its speed: the README demo's run phase (``rig run … --no-report`` in a fresh process)
in chunks of one transmit cycle (100 ms, the baseline) to 2 s, interleaved, the best of ``--repeats`` kept, as a
ratio to the baseline measured in the same run; and that every chunk recorded the same bus (every frame of
``/can/raw`` and every message count equal: the chunk is a setting of the computation, docs/can-protocol.md).

Run: ``python benchmarks/bench_chunk.py [--repeats 3] [--chunks "100 ms" "500 ms" ...]``.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_scenes import ROOT, run  # noqa: E402

DEMO = ROOT / "data" / "scenes" / "pin_insertion.toml"


def scene_in_chunks(chunk: str, folder: Path) -> Path:
    """The demo scene with its [scene] chunk set to ``chunk``."""
    lines = DEMO.read_text().splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("chunk = "))
    lines[at] = f'chunk = "{chunk}"'
    path = folder / f"demo_{chunk.replace(' ', '')}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per chunk, interleaved, the best kept")
    ap.add_argument("--chunks", nargs="+", default=["100 ms", "200 ms", "500 ms", "1 s", "2 s"])
    args = ap.parse_args()
    from rig.recorder import read_recording
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        scenes = {c: scene_in_chunks(c, folder) for c in args.chunks}
        best: dict[str, tuple] = {}
        for c, scene in scenes.items():                 # untimed: numba's cache warm, the fidelity choice kept
            run(scene, folder / "warm.mcap")
        for _ in range(args.repeats):
            for c, scene in scenes.items():
                r = run(scene, folder / f"{scene.stem}.mcap")
                if c not in best or r[2] > best[c][2]:
                    best[c] = r
        base = args.chunks[0]
        reference = read_recording(folder / f"{scenes[base].stem}.mcap")
        print(f"{'chunk':>8s} {'run phase':>9s} {'factor':>7s} {'x ' + base:>10s} {'command':>8s}  same bus")
        for c, (sim, phase, factor, wall) in best.items():
            rec = read_recording(folder / f"{scenes[c].stem}.mcap")
            same = rec.message_counts.get("/can/raw") is not None and all(
                np.array_equal(np.asarray(rec.can_frames[k]), np.asarray(reference.can_frames[k]))
                for k in reference.can_frames) and rec.message_counts == reference.message_counts
            print(f"{c:>8s} {phase:8.2f}s {factor:6.1f}x {factor / best[base][2]:9.2f}x {wall:7.2f}s  "
                  f"{'yes' if same else 'NO'}", flush=True)


if __name__ == "__main__":
    main()

"""``rig bench fidelity``: the same cam-bar scene at levels 0, 1 and 2 — what each answers and what it costs.

The runs and answers of :mod:`rig.plants.cam_bar.level_answers` (one revolution of the scene's nominal machine;
L2 with the method :mod:`rig.fidelity` picks for the scene at level 2): each level answers the questions of
:data:`rig.fidelity.QUESTIONS` it reaches (stroke, rod-force peak, flank switches, upper-dwell vibration);
the others stay empty. Cost: wall time per simulated second, best of a few repeats in one run (numba
compiled beforehand). Writes ``DIR/<scene>_fidelity.csv`` (level, question, answer, unit, wall_s_per_s) and
``DIR/<scene>_fidelity.png``.
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path
from typing import Any, Callable


REPEATS = 5


def _best(run: Callable[[], Any]) -> tuple[float, Any]:
    """Best wall time (s) of up to REPEATS calls (one when a call takes over a second) and the last result."""
    best, out = math.inf, None
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        out = run()
        best = min(best, time.perf_counter() - t0)
        if best > 1.0:
            break
    return best, out


def measure(scene_path: str | Path) -> list[dict[str, Any]]:
    """Rows (level, question, answer in display units, unit, wall_s_per_s, method, vs_L2) for L0, L1, L2 of a
    cam-bar scene."""
    from rig.fidelity import QUESTIONS, choose
    from rig.plants.cam_bar.level_answers import UNITS, Deviation, LevelRuns
    from rig.plants.cam_bar.scene_io import require_cam_bar
    from rig.scene import load_scene
    scene = load_scene(scene_path)
    require_cam_bar(scene, "rig bench fidelity")
    l2 = choose(scene, "cam_bar", forced=2)
    runs = LevelRuns(scene, l2.method, l2.options)
    runs.run(1)
    runs.run(2)                                # compile / load the caches before timing
    cost = {level: _best(lambda: runs.run(level)) for level in (0, 1, 2)}
    answers = {level: runs.answers(level, cost[level][1]) for level in (0, 1, 2)}
    rows = []
    for level in (0, 1, 2):
        per_s = cost[level][0] / runs.simulated[level]
        for q, need in QUESTIONS["cam_bar"].items():
            unit, scale = UNITS[q]
            value = answers[level].get(q) if need <= level else None
            rows.append({"level": level, "question": q, "answer": "" if value is None else f"{value * scale:.6g}",
                         "unit": unit, "wall_s_per_s": f"{per_s:.4g}",
                         "method": l2.method_text if level == 2 else "none",
                         "vs_L2": "" if value is None or level == 2 else Deviation(q, level, value, answers[2][q]).text()})
    return rows


def disagreements(rows: list[dict[str, Any]]) -> list[str]:
    """One line per lower-level answer that level 2 contradicts (beyond rig.fidelity's default model tolerance, a count
    at all): at this
    operating point that question needs level 2."""
    from rig.fidelity import MODEL_TOLERANCE
    from rig.plants.cam_bar.level_answers import UNITS, Deviation
    out = []
    level2 = {r["question"]: r for r in rows if int(r["level"]) == 2}
    for r in rows:
        if not r.get("vs_L2"):
            continue
        scale = UNITS[r["question"]][1]
        deviation = Deviation(r["question"], int(r["level"]), float(r["answer"]) / scale,
                              float(level2[r["question"]]["answer"]) / scale)
        if deviation.beyond(MODEL_TOLERANCE):
            out.append(f"{deviation.describe()}: at this operating point the groove dynamics matter (clearance, flank "
                       f"changes) and this question needs L2")
    return out


def _answer(row: dict[str, Any]) -> str:
    """An answer to 4 digits with its unit; a dash for a question the level cannot answer."""
    if not row["answer"]:
        return "—"
    return f"{float(row['answer']):.4g} {row['unit'] if row['unit'] != 'count' else ''}".rstrip()


def write(rows: list[dict[str, Any]], out: Path, name: str) -> tuple[Path, Path]:
    """CSV and a chart: cost per level (log bars) with the questions each level answers and their answers."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}_fidelity.csv"
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    levels = sorted({r["level"] for r in rows})
    cost = [float(next(r["wall_s_per_s"] for r in rows if r["level"] == lv)) for lv in levels]
    fig, ax = plt.subplots(figsize=(8, 4.2), layout="constrained")
    ax.bar([f"L{lv}" for lv in levels], cost, color=["#7fb3d5", "#5dade2", "#2e86c1"])
    ax.set_yscale("log")
    ax.set_ylabel("wall time per simulated second (s/s)")
    ax.set_title(f"{name}: what each level answers and what it costs (one revolution)")
    for i, lv in enumerate(levels):
        text = "\n".join(f"{r['question']}: {_answer(r)}" for r in rows if r["level"] == lv)
        ax.text(i, cost[i] * 1.3, text, ha="center", va="bottom", fontsize=8)
    ax.set_ylim(min(cost) / 3, max(cost) * 8)        # room above the tallest bar for its lines
    png = out / f"{name}_fidelity.png"
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return path, png


def cmd_fidelity(args: argparse.Namespace) -> int:
    from rig.outputs import claim_dir, writable_dir
    out = Path(args.output)
    writable_dir(out, "output")
    rows = measure(args.scene)
    csv_path, png = write(rows, claim_dir(out), Path(args.scene).stem)
    for level in (0, 1, 2):
        mine = [r for r in rows if r["level"] == level]
        answered = ", ".join(f"{r['question']} {_answer(r)}" for r in mine if r["answer"])
        print(f"L{level}: {float(mine[0]['wall_s_per_s']) * 1e3:9.3f} ms per simulated s; answers {answered}")
    for line in disagreements(rows):
        print(f"rig: warning: {line}", file=sys.stderr)
    print(f"wrote {csv_path} and {png}")
    return 0


def register(sub: argparse._SubParsersAction, parents: list[argparse.ArgumentParser]) -> None:
    """``rig bench fidelity [--scene SCENE] -o DIR``."""
    from rig.cli import DEFAULT_SCENE, DEFAULT_SCENE_TEXT
    p = sub.add_parser("fidelity", parents=parents,
                       help="the same cam-bar scene at levels 0, 1 and 2: what each answers and its cost (CSV + PNG)")
    p.add_argument("--scene", default=str(DEFAULT_SCENE), help=f"cam-bar scene (default {DEFAULT_SCENE_TEXT})")
    p.add_argument("-o", "--output", required=True, help="output directory")
    p.set_defaults(func=cmd_fidelity)

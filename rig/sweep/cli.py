"""``rig sweep``: a grid over scene parameters on an executor → CSV table and map plots."""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

MANIFEST = ".mechrig-sweep"      # in a sweep directory: the files the last sweep wrote there (removed by the next)


def cmd_sweep(args: argparse.Namespace) -> int:
    from rig.executors.options import run_on_executor
    from rig.outputs import claim_dir, clear_previous, list_written, writable_dir
    from rig.scene import load_scene
    from rig.analysis.numbers import plural
    from rig.console import progress as progress_bar
    from rig.sweep import grid, parse_param
    from rig.sweep.plots import MAX_MAPS, plot_sweep
    from rig.sweep.run import SweepInterrupted, inert_params, levels_text, run_sweep, write_table
    from rig.stops import stopped
    params = [parse_param(p) for p in args.param]
    scene = load_scene(args.scene)
    out = Path(args.output)
    writable_dir(out, "sweep")

    def table_of(done: Any) -> Path:
        """The table of a stopped sweep's points (no maps), in place of an earlier sweep's outputs."""
        before = clear_previous(claim_dir(out), MANIFEST, _earlier_sweep)
        table = write_table(done, out / "sweep.csv")
        list_written(out, MANIFEST, before)
        return table

    def sweep_on(executor: Any) -> Any:
        bars: list[Any] = []

        def starting() -> None:                 # the checks passed: the line naming the executor, then the bar
            if not args.quiet:
                print(f"sweep of {len(params)} parameter(s) on {executor.describe()}", file=sys.stderr)
            bars.append(progress_bar(len(grid(params)), "sweep", " points", not args.quiet))

        try:
            return run_sweep(scene, params, args.metric, executor, args.revolutions, args.fidelity, starting,
                             lambda points: bars[0].update(points))
        except SweepInterrupted as stop:               # the points done are kept: a table of them, then the stop
            for bar in bars:
                bar.close()
            if not stop.result.points:                  # nothing to keep: an earlier sweep's outputs stay as they were
                print(f"rig: the sweep was {stopped(stop)} before any of its {stop.total} points was done; nothing "
                      f"written", file=sys.stderr)
                stop.said = ""                      # said: rig.cli adds no "rig: interrupted" (a second Ctrl-C while the
                raise                               # executor closes is a new one, and says so)
            print(f"rig: the sweep was {stopped(stop)} after {len(stop.result.points)} of {stop.total} points; their "
                  f"rows are in {table_of(stop.result)} (no maps)", file=sys.stderr)
            stop.said = ""
            raise
        finally:
            for bar in bars:
                bar.close()

    def kept(done: Any, stop: KeyboardInterrupt) -> None:   # after the last point, while the workers closed
        print(f"rig: {stopped(stop)} while the workers closed, after the sweep's last point: its "
              f"{plural(len(done.points), 'point')} are in {table_of(done)} (no maps)", file=sys.stderr)

    result = run_on_executor(args, sweep_on, kept, local="dask-processes")
    before = clear_previous(claim_dir(out), MANIFEST, _earlier_sweep)
    table = write_table(result, out / "sweep.csv")
    failed = [(p, e) for p, e, v in zip(result.points, result.errors, result.values) if e]
    whole = sum(all(math.isnan(x) for x in v.values()) for e, v in zip(result.errors, result.values) if e)
    partly = f" ({len(failed) - whole} of them with values of their other metrics)" if len(failed) > whole else ""
    print(f"{plural(len(result.points), 'point')} at model level {levels_text(result.levels)}, {len(failed)} failed"
          f"{partly} -> {table}")
    for point, error in failed[:5]:
        print(f"  failed at {', '.join(f'{p.key} = {v}' for p, v in zip(params, point))}: {error}")
    for key in inert_params(result):
        print(f"note: {key} changed none of the metrics ({', '.join(result.metrics)}): every value gave the same "
              f"numbers — check that the model uses this key for them (docs/scale-out.md)")
    for path in plot_sweep(result, out):
        print(f"map: {path}")
    list_written(out, MANIFEST, before)
    combos = math.prod(len(p.values) for p in params[2:])
    if combos > MAX_MAPS:
        print(f"maps: the first {MAX_MAPS} of {combos} combinations of {', '.join(p.key for p in params[2:])} per "
              f"metric (the table holds every point; sweep fewer values of those for a map of each)")
    return 0


def _earlier_sweep(out: Path) -> set[str]:
    """What a sweep of an older rig (no manifest) wrote into ``out``: its table and metric maps."""
    from rig.sweep.metrics import METRICS
    return {"sweep.csv"} | {p.name for p in out.glob("*.png")
                            if any(p.stem == m or p.stem.startswith(f"{m}_") for m in METRICS)}


def register(sub: argparse._SubParsersAction, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``rig sweep`` to the ``rig`` parser."""
    from rig.executors.options import add_executor_arguments
    from rig.sweep.metrics import METRICS
    sweep = sub.add_parser("sweep", parents=parents, help="grid over scene parameters -> metrics table and maps")
    sweep.add_argument("scene", help="scene file (TOML) whose keys --param varies (required)")
    sweep.add_argument("--param", action="append", required=True, metavar="KEY=VALUES",
                       help="dotted scene key and comma-separated values, e.g. 'plant.k=1.09 N/mm,1.89 N/mm' "
                            "(repeat for a grid)")
    sweep.add_argument("--metric", action="append", required=True, choices=tuple(METRICS),
                       help="metric per point (repeatable), [with the lowest model level that answers it]: "
                            + "; ".join(f"{k} [level >= {m.level}]: {m.doc}" for k, m in METRICS.items()))
    sweep.add_argument("--fidelity", type=int, choices=(0, 1, 2),
                       help="model level of every point (default as rig run: [scene] fidelity, else the lowest "
                            "answering [scene] questions, else the plant's default); a metric below its level is "
                            "refused (exit 2), not written as 0 or NaN")
    sweep.add_argument("--revolutions", type=int,
                       help="cam revolutions per point, metrics over the last one (cam-bar scenes only; default 2)")
    sweep.add_argument("-o", "--output", default="out/sweep", help="directory of table and maps (default out/sweep)")
    add_executor_arguments(sweep, local="dask-processes")
    sweep.set_defaults(func=cmd_sweep)

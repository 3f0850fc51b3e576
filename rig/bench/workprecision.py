"""``rig bench work-precision [--scene SCENE ...] [--quick] [--t-sim S] [--time-limit S] [--target ERROR]
[--from DIR] -o DIR``: work–precision CSV and chart per scene.

Writes ``DIR/<scene-stem>.csv`` (:data:`rig.bench.harness.COLUMNS`) and ``DIR/<scene-stem>.png``, prints the
reference check and one summary line per method. Without ``--scene``: the four problems of issue 13
(:data:`SCENES`). ``--from DIR`` measures nothing: it charts and summarises the CSVs an earlier run wrote there
(another target, a redrawn chart). Heavy imports stay in :func:`run_scenes`.
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Any

SCENE_DIR = Path(__file__).resolve().parents[2] / "data" / "scenes"
SCENES = tuple(SCENE_DIR / f"{name}.toml" for name in
               ("pin_insertion_l2", "pin_insertion_l2_flank_switch", "clutch_startup", "clutch_shock_short"))
CSV_HEAD, PNG_HEAD = b"method,setting,error,wall_s,nfev,t_sim,status", b"\x89PNG\r\n\x1a\n"


def register(bench_sub: argparse._SubParsersAction, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``work-precision`` under ``rig bench``."""
    wp = bench_sub.add_parser("work-precision", parents=parents,
                              help="error against wall time and RHS calls: our solvers, scipy and CVODE (CSV + PNG)")
    wp.add_argument("--scene", action="append", type=Path,
                    help="a level-2 cam-bar or clutch_dynamic scene (repeatable; default: the four of issue 13)")
    wp.add_argument("--quick", action="store_true", help="fewer settings and repeats (about 20-45 s per problem)")
    wp.add_argument("--t-sim", type=float, metavar="S",
                    help="simulate only the first S seconds (default: one revolution / the scene's duration)")
    wp.add_argument("--target", type=float, default=None, metavar="ERROR",
                    help="error at which the printed summary compares the methods (default 1e-6)")
    wp.add_argument("--time-limit", type=float, metavar="S",
                    help="wall seconds per run: a peer is stopped there, and a method's finer settings after a run "
                         "over it are skipped (status timeout / skipped in the CSV); default: none")
    wp.add_argument("--from", dest="measured", type=Path, metavar="DIR",
                    help="measure nothing: chart and summarise DIR/<scene>.csv of an earlier run (e.g. "
                         "data/work_precision) at --target")
    wp.add_argument("-o", "--output", type=Path, required=True, help="directory for <scene>.csv and <scene>.png")
    wp.set_defaults(func=command)


def _check_output(path: Path, head: bytes) -> None:
    """ValueError unless ``path`` is absent, empty or a file of this kind (rig never overwrites other files)."""
    if path.is_dir():
        raise ValueError(f"cannot write {path}: it is a directory")
    if path.exists():
        with path.open("rb") as fh:
            start = fh.read(len(head))
        if start and start != head:
            raise ValueError(f"cannot write {path}: it exists and is not a work-precision file rig wrote")


def outputs(out: Path, scene: Path) -> tuple[Path, Path]:
    """The CSV and PNG paths of ``scene`` in ``out``."""
    return out / f"{scene.stem}.csv", out / f"{scene.stem}.png"


def run_scenes(scenes: list[Path], out: Path, quick: bool = False, t_sim: float | None = None,
               methods: tuple[str, ...] | None = None, limit: float | None = None, target: float | None = None,
               progress_bars: bool = True, measured: Path | None = None) -> list:
    """Chart every scene into ``out`` (``t_sim`` (s) shortens the span; ``methods`` a subset; ``limit``: wall
    seconds per run, :func:`rig.bench.harness.work_precision`; ``target``: the error the printed summary compares
    at, default :data:`rig.bench.harness.TARGET`; ``progress_bars``: a bar over each scene's runs; ``measured``: a
    directory whose ``<scene-stem>.csv`` are read instead of run); the results.
    ``out`` follows rig's rule for output directories (new, empty, or one rig wrote before: rig.outputs)."""
    if limit is not None and not limit > 0:
        raise ValueError(f"--time-limit must be positive (s), got {limit:g}")
    if target is not None and not 0.0 < target < 1.0:
        raise ValueError(f"--target must be a relative error in (0, 1), got {target:g}")
    if measured is not None and (quick or limit is not None or methods is not None):
        raise ValueError("--from measures nothing: --quick, --time-limit and a method subset do not apply")
    from rig.bench.harness import METHODS, TARGET, read_csv, summary, write_csv
    from rig.bench.problems import load_problem
    from rig.bench.wpchart import plot
    from rig.outputs import claim_dir, writable_dir
    if measured is not None and not measured.is_dir():
        raise ValueError(f"--from {measured}: no such directory (it names the folder of an earlier run's CSVs)")
    writable_dir(out, "work-precision charts")
    for scene in scenes:                     # check every input and output before the long runs
        if not scene.is_file():
            raise ValueError(f"scene {scene} " + ("is a directory, not a scene file" if scene.is_dir() else
                                                  "does not exist"))
        if measured is not None and not (source := outputs(measured, scene)[0]).is_file():
            raise ValueError(f"--from {measured}: no {source.name} there for the scene {scene}")
        for path, head in zip(outputs(out, scene), (CSV_HEAD, PNG_HEAD)):
            _check_output(path, head)
    claim_dir(out)
    goal = TARGET if target is None else target
    results = []
    for scene in scenes:
        problem = load_problem(scene, t_sim)
        csv_path, png_path = outputs(out, scene)
        if measured is None:
            result = _measure(problem, quick, methods or METHODS, limit, progress_bars)
            write_csv(result, csv_path)
            origin, wrote = "", f"{csv_path} and {png_path}"
        else:
            source = outputs(measured, scene)[0]
            result = read_csv(source, problem)
            origin, wrote = f"measured earlier ({source}); ", f"{png_path}"
        plot(result, png_path, goal)
        ref = result.reference
        print(f"{problem.name}: {origin}reference {ref.label}; {ref.describe()}"
              + ("" if ref.confirmed else "  ** REFERENCE NOT CONFIRMED: errors below the distance are marked "
                 "unresolved **"))
        print("\n".join(summary(result, goal)))
        print(f"wrote {wrote}")
        results.append(result)
    return results


def _measure(problem: Any, quick: bool, methods: tuple[str, ...], limit: float | None, progress_bars: bool) -> Any:
    """Run the work–precision sweep of ``problem`` under a progress bar over its runs (every run logged)."""
    from rig.bench.harness import run_count, work_precision
    from rig.console import progress
    log = logging.getLogger("rig")
    with progress(run_count(problem, quick, methods), problem.name, " runs", enabled=progress_bars) as bar:
        def done(row: Any, line: str) -> None:
            log.debug(line)                                  # every run is in the CSV; the bar shows where
            if bar.n == 0:
                bar.reset(total=bar.total)                   # its clock from the first run, not the warm-up
            bar.set_postfix_str(f"{row.method} {row.setting}", refresh=False)
            bar.update()

        # the reference's line is printed with the summary (run_scenes): here only its warning, at once
        return work_precision(problem, quick, methods,
                              log=lambda line: (log.warning if line.startswith("WARNING") else log.debug)(line),
                              limit=limit, done=done)


def command(args: argparse.Namespace) -> int:
    run_scenes(args.scene or list(SCENES), args.output, args.quick, args.t_sim, limit=args.time_limit,
               target=args.target, progress_bars=not args.quiet, measured=args.measured)
    return 0

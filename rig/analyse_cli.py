"""``rig analyse``: many recordings (globs) on an executor → one table and one report."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def cmd_analyse(args: argparse.Namespace) -> int:
    from rig.analysis.batch import analyse_batch, expand, report_lines, write_table
    from rig.analysis.batch_charts import write_charts
    from rig.analysis.numbers import plural
    from rig.analysis.stand_summary import NO_SHEET
    from rig.console import progress as progress_bar
    from rig.executors.options import executor_from_args
    from rig.outputs import claim_dir, writable_dir
    paths = expand(args.recordings)
    out = Path(args.output)
    writable_dir(out, "analysis")
    with executor_from_args(args, local="dask-processes") as executor:
        if not args.quiet:
            print(f"analysing {plural(len(paths), 'recording')} on {executor.describe()}", file=sys.stderr)
        t0 = time.perf_counter()
        with progress_bar(len(paths), "analyse", " recordings", not args.quiet) as bar:
            result = analyse_batch(paths, executor, bar.update)
        wall = time.perf_counter() - t0
    table = write_table(result, claim_dir(out) / "recordings.csv")
    charts = write_charts(result, out / "charts")
    lines = report_lines(result, [(c.group, str(c.path.relative_to(out)), c.omitted) for c in charts])
    report = out / "report.md"
    report.write_text("\n".join(lines) + "\n")
    print(lines[2])
    for line in lines:                           # the notes under the totals (runs that share a seed)
        if line.startswith("Note: "):
            print(line)
    for row in result.recordings:                # a lab sheet that could not be made: one line each, as rig report
        for line in row.stand:
            if line.startswith(NO_SHEET):
                print(f"rig: warning: {row.path}: {line}", file=sys.stderr)
    read = sum(not r.error for r in result.recordings)
    if not read:
        if len(paths) == 1:
            only = result.recordings[0]
            print(f"rig: error: {only.path}: {only.error} (not a recording: also in {table}, {report})",
                  file=sys.stderr)
        else:
            first = result.recordings[0]
            print(f"rig: error: none of the {len(paths)} files could be read as a recording (the first, {first.path}: "
                  f"{first.error}; every reason in {table}, {report})", file=sys.stderr)
        return 2
    unread = f" ({len(paths) - read} unreadable, their reasons in the table)" if read < len(paths) else ""
    print(f"{plural(read, 'recording')} analysed{unread} in {wall:.1f} s -> {table}, {report}"
          + (f" ({plural(len(charts), 'chart')} in {out / 'charts'})" if charts else ""))
    return 0


def register(sub: argparse._SubParsersAction, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``rig analyse`` to the ``rig`` parser."""
    from rig.executors.options import add_executor_arguments
    p = sub.add_parser("analyse", parents=parents,
                       help="analyse many recordings (globs) -> one table (a row per recording) and a report")
    p.add_argument("recordings", nargs="+",
                   help="recording files, folders (every *.mcap under them) or glob patterns (quote them; ** recurses)")
    p.add_argument("-o", "--output", default="out/analyse", help="directory of table and report (default out/analyse)")
    add_executor_arguments(p, local="dask-processes")
    p.set_defaults(func=cmd_analyse)

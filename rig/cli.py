"""The ``rig`` command: run, serve, record and report scenes; print plant summaries.

``rig`` alone runs the demo: the pin-insertion scene end to end with its embedded defaults.
"""
from __future__ import annotations

if __name__ == "__mp_main__":      # a Dask worker process that `python -m rig.cli` spawned (as rig.launch does for
    from rig.stops import spawned_worker           # the `rig` console script's)
    spawned_worker()

import argparse
import atexit
import importlib
import json
import logging
import math
import os
import sys
from pathlib import Path
from typing import Any, Callable

from rig.limits import MAX_CYCLES
from rig.outputs import (JSON_START, PNG_MAGIC, TRACE_MAGIC, UsageError, claim_dir, file_parent, new_folder,
                         recording_file, writable_dir, writable_file)

DATA = Path(__file__).resolve().parents[1] / "data"
DEFAULT_SCENE = DATA / "scenes" / "pin_insertion.toml"
DEFAULT_SCENE_TEXT = f"data/scenes/{DEFAULT_SCENE.name}"       # the default as --help shows it
# Commands kept in their own packages (python-can style plugins): each module has
# ``register(sub, parents)`` adding its subparser(s) with ``set_defaults(func=...)``; heavy imports stay
# inside the command functions so ``rig --help`` stays fast.
COMMAND_MODULES: tuple[str, ...] = ("rig.bench.cli", "rig.sweep.cli", "rig.analyse_cli",
                                     "rig.cam_design_cli")


def _print_cam_bar_summary(scene_path: Path, png: Path, run_level: int | None = None) -> None:
    """Print the level-1 summary of a cam-bar scene and write its cycle chart ``png``; ``run_level``: the level of
    the run it precedes (None: no run; with a run, the recording's line says which folder was created, not this)."""
    from rig.plants.cam_bar.scene_io import cam_bar_from_scene, read_spring_rates
    from rig.plants.cam_bar.summary import plot_cycle, summary_table
    from rig.scene import load_scene
    mech, omega = cam_bar_from_scene(scene_path)
    print(summary_table(mech, omega, run_level, read_spring_rates(load_scene(scene_path))))
    created = new_folder(png)
    png.parent.mkdir(parents=True, exist_ok=True)
    plot_cycle(mech, omega, png)
    print(f"cycle chart: {png}{'' if run_level is not None else _created(created, png)}")


def _analysed(recording: Path) -> tuple[Any, dict]:
    """Read a recording once and analyse it: (Recording, :func:`rig.analysis.analyse` result)."""
    from rig.analysis import analyse
    from rig.recorder import read_recording
    rec = read_recording(recording, can_frames=False)      # the analysis counts the bus frames, needs none
    return rec, analyse(rec)


def _print_values(st: dict) -> None:
    """Table of one program's process values in their display units (the unit column; rig.analysis.units):
    n, unit, mean, σ, min, max, μ±3σ band (one precision per row), Cp/Cpk against the limits, checks (nothing
    without statistics)."""
    if not st.get("values"):
        return
    from rig.analysis.capability import index_text
    from rig.analysis.numbers import fixed, row_places
    from rig.analysis.trend import drift_text
    print(f"  {'process value':>16} {'n':>4} {'unit':>5}  {'mean μ':>10} {'σ':>9} {'min':>10} {'max':>10}  "
          f"{'μ−3σ..μ+3σ':>21}  {'Cp':>7} {'Cpk':>7}  normal drift")
    outside = []
    for name, pv in st.get("values", {}).items():
        if pv.get("cp") is None or pv.get("cpk") is None:
            cap = f"{'-':>7} {'-':>7}"
        elif not pv["spread"] and pv["cpk"] < 0:                     # σ = 0 and the one value beyond a limit
            cap = f"{'n/a':>7} {'-inf':>7}"
            outside.append(name)
        else:                                                                          # σ = 0: say nothing
            cap = f"{index_text(pv['cp']):>7} {index_text(pv['cpk']):>7}" if pv["spread"] else f"{'n/a':>7} {'n/a':>7}"
        drift = drift_text(pv["trend"], "-")
        places = row_places(pv["mean"], pv["std"])                 # mean, min, max and the band at one precision
        band = f"{fixed(pv['minus_3sigma'], places)}..{fixed(pv['plus_3sigma'], places)}"
        print(f"  {name:>16} {pv['n']:4d} {pv.get('unit', ''):>5}  {fixed(pv['mean'], places):>10} {pv['std']:9.3g} "
              f"{fixed(pv['min'], places):>10} {fixed(pv['max'], places):>10}  {band:>21}  {cap}  "
              f"{_yes_no(pv['normality'].get('normal')):6} {drift}")
    for name in outside:
        print(f"  {name}: NOT capable, every value outside its limits (Cpk -inf)")


def _yes_no(flag: bool | None) -> str:
    return "-" if flag is None else "yes" if flag else "no"


NOK_LINES = 5     # NOK curves whose reasons the console summary prints


def _print_set_summary(result: dict) -> None:
    """Console summary of an analysis: verdict counts, why the first NOK curves failed, incomplete results,
    per-program warnings, the process-value table and the comparison with the device's statistics, theory
    lag, events."""
    from rig.analysis.device import agreement_text
    from rig.analysis.sets import memory_warning
    verdicts = result["verdicts"]
    nok = [v for v in verdicts if not v["ok"]]
    print(f"curves: {len(verdicts)}, OK {len(verdicts) - len(nok)}, NOK {len(nok)}")
    for v in nok[:NOK_LINES]:
        why = "; ".join(f"{f['name']}: {f.get('reason') or 'no reason recorded'}" for f in v["failed"])
        print(f"  NOK curve {v['number']}: {why or 'the device named no failing element'}")
    if len(nok) > NOK_LINES:
        print(f"  ... and {len(nok) - NOK_LINES} more NOK curves (results.csv has every reason)")
    cut = memory_warning(verdicts)
    if cut:
        print(f"  warning: {cut}")
    lost = result["not_recorded"]
    if lost:
        print(f"  warning: {len(lost)} of these curves not recorded, their frames incomplete (curve "
              f"{', '.join(map(str, lost[:10]))}{' …' if len(lost) > 10 else ''}): judged by the unit only")
    incomplete = result["incomplete"]
    if incomplete:
        print(f"  warning: {len(incomplete)} incomplete result(s): " + "; ".join(
            f"curve {r['number']} missing {', '.join(r['missing']) or '(unnamed values)'}" for r in incomplete))
    for program, st in result["sets"].items():
        for warning in st.get("warnings", []):
            print(f"  warning (program {program}): {warning}")
        by_element = ", ".join(f"{k} {v}" for k, v in st["nok_by_element"].items()) or "none"
        print(f"  program {program}: {st['n']} curves, NOK by element: {by_element}")
        _print_values(st)
        print(f"  device statistics (program {program}): {agreement_text(st['device_agreement'])}")
    lags = [row for row in result["theory"] if row.get("lag_time") is not None]
    if lags:
        parts = []
        for signal in sorted({r["signal"] for r in lags}):
            rows = [r for r in lags if r["signal"] == signal]
            lt = sum(r["lag_time"] for r in rows) / len(rows)
            angles = [r["lag_angle"] for r in rows if r.get("lag_angle") is not None]
            la = f" = {sum(angles) / len(angles) * 180 / math.pi:.2f}° of cam angle" if angles else ""
            parts.append(f"{signal.upper()} {lt * 1e3:.2f} ms{la}")
        print(f"  theory vs measurement, mean lag over {len({r['curve'] for r in lags})} curves: {', '.join(parts)}")
    if result["events"]:
        pairs = result.get("live_pairs_dropped", 0)
        counts = {k: f"{v} ({pairs} live pairs in all)" if k == "live_dropped" and pairs else str(v)
                  for k, v in result["events"].items()}
        print("  events: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))


def _compiled(summary: Any) -> str:
    """The note on a run phase that held numba's one-time compilations (left out of its real-time factor)."""
    return (f" without the {summary.compile_time:.1f} s of one-time numba compilation that fell in the run phase"
            if summary.compile_time >= 0.05 else "")


def _done(verb: str, curves: int) -> str:
    """'recorded 50 curves', or 'recorded the run' for a stand or lab scene (no curves)."""
    return f"{verb} {curves} curves" if curves else f"{verb} the run"


def _print_stand_summary(rec: Any) -> bool:
    """Console summary of a stand run (clutch dynamic stand or static rig, lab bench; no curves): its key results,
    each with what it is relative to. False (nothing printed) for other recordings."""
    from rig.analysis.stand_summary import stand_summary
    summary = stand_summary(rec)
    if summary is not None:
        print("\n".join(summary.lines))
    return summary is not None


def _report(recording: Any, out_dir: Path, fmt: str, analysis: dict | None = None, progress: bool = False,
            ok_plots: int = 0, nok_plots: int | None = None) -> Path:
    """Write the report of a recording (path or an already-read Recording, with its analysis if known);
    ``progress``: a bar on stderr counting the report's sections; ``ok_plots`` / ``nok_plots``: OK / NOK curves
    plotted one by one (None: the report's default, :data:`rig.analysis.report_blocks.NOK_PLOTS`)."""
    from rig.analysis.report import NOK_PLOTS, SECTIONS, write_report
    from rig.console import progress as progress_bar
    claim_dir(out_dir)
    with progress_bar(len(SECTIONS), "report", " sections", progress) as bar:
        def counted(name: str, section: Callable) -> Callable:
            def run(ctx: Any) -> list:
                bar.set_postfix_str(name, refresh=False)       # redrawn at the bar's pace (a log: every 10 s)
                try:
                    return section(ctx)
                finally:
                    bar.update()
            return run
        sections = [(name, counted(name, section)) for name, section in SECTIONS]
        return write_report(recording, out_dir, fmt=fmt, analysis=analysis, sections=sections, ok_plots=ok_plots,
                            nok_plots=NOK_PLOTS if nok_plots is None else nok_plots)


def _created(folder: Path | None, file: Path) -> str:
    """The note on an output line that rig made the ``file``'s folder (:func:`rig.outputs.new_folder`: the outermost
    folder it created, the file's own one or one above it)."""
    if folder is None or not folder.is_dir():
        return ""
    own = Path(os.path.abspath(file)).parent
    return f" (created the folder {folder})" if own == folder else f" (created the folders {folder} … {own})"


def cmd_run(args: argparse.Namespace) -> int:
    from rig.runner import run_scene
    scene = Path(args.scene)
    out = Path(args.output) if args.output else Path("out") / f"{scene.stem}.mcap"
    created = recording_file(out)
    report_dir = Path(args.report_dir) if args.report_dir else out.with_suffix("")
    unused = [opt for opt, given in (("--format", args.format != "html"), ("--ok-plots", args.ok_plots),
                                     ("--nok-plots", args.nok_plots is not None)) if given]
    if args.no_report and unused:
        raise UsageError(f"{', '.join(unused)} {'shapes' if len(unused) == 1 else 'shape'} the report, and --no-report writes none")
    if not args.no_report:
        if report_dir.resolve() == out.resolve():
            raise UsageError(f"cannot write the report to {report_dir}: that is the recording's path; give another "
                             f"--report-dir")
        writable_dir(report_dir, "report", hint="--report-dir DIR, or --no-report")
    cfg = _scene_config(scene, args.cycles, args.fidelity)
    plots = [opt for opt, given in (("--ok-plots", args.ok_plots), ("--nok-plots", args.nok_plots is not None)) if given]
    if plots and not cfg.measures_curves:
        raise UsageError(f"{', '.join(plots)} {'chooses' if len(plots) == 1 else 'choose'} which curves the report "
                         f"plots, and {scene} measures none (its acquisition unit's X and Y are not wired: a stand or "
                         f"lab scene)")
    if cfg.plant == "cam_bar":
        writable_file(out.with_suffix(".cycle.png"), "cycle chart", PNG_MAGIC)
        _print_cam_bar_summary(scene, out.with_suffix(".cycle.png"), cfg.fidelity.level)
    summary = run_scene(scene, out, cycles=args.cycles, mode="realtime" if args.realtime else None,
                        progress=not args.quiet, fidelity=args.fidelity)
    what = _done("recorded", summary.curves)
    carried = (f" (its last {summary.flush_time * 1e3:.0f} ms: the bus sending what was queued at the end)"
               if summary.flush_time >= 0.5e-3 else "")
    print(f"{what}, {summary.simulated_time:.2f} s simulated{carried} in {summary.run_time:.2f} s "
          f"({summary.realtime_factor:.1f}x real time{_compiled(summary)}; {summary.wall_time:.2f} s with "
          f"{'serial set-up and read-back' if cfg.serial['enabled'] else 'set-up and the recording closed'}), "
          f"{summary.frames} CAN frames received -> {summary.output}{_created(created, summary.output)}")
    try:
        rec, analysis = _analysed(summary.output)
        if not _print_stand_summary(rec):
            _print_set_summary(analysis)
        if not args.no_report:
            report = _report(rec, report_dir, args.format, analysis, progress=not args.quiet, ok_plots=args.ok_plots,
                             nok_plots=args.nok_plots)
            print(f"report: {report}")
    except KeyboardInterrupt as exc:        # the recording is whole: say so, and how to get the summary or report
        exc.report_of = (summary.output, report_dir, args.no_report)        # type: ignore[attr-defined]
        raise
    return 0


def cmd_serve(args: argparse.Namespace) -> int:
    from rig.runner import serve_scene
    if args.endpoints:
        writable_file(Path(args.endpoints), "serve endpoints", JSON_START)
    _scene_config(Path(args.scene), args.cycles, args.fidelity)

    def announce(endpoints: dict[str, Any]) -> None:
        print(json.dumps(endpoints), flush=True)
        if args.endpoints:
            Path(args.endpoints).write_text(json.dumps(endpoints))

    machine = serve_scene(args.scene, mode="realtime" if args.realtime else None, port=args.port, wait=args.wait,
                          cycles=args.cycles, release_timeout=args.release_timeout, announce=announce,
                          progress=not args.quiet, fidelity=args.fidelity)
    if machine.node.before_run is None:          # else released before a run started: its warning said so
        print(f"{_done('served', machine.curves)}, {machine.t:.2f} s simulated", file=sys.stderr)
    return 0


def cmd_record(args: argparse.Namespace) -> int:
    from rig.runner import record_scene
    from rig.runner.session import scene_digest
    created = recording_file(Path(args.output))
    cfg = _scene_config(Path(args.scene), args.cycles, args.fidelity)
    if args.endpoints:                   # what `rig serve --endpoints` wrote: where to connect, and what it serves
        served = _served(Path(args.endpoints))
        if served["scene_sha256"] != scene_digest(args.scene):
            raise UsageError(f"{args.endpoints}: the served machine runs {served['scene']}, not {args.scene} (the "
                             "files differ): record the scene it serves")
        level = cfg.fidelity.level
        if served["fidelity"] != level:
            raise UsageError(f"{args.endpoints}: the served machine runs {served['scene']} at fidelity L"
                             f"{served['fidelity']}, this host would record L{level}: give the same --fidelity to "
                             "both")
        _connect_as_served(args, served)
    elif args.can_port is None:
        raise UsageError("rig record needs --endpoints FILE (written by `rig serve --endpoints`) or --can-port")
    else:
        print(f"rig record: warning: without --endpoints the scene and fidelity the machine serves are not checked; "
              f"the recording's theory is {args.scene}'s", file=sys.stderr)
    summary = record_scene(args.scene, args.output, can_host=args.can_host or "127.0.0.1", can_port=args.can_port,
                           serial_port=args.serial, can_channel=args.can_channel, cycles=args.cycles,
                           progress=not args.quiet, fidelity=args.fidelity)
    print(f"{_done('recorded', summary.curves)}, {summary.simulated_time:.2f} s simulated in {summary.run_time:.2f} s "
          f"({summary.realtime_factor:.1f}x real time, the served machine and this host together; "
          f"{summary.wall_time:.2f} s with serial set-up and read-back) -> {summary.output}"
          f"{_created(created, summary.output)}")
    rec, analysis = _analysed(summary.output)
    if not _print_stand_summary(rec):
        _print_set_summary(analysis)
    return 0


def _connect_as_served(args: argparse.Namespace, served: dict[str, Any]) -> None:
    """Where rig record connects: the endpoints' CAN server, channel and serial port, each unless given."""
    args.can_host = args.can_host or served["can"]["host"]
    args.can_port = args.can_port or served["can"]["port"]
    args.can_channel = args.can_channel or served["can"]["channel"]
    args.serial = args.serial or served["serial"]


def _served(path: Path) -> dict[str, Any]:
    """The endpoints file of `rig serve`, with the keys rig record needs (a UsageError naming what is wrong)."""
    try:
        served = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise UsageError(f"cannot read the endpoints {path}: {(exc.strerror or str(exc)).lower()}") from None
    except ValueError as exc:
        raise UsageError(f"{path}: not the endpoints JSON of `rig serve` ({exc})") from None
    missing = [k for k in ("can", "serial", "scene", "scene_sha256", "fidelity") if not isinstance(served, dict)
               or k not in served]
    if missing:
        raise UsageError(f"{path}: not the endpoints JSON of this rig's `rig serve` (no {', '.join(missing)})")
    can = served["can"]
    if not (isinstance(can, dict) and isinstance(can.get("host"), str) and isinstance(can.get("port"), int)
            and not isinstance(can.get("port"), bool) and 0 < can["port"] < 65536):
        raise UsageError(f"{path}: \"can\" must be {{\"host\": a host name, \"port\": a TCP port number}}, as "
                         f"`rig serve --endpoints` writes it; got {can!r}")
    return served


def cmd_report(args: argparse.Namespace) -> int:
    from rig.recorder import RecordingError, read_recording
    from rig.recorder.completeness import losses, nothing_recorded
    from rig.recorder.reader import require_recording
    path = Path(args.recording)
    out = Path(args.output) if args.output else path.with_suffix("")
    require_recording(path)
    if out.resolve() == path.resolve():
        raise UsageError(f"cannot write the report to {out}: that is the recording; give -o DIRECTORY")
    writable_dir(out, "report")
    try:
        rec = read_recording(path, allow_partial=args.partial, can_frames=False)
    except RecordingError as exc:
        if exc.partial is None:
            raise
        raise RecordingError(f"{path}: truncated or corrupt recording, no report written; `rig report --partial "
                             f"{path}` reports what it holds, reading past what is damaged: "
                             f"{'; '.join(exc.partial.problems)}") from None
    empty = nothing_recorded(rec)
    if empty is not None:
        raise RecordingError(f"{path}: nothing to report, {empty}; no report written")
    if not rec.complete:
        print(f"{path}: incomplete recording; " + "; ".join(losses(rec)))
    path = _report(rec, out, args.format, progress=not args.quiet, ok_plots=args.ok_plots, nok_plots=args.nok_plots)
    print(f"report: {path}")
    return 0


def cmd_export_can(args: argparse.Namespace) -> int:
    from datetime import datetime, timezone
    from rig.recorder.export_can import export_can
    from rig.recorder.reader import require_recording
    if Path(args.output).resolve() == Path(args.recording).resolve():
        raise UsageError(f"cannot write the CAN trace to {args.output}: that is the recording")
    require_recording(args.recording)
    output = Path(args.output)
    writable_file(output, "CAN trace", TRACE_MAGIC.get(output.suffix.lower()))
    created = new_folder(output)
    e = export_can(args.recording, file_parent(output), partial=args.partial)
    start = datetime.fromtimestamp(e.start, timezone.utc).isoformat() if e.start else "unknown (1970-01-01)"
    print(f"exported {e.frames} CAN frames ({e.error_frames} error frames) on {len(e.channels) or 1} channel(s), "
          f"simulation time {e.t_first:.6f}..{e.t_last:.6f} s, trace start {start} -> {e.path}{_created(created, e.path)}")
    if e.lost:
        logging.getLogger("rig").warning(
            "the recording is cut or damaged, the trace holds the frames that read (damaged parts skipped, as `rig "
            "report --partial` skips them): %s; its last frame is at %.6f s of simulation time%s", e.lost, e.t_last,
            ": what the run sent after it (a killed run's chunk not yet written) is not in the file" if e.tail_lost
            else " (the run's end record counts every message and all were read: nothing of the run is lost, only the "
                 "file's index after its data)" if e.all_read
            else " (the file was read to its end: only what the parts named held is missing)")
    return 0


def cmd_repair(args: argparse.Namespace) -> int:
    from rig.recorder.reader import require_recording
    from rig.recorder.repair import repair
    source = Path(args.recording)
    output = Path(args.output) if args.output else source.with_name(f"{source.stem}.repaired.mcap")
    if output.resolve() == source.resolve():
        raise UsageError(f"cannot write the repaired recording to {output}: that is the recording it reads "
                         f"(name another)")
    require_recording(source)
    recording_file(output)
    done = repair(source, file_parent(output))
    topics = ", ".join(f"{topic} {n}" for topic, n in sorted(done.messages.items()))
    print(f"wrote {sum(done.messages.values())} messages ({topics}) -> {done.path}")
    if done.problems and done.whole:        # ("lacks what is lost for good" where nothing was; an audit)
        print(f"nothing of the run was lost: every message and its end record were read; what the source lacked "
              f"is written anew ({'; '.join(done.problems)})")
    elif done.problems:
        print(f"the source lacks what is lost for good: {'; '.join(done.problems)}")
    else:
        print("the source was whole: nothing was lost")
    return 0


def cmd_summary(args: argparse.Namespace) -> int:
    from rig.plants.cam_bar.scene_io import require_cam_bar
    from rig.scene import load_scene
    scene = Path(args.scene)
    png = Path(args.png) if args.png else Path("out") / f"{scene.stem}.cycle.png"
    writable_file(png, "cycle chart", PNG_MAGIC)
    require_cam_bar(load_scene(scene), "rig summary")
    _scene_config(scene, None, choose_level=False)      # the whole scene checked, as rig run checks it
    _print_cam_bar_summary(scene, png)
    return 0


def _scene_config(scene: Path, cycles: int | None, fidelity: int | None = None, choose_level: bool = True) -> Any:
    """The scene's run configuration at the level ``--fidelity`` forces (scene errors first, before anything starts
    or is written: the transducers and the unit's program are built once to check them); ``--cycles`` only for a
    scene that counts cycles; ``choose_level`` False: no level chosen (a command that does not run the plant)."""
    from rig.runner.config import read_config
    from rig.runner.machine import check_wiring, instruments
    from rig.scene import load_scene
    cfg = read_config(load_scene(scene), fidelity, choose_level=choose_level)
    instruments(cfg)
    check_wiring(cfg)
    if cycles is not None and cfg.cycles is None:
        raise UsageError(f"--cycles given, but {scene} runs for a duration ([scene] duration), not for cycles")
    return cfg


def cmd_tolerance(args: argparse.Namespace) -> int:
    from rig.plants.cam_bar.tolerance import load_tolerances
    from rig.executors.options import run_on_executor
    from rig.plants.cam_bar.tolerance_report import plot_study, run_study, study_json, study_table
    from rig.runner.session import scene_digest
    from rig.plants.cam_bar.scene_io import mechanism_from_scene, require_cam_bar
    from rig.scene import load_scene
    from rig.stops import stopped
    scene_path = Path(args.scene)
    chart = Path(args.output) / f"{scene_path.stem}.tolerance.png"
    writable_dir(Path(args.output), "tolerance chart", shared=True)
    writable_file(chart, "tolerance chart", PNG_MAGIC)
    if args.json:
        writable_file(Path(args.json), "tolerance JSON", JSON_START)
    require_cam_bar(load_scene(scene_path), "rig tolerance")
    cfg = _scene_config(scene_path, None, choose_level=False)     # the whole scene checked; no level: no plant run

    def write(study: Any) -> None:
        """The finished study's table, chart and JSON."""
        print(study_table(study))
        print(f"chart: {plot_study(study, chart)}")
        if args.json:
            run = {"scene": cfg.name, "scene_sha256": scene_digest(scene_path),  # its content, not its path's spelling
                   "seed": cfg.seed, "machines": args.samples, "task_samples": args.task_samples}
            file_parent(Path(args.json)).write_text(json.dumps(study_json(study, run), indent=1) + "\n")
            print(f"JSON: {args.json}")

    def study_on(executor: Any) -> Any:
        if not args.quiet:
            print(f"Monte Carlo on {executor.describe()}", file=sys.stderr)
        return run_study(mechanism_from_scene(cfg.scene), load_tolerances(), args.samples, cfg.seed, executor,
                         progress=not args.quiet, task_samples=args.task_samples)

    def kept(study: Any, stop: KeyboardInterrupt) -> None:  # after the last sample, while the workers closed
        write(study)
        print(f"rig: {stopped(stop)} while the workers closed, after the study's last sample: its outputs above are "
              f"whole", file=sys.stderr)

    write(run_on_executor(args, study_on, kept))
    return 0


def cmd_studies(args: argparse.Namespace) -> int:
    from rig.plants.clutch.studies import plot_parameter_studies, write_peak_table
    out = Path(args.output)
    writable_dir(out, "studies")
    claim_dir(out)
    for path in plot_parameter_studies(out) + [write_peak_table(out)]:
        print(path)
    return 0


# -- arguments ------------------------------------------------------------------------------------------
class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``rig run: error: argument --cycles: ... (rig run -h: usage)``, and no
    abbreviated options (``--cyc`` is not ``--cycles``: a later option of the same prefix would change its meaning)."""

    def __init__(self, *args, allow_abbrev: bool = False, **kwargs) -> None:
        super().__init__(*args, allow_abbrev=allow_abbrev, **kwargs)

    def error(self, message: str) -> None:
        self.exit(2, f"{self.prog}: error: {message} ({self.prog} -h: usage)\n")

    def parse_known_args(self, args=None, namespace=None):
        """As argparse's, noting in the namespace the innermost (sub)command parser that parsed (``_rig_parser``)."""
        ns, extra = super().parse_known_args(args, namespace)
        if not hasattr(ns, "_rig_parser"):      # the subcommand's own parser ran first and set it
            ns._rig_parser = self
        return ns, extra

    def parse_args(self, args=None, namespace=None):
        """As argparse's, but an unknown option is the subcommand's error (``rig run: error: unrecognized arguments:
        --cyles (rig run -h: usage)``), pointing at the usage that has the options it meant."""
        ns, extra = self.parse_known_args(args, namespace)
        if extra:
            argv = list(sys.argv[1:] if args is None else args)
            command = getattr(ns, "command", None)
            before = command in argv and extra[0] in argv and argv.index(extra[0]) < argv.index(command)
            (self if before else ns._rig_parser).error(f"unrecognized arguments: {' '.join(extra)}")
        return ns


MAX_SAMPLES = 10**10   # Monte-Carlo machines rig tolerance takes (10^6 take ~15 s on two workers: this, ~2 days)


def _count(minimum: int, maximum: int | None = None) -> Callable[[str], int]:
    """argparse type: a whole number >= ``minimum`` (and <= ``maximum``); written as an integer or, whole, in
    scientific notation (``1e6``)."""
    def count(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            try:
                number = float(text)
            except ValueError:
                number = math.nan
            if not (math.isfinite(number) and number.is_integer()):
                raise argparse.ArgumentTypeError(f"expected a whole number >= {minimum}, got {text!r}") from None
            value = int(number)
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        if maximum is not None and value > maximum:
            raise argparse.ArgumentTypeError(f"must be at most {maximum:.0e}, got {value:.3g}")
        return value
    return count


def _port(minimum: int) -> Callable[[str], int]:
    def port(text: str) -> int:
        value = _count(minimum)(text)
        if value > 65535:
            raise argparse.ArgumentTypeError(f"a TCP port is at most 65535, got {value}")
        return value
    return port


def _seconds(text: str) -> float:
    """argparse type: a duration in seconds, >= 0 and finite."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds >= 0, got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    from rig.executors.options import add_executor_arguments
    p = _Parser(prog="rig", description="Virtual test rig for mechanism experiments. "
                "Without a command: run the pin-insertion demo scene.")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars or notices (warnings and errors stay)")
    quiet = _Parser(add_help=False)        # -q also after the command: `rig run -q`
    quiet.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    sub = p.add_subparsers(dest="command", parser_class=_Parser)
    run = sub.add_parser("run", parents=[quiet], help="run a scene in one process (machine + host) and record it to MCAP")
    run.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE),
                     help=f"scene file (TOML) to run (default {DEFAULT_SCENE_TEXT}, the pin-insertion demo)")
    run.add_argument("-o", "--output", help="recording path, *.mcap (default out/<scene>.mcap; a missing folder is "
                     "created and the output line says so)")
    run.add_argument("--fidelity", type=int, choices=(0, 1, 2),
                        help="force the model level (default: [scene] fidelity, else the lowest answering "
                        "[scene] questions)")
    run.add_argument("--cycles", type=_count(1, MAX_CYCLES), help="override the scene's number of cycles (>= 1)")
    run.add_argument("--realtime", action="store_true", help="pace to the wall clock (warns when it falls behind)")
    where = run.add_mutually_exclusive_group()
    where.add_argument("--report-dir", help="report directory (default: next to the recording)")
    run.add_argument("--format", choices=("html", "md"), default="html", help="report format (default html)")
    where.add_argument("--no-report", action="store_true", help="record and print the summary, write no report")
    run.add_argument("--ok-plots", type=_count(0), default=0, metavar="N",
                     help="also plot the first N OK curves one by one (default 0)")
    run.add_argument("--nok-plots", type=_count(0), default=None, metavar="N",
                     help="plot the first N NOK curves one by one with their failed elements (default 12; the "
                          "report says how many of how many; every reason is in results.csv)")
    run.set_defaults(func=cmd_run)
    serve = sub.add_parser("serve", parents=[quiet],
                           help="run the simulated machine: CAN over socketcand, serial on a pty")
    serve.add_argument("scene", help="scene file (TOML) of the machine to serve (required)")
    serve.add_argument("--port", type=_port(0), help="socketcand TCP port (default: the scene's, 0 = any)")
    serve.add_argument("--realtime", action="store_true",
                       help="pace the machine to the wall clock like the real one (default: as fast as it runs)")
    serve.add_argument("--wait", type=_seconds, default=300.0,
                       help="seconds to wait for a host to arm the device (default 300)")
    serve.add_argument("--fidelity", type=int, choices=(0, 1, 2),
                        help="force the model level (default: [scene] fidelity, else the lowest answering "
                        "[scene] questions)")
    serve.add_argument("--cycles", type=_count(1, MAX_CYCLES), help="override the scene's number of cycles (>= 1)")
    serve.add_argument("--release-timeout", type=_seconds, default=300.0,
                       help="seconds to wait after the run for the host to release the device (CAN Release; "
                            "default 300)")
    serve.add_argument("--endpoints", help="also write the endpoints JSON to this file")
    serve.set_defaults(func=cmd_serve)
    rec = sub.add_parser("record", parents=[quiet], help="the host: connect to `rig serve` and record the run")
    rec.add_argument("scene", help="scene file (TOML) the served machine runs: the recording's theory and checks "
                     "(required; --endpoints checks that it is the served one)")
    rec.add_argument("-o", "--output", required=True, help="recording path, *.mcap (a missing folder is created and "
                     "the output line says so)")
    rec.add_argument("--can-host", help="the socketcand server's address (default: the endpoints', else 127.0.0.1)")
    rec.add_argument("--endpoints", metavar="FILE", help="the endpoints `rig serve --endpoints FILE` wrote: where to "
                     "connect, checked to serve this scene at this fidelity (--can-host/--can-port/--can-channel/"
                     "--serial given beside it override its entries)")
    rec.add_argument("--can-port", type=_port(1), help="the socketcand server's TCP port (default: the endpoints')")
    rec.add_argument("--can-channel", help="the CAN channel to open on the server (default: the endpoints', else "
                     "the scene's [links.can] channel)")
    rec.add_argument("--serial", help="serial port path or URL printed by `rig serve`")
    rec.add_argument("--fidelity", type=int, choices=(0, 1, 2),
                        help="force the model level (default: [scene] fidelity, else the lowest answering "
                        "[scene] questions)")
    rec.add_argument("--cycles", type=_count(1, MAX_CYCLES), help="record only the first N curves (>= 1)")
    rec.set_defaults(func=cmd_record)
    rep = sub.add_parser("report", parents=[quiet],
                         help="write an HTML/Markdown report with plots and CSV from a recording")
    rep.add_argument("recording", help="recording (.mcap) written by rig run or rig record (required)")
    rep.add_argument("-o", "--output", help="report directory (default: the recording's path without .mcap, "
                     "out/x.mcap -> out/x)")
    rep.add_argument("--format", choices=("html", "md"), default="html", help="report format (default html)")
    rep.add_argument("--partial", action="store_true",
                     help="report what a truncated recording (a killed run) holds and what was lost")
    rep.add_argument("--ok-plots", type=_count(0), default=0, metavar="N",
                     help="also plot the first N OK curves one by one (default 0)")
    rep.add_argument("--nok-plots", type=_count(0), default=None, metavar="N",
                     help="plot the first N NOK curves one by one with their failed elements (default 12; the "
                          "report says how many of how many; every reason is in results.csv)")
    rep.set_defaults(func=cmd_report)
    exp = sub.add_parser("export-can", parents=[quiet],
                         help="write the recording's CAN bus traffic (/can/raw) as a CAN trace: "
                         ".asc, .blf, .log (candump), .trc or .mf4 by extension")
    exp.add_argument("recording", help="recording (.mcap) whose CAN traffic is exported (required)")
    exp.add_argument("-o", "--output", required=True, help="trace file; its extension picks the format")
    exp.add_argument("--partial", action="store_true",
                     help="of a cut or damaged recording (a killed run): every frame that reads, damaged chunks "
                          "skipped as `rig report --partial` skips them, with a warning naming what is lost")
    exp.set_defaults(func=cmd_export_can)
    fix = sub.add_parser("repair", parents=[quiet],
                         help="rewrite a cut or damaged recording (a killed run) as a whole MCAP file that Foxglove and "
                              "other indexed readers open; what was lost is named in it")
    fix.add_argument("recording", help="the cut or damaged recording (.mcap)")
    fix.add_argument("-o", "--output", help="the repaired recording (default: <recording>.repaired.mcap beside it)")
    fix.set_defaults(func=cmd_repair)
    summ = sub.add_parser("summary", parents=[quiet], help="cam-bar kinematics/kinetostatics table and cycle chart")
    summ.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE),
                      help=f"cam-bar scene (default {DEFAULT_SCENE_TEXT})")
    summ.add_argument("--png", help="path of the cycle chart (default out/<scene>.cycle.png)")
    summ.set_defaults(func=cmd_summary)
    tol = sub.add_parser("tolerance", parents=[quiet],
                         help="cam-bar linear and Monte-Carlo tolerance analysis (table + PNG)")
    tol.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE),
                     help=f"cam-bar scene (default {DEFAULT_SCENE_TEXT})")
    tol.add_argument("--samples", type=_count(2, MAX_SAMPLES), default=20000,
                     help=f"Monte-Carlo machines (default 20000, at most {MAX_SAMPLES:.0e}: days on two workers)")
    add_executor_arguments(tol)
    tol.add_argument("--task-samples", type=_count(1), default=50_000, metavar="N",
                     help="machines per task (default 50000); with the seed it fixes the result bit for bit")
    tol.add_argument("-o", "--output", default="out", help="directory of the chart (default out)")
    tol.add_argument("--json", metavar="FILE", help="also write per-angle mean, sigma, 0.135/99.865 %% points "
                     "and the linear RSS (m) to FILE")
    tol.set_defaults(func=cmd_tolerance)
    stud = sub.add_parser("studies", parents=[quiet], help="clutch static-characteristic parameter studies (PNG)")
    stud.add_argument("-o", "--output", default="out/studies", help="directory of the charts (default out/studies)")
    stud.set_defaults(func=cmd_studies)
    for module in COMMAND_MODULES:
        importlib.import_module(module).register(sub, [quiet])
    return p


def _interrupted(exc: KeyboardInterrupt) -> str:
    """One line on Ctrl-C (or SIGTERM, named so): what a recorded run left (rig.runner.session.Interrupted), or that
    the report of a whole recording was cut, else nothing claimed; empty when the command said it (``exc.said``)."""
    from rig.stops import stopped
    if hasattr(exc, "said"):               # a command that said it itself ("": a sweep, what it kept) or has its line
        return getattr(exc, "said")
    said = stopped(exc)
    if hasattr(exc, "report_of"):
        recording, folder, no_report = getattr(exc, "report_of")
        if no_report:
            return (f"rig: {said} while summarising the run; the recording {recording} is complete: `rig report "
                    f"{recording}` writes its report")
        return (f"rig: {said} while summarising the run or writing its report; the recording {recording} is "
                f"complete: `rig report {recording} -o {folder}` writes the report")
    if not hasattr(exc, "recording"):
        return f"rig: {said}"
    recording = getattr(exc, "recording")
    if recording is None:
        kept = getattr(exc, "kept", None)
        return (f"rig: {said} before anything was recorded; no recording was written"
                + (f" (the earlier recording at {kept} is kept as it was)" if kept else ""))
    from rig.analysis.numbers import plural
    curves, until = getattr(exc, "curves", 0), getattr(exc, "simulation_time", 0.0)
    held = (f"{plural(curves, 'curve')}, " if curves else "") + f"{until:.2f} s of simulation time"
    return f"rig: {said}; what was recorded so far ({held}) is in {recording} (marked interrupted)"


def _plain(exc: BaseException) -> str:
    """An exception as one line in plain words: an OSError as "PATH: reason", not "[Errno 17] ..."."""
    if isinstance(exc, OSError) and exc.strerror:
        where = " -> ".join(str(f) for f in (exc.filename, exc.filename2) if f is not None)
        return f"{where}: {exc.strerror.lower()}" if where else exc.strerror.lower()
    return " ".join(str(exc).split("\n")[:1]) if not isinstance(exc, ValueError) else str(exc)


def _run(argv: list[str] | None) -> int:
    """Exit status: 0 done; 2 a usage or scene error (nothing run); 1 the run failed; 130 Ctrl-C."""
    args = build_parser().parse_args(argv)
    if args.command is None:
        args = build_parser().parse_args(["-q", "run"] if args.quiet else ["run"])
    args.quiet = getattr(args, "quiet", False)
    from rig.console import configure
    configure(quiet=args.quiet)
    from rig.recorder.errors import RecordingError
    from rig.runner.errors import RunError
    from rig.scene import SceneError
    from rig.solvers.base import SolverDivergence
    try:
        return args.func(args)
    except RunError as exc:
        print(f"rig: error: {exc}", file=sys.stderr)
        return 1
    except SolverDivergence as exc:         # the model's integration stopped: what, where and the fix, in one line
        notes = "".join(f"; {n}" for n in getattr(exc, "__notes__", ()))
        print(f"rig: error: the plant model could not go on: {_plain(exc)}{notes}", file=sys.stderr)
        return 1
    except (UsageError, SceneError, RecordingError, ValueError) as exc:
        print(f"rig: error: {_plain(exc)}", file=sys.stderr)
        return 2
    except BrokenPipeError:                 # `rig … | head`: the reader has what it wanted; no error to report
        _stdout_to_devnull()
        return 141
    except OSError as exc:
        print(f"rig: error: {_plain(exc)}", file=sys.stderr)
        return 1


def _stdout_to_devnull() -> None:
    """Point stdout at /dev/null, so that the interpreter's last flush into the closed pipe says nothing."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):      # not a file (a test's capture)
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, fd)
    os.close(devnull)


def main(argv: list[str] | None = None) -> int:
    """The ``rig`` command; Ctrl-C anywhere (imports included) ends it with one line and status 130."""
    try:
        return _run(argv)
    except KeyboardInterrupt as exc:
        line = _interrupted(exc)
        if line:
            print(line, file=sys.stderr)
        return 130


def entry() -> None:
    """The ``rig`` console script: :func:`main`, then the exit handlers (atexit: logging, executors), the output
    streams flushed, and out without the interpreter's teardown of every imported module — numpy, scipy, numba,
    matplotlib, python-can and the rig take 0.5–0.9 s to tear down, nothing of which a finished command needs (every
    file the rig writes is closed by then: the recorder closes its file, the rest write through ``with``)."""
    code = main()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):        # a closed pipe (`rig ... | head`): nothing more can be said
            pass
    os._exit(code)


if __name__ == "__main__":       # python -m rig.cli: as the console script, SIGTERM a stop that closes the recording
    from rig.stops import stop_on_signals       # (it killed the run outright, leaving a cut file; an audit)
    stop_on_signals()
    entry()

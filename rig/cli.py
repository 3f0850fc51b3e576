"""The ``rig`` command: run, serve, record and report scenes; print plant summaries.

``rig`` alone runs the demo: the pin-insertion scene end to end with its embedded defaults.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

DATA = Path(__file__).resolve().parents[1] / "data"
DEFAULT_SCENE = DATA / "scenes" / "pin_insertion.toml"


def _print_cam_bar_summary(scene_path: Path, png: Path) -> None:
    from rig.plants.cam_bar.summary import plot_cycle, summary_table
    from rig.runner.plants import make_plant
    from rig.scene import load_scene
    mech = make_plant("cam_bar", load_scene(scene_path))
    print(summary_table(mech))
    png.parent.mkdir(parents=True, exist_ok=True)
    plot_cycle(mech, png)
    print(f"cycle chart: {png}")


def _analysed(recording: Path) -> tuple[Any, dict]:
    """Read a recording once and analyse it: (Recording, :func:`rig.analysis.analyse` result)."""
    from rig.analysis import analyse
    from rig.recorder import read_recording
    rec = read_recording(recording)
    return rec, analyse(rec)


def _print_values(st: dict) -> None:
    """Table of one program's process values: n, unit, mean, σ, min, max, ±3σ band, Cp/Cpk, checks."""
    print(f"  {'process value':>16} {'n':>4} {'unit':>4}  {'mean':>10} {'sigma':>9} {'min':>10} {'max':>10}  "
          f"{'-3s..+3s':>21}  Cp    Cpk   normal drift")
    for name, pv in st.get("values", {}).items():
        cap = (f"{pv['cp']:5.2f} {pv['cpk']:5.2f}" if pv.get("cp") is not None and pv.get("cpk") is not None
               else "  -     -  ")
        print(f"  {name:>16} {pv['n']:4d} {pv.get('unit', ''):>4}  {pv['mean']:10.4g} {pv['std']:9.3g} "
              f"{pv['min']:10.4g} {pv['max']:10.4g}  {pv['minus_3sigma']:10.4g}..{pv['plus_3sigma']:<10.4g} {cap}  "
              f"{str(pv['normality'].get('normal', '-')):6} {pv['trend'].get('drift', '-')}")


def _print_set_summary(result: dict) -> None:
    """Console summary of an analysis: verdict counts, incomplete results, per-program warnings, the
    process-value table and the comparison with the device's statistics, theory lag, events."""
    from rig.analysis.device import agreement_text
    verdicts = result["verdicts"]
    nok = [v for v in verdicts if not v["ok"]]
    print(f"curves: {len(verdicts)}, OK {len(verdicts) - len(nok)}, NOK {len(nok)}")
    incomplete = result["incomplete"]
    if incomplete:
        print(f"  warning: {len(incomplete)} incomplete result(s): " + "; ".join(
            f"curve {r['number']} missing {', '.join(r['missing']) or '(unnamed values)'}" for r in incomplete))
    for program, st in result["sets"].items():
        for warning in st.get("warnings", []):
            print(f"  warning (program {program}): {warning}")
        print(f"  program {program}: {st['n']} curves, NOK by element {st['nok_by_element'] or 'none'}")
        _print_values(st)
        print(f"  device statistics (program {program}): {agreement_text(st['device_agreement'])}")
    lags = [row for row in result["theory"] if row.get("lag_time") is not None]
    if lags:
        lt = sum(r["lag_time"] for r in lags) / len(lags)
        la = sum(r.get("lag_angle", 0.0) for r in lags) / len(lags)
        print(f"  theory vs measurement: mean lag {lt * 1e3:.1f} ms = {la * 180 / 3.141592653589793:.1f} deg cam")
    if result["events"]:
        print("  events: " + ", ".join(f"{k} {v}" for k, v in sorted(result["events"].items())))


def _print_stand_summary(rec: Any) -> bool:
    """Console summary of a clutch-stand run (dynamic stand or static rig, no curves): its key results,
    each with what it is relative to. False (nothing printed) for other recordings."""
    if rec.curves:
        return False
    from rig.analysis.clutch_report import summary_lines
    from rig.analysis.static_clutch_report import summary_lines as static_lines
    lines = summary_lines(rec) or static_lines(rec)
    if lines:
        print("\n".join(lines))
    return bool(lines)


def _report(recording: Any, out_dir: Path, fmt: str, analysis: dict | None = None) -> Path:
    """Write the report of a recording (path or an already-read Recording, with its analysis if known)."""
    from rig.analysis.report import write_report
    return write_report(recording, out_dir, fmt=fmt, analysis=analysis)


def cmd_run(args: argparse.Namespace) -> int:
    from rig.runner import run_scene
    from rig.runner.config import read_config
    from rig.scene import load_scene
    scene = Path(args.scene)
    out = Path(args.output) if args.output else Path("out") / f"{scene.stem}.mcap"
    if read_config(load_scene(scene)).plant == "cam_bar":
        _print_cam_bar_summary(scene, out.with_suffix(".cycle.png"))
    summary = run_scene(scene, out, cycles=args.cycles, mode="realtime" if args.realtime else None,
                        progress=not args.quiet)
    print(f"recorded {summary.curves} curves, {summary.simulated_time:.2f} s simulated in {summary.run_time:.2f} s "
          f"({summary.realtime_factor:.1f}x real time; {summary.wall_time:.2f} s with serial set-up and read-back), "
          f"{summary.frames} CAN frames -> {summary.output}")
    rec, analysis = _analysed(summary.output)
    if not _print_stand_summary(rec):
        _print_set_summary(analysis)
    if not args.no_report:
        report = _report(rec, Path(args.report_dir) if args.report_dir else out.with_suffix(""), args.format, analysis)
        print(f"report: {report}")
    return 0


def cmd_serve(args: argparse.Namespace) -> int:
    from rig.runner import serve_scene

    def announce(endpoints: dict[str, Any]) -> None:
        print(json.dumps(endpoints), flush=True)
        if args.endpoints:
            Path(args.endpoints).write_text(json.dumps(endpoints))

    machine = serve_scene(args.scene, mode="realtime" if args.realtime else None, port=args.port, wait=args.wait,
                          cycles=args.cycles, release_timeout=args.release_timeout, announce=announce,
                          progress=not args.quiet)
    print(f"served {machine.curves} curves, {machine.t:.2f} s simulated", file=sys.stderr)
    return 0


def cmd_record(args: argparse.Namespace) -> int:
    from rig.runner import record_scene
    summary = record_scene(args.scene, args.output, can_host=args.can_host, can_port=args.can_port,
                           serial_port=args.serial, can_channel=args.can_channel, cycles=args.cycles,
                           progress=not args.quiet)
    print(f"recorded {summary.curves} curves, {summary.simulated_time:.2f} s simulated -> {summary.output}")
    _print_set_summary(_analysed(summary.output)[1])
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from rig.recorder import RecordingError, read_recording
    from rig.recorder.completeness import losses
    path = Path(args.recording)
    out = Path(args.output) if args.output else path.with_suffix("")
    try:
        rec = read_recording(path, allow_partial=args.partial)
    except RecordingError as exc:
        if exc.partial is None:
            raise
        raise RecordingError(f"{path}: truncated or corrupt recording ({'; '.join(exc.partial.problems)}); "
                             f"`rig report --partial {path}` reports what it holds") from None
    if not rec.complete:
        print(f"{path}: incomplete recording; " + "; ".join(losses(rec)))
    print(f"report: {_report(rec, out, args.format)}")
    return 0


def cmd_export_can(args: argparse.Namespace) -> int:
    from datetime import datetime, timezone
    from rig.recorder.export_can import export_can
    e = export_can(args.recording, args.output)
    start = datetime.fromtimestamp(e.start, timezone.utc).isoformat() if e.start else "unknown (1970-01-01)"
    print(f"exported {e.frames} CAN frames ({e.error_frames} error frames) on {len(e.channels) or 1} channel(s), "
          f"simulation time {e.t_first:.6f}..{e.t_last:.6f} s, trace start {start} -> {e.path}")
    return 0


def cmd_summary(args: argparse.Namespace) -> int:
    scene = Path(args.scene)
    _print_cam_bar_summary(scene, Path(args.png) if args.png else Path("out") / f"{scene.stem}.cycle.png")
    return 0


def cmd_tolerance(args: argparse.Namespace) -> int:
    from rig.plants.cam_bar.tolerance import load_tolerances
    from rig.plants.cam_bar.tolerance_report import plot_study, run_study, study_table
    from rig.runner.config import read_config
    from rig.runner.plants import make_plant
    from rig.scene import SceneError, load_scene
    scene_path = Path(args.scene)
    cfg = read_config(load_scene(scene_path))
    if cfg.plant != "cam_bar":
        raise SceneError(f"{scene_path} [scene]: tolerance analysis needs plant \"cam_bar\", not {cfg.plant!r}")
    study = run_study(make_plant("cam_bar", cfg.scene), load_tolerances(), args.samples, cfg.seed, args.workers)
    print(study_table(study))
    print(f"chart: {plot_study(study, Path(args.output) / f'{scene_path.stem}.tolerance.png')}")
    return 0


def cmd_studies(args: argparse.Namespace) -> int:
    from rig.plants.clutch.studies import plot_parameter_studies, write_peak_table
    out = Path(args.output)
    for path in plot_parameter_studies(out) + [write_peak_table(out)]:
        print(path)
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="rig", description="Virtual test rig for mechanism experiments. "
                                "Without a command: run the pin-insertion demo scene.")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    sub = p.add_subparsers(dest="command")
    run = sub.add_parser("run", help="run a scene in one process (machine + host) and record it to MCAP")
    run.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE))
    run.add_argument("-o", "--output", help="recording path (default out/<scene>.mcap)")
    run.add_argument("--cycles", type=int, help="override the scene's number of cycles")
    run.add_argument("--realtime", action="store_true", help="pace to the wall clock")
    run.add_argument("--report-dir", help="report directory (default: next to the recording)")
    run.add_argument("--format", choices=("html", "md"), default="html")
    run.add_argument("--no-report", action="store_true")
    run.set_defaults(func=cmd_run)
    serve = sub.add_parser("serve", help="run the simulated machine: CAN over socketcand, serial on a pty")
    serve.add_argument("scene")
    serve.add_argument("--port", type=int, help="socketcand TCP port (default: the scene's, 0 = any)")
    serve.add_argument("--realtime", action="store_true")
    serve.add_argument("--wait", type=float, default=300.0, help="seconds to wait for a host to arm the device")
    serve.add_argument("--cycles", type=int, help="override the scene's number of cycles")
    serve.add_argument("--release-timeout", type=float, default=300.0,
                       help="seconds to wait after the run for the host to release the device (CAN Release)")
    serve.add_argument("--endpoints", help="also write the endpoints JSON to this file")
    serve.set_defaults(func=cmd_serve)
    rec = sub.add_parser("record", help="the host: connect to `rig serve` and record the run")
    rec.add_argument("scene")
    rec.add_argument("-o", "--output", required=True)
    rec.add_argument("--can-host", default="127.0.0.1")
    rec.add_argument("--can-port", type=int, required=True)
    rec.add_argument("--can-channel")
    rec.add_argument("--serial", help="serial port path or URL printed by `rig serve`")
    rec.add_argument("--cycles", type=int, help="record only the first N curves")
    rec.set_defaults(func=cmd_record)
    rep = sub.add_parser("report", help="write an HTML/Markdown report with plots and CSV from a recording")
    rep.add_argument("recording")
    rep.add_argument("-o", "--output", help="report directory")
    rep.add_argument("--format", choices=("html", "md"), default="html")
    rep.add_argument("--partial", action="store_true",
                     help="report what a truncated recording (a killed run) holds and what was lost")
    rep.set_defaults(func=cmd_report)
    exp = sub.add_parser("export-can", help="write the recording's CAN bus traffic (/can/raw) as a CAN trace: "
                         ".asc, .blf, .log (candump), .trc or .mf4 by extension")
    exp.add_argument("recording")
    exp.add_argument("-o", "--output", required=True, help="trace file; its extension picks the format")
    exp.set_defaults(func=cmd_export_can)
    summ = sub.add_parser("summary", help="cam-bar kinematics/kinetostatics table and cycle chart")
    summ.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE))
    summ.add_argument("--png")
    summ.set_defaults(func=cmd_summary)
    tol = sub.add_parser("tolerance", help="cam-bar linear and Monte-Carlo tolerance analysis (table + PNG)")
    tol.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE))
    tol.add_argument("--samples", type=int, default=20000, help="Monte-Carlo machines (default 20000)")
    tol.add_argument("--workers", type=int, default=1, help="worker processes (results do not depend on it)")
    tol.add_argument("-o", "--output", default="out", help="directory of the chart (default out)")
    tol.set_defaults(func=cmd_tolerance)
    stud = sub.add_parser("studies", help="clutch static-characteristic parameter studies (PNG)")
    stud.add_argument("-o", "--output", default="out/studies")
    stud.set_defaults(func=cmd_studies)
    return p


def _interrupted(exc: KeyboardInterrupt) -> str:
    """One line on Ctrl-C: what a recorded run left (rig.runner.session.Interrupted), else nothing claimed."""
    if not hasattr(exc, "recording"):
        return "rig: interrupted"
    recording = getattr(exc, "recording")
    if recording is None:
        return "rig: interrupted before anything was recorded; no recording was written"
    return f"rig: interrupted; what was recorded so far is in {recording} (marked interrupted)"


def _run(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    if args.command is None:
        args = build_parser().parse_args(["-q", "run"] if args.quiet else ["run"])
    from rig.recorder import RecordingError
    from rig.runner.session import RunError
    from rig.scene import SceneError
    try:
        return args.func(args)
    except (SceneError, RunError, RecordingError, ValueError, OSError) as exc:
        print(f"rig: error: {exc}", file=sys.stderr)
        return 2


def main(argv: list[str] | None = None) -> int:
    """The ``rig`` command; Ctrl-C anywhere (imports included) ends it with one line and status 130."""
    try:
        return _run(argv)
    except KeyboardInterrupt as exc:
        print(_interrupted(exc), file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())

"""Recordings cut short: a run killed with SIGKILL reports with `rig report --partial` (and says what was
lost), plain `rig report` names the problem in one line; an interrupted run is marked in its recording
and its report; Ctrl-C before anything was recorded leaves no file; Ctrl-C during imports, no traceback."""
from __future__ import annotations

import builtins
import os
import re
import logging
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rig.cli import main
from rig.recorder import read_recording

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "data" / "scenes" / "pin_insertion.toml"


def _wait_for_4_mb(run: subprocess.Popen, out: Path) -> None:
    """Until the child run has written 4 MB of its recording (a whole chunk and more), within 120 s."""
    deadline = time.monotonic() + 120
    while not out.exists() or out.stat().st_size < 4_000_000:
        assert run.poll() is None, run.stderr.read()
        assert time.monotonic() < deadline, "the run did not write 4 MB in 120 s"
        time.sleep(0.05)

def test_a_run_killed_halfway_reports_with_partial(tmp_path, capsys):
    out = tmp_path / "killed.mcap"
    run = subprocess.Popen([sys.executable, "-m", "rig.cli", "-q", "run", str(SCENE), "--cycles", "200", "-o", str(out),
                            "--no-report"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        _wait_for_4_mb(run, out)
        os.kill(run.pid, signal.SIGKILL)
    finally:
        run.kill()
        run.wait()
    assert main(["report", str(out), "--format", "md"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "killed.mcap: truncated" in err and f"rig report --partial {out}" in err

    assert main(["report", "--partial", str(out), "-o", str(tmp_path / "report"), "--format", "md"]) == 0
    said = capsys.readouterr().out
    rec = read_recording(out, allow_partial=True)
    assert rec.truncated and 5 <= len(rec.curves) < 200
    assert "incomplete recording" in said and re.search(r"file ends (\d+ bytes into a record|after a whole record)", said)
    assert f"{len(rec.curves)} of 200 requested curves recorded" in said
    assert "no device statistics recorded" in said
    report = (tmp_path / "report" / "report.md").read_text()
    assert "no: file truncated" in report and f"{len(rec.curves)} of 200 requested curves" in report
    assert "the device sent no statistics" not in report and (                 # it did not end: none were read
        "the host reads the device's statistics at the end of a run, and this one did not end normally") in report
    assert report.index("Warning: incomplete recording, file truncated") < report.index("**OK: all") if "**OK: all" \
        in report else report.index("Warning: incomplete recording") < report.index("**NOK")   # before the verdict
    assert report.count("| OK |") + report.count("| NOK |") == len(rec.results)      # what it holds, reported
    with_result = {r["number"] for r in rec.results}
    unjudged = [c.number for c in rec.curves if c.number not in with_result]
    assert ("without a result, not judged (curve " + ", ".join(map(str, unjudged[:10]))) in report if unjudged \
        else "not judged" not in report
    oks = sum(bool(r["ok"]) for r in rec.results if r["number"] in {c.number for c in rec.curves})
    assert f"Individual plots of OK curves: 0 of {oks}" in report                    # a curve without result is not OK


@pytest.mark.parametrize("keep", [8, 3000])
def test_partial_report_of_a_recording_cut_before_its_first_message_is_an_error(tmp_path, capsys, keep):
    """Cut before any message (after the magic; inside the first chunk): nothing to report is said in one line,
    exit 2, and no report directory is left behind — not an empty report that looks like a result."""
    whole = tmp_path / "whole.mcap"
    assert main(["-q", "run", str(SCENE), "--cycles", "1", "-o", str(whole), "--no-report"]) == 0
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(whole.read_bytes()[:keep])
    capsys.readouterr()
    assert main(["report", "--partial", str(cut), "-o", str(tmp_path / "report")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cut.mcap: nothing to report, the recording holds no message: file ends" in err
    assert not (tmp_path / "report").exists()


def test_an_interrupted_run_is_marked_and_its_report_says_so(tmp_path, monkeypatch, capsys):
    from rig.runner import host as host_module
    original = host_module.Host.poll

    def poll(self, timeout: float = 0.0) -> int:
        if self.curves_recorded >= 1:      # Ctrl-C after the first curve
            raise KeyboardInterrupt
        return original(self, timeout)

    monkeypatch.setattr(host_module.Host, "poll", poll)
    out = tmp_path / "stopped.mcap"
    assert main(["-q", "run", str(SCENE), "--cycles", "3", "-o", str(out), "--no-report"]) == 130
    line = capsys.readouterr().err.splitlines()[-1]
    rec = read_recording(out)
    assert line == (f"rig: interrupted; what was recorded so far (1 curve, {rec.last_time:.2f} s of simulation time) "
                    f"is in {out} (marked interrupted)")
    assert not rec.truncated and not rec.complete and rec.interrupted == "KeyboardInterrupt"
    assert rec.events[-1]["kind"] == "interrupted" and len(rec.curves) == 1
    assert main(["report", str(out), "-o", str(tmp_path / "report"), "--format", "md"]) == 0
    assert "incomplete recording" in capsys.readouterr().out
    report = (tmp_path / "report" / "report.md").read_text()
    assert "| complete | no: interrupted by the user (Ctrl-C) |" in report      # no exception name, no "))"
    assert "Warning: incomplete recording, interrupted by the user (Ctrl-C): the verdict covers" in report
    assert "| interrupted by the user (Ctrl-C) at " in report and "KeyboardInterrupt" not in report
    assert "1 of 3 requested curves recorded" in report


def test_ctrl_c_during_a_curve_transfer_says_what_it_cut(tmp_path, monkeypatch):
    """Ctrl-C while a curve is on its way: the recording keeps every curve received whole, the cut one is an
    `incomplete_curve` event naming the interruption (it used to vanish without a word), and the last
    `live_dropped` report carries the device's last count."""
    from rig.runner import host as host_module
    from rig.runner import run_scene
    original = host_module.Host.poll
    fired = []

    def poll(self, timeout: float = 0.0) -> int:
        n = original(self, timeout)
        if not fired and self.curves_recorded >= 2 and self.can.assembler.in_transfer:
            fired.append(self.can.counters.get("live_dropped"))
            raise KeyboardInterrupt
        return n

    monkeypatch.setattr(host_module.Host, "poll", poll)
    out = tmp_path / "cut.mcap"
    with pytest.raises(KeyboardInterrupt):
        run_scene(SCENE, out, cycles=10)
    rec = read_recording(out)
    cut = [e for e in rec.events if e["kind"] == "incomplete_curve"]
    assert fired and len(cut) == 1 and "cut by the interruption of the run" in " ".join(cut[0]["problems"])
    assert cut[0]["number"] == len(rec.curves) + 1 and [c.number for c in rec.curves] == list(range(1, len(rec.curves) + 1))
    drops = [e for e in rec.events if e["kind"] == "live_dropped"]
    assert drops and drops[-1]["total"] >= fired[0]


def test_ctrl_c_before_anything_was_recorded_leaves_no_file(tmp_path, monkeypatch, capsys):
    from rig.runner import host as host_module

    def arm(self) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(host_module.Host, "arm", arm)
    out = tmp_path / "never.mcap"
    assert main(["-q", "run", str(SCENE), "--cycles", "3", "-o", str(out), "--no-report"]) == 130
    assert capsys.readouterr().err.splitlines()[-1] == ("rig: interrupted before anything was recorded; "
                                                        "no recording was written")
    assert not out.exists()


def test_ctrl_c_before_anything_was_recorded_keeps_the_earlier_recording(tmp_path, monkeypatch, capsys):
    """Re-running onto an existing recording and stopping before the first message leaves the earlier file as it
    was (it is moved aside while the run starts, put back when nothing was recorded, and removed once the new run
    has recorded); a run that records replaces it and leaves nothing aside."""
    from rig.runner import host as host_module
    out = tmp_path / "run.mcap"
    assert main(["-q", "run", str(SCENE), "--cycles", "1", "-o", str(out), "--no-report"]) == 0
    earlier = out.read_bytes()
    real_arm = host_module.Host.arm

    def arm(self) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(host_module.Host, "arm", arm)
    assert main(["-q", "run", str(SCENE), "--cycles", "2", "-o", str(out), "--no-report"]) == 130
    assert capsys.readouterr().err.splitlines()[-1] == (
        "rig: interrupted before anything was recorded; no recording was written "
        f"(the earlier recording at {out} is kept as it was)")
    assert out.read_bytes() == earlier and not [p.name for p in tmp_path.iterdir() if ".earlier" in p.name]
    monkeypatch.setattr(host_module.Host, "arm", real_arm)
    assert main(["-q", "run", str(SCENE), "--cycles", "2", "-o", str(out), "--no-report"]) == 0
    assert len(read_recording(out).curves) == 2 and not [p.name for p in tmp_path.iterdir() if ".earlier" in p.name]


def test_ctrl_c_during_imports_prints_one_line(tmp_path, monkeypatch, capsys):
    real_import = builtins.__import__

    def interrupted_import(name, *args, **kwargs):
        if name.startswith("rig.recorder"):
            raise KeyboardInterrupt
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", interrupted_import)
    assert main(["report", str(tmp_path / "any.mcap")]) == 130
    assert capsys.readouterr().err == "rig: interrupted\n"


@pytest.mark.parametrize("args", [["report", "missing.mcap"], ["report", "--partial", "missing.mcap"]])
def test_a_missing_recording_is_a_one_line_error(tmp_path, capsys, args):
    assert main([*args[:-1], str(tmp_path / args[-1])]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "missing.mcap" in err


@pytest.mark.parametrize("args", [["report", "missing.mcap"], ["export-can", "missing.mcap", "-o", "missing/f"]])
def test_a_missing_recording_is_named_before_an_output_in_the_way(tmp_path, capsys, monkeypatch, args):
    """The default report directory (the recording's name) and the trace both hold a file rig did not write: the
    error is about the missing recording, the real problem, not about the output."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "missing").mkdir()
    (tmp_path / "missing" / "f").write_text("not rig's")
    assert main(args) == 2
    assert capsys.readouterr().err == "rig: error: cannot read recording missing.mcap: no such file or directory\n"


@pytest.mark.parametrize("start", [["-c", "from rig.launch import entry; entry()"], ["-m", "rig.cli"]])
def test_sigterm_stops_the_console_script_as_ctrl_c_does(tmp_path, start):
    """``timeout``, ``docker stop``, systemd send SIGTERM: the run stops between steps and the recording is closed,
    marked interrupted, every curve once (it was cut like a SIGKILL, exit 143 and no word) — also when started as
    ``python -m rig.cli`` (which skipped the console script's handler: killed outright, a cut file; an audit)."""
    out = tmp_path / "terminated.mcap"
    run = subprocess.Popen([sys.executable, *start, "-q", "run", str(SCENE),
                            "--cycles", "400", "-o", str(out), "--no-report"], stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        _wait_for_4_mb(run, out)
        run.send_signal(signal.SIGTERM)
        err = run.communicate(timeout=120)[1]
    finally:
        run.kill()
        run.wait()
    assert run.returncode == 130 and "Traceback" not in err
    rec = read_recording(out)
    numbers = [c.number for c in rec.curves]
    assert rec.interrupted == "Terminated: SIGTERM" and not rec.truncated
    assert numbers == list(range(1, len(numbers) + 1))
    assert f"rig: terminated (SIGTERM); what was recorded so far ({len(numbers)} curves," in err
    assert "terminated by SIGTERM" in " ".join(rec.problems)             # the report's words (Ctrl-C's were used)

def test_the_console_script_takes_ctrl_c_before_it_imports_the_command_line():
    """The console script's module sets its Ctrl-C handler before rig.cli and its imports load: an interrupt while
    they load is one line and status 130 (checked in a child interpreter, the interrupt raised from the import of
    rig.cli itself, deterministically)."""
    code = ("import builtins, os, signal\n"
            "real = builtins.__import__\n"
            "def hook(name, *a, **k):\n"
            "    if name == 'rig.cli':\n"
            "        os.kill(os.getpid(), signal.SIGINT)\n"
            "    return real(name, *a, **k)\n"
            "builtins.__import__ = hook\n"
            "from rig.launch import entry\n"
            "entry()\n")
    done = subprocess.run([sys.executable, "-c", code, "report", "none.mcap"], capture_output=True, text=True,
                          timeout=120, cwd=ROOT)
    assert done.returncode == 130 and done.stderr == "rig: interrupted\n", done.stderr
    import tomllib
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["rig"] == "rig.launch:entry"


def test_worker_processes_spawned_from_the_console_script_leave_ctrl_c_to_their_parent():
    """Dask's worker processes (multiprocessing spawn) run the console script again as ``__mp_main__``: there a Ctrl-C
    at the terminal is ignored (the parent prints its one line and closes them; each worker once printed "rig:
    interrupted", then a traceback), and the tasks the parent cancels are no news. Checked in child interpreters."""
    code = ("import logging, signal, sys, types\n"
            "{setup}"
            "import rig.launch\n"
            "print(signal.getsignal(signal.SIGINT) is signal.SIG_IGN,\n"
            "      logging.getLogger('distributed.worker.state_machine').level)\n")
    worker = subprocess.run([sys.executable, "-c", code.format(setup="sys.modules['__mp_main__'] = "
                                                                     "types.ModuleType('__mp_main__')\n")],
                            capture_output=True, text=True, timeout=120, cwd=ROOT)
    parent = subprocess.run([sys.executable, "-c", code.format(setup="")], capture_output=True, text=True,
                            timeout=120, cwd=ROOT)
    assert worker.stdout.split() == ["True", str(logging.ERROR)], worker.stderr
    assert parent.stdout.split() == ["False", "0"], parent.stderr


def test_a_worker_process_spawned_from_python_m_rig_cli_ignores_ctrl_c_too():
    """`python -m rig.cli sweep … --workers 2` and Ctrl-C: the Dask worker processes, spawned with rig.cli as their
    __mp_main__ (not the console script, which imports rig.launch), printed the cancelled tasks' notices in Dask's raw
    format after the sweep's line (found with an audit's `python -c` wrapper, which no spawned worker can re-run)."""
    code = ("import logging, runpy, signal, sys, types\n"
            "sys.modules['__mp_main__'] = types.ModuleType('__mp_main__')   # as multiprocessing's spawn does\n"
            "runpy.run_module('rig.cli', run_name='__mp_main__', alter_sys=True)\n"
            "print(signal.getsignal(signal.SIGINT) is signal.SIG_IGN,\n"
            "      logging.getLogger('distributed.worker.state_machine').level)\n")
    worker = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert worker.stdout.split() == ["True", str(logging.ERROR)], worker.stderr


def test_a_directory_given_as_the_recording_is_named_as_such(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    assert capsys.readouterr().err == f"rig: error: cannot read recording {tmp_path}: is a directory\n"


def test_why_a_run_stopped_in_plain_words():
    from rig.recorder.reader import interruption_text
    assert interruption_text("KeyboardInterrupt") == "interrupted by the user (Ctrl-C)"
    assert interruption_text("RunError: no host connected") == "stopped by an error — RunError: no host connected"
    assert interruption_text("unknown reason") == "stopped early (the recording does not say why)"


def test_ctrl_c_while_writing_the_report_says_the_recording_is_whole(tmp_path, monkeypatch, capsys):
    """Ctrl-C in the report phase printed only "rig: interrupted": the recording is complete, and the line says so
    and how to write the report."""
    import rig.analysis.report as report_module
    from rig.recorder.completeness import losses

    def cut(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(report_module, "write_report", cut)
    out = tmp_path / "whole.mcap"
    assert main(["-q", "run", str(SCENE), "--cycles", "2", "-o", str(out)]) == 130
    line = capsys.readouterr().err.splitlines()[-1]
    assert line == (f"rig: interrupted while summarising the run or writing its report; the recording {out} is "
                    f"complete: `rig report {out} -o {out.with_suffix('')}` writes the report")
    rec = read_recording(out)
    assert rec.complete and losses(rec) == []


def test_ctrl_c_while_summarising_a_run_without_report_says_the_recording_is_whole(tmp_path, monkeypatch, capsys):
    """Ctrl-C after the run, during the console summary of `--no-report`: it printed a bare "rig: interrupted"."""
    import rig.cli as cli_module

    def cut(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(cli_module, "_print_set_summary", cut)
    out = tmp_path / "whole.mcap"
    assert main(["-q", "run", str(SCENE), "--cycles", "2", "-o", str(out), "--no-report"]) == 130
    line = capsys.readouterr().err.splitlines()[-1]
    assert line == (f"rig: interrupted while summarising the run; the recording {out} is complete: `rig report {out}` "
                    f"writes its report")
    assert read_recording(out).complete


def test_a_sigterm_stop_is_told_apart_through_the_exceptions_raised_from_it():
    """rig.stops: a Terminated (or a stop raised from one, as the runner's Interrupted is) reads "terminated
    (SIGTERM)", a Ctrl-C "interrupted"; a Terminated survives pickle and copy (a worker's exception travels)."""
    import copy
    import pickle
    from rig.runner.session import Interrupted
    from rig.stops import Terminated, stopped
    try:
        try:
            raise Terminated
        except KeyboardInterrupt as exc:
            raise Interrupted(None) from exc
    except KeyboardInterrupt as exc:
        assert stopped(exc) == "terminated (SIGTERM)" and stopped(exc.__cause__) == "terminated (SIGTERM)"
    assert stopped(KeyboardInterrupt()) == stopped(Interrupted(None)) == "interrupted"
    for twin in (pickle.loads(pickle.dumps(Terminated())), copy.copy(Terminated())):
        assert isinstance(twin, Terminated) and str(twin) == "SIGTERM"


def test_a_cut_lab_recording_does_not_miss_device_statistics_it_never_had(tmp_path):
    """A lab or a stand has its serial link off and reads no statistics: its cut recording said "no device statistics
    recorded (the host reads them at the end of a run)", a loss that is none (an audit)."""
    from rig.recorder.completeness import losses
    from rig.runner import run_scene
    out = run_scene(ROOT / "data" / "scenes" / "lab_speed.toml", tmp_path / "lab.mcap").output
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(out.read_bytes()[:int(out.stat().st_size * 0.7)])
    rec = read_recording(cut, allow_partial=True)
    said = losses(rec)
    assert rec.truncated and said and not any("device statistics" in line for line in said)

"""Feedback on long work and no log floods (issue 12): rig's stderr set-up, the run's progress bar, the
real-time pacer's warnings, the numba compilation notice, report/tolerance progress and bootstrap."""
from __future__ import annotations

import importlib.util
import logging
import os
import subprocess
import sys
import textwrap
import threading
import queue
from pathlib import Path

import pytest

from rig import cli, console
from rig.runner import session

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "data" / "scenes" / "pin_insertion.toml"
CLUTCH = ROOT / "data" / "scenes" / "clutch_startup.toml"


@pytest.fixture
def rig_console():
    """:func:`rig.console.configure` for one test, its handler removed afterwards."""
    console.configure()
    yield
    root = logging.getLogger()
    for handler in [h for h in root.handlers if isinstance(h, console._Handler)]:
        root.removeHandler(handler)
    console.log.setLevel(logging.NOTSET)


# -- logging -----------------------------------------------------------------------------------------
def test_known_harmless_library_messages_are_dropped_others_are_one_line(rig_console, capsys):
    can_log = logging.getLogger("can.interfaces.socketcand.socketcand")
    for _ in range(1000):
        can_log.warning("Got incomplete message => waiting for more data")
        can_log.warning("Failed to connect to server: <class 'ConnectionRefusedError'> Message: [Errno 111]")
    can_log.warning("Invalid Frame: < frame zz >\nsecond line")
    logging.getLogger("rig.test").info("a notice")
    logging.getLogger("rig.test").warning("a warning")
    err = capsys.readouterr().err.splitlines()
    assert err == ["rig: can.interfaces.socketcand.socketcand: warning: Invalid Frame: < frame zz >",
                   "rig: a notice", "rig: warning: a warning"]


def test_quiet_keeps_warnings_and_drops_notices(capsys):
    console.configure(quiet=True)
    try:
        logging.getLogger("rig.test").info("a notice")
        logging.getLogger("rig.test").warning("a warning")
        assert capsys.readouterr().err == "rig: warning: a warning\n"
    finally:
        console.configure(quiet=False)
        logging.getLogger().removeHandler(next(h for h in logging.getLogger().handlers
                                               if isinstance(h, console._Handler)))


def test_python_warnings_become_one_line(rig_console, capsys):
    import warnings
    warnings.showwarning(UserWarning("the problem is stiff\n  at t = 1 s"), UserWarning, "x.py", 1)
    assert capsys.readouterr().err == "rig: warning: UserWarning: the problem is stiff at t = 1 s\n"


def test_a_served_run_records_without_python_can_warnings(tmp_path, caplog):
    """The socketcand client splits lines across TCP reads all the time: none of that reaches a handler."""
    announced: queue.Queue = queue.Queue()
    server = threading.Thread(target=session.serve_scene, args=(DEMO,), kwargs=dict(
        cycles=2, port=0, wait=60, release_timeout=60, announce=announced.put), daemon=True)
    server.start()
    ep = announced.get(timeout=60)
    with caplog.at_level(logging.DEBUG, logger="can"):
        summary = session.record_scene(DEMO, tmp_path / "r.mcap", can_port=ep["can"]["port"], serial_port=ep["serial"],
                                       cycles=2, idle_timeout=30)
    server.join(timeout=60)
    assert summary.curves == 2
    noisy = [r for r in caplog.records if r.name.startswith("can") and r.getMessage().startswith(
        console.HARMLESS["can.interfaces.socketcand.socketcand"])]
    assert noisy == []


# -- the run's progress bar ----------------------------------------------------------------------------
def bar_lines(err: str) -> list[str]:
    return [line.strip() for line in err.replace("\r", "\n").splitlines() if line.strip()]


def test_the_run_bar_counts_machine_cycles_and_stays(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)        # as on a terminal: redrawn as the cycles pass
    session.run_scene(DEMO, tmp_path / "x.mcap", cycles=3, progress=True)
    lines = bar_lines(capsys.readouterr().err)
    assert lines[0].startswith("pin_insertion:   0%") and "0/3" in lines[0] and "t = 0.00 s" in lines[0]
    assert any("1/3" in line and "cycles/s" in line for line in lines)
    last = lines[-1]
    assert last.startswith("pin_insertion: 100%") and "3/3" in last and "3 curves recorded" in last
    assert any("reading the device statistics" in line for line in lines)


def test_into_a_log_the_run_bar_writes_few_lines(tmp_path, capsys):
    """stderr a file or a pipe (capsys here, a CI log): each redraw is a line there, so the bar redraws every 10 s, not
    ten times a second — a short run writes its first and last lines and the phases it names, no per-cycle lines."""
    session.run_scene(DEMO, tmp_path / "x.mcap", cycles=3, progress=True)
    lines = bar_lines(capsys.readouterr().err)
    assert lines[0].startswith("pin_insertion:   0%") and lines[-1].startswith("pin_insertion: 100%")
    assert not any("1/3" in line or "2/3" in line for line in lines) and len(lines) <= 6, lines


def test_a_duration_scene_bar_counts_simulated_seconds(tmp_path, capsys):
    session.run_scene(CLUTCH, tmp_path / "c.mcap", progress=True)
    lines = bar_lines(capsys.readouterr().err)
    assert lines[-1].startswith("clutch_startup: 100%") and "0.80/0.80 s simulated" in lines[-1]
    assert "curves" not in lines[-1]


# -- real time ---------------------------------------------------------------------------------------
class FakeClock:
    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds


def test_the_pacer_waits_when_ahead_and_warns_once_when_behind(caplog):
    clock = FakeClock()
    pace = session._Pacer(True, tolerance=0.1, clock=clock, sleep=clock.sleep)
    with caplog.at_level(logging.WARNING, logger="rig"):
        for k in range(1, 11):                 # 10 chunks of 0.1 s: the first 4 computed in 0.05 s, then 0.3 s each
            clock.now += 0.05 if k <= 4 else 0.3
            pace(0.1 * k)
        assert clock.now == pytest.approx(0.4 + 6 * 0.3)
        pace.finish()
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 2
    assert messages[0].startswith("real time: the simulation falls behind the wall clock (0.20 s behind at 0.50 s")
    assert messages[1] == "real time: behind the wall clock by more than 0.1 s in 6 of 10 steps (at most 1.20 s)"


def test_the_pacer_is_silent_when_it_keeps_up_or_is_not_real_time(caplog):
    for realtime, compute in ((True, 0.01), (False, 1.0)):
        clock = FakeClock()
        pace = session._Pacer(realtime, clock=clock, sleep=clock.sleep)
        with caplog.at_level(logging.WARNING, logger="rig"):
            for k in range(1, 6):
                clock.now += compute
                pace(0.1 * k)
            pace.finish()
        assert clock.now == pytest.approx(0.5 if realtime else 5.0)
    assert caplog.records == []


def test_real_time_paces_the_bus_draining_its_backlog_too(tmp_path, monkeypatch):
    """After the last cycle the unit's transmit queue still holds ≈ 0.3 s of frames: in real-time mode they go out
    on the wall clock too (the printed factor of a real-time run read 1.1× because they did not)."""
    from rig.recorder import read_recording
    paced: list[float] = []

    class Recording(session._Pacer):
        def __call__(self, t_sim: float) -> None:
            paced.append(t_sim)

    monkeypatch.setattr(session, "_Pacer", Recording)
    session.run_scene(DEMO, tmp_path / "r.mcap", cycles=1)
    last_frame = float(read_recording(tmp_path / "r.mcap").can_frames["t"][-1])
    assert paced == sorted(paced) and paced[-1] > 0.4 + 0.1          # past the cycle's end: the drain is paced
    assert last_frame - paced[-1] < 0.03                             # up to the last chunk of frames


# -- numba -------------------------------------------------------------------------------------------
PROBE = '''
import sys
from rig import console
console.COMPILED["rigprobe"] = ("the probe kernel", "3 s")
console.configure()
import rigprobe
print(rigprobe.twice(2.0))
'''


def test_the_first_compilation_is_announced_a_cached_one_is_not(tmp_path):
    (tmp_path / "rigprobe.py").write_text(textwrap.dedent('''
        from numba import njit

        @njit(cache=True)
        def twice(x):
            return 2.0 * x
    '''))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}
    runs = [subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env, timeout=120)
            for _ in range(2)]
    assert [r.stdout for r in runs] == ["4.0\n", "4.0\n"], runs
    assert runs[0].stderr == ("rig: compiling the probe kernel with numba: once, about 3 s "
                              "(later runs load it from the cache)\n")
    assert runs[1].stderr == ""


# -- report and tolerance progress ---------------------------------------------------------------------
def test_report_writing_shows_its_sections(tmp_path, capsys):
    rec = tmp_path / "x.mcap"
    session.run_scene(DEMO, rec, cycles=1)
    capsys.readouterr()
    cli._report(rec, tmp_path / "report", "md", progress=True)
    lines = bar_lines(capsys.readouterr().err)
    assert lines[-1].startswith("report: 100%")
    assert len(lines) <= 3, lines          # into a log: not a line per section (the section name forced a redraw)
    cli._report(rec, tmp_path / "report", "md", progress=False)
    assert capsys.readouterr().err == ""


def test_tolerance_shows_the_monte_carlo_machines(capsys):
    from rig.plants.cam_bar.tolerance import load_tolerances
    from rig.plants.cam_bar.tolerance_report import run_study
    from rig.runner.plants import make_plant
    from rig.scene import load_scene
    mech = make_plant("cam_bar", load_scene(DEMO)).mech
    quiet = run_study(mech, load_tolerances(), 300, 1, step_deg=10.0)
    assert capsys.readouterr().err == ""
    shown = run_study(mech, load_tolerances(), 300, 1, step_deg=10.0, progress=True)
    last = bar_lines(capsys.readouterr().err)[-1]
    assert last.startswith("tolerance, 2 runs of 300 machines: 100%") and "600/600" in last and "machine evaluations" in last
    assert (shown.mc.mean == quiet.mc.mean).all()


# -- bootstrap ---------------------------------------------------------------------------------------
@pytest.fixture
def bootstrap(tmp_path, monkeypatch):
    spec = importlib.util.spec_from_file_location("bootstrap_under_test", ROOT / "bootstrap.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    (tmp_path / "pyproject.toml").write_text("[project]\nname = 'x'\n")
    monkeypatch.setattr(module, "ROOT", tmp_path)
    monkeypatch.setattr(module, "VENV", tmp_path / ".venv")
    monkeypatch.setattr(module, "BIN", tmp_path / ".venv" / "bin")
    monkeypatch.setattr(module, "STAMP", tmp_path / ".venv" / ".installed")
    return module


def test_bootstrap_says_what_it_installs_and_lets_pip_show_progress(bootstrap, monkeypatch, capfd):
    calls = []

    class Builder:
        def __init__(self, **kwargs):
            assert kwargs == {"with_pip": True}

        def create(self, path):
            (Path(path) / "bin").mkdir(parents=True)
            (Path(path) / "bin" / "python").write_text("")

    def run(cmd, **kwargs):
        calls.append((cmd, kwargs))
        return subprocess.CompletedProcess(cmd, 0)

    monkeypatch.setattr(bootstrap.venv, "EnvBuilder", Builder)
    monkeypatch.setattr(bootstrap.subprocess, "run", run)
    bootstrap.ensure_environment()
    out, err = capfd.readouterr()
    assert out == ""
    lines = err.splitlines()
    assert lines[0].startswith("bootstrap: creating the virtual environment") and "a few seconds" in lines[0]
    assert lines[1].startswith("bootstrap: installing mechrig") and "1-3 minutes" in lines[1]
    assert lines[2].startswith("bootstrap: environment ready in")
    (cmd, kwargs), = calls
    assert "-q" not in cmd and cmd[-2:] == ["-e", f"{bootstrap.ROOT}[test]"] and "--progress-bar" in cmd
    assert kwargs["stdout"] == sys.stderr.fileno()         # pip's lines on stderr; stdout is the command's
    bootstrap.ensure_environment()                            # up to date: silent
    assert capfd.readouterr() == ("", "") and len(calls) == 1


def test_bootstrap_reports_a_failed_install_in_one_line(bootstrap, monkeypatch):
    (bootstrap.BIN).mkdir(parents=True)
    (bootstrap.BIN / "python").write_text("")
    monkeypatch.setattr(bootstrap.subprocess, "run", lambda cmd, **kw: subprocess.CompletedProcess(cmd, 1))
    with pytest.raises(SystemExit, match=r"bootstrap: pip failed \(exit status 1\)"):
        bootstrap.ensure_environment()
    assert not bootstrap.STAMP.exists()


@pytest.mark.parametrize("command, in_root", [("rig", False), ("pytest", True)])
def test_bootstrap_runs_commands_where_the_user_is_and_the_tests_in_the_project(bootstrap, monkeypatch, tmp_path,
                                                                               command, in_root):
    """`python3 /path/bootstrap.py rig report demo.mcap -o rep` from another directory reads and writes there."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    monkeypatch.setattr(bootstrap, "ensure_environment", lambda: None)
    seen = {}
    monkeypatch.setattr(bootstrap.os, "execvp", lambda exe, argv: seen.update(cwd=Path.cwd(), argv=argv))
    monkeypatch.setattr(sys, "argv", ["bootstrap.py", command, "report", "demo.mcap"])
    bootstrap.main()
    assert seen["cwd"] == (tmp_path if in_root else elsewhere) and seen["argv"][1:] == ["report", "demo.mcap"]


def test_a_run_without_the_serial_link_does_not_speak_of_it(tmp_path, capsys, monkeypatch):
    """lab_cam has [links.serial] enabled = false: no statistics read back, so neither the bar nor the console line
    may say so (they said "reading the device statistics" and "… s with serial set-up and read-back")."""
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    scene = DEMO.with_name("lab_cam.toml")
    assert cli.main(["run", str(scene), "-o", str(tmp_path / "lab.mcap"), "--no-report"]) == 0
    out, err = capsys.readouterr()
    assert "serial set-up" not in out and "set-up and the recording closed" in out
    assert not any("device statistics" in line for line in bar_lines(err))
    assert any("closing the recording" in line for line in bar_lines(err))


def test_statistics_not_read_back_for_a_scene_without_the_serial_link_blame_the_scene_not_the_device(tmp_path, capsys):
    """The demo with [links.serial] enabled = false said "not compared: the device sent no statistics for this
    program" (an audit): it was the scene that switched the read-back off."""
    scene = tmp_path / "noserial.toml"
    scene.write_text(DEMO.read_text().replace("[links.serial]\n", "[links.serial]\nenabled = false\n", 1))
    assert cli.main(["run", str(scene), "-o", str(tmp_path / "n.mcap"), "--cycles", "2", "--no-report"]) == 0
    out = capsys.readouterr().out
    assert ("device statistics (program 1): not compared: the scene's serial link is off ([links.serial] enabled = "
            "false): the host read no statistics back from the device") in out and "device sent no" not in out

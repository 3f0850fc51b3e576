"""`rig run` reads and analyses its recording once for the console summary and the report; `rig report`
works on its own."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import rig.analysis
import rig.analysis.report
import rig.recorder
import rig.runner
from rig import cli
from rig.recorder import Recorder


def small_recording(path):
    with Recorder(path, programs={1: {}}) as rec:
        for k in range(1, 6):
            t = k + np.arange(0.0, 0.1, 1e-3)
            rec.write_curve(k, 1, t, np.linspace(0, 0.04, t.size), 10 * np.sin(20 * (t - k)))
            rec.write_result({"number": k, "program": 1, "ok": True, "elements": [],
                              "process_values": {"y_max": 10.0 + 0.01 * k}}, t=float(t[-1]))
    return path


@pytest.fixture
def counted(monkeypatch):
    """Count every read_recording and analyse call the CLI and the report can make."""
    calls = {"read": 0, "analyse": 0}

    def count(key, f):
        def wrapper(*args, **kwargs):
            calls[key] += 1
            return f(*args, **kwargs)
        return wrapper

    read, analyse = count("read", rig.recorder.read_recording), count("analyse", rig.analysis.analyse)
    for module in (rig.recorder, rig.analysis.report):
        monkeypatch.setattr(module, "read_recording", read)
    for module in (rig.analysis, rig.analysis.report):
        monkeypatch.setattr(module, "analyse", analyse)
    return calls


def test_run_reads_and_analyses_once(tmp_path, monkeypatch, counted, capsys):
    path = small_recording(tmp_path / "run.mcap")
    summary = SimpleNamespace(output=path, curves=5, simulated_time=5.1, run_time=1.0, wall_time=1.2,
                              realtime_factor=5.1, frames=0, compile_time=0.0, flush_time=0.0)
    monkeypatch.setattr(rig.runner, "run_scene", lambda *args, **kwargs: summary)
    monkeypatch.setattr(cli, "_print_cam_bar_summary", lambda *args: None)
    assert cli.main(["-q", "run", "-o", str(path), "--report-dir", str(tmp_path / "report")]) == 0
    assert counted == {"read": 1, "analyse": 1}
    out = capsys.readouterr().out
    assert "curves: 5, OK 5, NOK 0" in out and f"report: {tmp_path / 'report' / 'report.html'}" in out
    assert (tmp_path / "report" / "report.html").exists()


def test_report_command_alone(tmp_path, counted, capsys):
    path = small_recording(tmp_path / "rec.mcap")
    assert cli.main(["report", str(path), "-o", str(tmp_path / "out"), "--format", "md"]) == 0
    assert counted == {"read": 1, "analyse": 1} and (tmp_path / "out" / "report.md").exists()

"""n per process value, results marked incomplete by the recorder, and how analysis, report and console show them."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rig import cli
from rig.analysis import analyse
from rig.analysis.report import write_report
from rig.analysis.sets import counts_warning, process_values, set_statistics
from rig.recorder import Recording

N = 20
PROGRAM = {"channels": {"x": {"unit": "m"}, "y": {"unit": "N"}}, "limits": {"y_min": [-75.0, -55.0]}}


def results() -> list[dict]:
    """N results of program 1; curve 3 lost y_min, curve 8 lost x_end (with a placeholder left in)."""
    rng = np.random.default_rng(4)
    out = []
    for k in range(1, N + 1):
        values = {"y_min": float(rng.normal(-65, 2)), "x_end": float(rng.normal(1e-3, 1e-5)),
                  "duration": float(rng.normal(0.255, 1e-3))}
        r = {"number": k, "program": 1, "ok": True, "elements": [], "process_values": values, "complete": True}
        if k == 3:
            del values["y_min"]
            r.update(complete=False, missing=["y_min"])
        if k == 8:
            values["x_end"] = 0.0                      # placeholder: must not count as a measurement
            r.update(complete=False, missing=["x_end"])
        out.append(r)
    return out


@pytest.fixture
def recording() -> Recording:
    return Recording(path=Path("synthetic.mcap"), programs={1: PROGRAM}, results=results())


def test_every_value_carries_n_and_units():
    s = set_statistics(results(), units={"x": "m", "y": "N"})
    v = s["values"]
    assert (v["y_min"]["n"], v["x_end"]["n"], v["duration"]["n"]) == (N - 1, N - 1, N)
    assert (v["y_min"]["unit"], v["x_end"]["unit"], v["duration"]["unit"]) == ("N", "m", "s")
    good = [r["process_values"]["x_end"] for r in results() if r["number"] != 8]
    assert v["x_end"]["mean"] == pytest.approx(np.mean(good), rel=1e-12)     # placeholder 0.0 left out
    assert "process values have different n: n=20: duration; n=19: x_end, y_min" in s["warnings"]


def test_counts_warning_only_when_n_differ():
    assert counts_warning({"a": 5, "b": 5}) is None
    assert counts_warning({"a": 5, "b": 4, "c": 5}) == "process values have different n: n=5: a, c; n=4: b"


def test_complete_results_and_absent_keys_change_nothing():
    plain = [{k: v for k, v in r.items() if k not in ("complete", "missing")} for r in results()]
    assert process_values(plain)["x_end"][7] == 0.0              # without the mark the placeholder is a value
    assert set_statistics(plain)["incomplete"] == 0


def test_analysis_counts_and_lists_incomplete_results(recording):
    a = analyse(recording)
    assert a["incomplete"] == [{"number": 3, "program": 1, "missing": ["y_min"]},
                               {"number": 8, "program": 1, "missing": ["x_end"]}]
    assert a["sets"][1]["incomplete"] == 2
    v = {r["number"]: r for r in a["verdicts"]}
    assert (v[3]["complete"], v[3]["missing"], v[4]["complete"], v[4]["missing"]) == (False, ["y_min"], True, [])


def test_report_verdict_table_shows_incomplete_results(recording, tmp_path):
    text = write_report(recording, tmp_path, fmt="md").read_text()
    assert "| curve | program | result | failing elements | complete |" in text
    assert "| 3 | 1 | OK |  | no, missing y_min |" in text and "| 8 | 1 | OK |  | no, missing x_end |" in text
    assert "| 4 | 1 | OK |  | yes |" in text
    assert "Warning: 2 incomplete result(s)" in text and "20 curves, 20 OK, 0 NOK, 2 incomplete" in text
    # the verdict's banner says it too (it read "OK: all 20 curves passed" above a table of incomplete results)
    assert "OK: all 20 curves passed (program 1); 2 of them judged by the unit with an incomplete result (curve 3, 8: process " \
           "values missing)" in text


def test_console_summary_warns_and_shows_n(recording, capsys):
    cli._print_set_summary(analyse(recording))
    out = capsys.readouterr().out
    assert "warning: 2 incomplete result(s): curve 3 missing y_min; curve 8 missing x_end" in out
    assert "different n: n=20: duration; n=19: x_end, y_min" in out
    header = next(line for line in out.splitlines() if line.split()[:2] == ["process", "value"])
    assert header.split()[2:4] == ["n", "unit"]
    row = next(line for line in out.splitlines() if line.split()[:1] == ["y_min"])
    assert row.split()[1:3] == ["19", "N"]

"""The host's set statistics against the device's own snapshot: agreement within float32 rounding, and
every kind of mismatch detected (a lost value, a wrong value, a lost result, a wrong OK count)."""
from __future__ import annotations

import copy
from types import SimpleNamespace

import numpy as np
import pytest

from firmware_sim.digiforce.statistics import ProgramStatistics
from rig import cli
from rig.analysis import analyse
from rig.analysis.device import agreement_text, compare_value, device_agreement, final_snapshot
from rig.recorder import Recorder, read_recording

N = 60


def device_and_host(seed: int = 5) -> tuple[dict, list[dict]]:
    """The device's statistics snapshot (float64 values) and the host's results (values as float32 over CAN)."""
    rng = np.random.default_rng(seed)
    stats = ProgramStatistics()
    results = []
    for k in range(1, N + 1):
        values = {"y_max": float(rng.normal(-7.96, 0.044)), "x_max": float(rng.normal(0.04219, 5e-5)),
                  "duration": float(rng.normal(0.2551, 7e-4))}
        ok = k % 20 != 0
        stats.add(SimpleNamespace(ok=ok, elements=[], process_values=values))
        results.append({"number": k, "program": 1, "ok": ok, "elements": [],
                        "process_values": {n: float(np.float32(v)) for n, v in values.items()}})
    return {"program": 1, **stats.summary({"x_max": [0.0415, 0.0425]})}, results


def test_host_equals_device_within_float32_rounding():
    snapshot, results = device_and_host()
    a = device_agreement(results, snapshot)
    assert a["comparable"] and a["equal"] and a["differs"] == [] and a["ok"] == {"host": 57, "device": 57}
    assert any(v["host"]["mean"] != v["device"]["mean"] for v in a["values"].values())   # rounding is there
    assert agreement_text(a).startswith("host statistics equal the device's (60 results")


def test_a_lost_value_is_detected():
    snapshot, results = device_and_host()
    del results[6]["process_values"]["y_max"]
    a = device_agreement(results, snapshot)
    assert a["comparable"] and not a["equal"] and a["differs"] == ["y_max"]
    assert a["values"]["y_max"]["differs"][0] == "n"
    assert (a["values"]["y_max"]["host"]["n"], a["values"]["y_max"]["device"]["n"]) == (59, 60)
    assert agreement_text(a).startswith("host statistics DIFFER from the device's (host vs device): y_max (n 59 vs 60")


def test_a_value_wrong_in_the_fourth_digit_is_detected():
    snapshot, results = device_and_host()
    results[10]["process_values"]["y_max"] += 1e-3                  # 0.013 %: far above float32 rounding
    a = device_agreement(results, snapshot)
    assert a["differs"] == ["y_max"] and "mean" in a["values"]["y_max"]["differs"]
    assert "n" not in a["values"]["y_max"]["differs"]


def test_wrong_ok_count_and_host_only_value_differ():
    snapshot, results = device_and_host()
    results[0]["ok"] = False
    a = device_agreement(results, snapshot)
    assert not a["equal"] and a["differs"] == [] and agreement_text(a).endswith("OK count 56 vs 57")
    snapshot, results = device_and_host()
    results[0]["process_values"]["extra"] = 1.0
    assert device_agreement(results, snapshot)["differs"] == ["extra"]


def test_tolerance_is_float32_rounding_not_more():
    v = np.full(50, 0.25) + np.arange(50) * 1e-4
    device = {"n": 50, "mean": float(v.mean()), "std": float(v.std(ddof=1))}
    assert compare_value(v.astype(np.float32).astype(float), device)["differs"] == []
    assert compare_value(v.astype(np.float16).astype(float), device)["differs"] == ["mean", "std"]


def test_not_compared_without_a_matching_snapshot():
    snapshot, results = device_and_host()
    a = device_agreement(results[:-1], snapshot)                 # a whole result was lost
    assert not a["comparable"] and a["equal"] is None
    assert agreement_text(a) == "not compared: the device counted 60 results, the recording holds 59"
    assert device_agreement(results, None)["comparable"] is False
    assert final_snapshot([{"program": 2, "total": 1}, snapshot, {"program": 2}], 1) is snapshot
    assert final_snapshot([{"total": 60}], 1) is None


@pytest.mark.parametrize("lose_value", [False, True])
def test_recorded_run_compared_and_printed(tmp_path, capsys, lose_value):
    snapshot, results = device_and_host()
    if lose_value:
        results[6]["process_values"].pop("y_max")
    path = tmp_path / "run.mcap"
    with Recorder(path, programs={1: {"limits": {"x_max": [0.0415, 0.0425]}}}) as rec:
        for k, r in enumerate(results):
            rec.write_result(r, t=float(k))
        rec.write_statistics({**copy.deepcopy(snapshot), "total": 0}, t=1.0)     # an earlier snapshot
        rec.write_statistics(snapshot, t=float(N))
    a = analyse(read_recording(path))
    agreement = a["sets"][1]["device_agreement"]
    assert agreement["equal"] is (not lose_value)
    cli._print_set_summary(a)
    line = next(s for s in capsys.readouterr().out.splitlines() if "device statistics (program 1)" in s)
    assert ("DIFFER" in line and "y_max (n 59 vs 60" in line) if lose_value else "equal the device's" in line


def test_the_console_counts_live_drop_reports_and_the_pairs_they_dropped(tmp_path, capsys):
    """"live_dropped 401" counted the reports; the pairs the unit did not send (3 953 177 in a 1000-cycle run, 98.8 %)
    were never printed. Now both."""
    path = tmp_path / "run.mcap"
    with Recorder(path) as rec:
        for t, count, total in ((1.0, 100, 100), (2.0, 50, 150), (3.0, 70, 220)):
            rec.write_event(t, "live_dropped", count=count, total=total)
    cli._print_set_summary(analyse(read_recording(path)))
    line = next(s for s in capsys.readouterr().out.splitlines() if "events:" in s)
    assert "live_dropped 3 (220 live pairs in all)" in line

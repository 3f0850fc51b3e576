"""Clutch-stand runs end to end: the console's key results, the report's metrics and the encoder speeds."""
from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np
import pytest

from drivers.encoder import FREQUENCY, PERIOD
from rig.analysis.clutch_report import stand_results, stimuli
from rig.analysis.report import write_report
from rig.cli import main
from rig.recorder import read_recording
from rig.scene import load_scene

SCENES = Path(__file__).resolve().parents[2] / "data" / "scenes"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """name -> (console output, recording) of the dynamic-stand scenes the tests look at."""
    out = {}
    tmp = tmp_path_factory.mktemp("clutch_runs")
    for name in ("clutch_startup", "clutch_shock_short_985", "clutch_blocked", "clutch_stop"):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert main(["-q", "run", str(SCENES / f"{name}.toml"), "-o", str(tmp / f"{name}.mcap"),
                         "--no-report"]) == 0
        out[name] = (buf.getvalue(), read_recording(tmp / f"{name}.mcap"))
    return out


def metrics(rec):
    return {m.name: m for m in stand_results(rec)[1]}


def test_console_prints_the_stands_key_results_not_curve_counts(runs):
    for name, (text, _) in runs.items():
        assert "curves: 0" not in text and "OK 0" not in text
        assert "clutch stand:" in text and "max torque" in text and "disengagements" in text and "shutdown" in text
    shock = runs["clutch_shock_short_985"][0]
    assert re.search(r"disengagements\s+1, at ", shock) and re.search(r"shutdown\s+not required", shock)
    assert "rule: 4 disengagements within 100 ms" in shock
    assert re.search(r"shock at 0.1 s: overshoot\s+n/a\s+\(a shock is a pulse", shock)
    assert not re.search(r"\b774\.2\b", shock)
    for text, _ in runs.values():            # angles: attached °, the power-on angle to 0.01° (was '0.000859°')
        assert re.search(r"encoders, -?\d+\.\d\d° at power-on", text) and " °" not in text


def test_stimuli_read_from_the_scenes():
    kinds = {name: [(s.kind, round(s.time, 6)) for s in stimuli(load_scene(SCENES / f"{name}.toml"))[0]]
             for name in ("clutch_startup", "clutch_shock_short", "clutch_overload_hold", "clutch_stop",
                          "clutch_shock_drop", "clutch_blocked")}
    assert kinds == {"clutch_startup": [("start", 0.0)], "clutch_shock_short": [("shock", 0.1)],
                     "clutch_overload_hold": [("shock", 0.1)], "clutch_stop": [("stop", 0.1)],
                     "clutch_shock_drop": [("shock", 0.1), ("step", 0.4)], "clutch_blocked": [("sweep", 0.0)]}
    s, rule = stimuli(load_scene(SCENES / "clutch_stop.toml"))
    assert s[0].before == pytest.approx(60.0) and "90" in s[0].text
    assert rule["shutdown_count"] == 4 and isinstance(rule["shutdown_count"], int)
    assert rule["shutdown_window"] == pytest.approx(0.1)


def test_metrics_fit_each_scene(runs):
    m = metrics(runs["clutch_startup"][1])                # thesis: peak 145 N·m, settled within 450 ms
    assert 120 < m["start-up: peak torque"].value < 160 and 100 < m["start-up: overshoot"].value < 250
    assert 0.1 < m["start-up: settling time"].value < 0.45
    assert m["start-up: final torque"].value == pytest.approx(50.0, abs=0.5)
    m = metrics(runs["clutch_shock_short_985"][1])        # the 985 N set: one apex pass, then restabilises
    assert m["shock at 0.1 s: overshoot"].value is None
    assert 0.15 < m["shock at 0.1 s: recovery time"].value < 0.35
    assert m["disengagements"].value.startswith("1,") and m["shutdown"].value == "not required"
    m = metrics(runs["clutch_stop"][1])                   # scene assumption: 60 N·m, brake raised to 90 N·m
    assert 75 < m["stop at 0.1 s: torque rise"].value < 90      # the brake raised to 90 N·m (from 60 N·m)
    assert 0.5 < m["stop at 0.1 s: standstill"].value < 0.7 and 0.5 < m["stop at 0.1 s: settling time"].value < 0.7
    m = metrics(runs["clutch_blocked"][1])
    assert m["overshoot"].value is None and m["settling time"].value is None
    assert m["disengagements"].value.startswith("2,") and m["relative angle swept"].value == pytest.approx(257.7, abs=2)   # drive speed (a0 − T)/b0
    # final speeds in the unit the scene's truth charts and CSVs show: rpm where it writes no speed (was rad/s there),
    # rad/s where it writes them so (the start-up's comparison)
    assert m["final speed ω1"].unit == "rpm" and m["final speed ω1"].value == pytest.approx(
        float(np.mean(runs["clutch_blocked"][1].truth["omega1"][-50:])) * 30 / np.pi, rel=0.05)
    assert metrics(runs["clutch_startup"][1])["final speed ω1"].unit == "rad/s"
    for name, (_, rec) in runs.items():                   # never a settling time as long as the run
        for x in metrics(rec).values():
            if "settling" in x.name or "recovery" in x.name:
                assert x.value is None or x.value < rec.series["/stand/torque"]["t"][-1] - 0.1


def test_a_stand_coasting_after_its_motor_tripped_has_no_final_speed(tmp_path):
    """clutch_overload_hold trips its motor by the shutdown rule at ~0.2 s; at the run's end (0.6 s) both halves still
    turn, slowing by ~22 rad/s² (1.3 % of the speed per 50 ms, under the trend bound): that is coasting, not a final
    speed (it was given as 84.81 rad/s; an audit)."""
    out = tmp_path / "hold.mcap"
    assert main(["-q", "run", str(SCENES / "clutch_overload_hold.toml"), "-o", str(out), "--no-report"]) == 0
    m = metrics(read_recording(out))
    assert m["shutdown"].value == "required" and m["shutdown"].at < 0.3
    for name in ("final speed ω1", "final speed ω3"):
        assert m[name].value is None and m[name].reference.startswith(
            f"coasting: the motor was tripped by the scene's shutdown rule at {m['shutdown'].at:.4g} s and the stand "
            "still turns at the end of the run: -1.1")


def speed_errors(rec, enc, truth_key):
    e, tr = rec.series[f"/stand/encoder{enc}"], rec.truth
    ok = np.isin(e["speed_method"], (FREQUENCY, PERIOD)) & (e["speed_time"] > 0.005)
    return e["t"][ok], np.abs(e["speed"][ok] - np.interp(e["speed_time"][ok], tr["t"], tr[truth_key]))


def test_encoder_speeds_follow_the_plant_without_flicker_or_chunk_spikes(runs):
    rec = runs["clutch_blocked"][1]                       # 0.2..0.6 rad/s: was a block of 0 / 0.77 rad/s flicker
    t, err = speed_errors(rec, 1, "omega1")
    assert t.size > 9000 and np.max(err) < 0.005
    assert np.all(rec.series["/stand/encoder2"]["speed"] == 0.0)      # the blocked half
    rec = runs["clutch_startup"][1]                       # was: spikes of ±40 rad/s every 0.1 s
    for enc, key in ((1, "omega1"), (2, "omega3")):
        t, err = speed_errors(rec, enc, key)
        assert np.max(err) < 0.6               # a 2 ms mean where the driven half locks on (ω̇ jumps by 1400 rad/s²)
        assert np.percentile(err, 99) < 0.1
        near = np.abs(t - np.round(t, 1)) < 3e-3          # readings around the device's 0.1 s chunks
        assert near.sum() > 20 and np.max(err[near]) < 0.2


def test_report_table_states_references(runs, tmp_path):
    out = write_report(runs["clutch_shock_short_985"][1], tmp_path / "r", fmt="md")
    text = out.read_text()
    assert "| shock at 0.1 s: overshoot | n/a | a shock is a pulse" in text
    assert "relative to / definition" in text and not re.search(r"\b774\.2\b", text)    # the old shock "overshoot"
    model = text[text.index("Model events"):].split("\n\n")[1]          # the section's own event table: display units
    assert "phi_r=" not in model and re.search(r"\| disengagement \| phi_r -?\d+(\.\d+)?°, direction", model), model
    first = next(line for line in text.splitlines() if line.startswith("**"))     # the verdict leads the report
    assert re.fullmatch(r"\*\*Clutch stand: disengagements 1, at .*; shutdown not required; max torque .* N·m at .* s\*\*",
                        first), first


def test_truth_and_events_end_with_the_run(runs):
    """The plant truth (computed by the host in fixed blocks) stops at the scene's duration, not at the end of
    the last block: nothing of the plant past the run is recorded. The link's summary is stamped when its counters
    hold: at the bus's device time after the run, among the unit's closing frames (a few ms after the run)."""
    for name, (_, rec) in runs.items():
        duration = load_scene(SCENES / f"{name}.toml").section("scene")["duration"]
        end = float(str(duration).split()[0])
        assert rec.truth["t"][-1] == pytest.approx(end, abs=1e-9), name
        plant = [ev for ev in rec.events if ev["kind"] != "link_summary"]
        assert plant and max(ev["t"] for ev in plant) <= end + 1e-9, name
        (summary,) = [ev for ev in rec.events if ev["kind"] == "link_summary"]
        assert end <= summary["t"] <= float(rec.can_frames["t"][-1]) < end + 0.05, name


def test_stand_readings_are_exported_with_units(runs, tmp_path):
    out = write_report(runs["clutch_startup"][1], tmp_path / "r")
    html = out.read_text()
    for name in ("stand_torque.csv", "stand_encoder1.csv", "stand_encoder2.csv"):
        assert f"<a href='{name}'>{name}</a>" in html
    rows = (tmp_path / "r" / "stand_torque.csv").read_text().splitlines()
    assert rows[0] == "t [s],torque [N*m]" and len(rows) - 1 == runs["clutch_startup"][1].series["/stand/torque"]["t"].size
    assert "<a href='004_truth.png'><img src='004_truth.png'" in html or "<a href='" in html.split("<figure>")[1]


def test_rig_analyse_of_stand_recordings_merges_their_key_results(runs, tmp_path):
    """`rig analyse` over stand recordings (no curves): each recording's scene, plant and console lines in the
    table, its numeric key results (counts and the shutdown flag included) merged over the recordings."""
    import csv
    from rig.analysis.clutch_metrics import Metric
    names = ("clutch_startup", "clutch_shock_short_985")
    paths = [str(runs[n][1].path) for n in names]
    out = tmp_path / "batch"
    assert main(["-q", "analyse", *paths, "-o", str(out)]) == 0
    rows = {r["scene"]: r for r in csv.DictReader((out / "recordings.csv").open())}
    assert set(rows) == set(names) and {r["plant"] for r in rows.values()} == {"clutch_dynamic"}
    for name in names:
        metrics = {m.name: m for m in stand_results(runs[name][1])[1]}
        row = rows[name]
        assert "max torque" in row["stand"] and row["curves"] == "0" and "  " not in row["stand"]   # no console padding
        assert float(row["stand.max_torque mean [N·m]"]) == pytest.approx(metrics["max torque"].value, rel=1e-12)
        assert float(row["stand.disengagements mean"]) == float(metrics["disengagements"].value.split(",")[0])
        assert float(row["stand.shutdown mean"]) == {"required": 1.0, "not required": 0.0}[metrics["shutdown"].value]
    assert float(rows["clutch_shock_short_985"]["stand.disengagements mean"]) >= 1   # the shock slips
    both = [float(rows[n]["stand.max_torque mean [N·m]"]) for n in names]
    report = (out / "report.md").read_text()
    for name, value in zip(names, both):     # a start-up and a shock test: two populations, not one mean
        line = next(x for x in report.splitlines() if x.startswith(f"| {name}") and "| stand.max_torque |" in x)
        assert line.split("|")[4].strip() == "1" and float(line.split("|")[7]) == pytest.approx(value, rel=1e-5)
    assert "## Stand and lab recordings (2)" in report and "(scene clutch_startup):" in report
    assert Metric("n", "3, at 0.1 s", "", "").number() == 3.0 and Metric("n", "abc", "", "").number() is None


def test_every_recorded_event_kind_is_explained_in_the_report(runs):
    """The events table's "what it means" cell is never empty for what the stands record."""
    from rig.analysis.report import EVENT_MEANING
    kinds = {e["kind"] for _, rec in runs.values() for e in rec.events}
    assert "phase_boundary" in kinds and not kinds - set(EVENT_MEANING), kinds - set(EVENT_MEANING)


def test_rig_values_are_shown_as_precisely_as_the_thesis_values_beside_them():
    from rig.analysis.stand_comparison import Row

    def shown(rig: float, thesis: float) -> str:
        return Row("q", "N*m", thesis, rig, False, "").rig_text()
    assert shown(100.05, 100.18) == "100.05"            # was "100" beside 100.18 and a -0.13 deviation
    assert shown(14.5213, 14.5) == "14.52" and shown(3.0, 3) == "3"


@pytest.mark.parametrize("old, new, said", [('thesis = "', 'thesis = "7 N', r"unit 'N.*' of '7 N.*' is not a torque"),
                                            ('thesis = "', 'thesis = "abc', r"thesis value 'abc.*' is not a number"),
                                            ('thesis = "100.18 rad/s"', 'thesis = 100.18',
                                             r"thesis value '100.18' has no unit, which makes it a count"),
                                            ('rig = "final speed ω3"', 'rig = "final sped ω3"',   # ran as "n/a" (an audit)
                                             r"rig = 'final sped ω3' is no result of this stand \(did you mean "
                                             r"'final speed ω3'\?\); its results: torque, ")])
def test_a_comparison_row_in_error_is_refused_before_the_run(tmp_path, capsys, old, new, said):
    """A [[comparison]] mistake once surfaced after a whole recording, naming the recording (exit 2 must mean nothing
    ran): it names the scene and nothing is recorded."""
    text = (SCENES / "clutch_startup.toml").read_text()
    assert old in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(old, new, 1))
    out = tmp_path / "bad.mcap"
    capsys.readouterr()
    assert main(["-q", "run", str(bad), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert re.search(rf"rig: error: {re.escape(str(bad))} \[\[comparison\]\] .*{said}", err) and not out.exists()


def test_every_result_a_run_gives_is_a_name_a_comparison_row_may_use(runs):
    """The names `check_rows` accepts (rig.analysis.clutch_metrics.result_names) hold every result the runs give —
    start-up, shock, stop and blocked sweep — so a correct row is never refused."""
    from rig.analysis.clutch_metrics import result_names
    for name, (_, rec) in runs.items():
        stim, got = stand_results(rec)
        assert {m.name for m in got} <= set(result_names(stim)), name


def test_the_stand_finds_its_encoders_and_torque_by_what_they_measure(runs, tmp_path):
    """The driving half's encoder (φ1) wired to Encoder2 and the driven half's (φ3) to Encoder1: the same key
    results — the report took Encoder1 as the driving half whatever it measured."""
    swap = {'to = "can.Encoder1"': 'to = "can.Encoder2"', 'to = "can.Encoder2"': 'to = "can.Encoder1"'}
    text = (SCENES / "clutch_shock_short_985.toml").read_text(encoding="utf-8")
    scene = tmp_path / "swapped.toml"
    scene.write_text(re.sub("|".join(map(re.escape, swap)), lambda m: swap[m[0]], text), encoding="utf-8")
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["-q", "run", str(scene), "-o", str(tmp_path / "swapped.mcap"), "--no-report"]) == 0
    rec = read_recording(tmp_path / "swapped.mcap")
    assert "/stand/encoder2" in rec.series and rec.scene().data["transducers"]
    got, want = metrics(rec), metrics(runs["clutch_shock_short_985"][1])
    assert got.keys() == want.keys()
    for name, m in want.items():
        assert got[name].value == (pytest.approx(m.value, rel=1e-9) if isinstance(m.value, float) else m.value), name


def test_the_speed_chart_speaks_the_scenes_speed_unit_and_encoder(runs, tmp_path):
    """The blocked stand shows speeds in rpm (its scene's unit, as the console and the truth chart): the speeds chart
    did too — it was fixed at rad/s, its caption at a 1024-line encoder whatever the scene wired."""
    out = write_report(runs["clutch_blocked"][1], tmp_path / "r", fmt="md")
    text = out.read_text()
    caption = next(line for line in text.splitlines() if line.startswith("*Speeds of both halves"))
    assert re.search(r"frequency above \d+(\.\d+)? rpm for the driving half's 4096 counts per turn", caption), caption
    assert "rad/s" not in caption


def test_a_count_thesis_beside_a_quantity_is_not_compared_and_says_why(tmp_path):
    """thesis = 14 beside the start-up's peak torque (N·m): the run recorded, then failed with "1.0 N*m has the wrong
    dimension", naming no key, and no report could be written. The row is not compared and says why."""
    from rig.analysis.clutch_metrics import Metric
    from rig.analysis.stand_comparison import compare
    from rig.scene import load_scene
    text = (SCENES / "clutch_leaf_startup.toml").read_text()
    assert 'thesis = "14.5 N*m"' in text
    scene_path = tmp_path / "count.toml"
    scene_path.write_text(text.replace('thesis = "14.5 N*m"', "thesis = 14", 1))
    peak = Metric("start-up: peak torque", 14.7, "N*m", "extreme reading", at=0.0466)
    (row,) = [r for r in compare(load_scene(scene_path), [], [peak]) if r.thesis == 14]
    assert row.rig is None and row.verdict == "n/a" and "is a count, the rig's 'start-up: peak torque' in N*m" in row.why


def test_a_stand_recording_that_lost_its_start_says_what_its_results_cover(runs):
    """The first chunk of a blocked-clutch run damaged: its results took the first reading kept (7 s) as power-on —
    "347.44° at power-on", a disengagement at 9.494 s the run never had (an audit). The relative angle meets the truth
    where it begins, and the console and report say what the results cover."""
    import copy
    from rig.analysis.clutch_report import lost_start_warnings, stand_record, summary_lines
    _, whole = runs["clutch_blocked"]
    cut = copy.copy(whole)
    start = 2.0                                                     # the run's first 2 s lost
    cut.series = {k: {c: v[s["t"] >= start] for c, v in s.items()} for k, s in whole.series.items()}   # truth too
    cut.complete = False
    assert whole.complete and not lost_start_warnings(whole)
    (said,) = lost_start_warnings(cut)
    assert said.startswith("the stand's readings begin at 2") and "cover 2" in said
    assert any(line == f"  warning: {said}" for line in summary_lines(cut, *stand_results(cut)))
    full, kept = stand_record(whole), stand_record(cut)
    at = kept.t_angle[0]                                          # the angle where the kept readings begin: the truth's
    assert kept.rel_angle[0] == pytest.approx(np.interp(at, full.t_angle, full.rel_angle), abs=np.radians(1.0))


def test_a_motor_stop_after_the_runs_end_leaves_its_final_speed():
    """A stop the scene sets after the recorded end (t_off beyond the run, or a cut recording) is not coasting: the
    steady speed held to the end is the final speed (it was called coasting; a review)."""
    from rig.analysis.clutch_metrics import StandRecord, Stimulus, stand_metrics
    t = np.linspace(0.0, 1.0, 1001)
    w = np.full(t.size, 100.0)
    rec = StandRecord(t, np.full(t.size, 50.0), None, None, {"ω3": (t, w, t, np.ones(t.size))}, 1.0, 1.0)

    def final(stim):
        return next(m for m in stand_metrics(rec, stim, None, None) if m.name == "final speed ω3")
    assert final([]).value == pytest.approx(100.0)
    assert final([Stimulus(5.0, "stop", "motor off")]).value == pytest.approx(100.0)
    late = final([Stimulus(0.5, "stop", "motor off")])
    assert late.value is None and late.reference.startswith("coasting: the motor was switched off at 0.5 s")

"""The course labs end to end: plant → transducers → CAN frames → host → recording → lab sheet, each sheet
against the closed forms of its mechanism (rig.mechanisms), and the frames decoded with cantools alone."""
from __future__ import annotations

import csv
import re
from math import cos, radians, tau
from pathlib import Path

import cantools
import numpy as np
import pytest

from firmware_sim.transducers import load_transducer
from rig.analysis.lab_report import lab_sheets, lab_warnings
from rig.mechanisms import Cardan, Geneva
from rig.plants.lab_bench import LabBench
from rig.recorder import read_recording
from rig.runner import run_scene
from rig.scene import SceneError, load_scene

SCENES = Path(__file__).resolve().parents[2] / "data" / "scenes"
DBC = Path(__file__).resolve().parents[2] / "data" / "can" / "rig.dbc"


def _run(tmp_path_factory, name: str, edit=None):
    scene = SCENES / f"{name}.toml"
    if edit is not None:
        scene = tmp_path_factory.mktemp(name) / f"{name}.toml"
        scene.write_text(edit((SCENES / f"{name}.toml").read_text()))
    out = tmp_path_factory.mktemp(f"{name}_run") / f"{name}.mcap"
    run_scene(scene, out)
    rec = read_recording(out)
    return rec, {s.title: s for s in lab_sheets(rec)}


@pytest.fixture(scope="module")
def speed(tmp_path_factory):
    return _run(tmp_path_factory, "lab_speed")


def test_speed_lab_instruments_against_the_counter(speed):
    rec, sheets = speed
    v = sheets["Speed measurement"].values
    assert v["resolution_rpm"] == pytest.approx(10.0)                     # 60 / (6 holes · 1 s)
    assert abs(v["counter_rpm"] - v["truth_rpm"]) <= v["resolution_rpm"]  # ±1 pulse in the gate
    assert abs(v["error mechanical tachometer"]) <= 0.05 + 0.01           # ±5 % class, 10 rpm dial
    assert abs(v["error tachogenerator"]) <= 0.015
    assert abs(v["error stroboscope (60·f_x)"]) <= 0.005                  # 0.1 Hz dial at 19 Hz, 0.2 % calibration
    assert len(sheets["Speed measurement"].rows) == 6       # counter, three instruments, truth over gate, at reading
    # data-sheet classes (data/devices): gain + non-linearity·FS + half the dial step + one counter step (10 rpm)
    counter = v["counter_rpm"]
    assert v["class mechanical tachometer"] == pytest.approx(0.05 + (5.0 + 10.0) / counter)
    assert v["class tachogenerator"] == pytest.approx(0.01 + (0.005 * 3000.0 + 10.0) / counter)
    assert v["class stroboscope (60·f_x)"] == pytest.approx(0.002 + (0.5 * 6.0 + 10.0) / counter)
    assert all(abs(v[f"error {k}"]) <= v[f"class {k}"] for k in ("mechanical tachometer", "tachogenerator"))
    assert "within its" in sheets["Speed measurement"].result


def test_the_speed_sheets_csv_has_one_number_per_column(speed, tmp_path):
    """lab_speed.csv held the report's cells ("1144 (+0.33 %)", "±3.19 % (class ±1 %): within"): a spreadsheet read
    text. Now each reading, its error and the limits are numbers of their own, equal to the sheet's values."""
    from rig.analysis.report import write_report
    rec, sheets = speed
    write_report(rec, tmp_path)
    with open(tmp_path / "lab_speed.csv", newline="", encoding="utf-8") as f:
        rows = {row["instrument"]: row for row in csv.DictReader(f)}
    v = sheets["Speed measurement"].values
    assert float(rows["pulse counter (N / (z·T))"]["mean (rpm)"]) == pytest.approx(v["counter_rpm"], rel=1e-6)
    for name in ("tachogenerator", "mechanical tachometer", "stroboscope (60·f_x)"):
        row = rows[name]
        readings = [float(row[f"reading {i} (rpm)"]) for i in (1, 2, 3)]
        errors = [float(row[f"reading {i} error vs counter (%)"]) for i in (1, 2, 3)]
        counter = [float(rows["pulse counter (N / (z·T))"][f"reading {i} (rpm)"]) for i in (1, 2, 3)]
        assert errors == pytest.approx([100 * (r - c) / c for r, c in zip(readings, counter)], abs=1e-3)  # (rounded rpm)
        assert float(row["error of the mean vs counter (%)"]) == pytest.approx(100 * v[f"error {name}"], rel=1e-5)
        assert float(row["worst-case limit (%)"]) == pytest.approx(100 * v[f"class {name}"], rel=1e-5)
        assert row["within the limit"] == ("yes" if abs(v[f"error {name}"]) <= v[f"class {name}"] else "no")
    assert float(rows["plant truth (mean over the gate)"]["counter error vs it (%)"]) == pytest.approx(
        100 * (v["counter_rpm"] - v["truth_rpm"]) / v["truth_rpm"], abs=1e-6)


@pytest.mark.parametrize("bench", ["cam", "cardan"])
def test_the_other_lab_csvs_hold_one_number_per_cell(bench, request, tmp_path):
    """lab_cardan.csv held "-0.04 %" and lab_cam_torque.csv "0–10" (a leftover): a spreadsheet read text. Every cell of
    their CSVs is now a number; the units are in the headers."""
    from rig.analysis.report import write_report
    rec, _ = request.getfixturevalue(bench)
    write_report(rec, tmp_path)
    files = sorted(tmp_path.glob("lab_*.csv"))
    assert len(files) == {"cam": 2, "cardan": 1}[bench]
    for path in files:
        with open(path, newline="", encoding="utf-8") as f:
            header, *rows = list(csv.reader(f))
        assert rows and all(len(row) == len(header) for row in rows)
        for row in rows:
            for name, cell in zip(header, row):
                assert re.fullmatch(r"[+-]?\d+(\.\d+)?", cell), (path.name, name, cell)


def test_the_speed_sheets_truth_is_that_of_the_gate_the_counter_shows(tmp_path_factory):
    """A speed that varies by ±60 rpm at 0.5 Hz: the truth row is the mean over the gate whose count each reading
    shows (the last completed gate, [1, 2] s for a reading at 2.5 s), not over the second before the reading, and
    the sheet says that the instruments, reading the speed of the moment, then differ from the counter."""
    def edit(text):
        text = re.sub(r'(?m)^amplitude = .*$', 'amplitude = "60 rpm"', text)
        return re.sub(r'(?m)^frequency = .*$', 'frequency = "0.5 Hz"', text)
    rec, sheets = _run(tmp_path_factory, "lab_speed", edit)
    sheet = sheets["Speed measurement"]
    truth, gate = rec.truth, 1.0
    counter = [float(x) for x in sheet.rows[0][1:4]]
    shown = [float(x) for x in next(r for r in sheet.rows if r[0] == "plant truth (mean over the gate)")[1:4]]
    pulses = rec.series["/stand/lab_speed"]
    for at, value, count in zip(read_lab_times(rec), shown, counter):
        end = np.floor(pulses["t"][np.searchsorted(pulses["t"], at, side="right") - 1] / gate + 1e-9) * gate
        inside = (truth["t"] > end - gate) & (truth["t"] <= end)
        expected = float(np.mean(truth["omega_in"][inside])) * 60 / tau
        assert value == pytest.approx(expected, abs=0.6)          # the row's integer rpm
        assert abs(count - expected) <= 10.0 + 0.6                # the counter within its step of that gate's mean
    assert any("the instruments read the speed of the moment" in note for note in sheet.notes)
    assert "against the counter (the shaft's speed at the readings differs from the counted gates' by up to" \
        in sheet.result                                          # the console line says it too, not only the report


def read_lab_times(rec) -> list[float]:
    from rig.analysis.lab_report import read_lab
    return read_lab(rec).lab["readings"]


def test_speed_lab_frames_decode_with_the_dbc_alone(speed):
    """/can/raw's LabSpeed frames through cantools give the recorded pulse counts; the counts are the pulses of
    whole gates: 6 holes × 19 rev/s = 114 per second, ±1."""
    rec, _ = speed
    db = cantools.database.load_file(str(DBC))
    msg = db.get_message_by_name("LabSpeed")
    raw = rec.can_frames
    frames = [bytes(d) for i, d in zip(raw["id"], raw["data"]) if i == msg.frame_id]
    decoded = np.array([msg.decode(d)["Pulses"] for d in frames])
    recorded = rec.series["/stand/lab_speed"]["pulses"]
    assert decoded.size == recorded.size > 200 and np.array_equal(decoded, recorded)
    after_first_gate = recorded[rec.series["/stand/lab_speed"]["t"] > 1.0]
    assert set(np.unique(after_first_gate)) <= {113.0, 114.0, 115.0}


def test_a_stroboscope_at_half_the_rotation_frequency_reads_half(tmp_path_factory):
    _, sheets = _run(tmp_path_factory, "lab_speed", lambda s: s.replace("divisor = 1", "divisor = 2"))
    assert sheets["Speed measurement"].values["error stroboscope (60·f_x)"] == pytest.approx(-0.5, abs=0.005)
    assert "stroboscope (60·f_x) -50" in sheets["Speed measurement"].result
    assert re.search(r"stroboscope \(60·f_x\) -50\.\d\d % \(OUTSIDE its worst-case ±\d", sheets["Speed measurement"].result)


def test_a_gate_too_short_for_one_pulse_is_named_not_a_division_by_zero(tmp_path_factory):
    """A 5 ms gate at 1140 rpm sees 0.57 pulses of the 6-hole disc: the counter read 0 and the sheet, dividing every
    instrument's error by it, ended the command in a ZeroDivisionError traceback (an audit)."""
    gate = 'to = "can.LabSpeed.Pulses"\nrate = "50 Hz"\n'
    with pytest.raises(ValueError, match=r"the pulse counter counted no pulse in its gate .*one pulse per gate of 5 ms "
                                         r"with the disc's 6 holes is 2000 rpm.*\(lengthen the counter's gate_time"):
        _run(tmp_path_factory, "lab_speed", lambda s: s.replace(gate, gate + 'overrides = { gate_time = "5 ms" }\n', 1))


def test_pulse_counter_counts_whole_gates():
    counter = load_transducer("slotted_disc_6", np.random.default_rng(0), gate_time="0.5 s")
    t = np.arange(1, 20001) / 10_000.0
    n = counter.measure(t[:7000], 2 * np.pi * 7.3 * t[:7000])       # 7.3 rev/s, the gate ends inside a chunk
    n = np.r_[n, counter.measure(t[7000:], 2 * np.pi * 7.3 * t[7000:])]
    assert np.all(n[t < 0.5] == 0)
    assert set(np.unique(n[t >= 0.5])) <= {21.0, 22.0}               # 6 · 7.3 · 0.5 = 21.9 pulses per gate
    assert n[t >= 0.5].mean() == pytest.approx(21.9, abs=0.3)


@pytest.fixture(scope="module")
def cardan(tmp_path_factory):
    return _run(tmp_path_factory, "lab_cardan")


def test_cardan_lab_against_the_closed_form(cardan):
    """Two encoders, 36 points per turn: the speed ratio by central differences at 10° equals the closed form
    differenced the same way (1e-3), whose extremes approach cos α and 1/cos α; the mean ratio over a turn
    is 1; the output angle follows tan φ2 = tan φ1 / cos α within two encoder counts."""
    _, sheets = cardan
    v = sheets["Cardan joint"].values
    joint, h = Cardan(radians(30)), radians(10)
    phi = np.arange(36) * h
    differenced = (joint.output_angle(phi + h) - joint.output_angle(phi - h)) / (2 * h)
    assert v["ratio_min"] == pytest.approx(differenced.min(), abs=1e-3)
    assert v["ratio_max"] == pytest.approx(differenced.max(), abs=1e-3)
    assert differenced.min() == pytest.approx(cos(radians(30)), abs=5e-3)
    assert differenced.max() == pytest.approx(1 / cos(radians(30)), abs=5e-3)
    assert v["ratio_mean"] == pytest.approx(1.0, abs=1e-4)
    assert v["lag_error_max"] < 2 * tau / 4096
    assert v["ratio_error_max"] < 2e-3                       # measurement error: against the same differences
    assert len(sheets["Cardan joint"].rows) == 36 and len(sheets["Cardan joint"].rows[0]) == 7


def test_the_sheet_finds_its_encoders_by_what_they_measure(cardan, tmp_path_factory):
    """The input shaft's encoder wired to Encoder2 and the output's to Encoder1: the same sheet (the sheet took
    Encoder1 as the input whatever it measured, and showed a -24.6 % "measurement error" with its sign flipped)."""
    swap = {'to = "can.Encoder1"': 'to = "can.Encoder2"', 'to = "can.Encoder2"': 'to = "can.Encoder1"'}
    edit = (lambda text: re.sub("|".join(map(re.escape, swap)), lambda m: swap[m[0]], text))
    rec, sheets = _run(tmp_path_factory, "lab_cardan", edit)
    assert rec.scene().data["transducers"]["input_encoder"]["to"] == "can.Encoder2"
    got, want = sheets["Cardan joint"].values, cardan[1]["Cardan joint"].values
    assert got.keys() == want.keys() and all(got[k] == pytest.approx(want[k], rel=1e-9, abs=1e-12) for k in want)


@pytest.mark.parametrize("slots, speed", [(5, "484.5 rpm"), (4, "484.5 rpm"), (5, "300 rpm"), (5, "2000 rpm")])
def test_geneva_lab_motion_ratio(tmp_path_factory, slots, speed):
    """k_m = (z − 2)/(2z); a counting encoder sees the motion from its first to its last count change, so the
    measured ratio lies between the theory with a whole count at both ends and k_m. z = 4 rests on whole counts
    (1024 per index): the sheet must not take a count flickering at rest for an indexing."""
    # at 300 rpm from 180° the crank lands exactly on odd multiples of π (mid-dwell) at sample times: the wheel's
    # truth once jumped a slot pitch there (72° of angle error) and its encoder lost counts for good
    _, sheets = _run(tmp_path_factory, "lab_geneva", lambda s: s.replace("slots = 5", f"slots = {slots}")
                     .replace('speed = "484.5 rpm"', f'speed = "{speed}"'))
    v = sheets["Geneva drive"].values
    assert v["k_m_theory"] == pytest.approx((slots - 2) / (2 * slots)) == Geneva(slots, 0.05).timing(1.0).motion_ratio
    assert v["k_m_low"] <= v["k_m"] <= v["k_m_theory"] and v["indexings"] >= 4
    assert v["k_m_low"] == pytest.approx(v["k_m_one_count"] - 5e-4 / Geneva(slots, 0.05).timing(
        float(speed.split()[0]) * tau / 60).period)                     # one 2 kHz reading interval
    assert v["angle_error_max"] < 4 * tau / 4096
    dwell = [r for r in sheets["Geneva drive"].rows if -180 <= int(r[0]) <= -60]     # the wheel locked
    assert len(dwell) == 13 and len({r[1] for r in dwell}) == 1          # its count held: no creep across the dwell
    assert all(float(r[3]) == pytest.approx(float(r[1]) - float(r[2]), abs=0.011) for r in sheets["Geneva drive"].rows)  # 2-decimal columns


def test_geneva_sheet_counts_every_whole_indexing_from_any_start(tmp_path_factory):
    """Started mid-indexing (crank on the centre line) or mid-dwell, the sheet averages every indexing the recording
    holds whole (the last one too, when a dwell follows it before the end), the same count as the plant truth shows;
    its lower bound (a whole count at both ends) does not depend on where the run starts."""
    found = {}
    for phi0 in ("0 deg", "180 deg"):
        rec, sheets = _run(tmp_path_factory, "lab_geneva", lambda s: s.replace('phi0 = "180 deg"', f'phi0 = "{phi0}"'))
        moving = np.diff(rec.truth["phi_out"]) > 0                            # the plant's wheel turning
        starts, ends = np.flatnonzero(np.diff(moving.astype(int)) == 1), np.flatnonzero(np.diff(moving.astype(int)) == -1)
        whole = sum(1 for a in starts if np.any(ends > a))                   # began after the start, ended before the end
        v = found[phi0] = sheets["Geneva drive"].values
        assert v["indexings"] == whole, phi0
        assert v["k_m_low"] <= v["k_m"] <= v["k_m_theory"], phi0
    assert found["0 deg"]["k_m_one_count"] == found["180 deg"]["k_m_one_count"]
    assert found["180 deg"]["indexings"] == 8                                 # 1 s at 484.5 rpm from mid-dwell


@pytest.fixture(scope="module")
def cam(tmp_path_factory):
    return _run(tmp_path_factory, "lab_cam")


def test_cam_follower_lab_differenced_against_the_law(cam):
    """Position every 10° through an LVDT (100 mm range: its error bound ≈ 0.5 mm here); the numerically
    differenced s'' is off the law by the central difference's own truncation plus a few per cent."""
    _, sheets = cam
    v = sheets["Cam follower"].values
    assert v["ds_max"] < 0.5e-3
    assert v["d1_rel"] < 0.05 and v["law_d2_rel"] > 0.05          # 10° is coarse for s'': the lab's lesson
    assert abs(v["d2_rel"] - v["law_d2_rel"]) < 0.05
    assert len(sheets["Cam follower"].rows) == 36
    # most of the difference is the LVDT's 100 Hz lag (τ = 1.6 ms) plus the reading's, and its offset
    assert 1.0e-3 < v["lag"] < 5e-3 and v["rest_max"] < 0.4 * v["ds_max"]


def test_cam_follower_without_instrument_errors_is_the_law(tmp_path_factory):
    """An ideal LVDT (no errors, no 100 Hz lag): what is left is the frames' 1 µm step and the encoder."""
    _, sheets = _run(tmp_path_factory, "lab_cam", lambda s: s.replace(
        'to = "can.LabMotion.Displacement"', 'to = "can.LabMotion.Displacement"\noverrides = { errors_enabled = false, dynamics_enabled = false }'))
    v = sheets["Cam follower"].values
    assert v["ds_max"] < 5e-6                                      # 1 µm LSB and the encoder's angle steps
    assert abs(v["lag"]) < 0.5e-3
    assert v["d2_rel"] == pytest.approx(v["law_d2_rel"], abs=0.01)


def test_cam_shaft_torque_lab(cam):
    _, sheets = cam
    v = sheets["Cam-shaft torque"].values
    assert v["deviation_max"] < 0.01 * v["peak"]
    assert abs(v["work_per_turn"]) < 0.01 * v["peak"] * tau       # spring and mass: no net work per turn
    # the two cam sheets read different stretches of the run, and say which (the torque sheet left out the first
    # turn, the follower sheet read only the last one, without a word)
    torque_note, follower_note = sheets["Cam-shaft torque"].notes[-1], sheets["Cam follower"].notes[-1]
    assert torque_note.startswith("Readings from the first whole turn on (") and "over 1.25 turns" in torque_note
    assert follower_note.startswith("Positions read on the last whole turn the encoder saw")


def _no_negative_zero_and_one_precision_per_column(rows):
    cells = [str(c) for row in rows for c in row]
    assert not [c for c in cells if re.fullmatch(r"[-+]0(\.0+)?( %)?", c)]        # "-0.00", "+0.0000" ...
    for column in zip(*rows):
        numbers = [str(c).removesuffix(" %") for c in column if re.fullmatch(r"[-+]?\d+\.\d+( %)?", str(c))]
        assert len({len(c.split(".")[1]) for c in numbers}) <= 1, column       # one number of decimals


def test_lab_cam_tables_have_one_precision_per_column_and_no_negative_zero(cam):
    """The torque column mixed '0.0007143', '0' and '+0.0007'; the follower table showed '-0.00', '-0.000'."""
    _, sheets = cam
    for title in ("Cam follower", "Cam-shaft torque"):
        _no_negative_zero_and_one_precision_per_column(sheets[title].rows)
    zero = [r for r in sheets["Cam-shaft torque"].rows if r[0] == "120–130"][0]
    assert zero[2] == "0.0000" and re.fullmatch(r"0\.\d{4}", zero[1]) and re.fullmatch(r"[+-]0\.\d{4}", zero[3])


def test_cam_bench_torque_is_the_energy_balance():
    """M dφ = dU + d(½ m v²) + d(½ J ω²) + d(m g s) (virtual power; the follower rises against its weight) on a
    ripple drive, checked by integrating the torque against the energies' changes at 1e-4."""
    scene = load_scene(SCENES / "lab_cam.toml")
    scene.data["speed"] = {"profile": "sinusoidal", "speed": "30 rpm", "amplitude": "6 rpm", "frequency": "0.7 Hz"}
    bench = LabBench.from_scene(scene)
    t = np.linspace(0.0, 3.0, 300_001)
    x = bench.truth(t)
    work = np.concatenate([[0.0], np.cumsum(0.5 * (x["torque"][1:] + x["torque"][:-1]) * np.diff(x["phi_in"]))])
    energy = (0.5 * bench.spring_rate * x["s"] ** 2 + bench.spring_preload * x["s"]
              + 0.5 * bench.follower_mass * x["v"] ** 2 + 0.5 * bench.cam_inertia * x["omega_in"] ** 2
              + bench.follower_mass * bench.gravity * x["s"])
    assert np.max(np.abs(work - (energy - energy[0]))) < 1e-4 * np.max(np.abs(energy - energy[0]))
    assert bench.gravity == pytest.approx(9.81)                  # the scene's vertical follower: its weight counts


def test_a_lab_scene_names_its_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((SCENES / "lab_geneva.toml").read_text().replace("slots = 5", "slots = 2"))
    with pytest.raises(SceneError, match=r"\[plant\].*slots .* must be a whole number >= 3"):
        run_scene(bad, tmp_path / "bad.mcap")
    bad.write_text((SCENES / "lab_cardan.toml").read_text().replace('kind = "cardan"', 'kind = "hooke"'))
    with pytest.raises(SceneError, match=r"\[plant\]: key 'kind' must be one of 'disc', 'cardan'"):
        run_scene(bad, tmp_path / "bad.mcap")
    # [lab] is checked before the run, not first when the report reads it after a whole recording
    for old, new, message in (('sheets = ["cardan"]', 'sheets = ["cardn"]', r"\[lab\]: unknown sheet\(s\) \['cardn'\]"),
                              ('sheets = ["cardan"]', 'sheets = ["cardan"]\nreadings = ["2 kg"]',
                               r"\[lab\] readings\[0\].*kg"),
                              ('sheets = ["cardan"]', 'sheets = ["geneva"]', r"\[lab\]: sheet 'geneva' needs a bench of "
                               r"\[plant\] kind = 'geneva', this scene's is 'cardan' \(sheets for it: speed, cardan\)")):
        text = (SCENES / "lab_cardan.toml").read_text()
        assert old in text
        bad.write_text(text.replace(old, new))
        with pytest.raises(SceneError, match=message):
            run_scene(bad, tmp_path / "bad.mcap")
        assert not (tmp_path / "bad.mcap").exists()
    text = (SCENES / "lab_speed.toml").read_text()
    bad.write_text(re.sub(r"readings = \[.*\n", "", text))
    with pytest.raises(SceneError, match=r"\[lab\]: the speed sheet needs 'readings'"):
        run_scene(bad, tmp_path / "bad.mcap")
    # a reading before the counter's first gate ends (it shows 0: the errors divided by it) or after the run
    for readings, index, at in (('["0.5 s", "2.5 s"]', 0, "0.5"), ('["2.5 s", "9 s"]', 1, "9")):
        bad.write_text(re.sub(r"readings = \[.*\]", f"readings = {readings}", text))
        with pytest.raises(SceneError, match=rf"\[lab\]: readings\[{index}\] = {at} s is outside the run's readings: "
                                             r"the pulse counter's first gate ends at 1 s .* and the run at 6 s"):
            run_scene(bad, tmp_path / "bad.mcap")
        assert not (tmp_path / "bad.mcap").exists()
    # the run's end in any spelling the runner takes (duration_s = 3: the check saw no duration and let 3.7 s pass)
    bad.write_text(text.replace('duration = "6 s"', "duration_s = 3"))
    with pytest.raises(SceneError, match=r"readings\[1\] = 3.7 s is outside the run's readings: .* and the run at 3 s"):
        run_scene(bad, tmp_path / "bad.mcap")


def test_a_lab_served_in_its_own_process_records_the_same_readings(cardan, tmp_path, serve_scene):
    """``rig serve`` + the host over socketcand: the wiring comes from the scene on both sides of the wire, so
    the host records the same encoder readings as the in-process run, and the same lab sheet."""
    from rig.runner import record_scene
    out = tmp_path / "cross.mcap"
    with serve_scene(SCENES / "lab_cardan.toml", tmp_path / "endpoints.json") as ep:
        record_scene(SCENES / "lab_cardan.toml", out, can_host=ep["can"]["host"], can_port=ep["can"]["port"],
                     serial_port=None, idle_timeout=60.0)
    a, b = cardan[0], read_recording(out)
    for topic in ("/stand/encoder1", "/stand/encoder2"):
        for name in ("count", "edge_time", "angle"):
            np.testing.assert_array_equal(a.series[topic][name], b.series[topic][name], err_msg=f"{topic} {name}")
    assert {s.title: s.values for s in lab_sheets(b)} == {t: s.values for t, s in cardan[1].items()}


@pytest.mark.parametrize("kind, mechanism", [("cardan", Cardan(radians(30))), ("geneva", Geneva(5, 0.05))])
def test_bench_output_acceleration_is_the_derivative_of_its_speed(kind, mechanism):
    """alpha_out = d(omega_out)/dt, with the input speed varying (the r·α1 term) — central differences."""
    from rig.motion.speed import SinusoidalSpeed
    bench = LabBench(kind, SinusoidalSpeed(50.0, 5.0, 2.0), mechanism)
    t = np.linspace(0.01, 0.5, 200_001)
    truth = bench.truth(t)
    fd = np.gradient(truth["omega_out"], t)
    inner = slice(2, -2)
    scale = np.max(np.abs(truth["alpha_out"]))
    smooth = np.ones(t.size, bool) if kind == "cardan" else \
        np.abs(np.gradient(fd, t)) < 1e3 * scale               # Geneva: not at the pin's entry and exit kinks
    assert np.max(np.abs(fd - truth["alpha_out"])[inner][smooth[inner]]) < 1e-4 * scale


def test_reading_columns_name_their_units_from_the_dbc(speed, tmp_path):
    """Every quantity column of an exported /stand/ topic names its unit (the DBC signal's, in the display unit):
    the tachogenerator and the displays read rad/s shown in rpm, the pulse count is a bare number."""
    from rig.analysis.export import export_series
    rec, _ = speed
    for topic, header in (("/stand/lab_speed", "t [s],pulses,tacho [rpm]"),
                          ("/stand/lab_display", "t [s],tachometer [rpm],strobe [rpm]")):
        path = export_series(rec.series[topic], tmp_path / "x.csv")
        assert path.read_text(encoding="utf-8").splitlines()[0] == header
    # with its topic, each reading has the decimals its DBC step resolves (0.01 rad/s = 0.0955 rpm: two; a pulse
    # count none), not the 9 digits of 1180.00658, and the same value to that step; the host's times keep theirs
    rows = [line.split(",") for line in export_series(rec.series["/stand/lab_display"], tmp_path / "d.csv",
                                                      topic="/stand/lab_display").read_text().splitlines()[1:]]
    rpm = rec.series["/stand/lab_display"]["tachometer"] * 60 / tau
    assert all(len(r[1].split(".")[1]) == 2 for r in rows) and np.allclose([float(r[1]) for r in rows], rpm, atol=0.005)
    pulses = export_series(rec.series["/stand/lab_speed"], tmp_path / "p.csv", topic="/stand/lab_speed").read_text()
    assert all("." not in line.split(",")[1] for line in pulses.splitlines()[1:])


def test_rig_analyse_merges_the_lab_sheets_numbers(speed, cardan, tmp_path):
    """`rig analyse` over lab recordings: each sheet's result numbers become values lab.<sheet>.<name> with their
    units in the table and the report (merged over the recordings), beside the sheets' console lines."""
    import csv
    from rig.cli import main
    out = tmp_path / "batch"
    assert main(["-q", "analyse", str(speed[0].path), str(cardan[0].path), "-o", str(out)]) == 0
    rows = {r["scene"]: r for r in csv.DictReader((out / "recordings.csv").open())}
    assert set(rows) == {"lab_speed", "lab_cardan"}
    v = cardan[1]["Cardan joint"].values
    assert float(rows["lab_cardan"]["lab.cardan.ratio_max mean"]) == pytest.approx(v["ratio_max"], rel=1e-12)
    assert float(rows["lab_cardan"]["lab.cardan.lag_error_max max [°]"]) == pytest.approx(
        np.degrees(v["lag_error_max"]))                          # display units, as the sheets show them
    counter = speed[1]["Speed measurement"].values["counter_rpm"]
    assert float(rows["lab_speed"]["lab.speed.counter_rpm mean [rpm]"]) == pytest.approx(counter, rel=1e-12)
    assert rows["lab_speed"]["lab.cardan.ratio_max n"] == ""                  # the speed lab has no Cardan
    errors = {k: x for k, x in speed[1]["Speed measurement"].values.items() if k.startswith("error ")}
    assert len(errors) == 3                                        # tachogenerator, tachometer, stroboscope
    for k, x in errors.items():                                    # names in snake case, as documented
        key = "lab.speed." + re.sub(r"\W+", "_", k.lower()).strip("_")
        assert float(rows["lab_speed"][f"{key} mean [%]"]) == pytest.approx(100 * x, rel=1e-12)
    report = (out / "report.md").read_text()
    assert "## Process values and lab results per scene (over all its recordings)" in report
    assert re.search(r"\| lab_cardan( L\d)? \| lab.cardan.ratio_max \|", report)
    assert "lab sheet cardan (cardan joint):" in report and "## Stand and lab recordings (2)" in report


def test_rig_analyse_says_on_the_console_when_a_lab_sheet_cannot_be_made(speed, tmp_path, capsys, monkeypatch):
    """A sheet that cannot be made (e.g. its scene's device file moved away) is one warning line per recording on
    the console, as `rig report` gives it, not only a line in the report."""
    from rig.analysis import lab_report
    from rig.cli import main

    def unreadable(rec):
        raise ValueError("cannot read device description devs/tacho.toml: No such file or directory")
    monkeypatch.setattr(lab_report, "lab_sheets", unreadable)
    assert main(["-q", "analyse", str(speed[0].path), "--executor", "serial", "-o", str(tmp_path / "an")]) == 0
    err = capsys.readouterr().err
    assert f"rig: warning: {speed[0].path}: lab: no sheet (cannot read device description devs/tacho.toml" in err
    assert not list((tmp_path / "an" / "charts").glob("*.png"))     # nothing to draw: no chart (it was an error)


def test_a_recording_without_a_scene_has_no_lab_section(tmp_path):
    """A truncated file that kept no scene is not called a broken lab: no lab section, no warning about it."""
    from rig.analysis.lab_report import lab_section, lab_sheets
    from rig.analysis.report_blocks import ReportContext
    from rig.recorder import Recording
    rec = Recording(path=tmp_path / "cut.mcap")
    assert lab_sheets(rec) is None
    assert lab_section(ReportContext(rec, {"verdicts": []}, tmp_path)) == []


def test_the_lab_report_opens_with_every_sheets_result(cardan, tmp_path):
    from rig.analysis.report import write_report
    text = write_report(cardan[0], tmp_path, fmt="md").read_text()
    summary = text.index("| sheet | result |")
    assert summary < text.index(".png") and f"| Cardan joint | {cardan[1]['Cardan joint'].result}" in text
    sheet = cardan[1]["Cardan joint"]                   # its table as CSV too, listed with the exports
    with open(tmp_path / "lab_cardan.csv", newline="", encoding="utf-8") as f:
        table = list(csv.reader(f))
    assert table == [sheet.headers, *[["" if c == "—" else str(c) for c in row] for row in sheet.rows]]
    assert len(table) > 30 and "lab_cardan.csv" in text[text.index("Exports"):]


def test_the_speed_sheet_reads_the_counters_gate_as_the_counter_does(tmp_path_factory):
    """A gate of 0.5 s given as the override gate_time_ms = 500: the counter counted 0.5 s gates while the sheet
    divided by the description's 1 s (every instrument "+100 % OUTSIDE") and refused a reading at 0.7 s."""
    _, sheets = _run(tmp_path_factory, "lab_speed", lambda s: s.replace(
        'to = "can.LabSpeed.Pulses"\nrate = "50 Hz"\n', 'to = "can.LabSpeed.Pulses"\nrate = "50 Hz"\n'
        'overrides = { gate_time_ms = 500 }\n', 1).replace('readings = ["2.5 s"', 'readings = ["0.7 s"', 1))
    sheet = sheets["Speed measurement"]
    assert "OUTSIDE" not in sheet.result and sheet.result.count("within") == 3


def test_a_cam_follower_that_would_lift_off_is_said(tmp_path_factory, cam):
    """At 700 rpm the contact force the lab cam's law needs goes below zero (−5.6 N: spring and weight no longer hold
    the follower on the cam): the run went on and the sheets compared against a theory assuming contact, without a
    word. Now a follower_lift event per revolution, recorded with the contact force, and a warning with the sheets;
    the shipped 30 rpm run has none."""
    from rig.analysis.lab_report import lift_warning, summary_lines
    rec, sheets = _run(tmp_path_factory, "lab_cam", lambda text: text.replace('speed = "30 rpm"', 'speed = "700 rpm"')
                       .replace('duration = "4.5 s"', 'duration = "1 s"'))
    lifts = [e for e in rec.events if e["kind"] == "follower_lift"]
    force = rec.truth["contact_force"]
    m, k = 0.4, 1500.0                                    # the scene's follower and spring, independently of the plant
    # the closed form on the cycloidal rise (h = 20 mm over 120°) at 700 rpm: F(φ) = m(ω²s'' + g) + k·s + F0
    h, beta, w = 0.02, np.radians(120.0), 700 * 2 * np.pi / 60

    def closed(phi):
        x = phi / beta
        return m * (w * w * h * 2 * np.pi * np.sin(2 * np.pi * x) / beta ** 2 + 9.81) + \
            k * h * (x - np.sin(2 * np.pi * x) / (2 * np.pi)) + 25.0

    from scipy.optimize import minimize_scalar
    least = minimize_scalar(closed, bounds=(np.radians(60), np.radians(120)), method="bounded", options={"xatol": 1e-12})
    worst = min(lifts, key=lambda e: e["force"])
    assert worst["force"] == pytest.approx(least.fun, abs=1e-6) and worst["force"] <= force.min() + 1e-9
    assert np.degrees(worst["min_cam_angle"]) == pytest.approx(np.degrees(least.x), abs=1e-3)      # 88.39°
    assert np.degrees(worst["cam_angle"]) < np.degrees(least.x) - 5.0         # the span starts well before (79.8°)
    assert force.min() < -5.0
    assert np.allclose(force, m * (rec.truth["a"] + 9.81) + k * rec.truth["s"] + 25.0, atol=1e-9)
    assert "the follower would lift off the cam" in summary_lines(list(sheets.values()), rec)[-1]
    assert lift_warning(cam[0]) is None and cam[0].truth["contact_force"].min() > 0.0


def test_a_lift_between_samples_is_found(tmp_path_factory):
    """At 6000 rpm and 600 Hz the cam turns 60° per sample and every sample fell where the law's acceleration is 0:
    the follower lifted off by −4600 N per turn without a word (an audit; 6100 rpm said it). The lift is looked for
    on a grid of at most 1° of cam angle: two spans per turn (the rise's and the return's deceleration)."""
    rec, _ = _run(tmp_path_factory, "lab_cam", lambda text: text.replace('speed = "30 rpm"', 'speed = "6000 rpm"')
                  .replace('duration = "4.5 s"', 'duration = "0.2 s"').replace('sample_rate = "10 kHz"',
                                                                                  'sample_rate = "600 Hz"'))
    lifts = [e for e in rec.events if e["kind"] == "follower_lift"]
    assert rec.truth["contact_force"].min() > 0.0                  # the samples alone show none
    assert len(lifts) >= 2 * 19 and min(e["force"] for e in lifts) < -4000.0


def test_a_lab_cam_with_a_negative_mass_or_spring_is_refused_and_program_errors_are_named_once(tmp_path):
    text = (SCENES / "lab_cam.toml").read_text()
    bad = tmp_path / "bad.toml"
    for old, new, key in (('follower_mass = "0.4 kg"', 'follower_mass = "-0.4 kg"', "follower_mass"),
                          ('spring_rate = "1.5 N/mm"', 'spring_rate = "-1.5 N/mm"', "spring_rate")):
        assert old in text
        bad.write_text(text.replace(old, new))
        with pytest.raises(SceneError, match=rf"\[plant\]: key '{key}'"):
            run_scene(bad, tmp_path / "bad.mcap")
    bad.write_text(text.replace('law = "3-4-5"', 'law = "3-4-6"', 1))
    with pytest.raises(SceneError) as info:
        run_scene(bad, tmp_path / "bad.mcap")
    assert str(info.value).count("bad.toml [plant]") == 1 and "unknown motion law" in str(info.value)


def test_readings_at_a_transducers_output_limit_are_said_not_fitted_as_lag(tmp_path_factory, cam):
    """A 200 mm stroke drives the 100 mm LVDT and the ±5 N·m torque shaft past their ranges: their readings sit at the
    output limits (105 mm, ±5.5 N·m), which the sheets read as "a reading lag of 1.35 ms and an offset of −37 mm"
    without a word. The sheets now say how many readings sit at the limit; the shipped run has none."""
    rec, sheets = _run(tmp_path_factory, "lab_cam", lambda text: text.replace('stroke = "20 mm"', 'stroke = "200 mm"'))
    follower, torque = sheets["Cam follower"].result, sheets["Cam-shaft torque"].result
    at_limit = int(np.count_nonzero(rec.series["/stand/lab_motion"]["displacement"] >= 0.105 - 1e-7))
    assert at_limit > 100 and follower.startswith(f"{at_limit} of ") and "at 105 mm" in follower
    assert "at -5.5 N·m" in torque and "at 5.5 N·m" in torque
    assert all("output limit" not in s.result for s in cam[1].values())


def test_the_work_per_turn_is_compared_with_the_theorys_over_the_same_turns(tmp_path_factory, cam):
    """With a speed ripple the cam's and follower's energy changes over a turn: the sheet said "0 for spring, mass and
    weight" beside 0.0103 J measured, as if it were all the instrument's. The theory over the same turns now stands
    beside it (0.0064 J there); at constant speed it is 0."""
    def ripple(text: str) -> str:
        return text.replace('profile = "constant"', 'profile = "sinusoidal"\namplitude = "10 rpm"\nfrequency = "1.3 Hz"')
    rec, sheets = _run(tmp_path_factory, "lab_cam", ripple)
    values = sheets["Cam-shaft torque"].values
    assert 0.005 < values["work_per_turn_theory"] < 0.008
    assert abs(values["work_per_turn"] - values["work_per_turn_theory"]) < 0.006       # the torque shaft's offset
    assert abs(cam[1]["Cam-shaft torque"].values["work_per_turn_theory"]) < 1e-5


@pytest.mark.parametrize("speed", ['phi0 = "37 deg"', 'profile = "ramp"\nspeed_end = "60 rpm"\nramp_time = "1 s"',
                                   'profile = "sinusoidal"\namplitude = "20 rpm"\nfrequency = "0.7 Hz"',
                                   'sample_rate = "1 kHz"'])
def test_the_sheets_encoder_angles_sit_on_the_disc_lines_from_any_start(tmp_path_factory, speed):
    """Each edge's angle, as the sheets take it, is where the shaft really was at that edge (within 1 % of a count):
    from a start between two lines (37° is 420.98 counts: the sheet added the exact power-on angle to whole counts,
    0.98 count high), from a shaft accelerating at power-on (a ramp, a speed ripple: one count high) and with the
    machine sampling at 1 kHz (the card's start, extrapolated, and the sheet's, from the truth, differed by a count)."""
    from rig.analysis.lab_report import read_lab
    if speed.startswith("sample_rate"):         # the Cardan output at power-on, extrapolated from 1 ms samples: 1e-4
        edit = lambda text: text.replace('sample_rate = "10 kHz"', speed)     # count off its line (both ends agree)
    elif speed.startswith("phi0"):
        edit = lambda text: text.replace('speed = "60 rpm"', f'speed = "60 rpm"\n{speed}')
    else:
        edit = lambda text: text.replace('profile = "constant"', speed).replace('speed = "60 rpm"', 'speed = "30 rpm"'
                                                                                 if "ramp" in speed else 'speed = "60 rpm"')
    rec, _ = _run(tmp_path_factory, "lab_cardan", edit)
    lab = read_lab(rec)
    for signal in ("phi_in", "phi_out"):
        t, angle = lab.angle(signal)
        truth = lab.bench.truth(t)[signal]
        assert t.size > 1000
        np.testing.assert_allclose((angle - truth) / (tau / 4096), 0.0, atol=0.01)


def test_a_counter_that_loses_the_shaft_is_said_with_the_sheets(tmp_path_factory, cardan):
    """At a Cardan angle of 89.9° the output shaft peaks at 60 rpm / cos α ≈ 34 400 rpm: 2.35 M edges/s against the
    counter card's 1 MHz. The card counted illegal transitions and the sheet read a mean ratio of 0.38 (theory 1)
    without a word — the encoder_illegal event was only in the events table. Now a warning beside the sheets; the
    shipped 30° run has none."""
    from rig.analysis.lab_report import lab_warnings, summary_lines
    rec, sheets = _run(tmp_path_factory, "lab_cardan", lambda text: text.replace('shaft_angle = "30 deg"',
                                                                                 'shaft_angle = "89.9 deg"', 1))
    said = [w for w in lab_warnings(rec) if w.startswith("counter Encoder2 counted illegal transitions")]
    assert said and any(line == f"warning: {said[0]}" for line in summary_lines(list(sheets.values()), rec))
    assert lab_warnings(cardan[0]) == []


def test_no_sheet_because_a_counter_lost_the_shaft_says_so(tmp_path):
    """The Geneva bench at 20 000 rpm: both counter cards lose the shaft (encoder_illegal), the sheet finds less than
    a turn — and the console said only that, blaming the run's length (an audit). Now with the counters' warnings."""
    from rig.analysis.stand_summary import NO_SHEET, stand_summary
    scene = tmp_path / "fast_geneva.toml"
    scene.write_text(re.sub(r'(?m)^speed = "484.5 rpm"', 'speed = "20000 rpm"', (SCENES / "lab_geneva.toml").read_text()))
    run_scene(scene, tmp_path / "g.mcap")
    lines = stand_summary(read_recording(tmp_path / "g.mcap")).lines
    assert lines[0].startswith(NO_SHEET)
    assert any(line.startswith("warning: counter Encoder1 counted illegal transitions") for line in lines[1:])


def test_a_counter_that_wraps_is_named_not_the_instruments(tmp_path_factory, speed):
    """A 2000-hole disc at 2500 rpm fills the 16-bit counter (83 333 pulses per 1 s gate, wrapping at 1966 rpm): it
    read 533 rpm and the sheet called all three instruments, each inside its range, ≈ 370 % OUTSIDE (an audit, then a
    review). It says the counter wrapped, and judges no instrument against it."""
    gate = 'to = "can.LabSpeed.Pulses"\nrate = "50 Hz"\n'
    _, sheets = _run(tmp_path_factory, "lab_speed", lambda s: re.sub(
        r'(?m)^speed = "[^"]*"', 'speed = "2500 rpm"', s.replace(gate, gate + "overrides = { holes = 2000 }\n", 1)))
    sheet = sheets["Speed measurement"]
    assert "(the counter wrapped: the instruments read beyond its range of 1966.08 rpm)" in sheet.result
    assert sheet.result.count("(not judged: the counter wrapped)") == 3 and "OUTSIDE" not in sheet.result
    assert any("65536 pulses per gate = 1966.08 rpm, where it wraps" in note for note in sheet.notes)
    assert "wrapped" not in speed[1]["Speed measurement"].result


def test_an_instrument_beyond_its_range_is_said_so_not_judged_by_its_class(tmp_path_factory):
    """At 5000 rpm the mechanical tachometer (a 0…3000 rpm dial) and the tachogenerator (0…3000 rpm) read beyond their
    ranges and were called within their class (an audit); the stroboscope (to 6000 rpm) is still judged."""
    _, sheets = _run(tmp_path_factory, "lab_speed", lambda s: re.sub(r'(?m)^speed = "[^"]*"', 'speed = "5000 rpm"', s))
    result = sheets["Speed measurement"].result
    assert re.search(r"mechanical tachometer [+-]\d+\.\d\d % \(beyond its range \(to 3000 rpm\): no class holds", result)
    assert re.search(r"tachogenerator [+-]\d+\.\d\d % \(beyond its range", result)
    assert re.search(r"stroboscope \(60·f_x\) [+-]\d+\.\d\d % \((within|OUTSIDE) its worst-case", result)


def test_readings_at_their_can_fields_limit_are_counted_and_not_judged(tmp_path_factory, speed):
    """At 52 000 rpm the displays' speeds (5445 rad/s) exceed their CAN fields (±5242.87 rad/s): the unit sends the
    limit, which the sheet called 3.7 % OUTSIDE with no word (a leftover). The host counts the readings at the
    field's limit (a ``reading_at_limit`` event, totals in ``link_summary``), the sheet judges neither display."""
    strobe = 'overrides = { divisor = 1 }'
    rec, sheets = _run(tmp_path_factory, "lab_speed", lambda s: re.sub(
        r'(?m)^speed = "[^"]*"', 'speed = "52000 rpm"', s.replace(strobe, strobe[:-2] + ', range_max = "1e5 rpm" }')))
    result = sheets["Speed measurement"].result
    assert result.count("(not judged: its readings sit at the CAN field's limit)") == 2 and "OUTSIDE" not in result
    first = {e["signal"]: e for e in rec.events if e["kind"] == "reading_at_limit"}
    assert set(first) == {"Tachometer", "Strobe"} and first["Strobe"]["limit"] == pytest.approx(5242.87)
    totals = next(e for e in rec.events if e["kind"] == "link_summary")["readings_at_limit"]
    display = rec.series["/stand/lab_display"]
    assert totals == {"LabDisplay.Tachometer": int(np.sum(display["tachometer"] >= 5242.87 - 0.005)),
                      "LabDisplay.Strobe": int(np.sum(display["strobe"] >= 5242.87 - 0.005))}
    assert totals["LabDisplay.Strobe"] > 200                                   # 50 Hz over 6 s, all but the first
    assert sum("the limit of its CAN field" in w for w in lab_warnings(rec)) == 2
    assert not [e for e in speed[0].events if e["kind"] == "reading_at_limit"]


def test_the_cardan_sheet_interpolates_between_sparse_readings_by_splines(tmp_path_factory):
    """At 3000 rpm the 1 kHz readings lie 18° of input apart: straight lines between them missed the output angle by
    0.18° (h²/8·max|φ2''| = 0.21°) and the ratio by 0.74 % (an audit). Cubic splines through the readings: within
    0.03°; the sheet says the readings lie further apart than its step."""
    _, sheets = _run(tmp_path_factory, "lab_cardan", lambda s: re.sub(r'(?m)^speed = "[^"]*"', 'speed = "3000 rpm"', s))
    sheet = sheets["Cardan joint"]
    assert np.degrees(sheet.values["lag_error_max"]) < 0.03
    assert sheet.values["ratio_error_max"] < 2e-3
    assert "(the readings lie 18° apart, more than the table's step)" in sheet.result
    assert any("The readings lie 18° of input angle apart" in note for note in sheet.notes)


def test_a_cardan_input_that_turns_back_is_named_and_a_geneva_k_m_outside_its_band_is_said(tmp_path_factory,
                                                                                         monkeypatch):
    """An output encoder that counts backwards (mounted the other way round) turns the Cardan's output back: the
    sheet's splines need both shafts turning one way, and say so (a review). A Geneva k_m outside the band a counting
    encoder can see is said so."""
    from rig.analysis import lab_report
    angle = lab_report.Lab.angle
    monkeypatch.setattr(lab_report.Lab, "angle", lambda lab, signal="phi_in": (
        lambda t, phi: (t, -phi if signal == "phi_out" else phi))(*angle(lab, signal)))
    with pytest.raises(ValueError, match="a Cardan shaft turned back"):
        _run(tmp_path_factory, "lab_cardan")
    monkeypatch.setattr(lab_report.Lab, "angle", angle)
    monkeypatch.setattr(lab_report, "_counted_motion_ratio", lambda geneva, count: 0.299)   # a band it lies below
    _, sheets = _run(tmp_path_factory, "lab_geneva")
    assert sheets["Geneva drive"].result.endswith("— OUTSIDE that band)")

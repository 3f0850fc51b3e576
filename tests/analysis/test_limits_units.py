"""Acceptance (issue 12): limits take units — a scene with its limits in mm gives exactly the Cp/Cpk of the
same scene written in SI, a bare number is an error naming the key and the file; every NOK row of
results.csv says why, in the scene's units."""
from __future__ import annotations

import csv
import re
from pathlib import Path

import pytest

from rig.analysis import analyse
from rig.analysis.report import write_report
from rig.recorder import read_recording
from rig.runner import run_scene
from rig.scene import SceneError

SCENE = Path(__file__).resolve().parents[2] / "data" / "scenes" / "pin_insertion.toml"
MM = 'y_min = ["-65 N", "-45 N"]         # peak rod compression at insertion (level 1: -54.6 N)\nx_max = ["41.5 mm", "42.5 mm"]'
CYCLES = 8


def variant(tmp: Path, name: str, limits: str, extra: tuple[tuple[str, str], ...] = ()) -> Path:
    text = SCENE.read_text(encoding="utf-8")
    block = re.search(r'y_min = \["-65 N", "-45 N"\][^\n]*\nx_max = \["41.5 mm", "42.5 mm"\]', text)
    assert block, "the demo scene's limits changed: update this test"
    text = text[:block.start()] + limits + text[block.end():]
    for old, new in extra:
        assert old in text
        text = text.replace(old, new)
    path = tmp / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("limits")
    scenes = {"mm": variant(tmp, "mm", MM),
              "si": variant(tmp, "si", 'y_min = ["-65 N", "-45 N"]\nx_max = ["0.0415 m", "0.0425 m"]'),
              # the force must build up earlier: every curve NOK, for the reasons
              "tight": variant(tmp, "tight", MM, (('range = ["30 mm", "43 mm"]', 'range = ["30 mm", "36.2 mm"]'),))}
    out = {}
    for name, scene in scenes.items():
        run_scene(scene, tmp / f"{name}.mcap", cycles=CYCLES)
        rec = read_recording(tmp / f"{name}.mcap")
        out[name] = (rec, analyse(rec))
    return out


def test_limits_in_mm_give_exactly_the_capability_of_the_si_scene(runs):
    (rec_mm, mm), (rec_si, si) = runs["mm"], runs["si"]
    assert rec_mm.programs[1]["limits"] == rec_si.programs[1]["limits"] == {"y_min": [-65.0, -45.0],
                                                                            "x_max": [0.0415, 0.0425]}
    for name in ("x_max", "y_min"):
        a, b = mm["sets"][1]["values"][name], si["sets"][1]["values"][name]
        assert (a["cp"], a["cpk"]) == (b["cp"], b["cpk"]) and a["cp"] is not None and 0.5 < a["cpk"] < 100
        dev_a, dev_b = rec_mm.statistics[-1]["values"][name], rec_si.statistics[-1]["values"][name]
        assert (dev_a["cp"], dev_a["cpk"]) == (dev_b["cp"], dev_b["cpk"])               # the device's own too
        assert a["cp"] == pytest.approx(dev_a["cp"], rel=1e-4)                          # float32 over CAN
    x = mm["sets"][1]["values"]["x_max"]
    assert (x["unit"], x["lsl"], x["usl"]) == ("mm", 41.5, 42.5)                      # shown as written


def test_a_bare_number_in_the_limits_is_an_error_naming_key_and_file(tmp_path):
    scene = variant(tmp_path, "bare", 'y_min = ["-65 N", "-45 N"]\nx_max = [0.0415, 0.0425]')
    with pytest.raises(SceneError) as err:
        run_scene(scene, tmp_path / "bare.mcap", cycles=1)
    message = str(err.value)
    assert str(scene) in message and "[device.config.limits] key 'x_max' (lower)" in message   # where the scene has it
    assert "has no unit" in message
    assert "it would be 0.0415 m" in message and '"0.0415 mm" or "0.0415 m"' in message   # what it would mean as SI;
    # the unit a scene usually writes first, then another scale


def test_reversed_limits_are_named_where_the_scene_writes_them(tmp_path):
    scene = variant(tmp_path, "reversed", 'y_min = ["-45 N", "-65 N"]')
    with pytest.raises(SceneError, match=r"\[device.config.limits\] key 'y_min': lower limit \"-45 N\" must be below"):
        run_scene(scene, tmp_path / "reversed.mcap", cycles=1)


def test_rig_run_checks_the_scene_before_writing_anything(tmp_path, capsys):
    from rig.cli import main
    scene = variant(tmp_path, "bare2", 'y_min = ["-65 N", "-45 N"]\nx_max = [41.5, 42.5]')
    assert main(["run", str(scene), "-o", str(tmp_path / "bare2.mcap")]) == 2
    assert "[device.config.limits] key 'x_max'" in capsys.readouterr().err
    assert not list(tmp_path.glob("bare2*.png")) and not (tmp_path / "bare2.mcap").exists()


def test_every_nok_row_of_results_csv_says_why_in_the_scenes_units(runs, tmp_path):
    rec, analysis = runs["tight"]
    assert not any(e["kind"] == "verdict_mismatch" for e in rec.events)            # host agrees with the device
    write_report(rec, tmp_path, analysis=analysis)
    with open(tmp_path / "results.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    nok = [r for r in rows if r["ok"] == "0"]
    assert len(rows) == CYCLES and len(nok) == CYCLES
    for r in nok:
        assert r["reason"] and r["failed_elements"]
        for name in r["failed_elements"].split(";"):
            assert f"{name}: " in r["reason"]
        assert re.search(r"-?\d[\d.]* (mm|N)\b", r["reason"]) and " m," not in r["reason"]
    element = next(e for e in rec.results[0]["elements"] if e["name"] == "pierce")
    crossing = re.fullmatch(r"the forward part never crosses y = -45 N falling with x in \[30 mm, 36.2 mm\]; "
                            r"it crosses at x = (\d+\.\d+) mm, outside the range", element["reason"])
    assert crossing and float(crossing[1]) > 36.2, element["reason"]
    text = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert "What failed and why" in text and element["reason"] in text


def test_limits_in_the_wrong_unit_are_named():
    """"41.5 m" written for mm: every value lies outside limits 1000× the data — a warning that says so (and a
    pair of plausible limits, even with every value outside them, is not flagged)."""
    from rig.analysis.sets import set_statistics
    results = [{"number": i, "program": 1, "ok": True, "process_values": {"x_max": 0.0421 + 1e-5 * i}}
               for i in range(10)]
    slip = set_statistics(results, {"x_max": (41.5, 42.5)}, {"x": "m", "y": "N"})["warnings"]
    assert any("x_max: every value lies outside its limits 41.5 … 42.5 m, which are 1.01e+03× the measured values"
               in w and "wrong unit" in w for w in slip)
    plausible = set_statistics(results, {"x_max": (0.0430, 0.0440)}, {"x": "m", "y": "N"})["warnings"]
    assert not any("wrong unit" in w for w in plausible)


def test_an_element_error_is_named_as_the_scene_counts_its_elements(tmp_path):
    """The unit numbers its elements from 0 (elements[0]); the scene's reader counts [[device.config.elements]] tables
    from 1, as the cam program's segments are counted."""
    text = SCENE.read_text(encoding="utf-8")
    assert 'y_min = "-75 N"' in text
    scene = tmp_path / "element.toml"
    scene.write_text(text.replace('y_min = "-75 N"', 'y_min = "-35 N"', 1), encoding="utf-8")
    with pytest.raises(SceneError, match=r"\[\[device.config.elements\]\] no. 1 \(window 'insertion'\): y_min \"-35 N\" "
                                         r"must be below y_max \"-40 N\""):
        run_scene(scene, tmp_path / "element.mcap", cycles=1)
    scene.write_text(text.replace('x_min = "36 mm"', 'x_min = "36 N"', 1), encoding="utf-8")
    with pytest.raises(SceneError, match=r"\[\[device.config.elements\]\] no. 1 \(window 'insertion'\).x_min: '36 N' has "
                                         r"the wrong dimension"):
        run_scene(scene, tmp_path / "element.mcap", cycles=1)

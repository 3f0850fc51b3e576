"""Scene validation and unit parsing: every failure names the key and the file."""
import re
from pathlib import Path

import pytest

from rig.scene import Field, SceneError, load_scene, read_table
from rig.units import UnitError, to_si

SCHEMA = {
    "L3": Field("m", doc="follower length"),
    "k": Field("N/m", default=1190.0),
    "speed": Field("rad/s", default=None),
    "label": Field(None, default="x"),
    "n": Field("1", default=3),
}


@pytest.mark.parametrize("value, unit, si, expected", [
    ("260 mm", None, "m", 0.26),
    (260, "mm", "m", 0.26),
    (1.19, "N_per_mm", "N/m", 1190.0),
    ("150 rpm", None, "rad/s", 5 * 3.141592653589793),
    (25, "N_m", "N*m", 25.0),
    ("90 deg", None, "rad", 3.141592653589793 / 2),
    (3, None, "1", 3.0),
])
def test_to_si_converts(value, unit, si, expected):
    assert to_si(value, si, unit) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("value, unit, message", [
    ("260 kg", None, "wrong dimension"),
    (260, None, "has no unit"),
    ("abc", None, "'abc' is not a quantity with a unit \\(e.g. \"260 mm\"\\)"),
    ("150 rmp", None, "'150 rmp': 'rmp' is not a unit rig knows"),
    (5, "furlongz", "the key's unit 'furlongz' is not a unit rig knows"),
    ("1 mm mm +", None, "cannot read"),
    ("mm", None, "'mm' is not a quantity with a unit \\(e.g. "),         # (read as 1 mm; an audit)
    ("260 mm**", None, "cannot read '260 mm\\*\\*' as a quantity \\(a number and a unit"),
    (True, None, "boolean"),
    ("5 mm", "mm", "already names the unit"),
])
def test_to_si_rejects(value, unit, message):
    with pytest.raises(UnitError, match=message):
        to_si(value, "m", unit, what="L3")


def test_read_table_suffix_and_string_forms_agree():
    a = read_table({"L3_mm": 260, "k_N_per_mm": 1.19}, SCHEMA, "scene.toml [plant]")
    b = read_table({"L3": "0.26 m", "k": "1190 N/m"}, SCHEMA, "scene.toml [plant]")
    assert a["L3"] == pytest.approx(b["L3"]) and a["k"] == pytest.approx(b["k"])
    assert a["label"] == "x" and a["n"] == 3 and a["speed"] is None


@pytest.mark.parametrize("table, message", [
    ({"L3_mm": 260, "L4": "1 m"}, r"unknown key 'L4' \(known keys"),              # nothing close: no guess
    ({"L3_mm": 260, "spede": "1 rpm"}, r"unknown key 'spede' \(did you mean 'speed'\?\) \(known keys"),
    ({"k": "1 N/mm"}, r"missing key 'L3'"),
    ({"L3": "260 N"}, r"key 'L3'.*wrong dimension"),
    ({"L3": "260 mm", "L3_mm": 260}, r"given twice"),
])
def test_read_table_errors_name_key_and_file(table, message):
    with pytest.raises(SceneError, match=message) as info:
        read_table(table, SCHEMA, "demo.toml [plant]")
    assert "demo.toml [plant]" in str(info.value)


def test_load_scene_reports_syntax_errors_and_missing_sections(tmp_path: Path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[plant\nL3 = 1")
    with pytest.raises(SceneError, match="bad.toml: not valid TOML"):
        load_scene(bad)
    good = tmp_path / "good.toml"
    good.write_text('[plant]\nL3 = "260 mm"\n')
    scene = load_scene(good)
    assert scene.read("plant", SCHEMA)["L3"] == pytest.approx(0.26)
    with pytest.raises(SceneError, match=r"good.toml: missing section \[speed\]"):
        scene.section("speed")
    with pytest.raises(SceneError, match="cannot read scene file"):
        load_scene(tmp_path / "absent.toml")


@pytest.mark.parametrize("value, unit, si, message", [
    ("2.5 Hz", None, "rad/s", r"'2.5 Hz' is a frequency, not an angular speed: write revolutions \("),
    ("150 1/min", None, "rad/s", r"'150 1/min' is a frequency, not an angular speed"),
    (2.5, "Hz", "rad/s", r"'2.5 Hz' is a frequency, not an angular speed"),         # speed_Hz = 2.5
    ("150 rpm", None, "Hz", r"'150 rpm' has an angle in its unit, expected something convertible to Hz \(no angle\)"),
    ("100 N*m", None, "N*m/rad", r"has no angle in its unit, expected something convertible to N\*m/rad"),
])
def test_an_angle_pint_counts_as_no_dimension_is_still_checked(value, unit, si, message):
    """pint counts the radian as dimensionless: "2.5 Hz" (150 rpm to an engineer) became 2.5 rad/s, a speed 2π too slow,
    without a word. A frequency for an angular speed is ambiguous (revolutions or radians per second): refused, naming
    both ways to write it; an angle where none belongs is refused too."""
    with pytest.raises(UnitError, match=message):
        to_si(value, si, unit, what="[speed] speed")


@pytest.mark.parametrize("value", ["150 rpm", "2.5 rev/s", "2.5 revolution/s", "900 deg/s", "15.707963267948966 rad/s"])
def test_an_angular_speed_in_revolutions_or_angles_per_time(value):
    assert to_si(value, "rad/s") == pytest.approx(5 * 3.141592653589793, rel=1e-12)


@pytest.mark.parametrize("value, si, message", [
    ("0,05 mm", "m", "has a comma"),                # read 5 mm: the comma was dropped (an audit)
    ("1,89 N/mm", "N/m", "has a comma"),            # read 189 N/mm
    ("1,500 rpm", "rad/s", "has a comma"),          # a thousands separator: as ambiguous
    ("1 500 rpm", "rad/s", "has two numbers side by side"),     # read 500 rpm: pint multiplied 1·500
    ("1 000 mm", "m", "has two numbers side by side"),          # read 0 m
    ("3 2 mm", "m", "has two numbers side by side"),
    ("2 1/2 in", "m", "has two numbers side by side"),            # a mixed fraction: pint read 1 in
    ("1.5 ± 0.1 mm", "m", "has a ±"),                             # read 0.15 mm
    ("1.5 +/- 0.1 mm", "m", "has a ±"),
])
def test_a_number_a_person_and_pint_read_differently_is_refused(value, si, message):
    with pytest.raises(UnitError, match=re.escape(f"stroke: '{value}' {message}")):
        to_si(value, si, what="stroke")


@pytest.mark.parametrize("value, si, expected", [("60 / mm", "1/m", 60000.0), ("1.5e3 mm", "m", 1.5), ("150 1/s", "Hz", 150.0),
                                                 ("10 ** 3 mm", "m", 1.0), ("0.5 * 2 mm", "m", 0.001)])
def test_one_number_with_its_unit_is_still_read(value, si, expected):
    assert to_si(value, si) == pytest.approx(expected)


def test_a_decimal_comma_in_a_scene_names_the_key(tmp_path: Path):
    scene = tmp_path / "s.toml"
    scene.write_text('[plant]\nL3 = "0,26 m"\n')
    with pytest.raises(SceneError, match=r"L3.*'0,26 m' has a comma"):
        load_scene(scene).read("plant", SCHEMA)


def test_a_per_unit_quantity_written_with_a_leading_slash_has_its_unit():
    """"60 / mm" (the demo's clearance_lambda) had no unit for rig analyse and rig sweep: pint reads "/ mm" alone as
    nothing, so two identical machines ("60 / mm", "60000 1/m") were two, and the sweep skipped its unit checks."""
    from rig.analysis.batch import _canonical
    from rig.units import split_quantity, unit_of
    assert split_quantity("60 / mm") == (60.0, "1/ mm") and unit_of("60 / mm") == "1/ mm"
    key = "plant.variation.clearance_lambda"
    assert _canonical({key: '"60 / mm"'}) == _canonical({key: '"60000 1/m"'}) != _canonical({key: '"61 / mm"'})

"""What the console says, in the words and digits a person reads: the statistics table, the theory lag, help texts,
scene errors and output paths."""
from __future__ import annotations

import pytest

from rig import cli


def _value(mean: float, std: float) -> dict:
    return {"n": 50, "unit": "s", "mean": mean, "std": std, "min": mean - 2 * std, "max": mean + 2 * std,
            "minus_3sigma": mean - 3 * std, "plus_3sigma": mean + 3 * std, "cp": None, "cpk": None,
            "spread": std > 0, "trend": {"drift": False}, "normality": {"normal": True}}


def test_the_statistics_table_says_mu_and_sigma_and_gives_each_band_one_precision(capsys):
    cli._print_values({"values": {"duration": _value(0.25511, 0.000693), "y_min": _value(-53.86, 1.94),
                                  "x_max": _value(42.0, 0.0)}})
    header, *rows = capsys.readouterr().out.splitlines()
    assert "μ−3σ..μ+3σ" in header and " σ " in header and "-3s" not in header and "sigma" not in header
    bands = [row.split()[7] for row in rows]
    assert bands == ["0.25303..0.25719", "-59.7..-48.0", "42.00..42.00"]   # 3 digits of the 6σ width; σ = 0: the mean's
    for band in bands:
        lo, hi = band.split("..")
        assert len(lo.split(".")[1]) == len(hi.split(".")[1])


def test_limits_no_value_meets_are_said_not_capable_not_n_a(capsys):
    """σ = 0 makes Cp/Cpk infinite, which says nothing — unless the one value lies beyond a limit (Cpk = −∞): then
    every value is outside, and the console and the report's capability table say so."""
    from rig.analysis.report import _capability, _indices
    inside = {**_value(42.0, 0.0), "cp": float("inf"), "cpk": float("inf"), "lsl": 41.5, "usl": 42.5}
    outside = {**_value(41.86, 0.0), "cp": float("inf"), "cpk": float("-inf"), "lsl": 50.0, "usl": 60.0}
    cli._print_values({"values": {"x_ok": inside, "x_max": outside}})
    out = capsys.readouterr().out.splitlines()
    assert out[1].split()[-4:-2] == ["n/a", "n/a"] and out[2].split()[-4:-2] == ["n/a", "-inf"]
    assert out[3] == "  x_max: NOT capable, every value outside its limits (Cpk -inf)"
    assert _capability(inside).startswith("n/a: no spread") and _indices(inside) == ["n/a", "n/a"]
    assert _capability(outside) == "NOT capable: every value outside the limits" and _indices(outside) == ["n/a", "−∞"]


def test_the_theory_lag_is_in_degrees_like_every_other_angle(capsys):
    result = {"verdicts": [], "incomplete": [], "not_recorded": [], "sets": {}, "events": {},
              "theory": [{"signal": "x", "curve": 1, "lag_time": 2.47e-3, "lag_angle": 0.03892}]}
    cli._print_set_summary(result)
    out = capsys.readouterr().out
    assert "X 2.47 ms = 2.23° of cam angle" in out and "deg" not in out


def _arguments(parser, name="rig"):
    import argparse
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub, p in action.choices.items():
                yield from _arguments(p, f"{name} {sub}")
        elif not isinstance(action, argparse._HelpAction):
            yield name, action


def test_every_argument_has_help_and_an_optional_scene_names_its_default():
    """`rig run -h` showed 'scene' with no word; cam-design's "cam-bar scene (default data/scenes/...)" is the
    model."""
    arguments = list(_arguments(cli.build_parser()))
    assert not [(name, a.dest) for name, a in arguments if not a.help]
    for name, a in arguments:
        if a.dest in ("scene", "recording"):
            assert ("(default " in a.help) == (a.default is not None), (name, a.help)
            assert a.default is None or "data/scenes/" in a.help
    report = {a.dest: a for name, a in arguments if name == "rig report"}
    assert "without .mcap" in report["output"].help


@pytest.mark.parametrize("line, message", [
    ('clearance = "-0.05 mm"', "[plant]: key 'clearance' must not be negative (groove clearance), got \"-0.05 mm\""),
    ("clearance_mm = -0.05", "key 'clearance_mm' must not be negative (groove clearance), got -0.05 mm"),
    ("sensor_position = 5.0", "key 'sensor_position' must be between 0 and 1 (the rod-force sensor's place along the "
                              "rod: 0 at the follower joint C, 1 at the slider joint D), got 5.0"),
    ('l4 = "0 mm"', "key 'l4' must be positive, got \"0 mm\""),
])
def test_a_scene_value_out_of_range_is_named_as_the_scene_wrote_it(tmp_path, line, message):
    """Was "cam-bar parameter clearance must not be negative, got -5e-05 m" (SI, not the scene's mm) and
    "sensor_position … got 5.0" without the range."""
    import re

    from rig.plants.cam_bar.scene_io import mechanism_from_scene
    from rig.scene import SceneError, load_scene
    key = line.split()[0].split("_mm")[0]
    text = re.sub(rf"(?m)^{key} = .*$", line, cli.DEFAULT_SCENE.read_text(), count=1)
    scene = tmp_path / "bad.toml"
    scene.write_text(text)
    with pytest.raises(SceneError) as info:
        mechanism_from_scene(load_scene(scene))
    assert str(info.value) == f"{scene} [plant]: {message.removeprefix('[plant]: ')}"


def test_a_word_where_a_quantity_belongs_is_not_unit_library_jargon():
    from rig.units import UnitError, to_si
    with pytest.raises(UnitError) as info:
        to_si("fast", "rad/s", what="x.toml [speed]: key 'speed'")
    assert str(info.value) == "x.toml [speed]: key 'speed': 'fast' is not a quantity with a unit (e.g. \"150 rpm\")"
    assert "registry" not in str(info.value)


def test_field_ranges_say_what_the_value_must_be():
    from rig.scene import Field
    assert Field("m", minimum=0.0).out_of_range(-1.0) == "must not be negative"
    assert Field("m", positive=True).out_of_range(0.0) == "must be positive"
    assert Field("1", minimum=0.0, maximum=1.0).out_of_range(1.5) == "must be between 0 and 1"
    assert Field("m", minimum=0.001).out_of_range(0.0) == "must be at least 0.001 m"
    assert Field("1", maximum=2.0).out_of_range(3.0) == "must be at most 2"
    assert Field("m", positive=True, maximum=1.0).out_of_range(0.0) == "must be above 0 m and at most 1 m"
    assert Field("1", minimum=0.0, maximum=1.0).out_of_range(0.5) is None


@pytest.mark.parametrize("name, suggested", [("x.txt", "x.mcap"), ("noext", "noext.mcap")])
def test_a_recording_must_be_named_mcap(tmp_path, capsys, name, suggested):
    """`-o x.txt` wrote an MCAP file named .txt; now refused before anything runs, with the name to use."""
    out = tmp_path / name
    assert cli.main(["-q", "run", "--cycles", "1", "--no-report", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == (f"rig: error: cannot write the recording to {out}: a recording is an MCAP file, its name must end "
                   f"in .mcap (e.g. {tmp_path / suggested})\n")
    assert not out.exists() and not list(tmp_path.iterdir())
    assert cli.main(["-q", "record", str(cli.DEFAULT_SCENE), "--can-port", "1", "-o", str(out)]) == 2
    assert "a recording is an MCAP file" in capsys.readouterr().err


def test_a_new_folder_for_the_recording_is_made_and_said(tmp_path, capsys):
    out = tmp_path / "new" / "deeper" / "x.mcap"
    assert cli.main(["-q", "run", "--cycles", "1", "--no-report", "-o", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    said = [line for line in lines if line.startswith("recorded ")]
    # both folders were made: it said only the innermost (an audit)
    assert said[0].endswith(f"-> {out} (created the folders {tmp_path / 'new'} … {out.parent})") and out.exists()
    assert sum("created the folder" in line for line in lines) == 1     # not also on the cycle chart's line
    again = tmp_path / "new" / "other" / "y.mcap"
    assert cli.main(["-q", "run", "--cycles", "1", "--no-report", "-o", str(again)]) == 0
    assert f"-> {again} (created the folder {again.parent})" in capsys.readouterr().out
    assert cli.main(["-q", "run", "--cycles", "1", "--no-report", "-o", str(out)]) == 0       # it exists now
    assert [line for line in capsys.readouterr().out.splitlines() if line.startswith("recorded ")][0].endswith(
        f"-> {out}")

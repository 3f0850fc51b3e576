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


def test_the_theory_lag_is_in_degrees_like_every_other_angle(capsys):
    result = {"verdicts": [], "incomplete": [], "sets": {}, "events": {},
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

"""Why an element failed: the rule, where (with units), the failure point; the same evaluation on a host."""
import numpy as np
import pytest

from firmware_sim.digiforce.elements import build_elements, normalize_elements, unit_format
from firmware_sim.digiforce.evaluation import Reevaluation

WIN = {"kind": "window", "name": "W", "x_min": 1.0, "x_max": 2.0, "y_min": 1.0, "y_max": 2.0}


def check(cfg, x, y, fmt=None):
    element = build_elements(normalize_elements([cfg], {"x": "m", "y": "N"}, "test"), fmt)[0]
    return element.check(np.asarray(x, float), np.asarray(y, float))


def test_reasons_name_rule_place_and_units():
    mm = lambda ch, v: f"{v * 1e3:.4g} mm" if ch == "x" else f"{v:.4g} N"    # a host's display units
    c = check(WIN | {"entry": "left", "exit": "right"}, [1.5, 1.5, 3.0], [0.0, 1.5, 1.5], mm)
    assert not c.ok and c.reason == "entry left: entered through the bottom side at x = 1500 mm, y = 1 N, not through the left"
    assert c.at == (1.5, 1.0)
    c = check(WIN | {"entry": "left", "exit": "right"}, [1.5, 1.5, 3.0], [0.0, 1.5, 1.5], unit_format({"x": "m", "y": "N"}))
    assert "at x = 1.5 m, y = 1 N" in c.reason


def test_check_reason_says_which_bound_and_marks_the_extreme():
    cfg = WIN | {"entry": "ignore", "exit": "ignore", "check": "y_min"}
    c = check(cfg, [0.5, 1.5, 2.5], [1.5, 0.2, 1.5])
    assert c.reason == "check y_min: y min 0.2 at x = 1.5 lies below the window (y min 1)" and c.at == (1.5, 0.2)
    c = check(cfg | {"check": "x_max"}, [0.5, 1.5, 2.5], [1.5, 1.5, 2.5])
    assert c.reason == "check x_max: x max 2.5 at y = 2.5 lies right of the window (x max 2) and above the window (y max 2)"
    trap = {"kind": "trapezoid", "name": "T", "axis": "y", "start": 0.0, "end": 2.0, "lower": [0.0, 1.0],
            "upper": [1.0, 2.0], "entry": "ignore", "exit": "ignore", "check": "y_max"}
    assert check(trap, [0.5, 1.0, 1.5], [0.5, 3.0, 1.5]).reason.endswith("lies beyond the top side of the trapezoid")


def test_reasons_name_the_curve_part():
    cfg = WIN | {"entry": "left", "exit": "right", "part": "forward"}
    c = check(cfg, [0.0, 1.5], [1.5, 1.5])
    assert c.reason == "exit right: the forward part ends inside the window, at x = 1.5, y = 1.5; it must leave through the right"
    assert c.at == (1.5, 1.5)


def test_threshold_reason_gives_the_closest_approach_or_the_crossings():
    th = {"kind": "threshold", "name": "S", "axis": "y", "value": 1.0, "direction": "rising"}
    c = check(th, [0, 1, 2, 3], [0.0, 0.6, 0.9, 0.5])
    assert c.reason == "the curve never crosses y = 1 rising; closest y = 0.9 at x = 2" and c.at == (2.0, 0.9)
    c = check(th | {"range": [2.0, 3.0]}, [0, 1, 2], [0.0, 1.5, 0.0])
    assert c.reason == "the curve never crosses y = 1 rising with x in [2, 3]; it crosses at x = 0.666667, outside the range"
    assert c.at == pytest.approx((2 / 3, 1.0))
    c = check(th | {"range": [5.0, 6.0]}, [0, 1, 2], [0.0, 0.5, 0.2])      # a curve cut short of the range
    assert c.reason == ("the curve never crosses y = 1 rising with x in [5, 6]; the curve never reaches that range "
                        "(x spans 0 … 2)") and c.at == (2.0, 0.2)


def test_envelope_reason_marks_the_pair():
    env = {"kind": "envelope", "name": "E", "references": [{"x": [0.0, 1.0], "y": [0.0, 1.0]}], "dy": 0.1}
    c = check(env, [0.0, 0.5, 1.0], [0.0, 0.9, 1.0])
    assert c.reason == "pair 1 at x = 0.5, y = 0.9 lies above the envelope [0.4, 0.6]" and c.at == (0.5, 0.9)


def test_host_reevaluation_reproduces_the_units_verdicts(unit, press):
    elements = [{"kind": "window", "name": "W_mid", "part": "forward", "x_min": 1.5, "x_max": 2.5, "y_min": 0.2,
                 "y_max": 1.5, "entry": "left", "exit": "right"},
                {"kind": "window", "name": "W_off", "enabled": False, "x_min": 10, "x_max": 11, "y_min": 0, "y_max": 1},
                {"kind": "threshold", "name": "S_ret", "part": "return", "axis": "x", "value": 2.0,
                 "direction": "falling"},
                {"kind": "window", "name": "W_peak", "x_min": 3.5, "x_max": 4.5, "y_min": 2.5, "y_max": 3.5,
                 "entry": "ignore", "exit": "ignore", "check": "y_max"}]
    unit.set_program(0, {"elements": elements, "reference": {"mode": "y_threshold", "y_threshold": 0.75}})
    host = Reevaluation(unit.get_program(0), unit_format({"x": "m", "y": "N"}))
    t, x, y = press()
    for k, scale in enumerate((1.0, 1.5, 0.1)):       # X referenced (shifted): the last never reaches the reference
        unit.start()
        unit.feed(t + k, x, scale * y)
        r = unit.stop()
        mine = host.verdicts(r.curve.t, r.curve.x, r.curve.y)
        assert [(v.name, v.ok, v.reason) for v in mine] == [(e.name, e.ok, e.reason) for e in r.elements], scale
        assert [v.name for v in mine if not v.ok] == [["W_mid", "S_ret", "W_peak"], ["W_mid", "W_peak"],
                                                      ["reference", "W_mid", "W_peak"]][k]
    assert [v.name for v in mine][:1] == ["reference"] and not mine[0].ok


def test_a_second_entry_says_where_the_curve_went_out_in_between():
    """Entered through the top, dipped below y min, came back through the bottom: the reason names the dip's depth
    beyond the violated limit (the real violation), not only the two entries."""
    c = check(WIN | {"entry": "top", "exit": "ignore"}, [1.2, 1.3, 1.5, 1.6, 1.7], [2.5, 1.5, 0.7, 1.4, 1.5])
    assert not c.ok
    assert c.reason.startswith("entry top: the curve entered the window 2 times (exactly once allowed): through the "
                               "top (y max 2)")
    assert c.reason.endswith("; in between it went below the window (y min 1) to y = 0.7 at x = 1.5, 0.3 beyond")
    trap = {"kind": "trapezoid", "name": "T", "axis": "y", "start": 0.0, "end": 3.0, "lower": [1.0, 1.0],
            "upper": [2.0, 2.0], "entry": "left", "exit": "ignore"}
    c = check(trap, [-0.5, 0.5, 1.0, 1.5, 2.0], [1.5, 1.5, 0.5, 1.5, 1.5])
    assert c.reason.endswith("; in between it went beyond the bottom side of the trapezoid to x = 1, y = 0.5")

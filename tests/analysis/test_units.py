"""Display units: what the scene writes decides, documented fallbacks otherwise; statistics in display units."""
import numpy as np
import pytest

from rig.analysis.sets import set_statistics
from rig.analysis.units import display_units, recording_units, unit, written_units
from rig.recorder import Recording

PROGRAM = {"channels": {"x": {"unit": "m"}, "y": {"unit": "N"}, "y2": {"enabled": False}},
           "elements": [{"kind": "threshold", "name": "S", "axis": "y", "value": -45.0}]}


def test_the_scene_decides_the_channel_units():
    config = {"control": {"start": {"mode": "x", "value": "1 mm"}}, "sampling": {"delta": "0.1 ms"},
              "elements": [{"kind": "window", "x_min": "3.6 cm", "x_max": "43 mm", "y_min": "-0.075 kN",
                            "y_max": "-40 N"}], "limits": {"y_min": ["-75 N", "-55 N"]}}
    assert written_units(config, "m") == "millimeter" and written_units(config, "N") == "newton"
    du = display_units(PROGRAM, config)
    assert (du.channel("x").label, du.channel("x").factor, du.channel("y").label) == ("mm", 1000.0, "N")
    assert du.value("x_max").label == "mm" and du.value("S.at").label == "mm" and du.value("duration").label == "s"
    assert du.value("pairs").label == ""
    inch = display_units(PROGRAM, {"limits": {"x_max": ["1.6 in", "1.7 in"]}})
    assert inch.channel("x").label == "in" and inch.channel("x")(0.0254) == pytest.approx(1.0)
    assert inch.signal("s").label == "in"                       # truth lengths follow the length channel
    kn = display_units(PROGRAM, {"elements": [{"y_min": "-0.075 kN", "y_max": "-0.04 kN", "x_min": "3 mm"}]})
    assert kn.channel("y").label == "kN" and kn.channel("y").text(-75.0) == "-0.075 kN"


def test_fallbacks_by_dimension():
    du = display_units(PROGRAM, None)                            # nothing written: the defaults
    assert (du.channel("x").label, du.channel("y").label) == ("mm", "N")
    assert du.signal("psi").label == "°" and du.signal("psi")(np.pi) == pytest.approx(180.0)
    assert du.signal("omega").label == "rpm" and du.signal("omega")(2 * np.pi) == pytest.approx(60.0)
    assert du.signal("M_sigma").label == "N·m" and du.signal("F_rod").label == "N"
    assert du.signal("unheard_of").label == "SI"
    assert unit("rad").text(np.pi / 2) == "90°" and unit("N*m").text(-3.852) == "-3.852 N·m"
    assert unit("m").axis("displacement") == "displacement (mm)"
    rec = Recording(path=None, scene_text='[device]\nprogram = 2\n[device.config.limits]\nx_max = ["2 in", "3 in"]\n',
                    programs={1: PROGRAM, 2: PROGRAM})
    assert recording_units(rec, 2).channel("x").label == "in" and recording_units(rec, 1).channel("x").label == "mm"


def test_statistics_in_display_units_capability_unchanged():
    rng = np.random.default_rng(3)
    results = [{"number": k, "program": 1, "ok": True, "elements": [],
                "process_values": {"x_max": float(rng.normal(0.0422, 5e-5)), "y_min": float(rng.normal(-65, 2))}}
               for k in range(1, 61)]
    limits = {"x_max": (0.0415, 0.0425), "y_min": (-75.0, -55.0)}
    si = set_statistics(results, limits, {"x": "m", "y": "N"})["values"]
    shown = set_statistics(results, limits, display_units(PROGRAM, {"limits": {"x_max": ["41.5 mm", "42.5 mm"]}}))
    x, x_si = shown["values"]["x_max"], si["x_max"]
    assert (x["unit"], x["unit_ascii"], x["factor"], x_si["unit"]) == ("mm", "mm", 1000.0, "m")
    assert (x["lsl"], x["usl"]) == (41.5, 42.5) and x["mean"] == pytest.approx(1000 * x_si["mean"], rel=1e-12)
    assert x["std"] == pytest.approx(1000 * x_si["std"], rel=1e-12)
    assert x["cp"] == pytest.approx(x_si["cp"], rel=1e-12) and x["cpk"] == pytest.approx(x_si["cpk"], rel=1e-12)
    assert shown["values"]["y_min"]["cp"] == si["y_min"]["cp"]


def test_an_energy_is_shown_in_joules_not_as_a_torque():
    """Work per turn ∮M dφ (J) read "N·m" in rig analyse's table (J and N·m share a dimension) while rig run printed J."""
    from rig.analysis.lab_report import shown_value
    from rig.analysis.units import unit
    assert (unit("J").label, unit("N*m").label) == ("J", "N·m")
    assert shown_value("work_per_turn", 0.0037) == (0.0037, "J")
    assert shown_value("work_per_turn_theory", 0.0037) == (0.0037, "J")      # a theory beside its value: same unit


def test_without_a_program_read_back_the_scene_config_gives_the_channel_units():
    """The serial link off: no program attachment. The report, results.csv and curves.csv showed an angle channel as
    mm and a torque as N (the unit's factory X and Y); the scene's [device.config] says rad and N·m, written in °."""
    config = {"channels": {"x": {"unit": "rad", "scaling": {"electrical": "10 V", "engineering": "340 deg"}},
                           "y": {"unit": "N*m", "scaling": {"electrical": "5 V", "engineering": "50 N*m"}}}}
    du = display_units(None, config)
    assert (du.channel("x").si, du.channel("x").label, du.channel("y").si) == ("rad", "°", "N*m")
    assert du.value("x_max").label == "°" and du.value("y_min").label == "N·m"
    plain = display_units(None, {"channels": {"y2": {"enabled": False}}})       # nothing configured: factory m, N
    assert (plain.channel("x").si, plain.channel("y").si) == ("m", "N") and "y2" not in plain.channels
    rec = Recording(path=None, scene_text='[device.config.channels.x]\nunit = "rad"\n'
                                          'scaling = { electrical = "10 V", engineering = "340 deg" }\n')
    assert recording_units(rec, 0).channel("x").label == "°"       # [device] program defaults to 0, as the run's

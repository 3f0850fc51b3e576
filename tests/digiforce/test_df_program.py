"""Programs (validation, storage, selection), identity, statistics against numpy, description file."""
import json

import numpy as np
import pytest

from firmware_sim.digiforce import DigiForce, DigiForceError
from firmware_sim.digiforce.description import DEFAULT_PATH, load_description


def test_identity_and_programs():
    dev = DigiForce()
    assert dev.identify() == "SIM DIGIFORCE 9310,SN0001,FW1.0"
    assert dev.n_programs == 16 and dev.active_program == 0
    dev.select_program(15)
    assert dev.active_program == 15 and dev.status()["program"] == 15
    for bad in (16, -1, "3", 1.0, True):
        with pytest.raises(DigiForceError, match="program number must be an integer 0...15"):
            dev.select_program(bad)


def test_program_roundtrip_is_json_and_normalised():
    dev = DigiForce()
    dev.set_program(3, {"name": "press-fit", "channels": {"x": {"cutoff": "200 Hz"}},
                        "elements": [{"kind": "window", "name": "W", "x_min": "10 mm", "x_max": "20 mm",
                                      "y_min": "0.1 kN", "y_max": 300}]})
    p = dev.get_program(3)
    assert json.loads(json.dumps(p)) == p
    assert p["channels"]["x"]["cutoff"] == 200.0 and p["elements"][0]["x_min"] == pytest.approx(0.01)
    assert p["elements"][0]["y_min"] == pytest.approx(100.0) and p["elements"][0]["entry"] == "any"
    dev.set_program(5, p)
    assert dev.get_program(5) == p
    assert dev.get_program(0)["name"] == "program 0"      # others untouched


@pytest.mark.parametrize("config, message", [
    ({"colour": 1}, "program 2: unknown key 'colour'"),
    ({"channels": {"y": {"range": "3 mV/V"}}}, "channels.y.range: 0.003 is not one of the unit's steps"),
    ({"channels": {"y": {"range": "2 V"}}}, "channels.y.range.*wrong dimension"),
    ({"channels": {"y": {"excitation": "10 V"}}}, "channels.y.excitation: 10 is not one of"),
    ({"channels": {"y": {"sensor_resistance": "100 ohm"}}}, "sensor_resistance: 100 ohm outside"),
    ({"channels": {"x": {"sensor_resistance": "700 ohm", "excitation": 5}}}, None),
    ({"channels": {"x": {"input": "bridge"}}}, "channels.x.input: 'bridge' is not one of 'voltage'"),
    ({"channels": {"y": {"unit": "kN"}}}, "engineering unit must be coherent SI"),
    ({"channels": {"y": {"unit": "blorps"}}}, "unknown unit 'blorps'"),
    ({"channels": {"y": {"scaling": {"electrical": 0}}}}, "non-zero"),
    ({"channels": {"y": {"scaling": {"mode": "teach", "points": [[0, 0]]}}}}, "two \\[electrical, engineering\\]"),
    ({"control": {"start": {"mode": "laser"}}}, "control.start.mode: 'laser' is not one of"),
    ({"control": {"stop": {"mode": "time"}}}, "control.stop: missing key 'duration'"),
    ({"control": {"stop": {"mode": "time", "duration": "-1 s"}}}, "duration: must be > 0"),
    ({"control": {"start": {"mode": "y", "value": 10}}, "channels": {"y": {"tare_at_start": True}}},
     "cannot tare the channel that triggers the start"),
    ({"sampling": {"mode": "dx"}}, "sampling: missing key 'delta'"),
    ({"sampling": {"overflow": "wrap"}}, "sampling.overflow: 'wrap' is not one of 'stop', 'decimate'"),
    ({"reference": {"mode": "y_threshold"}}, "reference: missing key 'y_threshold'"),
    ({"limits": {"y_mean": [0, 1]}}, "limits: 'y_mean' is not a process value"),
    ({"limits": {"y_max": [2, 1]}}, "lower limit 2 N must be below upper limit 1 N"),
    ({"limits": {"x_max": ["42.5 mm", "41.5 mm"]}}, 'lower limit "42.5 mm" must be below upper limit "41.5 mm"'),
    ({"elements": [{"kind": "window", "name": "A", "x_min": 0, "x_max": 1, "y_min": 0, "y_max": 1}] * 2},
     "element names must be unique"),
])
def test_program_validation_errors_name_the_key(config, message):
    dev = DigiForce()
    before = dev.get_program(2)
    if message is None:                                  # 5 V into 700 ohm = 7.1 mA: within the 8 mA supply
        dev.set_program(2, config)
        return
    with pytest.raises(DigiForceError, match=message):
        dev.set_program(2, config)
    assert dev.get_program(2) == before                  # a refused program changes nothing


def test_supply_current_limit():
    import tomllib
    data = tomllib.loads(DEFAULT_PATH.read_text())
    data["inputs"]["voltage"]["resistance_min"] = "100 ohm"   # a description that lets the current decide
    dev = DigiForce(data)
    dev.set_program(0, {"channels": {"x": {"sensor_resistance": "625 ohm"}}})
    with pytest.raises(DigiForceError, match="draws 8.33 mA, more than the input's 8 mA"):
        dev.set_program(0, {"channels": {"x": {"sensor_resistance": "600 ohm"}}})


def test_switching_mode_drops_old_settings():
    dev = DigiForce()
    dev.set_program(0, {"control": {"start": {"mode": "x", "value": 0.01}}})
    dev.set_program(0, {"control": {"start": {"mode": "command"}}})
    assert dev.get_program(0)["control"]["start"] == {"mode": "command"}


def test_description_file_and_errors(tmp_path):
    d = load_description(DEFAULT_PATH)
    assert d.max_rate == 100_000 and d.curve_memory == 4000 and d.evaluation_time == pytest.approx(0.09)
    assert d.cutoff_steps[0] == 5 and d.cutoff_steps[-1] == 5000
    assert d.inputs["bridge"].accuracy == 0.005 and d.inputs["voltage"].accuracy == 0.004
    bad = tmp_path / "bad.toml"
    bad.write_text(DEFAULT_PATH.read_text().replace('max_rate = "100 kHz"', 'max_rate = "100 kg"'))
    with pytest.raises(DigiForceError, match="max_rate.*wrong dimension"):
        DigiForce(str(bad))
    with pytest.raises(DigiForceError, match="cannot read device description"):
        DigiForce(str(tmp_path / "missing.toml"))


def run_curves(dev, press, peaks):
    t0, results = 0.0, []
    for peak in peaks:
        t, x, y = press(peak=peak)
        dev.start()
        dev.feed(t + t0, x, y)
        results.append(dev.stop())
        t0 += t[-1] + 1.0
    return results


def test_statistics_against_numpy(unit, press):
    unit.set_program(0, {"elements": [{"kind": "threshold", "name": "S", "axis": "y", "value": 3.0}],
                         "limits": {"y_max": [2.0, 4.0], "S.at": [None, 4.1]}})
    peaks = np.random.default_rng(5).normal(3.0, 0.3, 25)
    results = run_curves(unit, press, peaks)
    st = unit.statistics()
    assert json.loads(json.dumps(st)) == st
    ymax = np.array([r.process_values["y_max"] for r in results])
    assert ymax == pytest.approx(peaks, abs=2e-4)         # peak force seen at full stroke
    v = st["values"]["y_max"]
    assert v["mean"] == pytest.approx(ymax.mean(), rel=1e-12)
    assert v["std"] == pytest.approx(ymax.std(ddof=1), rel=1e-12)
    assert (v["min"], v["max"]) == (ymax.min(), ymax.max())
    s = ymax.std(ddof=1)
    assert v["cp"] == pytest.approx(2.0 / (6 * s), rel=1e-12)
    assert v["cpk"] == pytest.approx(min(4.0 - ymax.mean(), ymax.mean() - 2.0) / (3 * s), rel=1e-12)
    at = np.array([r.process_values["S.at"] for r in results])
    at = at[~np.isnan(at)]                                            # undefined where S failed
    assert st["values"]["S.at"]["n"] == at.size == st["ok"]
    assert st["values"]["S.at"]["cp"] is None                          # one-sided limit: only Cpk
    assert st["values"]["S.at"]["cpk"] == pytest.approx((4.1 - at.mean()) / (3 * at.std(ddof=1)), rel=1e-9)
    n_ok = int(np.sum(peaks >= 3.0 - 1e-4))                            # threshold S passes iff peak reaches 3
    assert abs(st["ok"] - n_ok) <= 1 and st["total"] == 25 and st["nok"] == 25 - st["ok"]
    assert st["elements"]["S"] == {"ok": st["ok"], "nok": st["nok"]}
    unit.reset_statistics()
    assert unit.statistics()["total"] == 0 and unit.statistics()["values"] == {}
    assert unit.statistics(3)["total"] == 0


def test_limits_carry_the_units_of_their_process_values():
    dev = DigiForce()
    dev.set_program(1, {"elements": [{"kind": "threshold", "name": "S", "axis": "y", "value": "2 N"}],
                        "limits": {"x_max": ["41.5 mm", "42.5 mm"], "y_min": ["-0.075 kN", "-55 N"],
                                   "duration": [None, "250 ms"], "pairs": [10, None], "S.at": ["1 cm", None]}})
    limits = dev.get_program(1)["limits"]
    assert limits["x_max"] == [0.0415, 0.0425] and limits["y_min"] == [-75.0, -55.0]
    assert limits["duration"] == [None, 0.25] and limits["pairs"] == [10.0, None] and limits["S.at"] == [0.01, None]
    with pytest.raises(DigiForceError, match=r"limits.x_max \(lower\): '41.5 N' has the wrong dimension"):
        dev.set_program(1, {"limits": {"x_max": ["41.5 N", "42.5 mm"]}})
    with pytest.raises(DigiForceError, match=r"limits.S.at \(lower\).*wrong dimension"):
        dev.set_program(1, {"limits": {"S.at": ["1 N", None]}})     # a Y threshold's crossing lies on X


def test_a_program_written_by_a_person_needs_units_the_interface_takes_si():
    dev = DigiForce()
    dev.set_program(1, {"limits": {"x_max": [0.0415, 0.0425]}})      # the unit's interfaces: SI numbers
    assert dev.get_program(1)["limits"]["x_max"] == [0.0415, 0.0425]
    with pytest.raises(DigiForceError, match=r'program 2.limits.x_max \(lower\): 0.0415 has no unit \(a bare number '
                                             r'is not read as SI here: it would be 0.0415 m\); write it with the unit '
                                             r'you mean, e.g. "0.0415 mm" or "0.0415 m"'):
        dev.set_program(2, {"limits": {"x_max": [0.0415, 0.0425]}}, units_required=True)
    with pytest.raises(DigiForceError, match=r"program 2.control.start.value: 0.001 has no unit"):
        dev.set_program(2, {"control": {"start": {"mode": "x", "value": 0.001}}}, units_required=True)
    with pytest.raises(DigiForceError, match=r"elements\[0\] \(window 'W'\).y_max: 2 has no unit"):
        dev.set_program(2, {"elements": [{"kind": "window", "name": "W", "x_min": "1 mm", "x_max": "2 mm",
                                          "y_min": "1 N", "y_max": 2}]}, units_required=True)
    assert dev.get_program(2) == DigiForce().get_program(2)          # refused: nothing changed
    # the unit's own (normalised, SI) settings are not the person's: a second scene-style change is fine
    dev.set_program(2, {"limits": {"x_max": ["41.5 mm", "42.5 mm"]}, "sampling": {"delta": "0.2 ms"}},
                    units_required=True)
    dev.set_program(2, {"name": "again", "limits": {"y_max": ["1 N", "2 N"]}}, units_required=True)
    assert dev.get_program(2)["limits"] == {"x_max": [0.0415, 0.0425], "y_max": [1.0, 2.0]}
    dev.set_program(2, {"limits": {"pairs": [10, 4000]}}, units_required=True)   # a count needs no unit


def test_envelope_references_take_units_like_every_other_value():
    """A reference curve written in mm and N gives the same band as the same curve in SI; bare numbers in a
    scene are refused naming the key; the unit's SI interface keeps taking plain numbers."""
    env = {"kind": "envelope", "name": "E", "dx": "0.1 mm", "dy": "5 N"}
    si = {"x": [0.040, 0.041, 0.042], "y": [-10.0, -50.0, -70.0]}
    dev = DigiForce()
    dev.set_program(1, {"elements": [env | {"references": [si]}]})
    dev.set_program(2, {"elements": [env | {"references": [{"x": [40, 41, 42], "x_unit": "mm",
                                                              "y": [-1e-2, -5e-2, -7e-2], "y_unit": "kN"}]}]},
                    units_required=True)
    dev.set_program(3, {"elements": [env | {"references": [{"x": ["40 mm", "4.1 cm", "0.042 m"],
                                                              "y": ["-10 N", "-50 N", "-70 N"]}]}]},
                    units_required=True)
    refs = [dev.get_program(n)["elements"][0]["references"][0] for n in (1, 2, 3)]
    for r in refs[1:]:
        assert np.allclose(r["x"], refs[0]["x"], rtol=1e-12) and np.allclose(r["y"], refs[0]["y"], rtol=1e-12)
    with pytest.raises(DigiForceError, match=r'references\[0\].x: numbers without a unit; add x_unit = "m"'):
        dev.set_program(4, {"elements": [env | {"references": [si]}]}, units_required=True)
    with pytest.raises(DigiForceError, match=r"references\[0\].x_unit.*wrong dimension|x_unit.*'N'"):
        dev.set_program(4, {"elements": [env | {"references": [si | {"x_unit": "N", "y_unit": "N"}]}]},
                        units_required=True)
    with pytest.raises(DigiForceError, match=r"x_unit names the unit \('mm'\); give plain numbers"):
        dev.set_program(4, {"elements": [env | {"references": [{"x": ["40 mm", 41], "x_unit": "mm",
                                                                  "y": ["1 N", "2 N"]}]}]}, units_required=True)
    dev.set_program(2, {"name": "renamed"}, units_required=True)     # the normalised SI reference stays valid

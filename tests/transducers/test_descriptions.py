"""Device descriptions: registry, unit-checked loading, overrides and clear errors."""
from pathlib import Path

import numpy as np
import pytest

from firmware_sim.transducers import (REGISTRY, LVDT, IncrementalEncoder, StrainAmplifier, StrainGaugeBridge,
                                      load_transducer)
from rig.scene import SceneError

DEVICES = Path(__file__).resolve().parents[2] / "data" / "devices"


def test_every_description_loads_with_its_registered_class():
    names = sorted(p.stem for p in DEVICES.glob("*.toml") if not p.stem.startswith("digiforce"))
    assert len(names) == 12
    for name in names:
        s = load_transducer(name, np.random.default_rng(0))
        assert isinstance(s, REGISTRY[type(s).TYPE])
    assert isinstance(load_transducer("burster_8411", np.random.default_rng(0)), StrainGaugeBridge)
    assert isinstance(load_transducer(DEVICES / "burster_8740.toml", np.random.default_rng(0)), LVDT)
    assert isinstance(load_transducer("encoder_1024", np.random.default_rng(0)), IncrementalEncoder)
    assert isinstance(load_transducer("leaf_half_bridge", np.random.default_rng(0)), StrainAmplifier)
    assert type(load_transducer("slotted_disc_6", np.random.default_rng(0))).TYPE == "pulse_counter"
    assert type(load_transducer("stroboscope", np.random.default_rng(0))).TYPE == "stroboscope"


def test_values_are_read_in_si_and_overrides_replace_file_values():
    s = load_transducer("burster_8740", np.random.default_rng(0))
    assert s.p["range_max"] == pytest.approx(0.1)
    assert s.p["nonlinearity_max"] == pytest.approx(0.0025)
    assert s.p["carrier_frequency"] == pytest.approx(12e3)
    o = load_transducer("burster_8740", np.random.default_rng(0), range_max_mm=50, bandwidth="200 Hz")
    assert o.p["range_max"] == pytest.approx(0.05) and o.p["bandwidth"] == pytest.approx(200.0)
    e = load_transducer("encoder_1024", np.random.default_rng(0), ppr=500, multiplier=2)
    assert (e.ppr, e.multiplier) == (500, 2)


def test_bad_descriptions_and_overrides_raise_naming_the_problem(tmp_path):
    rng = np.random.default_rng(0)
    with pytest.raises(SceneError, match="'colour'"):
        load_transducer("burster_8411", rng, colour="red")
    with pytest.raises(SceneError, match="preload.*wrong dimension"):
        load_transducer("burster_8411", rng, preload="25 mm")
    with pytest.raises(SceneError, match="cannot read device description"):
        load_transducer("no_such_sensor", rng)
    bad = tmp_path / "bad.toml"
    bad.write_text('[transducer]\ntype = "laser"\n')
    with pytest.raises(SceneError, match="type 'laser'"):
        load_transducer(bad, rng)
    bad.write_text('[transducer]\ntype = "lvdt"\nrange_min = "0 mm"\n')
    with pytest.raises(SceneError, match="missing key 'range_max'"):
        load_transducer(bad, rng)
    bad.write_text('[transducer]\ntype = "lvdt"\nrange_min = "0 mm"\nrange_max = 100\n')
    with pytest.raises(SceneError, match="range_max.*no unit"):
        load_transducer(bad, rng)
    with pytest.raises(ValueError, match="range_min"):
        load_transducer("burster_8740", rng, range_min="200 mm")
    with pytest.raises(TypeError, match="Generator"):
        load_transducer("burster_8740", 42)


def test_individual_errors_come_from_the_generator():
    a = load_transducer("burster_8411", np.random.default_rng(11))
    b = load_transducer("burster_8411", np.random.default_rng(11))
    c = load_transducer("burster_8411", np.random.default_rng(12))
    assert a.static == b.static and a.static != c.static


def test_stuck_output_fault_holds_the_value_at_onset_across_calls():
    s = load_transducer("torque_meter_50Nm", np.random.default_rng(0), errors_enabled=False, dynamics_enabled=False)
    s.inject("stuck", at=0.25)
    t = np.linspace(0.0, 0.5, 6)
    y = s.measure(t, 10.0 * t)
    held = s.nominal(10.0 * 0.2)
    np.testing.assert_allclose(y[3:], held)
    np.testing.assert_allclose(s.measure(np.array([1.0]), np.array([40.0])), held)


def test_stuck_from_the_start_holds_the_first_reading_not_zero():
    """A fault "stuck" with no onset time holds the output at its first sample (it held the zero output, so a stuck
    torque meter read 0 N·m as on a lost supply)."""
    s = load_transducer("torque_meter_50Nm", np.random.default_rng(0), errors_enabled=False, dynamics_enabled=False)
    s.inject("stuck")
    t = np.linspace(0.0, 0.5, 6)
    y = s.measure(t, 10.0 + 10.0 * t)
    np.testing.assert_allclose(y, s.nominal(10.0))
    assert s.nominal(10.0) != s.nominal(0.0)

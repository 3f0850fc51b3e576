"""Strain-gauge bridge: preload, overload damage, open bridge, excitation loss, shunt calibration."""
import numpy as np
import pytest

from firmware_sim.transducers import load_transducer, shunt_ratio

FS = 1.5e-3  # V/V at 1000 N (burster_8411.toml)


def ideal(**kw):
    return load_transducer("burster_8411", np.random.default_rng(0), errors_enabled=False,
                           dynamics_enabled=False, **kw)


def bridge_output_by_nodal_analysis(r_arm: float, r_shunt: float) -> float:
    """Solve the shunted 350 Ω bridge as a resistor network (Kirchhoff), output / excitation."""
    # nodes: 0 = +Vex (1 V), 1 = ground, 2 = left midpoint, 3 = right midpoint
    # left half: R(+→2), R∥shunt(2→gnd); right half: R(+→3), R(3→gnd)
    g = np.zeros((2, 2))
    i = np.zeros(2)
    for node, r_top, r_bottom in ((0, r_arm, 1 / (1 / r_arm + 1 / r_shunt)), (1, r_arm, r_arm)):
        g[node, node] = 1 / r_top + 1 / r_bottom
        i[node] = 1.0 / r_top
    v_left, v_right = np.linalg.solve(g, i)
    return v_left - v_right


def test_preload_is_seen_with_no_external_load():
    s = ideal(preload="-25 N")
    y = s.measure(np.array([0.0, 1.0]), np.array([0.0, 100.0]))
    np.testing.assert_allclose(s.to_physical(y), [-25.0, 75.0], atol=1e-9)
    s2 = ideal(preload_N=-25)
    assert s2.p["preload"] == -25.0


def test_saturation_and_permanent_zero_shift_after_overload():
    s = ideal()
    t = np.linspace(0.0, 3.0, 3001)
    q = np.interp(t, [0, 1, 1.5, 2, 3], [0, 0, 1800, 0, 0])  # 180 % FS tension, then unloaded
    y = s.measure(t, q)
    assert y.max() == pytest.approx(1.5 * FS)                # saturated at 150 % FS
    expected_shift = 0.1 * (1.8 - 1.5) * FS                  # zero_shift_per_overload · excess
    np.testing.assert_allclose(y[t > 2.0], expected_shift, atol=1e-15)
    assert s.zero_shift == pytest.approx(expected_shift)
    y2 = s.measure(np.array([10.0]), np.array([0.0]))       # permanent: still there later
    assert y2[0] == pytest.approx(expected_shift)


def test_no_zero_shift_below_damage_threshold_and_compression_shifts_negative():
    s = ideal()
    t = np.linspace(0.0, 2.0, 2001)
    y = s.measure(t, np.interp(t, [0, 1, 2], [0, 1450, 0]))
    assert y[-1] == 0.0
    y = s.measure(t + 3.0, np.interp(t, [0, 1, 2], [0, -2000, 0]))
    assert y[-1] == pytest.approx(-0.1 * 0.5 * FS)


def test_open_bridge_rails_and_recovers_after_repair():
    s = ideal()
    s.inject("open_bridge", at=0.5, until=0.8)
    t = np.linspace(0.0, 1.0, 101)
    y = s.measure(t, np.full(t.size, 200.0))
    window = (t >= 0.5) & (t < 0.8)
    assert np.all(y[window] == 0.5)
    np.testing.assert_allclose(s.to_physical(y[~window]), 200.0, atol=1e-9)


def test_excitation_loss_drops_output_to_zero():
    s = ideal()
    s.inject("excitation_loss", at=0.2)
    t = np.linspace(0.0, 1.0, 11)
    y = s.measure(t, np.full(t.size, 500.0))
    assert np.all(y[t >= 0.2] == 0.0)
    assert np.all(y[t < 0.2] == pytest.approx(0.75e-3))


def test_unknown_fault_and_bad_parameter_are_named():
    s = ideal()
    with pytest.raises(ValueError, match="unknown fault 'cable_cut'"):
        s.inject("cable_cut", at=1.0)
    with pytest.raises(ValueError, match="no parameter"):
        s.inject("open_bridge", at=1.0, colour="red")


def test_shunt_calibration_closed_form():
    s = ideal()
    out = s.shunt_output(R_shunt=59e3)
    assert out == pytest.approx(bridge_output_by_nodal_analysis(350.0, 59e3), rel=1e-12)
    assert out == pytest.approx(-1.47866e-3, rel=1e-5)
    assert s.shunt_output() == out                          # default: the built-in 59 kΩ
    assert s.to_physical(out) == pytest.approx(-985.777, rel=1e-5)  # equivalent force for the gain check
    assert shunt_ratio(350.0, 100e3) == pytest.approx(bridge_output_by_nodal_analysis(350.0, 100e3), rel=1e-12)
    with pytest.raises(ValueError, match="positive"):
        s.shunt_output(R_shunt=0.0)

"""Parameter studies of the flat-tappet characteristic (MODELS.md §4.2 expectations)."""
import math

import numpy as np
import pytest

from rig.plants.clutch.studies import (FAMILIES, characteristic, parameter_family, plot_parameter_studies,
                                       write_peak_table)


def test_torque_proportional_to_k_a_and_peak_angle_independent_of_it():
    fam = parameter_family("k_a")
    ratio = fam.torque[:, 1:-1] / fam.torque[2, 1:-1]          # both ends are zeros
    np.testing.assert_allclose(ratio, np.broadcast_to((fam.values / 28e3)[:, None], ratio.shape), rtol=1e-12)
    np.testing.assert_allclose(fam.peak_angle, fam.peak_angle[2], atol=1e-9)
    np.testing.assert_allclose(fam.peak_torque / fam.values, fam.peak_torque[2] / 28e3, rtol=1e-9)


def test_progressive_then_regressive_zero_at_apex():
    for name in FAMILIES:
        fam = parameter_family(name)
        np.testing.assert_allclose(fam.torque[:, 0], 0.0, atol=1e-15)
        np.testing.assert_allclose(fam.torque[:, -1], 0.0, atol=1e-12)
        for curve, pa in zip(fam.torque, fam.peak_angle):
            rising = fam.phi < pa - 1e-9
            assert np.all(np.diff(curve[rising]) > 0) and np.all(np.diff(curve[~rising]) < 0)


def test_peak_angle_closed_form_phase_two():
    """In phase II, T ∝ (r2 − r0 + δ + a2 cos u)·a2 sin u, u = 60° − φ: peak at 2a2c² + (r2 − r0 + δ)c − a2 = 0."""
    fam = parameter_family("delta")
    for delta, pa, pt in zip(fam.values, fam.peak_angle, fam.peak_torque):
        c = characteristic(delta=delta)
        a2, cc = c.clutch.limits.a2, 0.028 - 0.032 + delta
        u = math.acos((-cc + math.sqrt(cc ** 2 + 8 * a2 ** 2)) / (4 * a2))
        assert pa == pytest.approx(math.pi / 3 - u, abs=1e-8)
        assert pt == pytest.approx(3 * 28e3 * (cc + a2 * math.cos(u)) * a2 * math.sin(u), rel=1e-10)
    assert np.all(np.diff(fam.peak_torque) > 0) and np.all(np.diff(fam.peak_angle) < 0)


def test_friction_raises_the_loading_peak():
    dry = parameter_family("r1")
    wet = parameter_family("r1", mu_B=0.1)
    assert np.all(wet.peak_torque > dry.peak_torque)
    with pytest.raises(ValueError, match="unknown parameter"):
        characteristic(r3=0.01)


def test_plots_and_peak_table(tmp_path):
    paths = plot_parameter_studies(tmp_path)
    assert [p.name for p in paths] == [f"clutch_study_{n}.png" for n in FAMILIES]
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 10_000
    rows = write_peak_table(tmp_path).read_text().splitlines()
    assert rows[0] == "parameter,value,unit,peak_torque [N*m],peak_angle [deg]"    # values as the charts show them
    assert len(rows) == 1 + sum(len(v) for v in FAMILIES.values())
    ref = [r for r in rows if r.startswith("k_a,28,N/mm,")][0].split(",")
    assert float(ref[3]) == pytest.approx(parameter_family("k_a").peak_torque[2], rel=1e-5)
    assert [r for r in rows if r.startswith("r0,")][0].split(",")[1:3] == ["29", "mm"]

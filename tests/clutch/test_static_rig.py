"""Static clutch rig: stop-operator hysteresis, friction work, disengagement, scenes and their errors."""
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from rig.analysis.clutch_metrics import loop_energy
from rig.plants.clutch import FlatTappetClutch
from rig.plants.clutch.static_rig import LeverProgram, StaticClutchRig, load_static_rig
from rig.plants.clutch.variants import FlatTappetCharacteristic, LeafSpringClutch, measured_table
from rig.scene import SceneError

SCENES = Path(__file__).resolve().parents[2] / "data" / "scenes"
REF = dict(r0=0.032, r1=0.100, r2=0.028, k_a=28e3, delta=0.005, mu_B=0.1)


def flat_rig(forces, ramp=10.0):
    clutch = FlatTappetCharacteristic(FlatTappetClutch(**REF))
    program = LeverProgram.ramps(0.0, [(ramp, f) for f in forces])
    return clutch, StaticClutchRig(clutch, program, lever_arm=1.0)


def test_branches_followed_and_stuck_at_reversal():
    clutch, rig = flat_rig([4.0, 0.0])
    t = np.linspace(1e-3, 20.0, 4001)
    out = rig.advance(t)
    phi, m = out["relative_angle"], out["torque"]
    np.testing.assert_allclose(m, out["lever_force"] * 1.0)
    load = (t <= 10.0) & (phi > 0)
    np.testing.assert_allclose(clutch.torque(phi[load], 1), m[load], rtol=1e-9)
    assert np.all(np.diff(phi[t <= 10.0]) >= 0)
    unloading = t > 10.0
    moving = unloading & np.r_[False, np.diff(phi) != 0]
    stuck = unloading & ~moving
    assert stuck.any() and moving.any()
    # stuck while T_unload(φ) ≤ M ≤ T_load(φ); sliding on the unloading branch afterwards
    assert np.all(clutch.torque(phi[stuck], -1) <= m[stuck] + 1e-9)
    assert np.all(m[stuck] <= clutch.torque(phi[stuck], 1) + 1e-9)
    slide = unloading & (t > t[stuck][-1])
    np.testing.assert_allclose(clutch.torque(phi[slide], -1), m[slide], atol=1e-9)
    # friction holds a residual angle at zero load: T_unload(φ_res) = 0
    assert phi[-1] > 0 and float(clutch.torque(phi[-1], -1)) == pytest.approx(0.0, abs=1e-9)


def _k2(p, r0=0.032, r1=0.100, r2=0.028):
    pm = math.pi / 3 - math.asin((r1 - r0) / (r1 - r2) * math.sin(math.pi / 3))
    a2 = (r1 - r0) * math.sin(pm) / math.sin(math.pi / 3 - pm)
    return r1 - (r1 - r0) * math.cos(p) if p <= pm else r2 + a2 * math.cos(math.pi / 3 - p)


def test_second_cycle_loop_energy_equals_friction_work():
    _, rig = flat_rig([4.0, 0.0, 4.0, 0.0])
    t = np.linspace(0, 40.0, 80001)[1:]
    out = rig.advance(t)
    cycle = t > 20.0
    phi, m = out["relative_angle"][cycle], out["torque"][cycle]
    phi_res, phi_max = phi[0], phi.max()
    assert phi[-1] == pytest.approx(phi_res, abs=1e-12)           # the second loop closes
    reference, _ = quad(lambda p: 2 * 0.1 * 3 * 28e3 * (_k2(p) - 0.032 + 0.005) * _k2(p), phi_res, phi_max,
                        points=[0.0893], limit=200)
    energy = float(loop_energy(phi, m))
    assert energy > 0
    assert energy == pytest.approx(reference, rel=2e-4)


def test_overload_disengages_into_next_lobe():
    clutch, rig = flat_rig([5.0, 4.0])
    t = np.linspace(0.01, 20.0, 2000)
    out = rig.advance(t)
    kinds = [e.kind for e in rig.events]
    assert kinds == ["disengagement", "reengaged"]
    t_dis = rig.events[0].time
    assert rig.events[0].data["torque"] > clutch.peak_torque
    assert out["torque"][t < t_dis].max() <= clutch.peak_torque
    after = t >= rig.events[1].time
    # winds up the next lobe's loading branch, then (torque falling) friction holds it
    expected = clutch.period + float(clutch.angle(out["torque"][after][0], 1))
    np.testing.assert_allclose(out["relative_angle"][after], expected, atol=1e-12)
    overloaded = (t >= t_dis) & ~after
    np.testing.assert_allclose(out["relative_angle"][overloaded], clutch.disengagement_angle, atol=1e-12)


def test_advance_in_chunks_equals_one_call_and_time_checks():
    t = np.linspace(0.01, 40.0, 1000)
    _, whole = flat_rig([4.0, 0.0, 5.0, 0.0])
    _, parts = flat_rig([4.0, 0.0, 5.0, 0.0])
    ref = whole.advance(t)
    pieces = [parts.advance(chunk) for chunk in np.array_split(t, 7)]
    for key in ref:
        np.testing.assert_array_equal(np.concatenate([p[key] for p in pieces]), ref[key])
    assert [e.time for e in parts.events] == [e.time for e in whole.events]
    with pytest.raises(ValueError, match="increasing"):
        parts.advance(np.array([1.0, 2.0]))


def test_frictionless_table_has_no_loop():
    clutch = measured_table("rubber_d25_rubber_d20", through_origin=True)
    rig = StaticClutchRig(clutch, LeverProgram.ramps(0.0, [(10.0, 140.0), (10.0, 0.0)]))
    t = np.linspace(0.0, 20.0, 2001)[1:]
    out = rig.advance(t)
    np.testing.assert_allclose(out["relative_angle"], clutch.angle(out["torque"]), atol=1e-12)
    assert float(loop_energy(out["relative_angle"], out["torque"])) == pytest.approx(0.0, abs=1e-9)


def test_leaf_scene_strain_and_loops():
    rig = load_static_rig(SCENES / "clutch_static_leaf.toml")
    assert isinstance(rig.clutch, LeafSpringClutch) and rig.lever_arm == pytest.approx(1.0)
    t = np.linspace(0.05, rig.duration, 2400)
    out = rig.advance(t)
    np.testing.assert_allclose(out["leaf_strain"], rig.clutch.leaf_strain(out["relative_angle"]), rtol=1e-12)
    assert out["leaf_strain"].max() > 0 and not rig.events
    # loading and unloading at the same torque give different angles (the hysteresis)
    i_up = np.argmin(np.abs(out["torque"][t < 30] - 15.0))
    i_down = np.argmin(np.abs(np.where(t > 30, out["torque"], np.inf)[: t.size] - 15.0))
    assert out["relative_angle"][i_down] > out["relative_angle"][i_up] + 0.01


@pytest.mark.parametrize("name", ["clutch_static_leaf", "clutch_static_flat_tappet", "clutch_static_rubber_table"])
def test_shipped_scenes_load_and_run(name):
    rig = load_static_rig(SCENES / f"{name}.toml")
    out = rig.advance(np.linspace(0.1, rig.duration, 300))
    assert np.all(np.isfinite(out["relative_angle"]))


def _scene(tmp_path, text):
    path = tmp_path / "clutch_static_bad.toml"
    path.write_text(text)
    return path


FLAT = (SCENES / "clutch_static_flat_tappet.toml").read_text()


@pytest.mark.parametrize("old, new, pattern", [
    ('r0 = "32 mm"\n', "", r"missing key 'r0'"),
    ('lever_arm = "1000 mm"', 'lever_arm = "1000 N"', r"'lever_arm'.*wrong dimension"),
    ('variant = "flat_tappet"', 'variant = "flat_cam"', r"'variant' = 'flat_cam'"),
    ('r2 = "28 mm"', 'r2 = "120 mm"', r"\[plant.clutch\].*r2"),
    ('force = "4 N"', 'force = "-4 N"', r"\[\[program\]\] #1.*force >= 0"),
    ('duration = "20 s"', 'duration = "20 mm"', r"\[\[program\]\] #1.*'duration'"),
    ('[[program]]\nduration = "20 s"\nforce = "4 N"', '[[program]]\nduration = "20 s"\nforse = "4 N"',
     r"unknown key 'forse'"),
    ('lever_arm = "1000 mm"', 'lever_arm = "1000 mm"\nlevel = 2', r"\[plant\]: unknown key 'level'"),
])
def test_scene_errors_name_file_and_key(tmp_path, old, new, pattern):
    assert old in FLAT
    path = _scene(tmp_path, FLAT.replace(old, new, 1))
    with pytest.raises(SceneError, match=pattern) as info:
        load_static_rig(path)
    assert str(path) in str(info.value)


def test_scene_without_program(tmp_path):
    path = _scene(tmp_path, FLAT.split("[[program]]")[0])
    with pytest.raises(SceneError, match=r"\[\[program\]\]"):
        load_static_rig(path)

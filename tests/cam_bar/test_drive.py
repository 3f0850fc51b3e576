"""The cam drive at level 2 (rig.plants.cam_bar.drive): motor line, shaft compliance, start-up, speed ripple."""
from math import radians, tau
from pathlib import Path

import numpy as np
import pytest

from rig.motion import ConstantSpeed
from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.scene_io import mechanism_from_scene
from rig.plants.cam_bar.drive import CamDrive
from rig.plants.cam_bar.level2 import Level2
from rig.plants.cam_bar.plant import DEMO_SPEED
from rig.motion.speed import RPM
from rig.scene import SceneError, load_scene

from tests.cam_bar.test_cam_bar_scene import write


def _run(mech: PinInsertionMechanism, T: float, n: int = 4001, speed=DEMO_SPEED):
    model = Level2(mech, speed)
    t = np.linspace(0.0, T, n)
    run = model.simulate((0.0, T), t_eval=t, rtol=1e-7, atol=1e-12)
    return run, model.signals(t, run.solution.y)


def test_drive_off_by_default_and_state_layout():
    mech = PinInsertionMechanism()
    assert mech.cam_drive is None and len(Level2(mech, DEMO_SPEED).initial_state(0.0)) == 2
    y0 = Level2(PinInsertionMechanism(cam_drive=CamDrive()), DEMO_SPEED, energy=True).initial_state(0.0)
    assert len(y0) == 9 and y0[2:4] == (0.0, 0.0)                           # (e, τė, φ, ω, φ_m, ω_m, works)


def test_a_heavy_stiff_drive_turns_the_cam_at_constant_speed():
    """Huge inertias: the drive's reaction cannot change the speed, so level 2 equals the constant-speed run."""
    heavy = CamDrive(motor_inertia=1e4, cam_inertia=1e4, start="running")
    _, ref = _run(PinInsertionMechanism(), 0.4)
    _, sig = _run(PinInsertionMechanism(cam_drive=heavy), 0.4)
    assert np.max(np.abs(sig["omega"] / (150 * RPM) - 1.0)) < 1e-5
    e_ref, e = ref["psi"] - ref["psi_kin"], sig["psi"] - sig["psi_kin"]
    assert np.max(np.abs(e - e_ref)) < 1e-4 * np.max(np.abs(e_ref))


def test_speed_ripple_from_the_mechanisms_own_reaction_torque():
    """Running at 150 rpm: the cam slows while it drives the rise and speeds up when the follower drives it back
    (≈ ±1 rpm: the motor line's droop under the drive torque)."""
    _, sig = _run(PinInsertionMechanism(cam_drive=CamDrive(start="running")), 0.8)
    late = sig["t"] > 0.4
    omega, torque = sig["omega"][late], sig["drive_torque"][late]
    ripple = np.ptp(omega) / np.mean(omega)
    assert 0.003 < ripple < 0.05
    assert np.mean(omega) == pytest.approx(150 * RPM, rel=0.01)
    droop = np.polyfit(torque, omega, 1)              # steep motor line (J/b ≈ 3 ms): ω ≈ ω_s − T_d/b
    assert droop[0] == pytest.approx(-1.0 / CamDrive().slope, rel=0.1) and droop[1] == pytest.approx(150 * RPM)
    assert np.corrcoef(omega, torque)[0, 1] < -0.95


def test_start_up_from_rest_and_a_start_phase_jump_with_a_strong_motor():
    """From rest in the return stroke (260°) with the drawn spring: the default motor (pull-out 60 N·m at the cam)
    brings the cam to speed without a flank switch; one twice as strong accelerates the cam so hard that the
    follower, which must follow the return, leaves the working flank (switches in the first 0.1 s)."""
    speed = ConstantSpeed(150 * RPM, radians(260.0))
    run, sig = _run(PinInsertionMechanism(k=1090.0, cam_drive=CamDrive()), 0.15, speed=speed)
    assert sig["omega"][0] == 0.0 and sig["cam_angle"][0] == pytest.approx(radians(260.0))
    assert np.all(np.abs(sig["omega"][sig["t"] > 0.1] / (150 * RPM) - 1.0) < 0.02)
    assert run.switches == []
    run, sig = _run(PinInsertionMechanism(k=1090.0, cam_drive=CamDrive(max_torque=120.0)), 0.1, speed=speed)
    assert run.switches and run.switches[0].time < 0.05 and sig["R23"].min() < -1000.0


def test_scene_table(tmp_path):
    scene = write(tmp_path, '\n[plant.drive]\nslope = "30 N*m*s/rad"\nstart = "running"\n',
                  "[[plant.cam_program]]", "[[plant.cam_program]]")
    drive = mechanism_from_scene(scene).cam_drive
    assert drive == CamDrive(slope=30.0, start="running") and drive.synchronous(tau) == tau
    path = tmp_path / "scene.toml"
    text = path.read_text()
    for old, new, match in (('start = "running"', 'start = "later"', "start"),
                            ('slope = "30 N*m*s/rad"', 'slope = "0 N*m*s/rad"', "slope"),
                            ('slope = "30 N*m*s/rad"', 'gear = 3', "unknown key")):
        path.write_text(text.replace(old, new))
        with pytest.raises(SceneError, match=match):
            mechanism_from_scene(load_scene(path))


def test_a_motor_too_weak_for_the_peak_drive_torque_stalls_the_cam_and_says_so():
    """Pull-out 1 N·m at the cam against a peak drive torque of ≈ 3–4 N·m: from rest the cam never gets over the rise;
    it stops and rocks back, and each stop is a ``cam_stalled`` event (the run went on silently at no speed). The
    default motor (60 N·m) brings the cam to speed without one."""
    from rig.plants.cam_bar.level2_timeline import Level2Timeline
    t = np.arange(1, 10001) * 1e-4                              # 1 s at 10 kHz, in 100 ms chunks as the runner steps
    for max_torque, stalls in ((1.0, True), (60.0, False)):
        timeline = Level2Timeline(PinInsertionMechanism(cam_drive=CamDrive(max_torque=max_torque)), DEMO_SPEED)
        omega = np.concatenate([timeline.advance(chunk)["omega"] for chunk in np.split(t, 10)])
        found = [e for e in timeline.events if e.kind == "cam_stalled"]
        assert bool(found) == stalls
        if stalls:
            assert omega.max() > 0.0 and omega.min() < 0.0
            for e in found:                                     # at a sample where the cam stopped after turning
                k = int(np.argmin(np.abs(t - e.time)))
                assert omega[k] <= 0.0 < omega[k - 1] and e.data["omega"] == omega[k]


def test_level2_simulate_reports_the_stall_too():
    """The API's Level2.simulate (not only the runner's timeline) names the stalls of a weak motor: its run said
    nothing (a leftover). With t_eval the events are at those samples, as the timeline's."""
    from rig.plants.cam_bar.level2 import Level2
    t = np.arange(0, 10001) * 1e-4
    weak = Level2(PinInsertionMechanism(cam_drive=CamDrive(max_torque=1.0)), DEMO_SPEED)
    run = weak.simulate((0.0, 1.0), t_eval=t)
    omega = run.solution.y[3]
    assert run.stalls and [e for e in run.events if e.kind == "cam_stalled"] == run.stalls
    for e in run.stalls:
        k = int(np.argmin(np.abs(t - e.time)))
        assert omega[k] <= 0.0 < omega[k - 1] and e.data["omega"] == omega[k]
    assert not Level2(PinInsertionMechanism(cam_drive=CamDrive(max_torque=60.0)), DEMO_SPEED).simulate(
        (0.0, 1.0), t_eval=t).stalls


def test_a_motor_that_cannot_start_the_cam_and_lets_it_run_back_says_so():
    """A drive of 0.05 N·m at the cam, the cam at rest at 100° on the rise: the mechanism's torque turns it backwards
    from its start (to about −60°) and it never turns forwards — no ``cam_stalled`` event, since that looked for a stop
    after turning forwards, and the run recorded its curves as if driven (an audit). The event is now at the first
    sample turning back."""
    from rig.plants.cam_bar.level2_timeline import Level2Timeline
    speed = ConstantSpeed(DEMO_SPEED.omega, phi0=radians(100.0))
    timeline = Level2Timeline(PinInsertionMechanism(cam_drive=CamDrive(max_torque=0.05)), speed)
    t = np.arange(1, 2001) * 1e-4
    omega = np.concatenate([timeline.advance(chunk)["omega"] for chunk in np.split(t, 4)])
    found = [e for e in timeline.events if e.kind == "cam_stalled"]
    assert omega.max() <= 0.0 and omega.min() < -1.0                 # it never turned forwards
    assert len(found) == 1 and found[0].time == t[np.argmax(omega < 0.0)] and found[0].data["omega"] < 0.0


def test_a_run_that_runs_out_of_time_because_the_cam_stalled_says_so(tmp_path):
    """The as-tested machine with a 1 N·m motor: no curve came and the run ended in "check the device's start/stop
    settings", with the cam_stalled events unsaid (an audit): the message now names the stalls."""
    from rig.runner import run_scene
    from rig.runner.errors import OutOfTime
    scene = (Path(__file__).resolve().parents[2] / "data" / "scenes" / "pin_insertion_as_tested.toml").read_text()
    path = tmp_path / "weak.toml"
    path.write_text(scene.replace('start = "rest"', 'start = "rest"\nmax_torque = "1 N*m"', 1)
                    .replace("cycles = 5", 'cycles = 2\nmax_time = "1 s"', 1))
    with pytest.raises(OutOfTime, match=r"only [01] of 2 curves by .* \(the cam stalled \d+ time\(s\), first at t = "
                                        r".* its motor cannot carry the mechanism"):
        run_scene(path, tmp_path / "weak.mcap")

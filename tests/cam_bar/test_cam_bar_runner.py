"""Runner interface: advance() continuity across calls, truth signals, events; demo helpers."""
from math import pi, tau

import numpy as np
import pytest

from rig.motion import CamProgram, ConstantSpeed, Segment
from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.plant import CamBarPlant, Setting
from rig.plants.cam_bar.summary import plot_cycle, summary_table

OMEGA = 300 * pi / 30  # fast enough for flank switches with the spring


def test_advance_in_chunks_equals_one_call_and_events_match_angles():
    t = np.linspace(0.0, 0.45, 4501)  # > 2 revolutions at 300 rpm
    one = CamBarPlant(PinInsertionMechanism(k=1090.0), Setting(ConstantSpeed(OMEGA)))
    chunked = CamBarPlant(PinInsertionMechanism(k=1090.0), Setting(ConstantSpeed(OMEGA)))
    full = one.advance(t)
    parts = [chunked.advance(c) for c in np.array_split(t, 7)]
    for key in ("phi", "s", "psi", "F_rod", "R23", "M_sigma", "drive_torque"):
        assert np.concatenate([p[key] for p in parts]) == pytest.approx(full[key], abs=1e-12), key
    assert [(e.kind, round(e.time, 9)) for e in chunked.events] == [(e.kind, round(e.time, 9)) for e in one.events]
    switches = [e for e in one.events if e.kind == "flank_switch"]
    expected = one.mech.flank_switch_angles(OMEGA)
    assert len(expected) == 2 and len(switches) == 2 * len(expected) + 0  # two revolutions crossed fully
    for e in switches:
        assert np.min(np.abs(e.data["phi"] - expected)) < 1e-8
        assert e.time * OMEGA % tau == pytest.approx(e.data["phi"], abs=1e-8)
    assert switches[0].data["to"] == "other" and switches[1].data["to"] == "working"
    assert full["x_gripper"] == pytest.approx(one.mech.s0 - full["s"])
    assert full["cam_angle"].max() < tau


def test_accel_jump_events_for_harmonic_return():
    prog = CamProgram([Segment("dwell", pi / 3), Segment("rise", 2 * pi / 3, "3-4-5", 0.042),
                       Segment("dwell", 2 * pi / 9), Segment("return", 5 * pi / 9, "harmonic", 0.042),
                       Segment("dwell", 2 * pi / 9)])
    mech = CamBarPlant(PinInsertionMechanism(program=prog), Setting(ConstantSpeed(2 * pi)))  # 1 rev/s
    mech.advance(np.linspace(0.0, 1.7, 341))
    jumps = [e for e in mech.events if e.kind == "accel_jump"]
    assert [round(e.time, 9) for e in jumps] == pytest.approx([220 / 360, 320 / 360, 1 + 220 / 360])


def test_advance_rejects_bad_times():
    mech = CamBarPlant(PinInsertionMechanism())
    mech.advance(np.array([0.0, 0.1]))
    with pytest.raises(ValueError, match="not after the previous call"):
        mech.advance(np.array([0.05, 0.2]))
    with pytest.raises(ValueError, match="strictly increasing"):
        mech.advance(np.array([0.3, 0.2]))


def test_summary_and_plot(tmp_path):
    mech = PinInsertionMechanism()
    text = summary_table(mech, 150 * pi / 30)
    assert "slider (gripper) stroke" in text and "42.000 mm" in text and "at 150.0 rpm" in text
    assert "k = 1.19 N/mm" in text and "no spring" in text and "b_min" in text
    assert text.startswith("level 1 (kinetostatic, nominal machine, constant speed):")
    assert "R23 changes sign" in text and f"k = {mech.k / 1e3:.2f} N/mm (mounted)" in text
    assert text.count("(mounted)") == 1 and "this run is level" not in text
    path = plot_cycle(mech, 150 * pi / 30, tmp_path / "cycle.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("level, noted", [(None, False), (1, False), (0, False), (2, True)])
def test_summary_says_when_the_run_uses_another_level(level, noted):
    """The level-1 numbers printed before a level-2 run say they are not the run's own; a forced level-0 run
    simulates the same run as level 1 (its caveat says so), so they are its own."""
    text = summary_table(PinInsertionMechanism(), 150 * pi / 30, run_level=level)
    assert (f"this run is level {level}: these level-1 numbers are not its own" in text) == noted

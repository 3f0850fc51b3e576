"""Fidelity 2 through the runner interface and a scene recorded end to end."""
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from rig.motion import ConstantSpeed
from rig.plants.cam_bar import PinInsertionMechanism
from rig.motion.speed import RPM
from rig.plants.cam_bar.plant import CamBarPlant, Setting
from rig.plants.cam_bar.scene_io import read_fidelity
from rig.plants.cam_bar.variation import CycleVariation
from rig.recorder import read_recording
from rig.runner import run_scene
from rig.scene import SceneError, load_scene
from rig.units import to_si

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "data" / "scenes" / "pin_insertion_l2.toml"


def test_fidelity_is_read_from_the_scene(tmp_path):
    assert read_fidelity(load_scene(SCENE)) == 2
    assert read_fidelity(load_scene(ROOT / "data" / "scenes" / "pin_insertion.toml")) == 1
    assert CamBarPlant.from_scene(load_scene(SCENE)).setting.fidelity == 2
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENE.read_text().replace("fidelity = 2 ", 'fidelity = "exact" '))
    with pytest.raises(SceneError, match="'fidelity' must be 0, 1, 2 .* got 'exact'"):
        read_fidelity(load_scene(bad))
    with pytest.raises(ValueError, match="fidelity must be 0, 1 or 2"):
        Setting(fidelity=3)


def test_advance_in_chunks_continues_the_integration_and_reports_flank_switches():
    omega = 300 * RPM
    t = 0.125 + np.arange(1, 201) * 1e-4  # 225°…261° of the return at 300 rpm
    one = CamBarPlant(PinInsertionMechanism(k=1090.0), Setting(ConstantSpeed(omega), fidelity=2))
    chunked = CamBarPlant(PinInsertionMechanism(k=1090.0), Setting(ConstantSpeed(omega), fidelity=2))
    full = one.advance(t)
    parts = [chunked.advance(c) for c in np.array_split(t, 5)]
    for key, tol in (("s", 2e-6), ("psi", 1e-5), ("phi", 0.0)):
        assert np.concatenate([p[key] for p in parts]) == pytest.approx(full[key], abs=tol), key
    level1 = CamBarPlant(PinInsertionMechanism(k=1090.0), Setting(ConstantSpeed(omega))).advance(t)
    assert full["s"] == pytest.approx(level1["s"], abs=4 * one.mech.clearance * one.mech.L3 / one.mech.l3)
    assert np.max(np.abs(full["s"] - level1["s"])) > one.mech.clearance   # but the roller crossed the groove
    kinds = [(e.kind, e.data.get("to")) for e in one.events if e.kind == "flank_switch"]
    assert kinds == [("flank_switch", "other"), ("flank_switch", "working")]
    assert [e.kind for e in chunked.events] == [e.kind for e in one.events]
    assert chunked.events[0].time == pytest.approx(one.events[0].time, abs=1e-5)


def test_bounces_on_the_flank_it_returned_to_are_events_too():
    """After the switch back to the working flank at 300 rpm with the drawn spring the roller bounces on it: it
    leaves and strikes the working flank again, each flight shorter (a jump without a switch). Each bounce is a
    ``flank_bounce`` event with where it left, where it struck and its flight; chunking the samples changes none."""
    omega = 300 * RPM
    t = np.arange(1, 1601) * 1e-4                 # to the switch to the other flank, back, and the bounces after
    one = CamBarPlant(PinInsertionMechanism(k=1090.0), Setting(ConstantSpeed(omega), fidelity=2))
    chunked = CamBarPlant(PinInsertionMechanism(k=1090.0), Setting(ConstantSpeed(omega), fidelity=2))
    one.advance(t)
    for c in np.array_split(t, 7):
        chunked.advance(c)
    kinds = [(e.kind, e.data.get("to", e.data.get("flank"))) for e in one.events if e.kind.startswith("flank_")]
    assert kinds[:2] == [("flank_switch", "other"), ("flank_switch", "working")]
    bounces = [e for e in one.events if e.kind == "flank_bounce"]
    assert len(bounces) >= 2 and all(k == ("flank_bounce", "working") for k in kinds[2:])
    flights = [e.data["flight"] for e in bounces]
    assert all(f > 0 for f in flights) and flights == sorted(flights, reverse=True)   # each flight shorter
    for e in bounces:
        left, struck = e.data["left_phi"], e.data["phi"]
        assert 0 < struck - left == pytest.approx(omega * e.data["flight"], rel=1e-6)
    again = [e for e in chunked.events if e.kind.startswith("flank_")]
    assert [e.kind for e in again] == [k for k, _ in kinds]
    assert [e.time for e in again] == pytest.approx([e.time for e in one.events if e.kind.startswith("flank_")],
                                                    abs=1e-5)


def test_per_cycle_variation_runs_each_revolution_with_its_own_loads():
    mech = CamBarPlant(PinInsertionMechanism(), Setting(fidelity=2, variation=CycleVariation({"sensor_preload": 2.0}),
                                                        rng=np.random.default_rng(7)))
    t = np.arange(0.39, 0.41, 1e-4)       # across the boundary of revolutions 0 and 1 at 150 rpm
    out = mech.advance(t)
    cycle = out["phi"] // (2 * np.pi)
    offset = out["F_rod"] - out["rod_tension"]
    drawn = [mech.cycles.mechanism(c).sensor_preload for c in (0, 1)]
    assert offset[cycle == 0] == pytest.approx(drawn[0]) and offset[cycle == 1] == pytest.approx(drawn[1])
    assert abs(drawn[0] - drawn[1]) > 0.01


def test_level2_scene_records_end_to_end(tmp_path):
    out = tmp_path / "l2.mcap"
    summary = run_scene(SCENE, out, cycles=1)
    assert summary.curves == 1
    rec = read_recording(out)
    assert {"psi_kin", "delta_w", "delta_o", "R23"} <= set(rec.truth)
    gap = rec.truth["psi"] - rec.truth["psi_kin"]
    assert 0.0 < np.max(np.abs(gap)) < 1e-3                      # the follower deviates from the cam law
    assert np.max(rec.truth["delta_w"]) > 1e-6                   # pressed into the working flank
    curve = rec.curves[0]
    assert 0.041 < curve.x.max() < 0.043
    # the pin's force-travel law: no ringing (a step rang the contact ±100 N), the rod force follows level 1 of the
    # cycle's drawn machine (F_c 42.9 N) within what the load cell's static errors allow (its description's bounds)
    drawn = CamBarPlant.from_scene(load_scene(SCENE)).cycles.mechanism(0)
    peak = drawn.kinetostatics(np.linspace(0, 2 * np.pi, 3601), 150 * RPM).F_rod.min()
    cell = tomllib.loads((ROOT / "data" / "devices" / "burster_8411.toml").read_text())["transducer"]
    full_scale = to_si(cell["range_max"], "N")
    static = (full_scale * sum(to_si(cell[k], "1") for k in ("zero_offset_max", "nonlinearity_max"))
              + full_scale * to_si(cell["hysteresis_max"], "1") / 2 + to_si(cell["gain_error_max"], "1") * abs(peak))
    assert abs(curve.y.min() - peak) < static + 1.0              # 8.3 N + the noise and the 2 kHz element's ripple


def test_a_driven_cam_switches_to_the_next_cycles_loads_at_its_revolution_whatever_the_chunk():
    """With a cam drive the cam angle is a state: each revolution still runs with its own cycle's load parameters
    from the sample where it begins, so 250 ms chunks (longer than the dwell before the insertion) give the
    truth of 10 ms chunks; before, a chunk ran whole with the cycle it started in and a revolution began with
    the last one's insertion force."""
    from rig.runner.plants import make_plant
    scene = load_scene(ROOT / "data" / "scenes" / "pin_insertion_as_tested.toml")
    t = np.arange(1, 12_001) * 1e-4                         # 1.2 s: the start-up and two revolutions more
    runs = {}
    for chunk in (0.01, 0.25):
        plant = make_plant("cam_bar", scene)
        n = round(chunk * 1e4)
        parts = [plant.advance(c) for c in np.split(t, range(n, t.size, n))]
        runs[chunk] = {k: np.concatenate([p[k] for p in parts]) for k in ("R23", "F_rod", "phi")}
    fine, coarse = runs[0.01], runs[0.25]
    assert fine["phi"][-1] > 2 * np.pi * 2.5                       # into the third revolution
    # 1e-3 N apart (the restarts' rounding); a revolution run with the last cycle's loads was 2.6 N off
    assert np.max(np.abs(coarse["F_rod"] - fine["F_rod"])) < 1e-3 * np.max(np.abs(fine["F_rod"]))
    assert np.max(np.abs(coarse["R23"] - fine["R23"])) < 1e-3 * np.max(np.abs(fine["R23"]))


def test_level2_starts_with_its_first_sample_alone():
    """A first advance of one sample is the initial state (nothing to integrate), and the run goes on from it exactly
    as in one advance (the runner's wiring probe advances one sample)."""
    scene = load_scene(SCENE)
    whole, split = CamBarPlant.from_scene(scene, nominal=True), CamBarPlant.from_scene(scene, nominal=True)
    t = (1 + np.arange(2000)) / 10_000
    ref = whole.advance(t)
    first, rest = split.advance(t[:1]), split.advance(t[1:])
    for key in ("s", "psi", "R23", "e"):
        if key in ref:
            assert np.array_equal(np.concatenate([first[key], rest[key]]), ref[key]), key


def test_the_recording_holds_no_plant_signal_or_event_from_after_the_run(tmp_path, capsys):
    """The host computes the plant's theory in blocks of 0.5 s: a 3-cycle run of the machine as drawn at 300 rpm stopped
    at 0.75 s, but its recording held truth to 1.0 s and 10 flank switches (5 revolutions) beside 3 curves (an audit).
    The last block is now cut where the machine stopped; a forced level is the one the wiring check speaks of; a
    solver that cannot go on is one error line naming the integration."""
    from rig.cli import main
    drawn = ROOT / "data" / "scenes" / "pin_insertion_as_drawn.toml"
    out = tmp_path / "drawn.mcap"
    summary = run_scene(drawn, out, cycles=3)
    rec = read_recording(out)
    # the machine stops after the step (100 ms) in which its 3rd curve ended (0.572 s): at 0.6 s; the bus then drains
    # to 0.75 s with no plant behind it (an audit found the truth there, and a 4th revolution's flank switches)
    assert 0.7 < summary.simulated_time <= 0.75 and rec.truth["t"][-1] == pytest.approx(0.6)    # the drain: the
    # queued frames, some of whose sizes follow the sensors' draws (0.75 s, 0.745 s after their streams were named)
    plant = [e for e in rec.events if e["kind"] in ("flank_switch", "flank_bounce")]
    assert plant and max(e["t"] for e in plant) <= 0.6
    assert len([e for e in rec.events if e["kind"] == "flank_switch"]) == 6        # two in each of the 3 revolutions
    stroke = tmp_path / "stroke.toml"
    stroke.write_text(drawn.read_text().replace('questions = ["stroke", "rod_force", "flank_switches"]',
                                                'questions = ["stroke"]'))
    capsys.readouterr()
    assert main(["-q", "run", str(stroke), "--fidelity", "2", "--cycles", "1", "--no-report",
                 "-o", str(tmp_path / "s.mcap")]) == 0
    assert "does not have at this model level" not in capsys.readouterr().err
    soft = tmp_path / "soft.toml"
    soft.write_text(drawn.read_text().replace('roller_width = "10 mm"', 'roller_width = "0.08 mm"'))
    assert main(["-q", "run", str(soft), "--fidelity", "2", "--cycles", "1", "--no-report",
                 "-o", str(tmp_path / "soft.mcap")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rig: error: the plant model could not go on: solver diverged: roller "
                                               "penetrates a flank") and re.search(r"integrated with (DP45|Tsit5) \(rtol = ",
                                                                                    err[0])

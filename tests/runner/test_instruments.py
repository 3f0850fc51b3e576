"""The scene's instruments: draws from the seed and each one's name, not from where its table stands; channels the
curve frames cannot carry said before the run."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from rig.runner.config import read_config
from rig.runner.machine import instruments, seeded_generators
from rig.scene import load_scene

SCENE = Path(__file__).resolve().parents[2] / "data" / "scenes" / "pin_insertion.toml"


def _readings(scene_text: str, tmp_path: Path, name: str) -> dict[str, np.ndarray]:
    path = tmp_path / name
    path.write_text(scene_text)
    transducers, _ = instruments(read_config(load_scene(path), choose_level=False))
    t = np.linspace(0.0, 0.05, 500)
    return {k: sensor.measure(t, np.full(t.size, 0.01 if "lvdt" in k else -40.0)) for k, sensor in transducers.items()}


def test_generators_depend_on_the_seed_and_the_name_alone():
    one = seeded_generators(7, ["device", "a", "b"])
    other = seeded_generators(7, ["b", "extra", "a", "device"])
    assert all(one[k].random() == other[k].random() for k in ("device", "a", "b"))
    assert seeded_generators(8, ["a"])["a"].random() != seeded_generators(7, ["a"])["a"].random()
    draws = seeded_generators(7, ["a", "b"])
    assert draws["a"].random() != draws["b"].random()


def test_swapping_or_adding_transducer_tables_keeps_each_sensors_draws(tmp_path):
    """Swapping [transducers.rod_force] and [transducers.gripper_lvdt] re-drew both (x_max 42.16 → 41.89 mm, same
    seed; an audit): the sensors read the same whatever the order, and a table added first changes no other's."""
    text = SCENE.read_text()
    start, mid = text.index("[transducers.rod_force]"), text.index("[transducers.gripper_lvdt]")
    end = text.index("\n[", mid + 1)
    assert start < mid < end
    swapped = text[:start] + text[mid:end].rstrip("\n") + "\n\n" + text[start:mid].rstrip("\n") + "\n" + text[end:]
    base = _readings(text, tmp_path, "base.toml")
    turned = _readings(swapped, tmp_path, "swapped.toml")
    assert set(base) == set(turned) >= {"rod_force", "gripper_lvdt"}
    for name in base:
        np.testing.assert_array_equal(base[name], turned[name])


def test_a_channel_measuring_beyond_the_curve_frames_is_said_before_the_run(caplog, tmp_path):
    """An angle channel (10 V = 340°) sent its curves clipped at ±0.524 rad (±30°: the X field is sized for metres),
    said only by curve_clipped events after the run (an audit). The scene check says it, once."""
    from types import SimpleNamespace

    from rig.runner.machine import _warn_beyond_curve_fields
    angle = {"enabled": True, "unit": "rad", "range": 10.0, "tare_at_start": False,
             "scaling": {"mode": "sensitivity", "electrical": 10.0, "engineering": np.radians(340.0), "zero": 0.0}}
    metres = dict(angle, unit="m", scaling={"mode": "sensitivity", "electrical": 5.0, "engineering": 0.1, "zero": 0.0})
    cfg = SimpleNamespace(scene=SimpleNamespace(path=tmp_path / "angle.toml"))
    with caplog.at_level("WARNING"):
        _warn_beyond_curve_fields(cfg, {"channels": {"x": angle, "y": dict(metres, unit="N")}})
        _warn_beyond_curve_fields(cfg, {"channels": {"x": angle}})
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 1 and "[device.config.channels.x]: the channel measures up to ±5.934 rad" in said[0]
    assert "carry ±0.5243 rad (CurveBlock.X)" in said[0] and "an angle channel carries ±30°" in said[0]
    caplog.clear()
    with caplog.at_level("WARNING"):                    # the demo's LVDT: ±0.2 m within the field
        _warn_beyond_curve_fields(SimpleNamespace(scene=SimpleNamespace(path=tmp_path / "m.toml")),
                                  {"channels": {"x": metres}})
    assert not caplog.records


def test_a_channel_scaled_for_another_transducer_is_said(caplog, tmp_path):
    """A 2 mV/V cell on the channel set for 1.5 mV/V = 1000 N read every force 1.333× too large, without a word (an
    audit). The scene check names the transducer, the channel and the factor; the demo as shipped says nothing."""
    text = SCENE.read_text()
    assert 'description = "burster_8411"' in text
    swapped = text.replace('description = "burster_8411"', 'description = "burster_8411"\noverrides = { '
                           'output_at_max = "2 mV/V", output_at_min = "-2 mV/V" }', 1)
    with caplog.at_level("WARNING"):
        _readings(swapped, tmp_path, "cell.toml")
        _readings(text, tmp_path, "demo.toml")
    said = [r.getMessage() for r in caplog.records if "scaling" in r.getMessage()]
    assert len(said) == 1 and "cell.toml [transducers.rod_force] → device.y" in said[0]
    assert "-1000 … 1000 N as -1333 … 1333 N (× 1.333)" in said[0]

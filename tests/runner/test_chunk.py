"""The runner's chunk is a setting of the computation, not of the machine: the unit and its bus run in their own
transmit cycles (``[links.can] tx_period``) within a chunk and the transducers filter and count alike however their
samples are cut, so with a plant evaluated point by point (the demo, level 1) a chunk of one cycle and a chunk of
twenty record the same values, frame for frame (a plant that integrates restarts at each step: docs/can-protocol.md)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rig.recorder import read_recording
from rig.runner import run_scene
from rig.runner.session import RunError
from rig.scene import SceneError, load_scene
from rig.runner.config import read_config

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "data" / "scenes" / "pin_insertion.toml"


def _with(tmp_path: Path, name: str, **keys: str) -> Path:
    """The demo scene with its [scene] chunk and [links.can] keys replaced (``chunk``, ``tx_period``)."""
    text = SCENE.read_text()
    chunk = next(line for line in text.splitlines() if line.startswith("chunk = "))
    text = text.replace(chunk, f'chunk = "{keys.pop("chunk")}"', 1) if "chunk" in keys else text
    for key, value in keys.items():
        text = text.replace("[links.can]\n", f'[links.can]\n{key} = "{value}"\n', 1)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _content(path: Path) -> dict:
    """Everything a recording holds, decoded (the bus frame by frame, curves, results, statistics, events, series)."""
    rec = read_recording(path)
    return {"frames": {k: np.asarray(v) for k, v in rec.can_frames.items()},
            "curves": [(c.number, c.program, c.t, c.x, c.y, c.angle, c.theory, c.extra) for c in rec.curves],
            "results": rec.results, "statistics": rec.statistics, "events": rec.events,
            "series": {topic: rec.series[topic] for topic in rec.series},
            "topics": sorted(rec.message_counts), "end": rec.simulation_time}


def _same(a, b, where: str = "") -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and sorted(a) == sorted(b), where
        for k in a:
            _same(a[k], b[k], f"{where}/{k}")
    elif isinstance(a, (list, tuple)):
        assert isinstance(b, (list, tuple)) and len(a) == len(b), f"{where}: {len(a)} != {len(b)}"
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray):
        assert np.array_equal(a, np.asarray(b), equal_nan=a.dtype.kind == "f"), where
    else:
        assert a == b or (a != a and b != b), f"{where}: {a!r} != {b!r}"


def test_a_long_chunk_records_what_a_chunk_of_one_cycle_records(tmp_path: Path):
    """The demo in chunks of 100 ms (one transmit cycle), 300 ms and 2 s: the same frames at the same times (the live
    data planned cycle by cycle, the readings and heartbeats of each cycle), curves, results, statistics, events and
    series; the run ends at the end of the cycle with its last curve, not of the chunk. Before, a 2 s chunk planned
    its live data over 2 s at once and queued 5 curves in one step (the run failed: "too long for the bus")."""
    runs = {chunk: tmp_path / f"{chunk.replace(' ', '')}.mcap" for chunk in ("100 ms", "300 ms", "2 s")}
    for chunk, out in runs.items():
        run_scene(_with(tmp_path, chunk.replace(" ", ""), chunk=chunk), out, cycles=6)
    one = _content(runs["100 ms"])
    assert len(one["curves"]) == 6 and one["frames"]["t"].size > 10_000
    assert any(e["kind"] == "live_dropped" for e in one["events"])      # the live policy is at work in these runs
    for chunk in ("300 ms", "2 s"):
        _same(one, _content(runs[chunk]), chunk)


def test_a_run_of_a_duration_ends_at_the_first_cycle_end_after_it(tmp_path: Path, monkeypatch):
    """A 0.35 s stand run in 1 s chunks: the machine stops at 0.4 s, the end of the transmit cycle that reaches
    0.35 s (as in 100 ms chunks), and its plant computes nothing beyond; the recording's truth ends at 0.35 s."""
    import rig.runner.machine as machine
    reached = []
    make = machine.make_plant

    def spied(*args, **kwargs):
        plant = make(*args, **kwargs)
        if kwargs.get("nominal"):              # the signal probe (one chunk from 0) and the host's theory
            return plant
        advance = plant.advance
        plant.advance = lambda t: (reached.append(float(t[-1])), advance(t))[1]
        return plant

    monkeypatch.setattr(machine, "make_plant", spied)
    text = (ROOT / "data" / "scenes" / "clutch_startup.toml").read_text()
    assert 'duration = "0.8 s"' in text and 'chunk = "100 ms"' in text
    short = tmp_path / "short.toml"
    short.write_text(text.replace('duration = "0.8 s"', 'duration = "0.35 s"').replace('chunk = "100 ms"',
                                                                                       'chunk = "1 s"'))
    summary = run_scene(short, tmp_path / "short.mcap")
    assert 0.4 <= summary.simulated_time < 0.45 and max(reached) == pytest.approx(0.4)
    assert read_recording(tmp_path / "short.mcap").truth["t"][-1] == pytest.approx(0.35)


@pytest.mark.parametrize("keys, error", [
    ({"chunk": "250 ms"}, r"\[scene\]: key 'chunk' = 0.25 s must be a whole number of the unit's transmit cycles "
                          r"\(\[links.can\] tx_period = 0.1 s; it holds 2.5\).*or tx_period to a divisor of it"),
    ({"chunk": "100.0001 s"}, r"\[scene\]: key 'chunk' = 100 s must be a whole number .* it holds 1000"),
    ({"tx_period": "-0.1 s"}, r"\[links.can\]: key 'tx_period' must be positive, got -0.1 s"),
    ({"tx_period": "0.15 ms"}, r"\[links.can\]: key 'tx_period' = 0.00015 s must be a whole number \(at least 2\) of "
                               r"samples at \[scene\] sample_rate = 10000 Hz \(it holds 1.5\)"),
])
def test_a_chunk_or_cycle_that_does_not_divide_is_refused(tmp_path: Path, keys: dict, error: str):
    with pytest.raises(SceneError, match=error):
        read_config(load_scene(_with(tmp_path, "bad", **keys)))


def test_a_transmit_cycle_that_measures_several_curves_at_once_is_named_not_the_bus(tmp_path: Path):
    """A 2 s transmit cycle ends 5 demo cycles before the bus can send any: the queue is full because of the cycle;
    the error names [links.can] tx_period, not the bitrate."""
    scene = _with(tmp_path, "long_cycle", chunk="2 s", tx_period="2 s")
    with pytest.raises(RunError, match=r"one transmit cycle of the unit \(2 s\) measured \d+ curves at once.*if the "
                                       r"machine makes that many cycles so fast, shorten \[links.can\] tx_period "
                                       r"\(e.g. \"100 ms\"\)"):
        run_scene(scene, tmp_path / "long.mcap", cycles=10)

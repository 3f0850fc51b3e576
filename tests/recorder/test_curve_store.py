"""Curves and series read back in bounded memory (rig.recorder.curves, rig.recorder.series): beyond the held bytes a
curve is read again from the file when used, and looks the same as a held one; a series topic's later blocks are
noted, not held, the exports still write every sample, and the report says what its charts and analyses cover."""
from __future__ import annotations

import os
import pickle
from pathlib import Path

import numpy as np
import pytest

import rig.recorder.curves as curves
import rig.recorder.series as bulk
import rig.recorder.store as store
from rig.analysis.report import write_report
from rig.recorder import RecordingError, read_recording
from rig.recorder.schemas import TRUTH
from rig.runner import run_scene

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("store") / "run.mcap"
    run_scene(ROOT / "data" / "scenes" / "pin_insertion.toml", out, cycles=12, progress=False)
    return out


def _arrays(c) -> list:
    return [c.t, c.x, c.y, c.angle, *sorted(c.theory.items())]


def _same(a, b) -> bool:
    pairs = list(zip(_arrays(a), _arrays(b)))
    return len(_arrays(a)) == len(_arrays(b)) and all(
        (x is None and y is None) or (isinstance(x, tuple) and x[0] == y[0] and np.array_equal(x[1], y[1]))
        or (isinstance(x, np.ndarray) and np.array_equal(x, y)) for x, y in pairs)


def test_curves_beyond_the_held_bytes_are_read_again_and_equal(recording, monkeypatch):
    held = read_recording(recording)
    assert all(c.held for c in held.curves)
    first = sum(curves.nbytes({k: getattr(c, k) for k in curves.ARRAYS}) for c in held.curves[:3])
    monkeypatch.setattr(curves, "KEPT_BYTES", first)
    monkeypatch.setattr(store, "CACHED_CHUNKS", 1)
    lazy = read_recording(recording)
    assert [c.held for c in lazy.curves] == [True] * 3 + [False] * (len(lazy.curves) - 3)
    assert [c.number for c in lazy.curves] == [c.number for c in held.curves]
    for c, h in zip(reversed(lazy.curves), reversed(held.curves)):        # any order: chunks are read again
        assert _same(c, h) and (c.samples, c.has_angle, c.theory_sizes) == (h.samples, h.has_angle, h.theory_sizes)
        assert c.extra == h.extra and c.program == h.program
    again = pickle.loads(pickle.dumps(lazy))                                 # e.g. to a worker process
    assert _same(again.curves[-1], held.curves[-1])


def test_a_report_from_curves_read_again_is_the_held_ones(recording, tmp_path, monkeypatch):
    """The same report, every number and table, whether the curves are held or read again from the file."""
    write_report(recording, tmp_path / "held", fmt="md")
    monkeypatch.setattr(curves, "KEPT_BYTES", 0)
    write_report(recording, tmp_path / "lazy", fmt="md")
    for name in ("report.md", "results.csv", "curves.csv"):
        assert (tmp_path / "held" / name).read_text() == (tmp_path / "lazy" / name).read_text()


def test_a_recording_changed_after_it_was_read_is_said(recording, tmp_path, monkeypatch):
    copy = tmp_path / "copy.mcap"
    copy.write_bytes(recording.read_bytes())
    monkeypatch.setattr(curves, "KEPT_BYTES", 0)
    monkeypatch.setattr(store, "CACHED_CHUNKS", 0)                  # every use reads the file
    rec = read_recording(copy)
    with open(copy, "ab") as f:
        f.write(b"\0")
    with pytest.raises(RecordingError, match="changed after it was read"):
        rec.curves[0].t
    os.remove(copy)
    with pytest.raises(RecordingError, match="cannot read the recording's curves again"):
        rec.curves[1].t


def _joined(blocks) -> dict[str, np.ndarray]:
    blocks = list(blocks)
    return {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}


def test_a_topic_beyond_its_budget_holds_its_first_blocks_and_yields_all(recording, monkeypatch):
    whole = read_recording(recording)
    assert not whole.series_beyond
    truth = whole.truth
    per_sample = sum(v.itemsize for v in truth.values())
    budget = 1500 * per_sample                          # one block of the truth (1000 samples each) and a part
    monkeypatch.setattr(bulk, "KEPT_BYTES", budget)
    cut = read_recording(recording)
    held, beyond = cut.truth, cut.series_beyond[TRUTH]
    assert sum(v.nbytes for v in held.values()) <= budget
    assert 0 < held["t"].size < truth["t"].size
    assert held["t"].size + beyond.samples == truth["t"].size
    assert beyond.t_first > held["t"][-1] and beyond.t_last == truth["t"][-1]
    assert cut.last_time == whole.last_time
    assert cut.message_counts == whole.message_counts
    for k, v in _joined(cut.series_blocks(TRUTH)).items():
        np.testing.assert_array_equal(v, truth[k], err_msg=k)
    again = pickle.loads(pickle.dumps(cut))             # e.g. to a worker process
    np.testing.assert_array_equal(_joined(again.series_blocks(TRUTH))["t"], truth["t"])
    cut_at = min(b.t_first for b in cut.series_beyond.values())
    for topic, data in whole.series.items():             # every topic held up to one time: joins see one span
        held_t, later = cut.series.get(topic, {}).get("t", np.empty(0)), cut.series_beyond.get(topic)
        assert held_t.size + (later.samples if later else 0) == data["t"].size
        assert np.all(held_t < cut_at) and (later is None or later.t_first >= cut_at)
        assert later is None or data["t"][-1] < cut_at or later.t_last == data["t"][-1]
        np.testing.assert_array_equal(_joined(cut.series_blocks(topic))["t"], data["t"])
    assert len(cut.series_beyond) > 1                    # the encoder's readings cut where the truth's were


def test_the_exports_hold_every_sample_and_the_report_says_what_is_held(recording, tmp_path, monkeypatch):
    write_report(recording, tmp_path / "held", fmt="md")
    monkeypatch.setattr(bulk, "KEPT_BYTES", 1)          # every topic: its first block held, the rest noted
    write_report(recording, tmp_path / "cut", fmt="md")
    exported = sorted(p.name for p in (tmp_path / "held").glob("stand_*.csv"))
    assert exported
    for name in exported + ["results.csv", "curves.csv"]:
        assert (tmp_path / "held" / name).read_text() == (tmp_path / "cut" / name).read_text(), name
    report = (tmp_path / "cut" / "report.md").read_text()
    assert "Read in bounded memory" in report and f"{TRUTH}: " in report and "beyond the" in report
    assert "Read in bounded memory" not in (tmp_path / "held" / "report.md").read_text()


def test_a_recording_changed_after_it_was_read_is_said_for_its_series(recording, tmp_path, monkeypatch):
    copy = tmp_path / "copy.mcap"
    copy.write_bytes(recording.read_bytes())
    monkeypatch.setattr(bulk, "KEPT_BYTES", 1)
    rec = read_recording(copy)
    with open(copy, "ab") as f:
        f.write(b"\0")
    with pytest.raises(RecordingError, match="its series are read again"):
        list(rec.series_blocks(TRUTH))

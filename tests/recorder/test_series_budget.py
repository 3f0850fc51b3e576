"""Bulk series read back in bounded memory (rig.recorder.series): beyond a topic's held bytes the blocks are noted,
not held; the exports still write every sample, and the report says what its charts and analyses cover."""
from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

import rig.recorder.series as bulk
from rig.analysis.report import write_report
from rig.recorder import RecordingError, read_recording
from rig.recorder.schemas import TRUTH
from rig.runner import run_scene

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("series") / "run.mcap"
    run_scene(ROOT / "data" / "scenes" / "pin_insertion.toml", out, cycles=6, progress=False)
    return out


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
    for topic, data in whole.series.items():             # the smaller topics held whole
        if topic not in cut.series_beyond:
            assert cut.series[topic]["t"].size == data["t"].size


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

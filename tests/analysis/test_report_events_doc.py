"""Every event kind the report explains is named in docs/recording.md's /events row (a user reading the
recording's topics finds each kind there)."""
from __future__ import annotations

from pathlib import Path

from rig.analysis.report import EVENT_MEANING

DOC = Path(__file__).resolve().parents[2] / "docs" / "recording.md"


def test_every_event_kind_is_named_in_the_recording_doc():
    row = next(line for line in DOC.read_text(encoding="utf-8").splitlines() if line.startswith("| `/events` |"))
    missing = [kind for kind in EVENT_MEANING if f"`{kind}`" not in row]
    assert not missing, f"docs/recording.md's /events row does not name {missing}"

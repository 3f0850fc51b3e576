"""`rig repair`: a cut or damaged recording rewritten as a whole MCAP file that indexed readers open (the mcap
library's seeking reader here; `@mcap/core` and Foxglove's rules by hand on a killed demo run), holding exactly what the
salvage reader reads, and saying in its end record what was lost."""
from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader

from rig.cli import main
from rig.recorder import RecordingError, read_recording
from rig.recorder.repair import repair
from rig.runner import run_scene

from tests.recorder.test_damaged import _chunks, _flip, _record

ROOT = Path(__file__).resolve().parents[2]


def _messages(path: Path) -> list[tuple[str, int, int, bytes]]:
    """(topic, log time, sequence, data) of every message, in file order, by the indexed reader."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        reader.get_summary()                        # an indexed reader: needs the summary and footer
        return [(c.topic, m.log_time, m.sequence, m.data) for _, c, m in reader.iter_messages(log_time_order=False)]


def test_a_cut_recording_is_rewritten_whole_with_what_the_salvage_reads(tmp_path):
    whole = _record(tmp_path / "whole.mcap")
    raw = whole.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(raw[:_chunks(whole)[7].chunk_start_offset + 40])      # killed inside chunk 8
    with pytest.raises(Exception):
        _messages(cut)                                                     # what Foxglove's reader refuses
    done = repair(cut, tmp_path / "fixed.mcap")
    salvaged = read_recording(cut, allow_partial=True)
    fixed = read_recording(done.path)                                      # no allow_partial needed
    assert not fixed.truncated and not fixed.complete and fixed.interrupted.startswith("repaired by rig repair from")
    assert "cut short or damaged, then repaired by rig repair from cut.mcap: " in "; ".join(fixed.problems)
    assert [c.number for c in fixed.curves] == [c.number for c in salvaged.curves] == list(range(1, 8))
    assert fixed.message_counts == salvaged.message_counts and done.messages == dict(salvaged.message_counts)
    assert fixed.scene_text == salvaged.scene_text and fixed.metadata["rig"] == salvaged.metadata["rig"]
    original = _messages(whole)
    assert _messages(done.path) == original[:len(_messages(done.path))]    # the same records, times and sequences
    assert done.problems and "chunk 8" in done.problems[0]
    # the cut file has no end record: the repaired one states the simulated time its data reach, as a reader finds it
    assert fixed.simulation_time == salvaged.last_time == fixed.last_time > 0.0
    assert fixed.simulation_time < read_recording(whole).simulation_time


def test_a_copy_cut_in_its_last_chunk_states_the_time_its_data_reach_not_the_runs(tmp_path):
    """The end record is written before the last chunk: a copy cut inside that chunk has it (the whole run's time,
    complete) but not the chunk's messages; the repaired file says the time the data kept reach, and the run's."""
    whole = tmp_path / "whole.mcap"
    run_scene(ROOT / "data" / "scenes" / "pin_insertion.toml", whole, cycles=10)     # 4.3 s in two chunks
    last = _chunks(whole)[-1]
    assert last.message_end_time - last.message_start_time > 0.2e9
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(whole.read_bytes()[:last.chunk_start_offset + last.chunk_length // 2])
    fixed = read_recording(repair(cut, tmp_path / "fixed.mcap").path)
    run_time = read_recording(whole).simulation_time
    assert not fixed.complete and fixed.simulation_time == fixed.last_time < run_time
    assert f"its end record said {run_time:.6g} s of simulation" in fixed.interrupted
    raw = cut.read_bytes()                       # the end record's time damaged in the copy: repaired all the same
    said = repr(run_time).encode()
    assert raw.count(said) == 1
    cut.write_bytes(raw.replace(said, said[:-1] + b"x"))
    fixed = read_recording(repair(cut, tmp_path / "fixed2.mcap").path)
    assert fixed.simulation_time == fixed.last_time
    assert "its end record gave a damaged simulation time" in fixed.interrupted


def test_a_damaged_middle_chunk_is_named_and_the_rest_rewritten(tmp_path):
    whole = _record(tmp_path / "whole.mcap")
    index = _chunks(whole)[4]
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(_flip(whole.read_bytes(), index.chunk_start_offset + index.chunk_length // 2))
    done = repair(damaged, tmp_path / "fixed.mcap")
    fixed = read_recording(done.path)
    assert "fails its CRC" in done.problems[0] and "fails its CRC" in fixed.interrupted
    assert len(fixed.curves) == len(read_recording(damaged, allow_partial=True).curves) < 12
    said = "; ".join(fixed.problems)        # it said "cut short, then repaired … at 20.295 s" (an audit)
    assert "cut short or damaged, then repaired" in said and "(its data reach " in said


def test_a_whole_recording_repairs_to_itself(tmp_path):
    whole = _record(tmp_path / "whole.mcap")
    done = repair(whole, tmp_path / "copy.mcap")
    assert done.problems == [] and read_recording(done.path).complete
    assert _messages(done.path) == _messages(whole)


def test_nothing_to_repair_and_no_overwriting_of_the_source(tmp_path, capsys):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 20)
    with pytest.raises(RecordingError, match="no message can be read from it"):
        repair(junk, tmp_path / "out.mcap")
    assert not (tmp_path / "out.mcap").exists() and [p.name for p in tmp_path.iterdir()] == ["junk.mcap"]
    with pytest.raises(ValueError, match="must not replace its source"):
        repair(junk, junk)
    assert main(["repair", str(junk), "-o", str(junk)]) == 2       # whether damaged or not: the file it reads
    assert "that is the recording it reads (name another)" in capsys.readouterr().err


def test_cli_repair_names_its_output_and_what_was_lost(tmp_path, capsys):
    whole = _record(tmp_path / "whole.mcap")
    cut = tmp_path / "run.mcap"
    cut.write_bytes(whole.read_bytes()[:_chunks(whole)[5].chunk_start_offset + 40])
    assert main(["repair", str(cut)]) == 0
    out = capsys.readouterr().out
    fixed = tmp_path / "run.repaired.mcap"
    assert f"-> {fixed}" in out and "the source lacks what is lost for good: chunk 6" in out
    assert main(["report", str(fixed), "-o", str(tmp_path / "report"), "--format", "md"]) == 0
    report = (tmp_path / "report" / "report.md").read_text()
    assert "cut short or damaged, then repaired by rig repair from run.mcap" in report
    assert main(["repair", str(cut), "-o", str(cut)]) == 2


def test_messages_of_a_lost_chunk_of_definitions_are_kept_by_the_summary(tmp_path):
    """A flipped byte in chunk 2 (where the result, event and log channels are defined): the salvage reader reads their
    later messages by the intact summary's channels, and repair wrote only the curves (11 of 44 messages)."""
    whole = _record(tmp_path / "whole.mcap")
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(_flip(whole.read_bytes(), 15_000))
    salvaged = read_recording(damaged, allow_partial=True)
    done = repair(damaged, tmp_path / "fixed.mcap")
    assert done.messages == dict(salvaged.message_counts) and len(done.messages) > 1
    assert len(read_recording(done.path).results) == len(salvaged.results) > 0


def test_a_whole_run_whose_summary_alone_was_cut_stays_complete(tmp_path):
    """Every message and the end record read (the file cut inside its summary): nothing of the run is lost, so the
    rewritten file is complete, the repair noted in metadata ``rig.repair``."""
    whole = _record(tmp_path / "whole.mcap")
    raw = whole.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(raw[:len(raw) - 200])
    done = repair(cut, tmp_path / "fixed.mcap")
    fixed = read_recording(done.path)
    assert done.problems and done.whole and fixed.complete and fixed.metadata["rig.repair"]["source"] == "cut.mcap"
    assert fixed.message_counts == read_recording(whole).message_counts


def test_cli_repair_of_a_run_that_lost_only_its_index_says_nothing_was_lost(tmp_path, capsys):
    """It said "the source lacks what is lost for good: file ends after a whole record…" where every message and the
    end record were read (an audit)."""
    from rig.cli import main
    raw = _record(tmp_path / "whole.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(raw[:len(raw) - 200])
    assert main(["repair", str(cut), "-o", str(tmp_path / "fixed.mcap")]) == 0
    out = capsys.readouterr().out
    assert "nothing of the run was lost: every message and its end record were read" in out
    assert "lost for good" not in out


def test_an_empty_file_is_named(tmp_path):
    (tmp_path / "empty.mcap").write_bytes(b"")
    with pytest.raises(RecordingError, match="empty file"):
        repair(tmp_path / "empty.mcap", tmp_path / "out.mcap")


def _after_end_record(raw: bytes) -> int:
    """Offset just after the data section's ``rig.end`` metadata record (opcode 0x0C, then its length, then the name
    with its uint32 length)."""
    at = 0
    while True:
        at = raw.index(b"\x07\x00\x00\x00rig.end", at + 1)
        start = at - 9
        if raw[start] == 0x0C:
            return start + 9 + int.from_bytes(raw[start + 1:start + 9], "little")


def test_a_file_cut_after_its_end_record_has_lost_its_last_chunk_and_says_so(tmp_path):
    """The recorder writes the run's end record before the writer flushes its last chunk: a file cut between them (a
    kill, a full disk) read every record up to the cut and the end record, and repair called it whole — "nothing of
    the run was lost", complete — with 3 of 50 curves gone (an audit). The end record's message count tells."""
    whole = _record(tmp_path / "whole.mcap")
    raw = whole.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(raw[:_after_end_record(raw)])
    done = repair(cut, tmp_path / "fixed.mcap")
    fixed = read_recording(done.path)
    counted = int(read_recording(whole).end["messages"])
    kept = sum(fixed.message_counts.values())
    assert kept < counted and not done.whole and not fixed.complete
    assert any(f"{counted - kept} of the {counted} messages the run's end record counts are not in the file" in p
               for p in done.problems)


def test_a_run_whose_damage_cannot_be_told_from_its_data_stays_incomplete(tmp_path):
    """A bit flipped in a message index and one in the run's metadata both show only as the data section's CRC: the
    repair cannot tell an index-only damage from a changed seed, so either stays marked incomplete (calling the first
    whole called the second whole too, its seed changed; a review)."""
    whole = _record(tmp_path / "whole.mcap")
    first = _chunks(whole)[0]
    damaged = tmp_path / "index.mcap"
    damaged.write_bytes(_flip(whole.read_bytes(), first.chunk_start_offset + first.chunk_length + 20))
    assert read_recording(damaged, allow_partial=True).problems            # the damage is seen
    done = repair(damaged, tmp_path / "fixed.mcap")
    fixed = read_recording(done.path)
    assert not done.whole and not fixed.complete and fixed.message_counts == read_recording(whole).message_counts


def test_a_damaged_opening_magic_is_named_read_past_and_repaired_with_nothing_lost(tmp_path, capsys):
    """One bit flipped in the file's first 8 bytes: other readers refuse it (the mcap library here); rig names the
    damage, reads every message (its summary too: the reader checks the closing magic), and `rig repair` rewrites it
    whole and complete — a file with no MCAP header after its first bytes stays "not an MCAP file"."""
    from mcap.exceptions import InvalidMagic

    from rig.recorder.reader import require_whole_file
    whole = _record(tmp_path / "whole.mcap")
    raw = bytearray(whole.read_bytes())
    raw[3] ^= 0x10
    bad = tmp_path / "magic.mcap"
    bad.write_bytes(raw)
    with pytest.raises(InvalidMagic):
        _messages(bad)
    with pytest.raises(RecordingError, match="magic.mcap: truncated or corrupt .*opening magic .* is damaged"):
        read_recording(bad)
    part, original = read_recording(bad, allow_partial=True), read_recording(whole)
    assert part.message_counts == original.message_counts and not part.lost and not part.complete
    assert len(part.problems) == 1 and part.problems[0].startswith("the file's opening magic (its first 8 bytes, ")
    with pytest.raises(RecordingError, match="opening magic .* is damaged: .* other tools refuse the file; export needs a whole file"):
        require_whole_file(bad, "export")
    assert main(["repair", str(bad), "-o", str(tmp_path / "fixed.mcap")]) == 0
    out = capsys.readouterr().out
    assert "nothing of the run was lost" in out and "opening magic" in out
    fixed = read_recording(tmp_path / "fixed.mcap")
    assert fixed.complete and fixed.message_counts == original.message_counts
    assert _messages(tmp_path / "fixed.mcap") == _messages(whole)
    capsys.readouterr()
    same = main(["export-can", "--partial", str(whole), "-o", str(tmp_path / "whole.asc")])
    assert "opening magic" not in capsys.readouterr().err
    assert main(["export-can", "--partial", str(bad), "-o", str(tmp_path / "bad.asc")]) == same   # as the whole file
    assert "the file's opening magic (its first 8 bytes" in capsys.readouterr().err     # and the damage named
    other = tmp_path / "other.mcap"
    other.write_bytes(b"GIF89a.." + b"\x02" * 40)            # no header record after the first 8 bytes
    with pytest.raises(RecordingError, match="other.mcap: not an MCAP file"):
        read_recording(other, allow_partial=True)

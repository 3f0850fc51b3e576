"""Damaged recordings (bytes altered, not only cut short): `read_recording(..., allow_partial=True)` and `rig report
--partial` skip a chunk that fails its CRC or does not decode and read on — every other chunk by the summary's chunk
index when the summary is intact, else on to the next whole chunk — and name what was lost: the chunk, its time
range, its messages per topic. Plain `rig report` refuses a damaged file in one line."""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk

from rig.cli import main
from rig.recorder import Recorder, RecordingError, read_recording
from rig.recorder.completeness import losses

CURVES = 12
START = 1_700_000_000_000_000_000          # ns since 1970: simulation time 0


def _record(path: Path) -> Path:
    """A recording of 12 curves (1 s apart, 400 samples of noise each: they do not compress) and their results,
    in chunks of ~16 kB: a dozen chunks in 0.2 s."""
    rng = np.random.default_rng(7)
    with Recorder(path, scene_text="[scene]\nname = 'damage'\n", metadata={"cycles": CURVES}, chunk_size=16_000,
                  wall_clock_start=START, view_rate=None) as rec:
        for n in range(1, CURVES + 1):
            t = n - 1 + np.linspace(0.0, 0.5, 400)
            rec.write_curve(n, 1, t, rng.normal(size=t.size), rng.normal(size=t.size))
            rec.write_result({"number": n, "program": 1, "ok": True, "elements": [], "process_values": {}}, t=t[-1])
            rec.write_event(float(t[-1]), "curve", number=n)
    return path


@pytest.fixture(scope="module")
def whole(tmp_path_factory) -> Path:
    return _record(tmp_path_factory.mktemp("damaged") / "whole.mcap")


def _chunks(path: Path) -> list:
    """The chunk index entries of a whole file, in file order."""
    with open(path, "rb") as f:
        return sorted(make_reader(f).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)


def _topics(path: Path) -> dict[int, str]:
    with open(path, "rb") as f:
        return {i: c.topic for i, c in make_reader(f).get_summary().channels.items()}


def _held(path: Path, index) -> tuple[set[int], dict[str, int]]:
    """Curve numbers and messages per topic in one chunk of the whole file (read with the mcap library)."""
    raw = path.read_bytes()
    chunk = next(StreamReader(io.BytesIO(raw[index.chunk_start_offset:index.chunk_start_offset + index.chunk_length]),
                              skip_magic=True, emit_chunks=True).records)
    assert isinstance(chunk, Chunk)
    topics, counts, curves = _topics(path), {}, set()
    for record in breakup_chunk(chunk):
        if isinstance(record, Message):
            topic = topics[record.channel_id]
            counts[topic] = counts.get(topic, 0) + 1
            if topic == "/device/curve":
                curves.add(int(read_json(record.data)["number"]))
    return curves, counts


def read_json(data: bytes) -> dict:
    import orjson
    return orjson.loads(data)


def _flip(raw: bytes, at: int) -> bytes:
    damaged = bytearray(raw)
    damaged[at] ^= 0xFF
    return bytes(damaged)


def _numbers(rec) -> list[int]:
    return [c.number for c in rec.curves]


def test_a_damaged_chunk_is_skipped_and_the_rest_read_by_the_summary(whole, tmp_path, capsys):
    """One byte flipped in the middle of the 2nd chunk: the chunks after it and the summary are intact. Everything
    else is read, and the chunk is named with its time range (the chunk index's) and its messages per topic (its
    message index's) — not "lost: the messages after the last whole chunk, the summary and the end record"."""
    chunks = _chunks(whole)
    assert len(chunks) >= 6
    second = chunks[1]
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(_flip(whole.read_bytes(), second.chunk_start_offset + second.chunk_length // 2))
    lost_curves, lost_counts = _held(whole, second)
    original = read_recording(whole)

    with pytest.raises(RecordingError, match=f"chunk 2 of {len(chunks)} .* skipped"):
        read_recording(damaged)
    rec = read_recording(damaged, allow_partial=True)
    assert rec.truncated and rec.damaged and not rec.complete and rec.read_to_data_end and not rec.data_whole
    assert _numbers(rec) == [n for n in _numbers(original) if n not in lost_curves]
    assert rec.end["complete"] == "true" and rec.scene_text == original.scene_text
    [part] = rec.lost
    assert (part.what, part.start, part.end) == (f"chunk 2 of {len(chunks)}", second.chunk_start_offset,
                                                 second.chunk_start_offset + second.chunk_length)
    assert part.times == pytest.approx(((second.message_start_time - START) / 1e9,
                                        (second.message_end_time - START) / 1e9))
    assert part.messages == lost_counts
    assert {t: original.message_counts[t] - rec.message_counts.get(t, 0) for t in original.message_counts
            if original.message_counts[t] != rec.message_counts.get(t, 0)} == lost_counts    # counted, every one
    said = losses(rec)
    assert said[0].startswith(f"chunk 2 of {len(chunks)} (bytes {second.chunk_start_offset}-")
    assert "does not decode" in said[0] or "fails its CRC" in said[0]
    assert any(line.startswith("lost: only what the damaged part named above held") for line in said)
    assert not any("after the last whole chunk" in line for line in said)
    missing = sorted(lost_curves)
    assert f"{CURVES - len(missing)} of {CURVES} requested curves recorded; the other {len(missing)} are not in the " \
           f"file (curve" in "; ".join(said)

    capsys.readouterr()
    assert main(["report", str(damaged), "-o", str(tmp_path / "strict")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "chunk 2 of" in err and f"rig report --partial {damaged}" in err
    assert not (tmp_path / "strict").exists()
    assert main(["report", "--partial", str(damaged), "-o", str(tmp_path / "report"), "--format", "md"]) == 0
    out = capsys.readouterr().out
    assert f"chunk 2 of {len(chunks)}" in out and "after the last whole chunk" not in out
    report = (tmp_path / "report" / "report.md").read_text()
    assert "| complete | no: file damaged |" in report and f"chunk 2 of {len(chunks)}" in report


def test_many_damaged_chunks_are_each_named_and_the_others_read(whole, tmp_path):
    """A byte flipped in every other chunk: every intact chunk is read (it was "holds no message")."""
    chunks = _chunks(whole)
    raw = whole.read_bytes()
    for index in chunks[::2]:
        raw = _flip(raw, index.chunk_start_offset + index.chunk_length // 2)
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(raw)
    rec = read_recording(damaged, allow_partial=True)
    lost = set().union(*(_held(whole, index)[0] for index in chunks[::2]))
    assert _numbers(rec) == [n for n in range(1, CURVES + 1) if n not in lost] and rec.curves
    assert [p.what for p in rec.lost] == [f"chunk {k} of {len(chunks)}" for k in range(1, len(chunks) + 1, 2)]
    assert all(p.messages for p in rec.lost)


def test_a_chunk_whose_record_header_is_damaged_is_read_by_its_index(whole, tmp_path):
    """The opcode or the length of the 3rd chunk's record altered: its data passes its CRC and is read where the
    summary's chunk index places it; nothing of the run is lost, the damage is named."""
    chunks = _chunks(whole)
    third = chunks[2].chunk_start_offset
    original = read_recording(whole)
    for at in (third, third + 3):                       # opcode; a byte of the length
        damaged = tmp_path / "damaged.mcap"
        damaged.write_bytes(_flip(whole.read_bytes(), at))
        rec = read_recording(damaged, allow_partial=True)
        assert _numbers(rec) == _numbers(original) and rec.message_counts == original.message_counts
        assert rec.damaged and rec.data_whole and not rec.lost
        assert rec.problems[0].startswith(f"chunk 3 of {len(chunks)} (byte {third}): its record header is damaged")
        assert any(line.startswith("nothing of the run is lost") for line in losses(rec))


def test_without_a_summary_reading_resumes_at_the_next_whole_chunk(whole, tmp_path):
    """Bytes inserted in the 2nd chunk shift every offset after them (the summary's index no longer fits, its CRC
    check fails): the chunk is lost, the bytes after it are skipped up to the next whole chunk, and the rest is read."""
    chunks = _chunks(whole)
    second = chunks[1]
    middle = second.chunk_start_offset + second.chunk_length // 2
    raw = whole.read_bytes()
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(raw[:middle] + b"\x00damage" + raw[middle:])
    rec = read_recording(damaged, allow_partial=True)
    lost_curves, _ = _held(whole, second)
    assert _numbers(rec) == [n for n in range(1, CURVES + 1) if n not in lost_curves]
    assert rec.lost[0].what == "chunk 2" and rec.lost[0].start == second.chunk_start_offset
    assert rec.lost[0].times == pytest.approx(((second.message_start_time - START) / 1e9,
                                               (second.message_end_time - START) / 1e9))       # its own header's
    assert rec.read_to_data_end and rec.end["complete"] == "true"


def test_a_cut_file_with_a_damaged_chunk_is_read_on_to_the_cut(whole, tmp_path):
    """No summary (the file is cut in its 6th chunk) and the 3rd chunk damaged: chunks 1, 2, 4 and 5 are read, the
    3rd is named with its messages (from the message index after it), the cut is said as for any cut file."""
    chunks = _chunks(whole)
    third, sixth = chunks[2], chunks[5]
    raw = _flip(whole.read_bytes(), third.chunk_start_offset + third.chunk_length // 2)
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(raw[:sixth.chunk_start_offset + 100])
    rec = read_recording(damaged, allow_partial=True)
    kept = set().union(*(_held(whole, chunks[k])[0] for k in (0, 1, 3, 4)))
    assert set(_numbers(rec)) == kept
    part, cut = rec.lost
    assert part.what == "chunk 3" and part.messages == _held(whole, third)[1] and not part.cut
    assert cut.cut and cut.what == "chunk 6" and cut.log_times == (sixth.message_start_time, sixth.message_end_time)
    said = losses(rec)
    assert said[1].startswith("chunk 6 (bytes ") and "is cut by the end of the file: lost; it held messages logged at" \
        in said[1]
    assert "file ends 100 bytes into a record" in said[2]
    assert any(line.startswith("lost: the cut chunk named above") for line in said)


def test_channels_defined_in_a_lost_chunk(whole, tmp_path):
    """The 1st chunk defines the curves' channel. Damaged with the summary intact, the summary's channels name the
    later chunks' curves; in a cut file (no summary) those curves are counted as not read, never dropped silently,
    and the other topics' messages are read."""
    chunks = _chunks(whole)
    first = chunks[0]
    raw = _flip(whole.read_bytes(), first.chunk_start_offset + first.chunk_length // 2)
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(raw)
    rec = read_recording(damaged, allow_partial=True)
    assert set(_numbers(rec)) == set(range(1, CURVES + 1)) - _held(whole, first)[0]
    damaged.write_bytes(raw[:chunks[3].chunk_start_offset])
    rec = read_recording(damaged, allow_partial=True)
    unread = sum(_held(whole, index)[1]["/device/curve"] for index in chunks[1:3])
    assert not rec.curves and len(rec.results) == 2 and unread == 2
    assert any(p.startswith(f"{unread} message(s) on channel id(s) 1 not read: the record defining their channel was "
                            "in a damaged part") for p in rec.problems)


def test_a_damaged_end_record_is_named(whole, tmp_path):
    """The metadata record rig.end altered: named by the summary's metadata index; every message read."""
    with open(whole, "rb") as f:
        end = next(m for m in make_reader(f).get_summary().metadata_indexes if m.name == "rig.end")
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(_flip(whole.read_bytes(), end.offset))
    rec = read_recording(damaged, allow_partial=True)
    assert len(rec.curves) == CURVES and not rec.end
    assert [p.what for p in rec.lost] == ["metadata record 'rig.end'"]
    assert any(line.endswith("the run's end record is not in it") for line in losses(rec))


@settings(max_examples=80, derandomize=True, database=None, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_every_message_is_read_or_counted_as_lost(whole, tmp_path, data):
    """1 to 10 bytes flipped anywhere before the summary (which stays intact): each message of the original is read
    (and equal to the original's) or counted in the part that lost it — unless that part says its count is not known
    (a damaged message index) — and each loss is named in one line."""
    raw = bytearray(whole.read_bytes())
    chunks = _chunks(whole)
    data_end = chunks[-1].chunk_start_offset + chunks[-1].chunk_length
    for at, mask in data.draw(st.lists(st.tuples(st.integers(8, data_end), st.integers(1, 255)), min_size=1,
                                       max_size=10)):
        raw[at] ^= mask
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(raw)
    original, rec = read_recording(whole), read_recording(damaged, allow_partial=True)
    by_number = {c.number: (c.t.tobytes(), c.x.tobytes(), c.y.tobytes()) for c in original.curves}
    assert all(by_number[c.number] == (c.t.tobytes(), c.x.tobytes(), c.y.tobytes()) for c in rec.curves)
    assert all("\n" not in line for line in losses(rec)) and len(rec.problems) >= len(rec.lost)
    if any(p.held_data and (p.messages is None or p.uncounted) for p in rec.lost):
        return
    counted = dict(rec.message_counts)
    for part in rec.lost:
        for topic, n in (part.messages or {}).items():
            counted[topic] = counted.get(topic, 0) + n
    assert counted == original.message_counts, rec.problems


def test_a_chunk_a_broken_copy_repeats_is_read_once_and_named(whole, tmp_path, capsys):
    """A copy that wrote a chunk (and its message index) twice: every message of it would count twice (58 curves of
    50, n = 58 in every statistic, "nothing lost"); the repeat is skipped and named, the curves counted once."""
    chunks = _chunks(whole)
    second = chunks[1]
    end = second.chunk_start_offset + second.chunk_length + second.message_index_length
    raw = whole.read_bytes()
    twice = tmp_path / "twice.mcap"
    twice.write_bytes(raw[:end] + raw[second.chunk_start_offset:end] + raw[end:])
    rec = read_recording(twice, allow_partial=True)
    assert _numbers(rec) == list(range(1, CURVES + 1)) and len(rec.results) == CURVES
    assert [e["number"] for e in rec.events if e["kind"] == "curve"] == list(range(1, CURVES + 1))
    assert any("repeats chunk 2 " in p and "counted once" in p for p in rec.problems), rec.problems
    assert main(["-q", "report", str(twice), "-o", str(tmp_path / "r")]) == 2          # not a whole file: said
    assert "repeats chunk 2" in capsys.readouterr().err


def test_a_damaged_summary_is_named_not_read_as_a_whole_file(whole, tmp_path):
    """A byte flipped in the summary section (after the data end): the footer still reads, its summary CRC does not
    match. Every message is still read from the data section, but the file is not whole — other MCAP readers may not
    open it — and it read as complete, with no problem at all."""
    raw = whole.read_bytes()
    footer = raw[-8 - 29:-8]                        # opcode, length, summary start, summary offset start, CRC
    assert footer[0] == 0x02
    start = int.from_bytes(footer[9:17], "little")
    damaged = tmp_path / "summary.mcap"
    damaged.write_bytes(_flip(raw, start + 40))
    with pytest.raises(RecordingError, match=r"the summary section \(bytes \d+-\d+: .*\) is damaged: its CRC does not "
                                             r"match"):
        read_recording(damaged)
    rec = read_recording(damaged, allow_partial=True)
    assert _numbers(rec) == list(range(1, CURVES + 1)) and not rec.complete and rec.data_whole
    for at in range(start + 1, len(raw) - 8 - 29, 97):     # wherever in the summary: damaged, never "cut"
        rec = read_recording(tmp_path / "summary.mcap" if damaged.write_bytes(_flip(raw, at)) else damaged,
                             allow_partial=True)
        assert _numbers(rec) == list(range(1, CURVES + 1))
        assert any("summary section" in p for p in rec.problems), (at, rec.problems)
        assert not any("not closed" in p for p in rec.problems), (at, rec.problems)


def test_without_the_run_metadata_the_end_is_told_from_the_data_not_the_wall_clock(whole, tmp_path):
    """The 'rig' metadata record (wall-clock start) damaged: log times cannot be told as simulation times, and the
    data's end read as 1.7e9 s (the wall clock); it is the latest time the data itself carries."""
    with open(whole, "rb") as f:
        index = next(m for m in make_reader(f).get_summary().metadata_indexes if m.name == "rig")
    raw = bytearray(whole.read_bytes())
    raw[index.offset:index.offset + index.length] = bytes(index.length)
    damaged = tmp_path / "no_rig.mcap"
    damaged.write_bytes(bytes(raw))
    rec = read_recording(damaged, allow_partial=True)
    assert "wall_clock_start" not in rec.metadata.get("rig", {})
    assert rec.last_time == pytest.approx(CURVES - 1 + 0.5)              # the last curve's last sample (s)

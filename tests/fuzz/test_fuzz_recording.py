"""Fuzzing the recording reader (rig/recorder/reader.py): the demo's 1-cycle MCAP recording with bytes
flipped, inserted, deleted or cut off at random offsets, read with ``read_recording(path)`` and
``read_recording(path, allow_partial=True)``.

No crash other than :class:`RecordingError` naming the file and the problem, no hang. Read strictly, a
damaged file either raises or reads exactly as the original (the damage hit only its index, which the
data does not need): nothing damaged is accepted silently. Read with ``allow_partial``, it gives a
Recording (marked truncated, with its problems, when damaged) or a RecordingError, and what it recovers
is part of the original: no curve, result or message that the original does not hold.
"""
from __future__ import annotations

import io
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st
from mcap.data_stream import RecordBuilder
from mcap.records import Channel, DataEnd, Metadata
from mcap.stream_reader import StreamReader

from rig.recorder import Recording, RecordingError, read_recording

FUZZ = dict(derandomize=True, database=None, deadline=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _array(a: Any) -> Any:
    """``a`` comparable bit for bit (NaN equal to NaN)."""
    return None if a is None else (np.asarray(a).dtype.str, np.asarray(a).shape, np.asarray(a).tobytes())


def curve_key(c) -> tuple:
    """A curve record, comparable."""
    return (c.number, c.program, *(_array(a) for a in (c.t, c.x, c.y, c.angle)),
            tuple(sorted((k, _array(v)) for k, v in c.theory.items())), repr(sorted(c.extra.items())))


def content(rec: Recording) -> dict[str, Any]:
    """Everything a recording holds, comparable (arrays bit for bit)."""
    return {"counts": rec.message_counts, "curves": [curve_key(c) for c in rec.curves], "results": rec.results,
            "statistics": rec.statistics, "events": rec.events, "metadata": rec.metadata,
            "programs": rec.programs, "scene": rec.scene_text,
            "series": {t: {k: _array(v) for k, v in cols.items()} for t, cols in rec.series.items()},
            "can": {k: _array(v) if isinstance(v, np.ndarray) else v for k, v in rec.can_frames.items()}}


RAW_SPANS: list[tuple[int, int]] = []      # (start, end) of each top-level record of the demo file
METADATA: list[tuple[int, int, Metadata]] = []      # (start, end, record) of its metadata records


def top_level_records(raw: bytes) -> list[tuple[int, int, list[Any]]]:
    """(start, end, records read there) of the file's top-level records (magic, header, metadata,
    attachments, chunks with the records inside, indexes, summary, footer)."""
    stream = io.BytesIO(raw)
    out = [(0, 8, [])]
    for record in StreamReader(stream).records:
        if stream.tell() != out[-1][1]:
            out.append((out[-1][1], stream.tell(), []))
        out[-1][2].append(record)
    return out + [(len(raw) - 8, len(raw), [])]


@st.composite
def metadata_damage(draw: st.DrawFn) -> list[tuple]:
    """A metadata record rewritten with one value garbled (a wrong or foreign value, well framed)."""
    start, end, record = draw(st.sampled_from(METADATA))
    key = draw(st.sampled_from(sorted(record.metadata)))
    value = draw(st.one_of(st.sampled_from(["", "x", "-1", "nan", "1e999", "true", "false", "null", "0x10"]),
                           st.text(max_size=12)))
    builder = RecordBuilder()
    Metadata(record.name, {**record.metadata, key: value}).write(builder)
    return [("delete", start, end - start), ("insert", start, builder.end())]


@st.composite
def record_damage(draw: st.DrawFn, raw: bytes) -> list[tuple]:
    """1 to 3 edits, each in a record drawn uniformly among the file's records: a byte flipped, the file cut,
    bytes inserted or deleted, or a digit of a number written in the record (metadata, attachments)
    replaced by another character."""
    ops = []
    for _ in range(draw(st.integers(1, 3))):
        start, end = draw(st.sampled_from(RAW_SPANS))
        at = draw(st.integers(start, end - 1))
        kind = draw(st.sampled_from(["flip", "truncate", "insert", "delete", "digit"]))
        if kind == "digit":
            digit = re.compile(rb"\d").search(raw, at, end)
            at = digit.start() if digit else at
            kind, arg = "flip", [raw[at] ^ draw(st.sampled_from(b"x-.e+ 9"))]
        else:
            arg = {"flip": [draw(st.integers(1, 255))], "truncate": [], "delete": [draw(st.integers(1, 64))],
                   "insert": [draw(st.binary(min_size=1, max_size=16))]}[kind]
        ops.append((kind, at, *arg))
    return ops


class Original(tuple):
    """(bytes, Recording) of the demo file, shown by its size in hypothesis' reports."""

    def __repr__(self) -> str:
        return f"<demo recording, {len(self[0])} bytes>"


@pytest.fixture(scope="module")
def original(demo_recording: Path) -> Original:
    """The demo file's bytes and recording; notes its records for the damage strategies."""
    raw = demo_recording.read_bytes()
    spans = top_level_records(raw)
    RAW_SPANS[:] = [(start, end) for start, end, _ in spans]
    METADATA[:] = [(start, end, r[0]) for start, end, r in spans if len(r) == 1 and isinstance(r[0], Metadata)]
    return Original((raw, read_recording(demo_recording)))


@pytest.fixture(scope="module")
def target(tmp_path_factory) -> Path:
    """Where each example writes its damaged file."""
    return tmp_path_factory.mktemp("fuzz-mcap") / "damaged.mcap"


def read(path: Path, allow_partial: bool) -> Recording | RecordingError:
    """The recording, or the RecordingError it raises (any other exception fails the test)."""
    try:
        return read_recording(path, allow_partial=allow_partial)
    except RecordingError as exc:
        return exc


def check_error(exc: RecordingError, path: Path) -> str:
    """A RecordingError names the file and the problem; returns the problem's gist."""
    text = str(exc)
    assert str(path) in text and len(text) > len(str(path)) + 10, text
    assert exc.partial is None or isinstance(exc.partial, Recording)
    return "not an MCAP file" if "not an MCAP file" in text else \
        "truncated or corrupt" if "truncated or corrupt" in text else text.replace(str(path), "FILE")[:50]


def check_part_of(part: Recording, whole: Recording) -> None:
    """What a damaged file gave back is part of the original: fewer or as many messages per topic, and
    each curve recovered equal to the original's of that number."""
    for topic, n in part.message_counts.items():
        assert n <= whole.message_counts.get(topic, 0), (topic, n)
    originals = {c.number: curve_key(c) for c in whole.curves}
    for c in part.curves:
        assert curve_key(c) == originals.get(c.number), f"curve {c.number} recovered differs from the original"


@settings(max_examples=150, **FUZZ)
@given(st.data())
def test_damaged_recordings(fuzz_cases, mutate, original, target, data) -> None:
    """Damage anywhere, in any record or in a metadata value: a RecordingError or the whole content strictly;
    a Recording part of the original (or a RecordingError) with ``allow_partial``; no hang."""
    raw, whole = original
    ops = data.draw(st.one_of(mutate.mutations(len(raw)), record_damage(raw), metadata_damage()))
    target.write_bytes(mutate.apply(raw, ops))
    with fuzz_cases.example("recording reader: damaged demo MCAP", limit=60.0) as case:
        strict = case.within(case.HANG, read, target, False)
        if isinstance(strict, RecordingError):
            case.outcome(f"strict: RecordingError, {check_error(strict, target)}")
        else:
            assert strict.complete and not strict.truncated and not strict.problems
            assert content(strict) == content(whole), f"damaged file {ops} read as whole with different content"
            case.outcome("strict: read whole (only the index was hit), content identical")
        partial = case.within(case.HANG, read, target, True)
        if isinstance(partial, RecordingError):
            case.outcome(f"allow_partial: RecordingError, {check_error(partial, target)}")
            return
        assert partial.truncated == bool(partial.problems) == (not partial.complete), partial.problems
        check_part_of(partial, whole)
        lost = sum(whole.message_counts.values()) - sum(partial.message_counts.values())
        case.outcome("allow_partial: Recording, " + ("truncated, problems named" if partial.truncated else "whole")
                     + (", messages lost" if lost else ""))


def test_a_garbled_metadata_number_is_a_named_problem(original, target) -> None:
    """Found by the fuzzing: a damaged ``wall_clock_start`` escaped as a bare ValueError from int()."""
    raw, whole = original
    start, end, record = next(m for m in METADATA if m[2].name == "rig")
    builder = RecordBuilder()
    Metadata(record.name, {**record.metadata, "wall_clock_start": "17x5"}).write(builder)
    target.write_bytes(raw[:start] + builder.end() + raw[end:])
    with pytest.raises(RecordingError, match="metadata rig.wall_clock_start = '17x5' is not a number"):
        read_recording(target)
    partial = read_recording(target, allow_partial=True)
    assert partial.truncated and any("wall_clock_start" in p for p in partial.problems)
    assert content(partial)["series"] == content(whole)["series"] and len(partial.curves) == len(whole.curves)


def test_damage_in_the_summary_adds_no_message(original, target) -> None:
    """Found by the fuzzing: a flipped opcode in the summary (not CRC-checked) turned a Channel record into a
    Message, read as an extra message; the summary only repeats the data section, so it is not collected."""
    raw, whole = original
    spans = top_level_records(raw)
    data_end = next(end for start, end, records in spans if any(isinstance(r, DataEnd) for r in records))
    summary_channel = next(start for start, end, records in spans
                           if start >= data_end and records and isinstance(records[0], Channel))
    damaged = bytearray(raw)
    damaged[summary_channel] ^= 0x04 ^ 0x05            # opcode Channel (0x04) -> Message (0x05)
    target.write_bytes(bytes(damaged))
    with pytest.raises(RecordingError, match="the summary section .* is damaged"):    # said, not read as whole
        read_recording(target)
    assert content(read_recording(target, allow_partial=True)) == content(whole)

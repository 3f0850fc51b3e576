"""Recorder/reader round trip, robustness to interruption and corruption, raw-mcap readability, log times
anchored to the wall clock, CAN direction and flag columns, undefined values without JSON nulls."""
from __future__ import annotations

import json
import shutil

import can
import numpy as np
import pytest
from mcap.reader import make_reader

from rig.blockbus import BRS, ERROR, ESI, EXTENDED, FD, RX, FrameBlock
from rig.recorder import Recorder, RecordingError, read_recording

SCENE = "[scene]\nname = \"test\"\nseed = 7\n"
START = 1_700_000_000_123_456_789       # wall-clock start of the test recordings, ns since 1970
PROGRAM = {"elements": [{"kind": "window", "name": "W1", "x_min": 0.01, "x_max": 0.02, "y_min": 10.0,
                         "y_max": 50.0, "entry": "left", "exit": "right"}], "limits": {"y_max": [30.0, 50.0]}}


def make_curves(rng, n=3, size=4000):
    out = []
    for k in range(n):
        t = 1.0 + k + np.arange(size) * 1e-4
        out.append(dict(number=k + 1, program=1, t=t, x=rng.uniform(0, 0.04, size), y=rng.normal(40, 3, size),
                        angle=np.linspace(0, 2 * np.pi, size), theory={"t": t[::4], "y": rng.normal(40, 3, size // 4)}))
    return out


def record(path, rng, encoding="json", block_size=700, chunk_size=1 << 20, fail=None):
    t = np.arange(5003) * 1e-4
    truth = {"x": rng.normal(size=t.size), "F": rng.normal(size=t.size)}
    curves = make_curves(rng)
    frames = [(0.1, 0x101, b"\x01\x02\x03", False),
              can.Message(timestamp=0.2, arbitration_id=0x18FF0001, data=bytes(range(64)), is_fd=True,
                          is_extended_id=True)]
    with Recorder(path, scene_text=SCENE, metadata={"seed": 7, "scene": "test"}, programs={1: PROGRAM},
                  block_size=block_size, encoding=encoding, chunk_size=chunk_size, wall_clock_start=START) as rec:
        for a, b in ((0, 10), (10, 1500), (1500, 1501), (1501, t.size)):   # uneven writes, buffered into blocks
            rec.write_truth(t[a:b], {k: v[a:b] for k, v in truth.items()})
        rec.write_live(t[:2000], truth["x"][:2000], truth["F"][:2000])
        rec.write_can_frames(frames)
        for c in curves:
            rec.write_curve(**c, turning_index=1234)
            rec.write_result({"number": c["number"], "program": 1, "ok": c["number"] != 2,
                              "elements": [{"name": "W1", "kind": "window", "ok": c["number"] != 2,
                                            "reason": None if c["number"] != 2 else "entered through top"}],
                              "process_values": {"y_max": float(c["y"].max()), "x_at_y_max": float("nan")}},
                             t=c["t"][-1])
            if fail is not None and c["number"] == 2:
                raise fail
        rec.write_statistics({"count": 3, "ok": 2, "values": {"y_max": {"cp": float("inf")}}})
        rec.write_event(0.3, "flank", flank="rise", angle=np.float64(1.5))
        rec.write_event(0.4, "sequence_gap", frame=0x101, missing=np.int64(2))
    return t, truth, curves


@pytest.mark.parametrize("encoding", ["json", "base64"])
def test_round_trip_every_channel(tmp_path, encoding):
    path = tmp_path / "run.mcap"
    t, truth, curves = record(path, np.random.default_rng(1), encoding)
    rec = read_recording(path)
    assert rec.complete and not rec.truncated and rec.interrupted is None and rec.problems == []
    assert rec.end["complete"] == "true" and rec.last_time == pytest.approx(curves[-1]["t"][-1])
    assert rec.scene_text == SCENE
    assert rec.metadata["rig"]["seed"] == "7" and rec.metadata["rig"]["software_version"]
    assert rec.metadata["rig"]["encoding"] == encoding
    assert rec.programs == {1: PROGRAM}
    np.testing.assert_array_equal(rec.truth["t"], t)
    for k, v in truth.items():
        np.testing.assert_array_equal(rec.truth[k], v)
    assert rec.message_counts["/plant/truth"] == 8          # ceil(5003 / 700)
    np.testing.assert_array_equal(rec.live["y"], truth["F"][:2000])
    assert rec.can_frames["id"].tolist() == [0x101, 0x18FF0001]
    assert rec.can_frames["data"] == [b"\x01\x02\x03", bytes(range(64))]
    assert rec.can_frames["is_fd"].tolist() == [False, True]
    assert rec.can_frames["is_extended"].tolist() == [False, True]
    assert [c.number for c in rec.curves] == [1, 2, 3]
    for got, want in zip(rec.curves, curves):
        for k in ("t", "x", "y", "angle"):
            np.testing.assert_array_equal(getattr(got, k), want[k])
        np.testing.assert_array_equal(got.theory["y"], want["theory"]["y"])
        assert got.extra == {"turning_index": 1234}
    assert [r["ok"] for r in rec.results] == [True, False, True]
    assert rec.results[1]["elements"][0]["reason"] == "entered through top"
    assert rec.results[0]["process_values"]["x_at_y_max"] is None     # NaN is stored as JSON null
    assert rec.statistics == [{"count": 3, "ok": 2, "values": {"y_max": {"cp": None}}}]
    assert rec.events == [{"t": 0.3, "kind": "flank", "flank": "rise", "angle": 1.5},
                          {"t": 0.4, "kind": "sequence_gap", "frame": 0x101, "missing": 2}]


def test_raw_mcap_library_recovers_curves_and_schemas(tmp_path):
    path = tmp_path / "run.mcap"
    _, _, curves = record(path, np.random.default_rng(2))
    got = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for schema in summary.schemas.values():
            assert schema.encoding == "jsonschema"
            assert json.loads(schema.data)["type"] == "object"
        assert all(ch.message_encoding == "json" for ch in summary.channels.values())
        topics = {ch.topic for ch in summary.channels.values()}
        assert topics == {"/plant/truth", "/device/live", "/can/raw", "/device/curve",
                          "/device/result", "/device/statistics", "/events", "/log", "/view/plant", "/view/device"}
        assert reader.get_summary().statistics.message_start_time == START      # simulation time 0
        for _, channel, msg in reader.iter_messages(topics=["/device/curve"]):
            body = json.loads(msg.data)
            assert msg.log_time == START + round(body["t"][-1] * 1e9)   # wall-clock start + its last sample
            got[body["number"]] = body
        truth_times = [(m.log_time, json.loads(m.data)["t"][0]) for _, _, m in reader.iter_messages(["/plant/truth"])]
        sequences: dict[int, list[int]] = {}                    # per channel 1, 2, … (were all 0: gaps invisible)
        for _, channel, m in reader.iter_messages(log_time_order=False):
            sequences.setdefault(channel.id, []).append(m.sequence)
        assert sequences and all(seq == list(range(1, len(seq) + 1)) for seq in sequences.values())
        meta = next(m for m in reader.iter_metadata() if m.name == "rig").metadata
    assert meta["wall_clock_start"] == str(START)
    assert all(ns == START + round(t0 * 1e9) for ns, t0 in truth_times)
    assert sorted(got) == [1, 2, 3]
    for c in curves:
        for k in ("t", "x", "y", "angle"):
            assert got[c["number"]][k] == c[k].tolist()                 # exact: JSON floats round-trip


@pytest.mark.parametrize("exc, reason", [(RuntimeError("solver diverged"), "RuntimeError: solver diverged"),
                                         (KeyboardInterrupt(), "KeyboardInterrupt")])
def test_interrupted_recording_is_valid_and_marked(tmp_path, exc, reason):
    path = tmp_path / "run.mcap"
    with pytest.raises(type(exc)):
        record(path, np.random.default_rng(3), fail=exc)
    rec = read_recording(path)                          # a whole file: no allow_partial needed
    assert not rec.truncated and not rec.complete and rec.interrupted == reason
    assert rec.end == {"complete": "false", "reason": reason, "simulation_time": repr(float(rec.curves[-1].t[-1])),
                       "messages": str(sum(rec.message_counts.values()))}
    from rig.recorder.reader import interruption_text
    said = interruption_text(reason)                    # in plain words, the error's text kept
    assert any(p.startswith(f"{said} at ") and p.endswith(" s of simulation time") for p in rec.problems)
    assert ("Ctrl-C" in said) == (reason == "KeyboardInterrupt") and (reason in said) == (reason != "KeyboardInterrupt")
    assert [c.number for c in rec.curves] == [1, 2] and len(rec.results) == 2
    assert rec.truth["t"].size == 5003                  # buffered tail flushed on the way out
    assert rec.statistics == []
    assert rec.events == [{"t": float(rec.curves[-1].t[-1]), "kind": "interrupted", "reason": reason}]
    with open(path, "rb") as f:
        logs = [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=["/log"])]
    assert [(log["level"], log["name"]) for log in logs] == [(4, "interrupted")]      # foxglove.Log ERROR


def test_truncated_file_names_file_and_recovers_prefix(tmp_path):
    path = tmp_path / "run.mcap"
    _, truth, curves = record(path, np.random.default_rng(4), chunk_size=20_000)
    cut = tmp_path / "cut.mcap"
    data = path.read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.7)])
    with pytest.raises(RecordingError, match="cut.mcap") as info:
        read_recording(cut)
    assert "returns what it holds" in str(info.value) and "/plant/truth" in str(info.value)
    partial = read_recording(cut, allow_partial=True)
    assert partial.truncated and not partial.complete and partial.problems and partial.end == {}
    assert partial.scene_text == SCENE
    n = partial.truth["t"].size                       # the tail block is only written at close
    assert 4000 <= n < 5003
    np.testing.assert_array_equal(partial.truth["F"], truth["F"][:n])
    assert 1 <= len(partial.curves) < 3
    np.testing.assert_array_equal(partial.curves[0].y, curves[0]["y"])
    assert info.value.partial.message_counts == partial.message_counts


def test_corrupt_and_foreign_files(tmp_path):
    path = tmp_path / "run.mcap"
    record(path, np.random.default_rng(5))
    bad = tmp_path / "flipped.mcap"
    data = bytearray(path.read_bytes())
    data[len(data) // 3: len(data) // 3 + 64] = bytes(64)
    bad.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match="flipped.mcap.*(truncated or corrupt)"):
        read_recording(bad)
    other = tmp_path / "notes.mcap"
    other.write_text("hello, not an mcap file")
    with pytest.raises(RecordingError, match="notes.mcap: not an MCAP file"):
        read_recording(other)
    for text in ("hello", "hello\n"):                 # shorter than the magic: not taken for a cut recording
        other.write_text(text)
        with pytest.raises(RecordingError, match="notes.mcap: not an MCAP file"):
            read_recording(other, allow_partial=True)
    other.write_bytes(b"")
    with pytest.raises(RecordingError, match="notes.mcap: empty file"):
        read_recording(other, allow_partial=True)
    other.write_bytes(path.read_bytes()[:5])           # a recording cut inside its magic: partial, holds nothing
    assert read_recording(other, allow_partial=True).truncated
    with pytest.raises(RecordingError, match="missing.mcap"):
        read_recording(tmp_path / "missing.mcap")
    shutil.copy(path, tmp_path / "copy.mcap")
    assert read_recording(tmp_path / "copy.mcap").complete


def test_bad_input_is_named(tmp_path):
    with pytest.raises(ValueError, match="encoding"):
        Recorder(tmp_path / "a.mcap", encoding="xml")
    with Recorder(tmp_path / "b.mcap", block_size=10) as rec:
        with pytest.raises(ValueError, match="/plant/truth.*-1"):
            rec.write_truth(np.array([-1.0, 0.0]), {"x": np.zeros(2)})
        rec.write_truth(np.array([1.0, 2.0]), {"x": np.zeros(2)})
        with pytest.raises(ValueError, match="non-decreasing"):
            rec.write_truth(np.array([1.5]), {"x": np.zeros(1)})
        with pytest.raises(ValueError, match="differ"):
            rec.write_truth(np.array([3.0]), {"y": np.zeros(1)})
        with pytest.raises(ValueError, match="'x' has shape"):
            rec.write_truth(np.array([3.0, 4.0]), {"x": np.zeros(3)})
        with pytest.raises(ValueError, match="curve 5"):
            rec.write_curve(5, 1, np.arange(3.0), np.zeros(2), np.zeros(3))
        with pytest.raises(ValueError, match="'ok'"):
            rec.write_result({"number": 1})
        with pytest.raises(ValueError, match="before the previous frame"):
            rec.write_can_frames([(2.0, 1, b"", False), (1.0, 1, b"", False)])
    with pytest.raises(RuntimeError, match="after close"):
        rec.write_event(1.0, "late")
    assert read_recording(tmp_path / "b.mcap").truth["x"].tolist() == [0.0, 0.0]


def test_frame_block_direction_channel_and_flags_become_columns(tmp_path):
    flags = np.array([RX, FD | BRS | RX, FD | ESI | RX, ERROR | RX, EXTENDED, 0], np.uint8)
    data = np.zeros((6, 64), np.uint8)
    data[1, :12] = np.arange(12)
    block = FrameBlock(np.array([0.1, 0.2, 0.2, 0.3, 0.4, 0.4]), np.array([0x100, 0x300, 0x301, 0, 0x18FF0001, 0x50],
                                                                         np.uint32),
                       np.array([0, 12, 8, 0, 1, 8], np.int16), data, flags)
    with Recorder(tmp_path / "can.mcap", block_size=4) as rec:
        rec.write_can_frames(block.take(slice(0, 4)), channel="can0")
        rec.write_can_frames(block.take(slice(4, 6)), channel="aux")
    cf = read_recording(tmp_path / "can.mcap").can_frames
    assert cf["dir"] == ["rx", "rx", "rx", "rx", "tx", "tx"]
    assert cf["channel"] == ["can0"] * 4 + ["aux"] * 2
    assert cf["is_fd"].tolist() == [False, True, True, False, False, False]
    assert cf["brs"].tolist() == [False, True, False, False, False, False]
    assert cf["esi"].tolist() == [False, False, True, False, False, False]
    assert cf["error"].tolist() == [False, False, False, True, False, False]
    assert cf["is_extended"].tolist() == [False, False, False, False, True, False]
    assert cf["data"][1] == bytes(range(12)) and cf["data"][3] == b""
    assert cf["dir"][0] is cf["dir"][3] and cf["channel"][0] is cf["channel"][3]   # one str per word, not per frame
    counted = read_recording(tmp_path / "can.mcap", can_frames=False)              # what the analyses read
    assert counted.can_frames == {} and counted.can_counts == {"frames": 6, "sent": 2}
    whole = read_recording(tmp_path / "can.mcap")
    assert whole.can_counts == counted.can_counts and whole.summary() == counted.summary()
    assert counted.last_time == whole.last_time == 0.4 and "6 frames: 4 received, 2 sent" in counted.summary()


def test_frames_no_trace_format_can_hold_are_refused_when_written_not_when_exported(tmp_path):
    """An id beyond its format (an error frame's SocketCAN flag bits in it) and a remote (RTR) frame were written
    without a word; the first made every `rig export-can` fail, the second came back as a 0-byte data frame."""
    import can
    with Recorder(tmp_path / "odd.mcap") as rec:
        rec.write_can_frames([(0.1, 0x100, b"\x01", False)])
        for bad, problem in ((can.Message(timestamp=0.2, arbitration_id=0x20000080, is_extended_id=True,
                                          is_error_frame=True, data=bytes(8)), "id out of range"),
                             (can.Message(timestamp=0.2, arbitration_id=0x800, is_extended_id=False, check=False),
                              "id out of range"),
                             (can.Message(timestamp=0.2, arbitration_id=0x555, is_extended_id=False,
                                          is_remote_frame=True, dlc=4), "a remote \\(RTR\\) frame")):
            with pytest.raises(ValueError, match=rf"frame 1 of 2 at t = 0.2 s, id 0x{bad.arbitration_id:X}: {problem}"):
                rec.write_can_frames([can.Message(timestamp=0.15, arbitration_id=0x101, data=b""), bad])
        rec.write_can_frames([(0.3, 0x1FFFFFFF, b"", False)])
    cf = read_recording(tmp_path / "odd.mcap").can_frames
    assert cf["id"].tolist() == [0x100, 0x1FFFFFFF] and cf["t"].tolist() == [0.1, 0.3]     # nothing of the refused


def test_undefined_values_round_trip_without_json_nulls(tmp_path):
    path = tmp_path / "nan.mcap"
    t = np.arange(5) * 0.1
    x = np.array([1.0, np.nan, np.inf, 2.0, -np.inf])
    with Recorder(path, block_size=3) as rec:
        rec.write_truth(t, {"x": x, "a/b~c": t})          # a signal name that needs JSON Pointer escapes
        rec.write_curve(1, 1, t, x, t, theory={"y": x})
        rec.write_result({"number": 1, "ok": True, "elements": [{"name": "W", "reason": None}],
                          "process_values": {"y_max": float("nan"), "x/max": 1.5}})
    rec = read_recording(path)
    np.testing.assert_array_equal(rec.truth["x"], [1.0, np.nan, np.nan, 2.0, np.nan])   # inf: undefined as before
    np.testing.assert_array_equal(rec.truth["a/b~c"], t)
    np.testing.assert_array_equal(rec.curves[0].x, rec.truth["x"])
    np.testing.assert_array_equal(rec.curves[0].theory["y"], rec.truth["x"])
    assert rec.results == [{"number": 1, "ok": True, "elements": [{"name": "W", "reason": None}],
                            "process_values": {"x/max": 1.5, "y_max": None}}]
    with open(path, "rb") as f:
        data = {ch.topic: m.data for _, ch, m in make_reader(f).iter_messages()}      # the last of each topic
    assert not [topic for topic, d in data.items() if b"null" in d.replace(b'"nulls"', b"")]
    raw = {topic: json.loads(d) for topic, d in data.items()}
    assert raw["/device/result"]["nulls"] == ["/elements/0/reason", "/process_values/y_max"]
    assert raw["/device/result"]["process_values"] == {"x/max": 1.5}          # left out of its object
    assert raw["/plant/truth"] == {"t": t[3:].tolist(), "x": [2.0, 0.0], "a/b~c": t[3:].tolist(), "nulls": ["/x/1"]}
    assert raw["/view/plant"]["nulls"] == ["/x"] and "x" not in raw["/view/plant"]     # t = 0.4: x = -inf


def test_view_decimation_is_the_same_for_any_cut_of_the_stream():
    from rig.recorder.view import Decimator
    t = np.arange(20_000) * 1e-4                          # 2 s at 10 kHz
    whole = Decimator(100.0).pick(t)
    np.testing.assert_array_equal(whole, np.arange(0, 20_000, 100))   # the sample at each period's start
    pieces, dec = [], Decimator(100.0)
    for a, b in ((0, 7), (7, 7), (7, 5003), (5003, 20_000)):
        pieces.append(dec.pick(t[a:b]) + a)
    np.testing.assert_array_equal(np.concatenate(pieces), whole)
    with pytest.raises(ValueError, match="view rate"):
        Decimator(0.0)


@pytest.mark.parametrize("t", [np.arange(2000) / 1000, np.arange(2000) * 1e-3, np.linspace(0.0, 2.0, 2001)[:-1],
                               1e4 + np.arange(2000) * 1e-3], ids=["i/1000", "i*1e-3", "linspace", "t0=1e4"])
def test_a_sample_on_a_period_start_starts_it_whatever_the_rounding(t):
    """At 1 kHz every tenth sample lies on a 100 Hz period's start; t * rate rounds some of them just below a
    whole number (0.29 * 100 = 28.999999999999996): they still start their period, so the view is every tenth
    sample, 10 ms apart (it had 9 and 11 ms gaps)."""
    from rig.recorder.view import Decimator
    np.testing.assert_array_equal(Decimator(100.0).pick(t), np.arange(0, 2000, 10))


def test_views_can_be_turned_off_and_bad_settings_are_named(tmp_path):
    with Recorder(tmp_path / "noview.mcap", view_rate=None) as rec:
        rec.write_truth(np.arange(3.0), {"x": np.zeros(3)})
    assert set(read_recording(tmp_path / "noview.mcap").message_counts) == {"/plant/truth"}
    with pytest.raises(ValueError, match="wall_clock_start"):
        Recorder(tmp_path / "w.mcap", wall_clock_start=-5)
    with Recorder(tmp_path / "r.mcap") as rec:
        with pytest.raises(ValueError, match="'nulls'"):
            rec.write_truth(np.arange(2.0), {"nulls": np.zeros(2)})
        with pytest.raises(ValueError, match="reserved"):
            rec.write_result({"ok": True, "nulls": []})


def test_rows_are_written_as_dumps_message_writes_them():
    """The view topics' fast path gives the same bytes as the general encoder, undefined values included."""
    from rig.recorder.encoding import dumps_message, dumps_rows, loads_message
    rng = np.random.default_rng(5)
    cols = {"t": rng.uniform(0, 10, 50).tolist(), "a": rng.normal(size=50).tolist(), "b": rng.normal(size=50).tolist()}
    cols["a"][3], cols["b"][3], cols["b"][7], cols["a"][9] = float("nan"), float("inf"), -float("inf"), 1e300
    rows = dumps_rows(cols)
    assert len(rows) == 50
    for i, data in enumerate(rows):
        assert data == dumps_message({k: np.float64(v[i]) for k, v in cols.items()})
    assert loads_message(rows[3]) == {"t": cols["t"][3], "a": None, "b": None}
    with pytest.raises(ValueError, match="reserved"):
        dumps_rows({"nulls": [1.0]})


def test_a_cut_says_whether_it_ends_inside_a_record_or_after_one(tmp_path):
    """A killed writer usually leaves whole records without the data end and summary: the reader says so; a cut
    inside a record says how many bytes of it are there."""
    from mcap.records import DataEnd
    from mcap.stream_reader import StreamReader
    path = tmp_path / "run.mcap"
    record(path, np.random.default_rng(4), chunk_size=20_000)
    with open(path, "rb") as f:
        ends = []
        for r in StreamReader(f).records:
            if isinstance(r, DataEnd):
                break
            ends.append(f.tell())
    data = path.read_bytes()
    boundary = ends[len(ends) // 2]
    for size, said in ((boundary, "file ends after a whole record, without the data end, summary and footer"),
                       (boundary + 7, "file ends 7 bytes into a record")):
        cut = tmp_path / f"cut{size}.mcap"
        cut.write_bytes(data[:size])
        partial = read_recording(cut, allow_partial=True)
        assert partial.truncated and partial.problems[0].startswith(said), partial.problems


def test_what_a_damaged_or_cut_file_lost_is_what_was_not_read(tmp_path):
    """A cut in the summary or of the closing magic loses nothing of the run; an altered metadata record fails only
    the data section's CRC (every chunk passes its own): the reader says so instead of claiming lost messages, and
    the report's loss lines follow what was read."""
    from rig.recorder.completeness import losses
    path = tmp_path / "run.mcap"
    record(path, np.random.default_rng(4), chunk_size=20_000)
    whole = read_recording(path)
    data = path.read_bytes()
    meta = data.index(b"wall_clock_start")             # a metadata record near the front, outside every chunk
    altered = bytearray(data)
    altered[meta] ^= 0x20
    for name, content, said in (
            ("no_magic", data[:-8], "file ends after its footer, without MCAP's closing magic: every record was read"),
            ("in_summary", data[:-100], "file ends in its summary ("),
            ("altered", bytes(altered), "the data section's CRC does not match the one written at its end")):
        cut = tmp_path / f"{name}.mcap"
        cut.write_bytes(content)
        partial = read_recording(cut, allow_partial=True)
        assert partial.truncated and partial.data_whole and partial.problems[0].startswith(said), partial.problems
        assert len(partial.curves) == len(whole.curves) and partial.message_counts == whole.message_counts
        lines = losses(partial)
        assert "nothing of the run is lost: every message up to the file's data end was read" in lines, lines
        assert not any(line.startswith("lost:") for line in lines)
    cut = tmp_path / "half.mcap"
    cut.write_bytes(data[: len(data) // 2])
    partial = read_recording(cut, allow_partial=True)
    assert not partial.data_whole and not partial.damaged          # cut short, not altered
    assert any(line.startswith("lost: the cut chunk named above") for line in losses(partial))
    from mcap.reader import make_reader
    with open(path, "rb") as f:                                      # the chunk the cut runs into, by the summary
        [into] = [c for c in make_reader(f).get_summary().chunk_indexes
                  if c.chunk_start_offset < len(data) // 2 < c.chunk_start_offset + c.chunk_length]
    [part] = partial.lost
    assert part.cut and part.start == into.chunk_start_offset
    assert part.log_times == (into.message_start_time, into.message_end_time)


def test_the_end_record_says_how_far_the_data_reaches(tmp_path):
    """A block is logged at its first sample; the end record's simulation time is its last sample's (as far as the
    run got), not the log time of the last message."""
    path = tmp_path / "r.mcap"
    with Recorder(path) as rec:
        rec.write_block("/plant/truth", np.linspace(0.0, 2.5, 26), {"s": np.zeros(26)})
        rec.write_event(1.0, "flank_switch", phi=1.0)
    assert float(read_recording(path).end["simulation_time"]) == 2.5


def test_integer_and_boolean_arrays_are_written_as_their_lists():
    """Integer and boolean arrays go to orjson as arrays (no Python list per value): the same JSON as their lists,
    0-d arrays as scalars, strided and 2-D ones too."""
    import orjson
    from rig.recorder.encoding import dumps_message
    for value in (np.array(5), np.array(True), np.arange(10)[::3], np.array([[1, -2], [3, 4]], np.int16),
                  np.array([True, False]), np.array([0, 255], np.uint8), np.zeros(0, np.int64),
                  np.array([1, -70000], dtype=">i4")):
        assert dumps_message({"v": value}) == orjson.dumps({"v": value.tolist()})


def test_summary_counts_can_messages_apart_from_the_frames_they_hold(tmp_path):
    """A /can/raw message is a batch of frames: '135' beside the console's '134104 CAN frames received' read as
    frames; the summary says messages and gives the frames, received and sent as the console counts them."""
    from rig.recorder.reader import Recording
    rec = Recording(tmp_path / "r.mcap", message_counts={"/can/raw": 135, "/device/curve": 50},
                    can_counts={"frames": 5, "sent": 1})
    assert rec.summary().startswith("/can/raw: 135 messages (5 frames: 4 received, 1 sent), /device/curve: 50; ")
    rec.can_counts["sent"] = 0
    assert "/can/raw: 135 messages (5 frames received)" in rec.summary()
    assert Recording(tmp_path / "r.mcap", message_counts={"/can/raw": 1}).summary().startswith("/can/raw: 1 message;")


def test_an_event_found_after_a_later_one_keeps_its_time_and_the_channel_its_order(tmp_path):
    """A result cut by Ctrl-C (bus time 14.699945 s) was written before the last drop report (device time
    14.6988 s): /events and /log went back in log time, which MCAP readers flag. The later-found event is logged at
    the earlier-found one's log time; its message keeps its exact t."""
    path = tmp_path / "ev.mcap"
    with Recorder(path) as rec:
        rec.write_event(14.699945, "result", count=7)
        rec.write_event(14.6988, "live_dropped", count=3)
        rec.write_event(15.0, "later")
    with path.open("rb") as f:
        reader = make_reader(f)
        by_topic: dict[str, list[int]] = {}
        for _, channel, message in reader.iter_messages(log_time_order=False):
            by_topic.setdefault(channel.topic, []).append(message.log_time)
    for topic in ("/events", "/log"):
        assert by_topic[topic] == sorted(by_topic[topic]), topic
    assert by_topic["/events"][0] == by_topic["/events"][1] < by_topic["/events"][2]
    assert [(e["t"], e["kind"]) for e in read_recording(path).events] == \
        [(14.699945, "result"), (14.6988, "live_dropped"), (15.0, "later")]

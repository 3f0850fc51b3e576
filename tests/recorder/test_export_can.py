"""`rig export-can`: every trace format reads back through python-can with the recorded frames; MF4 decodes
with asammdf's bus logging and the DBC like cantools does; what each format keeps; errors."""
from __future__ import annotations

import io
from datetime import datetime, timezone
from pathlib import Path

import can
import cantools
import numpy as np
import orjson
import pytest
from asammdf import MDF
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import Writer

from rig.cli import main
from rig.recorder import Recorder, RecordingError, read_recording
from rig.recorder.export_can import FORMATS, export_can
from rig.runner import run_scene

ROOT = Path(__file__).resolve().parents[2]
DBC = ROOT / "data" / "can" / "rig.dbc"
#: time resolution of each format as read back (s): text formats print µs, BLF keeps ns, MF4 float64 s
RESOLUTION = {".asc": 0.5e-6, ".log": 0.5e-6, ".trc": 0.5e-6, ".blf": 1e-9, ".mf4": 0.0}
#: formats whose reader adds the header's start date (the recording's wall-clock start) to the frame times
ABSOLUTE = {".blf", ".trc", ".mf4"}
FLOAT_AT_EPOCH = 2.5e-7     # a float of s since 1970 holds ~0.24 µs
#: resolution of the header's start date (s): ASC prints ms, BLF's SYSTEMTIME holds ms, TRC days as a float, MF4 ns
HEADER = {".asc": 1e-3, ".blf": 1e-3, ".trc": 2e-6, ".mf4": 1e-6, ".log": 0.0}


def time_error(msgs: list[can.Message], t: np.ndarray, start: float, ext: str) -> float:
    """Largest |read-back time - (header start) - simulation time| (s)."""
    return float(np.abs(np.array([m.timestamp for m in msgs]) - (start if ext in ABSOLUTE else 0.0) - t).max())


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("export") / "run.mcap"
    run_scene(ROOT / "data" / "scenes" / "pin_insertion.toml", out, cycles=2, progress=False)
    return out


def read_back(path: Path) -> list[can.Message]:
    with can.LogReader(path) as reader:
        return list(reader)


@pytest.mark.parametrize("ext", list(FORMATS))
def test_every_format_reads_back_the_recorded_frames(recording, tmp_path, ext):
    cf = read_recording(recording).can_frames
    out = tmp_path / f"bus{ext}"
    summary = export_can(recording, out)
    msgs = read_back(out)
    n = len(cf["t"])
    assert summary.frames == len(msgs) == n > 1000
    direction = np.array(cf["dir"]) if "dir" in cf else np.full(n, "rx")
    assert [m.is_rx for m in msgs] == list(direction == "rx")
    if "dir" in cf:                                     # the host's own frames are on the bus too
        assert (direction == "tx").sum() > 0
    assert [m.arbitration_id for m in msgs] == cf["id"].tolist()
    assert [bytes(m.data) for m in msgs] == cf["data"]
    assert [m.dlc for m in msgs] == [len(d) for d in cf["data"]]
    assert [m.is_extended_id for m in msgs] == cf["is_extended"].tolist()
    assert [m.is_fd for m in msgs] == cf["is_fd"].tolist()
    for flag, key in (("bitrate_switch", "brs"), ("error_state_indicator", "esi"), ("is_error_frame", "error")):
        assert [getattr(m, flag) for m in msgs] == (list(cf[key]) if key in cf else [False] * n)
    err = time_error(msgs, cf["t"], summary.start, ext)
    assert err <= RESOLUTION[ext] + (FLOAT_AT_EPOCH + HEADER[ext] if summary.start and ext in ABSOLUTE else 1e-12), err


def test_mf4_decodes_with_asammdf_bus_logging_and_the_dbc(recording, tmp_path):
    out = tmp_path / "bus.mf4"
    summary = export_can(recording, out)
    cf = read_recording(recording).can_frames
    db = cantools.database.load_file(DBC)
    with MDF(out) as mdf:
        assert abs((mdf.header.start_time - datetime.fromtimestamp(summary.start, timezone.utc)).total_seconds()) <= 1e-6
        with mdf.extract_bus_logging({"CAN": [(DBC, 0)]}) as decoded:
            checked = 0
            for message, signals in (("LiveXY", ("X", "Y", "Tick")), ("Heartbeat", ("DeviceTime", "State")),
                                     ("Encoder1", ("Count", "EdgeTime")), ("StatusCounters", ("CurveCount",))):
                frame_id = db.get_message_by_name(message).frame_id
                rows = np.flatnonzero(cf["id"] == frame_id)
                assert rows.size, f"no {message} frames in the recording"
                expected = [db.decode_message(frame_id, cf["data"][i]) for i in rows]
                for name in signals:
                    sig = decoded.get(f"CAN1.{message}.{name}")
                    np.testing.assert_array_equal(sig.timestamps, cf["t"][rows])
                    if sig.samples.dtype.kind == "S":           # a value table: asammdf gives its text
                        assert [v.decode() for v in sig.samples] == [str(e[name]) for e in expected]
                    else:
                        np.testing.assert_allclose(sig.samples, [e[name] for e in expected], rtol=0, atol=1e-9)
                    checked += 1
    assert checked == 8


def _write_mcap(path: Path, blocks: list[dict], metadata: dict[str, str] | None = None) -> Path:
    """A recording holding only ``/can/raw`` blocks (and the ``rig`` metadata), as written by hand."""
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        w.add_metadata("rig", metadata or {})
        schema = w.register_schema("rig.CanFrames", "jsonschema", b"{}")
        channel = w.register_channel("/can/raw", "json", schema)
        for block in blocks:
            ns = int(block["t"][0] * 1e9) if block["t"] else 0
            w.add_message(channel, ns, orjson.dumps(block), ns)
        w.finish()
    return path


#  t, id, extended, fd, brs, esi, error, dir, channel, payload
FRAMES = [(0.0010004, 0x050, False, False, False, False, False, "tx", "rig", "0a0b0c0d0e0f1011"),
          (0.0015, 0x051, False, False, False, False, False, "rx", "rig", "0001020304050607"),
          (0.002, 0x1ABCDE12, True, False, False, False, False, "rx", "aux", "aabbcc"),
          (0.003, 0x201, False, True, True, False, False, "rx", "rig", bytes(range(12)).hex()),
          (0.004, 0x1FFFFFFF, True, True, False, True, False, "tx", "aux", bytes(range(64)).hex()),
          (0.005, 0x000, False, False, False, False, True, "rx", "rig", ""),
          (0.006123457, 0x7FF, False, False, False, False, False, "rx", "rig", "")]
WALL_START = 1_750_000_000_123_456_789        # ns since 1970; traces start at 1 750 000 000 s


def _blocks(frames: list[tuple]) -> list[dict]:
    cols = list(zip(*frames))
    keys = ("t", "id", "is_extended", "is_fd", "brs", "esi", "error", "dir", "channel", "data")
    full = {k: list(v) for k, v in zip(keys, cols)}
    return [{k: v[:3] for k, v in full.items()}, {k: v[3:] for k, v in full.items()}]


#: per format: channel as read back (bus number 1.. / 0-based / recorded name), error-frame fields kept
KEEPS = {".asc": ("0-based", ("channel",)), ".blf": ("0-based", ("channel", "id", "data")),
         ".log": ("name", ()), ".mf4": ("1-based", ("channel", "id", "data", "is_rx"))}


@pytest.mark.parametrize("ext", list(KEEPS))
def test_direction_channels_fd_flags_and_error_frames_are_kept(tmp_path, ext):
    rec = _write_mcap(tmp_path / "flags.mcap", _blocks(FRAMES), {"wall_clock_start": str(WALL_START)})
    out = tmp_path / f"flags{ext}"
    summary = export_can(rec, out)
    assert (summary.frames, summary.error_frames, summary.channels, summary.start) == (7, 1, ["rig", "aux"],
                                                                                         WALL_START / 1e9)
    msgs = read_back(out)
    assert len(msgs) == len(FRAMES)
    assert time_error(msgs, np.array([f[0] for f in FRAMES]), summary.start, ext) <= (
        RESOLUTION[ext] + FLOAT_AT_EPOCH + (HEADER[ext] if ext in ABSOLUTE else 0.0))
    channel_kind, error_fields = KEEPS[ext]
    for m, (t, fid, ext_id, fd, brs, esi, error, direction, name, data) in zip(msgs, FRAMES):
        assert m.is_error_frame == error
        channel = {"0-based": ["rig", "aux"].index(name), "1-based": ["rig", "aux"].index(name) + 1,
                   "name": name}[channel_kind]
        kept = {"channel": (m.channel, channel), "id": (m.arbitration_id, fid), "data": (m.data.hex(), data),
                "is_rx": (m.is_rx, direction == "rx")}
        if error:
            assert {k: kept[k][0] for k in error_fields} == {k: kept[k][1] for k in error_fields}
            continue
        assert {k: v[0] for k, v in kept.items()} == {k: v[1] for k, v in kept.items()}
        assert (m.is_extended_id, m.is_fd, m.bitrate_switch, m.error_state_indicator, m.dlc) == (
            ext_id, fd, brs, esi, len(data) // 2)


def test_headers_carry_the_wall_clock_start(tmp_path):
    rec = _write_mcap(tmp_path / "flags.mcap", _blocks(FRAMES), {"wall_clock_start": str(WALL_START)})
    start = WALL_START / 1e9                  # 1 750 000 000.123 456 789 s: the fraction is kept, not cut
    for ext in (".asc", ".blf", ".mf4"):
        export_can(rec, tmp_path / f"h{ext}")
    with can.ASCReader(tmp_path / "h.asc", relative_timestamp=False) as asc:
        assert next(iter(asc)).timestamp == pytest.approx(start + FRAMES[0][0], abs=HEADER[".asc"])
    head = (tmp_path / "h.asc").read_text().splitlines()
    date = head[0].removeprefix("date ")
    assert date.endswith(".123 2025") and f"Begin Triggerblock {date}" in head     # both: the start, ms padded
    with can.BLFReader(tmp_path / "h.blf") as blf:
        assert blf.start_timestamp == pytest.approx(start, abs=HEADER[".blf"])
    with MDF(tmp_path / "h.mf4") as mdf:
        assert abs((mdf.header.start_time - datetime.fromtimestamp(start, timezone.utc)).total_seconds()) <= 1e-6
    classic = [f for f in FRAMES if not f[3] and not f[6]]
    export_can(_write_mcap(tmp_path / "classic.mcap", _blocks(classic), {"wall_clock_start": str(WALL_START)}),
               tmp_path / "h.trc")
    msgs = read_back(tmp_path / "h.trc")
    assert [(m.arbitration_id, m.is_rx, m.channel, m.data.hex()) for m in msgs] == [
        (f[1], f[7] == "rx", ["rig", "aux"].index(f[8]) + 1, f[9]) for f in classic]
    assert [m.timestamp - start for m in msgs] == pytest.approx([f[0] for f in classic], abs=HEADER[".trc"])
    named = [line for line in (tmp_path / "h.trc").read_text().splitlines()[:8] if line.startswith(";   /")]
    assert named == [f";   {(tmp_path / 'h.trc').resolve()}"]          # the trace's own name, not its part file's


def test_trc_refuses_fd_and_error_frames_and_leaves_no_file(tmp_path):
    rec = _write_mcap(tmp_path / "fd.mcap", _blocks(FRAMES))
    out = tmp_path / "fd.trc"
    with pytest.raises(ValueError, match=r"TRC writer cannot hold CAN FD or error frames.*an FD frame at t = 0.003000 s \(id 0x201\)"):
        export_can(rec, out)
    assert not out.exists()


def test_a_log_gets_the_default_interface_for_an_empty_channel_name_and_refuses_one_with_spaces(tmp_path):
    """candump's .log names the interface in one word: an empty name was written as nothing ("(0.000000)  050#…"),
    a name with a space as two words, and can.LogReader could not read either file back."""
    empty = [f[:8] + ("",) + f[9:] for f in FRAMES]
    export_can(_write_mcap(tmp_path / "empty.mcap", _blocks(empty)), tmp_path / "empty.log")
    msgs = read_back(tmp_path / "empty.log")
    assert len(msgs) == len(FRAMES) and {m.channel for m in msgs if not m.is_error_frame} == {"vcan0"}
    spaced = [f[:8] + ("my bus",) + f[9:] for f in FRAMES]
    with pytest.raises(ValueError, match=r"channel 'my bus' has white space.*export to \.asc"):
        export_can(_write_mcap(tmp_path / "spaced.mcap", _blocks(spaced)), tmp_path / "spaced.log")
    assert not (tmp_path / "spaced.log").exists()
    assert len(read_back(export_can(tmp_path / "spaced.mcap", tmp_path / "spaced.asc") and tmp_path / "spaced.asc")) \
        == len(FRAMES)


def test_unknown_extension_is_an_error(recording, tmp_path):
    for name in ("bus.csv", "bus"):
        with pytest.raises(ValueError, match="unknown CAN trace format"):
            export_can(recording, tmp_path / name)
    assert main(["export-can", str(recording), "-o", str(tmp_path / "bus.txt")]) == 2


def test_recording_without_can_frames_is_an_error(tmp_path):
    path = tmp_path / "nocan.mcap"
    with Recorder(path) as rec:
        rec.write_event(0.1, "start")
    with pytest.raises(RecordingError, match=r"no /can/raw frames"):
        export_can(path, tmp_path / "bus.asc")
    assert not (tmp_path / "bus.asc").exists()


@pytest.mark.parametrize("change, problem", [
    (lambda b: b.pop("data"), "needs columns t, id, is_fd, is_extended, data"),
    (lambda b: b["id"].append(1), "columns id do not have the 3 rows"),
    (lambda b: b["id"].__setitem__(1, 0x800), "frame 1: id out of range"),
    (lambda b: b["data"].__setitem__(0, "00" * 9), "frame 0: data length not a CAN"),
    (lambda b: b["dir"].__setitem__(2, "up"), "frame 2: direction other than"),
    (lambda b: b["t"].__setitem__(1, 0.0001), "frame 1: time not finite, negative or before the previous")])
def test_malformed_can_blocks_are_errors_naming_the_problem(tmp_path, change, problem):
    blocks = _blocks(FRAMES)
    change(blocks[0])
    rec = _write_mcap(tmp_path / "bad.mcap", blocks)
    with pytest.raises(RecordingError, match=r"/can/raw message 0.*" + problem):
        export_can(rec, tmp_path / "bad.blf")
    assert not (tmp_path / "bad.blf").exists()


def test_cli_export_can(recording, tmp_path, capsys):
    out = tmp_path / "bus.blf"
    assert main(["export-can", str(recording), "-o", str(out)]) == 0
    n = len(read_recording(recording).can_frames["t"])
    assert f"exported {n} CAN frames" in capsys.readouterr().out
    assert len(read_back(out)) == n
    fresh = tmp_path / "new" / "bus.asc"          # a folder it makes is said, as rig run says it
    assert main(["export-can", str(recording), "-o", str(fresh)]) == 0
    assert f"-> {fresh} (created the folder {fresh.parent})" in capsys.readouterr().out


def test_truncated_recording_is_an_error(recording, tmp_path):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(recording.read_bytes()[:200_000])
    with pytest.raises(RecordingError, match=r"cut.mcap: truncated recording .*a killed run or a cut copy\); "
                                             r"exporting every CAN frame \(`rig export-can --partial` exports those "
                                             r"before the cut\) needs a whole file .*rig report --partial"):
        export_can(cut, tmp_path / "bus.log")
    assert not (tmp_path / "bus.log").exists()


def test_partial_exports_the_frames_before_the_cut_and_says_where_it_ends(tmp_path, capsys):
    """A killed run's file (8 cycles, two MCAP chunks, cut inside the second): `--partial` writes the frames it can read — each equal to the whole file's
    frame at its place, read back by python-can — with the run's wall-clock start (from the first block's log time: the
    metadata record is at the end), and a warning naming the last time and why."""
    recording, cut = tmp_path / "run.mcap", tmp_path / "cut.mcap"
    run_scene(ROOT / "data" / "scenes" / "pin_insertion.toml", recording, cycles=8, progress=False)
    with recording.open("rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    assert len(chunks) >= 2
    cut.write_bytes(recording.read_bytes()[:chunks[1].chunk_start_offset + chunks[1].chunk_length // 2])
    whole, part = tmp_path / "whole.log", tmp_path / "part.log"
    export_can(recording, whole)
    e = export_can(cut, part, partial=True)
    assert e.lost.startswith("chunk 2 (bytes ") and "is cut by the end of the file: lost" in e.lost
    assert "recording was not closed" in e.lost and 0 < e.frames and e.start == export_can(recording, whole).start
    a, b = read_back(whole), read_back(part)
    assert 0 < len(b) < len(a) and all(x.equals(y) for x, y in zip(a, b))
    assert main(["export-can", "--partial", str(cut), "-o", str(tmp_path / "cli.asc")]) == 0
    err = capsys.readouterr().err
    assert "the recording is cut or damaged, the trace holds the frames that read" in err and e.lost in err
    assert f"its last frame is at {e.t_last:.6f} s of simulation time" in err and e.t_last == pytest.approx(
        b[-1].timestamp, abs=1e-6)                               # where what is lost begins (.log: simulation time)
    assert e.tail_lost and "what the run sent after it (a killed run's chunk not yet written) is not in the file" in err
    # cut just after the last chunk (and its message indexes): every message is there, the run's end record counts
    # them, and the file lacks only its summary: not "lost: the messages after the last whole chunk"
    last = max(chunks, key=lambda c: c.chunk_start_offset)
    edge = tmp_path / "edge.mcap"
    edge.write_bytes(recording.read_bytes()[:last.chunk_start_offset + last.chunk_length + last.message_index_length])
    e = export_can(edge, tmp_path / "edge.log", partial=True)
    assert not e.tail_lost and e.all_read and len(read_back(tmp_path / "edge.log")) == len(a)
    assert main(["export-can", "--partial", str(edge), "-o", str(tmp_path / "edge.asc")]) == 0
    assert "nothing of the run is lost, only the file's index after its data" in capsys.readouterr().err
    from rig.recorder import read_recording
    from rig.recorder.completeness import losses
    said = losses(read_recording(edge, allow_partial=True))
    assert any(line.startswith("nothing of the run is lost: its end record counts") for line in said), said
    assert len(read_back(tmp_path / "cli.asc")) == len(b)
    # cut inside the first chunk: nothing before the cut reads, and the error says so (not "no frames in the recording")
    first = tmp_path / "first.mcap"
    first.write_bytes(recording.read_bytes()[:chunks[0].chunk_start_offset + chunks[0].chunk_length // 2])
    with pytest.raises(RecordingError, match=r"first.mcap: no /can/raw frames can be read \(chunk 1 .*is cut by the "
                                             r"end of the file.*a killed run's file can end inside its first — no "
                                             r"message of any topic can be read from it either$"):
        export_can(first, tmp_path / "none.log", partial=True)      # (it pointed at `rig report --partial`, which then
    assert not (tmp_path / "none.log").exists()                     # found nothing to report)


def test_partial_reads_past_a_damaged_chunk_as_the_report_does(tmp_path, capsys):
    """A chunk zeroed in a whole file: `--partial` stopped there (44 000 of 134 106 frames) while
    `rig report --partial` read past it. Now the trace holds every frame of the other chunks — exactly the whole
    file's frames less those of the damaged chunk's /can/raw messages, in order — and the warning names that chunk
    with its messages."""
    recording = tmp_path / "run.mcap"
    run_scene(ROOT / "data" / "scenes" / "pin_insertion.toml", recording, cycles=8, progress=False)
    with recording.open("rb") as f:
        summary = make_reader(f).get_summary()
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(chunks) >= 2
    can_id = next(i for i, c in summary.channels.items() if c.topic == "/can/raw")
    data = recording.read_bytes()
    victim = chunks[0]                # it defines the channels too: the summary's channel records serve
    record = next(StreamReader(io.BytesIO(data[victim.chunk_start_offset:victim.chunk_start_offset
                                               + victim.chunk_length]), skip_magic=True, emit_chunks=True).records)
    assert isinstance(record, Chunk)
    lost_frames = sum(len(orjson.loads(m.data)["t"]) for m in breakup_chunk(record)
                      if isinstance(m, Message) and m.channel_id == can_id)
    assert lost_frames > 0
    bad = bytearray(data)
    middle = victim.chunk_start_offset + victim.chunk_length // 2
    bad[middle:middle + 2000] = bytes(2000)
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(bad))
    whole, part = tmp_path / "whole.log", tmp_path / "part.log"
    export_can(recording, whole)
    e = export_can(damaged, part, partial=True)
    a, b = read_back(whole), read_back(part)
    assert len(b) == e.frames == len(a) - lost_frames
    it = iter(a)                                        # b is a in order, less a run of frames
    assert all(any(x.equals(y) for y in it) for x in b)
    assert e.lost.startswith("chunk 1 of ") and "skipped" in e.lost and "/can/raw" in e.lost
    assert e.t_last == pytest.approx(a[-1].timestamp)   # read to the end, past the damage
    assert not e.tail_lost                              # the warning said the run's tail was not in the file
    assert main(["export-can", "--partial", str(damaged), "-o", str(tmp_path / "cli.asc")]) == 0
    err = capsys.readouterr().err
    assert "the file was read to its end: only what the parts named held is missing" in err
    assert "is not in the file" not in err


@pytest.mark.parametrize("damage", ["flipped", "zeroed"])
def test_a_damaged_chunk_is_one_line_naming_the_file_and_no_trace_is_left(recording, tmp_path, capsys, damage):
    """Bytes flipped or zeroed in the middle of a whole file (its magic intact): the chunk there does not decompress
    (or fails its CRC); the export stops with one line, exit 2, and leaves no half trace."""
    data = bytearray(recording.read_bytes())
    n = len(data) // 2
    data[n:n + 4096] = bytes(b ^ 0xFF for b in data[n:n + 4096]) if damage == "flipped" else bytes(4096)
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    assert main(["-q", "export-can", str(bad), "-o", str(tmp_path / "bus.asc")]) == 2
    err = capsys.readouterr().err
    assert f"{bad}: cannot read the MCAP recording, it is damaged (" in err and "rig report --partial" in err
    assert "--partial` exports every frame that reads (damaged chunks skipped" in err       # not "before the damage"
    assert "rig export-can --partial" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "bus.asc").exists()


def test_a_missing_recording_is_a_usage_error_as_in_report(tmp_path, capsys):
    for argv in (["export-can", str(tmp_path / "none.mcap"), "-o", str(tmp_path / "bus.asc")],
                 ["report", str(tmp_path / "none.mcap"), "-o", str(tmp_path / "rep")]):
        assert main(["-q", *argv]) == 2
        assert f"cannot read recording {tmp_path / 'none.mcap'}: no such file or directory" in capsys.readouterr().err


def test_partial_export_of_a_cut_file_whose_first_chunk_is_damaged_says_the_channels_were_lost(tmp_path):
    """The first chunk defines the channels: damaged, and without a summary (the file is cut), the later chunks'
    messages have no topic. The error said a killed run's file "can end inside its first" chunk; it says this."""
    recording = tmp_path / "run.mcap"
    run_scene(ROOT / "data" / "scenes" / "pin_insertion.toml", recording, cycles=8, progress=False)
    with recording.open("rb") as f:
        chunks = sorted(make_reader(f).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)
    data = bytearray(recording.read_bytes())
    middle = chunks[0].chunk_start_offset + chunks[0].chunk_length // 2
    data[middle:middle + 2000] = bytes(2000)
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data[:chunks[-1].chunk_start_offset + chunks[-1].chunk_length]))    # whole chunks, no summary
    with pytest.raises(RecordingError, match=r"not read: the record defining their channel was in a damaged part\): "
                                             r"the channels were defined in a damaged part.* — `rig report --partial "
                                             r".*bad.mcap` says what the file holds"):
        export_can(bad, tmp_path / "none.log", partial=True)
    assert not (tmp_path / "none.log").exists()


@pytest.mark.parametrize("ext", [".blf", ".mf4"])
def test_the_trace_appears_under_its_name_only_when_whole(recording, tmp_path, monkeypatch, ext):
    """A killed export left a short trace under the name asked for that python-can read without complaint: the trace is
    written under a hidden part name and renamed at the end; a failure leaves neither."""
    from rig.recorder import export_can as module
    out = tmp_path / f"trace{ext}"
    sink = module.FORMATS[ext]
    seen = []

    def close(self):
        seen.append((out.exists(), sorted(p.name for p in tmp_path.iterdir())))
        original(self)
    original = sink.close
    monkeypatch.setattr(sink, "close", close)
    module.export_can(recording, out)
    assert seen[0][0] is False and all(n.startswith(".trace.") and n.endswith(ext) for n in seen[0][1])
    assert seen[0][1] or ext == ".mf4"          # asammdf writes its file in close() only
    assert [p.name for p in tmp_path.iterdir()] == [out.name] and len(read_back(out)) > 0

    def fail(self, frames):
        raise OSError("disk full")
    monkeypatch.setattr(sink, "write", fail)
    with pytest.raises(OSError):
        module.export_can(recording, tmp_path / f"other{ext}")
    assert [p.name for p in tmp_path.iterdir()] == [out.name]


def test_asc_and_blf_read_back_the_same_frame_times(tmp_path):
    """A start of …31.392608 s: the ASC header cut it to .392, python-can's BLF writer rounded it to .393, so the
    same frame read back 1 ms apart from the two files; both now take the start down to its millisecond."""
    start_ns = 1_795_000_031_392_608_000
    rec = _write_mcap(tmp_path / "s.mcap", _blocks(FRAMES), {"wall_clock_start": str(start_ns)})
    export_can(rec, tmp_path / "s.asc")
    export_can(rec, tmp_path / "s.blf")
    with can.ASCReader(tmp_path / "s.asc", relative_timestamp=False) as asc:
        from_asc = [m.timestamp for m in asc]
    with can.BLFReader(tmp_path / "s.blf") as blf:
        from_blf = [m.timestamp for m in blf]
    assert len(from_asc) == len(from_blf) == len(FRAMES)
    assert from_asc == pytest.approx(from_blf, abs=2e-6)
    assert from_asc[0] == pytest.approx(1_795_000_031.392 + FRAMES[0][0], abs=2e-6)

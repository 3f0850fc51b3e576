"""Export a recording's ``/can/raw`` bus traffic to the trace files CAN tools read.

``.asc`` (Vector ASCII), ``.blf`` (Vector binary logging), ``.log`` (candump ``-L``) and ``.trc`` (PEAK, v2.1)
are written by python-can's writers; ``.mf4`` (ASAM MDF 4.10 bus logging: ``CAN_DataFrame`` and
``CAN_ErrorFrame`` channel groups) by asammdf, a block of frames per call. The recording is streamed block by
block, never read whole.

Time base: every frame keeps its simulation time (s from the start of the run). Formats with a start date
in their header (ASC ``date`` and ``Begin Triggerblock``, BLF, TRC, MF4) get the recording's wall-clock start
(``rig`` metadata ``wall_clock_start``, ns since 1970) to the header's resolution — ASC and BLF (SYSTEMTIME) the
millisecond, TRC and MF4 finer —, or 1970-01-01 00:00 UTC (unknown) without it. The ASC dates are written with
zero-padded milliseconds (python-can's writer writes 21.76 for 21.076 s and dates ``date`` at the export).
Readers that add the header date to the frame times (python-can's BLF, TRC and MF4 readers, and its ASC reader
with ``relative_timestamp=False``) so return trace start + simulation time; ASC (python-can's default relative
times) and ``.log`` (no header) return simulation time. Python-can reads absolute times as float s since 1970,
which holds ~0.24 µs: finer BLF/MF4 times survive only relative to the header start.

What each format keeps, as read back by ``can.LogReader`` (id, extended flag, length and data always):

======  =========  =========  ==================  =======================  =======================
format  time       direction  FD, BRS, ESI        channel                  error frames
======  =========  =========  ==================  =======================  =======================
.asc    1 µs       Rx/Tx      yes                 number                   time, channel
.blf    1 ns       Rx/Tx      yes                 number                   time, channel, id, data
.log    1 µs       R/T        yes                 recorded name            time
.trc    1 µs       Rx/Tx      refused (an error)  number                   refused (an error)
.mf4    float64 s  Dir        yes (EDL/BRS/ESI)   number (BusChannel)      all (CAN_ErrorFrame)
======  =========  =========  ==================  =======================  =======================

Channel numbers count 1, 2, ... in the order the recorded names first appear (one bus: 1; python-can's ASC and
BLF readers return it less 1); without recorded names (or with empty ones) the ``.log`` gets python-can's default
``vcan0``, and a name with white space (no candump interface has one) is refused with an error.
"""
from __future__ import annotations

import contextlib
import itertools
import math
import os
import queue
import struct
import threading
from collections import Counter
from dataclasses import dataclass, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Iterator, Protocol

import can
import numpy as np
import orjson
from asammdf import MDF, Signal, Source
from asammdf.blocks import v4_constants as v4c
from can.util import CAN_FD_DLC, len2dlc
from mcap.exceptions import McapError
from zstandard import ZstdError
from mcap.reader import NonSeekingReader, make_reader
from mcap.records import Metadata

from rig.blockbus import ids_out_of_range, is_interface_name
from rig.recorder import schemas as S
from rig.recorder.completeness import all_counted, tail_lost
from rig.recorder.reader import Recording, RecordingError, check_front, require_whole_file, stage_chunk
from rig.recorder.salvage import DataSectionReader, plain

REQUIRED = ("t", "id", "is_fd", "is_extended", "data")
OPTIONAL = ("dir", "channel", "brs", "esi", "error")
_LEN2DLC = np.array([len2dlc(n) for n in range(65)], np.uint8)
_MDF_FIELDS = (("BusChannel", "<u1"), ("ID", "<u4"), ("IDE", "<u1"), ("DLC", "<u1"), ("DataLength", "<u1"),
               ("DataBytes", "(64,)u1"), ("Dir", "<u1"), ("EDL", "<u1"), ("BRS", "<u1"), ("ESI", "<u1"))


@dataclass(frozen=True)
class Frames:
    """One ``/can/raw`` block as columns: ``t`` (s, simulation time), ``id``, bool flags, ``bus`` (channel
    number from 1, in order of first appearance), ``channel`` names (None without that column) and the
    payloads concatenated in ``payload`` (``length`` bytes per frame, in order)."""

    t: np.ndarray
    id: np.ndarray
    extended: np.ndarray
    fd: np.ndarray
    brs: np.ndarray
    esi: np.ndarray
    error: np.ndarray
    rx: np.ndarray
    bus: np.ndarray
    channel: list[str] | None
    payload: bytes
    length: np.ndarray

    def __len__(self) -> int:
        return self.t.shape[0]

    def messages(self, named: bool) -> Iterator[can.Message]:
        """python-can messages; channel = the recorded name if ``named`` (else python-can's default when the
        recording has none), otherwise ``bus - 1`` (python-can's numbered writers count from 1)."""
        names = self.channel if named and self.channel is not None else itertools.repeat(None)
        start = 0
        for t, i, ext, fd, brs, esi, err, rx, bus, name, n in zip(
                self.t.tolist(), self.id.tolist(), self.extended.tolist(), self.fd.tolist(), self.brs.tolist(),
                self.esi.tolist(), self.error.tolist(), self.rx.tolist(), self.bus.tolist(), names,
                self.length.tolist()):
            yield can.Message(timestamp=t, arbitration_id=i, is_extended_id=ext, is_fd=fd, bitrate_switch=brs,
                              error_state_indicator=esi, is_error_frame=err, is_rx=rx,
                              channel=name if named else bus - 1, data=self.payload[start:start + n])
            start += n

    def data_bytes(self) -> np.ndarray:
        """Payloads as an (n, 64) uint8 array, zero past each frame's length."""
        out = np.zeros((len(self), 64), np.uint8)
        starts = np.cumsum(self.length) - self.length
        rows = np.repeat(np.arange(len(self)), self.length)
        out[rows, np.arange(rows.size) - np.repeat(starts, self.length)] = np.frombuffer(self.payload, np.uint8)
        return out


def _flags(block: dict, key: str, n: int) -> np.ndarray:
    return np.asarray(block[key], bool) if key in block else np.zeros(n, bool)


def _decode(block: Any, where: str, buses: dict[str, int], last: float) -> Frames:
    """Columns of one decoded ``/can/raw`` message, checked; ``last`` is the previous block's last time (s)."""
    if not isinstance(block, dict) or any(k not in block for k in REQUIRED):
        have = sorted(block) if isinstance(block, dict) else type(block).__name__
        raise RecordingError(f"{where}: needs columns {', '.join(REQUIRED)}; has {have}")
    n = len(block["t"])
    uneven = [k for k in (*REQUIRED, *OPTIONAL) if k in block and len(block[k]) != n]
    if uneven:
        raise RecordingError(f"{where}: columns {', '.join(uneven)} do not have the {n} rows of 't'")
    hexes = block["data"]
    try:
        payload = bytes.fromhex("".join(hexes))
    except (TypeError, ValueError) as exc:
        raise RecordingError(f"{where}: 'data' is not hex payloads ({exc})") from None
    length = np.array([len(h) // 2 for h in hexes], np.int64)
    dirs = block.get("dir", ["rx"] * n)
    unknown = set(dirs) - {"rx", "tx"}
    names = block.get("channel")
    f = Frames(t=np.asarray(block["t"], np.float64), id=np.asarray(block["id"], np.int64),
               extended=_flags(block, "is_extended", n), fd=_flags(block, "is_fd", n), brs=_flags(block, "brs", n),
               esi=_flags(block, "esi", n), error=_flags(block, "error", n), rx=np.array([d == "rx" for d in dirs], bool),
               bus=np.array([buses.setdefault(c, len(buses) + 1) for c in names] if names is not None else np.ones(n),
                            np.int64),
               channel=names, payload=payload, length=length)
    bad = {"direction other than 'rx'/'tx'": np.array([d in unknown for d in dirs], bool),
           "payload hex of odd length": np.array([len(h) % 2 == 1 for h in hexes], bool),
           "time not finite, negative or before the previous frame": ~np.isfinite(f.t) | (f.t < 0)
           | (np.diff(f.t, prepend=last) < 0),
           "id out of range (11-bit standard, 29-bit extended)":
               ids_out_of_range(f.id, f.extended),
           "data length not a CAN (0-8) or CAN FD length": np.where(f.fd, ~np.isin(length, CAN_FD_DLC), length > 8)}
    for problem, rows in bad.items():
        if rows.any():
            k = int(np.flatnonzero(rows)[0])
            raise RecordingError(f"{where}, frame {k}: {problem} (t={block['t'][k]!r}, id={block['id'][k]!r}, "
                                 f"data={hexes[k]!r}, dir={dirs[k]!r})")
    return f


#: what reading a damaged MCAP file raises: mcap's own errors, a chunk that does not decompress (zstd; lz4 raises
#: RuntimeError), a record cut inside its fields (struct.error)
DAMAGED = (McapError, ZstdError, RuntimeError, struct.error)


def _unreadable(path: Path, exc: Exception) -> RecordingError:
    return RecordingError(f"{path}: cannot read the MCAP recording, it is damaged ({plain(exc)}); exporting CAN "
                          f"needs an undamaged file — `rig export-can --partial` exports every frame that reads "
                          f"(damaged chunks skipped, and named), `rig report --partial {path}` reports what it holds")


def trace_start(path: Path) -> float:
    """Wall-clock start of a recording, s since 1970 (metadata ``rig.wall_clock_start``, ns); 0.0 when it has
    none."""
    try:
        with open(path, "rb") as f:
            meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    except DAMAGED as exc:
        raise _unreadable(path, exc) from None
    value = meta.get(S.RIG_METADATA, {}).get("wall_clock_start")
    if value is None:
        return 0.0
    try:
        return int(value) / 1e9
    except ValueError:
        raise RecordingError(f"{path}: metadata rig.wall_clock_start = {value!r} is not an integer "
                             f"(ns since 1970)") from None


def iter_frames(path: Path) -> Iterator[Frames]:
    """The ``/can/raw`` blocks of a whole recording in file order, decoded and checked one at a time (damage is a
    :class:`RecordingError`; :class:`Salvage` reads a cut or damaged file)."""
    buses: dict[str, int] = {}
    last = -np.inf
    try:
        with open(path, "rb") as f:
            # the stream reader yields each chunk's messages as it reads it; mcap's seeking reader in file order
            # reads every chunk before it yields the first message (a long run's file twice over in memory)
            for k, (_, _, msg) in enumerate(NonSeekingReader(f).iter_messages(topics=[S.CAN_RAW],
                                                                               log_time_order=False)):
                frames = _decode_message(msg.data, f"{path}: {S.CAN_RAW} message {k}", buses, last)
                if len(frames):
                    last = float(frames.t[-1])
                    yield frames
    except DAMAGED as exc:
        raise _unreadable(path, exc) from None


def _decode_message(data: bytes, where: str, buses: dict[str, int], last: float) -> Frames:
    try:
        block = orjson.loads(data)
    except orjson.JSONDecodeError as exc:
        raise RecordingError(f"{where}: not JSON ({exc})") from None
    return _decode(block, where, buses, last)


class _Cancelled(BaseException):
    """The export took no more blocks (writing the trace failed): the reading thread ends (a BaseException: the
    salvage reader, which skips a chunk on any Exception, lets it through)."""


class _FrameCollector:
    """The salvage reader's collector for an export: the ``/can/raw`` blocks of each chunk decoded and checked, all or
    none (a chunk with a malformed block is a lost part, named), handed on one block at a time; of the rest only the
    messages per topic are counted.
    ``start``: the run's wall-clock start (s since 1970): the ``rig`` metadata's, else the first block's log time
    less its first frame's simulation time."""

    def __init__(self, path: Path, hand_on: Callable[[Frames], None]):
        self.rec = Recording(path=path)
        self.channels: dict[int, str] = {}
        self.orphans: Counter[int] = Counter()
        self.start = 0.0
        self._hand_on, self._buses, self._last, self._k = hand_on, {}, -math.inf, 0

    def add(self, record: Any) -> None:
        """A record outside the chunks: metadata kept (the run's start, written when the recording opens, is the
        trace's start and puts the lost parts' times in simulation time), attachments are no part of a trace."""
        if isinstance(record, Metadata):
            self.rec.metadata[record.name] = dict(record.metadata)
            if record.name == S.RIG_METADATA and not self.start:
                with contextlib.suppress(KeyError, ValueError):
                    self.start = int(record.metadata["wall_clock_start"]) / 1e9

    def add_chunk(self, records: list[Any], offset: int | None = None) -> None:
        buses, state = dict(self._buses), {"last": self._last, "k": self._k}

        def decode(topic: str, data: bytes) -> Frames | None:
            if topic != S.CAN_RAW:
                return None
            frames = _decode_message(data, f"{self.rec.path}: {S.CAN_RAW} message {state['k']}", buses, state["last"])
            state["k"] += 1
            if len(frames):
                state["last"] = float(frames.t[-1])
            return frames

        self.channels, staged = stage_chunk(self.channels, records, decode)
        self._buses, self._last, self._k = buses, state["last"], state["k"]
        for record, topic, frames in staged:
            if topic is None:                   # its channel was defined in a part of the file that was lost
                self.orphans[record.channel_id] += 1
                continue
            self.rec.message_counts[topic] = self.rec.message_counts.get(topic, 0) + 1   # (the run's end record
            if frames is not None and len(frames):                                       # counts them all)
                if not self.start:
                    self.start = record.log_time / 1e9 - float(frames.t[0])
                self._hand_on(frames)


class Salvage:
    """The ``/can/raw`` blocks of a cut or damaged recording, read past damage as :func:`read_recording` reads it
    (:class:`~rig.recorder.salvage.DataSectionReader`: a chunk that fails its CRC or does not decode is skipped and
    named, a cut file is read up to the cut), streamed: a reading thread hands the blocks over a queue of a few, so
    memory stays bounded. After :meth:`blocks` is exhausted, ``problems`` says what the file lacks (the lost parts
    with their time ranges first) and ``start`` is the run's wall-clock start (s since 1970, 0.0 unknown)."""

    QUEUE = 4        # blocks read ahead

    def __init__(self, path: Path):
        self.path = path
        self.problems: list[str] = []
        self._queue: queue.Queue = queue.Queue(self.QUEUE)
        self._cancel = threading.Event()
        self._collector = _FrameCollector(path, lambda frames: self._put(("frames", frames)))

    @property
    def start(self) -> float:
        return self._collector.start

    @property
    def recording(self) -> Recording:
        """What was read of the file (after :meth:`blocks` is exhausted; its frames are not kept)."""
        return self._collector.rec

    @property
    def empty(self) -> bool:
        """No message of any topic was read (after :meth:`blocks` is exhausted)."""
        return not self._collector.rec.message_counts and not self.orphans

    @property
    def orphans(self) -> int:
        """Messages on channels whose definition was in a lost part (their topic unknown)."""
        return sum(self._collector.orphans.values())

    def _put(self, item: tuple) -> None:
        while not self._cancel.is_set():
            with contextlib.suppress(queue.Full):
                self._queue.put(item, timeout=0.05)
                return
        raise _Cancelled

    def _read(self) -> None:
        try:
            with open(self.path, "rb") as f:
                size, damage = check_front(self.path, f)     # a damaged opening magic: named with the rest
                reader = DataSectionReader(f, size, self._collector)
                reader.read()
                reader.check()
            reader.finish()
            rec = self._collector.rec
            self.problems = [damage] * bool(damage) + list(rec.problems) + (
                [] if reader.footer or rec.truncated else
                ["file ends without a footer (recording was not closed)"])
            self._put(("end", None))
        except _Cancelled:
            pass
        except BaseException as exc:  # noqa: BLE001  (handed to the exporting thread, which raises it)
            with contextlib.suppress(_Cancelled):
                self._put(("error", exc))

    def blocks(self) -> Iterator[Frames]:
        """The blocks in file order (each decoded and checked)."""
        thread = threading.Thread(target=self._read, name="export-can reader", daemon=True)
        thread.start()
        try:
            while True:
                kind, item = self._queue.get()
                if kind == "error":
                    raise item
                if kind == "end":
                    return
                yield item
        finally:
            self._cancel.set()
            thread.join()


class _Sink(Protocol):
    shown: Path             # the trace's name in messages (written under a hidden part name first)

    def write(self, frames: Frames) -> None: ...

    def close(self) -> None: ...


class _PythonCan:
    """A python-can writer, fed frame by frame (its only interface)."""

    named = False

    def __init__(self, writer: can.io.generic.MessageWriter):
        self.writer = writer

    def write(self, frames: Frames) -> None:
        for msg in frames.messages(self.named):
            self.writer.on_message_received(msg)

    def close(self) -> None:
        self.writer.stop()


class _AscWriter(can.ASCWriter):
    """python-can's ASC writer with both header dates (``date``, ``Begin Triggerblock``) at the trace start,
    milliseconds zero-padded."""

    def __init__(self, out: Path, start: float):
        self._start = datetime.fromtimestamp(start)          # local time, as python-can's reader reads it back
        super().__init__(out)

    def _format_header_datetime(self, dt: datetime) -> str:
        return self._start.strftime(f"%a %b %d %H:%M:%S.{self._start.microsecond // 1000:03d} %Y")


def _whole_ms(start: float) -> float:
    """The trace start down to its millisecond: the resolution of the ASC and BLF header dates, in both the same (ASC
    cut it, python-can's BLF writer rounded it: one frame read back 1 ms apart from the two files)."""
    return math.floor(start * 1e3) / 1e3


class _Asc(_PythonCan):
    def __init__(self, out: Path, start: float):
        start = _whole_ms(start)
        super().__init__(_AscWriter(out, start))
        self.writer.log_event("rig export: times are simulation time, s", start)   # header date = start
        self.writer.started = 0.0            # the writer subtracts this from every time: keep simulation time


class _Blf(_PythonCan):
    def __init__(self, out: Path, start: float):
        super().__init__(can.BLFWriter(out))
        self.writer.start_timestamp = 0.0    # object times (ns) = simulation time
        self.start = _whole_ms(start)

    def close(self) -> None:
        w = self.writer
        w.start_timestamp, w.stop_timestamp = self.start, self.start + (w.stop_timestamp or 0.0)   # header dates
        super().close()


class _Log(_PythonCan):
    named = True

    def __init__(self, out: Path, start: float):
        super().__init__(can.CanutilsLogWriter(out))
        self.shown = out

    def write(self, frames: Frames) -> None:
        """A name with white space cannot be a candump interface (its reader splits lines at spaces: the file
        would not read back); an empty name is none (python-can's default ``vcan0``)."""
        if frames.channel is not None:
            spaced = next((c for c in frames.channel if c and not is_interface_name(c)), None)
            if spaced is not None:
                raise ValueError(f"{self.shown}: the recording's CAN channel {spaced!r} has white space, which a "
                                 "candump .log cannot hold (its interface names are single words); export to .asc, "
                                 ".blf, .trc or .mf4, which number the channels")
            if "" in frames.channel:
                frames = replace(frames, channel=[c or None for c in frames.channel])
        super().write(frames)


class _Trc(_PythonCan):
    def __init__(self, out: Path, start: float):
        super().__init__(can.TRCWriter(out))
        self.writer.first_timestamp = 0.0    # offsets (ms) = simulation time
        self.start = start
        self.shown = out                     # the name its messages give (export_can: the trace's, not the part's)

    def write(self, frames: Frames) -> None:
        bad = np.flatnonzero(frames.fd | frames.error)
        if bad.size:
            k = int(bad[0])
            raise ValueError(f"{self.shown}: python-can's TRC writer cannot hold CAN FD or error frames, and the "
                             f"recording has {'an FD' if frames.fd[k] else 'an error'} frame at t = "
                             f"{frames.t[k]:.6f} s (id 0x{int(frames.id[k]):X}); export to .asc, .blf, .log or .mf4")
        if not self.writer.header_written:   # the header names the trace (it is written under a part name first)
            self.writer.filepath = os.path.abspath(self.shown)
            self.writer.write_header(self.start)
        super().write(frames)


class _Mf4:
    """ASAM MDF 4.10 bus logging through asammdf: one structured record array per block and frame kind."""

    def __init__(self, out: Path, start: float):
        self.out = out
        self.mdf = MDF(version="4.10")
        self.mdf.header.start_time = datetime.fromtimestamp(start, timezone.utc)
        self.groups: dict[str, int] = {}
        self.source = Source(name="CAN", path="CAN", comment="rig /can/raw", source_type=v4c.SOURCE_BUS,
                             bus_type=v4c.BUS_TYPE_CAN)

    def write(self, frames: Frames) -> None:
        data = frames.data_bytes()
        for kind, rows in (("CAN_DataFrame", ~frames.error), ("CAN_ErrorFrame", frames.error)):
            if not rows.any():
                continue
            rec = np.zeros(int(rows.sum()), [(f"{kind}.{name}", dtype) for name, dtype in _MDF_FIELDS])
            for name, values in (("BusChannel", frames.bus), ("ID", frames.id), ("IDE", frames.extended),
                                 ("DLC", _LEN2DLC[frames.length]), ("DataLength", frames.length),
                                 ("DataBytes", data), ("Dir", ~frames.rx), ("EDL", frames.fd),
                                 ("BRS", frames.brs), ("ESI", frames.esi)):
                rec[f"{kind}.{name}"] = values[rows]
            if kind in self.groups:
                self.mdf.extend(self.groups[kind], [(frames.t[rows], None), (rec, None)])
            else:
                self.groups[kind] = self.mdf.append(Signal(name=kind, samples=rec, timestamps=frames.t[rows],
                                                           source=self.source))

    def close(self) -> None:
        try:
            self.mdf.save(self.out, overwrite=True, compression=v4c.CompressionAlgorithm.TRANSPOSED_DEFLATE)
        finally:
            self.mdf.close()


FORMATS: dict[str, type] = {".asc": _Asc, ".blf": _Blf, ".log": _Log, ".trc": _Trc, ".mf4": _Mf4}


@dataclass(frozen=True)
class Export:
    """What :func:`export_can` wrote: ``frames`` (of them ``error_frames``), channel names in bus order, the
    trace start (s since 1970, 0.0 = unknown) and the simulation time span (s)."""

    path: Path
    frames: int
    error_frames: int
    channels: list[str]
    start: float
    t_first: float
    t_last: float
    lost: str = ""      # partial: what the recording lacks, its lost parts first ("" = nothing)
    tail_lost: bool = False     # partial: frames after the last one exported may be missing (a cut before them)
    all_read: bool = False      # partial: the run's end record counts every message and all were read


def export_can(recording: str | Path, out: str | Path, partial: bool = False) -> Export:
    """Write the ``/can/raw`` frames of ``recording`` to ``out``, in the format of its extension (see
    :data:`FORMATS`). A recording without CAN frames, an unknown extension or frames the format cannot hold are
    errors (no output is left behind). ``partial``: a cut or damaged recording (a killed run) gives the frames up to
    where it can no longer be read, and ``lost`` says why the trace ends there; otherwise it is an error. The trace is
    written under a hidden name beside ``out`` and renamed when whole: a killed export leaves no short trace that
    reads as complete under the name asked for."""
    recording, out = Path(recording), Path(out)
    sink_type = FORMATS.get(out.suffix.lower())
    if sink_type is None:
        raise ValueError(f"{out}: unknown CAN trace format {out.suffix or '(no extension)'!r}; "
                         f"use one of {', '.join(FORMATS)}")
    if partial:
        salvage = Salvage(recording)
        blocks = salvage.blocks()
    else:
        require_whole_file(recording, "exporting every CAN frame (`rig export-can --partial` exports those before the "
                                      "cut)")
        blocks = iter_frames(recording)
    with contextlib.closing(blocks):          # however the export ends, a salvage's reading thread ends with it
        first = next(blocks, None)
        if first is None:
            if partial and salvage.problems:
                why = ("the channels were defined in a damaged part, so the messages after it cannot be told apart by "
                       "topic" if salvage.orphans else "the recorder writes its messages in chunks of several seconds, "
                       "and a killed run's file can end inside its first")
                held = ("no message of any topic can be read from it either" if salvage.empty else
                        f"`rig report --partial {recording}` says what the file holds")
                raise RecordingError(f"{recording}: no {S.CAN_RAW} frames can be read "
                                     f"({'; '.join(salvage.problems)}): {why} — {held}")
            raise RecordingError(f"{recording}: no {S.CAN_RAW} frames in the recording, nothing to export")
        start = salvage.start if partial else trace_start(recording)
        part = out.with_name(f".{out.stem}.{os.getpid()}.part{out.suffix}")     # the extension: asammdf keeps .mf4
        sink: _Sink = sink_type(part, start)
        sink.shown = out
        frames = errors = 0
        names: dict[str, None] = {}
        try:
            for block in itertools.chain([first], blocks):
                sink.write(block)
                frames += len(block)
                errors += int(block.error.sum())
                names.update(dict.fromkeys(block.channel or ()))
                t_last = float(block.t[-1])
            sink.close()
            os.replace(part, out)
        except BaseException:
            with contextlib.suppress(Exception):
                sink.close()
            part.unlink(missing_ok=True)
            raise
    return Export(out, frames, errors, list(names), start, float(first.t[0]), t_last,
                  "; ".join(salvage.problems) if partial else "", partial and tail_lost(salvage.recording),
                  partial and all_counted(salvage.recording))

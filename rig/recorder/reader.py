"""Read a rig MCAP recording back into arrays; recover what is readable from truncated files."""
from __future__ import annotations

import ctypes
import ctypes.util
import math
import os
import struct
from collections import defaultdict
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterator

import numpy as np
import orjson
from mcap.records import Attachment, Channel, Message, Metadata

from rig.recorder import schemas as S
from rig.recorder.salvage import MCAP_MAGIC, DataSectionReader, LostPart
from rig.recorder import curves, series as bulk
from rig.recorder.curves import CurveRecord, curve_arrays, curve_message, nbytes
from rig.recorder.encoding import decode_block, loads_message
from rig.recorder.errors import RecordingError
from rig.recorder.store import MessageStore

if TYPE_CHECKING:
    from rig.scene import Scene


@dataclass
class Recording:
    """Everything in a recording. ``series`` maps each bulk topic to concatenated arrays (incl. ``t``);
    ``can_frames`` the ``/can/raw`` columns (``t``, ``id``, ``data`` bytes, ``dir`` and ``channel`` str lists,
    bool arrays ``is_fd``, ``brs``, ``esi``, ``is_extended``, ``error``; empty when read with ``can_frames=False``),
    ``can_counts`` its ``frames`` and ``sent`` (the host's own) counted either way. View channels and ``/log``
    repeat other topics and are only counted. A topic's arrays beyond :data:`rig.recorder.series.KEPT_BYTES` are not
    held: ``series`` holds its first samples, ``series_beyond`` says what the rest spans, and
    :meth:`series_blocks` yields all of them (the rest read again from the file, ``series_store``).

    ``complete``: the file is whole and the run ended normally. ``truncated``: the file is cut short or
    damaged (read with ``allow_partial``). ``end``: the run's end record (metadata ``rig.end``: ``complete``,
    ``reason``, ``simulation_time``, ``messages``), empty when the writer never closed the file.
    ``last_time``: simulation time (s) of the latest data read (a sample, a frame or a message).
    ``data_whole``: every record up to the data end was read, or all but an index or framing record (whatever a
    truncated file lacks is then only the index after it: summary, footer, closing magic). ``lost``: the damaged
    parts skipped (each also named in ``problems``); ``read_to_data_end``: reading went on to the data end (past
    any damaged part), so a damaged file lacks only its ``lost`` parts. ``damaged``: some of the file's bytes were
    altered (a CRC, a record or a value does not read), as opposed to a file only cut short.
    """

    path: Path
    scene_text: str | None = None
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    programs: dict[int, dict] = field(default_factory=dict)
    curves: list[CurveRecord] = field(default_factory=list)
    results: list[dict] = field(default_factory=list)
    statistics: list[dict] = field(default_factory=list)
    events: list[dict] = field(default_factory=list)
    series: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    series_beyond: dict[str, bulk.Beyond] = field(default_factory=dict)
    series_store: MessageStore | None = None
    can_frames: dict[str, Any] = field(default_factory=dict)
    can_counts: dict[str, int] = field(default_factory=lambda: {"frames": 0, "sent": 0})
    message_counts: dict[str, int] = field(default_factory=dict)
    complete: bool = True
    truncated: bool = False
    problems: list[str] = field(default_factory=list)
    last_time: float = 0.0
    data_whole: bool = True
    lost: list[LostPart] = field(default_factory=list)
    read_to_data_end: bool = True
    damaged: bool = False

    @property
    def end(self) -> dict[str, str]:
        return self.metadata.get(S.END_METADATA, {})

    @property
    def interrupted(self) -> str | None:
        """Why the run stopped early, as its end record says (None: it did not say so)."""
        return self.end.get("reason") or "unknown reason" if self.end.get("complete") == "false" else None

    @property
    def truth(self) -> dict[str, np.ndarray]:
        return self.series.get(S.TRUTH, {})

    @property
    def live(self) -> dict[str, np.ndarray]:
        return self.series.get(S.LIVE, {})

    @property
    def serial_link_off(self) -> bool:
        """Whether the run had its serial link off (a stand, a lab): the host read no device statistics, none lost."""
        return self.metadata.get(S.RIG_METADATA, {}).get("serial_link") == "off"

    def series_blocks(self, topic: str) -> Iterator[dict[str, np.ndarray]]:
        """Every sample of a bulk topic in file order, a block at a time (what ``series`` holds first)."""
        return bulk.blocks(self.series.get(topic, {}), self.series_beyond.get(topic), self.series_store)

    def scene(self) -> "Scene":
        """The recorded scene, named ``<recording>:scene.toml`` in its errors; SceneError if there is none or
        it is not valid TOML."""
        import tomllib
        from rig.scene import Scene, SceneError
        if not self.scene_text:
            raise SceneError(f"{self.path}: the recording holds no scene")
        try:
            data = tomllib.loads(self.scene_text)
        except tomllib.TOMLDecodeError as exc:
            raise SceneError(f"{self.path}: recorded scene is not valid TOML: {exc}") from None
        return Scene(Path(f"{self.path}:scene.toml"), data, self.scene_text, self.scene_folder)

    @property
    def scene_folder(self) -> Path:
        """Where the relative paths the recorded scene names lie: the scene file's folder when the recording names the
        file whole (``rig run`` does), else — a scene file named relative to an unknown directory — the recording's."""
        written = Path(self.metadata.get("rig", {}).get("scene_file", ""))
        return written.parent if written.is_absolute() else self.path.parent

    @property
    def simulation_time(self) -> float | None:
        """Simulated time of the run (s) as its end record states it; None when the writer never closed the file."""
        value = self.end.get("simulation_time")
        return float(value) if value else None

    def _count_text(self, topic: str, count: int) -> str:
        """'/can/raw: 135 messages (134106 frames: 134104 received, 2 sent)': a ``/can/raw`` message is a batch of
        frames, so its count is not read as frames; other topics '/device/curve: 50'."""
        if topic != S.CAN_RAW:
            return f"{topic}: {count}"
        messages = f"{topic}: {count} message{'' if count == 1 else 's'}"
        frames, sent = self.can_counts["frames"], self.can_counts["sent"]
        if not frames:
            return messages
        return f"{messages} ({frames} frames{f': {frames - sent} received, {sent} sent' if sent else ' received'})"

    def summary(self) -> str:
        """Messages per topic (/can/raw also its frames), programs and whether the scene is recorded (one line)."""
        counts = ", ".join(self._count_text(k, v) for k, v in sorted(self.message_counts.items())) or "no messages"
        return f"{counts}; {len(self.programs)} program(s), scene {'present' if self.scene_text else 'absent'}"


#: end-record reasons (:func:`rig.recorder.writer.interruption`: the exception's type) of a run the user stopped
USER_STOPS = ("KeyboardInterrupt", "Interrupted")


def interruption_text(reason: str) -> str:
    """Why a run stopped early in plain words, from its end record's ``reason`` (the exception, e.g.
    ``KeyboardInterrupt``, ``Terminated: SIGTERM`` or ``RunError: …``): "interrupted by the user (Ctrl-C)",
    "terminated by SIGTERM (…)", "stopped by an error — …"."""
    kind = reason.split(":", 1)[0].strip()
    if kind in USER_STOPS:
        return "interrupted by the user (Ctrl-C)"
    if kind == "Terminated":                       # rig.stops.Terminated: the console script's SIGTERM
        return "terminated by SIGTERM (timeout, docker stop, systemd or a CI runner)"
    if reason == "unknown reason":                 # the reader's word for an end record without a reason
        return "stopped early (the recording does not say why)"
    if S.is_repaired(reason):                        # rig.recorder.repair: a cut or damaged file rewritten whole
        return f"cut short or damaged, then {reason}"
    return f"stopped by an error — {reason}"


def _curve(msg: dict) -> tuple[dict[str, Any], dict[str, Any]]:
    """A ``/device/curve`` message as (its number, program and other fields; its arrays)."""
    return {"number": int(msg["number"]), "program": int(msg["program"]),
            "extra": {k: v for k, v in msg.items() if k not in _CURVE_FIELDS}}, curve_arrays(msg)


_CURVE_FIELDS = frozenset({"number", "program", "t", "x", "y", "angle", "theory"})
_CAN_FLAGS = ("is_fd", "brs", "esi", "is_extended", "error")
_WORDS: dict[str, str] = {}      # one str object per direction / channel name, whatever the number of frames


def _can_tally(msg: dict) -> tuple[int, int, float]:
    """A ``/can/raw`` message's frames, frames the host sent, and its last frame's time (s; -inf without frames)."""
    return len(msg["t"]), msg["dir"].count("tx"), float(msg["t"][-1]) if msg["t"] else -math.inf


def _can_columns(msg: dict) -> dict[str, Any]:
    """One ``/can/raw`` message as compact columns, decoded as it is read: numbers in arrays, the data as bytes,
    the directions and channel names shared (a long run's millions of frames held as parsed JSON took ≈ 400 bytes
    each)."""
    return {"t": np.asarray(msg["t"], dtype=np.float64), "id": np.asarray(msg["id"], dtype=np.int64),
            **{key: [_WORDS.setdefault(v, v) for v in msg[key]] for key in ("dir", "channel")},
            **{key: np.asarray(msg[key], dtype=bool) for key in _CAN_FLAGS},
            "data": [bytes.fromhex(d) for d in msg["data"]]}


def _can(blocks: list[dict]) -> dict[str, Any]:
    """The columns of every ``/can/raw`` message, joined."""
    return {**{key: np.concatenate([b[key] for b in blocks]) for key in ("t", "id", *_CAN_FLAGS)},
            **{key: [v for b in blocks for v in b[key]] for key in ("dir", "channel", "data")}}


_REPEATS = frozenset({*S.VIEWS, S.LOG})      # topics that repeat others' data in a viewer's form


def stage_chunk(channels: dict[int, str], records: list[Any],
                decode: Callable[[str, bytes], Any]) -> tuple[dict[int, str], list[tuple[Any, str | None, Any]]]:
    """A chunk's records staged, before any is kept: ``channels`` with the chunk's channel definitions added (a
    copy), and each message as (record, its topic — None where its channel was defined in a lost part —,
    ``decode(topic, data)``); a message that does not decode raises with nothing of the chunk kept."""
    channels = dict(channels)
    staged = []
    for record in records:
        if isinstance(record, Channel):
            channels[record.id] = record.topic
        elif isinstance(record, Message):
            topic = channels.get(record.channel_id)
            staged.append((record, topic, None if topic is None else decode(topic, record.data)))
    return channels, staged


class Collector:
    """Sorts decoded records into a :class:`Recording`: the reader's, and the salvage and repair passes' (which read
    the data section themselves). With the recording's ``path`` (and its (size, mtime_ns) ``stamp``) curves and series
    beyond their budgets are noted to be read again from it; without, everything is held."""

    def __init__(self, rec: Recording, can_frames: bool = True, path: Path | None = None,
                 stamp: tuple[int, int] = (0, 0)):
        self.rec = rec
        self.keep_can = can_frames
        # where curves beyond curves.KEPT_BYTES and series beyond series.KEPT_BYTES are read again from (none
        # without a file: everything held)
        self.store = None if path is None else MessageStore(path, stamp, curve_message, "curves")
        rec.series_store = None if path is None else MessageStore(path, stamp, decode_block, "series")
        self.kept = 0                                       # bytes of curve arrays held
        self.series_kept: dict[str, int] = defaultdict(int)     # bytes of each topic's series held
        self.series_cut: float | None = None            # the time (s) every series topic is held up to (see _series)
        self.can_end = -math.inf                            # the last /can/raw frame's time (s)
        self.channels: dict[int, str] = {}
        self.blocks: dict[str, list[dict[str, np.ndarray]]] = defaultdict(list)
        self.can: list[dict] = []
        self.last_log_ns = 0
        self.orphans: dict[int, int] = defaultdict(int)     # messages on a channel never defined: per channel id

    def add(self, record: Any) -> None:
        """A record outside the chunks (attachment, metadata; others are only framing)."""
        rec = self.rec
        if isinstance(record, Attachment):
            if record.name == S.SCENE_ATTACHMENT:
                rec.scene_text = record.data.decode("utf-8")
            elif record.name.startswith("device/program/"):
                rec.programs[int(Path(record.name).stem)] = orjson.loads(record.data)
        elif isinstance(record, Metadata):
            rec.metadata[record.name] = dict(record.metadata)

    def add_chunk(self, records: list[Any], offset: int | None = None) -> None:
        """The records of one chunk (whose record starts at byte ``offset``), all or none: every message is decoded
        before any is kept (a message that does not decode raises with nothing of its chunk collected)."""
        self.channels, staged = stage_chunk(self.channels, records, self._decode)
        place = {id(r): i for i, r in enumerate(records)} if offset is not None and self.store is not None else None
        rec = self.rec
        for record, topic, value in staged:
            if topic is None:                   # its channel was defined in a part of the file that was lost
                self.orphans[record.channel_id] += 1
                continue
            if topic == S.CAN_RAW and value is not None:
                (frames, sent, end), columns = value
                rec.can_counts["frames"] += frames
                rec.can_counts["sent"] += sent
                self.can_end = max(self.can_end, end)
                if columns is not None:
                    self.can.append(columns)
            elif topic == S.CURVE and value is not None:
                fields, arrays = value
                size = nbytes(arrays)
                if place is None or self.kept + size <= curves.KEPT_BYTES:
                    self.kept += size
                    rec.curves.append(CurveRecord(**fields, **arrays))
                else:
                    rec.curves.append(CurveRecord(**fields, **arrays, store=self.store,     # what they hold, not them
                                                  key=self.store.place(offset, place[id(record)])))
            elif topic in (S.RESULT, S.STATISTICS, S.EVENTS):
                {S.RESULT: rec.results, S.STATISTICS: rec.statistics, S.EVENTS: rec.events}[topic].append(value)
            elif value is not None:
                self._series(topic, value, None if place is None else (offset, place[id(record)]))
            rec.message_counts[topic] = rec.message_counts.get(topic, 0) + 1
            self.last_log_ns = max(self.last_log_ns, record.log_time)

    def _series(self, topic: str, block: dict[str, np.ndarray], where: tuple[int, int] | None) -> None:
        """A bulk block held, or noted where it is in the file (``where``: its chunk's offset and place; None: held
        whatever its size). Every topic is cut at one time, so that analyses joining topics see the same span: the
        first block of any topic whose held bytes would pass the budget sets it (``series_cut``, its first sample's
        time); from then on a block of any topic starting there or later is noted, not held (:meth:`finish` trims
        what the held ones hold past it)."""
        size = bulk.block_bytes(block)
        t = block.get("t")
        first = float(t[0]) if t is not None and t.size else -math.inf
        kept = self.series_kept[topic]                  # a topic's first block is held whatever its size
        if where is not None and self.series_cut is None and 0 < kept and kept + size > bulk.KEPT_BYTES:
            self.series_cut = first
        if where is not None and self.series_cut is not None and first >= self.series_cut:
            self.rec.series_beyond.setdefault(topic, bulk.Beyond()).add(self.rec.series_store.place(*where), block)
        else:
            self.series_kept[topic] += size
            self.blocks[topic].append(block)

    def _decode(self, topic: str, data: bytes) -> Any:
        if topic in _REPEATS or not S.is_rig_topic(topic):     # (another tool's topic: counted, not read — a JSON
            return None                                         # or CDR message of its own was called damage)
        if topic == S.CURVE:
            return _curve(loads_message(data))
        if topic == S.CAN_RAW:
            msg = loads_message(data)
            return _can_tally(msg), (_can_columns(msg) if self.keep_can else None)
        if topic in (S.RESULT, S.STATISTICS, S.EVENTS):
            return loads_message(data)
        return decode_block(data)

    def finish(self) -> Recording:
        for topic, blocks in self.blocks.items():     # column by column, each block's part freed once joined (a
            series = self.rec.series[topic] = {}       # 1000-cycle demo read holds 170 MB after, not 204 MB)
            for k in list(blocks[0]):
                series[k] = np.concatenate([b.pop(k) for b in blocks])
            blocks.clear()
            if self.series_cut is not None and "t" in series:      # the held part past the common cut: its tail
                n = int(np.searchsorted(series["t"], self.series_cut, side="left"))
                if n < series["t"].size:
                    self.rec.series_beyond.setdefault(topic, bulk.Beyond()).set_tail(
                        {k: v[n:].copy() for k, v in series.items()})
                    for k in series:
                        series[k] = series[k][:n].copy()
        if self.can:
            self.rec.can_frames = _can(self.can)
        # a block's log time is its first sample's: its samples (and a CAN block's frames) reach further
        ends = [float(s["t"][-1]) for s in self.rec.series.values() if "t" in s and len(s["t"])]
        ends += [b.t_last for b in self.rec.series_beyond.values() if b.samples]
        ends += [c.t_end for c in self.rec.curves if c.t_end is not None]
        ends += [float(e["t"]) for e in self.rec.events if isinstance(e.get("t"), (int, float))]
        if "wall_clock_start" in self.rec.metadata.get(S.RIG_METADATA, {}):   # log times as simulation times
            start = _metadata_number(self.rec, S.RIG_METADATA, "wall_clock_start", "0", int)
            ends.append(max(self.last_log_ns - start, 0) / 1e9)
        self.rec.last_time = max([*ends, self.can_end])
        return self.rec


def release_free_memory() -> None:
    """Hand the heap's free pages back to the operating system (glibc's ``malloc_trim``; elsewhere nothing): reading
    decodes a long run's messages into large transient objects whose freed space the heap otherwise keeps (a 5000-curve
    recording: 394 MB of heap after reading, 207 MB trimmed)."""
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


@cache
def _malloc_trim() -> Callable[[int], int] | None:
    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
    except (OSError, AttributeError, TypeError):     # not glibc: no such function
        return None


def _metadata_number(rec: Recording, name: str, key: str, default: str, kind: type) -> Any:
    """Metadata value ``name.key`` read as ``kind``; a ValueError naming it when it is not a number."""
    text = rec.metadata.get(name, {}).get(key, default)
    try:
        return kind(text)
    except ValueError:
        raise ValueError(f"metadata {name}.{key} = {text!r} is not a number") from None


def check_front(path: Path, f: Any) -> tuple[int, str]:
    """The size of the open recording ``f`` and what is wrong with its opening magic ('' when intact), after checking
    it is not empty and starts as an MCAP file does — or, its first 8 bytes damaged, goes on as one
    (:func:`_records_after_magic`)."""
    size = os.fstat(f.fileno()).st_size
    if size == 0:
        raise RecordingError(f"{path}: empty file (0 bytes), not a recording")
    head = f.read(len(MCAP_MAGIC))
    if MCAP_MAGIC.startswith(head):
        return size, ""
    if not _records_after_magic(f, size):
        raise RecordingError(f"{path}: not an MCAP file (bad magic bytes)")
    f.seek(len(MCAP_MAGIC))
    return size, (f"the file's opening magic (its first {len(MCAP_MAGIC)} bytes, {head!r} for {MCAP_MAGIC!r}) is "
                  "damaged: the records after it read as MCAP, but other tools refuse the file")


def _records_after_magic(f: Any, size: int) -> bool:
    """Whether an MCAP header record follows a damaged opening magic: its opcode, a length inside the file and a
    profile string that fits it — the rest of a recording, not another kind of file."""
    f.seek(len(MCAP_MAGIC))
    head = f.read(13)
    if len(head) < 13 or head[0] != 0x01:
        return False
    length, profile = struct.unpack_from("<QI", head, 1)
    return 8 <= length <= min(1 << 20, size - len(MCAP_MAGIC) - 9) and profile + 8 <= length


def _unreadable(path: Path, exc: OSError) -> RecordingError:
    return RecordingError(f"cannot read recording {path}: {(exc.strerror or str(exc)).lower()}")


def require_recording(path: str | Path) -> None:
    """A :class:`RecordingError` in plain words unless ``path`` can be opened and starts as an MCAP file: checked
    before an output is, so that a missing recording is named as such, not the output in the way."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            check_front(path, f)               # a damaged opening magic: the reader names it, and reads on
    except OSError as exc:
        raise _unreadable(path, exc) from None


def require_whole_file(path: str | Path, need: str) -> None:
    """A :class:`RecordingError` in plain words unless ``path`` is a whole MCAP file (its magic at both ends):
    missing, empty, not MCAP, or cut short (a killed run or a cut copy) — ``need``: what the caller needs it for."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            size, damage = check_front(path, f)
            f.seek(max(0, size - len(MCAP_MAGIC)))
            tail = f.read()
    except OSError as exc:
        raise _unreadable(path, exc) from None
    if damage:
        raise RecordingError(f"{path}: {damage}; {need} needs a whole file (`rig repair {path}` rewrites it whole, "
                             f"`rig report --partial {path}` reports what it holds)")
    if size < 2 * len(MCAP_MAGIC) or tail != MCAP_MAGIC:
        raise RecordingError(f"{path}: truncated recording (it does not end with MCAP's closing magic: a killed run "
                             f"or a cut copy); {need} needs a whole file — `rig report --partial {path}` reports "
                             "what it holds")


def read_recording(path: str | Path, allow_partial: bool = False, can_frames: bool = True) -> Recording:
    """Read a recording made by :class:`rig.recorder.Recorder`.

    A truncated or damaged file raises :class:`RecordingError` naming the file, the problem and what
    was recovered (also in ``exc.partial``); with ``allow_partial`` the partial recording is returned
    with ``truncated = True``, ``complete = False`` and ``problems`` filled in: a chunk that fails its CRC
    or does not decode is skipped and the reading goes on (``lost`` names it, with its time range and
    messages per topic where the index says so), as it does past damaged bytes (to where the summary's index,
    or without an intact summary the next whole chunk, says the next record starts); a cut file is read up to
    the cut. A whole file of a run that stopped early reads without error, with ``complete = False`` and the
    reason in ``problems``. ``can_frames=False``: the ``/can/raw`` frames are counted, not kept (an analysis that
    needs none of them reads a long run's millions of frames in a fraction of the memory and time).
    """
    path = Path(path)
    rec = Recording(path=path)
    try:
        with open(path, "rb") as f:
            st = os.fstat(f.fileno())
            collector = Collector(rec, can_frames, path, (st.st_size, st.st_mtime_ns))
            size, damage = check_front(path, f)
            reader = DataSectionReader(f, size, collector)
            if damage:
                rec.truncated = rec.damaged = True
                rec.problems.append(f"{damage} (`rig repair` rewrites it whole)")
            reader.read()
            reader.check()
    except OSError as exc:
        raise _unreadable(path, exc) from None
    if not reader.footer and not rec.truncated:
        rec.truncated = True
        rec.problems.append("file ends without a footer (recording was not closed)")
    reader.finish()
    try:
        collector.finish()
        if rec.interrupted is not None:
            t = _metadata_number(rec, S.END_METADATA, "simulation_time", "nan", float)
            at = (f" (its data reach {t:.3f} s of simulation time)" if S.is_repaired(rec.interrupted)
                  else f" at {t:.3f} s of simulation time")     # (a repaired file's time is not where it was damaged)
            rec.problems.append(interruption_text(rec.interrupted) + (at if math.isfinite(t) else ""))
    except ValueError as exc:  # a damaged metadata value
        rec.truncated = rec.damaged = True
        rec.problems.append(f"damaged {exc}")
    rec.complete = not rec.truncated and rec.interrupted is None
    release_free_memory()
    if rec.truncated and not allow_partial:
        raise RecordingError(f"{path}: truncated or corrupt MCAP recording; read_recording(..., allow_partial=True) "
                             f"returns what it holds ({rec.summary()}), reading past what is damaged: "
                             f"{'; '.join(rec.problems)}",
                             partial=rec)
    return rec

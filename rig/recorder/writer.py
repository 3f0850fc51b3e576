"""MCAP recorder: self-describing JSON channels written in blocks, with per-sample view channels.

Log time = the run's wall-clock start (ns since 1970, metadata ``rig`` ``wall_clock_start``) + the
simulation time; messages carry the simulation time (``t``, s). Use as a context manager so the file is
finished (summary, indexes, footer) even when the run is interrupted by an exception or Ctrl-C; the end
is recorded (metadata ``rig.end``: ``complete``, ``reason``; an ``interrupted`` event when it was not)::

    with Recorder("run.mcap", scene_text=scene.text, metadata={"seed": 7}) as rec:
        rec.write_truth(t, {"x": x, "F": F})
        rec.write_curve(1, 1, t, x, y)
"""
from __future__ import annotations

import json
import math
import platform
import time
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

import can
import mcap
import numpy as np
from mcap.writer import CompressionType, Writer

import rig
from rig.blockbus import BRS, ERROR, ESI, EXTENDED, FD, REMOTE, RX, FrameBlock, frames_of, ids_out_of_range
from rig.recorder import schemas as S
from rig.recorder.encoding import ENCODINGS, NULLS, dumps, dumps_message, dumps_rows, encode_array, encode_block
from rig.recorder.log import log_message
from rig.recorder.view import Decimator

COMPRESSIONS = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
CAN_COLUMNS = ("t", "id", "dir", "channel", "is_fd", "brs", "esi", "is_extended", "error", "data")


def to_ns(t: float, what: str) -> int:
    """Simulation time in s to ns (must be finite and >= 0)."""
    t = float(t)
    if not math.isfinite(t) or t < 0:
        raise ValueError(f"{what}: time {t!r} s cannot be a log time (needs a finite time >= 0)")
    return int(round(t * 1e9))


def interruption(exc: BaseException) -> str:
    """How a run's end record names the exception that stopped it: ``Type: message`` or ``Type``."""
    return f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__


def _check_times(t: np.ndarray, last: float, topic: str) -> None:
    if t.ndim != 1:
        raise ValueError(f"{topic}: time must be a 1-D array, got shape {t.shape}")
    if t.size and (t[0] < last or np.any(np.diff(t) < 0)):
        raise ValueError(f"{topic}: times must be non-decreasing across writes (got {t[0]!r} s after {last!r} s)")


class _Block:
    """Accumulates samples of one bulk channel until a block is full."""

    def __init__(self, channel_id: int, fields: tuple[str, ...]):
        self.channel_id = channel_id
        self.fields = fields
        self.parts: list[tuple[np.ndarray, dict[str, np.ndarray]]] = []
        self.count = 0
        self.last_t = -math.inf

    def append(self, t: np.ndarray, signals: dict[str, np.ndarray]) -> None:
        self.parts.append((t, signals))
        self.count += t.size
        self.last_t = float(t[-1])

    def take(self, size: int, final: bool) -> Iterable[tuple[np.ndarray, dict[str, np.ndarray]]]:
        """Yield full blocks of ``size`` samples (and the remainder if ``final``)."""
        if self.count < size and not (final and self.count):
            return
        t = np.concatenate([p[0] for p in self.parts])
        sig = {f: np.concatenate([p[1][f] for p in self.parts]) for f in self.fields}
        stop = t.size if final else t.size - t.size % size
        for i in range(0, stop, size):
            yield t[i:i + size], {f: v[i:i + size] for f, v in sig.items()}
        self.parts = [(t[stop:], {f: v[stop:] for f, v in sig.items()})] if stop < t.size else []
        self.count = t.size - stop


def _hex_payloads(data: np.ndarray, dlc: np.ndarray) -> np.ndarray:
    """Each frame's first ``dlc`` payload bytes (rows of ``data``, uint8) as lower-case hex text (a str array)."""
    n, width = data.shape
    if not width:
        return np.full(n, "")
    out = np.frombuffer(data.tobytes().hex().encode("ascii"), dtype=f"S{2 * width}").astype(f"U{2 * width}")
    for d in np.unique(dlc[dlc < width]).tolist():     # per payload length, not per frame: a shorter string type
        rows = dlc == d                                 # keeps each row's first 2·d characters
        out[rows] = out[rows].astype(f"U{2 * d}") if d else ""
    return out


class Recorder:
    """Write one rig run to an MCAP file.

    path: output file. scene_text: the scene TOML (stored as attachment ``scene.toml``).
    metadata: extra key/values stored with the software version in metadata record ``rig``.
    programs: device program configs ``{number: dict}`` (attachments ``device/program/<n>.json``).
    block_size: samples per bulk message. encoding: ``"json"`` (plottable) or ``"base64"`` (fast).
    compression: ``"zstd"``, ``"lz4"`` or ``"none"`` (chunk compression). chunk_size: bytes per MCAP chunk
    (4 MiB: the writer holds one index record per chunk until it closes, ~0.15 MB per 1000 demo cycles).
    wall_clock_start: ns since 1970 that simulation time 0 maps to in log times (default: now).
    view_rate: Hz of the view channels ``/view/plant`` (truth) and ``/view/device`` (curves); None: none.
    units: the signals' SI units for the channels' schema descriptions ("phi, rad"), by topic and signal name; the
    topic ``""`` holds those of any topic (a view channel takes its source's: ``/view/plant`` those of
    ``/plant/truth``, ``/view/device`` those of ``/device/curve``).
    """

    def __init__(self, path: str | Path, scene_text: str | None = None,
                 metadata: Mapping[str, Any] | None = None, programs: Mapping[int, Mapping] | None = None,
                 block_size: int = 1000, encoding: str = "json", compression: str = "zstd",
                 chunk_size: int = 4 << 20, wall_clock_start: int | None = None, view_rate: float | None = 100.0,
                 units: Mapping[str, Mapping[str, str]] | None = None):
        if encoding not in ENCODINGS:
            raise ValueError(f"Recorder: unknown encoding {encoding!r} (use one of {ENCODINGS})")
        if compression not in COMPRESSIONS:
            raise ValueError(f"Recorder: unknown compression {compression!r} (use one of {sorted(COMPRESSIONS)})")
        if int(block_size) < 1:
            raise ValueError(f"Recorder: block_size must be >= 1, got {block_size}")
        start = time.time_ns() if wall_clock_start is None else wall_clock_start
        if not isinstance(start, (int, np.integer)) or start < 0:
            raise ValueError(f"Recorder: wall_clock_start must be ns since 1970 as an int >= 0, got {start!r}")
        self._views = {topic: Decimator(view_rate) for topic in S.VIEWS} if view_rate is not None else {}
        self.path = Path(path)
        self.encoding = encoding
        self.block_size = int(block_size)
        self.wall_clock_start = int(start)
        self.messages = 0                     # messages written so far
        self.curves = 0                       # of them /device/curve messages: curves recorded
        self._file = open(self.path, "wb")
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=COMPRESSIONS[compression],
                              enable_data_crcs=True)
        self._writer.start(profile="", library=f"mechrig/{rig.__version__}")
        self._units = {topic: dict(u) for topic, u in (units or {}).items()}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}     # per channel: the last message's sequence number (1, 2, …)
        self._blocks: dict[str, _Block] = {}
        self._can: dict[str, list[np.ndarray]] = {c: [] for c in CAN_COLUMNS}   # buffered frames: column chunks
        self._can_frames = 0                       # frames buffered
        self._can_last = -math.inf
        self._last_ns = self.wall_clock_start      # latest log time written
        self.last_event_time = 0.0                  # s: the latest event's simulation time
        self._event_ns = 0                          # ns: the latest event's log time (less the wall-clock start)
        self._data_end = 0.0                       # latest sample time written in any block, curve or frame (s)
        self._closed = False
        self.held: list[Callable[[], None]] = []    # called first on close: producers write what they still hold
        meta = {"software_version": rig.__version__, "mcap_version": mcap.__version__,
                "python": platform.python_version(), "encoding": encoding,
                "time": "log time = wall_clock_start + simulation time, ns; messages carry simulation time t, s",
                "wall_clock_start": str(self.wall_clock_start), "view_rate": json.dumps(view_rate)}
        for key, value in (metadata or {}).items():
            meta[str(key)] = value if isinstance(value, str) else json.dumps(value)
        self._writer.add_metadata(S.RIG_METADATA, meta)
        if scene_text is not None:
            self._writer.add_attachment(self._last_ns, self._last_ns, S.SCENE_ATTACHMENT, "application/toml",
                                        scene_text.encode())
        for number, config in (programs or {}).items():
            self.write_program(number, config)

    # -- context manager -------------------------------------------------------------------------
    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: object) -> None:
        self.close(None if exc is None else interruption(exc))

    @property
    def simulation_time(self) -> float:
        """Latest simulation time written (s): of a message's log time, or of a sample inside a block (a block is
        logged at its first sample)."""
        return max((self._last_ns - self.wall_clock_start) / 1e9, self._data_end)

    def close(self, interrupted: str | None = None) -> None:
        """Flush buffered blocks, record the end and finish the file (idempotent). ``interrupted``: why the
        run stopped early (an ``interrupted`` event and ``rig.end`` complete=false); None: a normal end."""
        if self._closed:
            return
        try:
            for hold in self.held:           # what a producer holds back (a host's events not yet in time order)
                hold()
            for topic in list(self._blocks):
                self._flush(topic, final=True)
            self._flush_can(final=True)
            if interrupted is not None:
                self.write_event(self.simulation_time, "interrupted", reason=interrupted)
        finally:
            self._closed = True
            try:
                self._writer.add_metadata(S.END_METADATA, {
                    "complete": "false" if interrupted is not None else "true", "reason": interrupted or "",
                    "simulation_time": repr(self.simulation_time), "messages": str(self.messages)})
                self._writer.finish()
            finally:
                self._file.close()

    # -- channels --------------------------------------------------------------------------------
    def _channel(self, topic: str, schema: dict | Callable[[], dict], name: str,
                 meta: Mapping[str, str] | None = None) -> int:
        """The channel id of ``topic``, registered on its first message with ``schema`` (or what a callable gives:
        built once, not for every message)."""
        if topic not in self._channels:
            schema = schema() if callable(schema) else schema
            sid = self._writer.register_schema(name=name, encoding="jsonschema", data=S.schema_bytes(schema))
            self._channels[topic] = self._writer.register_channel(
                topic=topic, message_encoding="json", schema_id=sid, metadata=dict(meta or {}))
        return self._channels[topic]

    def _units_of(self, topic: str) -> dict[str, str]:
        """The SI units of ``topic``'s signals by name (those of any topic, then its own; a view its source's)."""
        source = {S.VIEW_PLANT: S.TRUTH, S.VIEW_DEVICE: S.CURVE}.get(topic, topic)
        return {**self._units.get("", {}), **self._units.get(source, {})}

    def _put(self, channel_id: int, t_ns: int, data: bytes) -> None:
        """Write one message at simulation time ``t_ns`` (ns)."""
        if self._closed:
            raise RuntimeError(f"Recorder {self.path}: write after close")
        log_ns = self.wall_clock_start + t_ns
        sequence = self._sequence[channel_id] = self._sequence.get(channel_id, 0) + 1   # gaps visible to any reader
        self._writer.add_message(channel_id=channel_id, log_time=log_ns, data=data, publish_time=log_ns,
                                 sequence=sequence)
        self._last_ns = max(self._last_ns, log_ns)
        self.messages += 1

    def _time_ns(self, t: float | None, what: str) -> int:
        return self._last_ns - self.wall_clock_start if t is None else to_ns(t, what)

    # -- bulk blocks -----------------------------------------------------------------------------
    def write_block(self, topic: str, t: np.ndarray, signals: Mapping[str, np.ndarray]) -> None:
        """Append samples to bulk channel ``topic`` (t in s, non-decreasing; signals SI, same length).

        The first write fixes the channel's signal names; later writes must give the same names.
        """
        if self._closed:
            raise RuntimeError(f"Recorder {self.path}: write after close")
        if not topic.startswith("/"):
            raise ValueError(f"topic {topic!r} must start with '/'")
        t = np.asarray(t, dtype=np.float64)
        sig = {str(k): np.asarray(v, dtype=np.float64) for k, v in signals.items()}
        reserved = {"t", NULLS} & set(sig)
        if reserved:
            raise ValueError(f"{topic}: a signal may not be called {sorted(reserved)[0]!r} (reserved: 't' is the "
                             f"time, {NULLS!r} lists undefined values)")
        for name, v in sig.items():
            if v.shape != t.shape:
                raise ValueError(f"{topic}: signal {name!r} has shape {v.shape}, time has {t.shape}")
        block = self._blocks.get(topic)
        if block is None:
            schema = S.block_schema(f"rig.Block{topic}", sig, self.encoding, self._units_of(topic))
            cid = self._channel(topic, schema, f"rig.Block{topic}",
                                {"encoding": self.encoding, "time_unit": "s"})
            block = self._blocks[topic] = _Block(cid, tuple(sig))
        elif set(sig) != set(block.fields):
            raise ValueError(f"{topic}: signals {sorted(sig)} differ from the channel's {sorted(block.fields)}")
        _check_times(t, block.last_t, topic)
        if t.size == 0:
            return
        to_ns(t[0], topic)
        self._data_end = max(self._data_end, float(t[-1]))
        block.append(t, sig)
        self._flush(topic, final=False)

    def _flush(self, topic: str, final: bool) -> None:
        block = self._blocks[topic]
        for t, sig in block.take(self.block_size, final):
            self._put(block.channel_id, to_ns(t[0], topic), encode_block(t, sig, self.encoding))

    def _view(self, topic: str, t: np.ndarray, signals: Mapping[str, np.ndarray], description: str) -> None:
        """One message per sample kept by the topic's decimator (``view_rate``): ``{"t": s, signal: value}``."""
        decimator = self._views.get(topic)
        if decimator is None:
            return
        cid = self._channel(topic, lambda: S.view_schema(f"rig.View{topic}", signals, description,
                                                         self._units_of(topic)), f"rig.View{topic}",
                            {"rate_hz": repr(decimator.rate), "time_unit": "s"})
        keep = decimator.pick(t)
        if not keep.size:
            return
        columns = {"t": t[keep].tolist(), **{k: np.asarray(v, dtype=np.float64)[keep].tolist()
                                             for k, v in signals.items()}}
        for ti, message in zip(columns["t"], dumps_rows(columns)):
            self._put(cid, to_ns(ti, topic), message)

    def write_truth(self, t: np.ndarray, signals: Mapping[str, np.ndarray]) -> None:
        """Physical truth of the plant (``/plant/truth``, and decimated ``/view/plant``)."""
        self.write_block(S.TRUTH, t, signals)
        self._view(S.VIEW_PLANT, np.asarray(t, dtype=np.float64),
                   {str(k): np.asarray(v, dtype=np.float64) for k, v in signals.items()},
                   "plant truth, one sample per message (decimated /plant/truth)")

    def write_live(self, t: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
        """Live X/Y values streamed by the device (``/device/live``)."""
        self.write_block(S.LIVE, t, {"x": x, "y": y})

    # -- CAN ------------------------------------------------------------------------------------
    def write_can_frames(self, frames: FrameBlock | Iterable[Any], channel: str = "") -> None:
        """Raw CAN frames on ``channel`` (``/can/raw``): a :class:`rig.blockbus.FrameBlock`, python-can
        ``Message`` objects or ``(t, id, data, is_fd)`` tuples. Direction from the RX flag (``rx`` when set,
        ``tx``: sent by the host); flags FD, BRS, ESI, EXTENDED, ERROR as columns; every frame on ``channel`` (a
        message's own ``channel`` is not read). An id that does not fit its format, or a remote (RTR) frame (the
        schema has no RTR flag; the rig's links carry none), is a ValueError naming the frame: nothing of the call
        is written."""
        if not isinstance(frames, FrameBlock):
            frames = frames_of(f if hasattr(f, "arbitration_id") else can.Message(
                timestamp=float(f[0]), arbitration_id=int(f[1]), data=bytes(f[2]), is_fd=bool(f[3]),
                is_extended_id=int(f[1]) > 0x7FF, check=False) for f in frames)
        flags = frames.flags
        for problem, rows in (("id out of range (11-bit standard, 29-bit extended)",
                               ids_out_of_range(frames.arbitration_id, (flags & EXTENDED) != 0)),
                              ("a remote (RTR) frame, which /can/raw cannot hold", (flags & REMOTE) != 0)):
            if rows.any():
                k = int(np.flatnonzero(rows)[0])
                raise ValueError(f"{S.CAN_RAW}: frame {k} of {len(frames)} at t = {frames.timestamp[k]} s, id "
                                 f"0x{int(frames.arbitration_id[k]):X}: {problem}; none of these frames is written")
        t = frames.timestamp.astype(float)
        if t.size:
            late = np.flatnonzero(np.diff(np.concatenate([[self._can_last], t])) < 0)
            if late.size:
                k = int(late[0])
                raise ValueError(f"{S.CAN_RAW}: frame time {t[k]} s is before the previous frame "
                                 f"({self._can_last if k == 0 else t[k - 1]} s)")
            for k in np.flatnonzero(~np.isfinite(t) | (t < 0))[:1]:
                to_ns(t[k], S.CAN_RAW)          # raises, naming the bad time
            self._can_last = float(t[-1])
            self._data_end = max(self._data_end, self._can_last)
        n = len(frames)
        part = {"t": t, "id": frames.arbitration_id.astype(np.int64), "dir": np.where((flags & RX) != 0, "rx", "tx"),
                "channel": np.full(n, str(channel)),
                **{name: (flags & bit) != 0 for name, bit in (("is_fd", FD), ("brs", BRS), ("esi", ESI),
                                                              ("is_extended", EXTENDED), ("error", ERROR))},
                "data": _hex_payloads(frames.data, frames.dlc)}
        for name, col in part.items():
            self._can[name].append(col)
        self._can_frames += n
        self._flush_can(final=False)

    def _flush_can(self, final: bool) -> None:
        """Write the buffered frames in messages of ``block_size`` frames (``final``: the rest too)."""
        size = self._can_frames
        if not size:
            return
        cid = self._channel(S.CAN_RAW, S.CAN_SCHEMA, "rig.CanFrames")      # registered with the first frames
        if size < self.block_size and not final:
            return
        cols = {name: np.concatenate(chunks) for name, chunks in self._can.items()}
        start = 0
        while size - start >= self.block_size or (final and start < size):
            block = {name: col[start:start + self.block_size] for name, col in cols.items()}
            for name in ("dir", "channel", "data"):
                block[name] = block[name].tolist()
            self._put(cid, to_ns(block["t"][0], S.CAN_RAW), dumps_message(block))
            start += block["t"].size
        self._can = {name: [col[start:]] for name, col in cols.items()}
        self._can_frames = size - start

    # -- device ---------------------------------------------------------------------------------
    def write_curve(self, number: int, program: int, t: np.ndarray, x: np.ndarray, y: np.ndarray,
                    theory: Mapping[str, np.ndarray] | None = None, angle: np.ndarray | None = None,
                    **extra: Any) -> None:
        """One measured curve (``/device/curve``, and decimated ``/view/device``), log time = its last sample: when the
        unit has the whole curve (a viewer's X–Y panel then shows, as the instrument does, the last complete curve).

        theory: arrays of the theoretical curve (keys ``t``, ``x``, ``y``, ``angle``; without ``t`` it
        shares the curve's times). angle: measured cam angle per sample, rad. extra: JSON scalars/lists.
        """
        t = np.asarray(t, dtype=np.float64)
        arrays = {"t": t, "x": x, "y": y}
        if angle is not None:
            arrays["angle"] = angle
        if t.ndim != 1 or t.size == 0:
            raise ValueError(f"{S.CURVE}: curve {number} needs a non-empty 1-D time array, got shape {t.shape}")
        for name, v in arrays.items():
            if np.shape(v) != t.shape:
                raise ValueError(f"{S.CURVE}: curve {number} array {name!r} has shape {np.shape(v)}, t has {t.shape}")
        clash = set(extra) & {"number", "program", "theory", *arrays}
        if clash:
            raise ValueError(f"{S.CURVE}: extra fields {sorted(clash)} clash with curve fields")
        msg: dict[str, Any] = {"number": int(number), "program": int(program)}
        msg.update({k: encode_array(v, self.encoding) for k, v in arrays.items()})
        if theory is not None:
            msg["theory"] = {str(k): encode_array(v, self.encoding) for k, v in theory.items()}
        msg.update(extra)
        cid = self._channel(S.CURVE, lambda: S.curve_schema(self.encoding, self._units_of(S.CURVE)), "rig.Curve",
                            {"encoding": self.encoding})
        self._put(cid, to_ns(t[-1], f"{S.CURVE} curve {number}"), dumps_message(msg))
        self.curves += 1
        self._data_end = max(self._data_end, float(t[-1]))
        self._view(S.VIEW_DEVICE, t, {"x": np.asarray(x, dtype=np.float64), "y": np.asarray(y, dtype=np.float64)},
                   "measured curves' X and Y, one sample per message (decimated /device/curve)")

    def write_result(self, result: Mapping[str, Any], t: float | None = None) -> None:
        """Per-curve result with process values (``/device/result``), e.g. ``CurveResult.to_dict()``.

        t: log time in s; default the result's ``"t"`` key or else the latest time written.
        """
        if "ok" not in result:
            raise ValueError(f"{S.RESULT}: result has no 'ok' key (keys: {sorted(result)})")
        when = t if t is not None else result.get("t")
        cid = self._channel(S.RESULT, lambda: S.result_schema(self._units_of(S.CURVE)), "rig.CurveResult")
        self._put(cid, self._time_ns(when, S.RESULT), dumps_message(result))

    def write_statistics(self, stats: Mapping[str, Any], t: float | None = None) -> None:
        """Statistics snapshot of the device (``/device/statistics``); t default = latest time written."""
        cid = self._channel(S.STATISTICS, lambda: S.statistics_schema(self._units_of(S.CURVE)),
                            "rig.DeviceStatistics")
        self._put(cid, self._time_ns(t, S.STATISTICS), dumps_message(stats))

    def write_event(self, t: float, kind: str, **data: Any) -> None:
        """An event (``/events``, and as ``foxglove.Log`` on ``/log``): flank switch, fault, sequence gap,
        disengagement, ..."""
        if not kind:
            raise ValueError(f"{S.EVENTS}: event kind must be a non-empty string")
        if {"t", "kind"} & set(data):
            raise ValueError(f"{S.EVENTS}: event data may not use the keys 't' or 'kind'")
        t_ns = to_ns(t, f"{S.EVENTS} {kind}")
        # events come from several clocks (plant, bus, device) and are found in the order the host polls them: one
        # found after a later one is logged at that one's log time (the channel stays in order), its t exact
        log_ns = max(t_ns, self._event_ns)
        self._event_ns = log_ns
        self.last_event_time = max(self.last_event_time, float(t))
        self._put(self._channel(S.EVENTS, S.EVENT_SCHEMA, "rig.Event"), log_ns,
                  dumps_message({"t": float(t), "kind": str(kind), **data}))
        self._put(self._channel(S.LOG, S.LOG_SCHEMA, "foxglove.Log"), log_ns,
                  dumps_message(log_message(self.wall_clock_start + t_ns, float(t), str(kind), data)))

    def write_program(self, number: int, config: Mapping[str, Any]) -> None:
        """Store a device program configuration (elements, limits) as a JSON attachment."""
        if self._closed:
            raise RuntimeError(f"Recorder {self.path}: write after close")
        name = S.PROGRAM_ATTACHMENT.format(number=int(number))
        self._writer.add_attachment(self._last_ns, self._last_ns, name, "application/json", dumps(config))

"""The acquisition unit as a CAN node: frames from ``data/can/rig.dbc`` on any python-can bus.

The node owns a transmit queue and a virtual bus clock. Publishing only queues frames;
:meth:`CanNode.advance_to` puts on the wire what fits up to a virtual time, frame by frame, each
taking its exact wire time (:mod:`firmware_sim.can_budget`), lowest identifier first among the
frames ready when the bus becomes free (CAN arbitration). ``msg.timestamp`` is the virtual time at
the end of the frame (the receiving bus keeps it if it preserves timestamps, e.g. python-can's
``virtual`` interface with ``preserve_timestamps=True``).

Live data gets at most ``live_share`` of the bus time of each chunk: a chunk is decimated by an
integer factor to fit, and live frames still queued ``live_max_age`` seconds after their last
sample are stale and dropped; every dropped pair is counted (:attr:`CanNode.live_dropped`, sent in
the ``StatusCounters`` frame). Curves (after each measurement) go out in blocks at whatever rate
the bus leaves them.
"""
from __future__ import annotations

import binascii
import copy
import heapq
import itertools
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Sequence

import can
import cantools
import numpy as np

from firmware_sim.can_budget import BusTiming

DBC_PATH = Path(__file__).resolve().parents[1] / "data" / "can" / "rig.dbc"

X_LSB = 1e-6                     # m per count of every X signal (20-bit signed)
Y_LSB = 0.005                    # N per count of every Y / force signal (20-bit signed)
RAW20 = (-(1 << 19), (1 << 19) - 1)
FD_PAIRS = 11                    # pairs per 64-byte FD frame
TICK = 1e-4                      # s per count of the 16-bit Tick signals
T_START_LSB, DT_LSB, T_OFFSET_LSB = 1e-6, 1e-9, 1e-5   # s per count: curve start, uniform step, offsets
CURVE_TIME_TOL = 5e-6            # s: a curve is sent as uniformly sampled if that reproduces its times
NO_FAIL = 127
COMMANDS = {1: "start", 2: "stop", 3: "select_program", 4: "tare", 5: "reset_statistics", 6: "identify"}
TARE_CHANNELS = {0: "x", 1: "y", 2: "y2", 3: None}
STATES = {"idle": 0, "measuring": 1, "armed": 2}
UNKNOWN_STATE = 15
PROCESS_VALUES = {"XMax": "x_max", "XMin": "x_min", "YMax": "y_max", "YMin": "y_min", "XAtYMax": "x_at_y_max",
                  "YAtXMax": "y_at_x_max", "XEnd": "x_end", "YEnd": "y_end", "Duration": "duration"}


def quantise(values: np.ndarray, lsb: float) -> tuple[np.ndarray, int]:
    """Raw 20-bit counts of ``values`` (SI) and how many had to be clipped to the signal range."""
    raw = np.rint(np.asarray(values, dtype=float) / lsb)
    clipped = int(np.count_nonzero((raw < RAW20[0]) | (raw > RAW20[1])))
    return np.clip(raw, *RAW20).astype(np.int64), clipped


def curve_crc(raw_x: np.ndarray, raw_y: np.ndarray) -> int:
    """CRC-16/CCITT-FALSE over the raw pairs as little-endian int32 (X then Y of each pair)."""
    pairs = np.column_stack([raw_x, raw_y]).astype("<i4")
    return binascii.crc_hqx(pairs.tobytes(), 0xFFFF)


def _fd_pairs(raw_x: np.ndarray, raw_y: np.ndarray) -> dict[str, np.ndarray]:
    """Columns X0..X10, Y0..Y10 of the FD frames carrying these raw pairs, 11 per frame (unused: 0)."""
    frames = -(-raw_x.size // FD_PAIRS)
    grid = np.zeros((2, frames * FD_PAIRS), dtype=np.int64)
    grid[0, :raw_x.size], grid[1, :raw_y.size] = raw_x, raw_y
    grid = grid.reshape(2, frames, FD_PAIRS)
    return {f"{axis}{k}": grid[a, :, k] for a, axis in enumerate("XY") for k in range(FD_PAIRS)}


class _Packing:
    """Packs rows of raw signal values into payloads of one DBC message with numpy: the same bytes as
    cantools' ``encode`` for little-endian integer signals, classic or FD (checked in the tests). The hot
    path of curve and live transfer, where per-frame cantools calls dominated the run time."""

    def __init__(self, message: Any) -> None:
        signals = message.signals
        if message.is_multiplexed() or any(s.byte_order != "little_endian" or s.is_float or s.length >= 64
                                           or s.start % 8 + s.length > 64 for s in signals):
            raise ValueError(f"{message.name}: packed encoding supports little-endian integer signals only")
        self.message = message
        self.names = tuple(s.name for s in signals)
        col = lambda values, dtype: np.array(values, dtype=dtype)[:, None]
        self.lo = col([-(1 << (s.length - 1)) if s.is_signed else 0 for s in signals], np.int64)
        self.hi = col([(1 << (s.length - 1 if s.is_signed else s.length)) - 1 for s in signals], np.int64)
        self.mask = col([(1 << s.length) - 1 for s in signals], np.uint64)
        self.shift = col([s.start % 8 for s in signals], np.uint64)
        first = np.array([s.start // 8 for s in signals])
        self.groups = [(int(b), np.flatnonzero(first == b)) for b in np.unique(first)]

    def pack(self, columns: dict[str, np.ndarray], n: int) -> bytes:
        """Payloads of ``n`` frames, concatenated; signals missing from ``columns`` are 0."""
        raw = np.zeros((len(self.names), n), dtype=np.int64)
        for i, name in enumerate(self.names):
            if name in columns:
                raw[i] = columns[name]
        bad = (raw < self.lo) | (raw > self.hi)
        if bad.any():
            i = int(np.argmax(bad.any(axis=1)))
            raise ValueError(f"{self.message.name}.{self.names[i]}: raw value outside {self.lo[i, 0]}..{self.hi[i, 0]}")
        words = (raw.view(np.uint64) & self.mask) << self.shift
        length = self.message.length
        payload = np.zeros((n, length + 8), dtype=np.uint8)
        for first, rows in self.groups:
            word = np.bitwise_or.reduce(words[rows], axis=0).astype("<u8")
            payload[:, first:first + 8] |= word.view(np.uint8).reshape(n, 8)
        return payload[:, :length].tobytes()


#: frames of one measurement's transfer: they leave one transmit FIFO in order, at the header's priority,
#: so a later curve never overtakes an earlier one (live data and status still win arbitration)
TRANSFER_FRAMES = frozenset({"CurveHeader", "CurveTiming", "CurveTimes", "CurveBlock", "CurveBlockFD", "CurveEnd",
                             "Result", "ResultValue"})


@dataclass(slots=True)
class _Pending:
    key: tuple                       # (priority, enqueue order): CAN arbitration order (see TRANSFER_FRAMES)
    ready: float                     # virtual time from which the frame may be sent (s)
    data: bytearray                  # payload; byte 0 (Seq) is filled in at transmission
    is_fd: bool
    expires: float | None = None     # live frames: dropped if still queued after this time
    pairs: int = 0                   # live pairs carried (for the dropped count)
    curve_end: bool = False
    frame_id: int = 0
    rank: int = 0                    # key as one integer (faster heap comparisons): priority << 40 | order
    duration: float = 0.0            # wire time (s) if known when queued (worst-case stuffing), else 0


class _Frame(can.Message):
    """A sent frame. python-can's ``virtual`` bus deep-copies every frame for each receiver; this copy
    builds the plain :class:`can.Message` directly instead of going through :mod:`copy`'s generic
    machinery for the payload (the same frame arrives, at a third of the cost)."""

    __slots__ = ()

    def __deepcopy__(self, memo: dict | None) -> can.Message:
        return can.Message(timestamp=self.timestamp, arbitration_id=self.arbitration_id,
                           is_extended_id=self.is_extended_id, is_remote_frame=self.is_remote_frame,
                           is_error_frame=self.is_error_frame,
                           channel=self.channel if isinstance(self.channel, (str, int, type(None)))
                           else copy.deepcopy(self.channel, memo),
                           dlc=self.dlc, data=bytearray(self.data), is_fd=self.is_fd, is_rx=self.is_rx,
                           bitrate_switch=self.bitrate_switch, error_state_indicator=self.error_state_indicator)


class CanNode:
    """DigiForce-style device on a python-can bus, with a bit budget in virtual time.

    ``device`` provides ``select_program, start, stop, tare, reset_statistics, identify, status,
    last_result`` (see ``firmware_sim.digiforce``). ``bitrate`` (bit/s) is the nominal bitrate;
    ``fd=True`` sends live data and curve blocks in 64-byte CAN FD frames, with the data phase at
    ``data_bitrate`` (bit/s, bitrate switch) if given.
    """

    def __init__(self, bus: can.BusABC, device: Any, bitrate: float = 500_000, fd: bool = False,
                 data_bitrate: float | None = None, *, stuffing: str = "worst", live_share: float = 0.5,
                 live_max_age: float = 0.05, heartbeat_period: float = 0.1, t0: float = 0.0,
                 dbc_path: str | Path = DBC_PATH) -> None:
        if not 0.0 < live_share <= 1.0:
            raise ValueError(f"live_share must be in (0, 1], got {live_share}")
        if not heartbeat_period > 0 or not live_max_age > 0:
            raise ValueError("heartbeat_period and live_max_age must be positive (s)")
        self.bus, self.device = bus, device
        self.timing = BusTiming(float(bitrate), fd, None if data_bitrate is None else float(data_bitrate), stuffing)
        self._plan = replace(self.timing, stuffing="worst")
        self.db = cantools.database.load_file(str(dbc_path))
        self._msg = {m.name: m for m in self.db.messages}
        for m in self.db.messages:
            if "DEVICE" in m.senders and not any(s.name == "Seq" and s.start == 0 and s.length == 8 for s in m.signals):
                raise ValueError(f"{dbc_path}: device frame {m.name} must start with the 8-bit Seq counter")
        self.live_share, self.live_max_age, self.heartbeat_period = live_share, live_max_age, heartbeat_period
        self.now = float(t0)             # device time of the last advance_to (s)
        self.bus_free = float(t0)        # virtual time at which the bus is next idle (s)
        self._next_heartbeat = float(t0)
        self._queue: list[tuple[int, _Pending]] = []   # ready frames as (rank, frame), in arbitration order
        self._waiting: list[tuple[float, int, _Pending]] = []   # not yet ready, by ready time
        self._order = itertools.count()
        self._seq: dict[int, int] = {}
        self._packing: dict[str, _Packing] = {}
        self._wire_time: dict[tuple[int, int, bool], float] = {}   # worst-case stuffing: per (id, length, fd)
        self._curve_ends = 0             # queued Result frames (curves whose transfer has not finished)
        self._published_result: Any = None
        self.live_dropped = 0            # live pairs not sent (decimated or stale)
        self.live_sent = 0
        self.clipped = 0                 # values saturated to the signal range
        self.frames_sent = 0
        self.busy_time = 0.0             # total wire time of sent frames (s)
        self.rx_errors: list[str] = []   # malformed or unexpected frames received
        self.curves_measured = 0

    # ------------------------------------------------------------------ queueing
    def _enqueue(self, name: str, signals: dict[str, Any], ready: float, **extra: Any) -> None:
        msg = self._msg[name]
        if "Seq" in (s.name for s in msg.signals):
            signals = {"Seq": 0, **signals}
        data = bytearray(msg.encode(signals, scaling=False, padding=False, strict=False))  # ranges: see quantise()
        priority = self._msg["CurveHeader"].frame_id if name in TRANSFER_FRAMES else msg.frame_id
        order = next(self._order)
        item = _Pending((priority, order), float(ready), data, msg.is_fd, frame_id=msg.frame_id,
                        rank=priority << 40 | order, duration=self._planned_duration(msg.frame_id, len(data), msg.is_fd),
                        **extra)
        self._curve_ends += item.curve_end
        heapq.heappush(self._waiting, (item.ready, item.key[1], item))

    def _enqueue_rows(self, name: str, columns: dict[str, np.ndarray], ready: np.ndarray,
                      expires: np.ndarray | None = None, pairs: int | np.ndarray = 0) -> None:
        """Queue one frame per row of ``columns`` (raw integer signal values; missing ones are 0), packed
        with numpy (:class:`_Packing`); ``pairs``: live pairs carried, per frame or for all."""
        msg = self._msg[name]
        packing = self._packing.get(name)
        if packing is None:
            packing = self._packing[name] = _Packing(msg)
        n, length = len(ready), msg.length
        data = packing.pack(columns, n)
        priority = self._msg["CurveHeader"].frame_id if name in TRANSFER_FRAMES else msg.frame_id
        fid, fd, waiting, push = msg.frame_id, msg.is_fd, self._waiting, heapq.heappush
        duration = self._planned_duration(fid, length, fd)
        for i, at, until, carried, order in zip(
                range(0, length * n, length), np.asarray(ready, dtype=float).tolist(),
                itertools.repeat(None) if expires is None else np.asarray(expires, dtype=float).tolist(),
                np.broadcast_to(np.asarray(pairs, dtype=np.int64), (n,)).tolist(), self._order):
            push(waiting, (at, order, _Pending((priority, order), at, bytearray(data[i:i + length]), fd, until,
                                               carried, False, fid, priority << 40 | order, duration)))

    def frame_time_planned(self, name: str) -> float:
        """Worst-case wire time (s) of one frame of DBC message ``name`` on this bus."""
        msg = self._msg[name]
        return self._plan.frame_time(msg.frame_id, bytes(msg.length), msg.is_fd)

    @property
    def pending_frames(self) -> int:
        """Frames queued and not yet on the wire."""
        return len(self._queue) + len(self._waiting)

    def has_pending_before(self, t: float) -> bool:
        """Whether any frame queued for sending at or before time ``t`` (s) is not yet on the wire."""
        return any(item.ready <= t for _, item in self._queue) or bool(self._waiting and self._waiting[0][0] <= t)

    @property
    def curves_pending(self) -> int:
        """Curves whose transfer has not finished."""
        return self._curve_ends

    def counters(self) -> dict[str, float]:
        """What the node did: live pairs sent/dropped, clipped values, frames, bus load so far."""
        return {"live_sent": self.live_sent, "live_dropped": self.live_dropped, "clipped": self.clipped,
                "frames_sent": self.frames_sent, "busy_time": self.busy_time,
                "bus_load": self.busy_time / self.now if self.now > 0 else 0.0,
                "pending_frames": self.pending_frames, "rx_errors": len(self.rx_errors)}

    # ------------------------------------------------------------------ publishing
    def publish_live(self, t: np.ndarray, x: np.ndarray, y: np.ndarray) -> int:
        """Queue live pairs sampled at uniformly spaced times ``t`` (s); X in m, Y in N.

        The chunk is decimated by the smallest integer factor that fits ``live_share`` of the bus
        time of the chunk; returns that factor. Pairs not sent are added to :attr:`live_dropped`.
        """
        t, x, y = (np.asarray(a, dtype=float) for a in (t, x, y))
        if t.ndim != 1 or t.size < 2 or x.shape != t.shape or y.shape != t.shape:
            raise ValueError(f"publish_live needs equal-length 1-D t, x, y with >= 2 samples, got {t.shape}, {x.shape}, {y.shape}")
        dt = (t[-1] - t[0]) / (t.size - 1)
        if not dt > 0 or not np.allclose(np.diff(t), dt, rtol=1e-6, atol=1e-12):
            raise ValueError("publish_live needs strictly increasing, uniformly spaced sample times")
        name, per_frame = ("LiveXYFD", FD_PAIRS) if self.timing.fd else ("LiveXY", 1)
        fits = int(self.live_share * t.size * dt / self.frame_time_planned(name)) * per_frame
        if fits == 0:
            self.live_dropped += t.size
            return t.size
        factor = -(-t.size // fits)
        keep = slice(None, None, factor)
        tk, (rx, cx), (ry, cy) = t[keep], quantise(x[keep], X_LSB), quantise(y[keep], Y_LSB)
        self.clipped += cx + cy
        self.live_dropped += t.size - tk.size
        ticks = np.rint(tk / TICK).astype(np.int64) % 65536
        if not self.timing.fd:
            self._enqueue_rows(name, {"Tick": ticks, "X": rx, "Y": ry}, tk, tk + self.live_max_age, pairs=1)
            return factor
        first = np.arange(0, tk.size, per_frame)
        last = np.minimum(first + per_frame, tk.size) - 1
        self._enqueue_rows(name, {"Tick": ticks[first], "Dt": np.full(first.size, int(round(factor * dt / 1e-6))),
                                  "NPairs": last - first + 1, **_fd_pairs(rx, ry)}, tk[last],
                           tk[last] + self.live_max_age, pairs=last - first + 1)
        return factor

    def publish_measurement(self, t: float, result: Any) -> None:
        """Queue curve (header, blocks, end) and result frames of one measurement at time ``t`` (s).

        :meth:`advance_to` calls this for a new ``device.last_result`` not yet published this way."""
        ct, cx, cy = (np.asarray(a, dtype=float) for a in (result.curve.t, result.curve.x, result.curve.y))
        if cx.shape != cy.shape or ct.shape != cx.shape or cx.ndim != 1 or not 0 < cx.size < 65536:
            raise ValueError(f"curve of result {result.number}: t, x, y must be 1-D, equal length, 1..65535 pairs")
        number = int(result.number) % 65536
        (rx, kx), (ry, ky) = quantise(cx, X_LSB), quantise(cy, Y_LSB)
        self.clipped += kx + ky
        self.curves_measured += 1
        self._published_result = result
        self._enqueue("CurveHeader", {"CurveNo": number, "Count": cx.size, "Program": int(result.program) % 256}, t)
        self._enqueue_curve_times(number, ct, t)
        if self.timing.fd:
            blocks = -(-cx.size // FD_PAIRS)
            self._enqueue_rows("CurveBlockFD", {"CurveNo": np.full(blocks, number % 256), "Block": np.arange(blocks),
                                                "NPairs": np.minimum(cx.size - FD_PAIRS * np.arange(blocks), FD_PAIRS),
                                                **_fd_pairs(rx, ry)}, np.full(blocks, float(t)))
        else:
            if cx.size > 4096:
                raise ValueError(f"curve of result {result.number} has {cx.size} pairs; classic CAN blocks index at most 4096")
            self._enqueue_rows("CurveBlock", {"CurveNo": np.full(cx.size, number % 16), "Block": np.arange(cx.size),
                                              "X": rx, "Y": ry}, np.full(cx.size, float(t)))
        self._enqueue("CurveEnd", {"CurveNo": number, "Count": cx.size, "Crc": curve_crc(rx, ry),
                                   "Clipped": min(kx + ky, 255)}, t)
        failed = [i for i, e in enumerate(result.elements) if not e.ok]
        self._enqueue("Result", {"CurveNo": number, "Ok": int(bool(result.ok)),
                                 "FirstFail": failed[0] if failed and failed[0] < NO_FAIL else NO_FAIL,
                                 "FailMask": sum(1 << i for i in failed if i < 32)}, t, curve_end=True)
        for pv, (signal, key) in enumerate(PROCESS_VALUES.items()):
            if key in result.process_values:
                self._enqueue("ResultValue", {"CurveNo": number % 256, "Pv": pv,
                                              signal: float(result.process_values[key])}, t)

    def _enqueue_curve_times(self, number: int, ct: np.ndarray, t: float) -> None:
        """CurveTiming (start and uniform step), plus CurveTimes offsets if the sampling is not uniform."""
        start = int(round(ct[0] / T_START_LSB))
        step = int(round((ct[-1] - ct[0]) / max(ct.size - 1, 1) / DT_LSB))
        grid = start * T_START_LSB + np.arange(ct.size) * step * DT_LSB
        uniform = ct.size > 1 and 0 < step < (1 << 24) and np.max(np.abs(ct - grid)) <= CURVE_TIME_TOL
        self._enqueue("CurveTiming", {"CurveNo": number % 256, "Dt": step if uniform else 0,
                                      "TStart": start % (1 << 24)}, t)
        if uniform:
            return
        raw = np.rint((ct - start * T_START_LSB) / T_OFFSET_LSB)
        self.clipped += int(np.count_nonzero((raw < 0) | (raw >= 1 << 20)))
        raw = np.clip(raw, 0, (1 << 20) - 1).astype(np.int64)
        for b, i in enumerate(range(0, ct.size, 2)):
            self._enqueue("CurveTimes", {"CurveNo": number % 16, "Block": b, "T0": int(raw[i]),
                                         "T1": int(raw[i + 1]) if i + 1 < ct.size else 0}, t)

    def publish_encoders(self, t: float, counts: Sequence[int], edge_times: Sequence[float]) -> None:
        """Queue the latched counts and last edge times (s, device time) of encoders 1 and 2."""
        if len(counts) != 2 or len(edge_times) != 2:
            raise ValueError(f"publish_encoders needs 2 counts and 2 edge times, got {len(counts)} and {len(edge_times)}")
        for i, (count, edge) in enumerate(zip(counts, edge_times)):
            self._enqueue(f"Encoder{i + 1}", {"Count": int(count), "EdgeTime": int(round(edge / 1e-6)) % (1 << 24)}, t)

    def publish_torque(self, t: float, torque: float, brake_force: float) -> None:
        """Queue one torque (N·m) and brake force (N) reading taken at time ``t`` (s)."""
        (rt,), kt = quantise(np.array([torque]), self._msg["Torque"].get_signal_by_name("Torque").scale)
        (rb,), kb = quantise(np.array([brake_force]), Y_LSB)
        self.clipped += kt + kb
        self._enqueue("Torque", {"Tick": int(round(t / TICK)) % 65536, "Torque": int(rt), "BrakeForce": int(rb)}, t)

    def publish_static(self, t: float, angle: float, strain: float) -> None:
        """Queue one static-rig reading taken at time ``t`` (s): angle (rad) and leaf strain (m/m)."""
        msg = self._msg["StaticRig"]
        (ra,), ka = quantise(np.array([angle]), msg.get_signal_by_name("Angle").scale)
        (rs,), ks = quantise(np.array([strain]), msg.get_signal_by_name("Strain").scale)
        self.clipped += ka + ks
        self._enqueue("StaticRig", {"Tick": int(round(t / TICK)) % 65536, "Angle": int(ra), "Strain": int(rs)}, t)

    def publish_status(self, t: float) -> None:
        """Queue a heartbeat and the status counters, with the device state at time ``t`` (s)."""
        status = self.device.status()
        last = getattr(self.device, "last_result", None)
        self._enqueue("Heartbeat", {
            "State": STATES.get(status.get("state"), UNKNOWN_STATE),
            "LastOk": 2 if last is None else int(bool(last.ok)),
            "Program": int(status.get("program", 0)) % 256,
            "DeviceTime": int(round(t * 1000)) % (1 << 32),
            "Errors": min(len(status.get("errors", ())), 255)}, t)
        self._enqueue("StatusCounters", {"LiveDropped": self.live_dropped % (1 << 32),
                                         "CurveCount": self.curves_measured % 65536,
                                         "CurvesPending": min(self.curves_pending, 255)}, t)

    # ------------------------------------------------------------------ host commands
    def handle_commands(self) -> int:
        """Apply every host command waiting on the bus at the device time :attr:`now`; returns how many."""
        done = 0
        while (msg := self.bus.recv(timeout=0.0)) is not None:
            if msg.arbitration_id != self._msg["HostCommand"].frame_id or msg.is_error_frame:
                continue                     # other nodes' traffic is not for us
            if len(msg.data) != 8:
                self.rx_errors.append(f"HostCommand frame with {len(msg.data)} data bytes (expected 8)")
                continue
            cmd = self._msg["HostCommand"].decode(bytes(msg.data), decode_choices=False)
            status = self._apply(int(cmd["Cmd"]), int(cmd["Arg"]))
            self._enqueue("CommandAck", {"Cmd": cmd["Cmd"], "Arg": cmd["Arg"], "HostSeq": cmd["HostSeq"],
                                         "AckStatus": status}, self.now)
            done += 1
        return done

    def _apply(self, cmd: int, arg: int) -> int:
        """Run one command on the device: 0 done, 1 rejected by the device, 2 unknown command."""
        name = COMMANDS.get(cmd)
        if name is None:
            self.rx_errors.append(f"unknown host command {cmd}")
            return 2
        try:
            if name in ("start", "stop"):
                getattr(self.device, name)(self.now)
            elif name == "select_program":
                self.device.select_program(arg)
            elif name == "tare":
                self.device.tare(TARE_CHANNELS[arg])
            else:
                getattr(self.device, name)()
        except (ValueError, KeyError, RuntimeError) as exc:
            self.rx_errors.append(f"host command {name}({arg}) rejected: {exc}")
            return 1
        return 0

    # ------------------------------------------------------------------ the wire
    def advance_to(self, t: float) -> int:
        """Run the node up to virtual time ``t`` (s): commands, heartbeats, new results, then send
        every queued frame that is complete on the wire by ``t``. Returns the number of frames sent."""
        if t < self.now:
            raise ValueError(f"advance_to({t}) goes back in time (node is at {self.now})")
        self.now = float(t)
        self.handle_commands()
        result = getattr(self.device, "last_result", None)
        if result is not None and result is not self._published_result:
            self.publish_measurement(self.now, result)
        while self._next_heartbeat <= t:
            self.publish_status(self._next_heartbeat)
            self._next_heartbeat += self.heartbeat_period
        return self._transmit(t)

    def _planned_duration(self, frame_id: int, length: int, is_fd: bool) -> float:
        """Wire time (s) of a frame known before its payload is final: with worst-case stuffing it depends on
        id, length and format only; 0 with exact stuffing (counted from the bits at transmission)."""
        if self.timing.stuffing != "worst":
            return 0.0
        key = (frame_id, length, is_fd)
        if key not in self._wire_time:
            self._wire_time[key] = self.timing.frame_time(frame_id, bytes(length), is_fd)
        return self._wire_time[key]

    def _transmit(self, t: float) -> int:
        """Send the queued frames that are complete on the wire by ``t`` (s), in arbitration order."""
        queue, waiting, seqs, send, frame_time = self._queue, self._waiting, self._seq, self.bus.send, self.timing.frame_time
        brs = self.timing.data_bitrate is not None
        pop, push = heapq.heappop, heapq.heappush
        bus_free, busy, sent, live_sent, curve_ends, dropped = self.bus_free, 0.0, 0, 0, 0, 0
        try:
            while True:
                while waiting and waiting[0][0] <= bus_free:
                    item = pop(waiting)[2]
                    push(queue, (item.rank, item))
                if not queue:
                    if not waiting or waiting[0][0] >= t:
                        bus_free = max(bus_free, t)
                        return sent
                    bus_free = waiting[0][0]
                    continue
                item = queue[0][1]
                if item.expires is not None and bus_free > item.expires:
                    pop(queue)
                    dropped += item.pairs
                    continue
                fid = item.frame_id
                seq = seqs.get(fid, 0)
                item.data[0] = seq
                duration = item.duration or frame_time(fid, bytes(item.data), item.is_fd)
                end = bus_free + duration
                if end > t:
                    return sent
                pop(queue)
                seqs[fid] = (seq + 1) % 256
                send(_Frame(timestamp=end, arbitration_id=fid, is_extended_id=False, data=item.data, is_fd=item.is_fd,
                            bitrate_switch=item.is_fd and brs))
                bus_free = end
                busy += duration
                sent += 1
                live_sent += item.pairs
                curve_ends += item.curve_end
        finally:
            self.bus_free = bus_free
            self.busy_time += busy
            self.frames_sent += sent
            self.live_sent += live_sent
            self.live_dropped += dropped
            self._curve_ends -= curve_ends

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
import heapq
import itertools
from dataclasses import dataclass, field, replace
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


#: frames of one measurement's transfer: they leave one transmit FIFO in order, at the header's priority,
#: so a later curve never overtakes an earlier one (live data and status still win arbitration)
TRANSFER_FRAMES = frozenset({"CurveHeader", "CurveTiming", "CurveTimes", "CurveBlock", "CurveBlockFD", "CurveEnd",
                             "Result", "ResultValue"})


@dataclass(order=True)
class _Pending:
    key: tuple                       # (priority, enqueue order): CAN arbitration order (see TRANSFER_FRAMES)
    ready: float                     # virtual time from which the frame may be sent (s)
    data: bytearray                  # payload; byte 0 (Seq) is filled in at transmission
    is_fd: bool
    expires: float | None = None     # live frames: dropped if still queued after this time
    pairs: int = 0                   # live pairs carried (for the dropped count)
    curve_end: bool = False
    frame_id: int = field(default=0, compare=False)


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
        self._queue: list[tuple[tuple, _Pending]] = []   # ready frames as (key, frame), in arbitration order
        self._waiting: list[tuple[float, int, _Pending]] = []   # not yet ready, by ready time
        self._order = itertools.count()
        self._seq: dict[int, int] = {}
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
        item = _Pending((priority, next(self._order)), float(ready), data, msg.is_fd, frame_id=msg.frame_id, **extra)
        heapq.heappush(self._waiting, (item.ready, item.key[1], item))

    def _enqueue_rows(self, name: str, columns: dict[str, np.ndarray], ready: np.ndarray,
                      expires: np.ndarray | None = None, pairs: int = 0) -> None:
        """Queue one frame per row of ``columns`` (raw integer signal values), packed with numpy.

        Same bytes as cantools' ``encode`` for classic little-endian frames (checked in the tests);
        the hot path of curve and live transfer, where per-frame cantools calls dominated the run time.
        """
        msg = self._msg[name]
        if msg.is_fd or msg.length > 8 or any(sig.byte_order != "little_endian" for sig in msg.signals):
            raise ValueError(f"{name}: packed encoding supports classic little-endian frames only")
        n = len(ready)
        word = np.zeros(n, dtype=np.uint64)
        for sig in msg.signals:
            raw = np.zeros(n, dtype=np.int64) if sig.name == "Seq" else np.asarray(columns[sig.name], dtype=np.int64)
            lo, hi = (-(1 << (sig.length - 1)), (1 << (sig.length - 1)) - 1) if sig.is_signed else (0, (1 << sig.length) - 1)
            if raw.size and (raw.min() < lo or raw.max() > hi):
                raise ValueError(f"{name}.{sig.name}: raw value outside {lo}..{hi}")
            word |= (raw & ((1 << sig.length) - 1)).astype(np.uint64) << np.uint64(sig.start)
        data = word.astype("<u8").tobytes()
        priority = self._msg["CurveHeader"].frame_id if name in TRANSFER_FRAMES else msg.frame_id
        for i in range(n):
            item = _Pending((priority, next(self._order)), float(ready[i]), bytearray(data[8 * i:8 * i + msg.length]),
                            False, None if expires is None else float(expires[i]), pairs, frame_id=msg.frame_id)
            heapq.heappush(self._waiting, (item.ready, item.key[1], item))

    def frame_time_planned(self, name: str) -> float:
        """Worst-case wire time (s) of one frame of DBC message ``name`` on this bus."""
        msg = self._msg[name]
        return self._plan.frame_time(msg.frame_id, bytes(msg.length), msg.is_fd)

    @property
    def pending_frames(self) -> int:
        """Frames queued and not yet on the wire."""
        return len(self._queue) + len(self._waiting)

    def pending_before(self, t: float) -> int:
        """Frames queued for sending at or before time ``t`` (s) and not yet on the wire."""
        return sum(item.ready <= t for _, item in self._queue) + sum(w[0] <= t for w in self._waiting)

    @property
    def curves_pending(self) -> int:
        """Curves whose transfer has not finished."""
        return sum(p.curve_end for _, p in self._queue) + sum(w[2].curve_end for w in self._waiting)

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
        for i in range(0, tk.size, per_frame):
            j = min(i + per_frame, tk.size)
            sig = {"Tick": int(ticks[i]), "Dt": int(round(factor * dt / 1e-6)), "NPairs": j - i}
            for k in range(FD_PAIRS):
                sig[f"X{k}"] = int(rx[i + k]) if i + k < j else 0
                sig[f"Y{k}"] = int(ry[i + k]) if i + k < j else 0
            self._enqueue(name, sig, tk[j - 1], expires=tk[j - 1] + self.live_max_age, pairs=j - i)
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
            for b, i in enumerate(range(0, cx.size, FD_PAIRS)):
                j = min(i + FD_PAIRS, cx.size)
                sig = {"CurveNo": number % 256, "Block": b, "NPairs": j - i}
                for k in range(FD_PAIRS):
                    sig[f"X{k}"] = int(rx[i + k]) if i + k < j else 0
                    sig[f"Y{k}"] = int(ry[i + k]) if i + k < j else 0
                self._enqueue("CurveBlockFD", sig, t)
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

    def _transmit(self, t: float) -> int:
        sent = 0
        while True:
            while self._waiting and self._waiting[0][0] <= self.bus_free:
                item = heapq.heappop(self._waiting)[2]
                heapq.heappush(self._queue, (item.key, item))
            if not self._queue:
                if not self._waiting or self._waiting[0][0] >= t:
                    self.bus_free = max(self.bus_free, t)
                    return sent
                self.bus_free = self._waiting[0][0]
                continue
            item = self._queue[0][1]
            if item.expires is not None and self.bus_free > item.expires:
                heapq.heappop(self._queue)
                self.live_dropped += item.pairs
                continue
            fid = item.frame_id
            seq = self._seq.get(fid, 0)
            item.data[0] = seq
            duration = self.timing.frame_time(fid, bytes(item.data), item.is_fd)
            end = self.bus_free + duration
            if end > t:
                return sent
            heapq.heappop(self._queue)
            self._seq[fid] = (seq + 1) % 256
            self.bus.send(can.Message(arbitration_id=fid, data=item.data, is_extended_id=False, is_fd=item.is_fd,
                                      bitrate_switch=item.is_fd and self.timing.data_bitrate is not None,
                                      timestamp=end))
            self.bus_free = end
            self.busy_time += duration
            self.frames_sent += 1
            self.live_sent += item.pairs
            sent += 1

"""Host side of the CAN link: receive from any python-can bus, decode with the DBC, check, reassemble.

Frames are decoded from the DBC's bit layout (:mod:`drivers.can.layout`; cantools for multiplexed or
float frames). :meth:`CanHost.receive_many` takes a batch of frames and decodes runs of live and
curve-block frames together, with the same outcome as :meth:`CanHost.receive` frame by frame.

Every irregularity (unknown id, wrong length, undecodable payload, error frame, sequence gap,
incomplete or corrupt curve) becomes a :class:`LinkEvent` in :attr:`CanHost.events`; nothing
received before it is lost and reception continues.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import can
import cantools
import numpy as np

from drivers.can.drain import drain
from drivers.can.layout import FrameLayout, supports
from drivers.can.reassembly import Curve, CurveAssembler
from drivers.can.sequence import SequenceChecker
from drivers.can.timebase import unwrap

DBC_PATH = Path(__file__).resolve().parents[2] / "data" / "can" / "rig.dbc"
COMMANDS = {"start": 1, "stop": 2, "select_program": 3, "tare": 4, "reset_statistics": 5, "identify": 6}
TARE_CHANNELS = {"x": 0, "y": 1, "y2": 2, None: 3}
STATES = {0: "idle", 1: "measuring", 2: "armed", 15: "unknown"}
ACK = {0: "done", 1: "rejected", 2: "unknown_command"}
PROCESS_VALUES = {"XMax": "x_max", "XMin": "x_min", "YMax": "y_max", "YMin": "y_min", "XAtYMax": "x_at_y_max",
                  "YAtXMax": "y_at_x_max", "XEnd": "x_end", "YEnd": "y_end", "Duration": "duration"}
TICK_WRAP = 6.5536          # s, 16-bit Tick at 100 us
EDGE_WRAP = 16.777216       # s, 24-bit EdgeTime and TStart at 1 us


@dataclass(frozen=True)
class LinkEvent:
    """Something wrong on the link: ``kind`` is one of sequence_gap, unknown_frame, bad_length,
    decode_error, error_frame, curve; ``count`` = frames (or pairs) concerned."""

    time: float
    kind: str
    frame_id: int
    count: int
    detail: str


@dataclass
class CurveResult:
    """Evaluation result of one curve: OK/NOK, failing elements and process values (SI)."""

    number: int
    ok: bool
    first_fail: int | None
    fail_mask: int
    process_values: dict[str, float] = field(default_factory=dict)


class CanHost:
    """Receives and decodes the device's frames from ``bus``; sends host commands to it."""

    def __init__(self, bus: can.BusABC, dbc_path: str | Path = DBC_PATH) -> None:
        self.bus = bus
        self.db = cantools.database.load_file(str(dbc_path))
        self._by_id = {m.frame_id: m for m in self.db.messages if "DEVICE" in m.senders}
        self._layouts = {fid: FrameLayout(m) for fid, m in self._by_id.items() if supports(m)}
        self._command = self.db.get_message_by_name("HostCommand")
        live = self.db.get_message_by_name("LiveXY")
        self.x_lsb, self.y_lsb = live.get_signal_by_name("X").scale, live.get_signal_by_name("Y").scale
        self._fd_pairs = sum(s.name.startswith("X") for s in self.db.get_message_by_name("CurveBlockFD").signals)
        self._fd_x = [f"X{k}" for k in range(self._fd_pairs)]
        self._fd_y = [f"Y{k}" for k in range(self._fd_pairs)]
        self._handlers = {"Heartbeat": self._heartbeat, "StatusCounters": self._counters,
                          "LiveXY": self._live, "LiveXYFD": self._live_fd, "CurveHeader": self._curve_header, "CurveTiming": self._curve_timing, "CurveTimes": self._curve_times,
                          "CurveBlock": self._curve_block, "CurveBlockFD": self._curve_block_fd,
                          "CurveEnd": self._curve_end, "Result": self._result, "ResultValue": self._result_value,
                          "Encoder1": self._encoder, "Encoder2": self._encoder, "Torque": self._torque,
                          "StaticRig": self._static, "CommandAck": self._ack}
        self.sequence = SequenceChecker()
        self.assembler = CurveAssembler(self.x_lsb, self.y_lsb, self._fd_pairs)
        self.events: list[LinkEvent] = []
        self.frames_received = 0
        self.status: dict[str, Any] = {}
        self.counters: dict[str, int] = {}
        self.results: dict[int, CurveResult] = {}
        self.encoders: dict[int, dict[str, float]] = {}
        self.torque: list[tuple[float, float, float]] = []      # (t s, torque N*m, brake force N)
        self.encoder_log: list[tuple[int, float, int, float]] = []  # (encoder 1/2, received s, count, edge time s)
        self.static: list[tuple[float, float, float]] = []      # (t s, angle rad, leaf strain m/m): static rig
        self.acks: list[dict[str, Any]] = []
        self._live: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []   # (t s, raw xs, raw ys) per frame or run
        self._runs = {self.db.get_message_by_name(name).frame_id: handler for name, handler in (
            ("LiveXY", self._live_run), ("LiveXYFD", self._live_run), ("CurveBlock", self._curve_block_run),
            ("CurveBlockFD", self._curve_block_run))}
        self._device_time = 0.0       # latest device time known (s): heartbeat or live stamp
        self._host_seq = 0
        self._last_result: CurveResult | None = None

    # ------------------------------------------------------------------ reception
    def poll(self, timeout: float = 0.0, max_frames: int | None = None) -> int:
        """Receive and process frames until none arrives within ``timeout`` (s); returns how many."""
        n = 0
        while max_frames is None or n < max_frames:
            frames = drain(self.bus, timeout, None if max_frames is None else max_frames - n)
            if not frames:
                break
            self.receive_many(frames)
            n += len(frames)
        return n

    def receive(self, msg: can.Message) -> None:
        """Process one received frame; problems become events, never exceptions."""
        self.frames_received += 1
        fid = msg.arbitration_id
        if msg.is_error_frame:
            self._event(msg, "error_frame", 1, "error frame on the bus")
            return
        spec = self._by_id.get(fid)
        if spec is None:
            if fid != self._command.frame_id:
                self._event(msg, "unknown_frame", 1, f"frame id 0x{fid:03X} is not a device frame of the DBC")
            return
        if len(msg.data) != spec.length:
            self._event(msg, "bad_length", 1, f"{spec.name} (0x{fid:03X}) has {len(msg.data)} data bytes, DBC says {spec.length}")
            return
        try:
            layout = self._layouts.get(fid)
            raw = (layout.decode_one(msg.data) if layout is not None
                   else spec.decode(bytes(msg.data), decode_choices=False, scaling=False))
        except (cantools.database.errors.DecodeError, ValueError, KeyError) as exc:
            self._event(msg, "decode_error", 1, f"{spec.name} (0x{fid:03X}): {exc}")
            return
        gap = self.sequence.check(fid, raw["Seq"])
        if gap:
            self._event(msg, "sequence_gap", gap, f"{spec.name} (0x{fid:03X}): {gap} frame(s) missing before Seq {raw['Seq']}")
        self._handlers[spec.name](msg, spec, raw)

    def receive_many(self, frames: Sequence[can.Message]) -> None:
        """Process received frames in order, with the outcome of :meth:`receive` on each.

        Well-formed live and curve-block frames between two other frames are decoded together, per
        frame id: they touch independent state (live buffer and device time; curve assembler, which only
        header and end frames change), and their events are put back in frame order.
        """
        lengths = {fid: self._layouts[fid].length for fid in self._runs}
        bulk = [lengths.get(m.arbitration_id) == len(m.data) and not m.is_error_frame for m in frames]
        group: dict[int, list[int]] = {}
        for k, (msg, is_bulk) in enumerate(zip(frames, bulk)):
            if is_bulk:
                group.setdefault(msg.arbitration_id, []).append(k)
                continue
            self._receive_groups(frames, group)
            group = {}
            self.receive(msg)
        self._receive_groups(frames, group)

    def _receive_groups(self, frames: Sequence[can.Message], group: dict[int, list[int]]) -> None:
        """Decode and handle the frames ``frames[k]`` listed per frame id in ``group``."""
        events = []
        for fid, index in group.items():
            layout, spec = self._layouts[fid], self._by_id[fid]
            run = [frames[k] for k in index]
            self.frames_received += len(run)
            raw = layout.decode(np.frombuffer(b"".join(m.data for m in run), dtype=np.uint8).reshape(len(run), -1))
            gaps = self.sequence.check_many(fid, raw["Seq"])
            for k in np.flatnonzero(gaps).tolist():
                events.append((index[k], 0, run[k], "sequence_gap", int(gaps[k]),
                               f"{spec.name} (0x{fid:03X}): {gaps[k]} frame(s) missing before Seq {raw['Seq'][k]}"))
            events.extend((index[k], 1, run[k], "curve", 1, p) for k, p in self._runs[fid](raw))
        for _, _, msg, kind, count, detail in sorted(events, key=lambda e: e[:2]):
            self._event(msg, kind, count, detail)

    def _event(self, msg: can.Message, kind: str, count: int, detail: str) -> None:
        self.events.append(LinkEvent(msg.timestamp, kind, msg.arbitration_id, count, detail))

    def events_of(self, kind: str) -> list[LinkEvent]:
        """The events of one kind, in arrival order."""
        return [e for e in self.events if e.kind == kind]

    # ------------------------------------------------------------------ frame handlers
    def _heartbeat(self, msg, spec, raw) -> None:
        self._device_time = raw["DeviceTime"] * 1e-3
        self.status = {"state": STATES.get(raw["State"], f"unknown({raw['State']})"), "program": raw["Program"],
                       "last_ok": {0: False, 1: True}.get(raw["LastOk"]), "device_time": self._device_time,
                       "errors": raw["Errors"]}

    def _counters(self, msg, spec, raw) -> None:
        self.counters = {"live_dropped": raw["LiveDropped"], "curve_count": raw["CurveCount"],
                         "curves_pending": raw["CurvesPending"]}

    def _live_time(self, tick: int) -> float:
        t = unwrap(tick * 1e-4, TICK_WRAP, self._device_time)
        self._device_time = max(self._device_time, t)
        return t

    def _live(self, msg, spec, raw) -> None:
        self._live_run({k: np.array([v]) for k, v in raw.items()})

    _live_fd = _live

    def _live_run(self, raw: dict[str, np.ndarray]) -> list[tuple[int, str]]:
        """Live frames (LiveXY: one pair at Tick; LiveXYFD: NPairs pairs at Tick + i*Dt), in order."""
        if "NPairs" not in raw:
            self._live.append((np.array([self._live_time(tick) for tick in raw["Tick"].tolist()]), raw["X"], raw["Y"]))
            return []
        dt = raw["Dt"] * 1e-6
        t0 = np.zeros(len(dt))
        for k, (tick, step, n) in enumerate(zip(raw["Tick"].tolist(), dt.tolist(), raw["NPairs"].tolist())):
            t0[k] = self._live_time(tick)
            self._device_time = max(self._device_time, t0[k] + (n - 1) * step)
        counts = np.minimum(raw["NPairs"], self._fd_pairs)
        first = np.repeat(np.cumsum(counts) - counts, counts)
        slot = np.arange(int(counts.sum())) - first
        t = np.repeat(t0, counts) + np.repeat(dt, counts) * slot
        rows = np.repeat(np.arange(len(counts)), counts)
        xs, ys = np.column_stack([raw[k] for k in self._fd_x]), np.column_stack([raw[k] for k in self._fd_y])
        self._live.append((t, xs[rows, slot], ys[rows, slot]))
        return []

    def take_live(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Live pairs received since the last call: times (s, device time), X (m), Y (N)."""
        blocks, self._live = self._live, []
        if not blocks:
            return np.zeros(0), np.zeros(0), np.zeros(0)
        t, x, y = (np.concatenate([b[k] for b in blocks]) for k in range(3))
        return t, x * self.x_lsb, y * self.y_lsb

    def _curve_problems(self, msg, problems: list[str]) -> None:
        for p in problems:
            self._event(msg, "curve", 1, p)

    def _curve_header(self, msg, spec, raw) -> None:
        self._curve_problems(msg, self.assembler.header(raw["CurveNo"], raw["Count"], raw["Program"]))

    def _curve_timing(self, msg, spec, raw) -> None:
        scale = {s.name: s.scale for s in spec.signals}
        t_start = unwrap(raw["TStart"] * scale["TStart"], EDGE_WRAP, self._device_time)
        self._curve_problems(msg, self.assembler.timing(raw["CurveNo"], t_start, raw["Dt"] * scale["Dt"]))

    def _curve_times(self, msg, spec, raw) -> None:
        lsb = spec.get_signal_by_name("T0").scale
        offsets = np.array([raw["T0"], raw["T1"]]) * lsb
        self._curve_problems(msg, self.assembler.times(raw["CurveNo"], 2 * raw["Block"], offsets))

    def _curve_block(self, msg, spec, raw) -> None:
        self._curve_problems(msg, [p for _, p in self._curve_block_run({k: np.array([v]) for k, v in raw.items()})])

    _curve_block_fd = _curve_block

    def _curve_block_run(self, raw: dict[str, np.ndarray]) -> list[tuple[int, str]]:
        """Curve blocks (CurveBlock: one pair numbered Block of curve CurveNo mod 16; CurveBlockFD: NPairs
        pairs from Block*11 of curve CurveNo mod 256); returns (frame index, problem)."""
        if "NPairs" not in raw:
            return self.assembler.pairs(raw["CurveNo"], 16, raw["Block"], np.ones_like(raw["Block"]),
                                             np.column_stack([raw["X"], raw["Y"]])[:, None, :])
        xs, ys = np.column_stack([raw[k] for k in self._fd_x]), np.column_stack([raw[k] for k in self._fd_y])
        return self.assembler.pairs(raw["CurveNo"], 256, raw["Block"] * self._fd_pairs,
                                         np.minimum(raw["NPairs"], self._fd_pairs), np.stack([xs, ys], axis=2))

    def _curve_end(self, msg, spec, raw) -> None:
        self._curve_problems(msg, self.assembler.end(raw["CurveNo"], raw["Count"], raw["Crc"], raw["Clipped"]))

    @property
    def device_time(self) -> float:
        """Latest device time known from heartbeats and live stamps (s)."""
        return self._device_time

    def curves(self) -> list[Curve]:
        """Curves transferred completely, count and checksum verified."""
        return [c for c in self.assembler.done if c.complete]

    def incomplete_curves(self) -> list[Curve]:
        """Curves with missing pairs, a wrong count or checksum (kept with their ``received`` mask)."""
        return [c for c in self.assembler.done if not c.complete]

    def _result(self, msg, spec, raw) -> None:
        first = None if raw["FirstFail"] == 127 else raw["FirstFail"]
        self._last_result = CurveResult(raw["CurveNo"], bool(raw["Ok"]), first, raw["FailMask"])
        self.results[raw["CurveNo"]] = self._last_result

    def _result_value(self, msg, spec, raw) -> None:
        res = self._last_result
        signal = next((name for name in PROCESS_VALUES if name in raw), None)
        if res is None or res.number % 256 != raw["CurveNo"] or signal is None:
            self._event(msg, "curve", 1, f"process value for curve {raw['CurveNo']} (mod 256) without its Result frame")
            return
        res.process_values[PROCESS_VALUES[signal]] = float(raw[signal])

    def _encoder(self, msg, spec, raw) -> None:
        reading = {"count": raw["Count"], "edge_time": unwrap(raw["EdgeTime"] * 1e-6, EDGE_WRAP, self._device_time),
                   "received": msg.timestamp}
        self.encoders[int(spec.name[-1])] = reading
        self.encoder_log.append((int(spec.name[-1]), reading["received"], reading["count"], reading["edge_time"]))

    def _torque(self, msg, spec, raw) -> None:
        torque = raw["Torque"] * spec.get_signal_by_name("Torque").scale
        self.torque.append((self._live_time(raw["Tick"]), torque, raw["BrakeForce"] * self.y_lsb))

    def _static(self, msg, spec, raw) -> None:
        self.static.append((self._live_time(raw["Tick"]), raw["Angle"] * spec.get_signal_by_name("Angle").scale,
                            raw["Strain"] * spec.get_signal_by_name("Strain").scale))

    def _ack(self, msg, spec, raw) -> None:
        self.acks.append({"cmd": raw["Cmd"], "arg": raw["Arg"], "host_seq": raw["HostSeq"],
                          "status": ACK.get(raw["AckStatus"], f"unknown({raw['AckStatus']})")})

    # ------------------------------------------------------------------ commands
    def send_command(self, command: str, arg: int = 0) -> int:
        """Send one host command (``start``, ``stop``, ``select_program``, ``tare``,
        ``reset_statistics``, ``identify``); returns its HostSeq, echoed in the device's ack."""
        if command not in COMMANDS:
            raise ValueError(f"unknown CAN host command {command!r} (known: {', '.join(COMMANDS)})")
        seq = self._host_seq
        self._host_seq = (seq + 1) % 256
        data = self._command.encode({"Cmd": COMMANDS[command], "Arg": arg, "HostSeq": seq}, strict=True)
        self.bus.send(can.Message(arbitration_id=self._command.frame_id, data=data, is_extended_id=False))
        return seq

    def start(self) -> int:
        return self.send_command("start")

    def stop(self) -> int:
        return self.send_command("stop")

    def select_program(self, number: int) -> int:
        return self.send_command("select_program", number)

    def tare(self, channel: str | None = None) -> int:
        """Tare channel ``x``, ``y``, ``y2`` or (None) x and y."""
        if channel not in TARE_CHANNELS:
            raise ValueError(f"unknown tare channel {channel!r} (known: x, y, y2 or None for x and y)")
        return self.send_command("tare", TARE_CHANNELS[channel])

    def reset_statistics(self) -> int:
        return self.send_command("reset_statistics")

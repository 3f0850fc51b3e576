"""Host side of the CAN link: receive from any python-can bus, decode with the DBC, check, reassemble.

Frames are decoded from the DBC's bit layout (:mod:`drivers.can.layout`; cantools for multiplexed or
float frames). :meth:`CanHost.receive_block` takes a block of frames (:class:`rig.blockbus.FrameBlock`)
and decodes runs of live and curve-block frames together, with the same outcome as
:meth:`CanHost.receive` frame by frame (which stays scalar, for per-frame callers).

A result is complete when its end marker (``ResultValue`` Pv 255) has arrived with every process value
it announces. A result whose end marker is missing when the next result or curve header arrives, or
``result_timeout`` seconds of bus time after its ``Result`` frame, or at :meth:`CanHost.flush`, is
released marked incomplete with the names of the missing values (and a ``result`` event).

Every irregularity (unknown id, wrong length, undecodable payload, error frame, sequence gap,
incomplete or corrupt curve) becomes a :class:`LinkEvent` in :attr:`CanHost.events`; nothing
received before it is lost and reception continues.
"""
from __future__ import annotations

import functools
import itertools
import math
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple, Sequence

import can
import cantools
import numpy as np

from drivers.can.drain import drain_block
from drivers.can.layout import FrameLayout, supports
from drivers.can.process_values import PROCESS_VALUES
from drivers.can.reassembly import Curve, CurveAssembler
from drivers.can.sequence import SequenceChecker
from drivers.can.timebase import unwrap
from rig.blockbus import ERROR, EXTENDED, FD, FrameBlock
from rig.dbc import DBC_PATH, load_dbc

COMMANDS = {"start": 1, "stop": 2, "select_program": 3, "tare": 4, "reset_statistics": 5, "identify": 6,
            "release": 7}
TARE_CHANNELS = {"x": 0, "y": 1, "y2": 2, None: 3}
STATES = {0: "idle", 1: "measuring", 2: "armed", 15: "unknown"}
ACK = {0: "done", 1: "rejected", 2: "unknown_command"}
TICK_WRAP = 6.5536          # s, 16-bit Tick at 100 us
EDGE_WRAP = 16.777216       # s, 24-bit EdgeTime and TStart at 1 us
START_WRAP = 2.0 ** 40 * 1e-6   # s, 40-bit curve start (TStartHigh:TStart) at 1 us: 12.7 days
NUMBER_WRAP = 65536         # 16-bit CurveNo of CurveHeader and Result
PV_END = 255                # ResultValue multiplexer value of the end marker


class _Rx(NamedTuple):
    """One received frame, as the handlers need it."""

    timestamp: float
    arbitration_id: int
    data: bytes
    is_error_frame: bool
    is_extended_id: bool = False
    is_fd: bool = False


#: what each ``TxStatus.StopCause`` of a run that did not complete means (docs/can-protocol.md)
STOP_CAUSES = {
    "OperatorStop": "the unit's operator stopped it (Ctrl-C or SIGTERM on its rig serve, or on rig run)",
    "HostLeft": "its hosts (the connections that sent, the one that started the run) all disconnected without "
                "releasing the unit",
    "HostStalled": "the host stopped reading its frames and the unit waited for it in vain",
    "BusOverload": "the CAN bus cannot carry the curves the unit measures (its scene's [links.can])",
    "OutOfTime": "the scene's cycles were not complete by its max_time (its queue was sent)",
    "Fault": "the simulated machine could not go on (its console names the error)",
}


@dataclass(frozen=True)
class LinkEvent:
    """Something wrong on the link: ``kind`` is one of sequence_gap, unknown_frame, bad_length,
    decode_error, error_frame, curve, result, run_stopped; ``count`` = frames (or pairs, or missing values)
    concerned (run_stopped: the unit's run ended other than complete, the detail names its StopCause)."""

    time: float
    kind: str
    frame_id: int
    count: int
    detail: str


@dataclass
class CurveResult:
    """Evaluation result of one curve: OK/NOK, failing elements and process values (SI). ``complete``:
    the end marker arrived with every value it announces; ``missing``: names of values that did not
    arrive (the announced ones, or all of them when the end marker itself is missing). ``memory_full``: the
    curve filled the unit's memory and was cut there; ``decimated``: it was thinned to fit (end marker flags)."""

    number: int
    ok: bool
    first_fail: int | None
    fail_mask: int
    process_values: dict[str, float] = field(default_factory=dict)
    complete: bool = False
    missing: list[str] = field(default_factory=list)
    received: float = 0.0          # bus time of the Result frame (s)
    memory_full: bool = False
    decimated: bool = False


class CanHost:
    """Receives and decodes the device's frames from ``bus``; sends host commands to it."""

    def __init__(self, bus: can.BusABC, dbc_path: str | Path = DBC_PATH, result_timeout: float = 1.0) -> None:
        self.bus = bus
        self.result_timeout = result_timeout
        self.db = load_dbc(str(dbc_path))
        self._by_id = {m.frame_id: m for m in self.db.messages if "DEVICE" in m.senders}
        self._layouts = {fid: FrameLayout(m) for fid, m in self._by_id.items() if supports(m)}
        self._command = self.db.get_message_by_name("HostCommand")
        self._result_id = self.db.get_message_by_name("Result").frame_id     # the frame a cut result event names
        live = self.db.get_message_by_name("LiveXY")
        self.x_lsb, self.y_lsb = live.get_signal_by_name("X").scale, live.get_signal_by_name("Y").scale
        self._fd_pairs = sum(s.name.startswith("X") for s in self.db.get_message_by_name("CurveBlockFD").signals)
        self._fd_x = [f"X{k}" for k in range(self._fd_pairs)]
        self._fd_y = [f"Y{k}" for k in range(self._fd_pairs)]
        self._handlers = {"Heartbeat": self._heartbeat, "StatusCounters": self._counters,
                          "LiveXY": self._live, "LiveXYFD": self._live_fd, "CurveHeader": self._curve_header, "CurveTiming": self._curve_timing, "CurveTimes": self._curve_times,
                          "CurveBlock": self._curve_block, "CurveBlockFD": self._curve_block_fd,
                          "CurveEnd": self._curve_end, "Result": self._result, "ResultValue": self._result_value,
                          "CommandAck": self._ack, "TxStatus": self._tx_status}
        for m in self._by_id.values():      # every other device frame is a reading: a counter or Tick-stamped values
            if m.name not in self._handlers:
                names = {sg.name for sg in m.signals}
                self._handlers[m.name] = self._counter if {"Count", "EdgeTime"} <= names else self._reading
        self._dispatch = {fid: (spec, spec.length, self._decoder(spec), self._handlers[spec.name])
                          for fid, spec in self._by_id.items()}     # per frame id: what receiving it takes
        self.sequence = SequenceChecker()
        self.assembler = CurveAssembler(self.x_lsb, self.y_lsb, self._fd_pairs)
        self._last_number: dict[str, int] = {}      # last full curve number per frame kind (CurveNo is 16-bit)
        self.events: list[LinkEvent] = []
        self.frames_received = 0
        self.status: dict[str, Any] = {}
        self.counters: dict[str, int] = {}
        self.run_ended = False        # the device's last frame of the run (TxStatus RunEnded) has arrived
        self.stop_cause = ""          # then why its run ended: a TxStatus.StopCause choice ("Completed", ...)
        self._stop_causes = {value: str(name) for value, name in
                             self.db.get_message_by_name("TxStatus").get_signal_by_name("StopCause").choices.items()}
        self.drop_period = 1.0        # s of device time between two reports of dropped live pairs
        self.drop_reports: list[dict[str, float]] = []   # not yet taken (see take_drop_reports)
        self._drops_reported, self._drops_at = 0, -float("inf")
        self.results: dict[int, CurveResult] = {}                # released results not yet taken
        self.counters_log: list[tuple[str, float, int, float, int]] = []   # (message, received s, count, edge time s,
        #                                                                        the card's illegal transitions)
        self._edges: dict[str, tuple[int, float]] = {}    # per counter: its last raw EdgeTime and that edge's time (s)
        self._wraps: dict[str, tuple[int, int]] = {}      # per counter: its last raw Count and that count unwrapped
        self.readings: list[tuple[str, np.ndarray, dict[str, np.ndarray]]] = []   # blocks: (message, t s, {signal: DBC units})
        self.acks: list[dict[str, Any]] = []
        self._live: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []   # (t s, raw xs, raw ys) per run
        # live frames received one by one, not yet put in _live: LiveXY as three flat lists (t s, raw x, raw y),
        # LiveXYFD as rows (t0 s, dt s, raw xs, raw ys); one kind at a time, so arrival order is kept
        self._live_pairs: tuple[list[float], list[int], list[int]] = ([], [], [])
        self._live_rows: list[tuple[float, float, list[int], list[int]]] = []
        self._runs = {self.db.get_message_by_name(name).frame_id: handler for name, handler in (
            ("LiveXY", self._live_run), ("LiveXYFD", self._live_run), ("CurveBlock", self._curve_block_run),
            ("CurveBlockFD", self._curve_block_run))}
        self._runs.update({fid: functools.partial(self._reading_run, spec) for fid, spec in self._by_id.items()
                           if self._handlers[spec.name] == self._reading and fid in self._layouts})
        # frames stamped with the device's 16-bit Tick: their times unwrap in frame order, each moving the device time
        self._ticked = {fid for fid in self._runs if "Tick" in {sg.name for sg in self._by_id[fid].signals}}
        self._counter_ids = {fid for fid, spec in self._by_id.items()
                             if self._handlers[spec.name] == self._counter and fid in self._layouts}
        self._run_lengths = {fid: self._layouts[fid].length for fid in (*self._runs, *self._counter_ids)}
        self._device_time = 0.0       # latest device time known (s): heartbeat or live stamp
        self._run_device_time = 0.0   # the device time before the bulk run being decoded (s)
        self._run_clock: tuple[np.ndarray, np.ndarray] | None = None   # its Tick-stamped frames: index, time after
        self._bus_time = 0.0          # latest frame time stamp (s)
        self._host_seq = 0
        self._sent: list[can.Message] = []   # commands sent, not yet taken (see take_sent)
        self._pending: CurveResult | None = None   # result waiting for its end marker
        self._released: deque[CurveResult] = deque()
        self._start_high = 0.0        # s: TStartHigh of the curve being received

    # ------------------------------------------------------------------ reception
    def poll(self, timeout: float = 0.0) -> int:
        """Receive and process every frame waiting (waits up to ``timeout`` s for the first); returns how many."""
        block = drain_block(self.bus, timeout)
        self.receive_block(block)
        return len(block)

    def receive(self, msg: can.Message) -> None:
        """Process one received frame; problems become events, never exceptions."""
        self._receive_one(msg)
        self._check_result_timeout()

    def receive_many(self, frames: Sequence[can.Message]) -> None:
        """Process received python-can messages in order (as one block)."""
        self.receive_block(FrameBlock.of_messages(list(frames)))

    def _decoder(self, spec):
        """Raw values of one payload of ``spec``: the layout's decoder, or cantools' (multiplexed frames)."""
        layout = self._layouts.get(spec.frame_id)
        if layout is not None:
            return layout.decode_one
        return lambda data: spec.decode(bytes(data), decode_choices=False, scaling=False)

    def _receive_one(self, msg: can.Message | _Rx) -> None:
        """One frame (a python-can message or an :class:`_Rx`; read, never kept)."""
        self.frames_received += 1
        if msg.timestamp > self._bus_time:
            self._bus_time = msg.timestamp
        fid = msg.arbitration_id
        if msg.is_error_frame:
            self._event(msg, "error_frame", 1, "error frame on the bus")
            return
        entry = None if msg.is_extended_id else self._dispatch.get(fid)     # the DBC's ids are all 11-bit
        if entry is None:
            if fid != self._command.frame_id or msg.is_extended_id:
                name = f"0x{fid:08X} (extended)" if msg.is_extended_id else f"0x{fid:03X}"
                self._event(msg, "unknown_frame", 1, f"frame id {name} is not a device frame of the DBC")
            return
        spec, length, decode, handler = entry
        data = msg.data
        if len(data) > 8 and not msg.is_fd:
            self._event(msg, "bad_length", 1, f"{spec.name} (0x{fid:03X}) has {len(data)} data bytes in a classic "
                        "(non-FD) frame; more than 8 need CAN FD")
            return
        if len(data) != length:
            self._event(msg, "bad_length", 1, f"{spec.name} (0x{fid:03X}) has {len(data)} data bytes, DBC says {length}")
            return
        try:
            raw = decode(data)
        except (cantools.database.errors.DecodeError, ValueError, KeyError) as exc:
            self._event(msg, "decode_error", 1, f"{spec.name} (0x{fid:03X}): {exc}")
            return
        gap = self.sequence.check(fid, raw["Seq"])
        if gap:
            self._event(msg, "sequence_gap", gap, f"{spec.name} (0x{fid:03X}): {gap} frame(s) missing before Seq {raw['Seq']}")
        handler(msg, spec, raw)

    def receive_block(self, block: FrameBlock) -> None:
        """Process a block of received frames in order, with the outcome of :meth:`receive` on each.

        Well-formed live, curve-block and counter frames between two other frames are decoded together, per
        frame id: they touch independent state (live buffer and device time; curve assembler, which only
        header and end frames change; counter rows, unwrapped against the device time the live frames before
        each left), and their events and counter rows are put back in frame order.
        """
        n = len(block)
        if not n:
            return
        ids = block.arbitration_id.astype(np.int64)
        expected = np.full(ids.shape, -1)
        for fid, length in self._run_lengths.items():
            expected[ids == fid] = length
        bulk = (expected == block.dlc) & ((block.flags & (ERROR | EXTENDED)) == 0) & ((block.dlc <= 8) | ((block.flags & FD) != 0))
        start = 0
        for k in np.flatnonzero(~bulk).tolist() + [n]:
            if k > start:
                self._receive_bulk(block, ids, start, k)
            if k < n:
                self._receive_one(_Rx(float(block.timestamp[k]), int(ids[k]), block.payload(k),
                                      bool(block.flags[k] & ERROR), bool(block.flags[k] & EXTENDED),
                                      bool(block.flags[k] & FD)))
                self._check_result_timeout()
            start = k + 1

    def _receive_bulk(self, block: FrameBlock, ids: np.ndarray, start: int, stop: int) -> None:
        """The bulk frames ``start:stop``, split after the frame whose time stamp makes a pending result time
        out (where :meth:`receive` releases it); the bus time advances as frame by frame."""
        times = np.maximum.accumulate(np.maximum(block.timestamp[start:stop], self._bus_time))
        res = self._pending
        late = np.flatnonzero(times - res.received > self.result_timeout) if res is not None else []
        cut = start + int(late[0]) + 1 if len(late) else stop
        self._receive_run(block, ids, start, cut)
        self._bus_time = float(times[cut - start - 1])
        self._check_result_timeout()
        if cut < stop:
            self._receive_run(block, ids, cut, stop)
            self._bus_time = float(times[-1])

    def _receive_run(self, block: FrameBlock, ids: np.ndarray, start: int, stop: int) -> None:
        """Decode the bulk frames ``start:stop`` of ``block`` together, per frame id."""
        events = []
        run_ids = ids[start:stop]
        self._run_device_time = self._device_time
        decoded = {}
        for fid in np.unique(run_ids).tolist():
            index = start + np.flatnonzero(run_ids == fid)
            layout, spec = self._layouts[fid], self._by_id[fid]
            self.frames_received += index.size
            raw = decoded[fid] = layout.decode(block.data[index, :layout.length])
            gaps = self.sequence.check_many(fid, raw["Seq"])
            for k in np.flatnonzero(gaps).tolist():
                events.append((int(index[k]), 0, "sequence_gap", int(gaps[k]),
                               f"{spec.name} (0x{fid:03X}): {gaps[k]} frame(s) missing before Seq {raw['Seq'][k]}"))
        clock = self._clock_run(decoded, run_ids, start)
        counters = []
        for fid, raw in decoded.items():
            index = start + np.flatnonzero(run_ids == fid)
            if fid in self._runs:
                t = clock[fid] if fid in clock else block.timestamp[index]
                events.extend((int(index[k]), 1, "curve", 1, p) for k, p in self._runs[fid](raw, index, t))
            if fid in self._counter_ids:
                counters.extend(zip(index.tolist(), self._counter_rows(self._by_id[fid].name, raw, index,
                                                                       block.timestamp)))
        self.counters_log.extend(row for _, row in sorted(counters, key=lambda r: r[0]))
        for k, _, kind, count, detail in sorted(events, key=lambda e: e[:2]):
            self._event(_Rx(float(block.timestamp[k]), int(ids[k]), b"", False), kind, count, detail)

    def _clock_run(self, decoded: dict[int, dict[str, np.ndarray]], run_ids: np.ndarray,
                   start: int) -> dict[int, np.ndarray]:
        """The device times (s) of a run's Tick-stamped frames (live, readings), per frame id: each Tick unwrapped
        against the device time the frames before it left, in frame order, as :meth:`receive` does frame by frame
        (a LiveXYFD frame moves the device time to its last pair). Sets ``_run_clock`` (run index, device time after
        each such frame) for the counters' edge times."""
        ticked = [fid for fid in decoded if fid in self._ticked]
        self._run_clock = None
        if not ticked:
            return {}
        where = [np.flatnonzero(run_ids == fid) for fid in ticked]
        tick = np.concatenate([decoded[fid]["Tick"] for fid in ticked]).tolist()
        span = np.concatenate([(decoded[fid]["NPairs"] - 1) * (decoded[fid]["Dt"] * 1e-6) if "NPairs" in decoded[fid]
                               else np.zeros(len(decoded[fid]["Tick"])) for fid in ticked]).tolist()
        index = np.concatenate(where)
        t, after = np.empty(index.size), np.empty(index.size)
        for k in np.argsort(index, kind="stable").tolist():
            t[k] = self._live_time(tick[k])
            self._device_time = after[k] = max(self._device_time, t[k] + span[k])
        self._run_clock = (start + index, after)
        bounds = np.cumsum([0] + [w.size for w in where])
        return {fid: t[a:b] for fid, a, b in zip(ticked, bounds, bounds[1:])}

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
        self.counters.update({"live_dropped": raw["LiveDropped"], "curve_count": raw["CurveCount"],
                              "curves_pending": raw["CurvesPending"]})

    def _report_drops(self) -> None:
        """A ``live_dropped`` report (at the device time the status frames were taken, from the heartbeat before
        them): pairs the unit did not send since the previous report, with the live factor, stale count and backlog
        of the same status (made on its last frame, TxStatus, so that every figure is of one moment)."""
        c = self.counters
        self.drop_reports.append({"t": self._device_time, "count": (c["live_dropped"] - self._drops_reported) % (1 << 32),
                                  "total": c["live_dropped"], "stale": c.get("live_stale", 0),
                                  "live_factor": c.get("live_factor", 1), "backlog": c.get("backlog", 0.0)})
        self._drops_reported, self._drops_at = c["live_dropped"], self._device_time

    def _tx_status(self, msg, spec, raw) -> None:
        self.counters.update({"backlog": raw["Backlog"] * spec.get_signal_by_name("Backlog").scale,
                              "live_factor": raw["LiveFactor"], "live_stale": raw["LiveStale"]})
        if raw["RunEnded"] and not self.run_ended:
            self.stop_cause = self._stop_causes.get(raw["StopCause"], f"unknown ({raw['StopCause']})")
            if self.stop_cause != "Completed":
                backlog = raw["Backlog"] * spec.get_signal_by_name("Backlog").scale
                self._event(msg, "run_stopped", 0, self.stop_reason + (
                    f"; what the unit still had queued was not sent (its wire time {backlog:.3f} s)"
                    if self.stopped_early else ""))
        self.run_ended = self.run_ended or bool(raw["RunEnded"])
        if self.counters.get("live_dropped", 0) != self._drops_reported and (
                self.run_ended or self._device_time - self._drops_at >= self.drop_period):
            self._report_drops()

    @property
    def stop_reason(self) -> str:
        """The run's ``StopCause`` and what it means ("HostStalled: the host stopped reading …"); "" before the run's
        last frame."""
        if not self.stop_cause:
            return ""
        return f"{self.stop_cause}: {STOP_CAUSES.get(self.stop_cause, 'a cause this host does not know')}"

    @property
    def stopped_early(self) -> bool:
        """Whether the unit stopped its run, discarding what it still had queued: any ``StopCause`` but ``Completed``
        and ``OutOfTime`` (which end as a complete run does)."""
        return self.stop_cause not in ("", "Completed", "OutOfTime")

    def _live_time(self, tick: int) -> float:
        t = unwrap(tick * 1e-4, TICK_WRAP, self._device_time)
        if t > self._device_time:
            self._device_time = t
        return t

    def _live(self, msg, spec, raw) -> None:
        """One live frame received on its own (LiveXY: one pair; LiveXYFD: NPairs pairs at Tick + i*Dt)."""
        t0 = self._live_time(raw["Tick"])
        if "NPairs" not in raw:
            if self._live_rows:
                self._flush_live_rows()
            t, x, y = self._live_pairs
            t.append(t0)
            x.append(raw["X"])
            y.append(raw["Y"])
            return
        if self._live_pairs[0]:
            self._flush_live_rows()
        dt, n = raw["Dt"] * 1e-6, min(raw["NPairs"], self._fd_pairs)
        self._live_rows.append((t0, dt, [raw[k] for k in self._fd_x[:n]], [raw[k] for k in self._fd_y[:n]]))
        self._device_time = max(self._device_time, t0 + (raw["NPairs"] - 1) * dt)

    _live_fd = _live

    def _flush_live_rows(self) -> None:
        if self._live_pairs[0]:
            t, x, y = self._live_pairs
            self._live.append((np.array(t), np.array(x, dtype=np.int64), np.array(y, dtype=np.int64)))
            self._live_pairs = ([], [], [])
        if self._live_rows:
            t0, dt, xs, ys = zip(*self._live_rows)
            counts = np.array([len(x) for x in xs])
            slot = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
            t = np.repeat(np.array(t0), counts) + np.repeat(np.array(dt), counts) * slot
            flat = lambda rows: np.fromiter(itertools.chain.from_iterable(rows), np.int64, slot.size)  # noqa: E731
            self._live.append((t, flat(xs), flat(ys)))
            self._live_rows = []

    def _live_run(self, raw: dict[str, np.ndarray], index: np.ndarray, t0: np.ndarray) -> list[tuple[int, str]]:
        """Live frames (LiveXY: one pair at Tick; LiveXYFD: NPairs pairs at Tick + i*Dt), in order; ``t0``: their
        Ticks as device times (s)."""
        self._flush_live_rows()
        if "NPairs" not in raw:
            self._live.append((t0, raw["X"], raw["Y"]))
            return []
        dt = raw["Dt"] * 1e-6
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
        self._flush_live_rows()
        blocks, self._live = self._live, []
        if not blocks:
            return np.zeros(0), np.zeros(0), np.zeros(0)
        t, x, y = (np.concatenate([b[k] for b in blocks]) for k in range(3))
        return t, x * self.x_lsb, y * self.y_lsb

    def _curve_problems(self, msg, problems: list[str]) -> None:
        for p in problems:
            self._event(msg, "curve", 1, p)

    def _full_number(self, kind: str, curve_no: int) -> int:
        """The curve number counted on from the 16-bit ``CurveNo`` of a ``kind`` frame (CurveHeader, Result): the
        number congruent to it modulo 65536 nearest to the one after the last of that kind (the first is taken as
        is), so numbers keep increasing past 65535 (after 7.3 h at 150 rpm); exact while fewer than 32768 curves
        pass unseen."""
        last = self._last_number.get(kind)
        number = int(curve_no) if last is None else int(unwrap(curve_no, NUMBER_WRAP, last + 1))
        self._last_number[kind] = number
        return number

    def _curve_header(self, msg, spec, raw) -> None:
        number = self._full_number("header", raw["CurveNo"])
        self._release_pending(msg, f"the header of curve {number} arrived")
        self._start_high = raw["TStartHigh"] * spec.get_signal_by_name("TStartHigh").scale
        self._curve_problems(msg, self.assembler.header(number, raw["Count"], raw["Program"]))

    def _curve_timing(self, msg, spec, raw) -> None:
        scale = {s.name: s.scale for s in spec.signals}
        t_start = unwrap(self._start_high + raw["TStart"] * scale["TStart"], START_WRAP, self._device_time)
        self._curve_problems(msg, self.assembler.timing(raw["CurveNo"], t_start, raw["Dt"] * scale["Dt"]))

    def _curve_times(self, msg, spec, raw) -> None:
        lsb = spec.get_signal_by_name("T0").scale
        offsets = np.array([raw["T0"], raw["T1"]]) * lsb
        self._curve_problems(msg, self.assembler.times(raw["CurveNo"], 2 * raw["Block"], offsets))

    def _curve_block(self, msg, spec, raw) -> None:
        """One curve-block frame received on its own."""
        if "NPairs" not in raw:
            problem = self.assembler.pair_run(raw["CurveNo"], 16, raw["Block"], [raw["X"]], [raw["Y"]])
        else:
            n = min(raw["NPairs"], self._fd_pairs)
            problem = self.assembler.pair_run(raw["CurveNo"], 256, raw["Block"] * self._fd_pairs,
                                              [raw[k] for k in self._fd_x[:n]], [raw[k] for k in self._fd_y[:n]])
        self._curve_problems(msg, [problem] if problem else [])

    _curve_block_fd = _curve_block

    def _curve_block_run(self, raw: dict[str, np.ndarray], index: np.ndarray,
                         t: np.ndarray) -> list[tuple[int, str]]:
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
        """Curves transferred completely, count and checksum verified (not yet taken)."""
        return [c for c in self.assembler.done if c.complete]

    def incomplete_curves(self) -> list[Curve]:
        """Curves with missing pairs, a wrong count or checksum (kept with their ``received`` mask; not yet taken)."""
        return [c for c in self.assembler.done if not c.complete]

    def take_curves(self) -> list[Curve]:
        """Every finished curve (complete or not) received since the last call, in order."""
        done, self.assembler.done = self.assembler.done, []
        return done

    # ------------------------------------------------------------------ results
    def _result(self, msg, spec, raw) -> None:
        number = self._full_number("result", raw["CurveNo"])
        self._release_pending(msg, f"the result of curve {number} arrived")
        first = None if raw["FirstFail"] == 127 else raw["FirstFail"]
        self._pending = CurveResult(number, bool(raw["Ok"]), first, raw["FailMask"], received=msg.timestamp)

    def _result_value(self, msg, spec, raw) -> None:
        res = self._pending
        if res is None or res.number % 256 != raw["CurveNo"]:
            what = "end marker" if raw["Pv"] == PV_END else "process value"
            self._event(msg, "curve", 1, f"{what} for curve {raw['CurveNo']} (mod 256) without its Result frame")
            return
        if raw["Pv"] == PV_END:
            names = list(PROCESS_VALUES.values())
            announced = [names[i] for i in range(len(names)) if raw["PvMask"] >> i & 1]
            res.missing = [name for name in announced if name not in res.process_values]
            res.complete = not res.missing and raw["PvCount"] == len(announced)
            res.memory_full, res.decimated = bool(raw.get("MemoryFull", 0)), bool(raw.get("Decimated", 0))
            if not res.complete:
                self._event(msg, "result", len(res.missing), f"result of curve {res.number}: process values "
                            f"{', '.join(res.missing) or '(count mismatch)'} did not arrive")
            self._release(res)
            return
        signal = next((name for name in PROCESS_VALUES if name in raw), None)
        if signal is None:
            self._event(msg, "decode_error", 1, f"ResultValue (0x{msg.arbitration_id:03X}): unknown Pv {raw['Pv']}")
            return
        res.process_values[PROCESS_VALUES[signal]] = float(raw[signal])

    def _release(self, res: CurveResult) -> None:
        self._pending = None
        self.results[res.number] = res
        self._released.append(res)

    def _release_pending(self, msg, why: str) -> None:
        """Release the pending result as incomplete (its end marker is lost): ``why`` says what came instead."""
        res = self._pending
        if res is None:
            return
        res.missing = [name for name in PROCESS_VALUES.values() if name not in res.process_values]
        self._event(msg, "result", len(res.missing), f"result of curve {res.number}: no end marker before {why}; "
                    f"{len(res.missing)} of {len(PROCESS_VALUES)} process values missing "
                    f"({', '.join(res.missing) or 'none'}); values received: {', '.join(res.process_values) or 'none'}")
        self._release(res)

    def _check_result_timeout(self) -> None:
        res = self._pending
        if res is not None and self._bus_time - res.received > self.result_timeout:
            self._release_pending(_Rx(self._bus_time, self._result_id, b"", False),
                                  f"{self.result_timeout:g} s of bus time passed")

    def flush(self, why: str = "the end of the recording") -> None:
        """End of reception (``why``): a result still waiting for its end marker is released as incomplete, a curve
        still being transferred becomes an incomplete curve (:meth:`take_curves`) and live pairs not yet reported a
        last ``live_dropped`` report."""
        self._release_pending(_Rx(self._bus_time, self._result_id, b"", False), why)
        self.assembler.abandon(f"its transfer was cut by {why}")
        if self.counters.get("live_dropped", self._drops_reported) != self._drops_reported:
            self._report_drops()

    def take_results(self) -> list[CurveResult]:
        """Results released (complete or marked incomplete) since the last call, in order."""
        out = list(self._released)
        self._released.clear()
        for res in out:
            self.results.pop(res.number, None)
        return out

    def _counter(self, msg, spec, raw) -> None:
        """A counter's latched count, last edge time (device time) and illegal transitions, unwrapped."""
        edge = self._edge_times(spec.name, np.array([raw["EdgeTime"]]), self._device_time)
        count, illegal = self._counts(spec, {k: np.array([v]) for k, v in raw.items()})
        self.counters_log.append((spec.name, msg.timestamp, int(count[0]), float(edge[0]), int(illegal[0])))

    def _counts(self, spec, raw: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Counter ``spec``'s counts and illegal transitions (0 without that signal; the card's count as sent: it
        saturates at the field's maximum) of frames in arrival order. A count the DBC sends unsigned is unwrapped,
        modulo its range, by a change between two readings of less than half the range (24 bits: ±8.4 M counts), the
        first read as two's complement (the count is 0 at power-on; a shaft turned backwards reads below it)."""
        count = np.asarray(raw["Count"], dtype=np.int64)
        illegal = np.asarray(raw["Illegal"], dtype=np.int64) if "Illegal" in raw else np.zeros(count.size, np.int64)
        sig = spec.get_signal_by_name("Count")
        if sig.is_signed:
            return count, illegal
        m = 1 << sig.length
        last_raw, last = self._wraps.get(spec.name, (int(count[0]), int(count[0]) - (m if count[0] >= m // 2 else 0)))
        unwrapped = last + np.cumsum((np.diff(np.concatenate(([last_raw], count))) + m // 2) % m - m // 2)
        self._wraps[spec.name] = (int(count[-1]), int(unwrapped[-1]))
        return unwrapped, illegal

    def _edge_times(self, name: str, raw: np.ndarray, reference: float | np.ndarray) -> np.ndarray:
        """The device times (s) of counter ``name``'s raw 24-bit ``EdgeTime`` values (µs; in arrival order), against
        the device time ``reference`` at each. A value that differs from the one before it is a new edge, recent
        (latched since the last reading): the time congruent to it nearest ``reference``. An unchanged value is the
        same edge as before, however old (a shaft at rest): its time stays what it was — unwrapping it again would
        move it by a whole wrap into the future once it is more than 8.4 s old."""
        nearest = unwrap(raw * 1e-6, EDGE_WRAP, reference)
        last_raw, last_time = self._edges.get(name, (-1, math.nan))
        new = raw != np.concatenate(([last_raw], raw[:-1]))
        source = np.maximum.accumulate(np.where(new, np.arange(raw.size), -1))   # the reading its edge is from
        out = np.where(source >= 0, nearest[np.maximum(source, 0)], last_time)
        self._edges[name] = (int(raw[-1]), float(out[-1]))
        return out

    def _counter_rows(self, name: str, raw: dict[str, np.ndarray], index: np.ndarray,
                      times: np.ndarray) -> list[tuple[str, float, int, float, int]]:
        """The rows :meth:`_counter` adds for the bulk counter frames ``index`` of message ``name`` (``times``: the
        block's time stamps, s), each edge time unwrapped against the device time as the run's Tick-stamped frames
        before it left it (``_run_clock``)."""
        reference: float | np.ndarray = self._run_device_time
        if self._run_clock is not None:
            ticked, after = self._run_clock
            order = np.argsort(ticked, kind="stable")
            ticked, after = ticked[order], np.maximum.accumulate(after[order])
            k = np.searchsorted(ticked, index)          # Tick-stamped frames of the run before each counter frame
            reference = np.where(k > 0, after[np.maximum(k - 1, 0)], self._run_device_time)
        edge = self._edge_times(name, raw["EdgeTime"], reference)
        count, illegal = self._counts(self.db.get_message_by_name(name), raw)
        return list(zip(itertools.repeat(name), times[index].tolist(), count.tolist(), edge.tolist(), illegal.tolist()))

    def _reading(self, msg, spec, raw) -> None:
        """Readings in the DBC's units at their Tick (device time; the frame's time without one)."""
        t = self._live_time(raw["Tick"]) if "Tick" in raw else msg.timestamp
        self._reading_run(spec, {name: np.array([value]) for name, value in raw.items()}, None, np.array([t]))

    def _reading_run(self, spec, raw: dict[str, np.ndarray], index: np.ndarray | None,
                     t: np.ndarray) -> list[tuple[int, str]]:
        """Reading frames of ``spec`` decoded together (or one: :meth:`_reading`), at ``t`` (their Ticks as device
        times, or the frames' time stamps without one), s."""
        self.readings.append((spec.name, t, {sg.name: raw[sg.name] * sg.scale + sg.offset for sg in spec.signals
                                             if sg.name not in ("Seq", "Tick")}))
        return []

    def take_readings(self) -> dict[str, Any]:
        """Readings received since the last call, and forgets them: ``counters`` (rows: message, received s, count,
        edge time s, the card's illegal transitions since power-on; counts unwrapped) and ``readings`` ({message: (t s, {signal: values in the DBC's unit})}, in arrival order)."""
        blocks: dict[str, list] = {}
        for name, t, values in self.readings:
            blocks.setdefault(name, []).append((t, values))
        readings = {name: (np.concatenate([b[0] for b in got]),
                           {sg: np.concatenate([b[1][sg] for b in got]) for sg in got[0][1]})
                    for name, got in blocks.items()}
        out = {"counters": self.counters_log, "readings": readings}
        self.counters_log, self.readings = [], []
        return out

    def take_drop_reports(self) -> list[dict[str, float]]:
        """Reports of live pairs the unit did not send (at most one per ``drop_period`` of device time, and one
        at the end of the run), since the last call."""
        out, self.drop_reports = self.drop_reports, []
        return out

    def take_events(self) -> list[LinkEvent]:
        """Link events since the last call, and forgets them."""
        out, self.events = self.events, []
        return out

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
        msg = can.Message(timestamp=self._bus_time, arbitration_id=self._command.frame_id, data=data,
                          is_extended_id=False, is_rx=False)
        self.bus.send(msg)
        self._sent.append(msg)
        return seq

    def take_sent(self) -> FrameBlock:
        """The frames this host sent since the last call (RX flag clear), stamped with the latest bus time
        it knew when sending (s)."""
        block, self._sent = FrameBlock.of_messages(self._sent), []
        return block

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

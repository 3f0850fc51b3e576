"""The acquisition unit as a CAN node: frames from ``data/can/rig.dbc`` on any python-can bus.

The node owns a bounded transmit queue and a virtual bus clock. Publishing only queues frames;
:meth:`CanNode.advance_to` puts on the wire what fits up to a virtual time, each frame taking its
worst-case wire time (:mod:`firmware_sim.can_budget`), lowest identifier first among the frames ready
when the bus falls idle (CAN arbitration, :mod:`firmware_sim.can_arbitration`). Each sent frame is
stamped with the virtual time at which its last bit left the wire, in whole microseconds, as a CAN
controller's receive time stamp. On a bus with ``send_block`` (the in-process :class:`rig.blockbus.BlockBus`)
the frames of one advance travel as one block; any other python-can bus gets them one ``send`` each.

The unit's transmit policy (docs/can-protocol.md, "Transmit queue"): curves first. A curve's transfer
(header, timing, blocks, end, result, process values, end marker) is never dropped; at most
``tx_curves`` transfers wait, and a curve beyond that raises :class:`BusOverload` (the configuration
cannot fit the bus). Live data takes at most ``live_share`` of each transmit cycle's bus time (the samples
one :meth:`publish_live` call gives) and only the time the queued transfer and status frames leave free in that
cycle: it is decimated by an integer factor, or dropped, to fit; live frames still queued ``live_max_age`` after
their last sample are stale and dropped. Every pair not sent is counted (``LiveDropped`` in ``StatusCounters``;
stale ones also in ``LiveStale`` of ``TxStatus``).
"""
from __future__ import annotations

import binascii
import math
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Callable
from typing import Any

import can
import numpy as np

from firmware_sim.can_arbitration import DROPPED, PENDING, SENT, arbitrate
from firmware_sim.can_budget import BusTiming
from rig.blockbus import BRS, FD, FrameBlock
from rig.dbc import DBC_PATH, load_dbc

X_LSB = 1e-6                     # m per count of every X signal (20-bit signed)
Y_LSB = 0.005                    # N per count of every Y / force signal (20-bit signed)
FD_PAIRS = 11                    # pairs per 64-byte FD frame
TICK = 1e-4                      # s per count of the 16-bit Tick signals
T_START_LSB, DT_LSB, T_OFFSET_LSB = 1e-6, 1e-9, 1e-5   # s per count: curve start, uniform step, offsets
CURVE_TIME_TOL = 5e-6            # s: a curve is sent as uniformly sampled if that reproduces its times
NO_FAIL = 127
PV_END = 255                     # ResultValue multiplexer value of the end marker
COMMANDS = {1: "start", 2: "stop", 3: "select_program", 4: "tare", 5: "reset_statistics", 6: "identify",
            7: "release"}
TARE_CHANNELS = {0: "x", 1: "y", 2: "y2", 3: None}
STARTING = ("select_program", "start")   # the commands that start a served unit's run (rig serve)
STATES = {"idle": 0, "measuring": 1, "armed": 2}
UNKNOWN_STATE = 15
PROCESS_VALUES = {"XMax": "x_max", "XMin": "x_min", "YMax": "y_max", "YMin": "y_min", "XAtYMax": "x_at_y_max",
                  "YAtXMax": "y_at_x_max", "XEnd": "x_end", "YEnd": "y_end", "Duration": "duration"}


class BusOverload(RuntimeError):
    """More curves wait for the bus than the unit can hold: the configuration cannot fit the bus."""


def quantise(values: np.ndarray, lsb: float, bits: int = 20) -> tuple[np.ndarray, int]:
    """Raw signed ``bits``-bit counts of ``values`` (SI) and how many had to be clipped to the signal range."""
    lo, hi = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    raw = np.rint(np.asarray(values, dtype=float) / lsb)
    clipped = int(np.count_nonzero((raw < lo) | (raw > hi)))
    return np.clip(raw, lo, hi).astype(np.int64), clipped


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

    def pack(self, columns: dict[str, np.ndarray], n: int) -> np.ndarray:
        """Payloads of ``n`` frames as an (n, length) uint8 array; signals missing from ``columns`` are 0."""
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
        return payload[:, :length]


#: frames of one measurement's transfer: they leave one transmit FIFO in order, at the header's priority,
#: so a later curve never overtakes an earlier one (live data and status still win arbitration)
TRANSFER_FRAMES = frozenset({"CurveHeader", "CurveTiming", "CurveTimes", "CurveBlock", "CurveBlockFD", "CurveEnd",
                             "Result", "ResultValue"})
#: the unit's own frames: everything else a device sends in the DBC is a reading (publish_reading)
OWN_FRAMES = TRANSFER_FRAMES | {"Heartbeat", "StatusCounters", "TxStatus", "CommandAck", "LiveXY", "LiveXYFD"}
_COLUMNS = ("ready", "expires", "rank", "frame_id", "duration", "pairs", "transfer_end", "is_fd", "dlc", "data")


@dataclass(slots=True)
class _Batch:
    """Frames queued together, as columns (see :data:`_COLUMNS`)."""

    ready: np.ndarray          # s: earliest start on the wire
    expires: np.ndarray        # s: dropped if not started by then (inf: never)
    rank: np.ndarray           # priority << 40 | enqueue order: arbitration order
    frame_id: np.ndarray
    duration: np.ndarray       # s: worst-case wire time
    pairs: np.ndarray          # live pairs carried
    transfer_end: np.ndarray   # last frame of a curve's transfer
    is_fd: np.ndarray
    dlc: np.ndarray
    data: np.ndarray           # (n, width) payloads, Seq byte filled at transmission


class _TxQueue:
    """The node's transmit queue: batches appended, merged at transmission, unsent frames kept."""

    def __init__(self, width: int) -> None:
        self.width = width
        self._batches: list[_Batch] = []
        self.frames = 0
        self.transfer_time = 0.0       # s: wire time of queued frames that never go stale (all but live)
        self.transfers = 0             # curve transfers queued and not finished

    def add(self, batch: _Batch) -> None:
        self._batches.append(batch)
        self.frames += batch.ready.size
        self.transfer_time += float(batch.duration[np.isinf(batch.expires)].sum())
        self.transfers += int(batch.transfer_end.sum())

    def merged(self) -> _Batch | None:
        """All queued frames as one batch (None when empty)."""
        if not self._batches:
            return None
        if len(self._batches) > 1:
            self._batches = [_Batch(*(np.concatenate([getattr(b, c) for b in self._batches]) for c in _COLUMNS))]
        return self._batches[0]

    def remove(self, batch: _Batch, gone: np.ndarray) -> None:
        """Take the frames ``gone`` (a mask of the merged batch: sent or dropped) out of the queue."""
        self.frames -= int(gone.sum())
        self.transfer_time -= float(batch.duration[gone & np.isinf(batch.expires)].sum())
        self.transfers -= int(batch.transfer_end[gone].sum())
        keep = ~gone
        self._batches = [_Batch(*(getattr(batch, c)[keep] for c in _COLUMNS))] if keep.any() else []
        if not self._batches:
            self.transfer_time = 0.0


def _filled(value: Any, n: int, dtype: Any) -> np.ndarray:
    """``value`` (one value, or ``n`` of them) as a new array of ``n`` values of ``dtype``."""
    return np.full(n, value, dtype) if np.ndim(value) == 0 else np.array(value, dtype).reshape(n)


class CanNode:
    """DigiForce-style device on a python-can bus, with a bit budget in virtual time.

    ``device`` provides ``select_program, start, stop, tare, reset_statistics, identify, status,
    last_result`` (see ``firmware_sim.digiforce``). ``bitrate`` (bit/s) is the nominal bitrate;
    ``fd=True`` sends live data and curve blocks in 64-byte CAN FD frames, with the data phase at
    ``data_bitrate`` (bit/s, bitrate switch) if given. ``tx_curves``: curve transfers the unit holds
    for sending (a further one raises :class:`BusOverload`).
    """

    def __init__(self, bus: can.BusABC, device: Any, bitrate: float = 500_000, fd: bool = False,
                 data_bitrate: float | None = None, *, live_share: float = 0.5, live_max_age: float = 0.05,
                 heartbeat_period: float = 0.1, tx_curves: int = 4, t0: float = 0.0,
                 dbc_path: str | Path = DBC_PATH) -> None:
        if not 0.0 < live_share <= 1.0:
            raise ValueError(f"live_share must be in (0, 1], got {live_share}")
        if not heartbeat_period > 0 or not live_max_age > 0:
            raise ValueError("heartbeat_period and live_max_age must be positive (s)")
        if int(tx_curves) < 1:
            raise ValueError(f"tx_curves must be >= 1, got {tx_curves}")
        self.bus, self.device = bus, device
        self.timing = BusTiming(float(bitrate), fd, None if data_bitrate is None else float(data_bitrate))
        self.db = load_dbc(str(dbc_path))
        self._msg = {m.name: m for m in self.db.messages}
        self._stop_causes = {str(name): value for value, name in
                             self._msg["TxStatus"].get_signal_by_name("StopCause").choices.items()}
        for m in self.db.messages:
            if "DEVICE" in m.senders and not any(s.name == "Seq" and s.start == 0 and s.length == 8 for s in m.signals):
                raise ValueError(f"{dbc_path}: device frame {m.name} must start with the 8-bit Seq counter")
        self.live_share, self.live_max_age, self.heartbeat_period = live_share, live_max_age, heartbeat_period
        self.tx_curves = int(tx_curves)
        self.now = float(t0)             # device time of the last advance_to (s)
        self.bus_free = float(t0)        # virtual time at which the bus is next idle (s)
        self._next_heartbeat = float(t0)
        self._queue = _TxQueue(64 if fd else 8)
        self._order = 0                  # enqueue counter (low bits of the arbitration rank)
        self._seq: dict[int, int] = {}
        self._packing: dict[str, _Packing] = {}
        self._signals: dict[str, dict[str, Any]] = {}        # reading message -> its DBC signals by name
        self._published_result: Any = None
        self._send_block = getattr(bus, "send_block", None)
        self.live_dropped = 0            # live pairs not sent (decimated, throttled or stale)
        self.live_stale = 0              # of which: dropped because stale
        self.live_factor = 0             # decimation of the last live chunk (0: none sent, as before the first)
        self.live_sent = 0
        self.clipped = 0                 # values saturated to the signal range
        self.frames_discarded = 0        # queued frames a stopped run did not send (abort)
        self.ended = False               # the run's last frame (TxStatus RunEnded) is queued: nothing follows
        self.stop_cause = ""             # then its StopCause
        self.rx_errors: list[str] = []   # malformed or unexpected frames received
        self.curves_measured = 0
        self.released = False            # the host said it is done (HostCommand Release)
        # Set while a served unit waits for its run (rig serve's idle phase): every command but an accepted
        # SelectProgram or Start is acknowledged through it, at once (by the idle node); the first accepted one
        # starts the run, is acknowledged here at device time 0 and clears it.
        self.before_run: Callable[[dict[str, int]], None] | None = None
        # the scheduler's compiled kernel loaded now (from numba's cache; a process's first compiled call also starts
        # numba, ≈ 0.2 s), as a unit boots before it measures: not in the first chunk of a run
        arbitrate(np.zeros(0), np.zeros(0, np.int64), np.zeros(0), np.zeros(0), np.zeros(0, np.int64), 0.0, 0.0)

    # ------------------------------------------------------------------ queueing
    def _priority(self, name: str) -> int:
        return self._msg["CurveHeader" if name in TRANSFER_FRAMES else name].frame_id

    def _add(self, name: str, payload: np.ndarray, ready: np.ndarray, expires: np.ndarray | None = None,
             pairs: np.ndarray | int = 0, transfer_end: np.ndarray | bool = False) -> None:
        """Queue the frames of DBC message ``name`` whose payloads are the rows of ``payload``."""
        msg = self._msg[name]
        n = payload.shape[0]
        data = np.zeros((n, self._queue.width), np.uint8)
        data[:, :payload.shape[1]] = payload
        rank = (self._priority(name) << 40) | (self._order + np.arange(n, dtype=np.int64))
        self._order += n
        self._queue.add(_Batch(np.asarray(ready, float).reshape(n),
                               _filled(np.inf if expires is None else expires, n, float), rank,
                               _filled(msg.frame_id, n, np.int64),
                               _filled(self.timing.frame_time(msg.frame_id, bytes(msg.length), msg.is_fd), n, float),
                               _filled(pairs, n, np.int64), _filled(transfer_end, n, bool), _filled(msg.is_fd, n, bool),
                               _filled(msg.length, n, np.int16), data))

    def _enqueue(self, name: str, signals: dict[str, Any], ready: float, transfer_end: bool = False) -> None:
        """Queue one frame encoded by cantools (Seq is filled in at transmission)."""
        msg = self._msg[name]
        data = msg.encode({"Seq": 0, **signals}, scaling=False, padding=False, strict=False)  # ranges: see quantise()
        self._add(name, np.frombuffer(data, np.uint8).reshape(1, -1), np.array([ready]), transfer_end=transfer_end)

    def _enqueue_rows(self, name: str, columns: dict[str, np.ndarray], ready: np.ndarray,
                      expires: np.ndarray | None = None, pairs: int | np.ndarray = 0) -> None:
        """Queue one frame per row of ``columns`` (raw integer signal values; missing ones are 0), packed
        with numpy (:class:`_Packing`); ``pairs``: live pairs carried, per frame or for all."""
        packing = self._packing.get(name)
        if packing is None:
            packing = self._packing[name] = _Packing(self._msg[name])
        ready = np.asarray(ready, float)
        self._add(name, packing.pack(columns, ready.size), ready, expires, pairs)

    def frame_time_planned(self, name: str) -> float:
        """Worst-case wire time (s) of one frame of DBC message ``name`` on this bus."""
        msg = self._msg[name]
        return self.timing.frame_time(msg.frame_id, bytes(msg.length), msg.is_fd)

    @property
    def pending_frames(self) -> int:
        """Frames queued and not yet on the wire."""
        return self._queue.frames

    @property
    def backlog_time(self) -> float:
        """Wire time (s) of the queued frames that wait until sent (transfers and status; not live)."""
        return max(self._queue.transfer_time, 0.0)

    def has_pending_before(self, t: float) -> bool:
        """Whether any frame queued for sending at or before time ``t`` (s) is not yet on the wire."""
        batch = self._queue.merged()
        return batch is not None and bool(np.any(batch.ready <= t))

    @property
    def curves_pending(self) -> int:
        """Curves whose transfer has not finished."""
        return self._queue.transfers

    # ------------------------------------------------------------------ publishing
    def publish_live(self, t: np.ndarray, x: np.ndarray, y: np.ndarray) -> int:
        """Queue live pairs sampled at uniformly spaced times ``t`` (s; one transmit cycle); X in m, Y in N.

        The cycle gets at most ``live_share`` of its bus time, and no more than the queued transfer and
        status frames leave free in it (curves first). Only pairs sampled on the ``Tick`` grid (100 µs) are sent,
        so that every stamp is exact (at 20 kHz every other one), decimated by the smallest integer factor that
        fits; returns the factor against the samples (0: nothing fits, the cycle's pairs are dropped). Pairs not sent
        are counted in :attr:`live_dropped`.
        """
        t, x, y = (np.asarray(a, dtype=float) for a in (t, x, y))
        if t.ndim != 1 or t.size < 2 or x.shape != t.shape or y.shape != t.shape:
            raise ValueError(f"publish_live needs equal-length 1-D t, x, y with >= 2 samples, got {t.shape}, {x.shape}, {y.shape}")
        dt = (t[-1] - t[0]) / (t.size - 1)
        if not dt > 0 or not np.allclose(np.diff(t), dt, rtol=1e-6, atol=1e-12):
            raise ValueError("publish_live needs strictly increasing, uniformly spaced sample times")
        name, per_frame = ("LiveXYFD", FD_PAIRS) if self.timing.fd else ("LiveXY", 1)
        free = max(0.0, t[-1] - max(self.bus_free, t[0] - dt) - self.backlog_time)
        budget = min(self.live_share * t.size * dt, free)
        fits = int(budget / self.frame_time_planned(name) + 1e-9) * per_frame
        ticks_at = t / TICK
        grid = np.flatnonzero(np.abs(ticks_at - np.rint(ticks_at)) < 1e-3)  # a Tick stamp is exact only on its
        if fits == 0 or grid.size == 0:                                      # 100 µs grid: 20 kHz sends every other
            self.live_dropped += t.size
            self.live_factor = 0
            return 0
        step = int(grid[1] - grid[0]) if grid.size > 1 else 1                # samples from one grid sample to the next
        keep = grid[::-(-grid.size // fits)]
        factor = self.live_factor = step * -(-grid.size // fits)
        tk, (rx, cx), (ry, cy) = t[keep], quantise(x[keep], X_LSB), quantise(y[keep], Y_LSB)
        self.clipped += cx + cy
        self.live_dropped += t.size - tk.size
        ticks = np.rint(ticks_at[keep]).astype(np.int64) % 65536
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
        """Queue the transfer of one measurement at time ``t`` (s): curve header, timing, blocks, end,
        result, its process values and the end marker (``ResultValue`` Pv 255: which values were sent).

        :meth:`advance_to` calls this for a new ``device.last_result`` not yet published this way. Raises
        :class:`BusOverload` (after queueing: nothing is lost) when more than ``tx_curves`` transfers wait.
        """
        ct, cx, cy = (np.asarray(a, dtype=float) for a in (result.curve.t, result.curve.x, result.curve.y))
        if cx.shape != cy.shape or ct.shape != cx.shape or cx.ndim != 1 or not 0 < cx.size < 65536:
            raise ValueError(f"curve of result {result.number}: t, x, y must be 1-D, equal length, 1..65535 pairs")
        if not self.timing.fd and cx.size > 4096:
            raise ValueError(f"curve of result {result.number} has {cx.size} pairs; classic CAN blocks index at most 4096")
        number = int(result.number) % 65536
        (rx, kx), (ry, ky) = quantise(cx, X_LSB), quantise(cy, Y_LSB)
        self.clipped += kx + ky
        self.curves_measured += 1
        self._published_result = result
        start = int(round(ct[0] / T_START_LSB))
        self._enqueue("CurveHeader", {"CurveNo": number, "Count": cx.size, "Program": int(result.program) % 256,
                                      "TStartHigh": (start >> 24) & 0xFFFF}, t)
        kt = self._enqueue_curve_times(number, ct, start, t)
        if self.timing.fd:
            blocks = -(-cx.size // FD_PAIRS)
            self._enqueue_rows("CurveBlockFD", {"CurveNo": np.full(blocks, number % 256), "Block": np.arange(blocks),
                                                "NPairs": np.minimum(cx.size - FD_PAIRS * np.arange(blocks), FD_PAIRS),
                                                **_fd_pairs(rx, ry)}, np.full(blocks, float(t)))
        else:
            self._enqueue_rows("CurveBlock", {"CurveNo": np.full(cx.size, number % 16), "Block": np.arange(cx.size),
                                              "X": rx, "Y": ry}, np.full(cx.size, float(t)))
        self._enqueue("CurveEnd", {"CurveNo": number, "Count": cx.size, "Crc": curve_crc(rx, ry),
                                   "Clipped": min(kx + ky + kt, 255)}, t)
        failed = [i for i, e in enumerate(result.elements) if not e.ok]
        self._enqueue("Result", {"CurveNo": number, "Ok": int(bool(result.ok)),
                                 "FirstFail": failed[0] if failed and failed[0] < NO_FAIL else NO_FAIL,
                                 "FailMask": sum(1 << i for i in failed if i < 32)}, t)
        mask = 0
        for pv, (signal, key) in enumerate(PROCESS_VALUES.items()):
            if key in result.process_values:
                self._enqueue("ResultValue", {"CurveNo": number % 256, "Pv": pv,
                                              signal: float(result.process_values[key])}, t)
                mask |= 1 << pv
        self._enqueue("ResultValue", {"CurveNo": number % 256, "Pv": PV_END, "PvMask": mask,
                                      "PvCount": bin(mask).count("1"),
                                      "MemoryFull": int(bool(getattr(result.curve, "overflow", False))),
                                      "Decimated": int(getattr(result.curve, "decimations", 0) > 0)},
                      t, transfer_end=True)
        if self.curves_pending > self.tx_curves:
            kind = f"CAN FD {self.timing.bitrate:g}/{self.timing.fast_bitrate:g}" if self.timing.fd else \
                f"classic CAN {self.timing.bitrate:g}"
            raise BusOverload(f"the {kind} bit/s bus cannot carry the curves: {self.curves_pending} curve transfers "
                              f"wait at {t:.3f} s (the unit holds {self.tx_curves}), {self.backlog_time:.2f} s of frames "
                              "queued. Raise [links.can] bitrate, use CAN FD, lower the sample rate or sample by ΔX.")

    def _enqueue_curve_times(self, number: int, ct: np.ndarray, start: int, t: float) -> int:
        """CurveTiming (start in µs and uniform step), plus CurveTimes offsets if the sampling is not uniform; the
        number of offsets saturated (a non-uniform curve longer than the 20-bit field's 10.49 s)."""
        step = int(round((ct[-1] - ct[0]) / max(ct.size - 1, 1) / DT_LSB))
        grid = start * T_START_LSB + np.arange(ct.size) * step * DT_LSB
        uniform = ct.size > 1 and 0 < step < (1 << 24) and np.max(np.abs(ct - grid)) <= CURVE_TIME_TOL
        self._enqueue("CurveTiming", {"CurveNo": number % 256, "Dt": step if uniform else 0,
                                      "TStart": start % (1 << 24)}, t)
        if uniform:
            return 0
        raw = np.rint((ct - start * T_START_LSB) / T_OFFSET_LSB)
        saturated = int(np.count_nonzero((raw < 0) | (raw >= 1 << 20)))
        self.clipped += saturated
        raw = np.clip(raw, 0, (1 << 20) - 1).astype(np.int64)
        pairs = np.append(raw, 0)[:2 * (-(-ct.size // 2))].reshape(-1, 2)
        self._enqueue_rows("CurveTimes", {"CurveNo": np.full(len(pairs), number % 16), "Block": np.arange(len(pairs)),
                                          "T0": pairs[:, 0], "T1": pairs[:, 1]}, np.full(len(pairs), float(t)))
        return saturated

    def publish_reading(self, name: str, t: float | np.ndarray, values: dict[str, Any]) -> None:
        """Queue readings taken at times ``t`` (s) in frames of DBC message ``name``: ``values`` maps its signal
        names to physical values (the DBC's units; one per reading or one for all). Signed signals are quantised
        with the DBC scale and clipped to their range (counted in :attr:`clipped`); unsigned ones are device-time
        stamps and wrap modulo their range (``EdgeTime``); ``Tick`` is the reading time unless given; signals
        not given are 0. The scene's wiring (``to = "can.MESSAGE[.SIGNAL]"``) says which transducer fills which."""
        msg = self._msg.get(name)
        if msg is None or name in OWN_FRAMES or "DEVICE" not in msg.senders:
            raise ValueError(f"{name!r} is not a device reading message of the DBC")
        t = np.atleast_1d(np.asarray(t, float))
        signals = self._signals.get(name) or self._signals.setdefault(name, {s.name: s for s in msg.signals})
        stamps = {"Tick": t} if "Tick" in signals else {}
        columns = {}
        for signal, value in {**stamps, **values}.items():
            spec = signals.get(signal)
            if spec is None or signal == "Seq":
                raise ValueError(f"{name} has no signal {signal!r} (it has "
                                 f"{', '.join(s.name for s in msg.signals if s.name != 'Seq')})")
            value = np.broadcast_to(np.asarray(value, float), t.shape)
            if spec.is_signed:
                columns[signal], clipped = quantise(value, spec.scale, spec.length)
                self.clipped += clipped
            else:
                columns[signal] = np.rint(value / spec.scale).astype(np.int64) % (1 << spec.length)
        self._enqueue_rows(name, columns, t)

    def publish_status(self, t: float, run_ended: bool = False, stop_cause: str = "Completed",
                       backlog: float | None = None) -> None:
        """Queue a heartbeat, the status counters and the transmit-queue status at time ``t`` (s); ``stop_cause``: a
        ``StopCause`` choice of the DBC (with ``run_ended``), ``backlog``: the wire time (s) reported instead of the
        queue's."""
        status = self.device.status()
        state, last = self.device.state_at(t)         # at t, which may lie inside the chunk just fed
        self._enqueue("Heartbeat", {
            "State": STATES.get(state, UNKNOWN_STATE),
            "LastOk": 2 if last is None else int(bool(last.ok)),
            "Program": int(status.get("program", 0)) % 256,
            "DeviceTime": int(round(t * 1000)) % (1 << 32),
            "Errors": min(len(status.get("errors", ())), 255)}, t)
        self._enqueue("StatusCounters", {"LiveDropped": self.live_dropped % (1 << 32),
                                         "CurveCount": self.curves_measured % 65536,
                                         "CurvesPending": min(self.curves_pending, 255)}, t)
        backlog = self.backlog_time if backlog is None else backlog
        self._enqueue("TxStatus", {"Backlog": min(int(round(backlog * 1000)), 65535),
                                   "LiveFactor": min(self.live_factor, 255), "LiveStale": self.live_stale % (1 << 24),
                                   "RunEnded": int(run_ended), "StopCause": self._stop_causes[stop_cause]}, t)

    # ------------------------------------------------------------------ host commands
    def handle_commands(self) -> int:
        """Apply every host command waiting on the bus at the device time :attr:`now` (each is acknowledged);
        returns how many were carried out (a rejected one — a short frame, an unknown command, a refused
        argument — does not count). While :attr:`before_run` is set only an accepted SelectProgram or Start
        counts (it starts the run)."""
        done = 0
        while (msg := self.bus.recv(timeout=0.0)) is not None:
            if msg.arbitration_id != self._msg["HostCommand"].frame_id or msg.is_extended_id or msg.is_error_frame:
                continue                     # other nodes' traffic is not for us (0x00000050 is not 0x050)
            if len(msg.data) == 8:
                cmd = self._msg["HostCommand"].decode(bytes(msg.data), decode_choices=False)
                status = self._apply(int(cmd["Cmd"]), int(cmd["Arg"]))
            else:                            # not executed: rejected, echoing the fields it has (missing: 0)
                self.rx_errors.append(f"HostCommand frame with {len(msg.data)} data bytes rejected (expected 8)")
                cmd = dict(zip(("Cmd", "Arg", "HostSeq"), bytes(msg.data[:3]).ljust(3, b"\0")))
                status = 1
            ack = {"Cmd": int(cmd["Cmd"]), "Arg": int(cmd["Arg"]), "HostSeq": int(cmd["HostSeq"]), "AckStatus": status}
            if self.before_run is not None and not (status == 0 and COMMANDS.get(ack["Cmd"]) in STARTING):
                self.before_run(ack)
                continue
            self.before_run = None
            self.acknowledge(ack)
            done += status == 0
        return done

    def acknowledge(self, ack: dict[str, int]) -> None:
        """Queue a ``CommandAck`` with these signals at the device time :attr:`now`."""
        self._enqueue("CommandAck", ack, self.now)

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
            elif name == "release":
                self.released = True
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

    def close(self, t: float, cause: str = "Completed") -> int:
        """End of the run at time ``t`` (s): the final status (``RunEnded`` set, ``StopCause`` ``cause``), then
        everything still queued goes on the wire; no heartbeat follows. Returns the number of frames sent."""
        self._check_cause(cause)
        self.now = max(self.now, float(t))
        self._next_heartbeat = math.inf
        self.publish_status(self.now, run_ended=True, stop_cause=cause)
        self.ended, self.stop_cause = True, cause
        return self._transmit(self.now + self.backlog_time + 1.0)

    def _check_cause(self, cause: str, stop: bool = False) -> None:
        """``cause`` must be a ``StopCause`` choice of the DBC (``stop``: other than ``Completed``)."""
        if cause not in self._stop_causes or (stop and cause == "Completed"):
            known = [c for c in self._stop_causes if not (stop and c == "Completed")]
            raise ValueError(f"unknown stop cause {cause!r} (the DBC's TxStatus.StopCause has {', '.join(known)})")

    def abort(self, cause: str) -> int:
        """The run stops at :attr:`now` for ``cause`` (a ``StopCause`` choice of the DBC other than ``Completed``):
        the unit discards what it still has queued (counted in :attr:`frames_discarded`, its live pairs in
        :attr:`live_dropped`; its wire time is the final ``TxStatus.Backlog``) and sends its final status at once
        (``RunEnded`` set, ``StopCause`` named); nothing follows. Nothing happens once the run has ended. Returns the
        number of frames sent."""
        if self.ended:
            return 0
        self._check_cause(cause, stop=True)
        backlog = self.backlog_time
        q = self._queue.merged()
        if q is not None:
            self.frames_discarded += q.ready.size
            self.live_dropped += int(q.pairs.sum())
            self._queue.remove(q, np.ones(q.ready.size, bool))
        self._next_heartbeat = math.inf
        self.publish_status(self.now, run_ended=True, stop_cause=cause, backlog=backlog)
        self.ended, self.stop_cause = True, cause
        return self._transmit(self.now + 1.0)

    def _transmit(self, t: float) -> int:
        """Send the queued frames that are complete on the wire by ``t`` (s), in arbitration order."""
        q = self._queue.merged()
        if q is None:
            self.bus_free = max(self.bus_free, t)
            return 0
        state, ends, order, self.bus_free = arbitrate(q.ready, q.rank, q.duration, q.expires,
                                                      np.argsort(q.ready, kind="stable"), self.bus_free, float(t))
        sent, dropped = state == SENT, state == DROPPED
        self.live_stale += int(q.pairs[dropped].sum())
        self.live_dropped += int(q.pairs[dropped].sum())
        self.live_sent += int(q.pairs[sent].sum())
        if order.size:
            self._send(q, order, ends[order])
        self._queue.remove(q, state != PENDING)
        return int(order.size)

    def _send(self, q: _Batch, order: np.ndarray, ends: np.ndarray) -> None:
        """Fill in the Seq counters of the frames ``order`` (wire order) and put them on the bus."""
        data, fid = q.data[order], q.frame_id[order]
        for f in np.unique(fid).tolist():
            rows = np.flatnonzero(fid == f)
            first = self._seq.get(f, 0)
            data[rows, 0] = (first + np.arange(rows.size)) % 256
            self._seq[f] = (first + rows.size) % 256
        fd = q.is_fd[order]
        flags = np.where(fd, FD | (BRS if self.timing.data_bitrate is not None else 0), 0).astype(np.uint8)
        block = FrameBlock(np.rint(ends * 1e6) / 1e6, fid.astype(np.uint32), q.dlc[order], data, flags)
        if self._send_block is not None:
            self._send_block(block)
        else:
            for msg in block.messages():
                self.bus.send(msg)

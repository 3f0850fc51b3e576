"""Frames in blocks: :class:`FrameBlock` (columns of many CAN frames) and :class:`BlockBus`, an in-process
python-can bus that carries them without a ``can.Message`` per frame.

``BlockBus`` is registered with python-can as interface ``"blockbus"`` (entry point ``can.interface``), so
``can.Bus(interface="blockbus", channel=...)`` opens it like any other bus and code written against
``can.BusABC`` (``send``/``recv``) works unchanged. Peers that know blocks exchange them whole with
:meth:`BlockBus.send_block` / :meth:`BlockBus.recv_blocks`: one shared, read-only block per send, delivered
to every other bus on the channel; per-frame ``recv`` unpacks a block frame by frame. Time stamps are
always kept (a virtual-time rig's frames carry the time their last bit left the wire). Across processes
or on real hardware the rig uses python-can's own interfaces (socketcand, socketcan, pcan, ...).
"""
from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass
from typing import Iterable, Sequence

import can
import numpy as np

FD, BRS, ESI, EXTENDED, ERROR, RX, REMOTE = (1 << k for k in range(7))   # bits of FrameBlock.flags
WIDTH = 64                                   # payload bytes per row (the largest CAN FD frame)


@dataclass(frozen=True, slots=True, eq=False)
class FrameBlock:
    """``n`` CAN frames as columns: ``timestamp`` (s, float64), ``arbitration_id`` (uint32), ``dlc`` (data
    bytes, int16), ``data`` (uint8, shape (n, w), bytes past ``dlc`` are 0) and ``flags`` (uint8 bits
    :data:`FD`, :data:`BRS`, :data:`ESI`, :data:`EXTENDED`, :data:`ERROR`, :data:`RX`, :data:`REMOTE`)."""

    timestamp: np.ndarray
    arbitration_id: np.ndarray
    dlc: np.ndarray
    data: np.ndarray
    flags: np.ndarray

    def __post_init__(self) -> None:
        n = self.timestamp.shape[0]
        if any(a.shape[0] != n for a in (self.arbitration_id, self.dlc, self.data, self.flags)) or self.data.ndim != 2:
            raise ValueError("FrameBlock: columns must have one row per frame and data must be 2-D")
        if n and int(self.dlc.max()) > self.data.shape[1]:
            raise ValueError(f"FrameBlock: a frame has {int(self.dlc.max())} data bytes, rows hold {self.data.shape[1]}")

    def __len__(self) -> int:
        return self.timestamp.shape[0]

    @classmethod
    def empty(cls) -> "FrameBlock":
        return cls(np.zeros(0), np.zeros(0, np.uint32), np.zeros(0, np.int16), np.zeros((0, 8), np.uint8),
                   np.zeros(0, np.uint8))

    @classmethod
    def of_messages(cls, messages: Sequence[can.Message]) -> "FrameBlock":
        """The block of python-can messages (in order)."""
        n = len(messages)
        width = max([8] + [len(m.data) for m in messages])
        data = np.zeros((n, width), np.uint8)
        for i, m in enumerate(messages):
            data[i, :len(m.data)] = np.frombuffer(bytes(m.data), np.uint8)
        flags = np.array([FD * m.is_fd | BRS * m.bitrate_switch | ESI * m.error_state_indicator
                          | EXTENDED * m.is_extended_id | ERROR * m.is_error_frame | RX * m.is_rx
                          | REMOTE * m.is_remote_frame for m in messages], np.uint8)
        return cls(np.array([m.timestamp for m in messages], float),
                   np.array([m.arbitration_id for m in messages], np.uint32),
                   np.array([len(m.data) for m in messages], np.int16), data, flags.reshape(n))

    @classmethod
    def concat(cls, blocks: Sequence["FrameBlock"]) -> "FrameBlock":
        """One block of several, in order."""
        blocks = [b for b in blocks if len(b)]
        if not blocks:
            return cls.empty()
        if len(blocks) == 1:
            return blocks[0]
        width = max(b.data.shape[1] for b in blocks)
        data = np.zeros((sum(len(b) for b in blocks), width), np.uint8)
        row = 0
        for b in blocks:
            data[row:row + len(b), :b.data.shape[1]] = b.data
            row += len(b)
        return cls(*(np.concatenate([getattr(b, f) for b in blocks]) for f in ("timestamp", "arbitration_id", "dlc")),
                   data, np.concatenate([b.flags for b in blocks]))

    def take(self, index: np.ndarray | slice) -> "FrameBlock":
        """The frames at ``index`` (an index array, boolean mask or slice)."""
        return FrameBlock(self.timestamp[index], self.arbitration_id[index], self.dlc[index], self.data[index],
                          self.flags[index])

    def payload(self, i: int) -> bytes:
        """Data bytes of frame ``i``."""
        return self.data[i, :self.dlc[i]].tobytes()

    def message(self, i: int, channel: str | None = None) -> can.Message:
        """Frame ``i`` as a python-can message."""
        f = int(self.flags[i])
        return can.Message(timestamp=float(self.timestamp[i]), arbitration_id=int(self.arbitration_id[i]),
                           is_extended_id=bool(f & EXTENDED), is_remote_frame=bool(f & REMOTE),
                           is_error_frame=bool(f & ERROR), channel=channel, dlc=int(self.dlc[i]),
                           data=self.payload(i), is_fd=bool(f & FD), is_rx=bool(f & RX),
                           bitrate_switch=bool(f & BRS), error_state_indicator=bool(f & ESI))

    def messages(self, channel: str | None = None) -> list[can.Message]:
        return [self.message(i, channel) for i in range(len(self))]


def ids_out_of_range(ids: np.ndarray, extended: np.ndarray) -> np.ndarray:
    """Which arbitration ids do not fit their frame's format (11-bit standard, 29-bit extended)."""
    ids = np.asarray(ids, np.int64)
    return (ids < 0) | (ids > np.where(np.asarray(extended, bool), 0x1FFFFFFF, 0x7FF))


def is_interface_name(name: str) -> bool:
    """Whether ``name`` can name a CAN interface (channel): not empty, no white space (candump's .log and SocketCAN
    take a single word)."""
    return bool(name) and not any(ch.isspace() for ch in name)


def frames_of(received: Iterable[FrameBlock | can.Message]) -> FrameBlock:
    """One block of what a receiver got, blocks and single messages mixed, in order."""
    blocks, singles = [], []
    for item in received:
        if isinstance(item, FrameBlock):
            if singles:
                blocks.append(FrameBlock.of_messages(singles))
                singles = []
            blocks.append(item)
        else:
            singles.append(item)
    if singles:
        blocks.append(FrameBlock.of_messages(singles))
    return FrameBlock.concat(blocks)


_channels: dict[str, list["BlockBus"]] = {}
_channels_lock = threading.Lock()


class BlockBus(can.BusABC):
    """In-process bus on a named ``channel``: every frame sent by one bus reaches every other bus on it.

    ``receive_own_messages`` is not supported (a sender never sees its own frames).
    """

    def __init__(self, channel: str = "blockbus", **kwargs) -> None:
        super().__init__(channel=channel, **kwargs)
        self.channel_info = f"mechrig block bus, channel {channel!r}"
        self._channel = str(channel)
        self._rx: deque[FrameBlock] = deque()
        self._head = 0                     # frames of _rx[0] already taken one by one
        self._pending = 0                  # frames received and not yet taken
        self._open = True
        self.sent = 0                      # frames this bus has sent
        self.reading = False               # something has asked it for frames (a consumer is there)
        self.dropped = 0                   # frames dropped unread (overflow)
        self._ready = threading.Condition(threading.Lock())     # notified on arrivals, takes and shutdown
        with _channels_lock:
            _channels.setdefault(self._channel, []).append(self)

    def _peers(self) -> list["BlockBus"]:
        with _channels_lock:
            return [b for b in _channels.get(self._channel, ()) if b is not self]

    def send_block(self, block: FrameBlock) -> None:
        """Deliver ``block`` to every other bus on the channel (shared, made read-only)."""
        if not len(block):
            return
        for a in (block.timestamp, block.arbitration_id, block.dlc, block.data, block.flags):
            a.flags.writeable = False
        self.sent += len(block)
        for peer in self._peers():
            with peer._ready:
                peer._rx.append(block)
                peer._pending += len(block)
                peer._ready.notify_all()

    @property
    def pending(self) -> int:
        """Frames received and not yet taken (read without the lock: a snapshot)."""
        return self._pending

    @property
    def closed(self) -> bool:
        return not self._open

    def wait_pending_below(self, frames: int, timeout: float) -> bool:
        """Wait up to ``timeout`` s until fewer than ``frames`` frames wait here (or the bus is shut down, when none
        will be taken any more); whether that is so. A sender that waits for its receiver's room before sending
        bounds what waits between them (the served machine's back-pressure)."""
        with self._ready:
            return self._ready.wait_for(lambda: self._pending < frames or not self._open, timeout)

    def overflow(self, keep: int) -> int:
        """Drop the oldest waiting frames, whole blocks, while at least ``keep`` would still wait without the block (a
        receiver that does not read, as a CAN interface's receive queue overflows: fewer than ``keep`` plus one block
        stay); how many were dropped, also added to :attr:`dropped`."""
        gone = 0
        with self._ready:
            while self._rx and self._pending - (len(self._rx[0]) - self._head) >= keep:
                n = len(self._rx.popleft()) - self._head
                self._head, self._pending, gone = 0, self._pending - n, gone + n
            if gone:
                self.dropped += gone
                self._ready.notify_all()
        return gone

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.send_block(FrameBlock.of_messages([msg]))

    def recv_blocks(self, timeout: float | None = 0.0, limit: int | None = None) -> list[FrameBlock]:
        """Every block waiting (waits up to ``timeout`` s for the first; None: forever); with ``limit``, whole blocks
        until they hold ``limit`` frames or more (at least one block), the rest left waiting."""
        self.reading = True
        with self._ready:
            if not self._rx and timeout != 0.0:
                self._ready.wait_for(lambda: bool(self._rx), timeout)
            head, self._head = self._head, 0
            if limit is None:
                blocks, self._rx = list(self._rx), deque()
                self._pending = 0
            else:
                blocks, taken = [], -head
                while self._rx and (taken < limit or not blocks):     # at least one block, whatever the limit
                    blocks.append(self._rx.popleft())
                    taken += len(blocks[-1])
                self._pending -= max(taken, 0)
            self._ready.notify_all()
        if blocks and head:
            blocks[0] = blocks[0].take(slice(head, None))
        return blocks

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        self.reading = True
        with self._ready:
            if not self._rx and timeout != 0.0:
                self._ready.wait_for(lambda: bool(self._rx), timeout)
            if not self._rx:
                return None, False
            block, i = self._rx[0], self._head
            self._head += 1
            self._pending -= 1
            if self._head >= len(block):
                self._rx.popleft()
                self._head = 0
            if self._pending % 1024 == 0:      # a waiting sender need not wake for every frame taken
                self._ready.notify_all()
        return block.message(i, self._channel), False

    def shutdown(self) -> None:
        with self._ready:
            self._open = False
            self._rx, self._head, self._pending = deque(), 0, 0     # nothing will take them: not kept
            self._ready.notify_all()
        with _channels_lock:
            peers = _channels.get(self._channel, [])
            if self in peers:
                peers.remove(self)
            if not peers:
                _channels.pop(self._channel, None)
        super().shutdown()

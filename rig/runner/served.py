"""The CAN clock of a served machine (``rig serve``), on both ends of socketcand.

On the wire every frame carries Unix time, as socketcand's would. The machine keeps its virtual device
time; :class:`Anchored` adds an origin (s of Unix time) to the stamps of what it sends:

* idle, before a host starts the run: :class:`IdleStatus` sends heartbeat and status frames from a
  throwaway node whose clock is the wall clock (origin: the wall-clock time the node started), and the
  answers to the commands that do not start the run;
* the run: the machine's own node, untouched by the idle phase (its time and ``Seq`` counters start at
  0), with origin ``ceil(wall clock at the go)``, a whole second, so stamps never go back.

:class:`RunClock` is the host's side: it drops the idle frames, i.e. everything before the
``CommandAck`` accepting the host's SelectProgram or Start that started the run, takes the run's origin from
that ack (its stamp is the origin plus less than 1 s of device time) and gives the later frames their device time back, in whole
microseconds as sent — the stamps an in-process run records.
"""
from __future__ import annotations

import dataclasses
import math
import select
import socket
import threading
import time
from typing import Any

import can
import numpy as np

from rig.dbc import load_dbc
from firmware_sim.can_node import CanNode
from rig.blockbus import FrameBlock

_ACK = load_dbc().get_message_by_name("CommandAck")
_STARTING = {int(code) for code, name in load_dbc().get_message_by_name("HostCommand").get_signal_by_name("Cmd")
             .choices.items() if str(name) in ("SelectProgram", "Start")}


def starts_run(msg: can.Message) -> bool:
    """Whether ``msg`` acknowledges an accepted SelectProgram or Start: the served run's first frame."""
    if msg.arbitration_id != _ACK.frame_id or len(msg.data) != _ACK.length:
        return False
    ack = _ACK.decode(bytes(msg.data), decode_choices=False)
    return ack["AckStatus"] == 0 and ack["Cmd"] in _STARTING


class Anchored:
    """``bus`` (a :class:`rig.blockbus.BlockBus`) for a node whose frames get ``origin`` (s) added to their
    time stamps. ``deaf``: the node receives nothing (what arrives is discarded)."""

    def __init__(self, bus: Any, origin: float = 0.0, deaf: bool = False) -> None:
        self.bus, self.origin, self.deaf = bus, origin, deaf

    def send_block(self, block: FrameBlock) -> None:
        self.bus.send_block(dataclasses.replace(block, timestamp=block.timestamp + self.origin))

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.send_block(FrameBlock.of_messages([msg]))

    def recv(self, timeout: float | None = None) -> can.Message | None:
        if self.deaf:
            self.bus.recv_blocks(0.0)
            return None
        return self.bus.recv(timeout)


class IdleStatus:
    """Heartbeat, status counters and transmit status of ``like.device`` every ``like.heartbeat_period`` s
    of wall time on ``bus`` (a BlockBus, closed by :meth:`close`), from a node set up like ``like`` that
    ignores commands; its device time counts from its start. ``lock`` guards the device (shared with the
    serial link)."""

    def __init__(self, like: CanNode, bus: Any, lock: threading.Lock) -> None:
        self._lock, self._bus = lock, bus
        self._start = time.monotonic()
        timing = like.timing
        self._node = CanNode(Anchored(bus, time.time(), deaf=True), like.device, bitrate=timing.bitrate, fd=timing.fd,
                             data_bitrate=timing.data_bitrate, heartbeat_period=like.heartbeat_period)

    def advance(self) -> None:
        """Send what is due by now."""
        with self._lock:
            self._node.advance_to(time.monotonic() - self._start)

    def acknowledge(self, ack: dict[str, int]) -> None:
        """Answer a command received while idle (``CommandAck`` signals ``ack``), stamped now in the idle
        node's time; it leaves with the next :meth:`advance`. Called with the device lock held."""
        self._node.now = max(self._node.now, time.monotonic() - self._start)
        self._node.acknowledge(ack)

    def close(self) -> None:
        self._bus.shutdown()


class RunClock(can.BusABC):
    """The host's view of a served machine's socketcand ``bus``: the run's frames only, in device time."""

    def __init__(self, bus: can.BusABC, **kwargs: Any) -> None:
        super().__init__(channel=bus.channel_info, **kwargs)
        self.channel_info = f"{bus.channel_info}, device time"
        self._bus = bus
        self._commanded = False
        self.origin: float | None = None      # s of Unix time: device time 0 of the run
        if getattr(bus, "recv_blocks", None) is not None:
            self.recv_blocks = self._recv_blocks      # whole blocks from a bus that gives them (drain_block)

    def _of_the_run(self, block: FrameBlock) -> FrameBlock | None:
        """``block``'s frames of the run, in device time: none before the frame that starts it (idle traffic, answers
        to idle commands too), which sets the origin."""
        if self.origin is None:
            first = next((i for i in range(len(block)) if starts_run(block.message(i))), None) \
                if self._commanded else None
            if first is None:
                return None
            self.origin = float(math.floor(block.timestamp[first]))
            block = block.take(slice(first, None))
        return dataclasses.replace(block, timestamp=np.round((block.timestamp - self.origin) * 1e6) / 1e6)

    def _recv_blocks(self, timeout: float | None = 0.0) -> list[FrameBlock]:
        """What ``bus.recv_blocks`` gives, as :meth:`_recv_internal` gives it frame by frame (:meth:`_of_the_run`)."""
        kept = (self._of_the_run(b if isinstance(b, FrameBlock) else FrameBlock.of_messages([b]))
                for b in self._bus.recv_blocks(timeout))
        return [b for b in kept if b is not None]

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._commanded = True
        self._bus.send(msg, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        msg = self._bus.recv(timeout)
        kept = None if msg is None else self._of_the_run(FrameBlock.of_messages([msg]))
        if kept is None:
            return None, False
        msg.timestamp = float(kept.timestamp[0])
        return msg, False

    @property
    def closed(self) -> bool:
        """True when the server has closed the connection (its ``rig serve`` stopped): python-can's socketcand bus
        then only returns nothing, as on a quiet bus. Looked at without taking any data (a peek at the socket)."""
        sock = getattr(self._bus, "_SocketCanDaemonBus__socket", None)    # python-can keeps it private
        if sock is None:
            return False
        try:
            readable, _, _ = select.select([sock], [], [], 0.0)
            return bool(readable) and sock.recv(1, socket.MSG_PEEK) == b""
        except OSError:
            return True

    def shutdown(self) -> None:
        super().shutdown()
        self._bus.shutdown()

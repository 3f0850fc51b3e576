"""python-can's stock ``socketcand`` client, receiving in blocks: :class:`SocketcandBlockBus`.

The stock client (``can.interfaces.socketcand.SocketCanDaemonBus``) reads 1024 bytes per socket read and makes a
``can.Message`` of each ``< frame … >`` message, one ``recv`` of the host per frame: a served run's host spent ~11 µs
per frame there, under 10× real time for the demo. This subclass connects, shakes hands and sends as the stock client
does, and its ``recv`` gives the same messages; :meth:`SocketcandBlockBus.recv_blocks` reads up to :data:`READ` bytes
per socket read and makes one :class:`rig.blockbus.FrameBlock` of the frames in it (the values the stock client
gives each), which :func:`drivers.can.drain.drain_block` takes whole. A message that is no plain classic frame
(``< error … >``, a field written otherwise) is converted by the stock client's own function, in its place.
"""
from __future__ import annotations

import re
import select

import can
import numpy as np
from can.interfaces.socketcand.socketcand import SocketCanDaemonBus, convert_ascii_message_to_can_message

from rig.blockbus import EXTENDED, RX, FrameBlock, frames_of

READ = 1 << 20                    # bytes per socket read at most
INCOMPLETE = 200                  # characters of an unfinished message kept at most (the stock client's bound)
_MESSAGE = re.compile(rb"<[^<>]*>")
_FRAME = re.compile(rb"< frame ([0-9A-Fa-f]{1,8}) ([0-9]+\.[0-9]+) ((?:[0-9A-Fa-f]{2}){0,8}) >")


def _block(frames: list[tuple[bytes, bytes, bytes]]) -> FrameBlock:
    """(id hex, time, data hex) of classic frames as one block, each value as the stock client reads it."""
    data = bytes.fromhex(b"".join(d.ljust(16, b"0") for _, _, d in frames).decode("ascii"))
    return FrameBlock(np.array([float(t) for _, t, _ in frames]),
                      np.array([int(i, 16) for i, _, _ in frames], np.uint32),
                      np.array([len(d) // 2 for _, _, d in frames], np.int16),
                      np.frombuffer(data, np.uint8).reshape(len(frames), 8).copy(),
                      np.array([RX | EXTENDED * (len(i) != 3) for i, _, _ in frames], np.uint8))


def parse_messages(text: bytes) -> list[FrameBlock | can.Message]:
    """The messages of ``text`` (whole ``< … >`` messages; text between them is dropped, as the stock client drops
    it), in order: runs of classic frames as blocks, any other message as the stock client converts it (none where it
    gives none)."""
    frames = _FRAME.findall(text)
    if len(frames) == text.count(b"<") == text.count(b">"):      # frames only: the common case, one block
        return [_block(frames)] if frames else []
    out: list[FrameBlock | can.Message] = []
    run: list[tuple[bytes, bytes, bytes]] = []
    for message in _MESSAGE.findall(text):
        frame = _FRAME.fullmatch(message)
        if frame is not None:
            run.append(frame.groups())
            continue
        if run:
            out.append(_block(run))
            run = []
        msg = convert_ascii_message_to_can_message(message.decode("ascii", errors="replace"))
        if msg is not None:
            out.append(msg)
    return out + ([_block(run)] if run else [])


class SocketcandBlockBus(SocketCanDaemonBus):
    """The stock socketcand client (the same arguments), with :meth:`recv_blocks`: every message complete in what
    one socket read brings, at once."""

    def __init__(self, channel: str, host: str, port: int, tcp_tune: bool = False, can_filters=None,
                 **kwargs) -> None:
        super().__init__(channel, host, port, tcp_tune=tcp_tune, can_filters=can_filters, **kwargs)
        self._socket = self._SocketCanDaemonBus__socket        # python-can keeps it private
        self._text = b""                                       # received, not yet a whole message
        self._ready: list[can.Message] = []                    # frames for the per-frame recv, in reverse order

    def recv_blocks(self, timeout: float | None = 0.0) -> list[FrameBlock | can.Message]:
        """The messages one socket read completes (waits up to ``timeout`` s for it; None: forever), frames left over
        from the per-frame ``recv`` first."""
        if self._ready:
            left, self._ready = self._ready[::-1], []
            return left
        try:
            readable, _, _ = select.select([self._socket], [], [], timeout)
            if not readable:
                return []
            data = self._socket.recv(READ)
        except OSError as exc:
            raise can.CanError(f"Failed to receive: {exc}") from exc
        text = self._text + data
        end = text.rfind(b">") + 1
        rest = text[end:]
        rest = rest[rest.rfind(b"<"):] if b"<" in rest else b""   # an unfinished message, not what precedes it
        self._text = rest if len(rest) <= INCOMPLETE else b""      # (one that never ends is not kept for ever)
        return parse_messages(text[:end])

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if not self._ready:
            self._ready = frames_of(self.recv_blocks(timeout)).messages(self.channel)[::-1]
        return (self._ready.pop() if self._ready else None), False

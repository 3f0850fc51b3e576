"""A socketcand-protocol server: serves a python-can bus to TCP clients (raw mode).

Speaks what python-can's stock ``socketcand`` client expects (``can.Bus(interface="socketcand",
host=..., port=..., channel=...)``) and answers as socketcand does (linux-can/socketcand,
doc/protocol.md)::

    server: < hi >              client: < open CHANNEL >
    server: < ok >              client: < rawmode >
    server: < ok >
    server: < frame ID SECS.USECS DATA >      (ID: 3 hex digits standard, 8 extended; DATA: hex, no spaces)
    client: < send ID LEN B0 B1 ... >         (LEN and bytes in hex; accepted from < open > on)
    client: < echo >            server: < echo >          (in every state)
    client: anything else       server: < error unknown command >   (the connection stays open)

A ``send`` that cannot be parsed is logged and dropped without a reply, as socketcand does. Every
connection gets its own bus object from ``bus_factory`` (default: python-can ``virtual`` on the served
channel), so all clients and the in-process device share one bus. ``SECS.USECS`` is the frame's own time
stamp, forwarded unchanged (socketcand forwards the kernel's receive time, Unix time); a frame a client
sends is stamped with the server's wall clock (Unix time) when it arrives. The stock client compares its
handshake replies byte for byte, so after the last ``< ok >`` the server waits ``grace`` seconds before
streaming frames (frames meanwhile are buffered by the bus, not lost). socketcand's ASCII raw mode
carries classic frames only: CAN FD frames (more than 8 data bytes) are not forwarded; they are counted
in :attr:`SocketcandServer.fd_dropped` and logged. The UDP discovery beacon is optional (the client does
not need it when host and port are given).
"""
from __future__ import annotations

import argparse
import logging
import re
import socket
import sys
import select
import threading
import time
from typing import Callable

import can
import numpy as np

from rig.blockbus import ERROR, EXTENDED, REMOTE, BlockBus, FrameBlock

log = logging.getLogger(__name__)
BEACON_PORT = 42000
_HEX = re.compile(r"[0-9A-Fa-f]{1,8}")      # a field of a send command: hex digits only (no sign, 0x or _)


MAX_COMMAND = 1024   # characters; the longest command (`< send 1FFFFFFF 64 <128 hex digits> >`) is ~150


def frame_line(msg: can.Message) -> str:
    """``< frame ... >`` line of a received frame, as socketcand sends it."""
    fid = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    secs = int(msg.timestamp)
    usecs = int(round((msg.timestamp - secs) * 1e6))
    if usecs == 1_000_000:
        secs, usecs = secs + 1, 0
    return f"< frame {fid} {secs}.{usecs:06d} {bytes(msg.data).hex().upper()} >"


FORWARD_BATCH = 4096   # frames at most (plus one block) a forwarder takes from a block bus per write to its client


def frame_lines(block: FrameBlock) -> str:
    """The ``< frame ... >`` lines of a block's classic data frames, each as :func:`frame_line` writes it (error and
    remote frames and CAN FD frames of more than 8 bytes are left out, as the forwarder leaves them out)."""
    keep = ((block.flags & (ERROR | REMOTE)) == 0) & (block.dlc <= 8)
    if not keep.all():
        block = block.take(keep)
    if not len(block):
        return ""
    secs = block.timestamp.astype(np.int64)                         # int(t): towards zero, as frame_line
    usecs = np.round((block.timestamp - secs) * 1e6).astype(np.int64)  # half to even, as Python's round
    carry = usecs == 1_000_000
    secs, usecs = secs + carry, np.where(carry, 0, usecs)
    rows = np.zeros((len(block), 8), np.uint8)                          # 8 bytes a row, whatever the block's width
    rows[:, :min(8, block.data.shape[1])] = block.data[:, :8]
    hexed = rows.tobytes().hex().upper()
    return "".join([f"< frame {fid:{'08X' if ext else '03X'}} {s}.{u:06d} {hexed[16 * i:16 * i + 2 * d]} >"
                    for i, (fid, ext, s, u, d) in enumerate(zip(
                        block.arbitration_id.tolist(), ((block.flags & EXTENDED) != 0).tolist(), secs.tolist(),
                        usecs.tolist(), block.dlc.tolist()))])


def split_commands(buffer: str) -> tuple[list[str | None], str]:
    """The commands complete in ``buffer`` (text received so far) and the rest to keep for more text.

    Each command is the stripped text between a ``<`` and the next ``>``; ``None`` stands for text up to a
    ``>`` that has no ``<`` before it (data outside ``< >``, discarded).
    """
    bodies: list[str | None] = []
    while (end := buffer.find(">")) != -1:
        start = buffer.find("<")
        bodies.append(buffer[start + 1:end].strip() if -1 < start < end else None)
        buffer = buffer[end + 1:]
    return bodies, buffer


def parse_send(body: str) -> can.Message:
    """The frame of a ``send ID LEN B0 ...`` command (body without the angle brackets). As socketcand reads it, an
    id of 8 hex digits is a 29-bit (extended) identifier and any other length an 11-bit one (``50``, ``050`` and
    ``0050`` are all 0x050)."""
    parts = body.split()
    if len(parts) < 3 or parts[0] != "send":
        raise ValueError(f"not a send command: {body!r}")
    if not all(_HEX.fullmatch(p) for p in parts[1:]):
        raise ValueError(f"send command with non-hex fields: {body!r}")
    try:
        fid, length, data = int(parts[1], 16), int(parts[2], 16), bytes(int(b, 16) for b in parts[3:])
    except ValueError:
        raise ValueError(f"send command with non-hex fields: {body!r}") from None
    extended = len(parts[1]) == 8
    if length != len(data) or length > 8 or fid > (0x1FFFFFFF if extended else 0x7FF):
        raise ValueError(f"send command with inconsistent id/length/data: {body!r}")
    return can.Message(arbitration_id=fid, is_extended_id=extended, data=data)


class SocketcandServer:
    """Serves ``channel`` over loopback TCP; :meth:`start` returns the port (``port=0``: any free one)."""

    def __init__(self, channel: str = "vcan0", host: str = "127.0.0.1", port: int = 0,
                 bus_factory: Callable[[], can.BusABC] | None = None, grace: float = 0.1,
                 beacon_to: tuple[str, int] | None = None, beacon_period: float = 3.0) -> None:
        self.channel, self.grace = channel, grace
        self.bus_factory = bus_factory or (lambda: can.Bus(interface="virtual", channel=channel,
                                                           preserve_timestamps=True))
        self._listener = socket.create_server((host, port))
        self.host, self.port = self._listener.getsockname()[:2]
        self._stop = threading.Event()
        self._draining = threading.Event()   # forwarders end once they have sent all their bus holds (drain())
        self._threads: list[threading.Thread] = []
        self._forwarders: list[tuple[threading.Thread, can.BusABC]] = []     # per connection in raw mode
        self._conns: set[socket.socket] = set()     # open client connections (stop() unblocks their threads)
        self._lock = threading.Lock()
        self.fd_dropped = 0
        self.open_buses = 0                # clients that opened the bus and are still connected
        self.errors: list[str] = []        # malformed or unsupported client commands
        self.beacon_to, self.beacon_period = beacon_to, beacon_period

    def start(self) -> int:
        """Start accepting clients (and beaconing if configured) in background threads."""
        self._spawn(self._accept_loop)
        if self.beacon_to is not None:
            self._spawn(self._beacon_loop)
        return self.port

    def _spawn(self, target: Callable, *args) -> threading.Thread:
        th = threading.Thread(target=target, args=args, daemon=True)
        th.start()
        self._threads.append(th)
        return th

    def drain(self, timeout: float, which: Callable[[can.BusABC], bool] = lambda bus: True) -> bool:
        """Let every connection's forwarder send all its bus holds, then end (no frame is to come: the served run
        stopped); waits up to ``timeout`` s for those whose bus ``which`` selects (default all), and whether they all
        got there. Call before :meth:`stop`, which discards what a forwarder has not sent."""
        self._draining.set()
        deadline = time.monotonic() + timeout
        waited = [th for th, bus in list(self._forwarders) if which(bus)]
        for th in waited:
            th.join(timeout=max(0.0, deadline - time.monotonic()))
        return not any(th.is_alive() for th in waited)

    def stop(self) -> None:
        """Close the listener and all connections; joins the server threads."""
        self._stop.set()
        self._listener.close()
        with self._lock:
            conns = list(self._conns)
        for conn in conns:                  # a forwarder blocked on a client that stopped reading returns
            try:
                conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        for th in self._threads:
            th.join(timeout=2.0)

    def __enter__(self) -> "SocketcandServer":
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def _error(self, text: str) -> None:
        log.warning("socketcand server: %s", text)
        with self._lock:
            self.errors.append(text)

    def _accept_loop(self) -> None:
        self._listener.settimeout(0.1)
        while not self._stop.is_set():
            try:
                conn, _ = self._listener.accept()
            except (TimeoutError, socket.timeout):
                continue
            except OSError:
                return
            self._spawn(self._serve, conn)

    def _serve(self, conn: socket.socket) -> None:
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        conn.settimeout(None)               # writes block while the client's buffer is full (TCP's back-pressure):
        # a socket timeout would also time out the forwarder's sendall, which then gave up the stream for good
        sending = threading.Lock()          # the reader (replies) and the forwarder (frames) both write
        with self._lock:
            self._conns.add(conn)

        def reply(text: str) -> None:
            with sending:
                conn.sendall(text.encode("ascii"))

        bus: can.BusABC | None = None
        buffer, raw, discarded = "", False, 0
        try:
            reply("< hi >")
            while not self._stop.is_set():
                if not select.select([conn], [], [], 0.1)[0]:      # wait for a command, seeing stop() meanwhile
                    continue
                chunk = conn.recv(4096)
                if not chunk:
                    return
                bodies, buffer = split_commands(buffer + chunk.decode("ascii", errors="replace"))
                if len(buffer) > MAX_COMMAND:       # no '>' in sight: garbage, not a command; memory stays bounded
                    discarded, buffer = discarded + len(buffer), ""
                elif discarded and bodies:          # one error per run of garbage, when it ends
                    self._error(f"{discarded} characters without a closing '>' discarded (no command is longer "
                                f"than {MAX_COMMAND})")
                    discarded = 0
                for body in bodies:
                    if body is None:
                        self._error("data outside < > discarded")
                    elif body == "echo":
                        reply("< echo >")
                    elif body.startswith("open ") and bus is None:
                        if body[5:].strip() != self.channel:
                            reply("< error could not open bus >")
                            self._error(f"client asked for channel {body[5:].strip()!r}, serving {self.channel!r}")
                            return
                        bus = self.bus_factory()
                        with self._lock:
                            self.open_buses += 1
                        reply("< ok >")
                    elif body == "rawmode" and bus is not None and not raw:
                        reply("< ok >")
                        raw = True
                        self._forwarders.append((self._spawn(self._forward, conn, bus, sending), bus))
                    elif body.startswith("send ") and bus is not None:
                        try:
                            msg = parse_send(body)
                        except ValueError as exc:
                            self._error(str(exc))
                            continue
                        msg.timestamp = time.time()
                        bus.send(msg)
                    else:
                        reply("< error unknown command >")
                        self._error(f"unsupported command {body!r} in this state: answered < error unknown command >")
        except OSError as exc:
            log.info("socketcand client connection closed: %s", exc)
        finally:
            with self._lock:
                self._conns.discard(conn)
            try:
                conn.shutdown(socket.SHUT_RDWR)     # the forwarder, perhaps blocked in a send, returns
            except OSError:
                pass
            conn.close()
            if bus is not None:
                bus.shutdown()
                with self._lock:
                    self.open_buses -= 1

    def _forward(self, conn: socket.socket, bus: can.BusABC, sending: threading.Lock) -> None:
        """Stream the bus's frames to the client (after the handshake grace time): from a bus that delivers blocks
        (:class:`rig.blockbus.BlockBus`) up to :data:`FORWARD_BATCH` frames per write, else frame
        by frame."""
        time.sleep(self.grace)
        if isinstance(bus, BlockBus):
            return self._forward_blocks(conn, bus, sending)
        try:
            while not self._stop.is_set() and conn.fileno() != -1:
                msg = bus.recv(0.05)
                if msg is None and self._draining.is_set():
                    return                      # all its bus held is sent (drain())
                if msg is None or msg.is_error_frame or msg.is_remote_frame:
                    continue
                if len(msg.data) > 8:
                    with self._lock:
                        self.fd_dropped += 1
                    log.warning("socketcand server: CAN FD frame 0x%X (%d bytes) not forwarded",
                                msg.arbitration_id, len(msg.data))
                    continue
                with sending:
                    conn.sendall(frame_line(msg).encode("ascii"))
        except (OSError, can.CanError):
            return

    def _forward_blocks(self, conn: socket.socket, bus: can.BusABC, sending: threading.Lock) -> None:
        """:meth:`_forward` of a block bus: a write per batch of frames (one ``sendall`` per frame cost ~17 µs)."""
        try:
            while not self._stop.is_set() and conn.fileno() != -1:
                blocks = bus.recv_blocks(0.05, FORWARD_BATCH)
                if not blocks and self._draining.is_set():
                    return                      # all its bus held is sent (drain())
                fd = sum(int(np.count_nonzero((b.dlc > 8) & ((b.flags & (ERROR | REMOTE)) == 0))) for b in blocks)
                if fd:
                    with self._lock:
                        self.fd_dropped += fd
                    log.warning("socketcand server: %d CAN FD frame(s) of more than 8 bytes not forwarded", fd)
                text = "".join(frame_lines(b) for b in blocks)
                if text:
                    with sending:
                        conn.sendall(text.encode("ascii"))
        except (OSError, can.CanError):
            return

    def _beacon_loop(self) -> None:
        text = (f'<CANBeacon name="{socket.gethostname()}" type="SocketCAN" description="mechrig device">'
                f'<URL>can://{self.host}:{self.port}</URL><Bus name="{self.channel}"/></CANBeacon>').encode()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
            udp.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            while not self._stop.is_set():
                udp.sendto(text, self.beacon_to)
                self._stop.wait(self.beacon_period)


def main(argv: list[str] | None = None) -> int:
    """Serve a python-can bus (default: ``virtual``) over socketcand until interrupted."""
    ap = argparse.ArgumentParser(prog="python -m firmware_sim.socketcand_server", description=main.__doc__)
    ap.add_argument("--interface", default="virtual", help="python-can interface of the served bus")
    ap.add_argument("--channel", default="vcan0", help="channel name (also the name clients open)")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=29536, help="TCP port (0: any free port)")
    ap.add_argument("--beacon", action="store_true", help=f"send the UDP discovery beacon to port {BEACON_PORT}")
    args = ap.parse_args(argv)
    factory = lambda: can.Bus(interface=args.interface, channel=args.channel)  # noqa: E731
    server = SocketcandServer(args.channel, args.host, args.port, factory,
                              beacon_to=("255.255.255.255", BEACON_PORT) if args.beacon else None)
    server.start()
    print(f"socketcand serving {args.interface}:{args.channel} on {server.host}:{server.port}", flush=True)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        server.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())

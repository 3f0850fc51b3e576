"""The DigiForce as a serial device: serves docs/serial-protocol.md on a pty, TCP or pyserial URL.

A background thread receives frames, executes them on the DigiForce and sends the responses paced
at the baud rate (10 bits per byte, 8N1): a response of n bytes is delivered in chunks, each written
when its last byte would have left the UART, so the host sees the last byte n·10/baud after the
first could start. Received bytes are accounted the same way before a request is executed.
"""
from __future__ import annotations

import logging
import threading
import time
from typing import Any, Callable

from firmware_sim.serial_protocol.commands import Commands
from firmware_sim.serial_protocol.framing import Bad, Reply, Request, Receiver, frame, handshake
from firmware_sim.serial_protocol.transport import LinkLost, open_transport

log = logging.getLogger(__name__)

BITS_PER_BYTE = 10        # 8N1: start bit, 8 data bits, stop bit
SLOT = 0.002              # s between paced writes
MIN_GAP = 0.1             # s, inter-character timeout floor (20 character times at low rates)


class SerialDevice:
    """Serve ``device`` (a DigiForce) on ``port_or_url``: ``"pty"``, ``"tcp://HOST:PORT"`` or a pyserial URL.

    ``port`` is what the host opens (the pty's slave path, ``socket://HOST:PORT`` or the URL itself).
    ``clock()`` gives the time (s) handed to ``device.start``/``stop`` (default None: the device's "now",
    i.e. its next / latest sample);
    ``lock`` serialises device access with other users of the same DigiForce.
    """

    def __init__(self, device: Any, port_or_url: str = "pty", baudrate: int = 115200, address: int = 1, *,
                 clock: Callable[[], float] | None = None, lock: threading.Lock | None = None) -> None:
        if not isinstance(baudrate, int) or baudrate <= 0:
            raise ValueError(f"serial device: baud rate must be a positive integer, got {baudrate!r}")
        if not isinstance(address, int) or not 1 <= address <= 0xFE:
            raise ValueError(f"serial device: address must be an integer in 1..254, got {address!r}")
        self.baudrate, self.address = baudrate, address
        self._char = BITS_PER_BYTE / baudrate
        self._gap = max(MIN_GAP, 20 * self._char)
        self._chunk = max(1, round(SLOT / self._char))
        self._commands = Commands(device, clock, lock or threading.Lock())
        self._transport = open_transport(port_or_url, baudrate)
        self.port: str = self._transport.url
        self._rx = Receiver()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._faults = threading.Lock()
        self._drop = self._corrupt = 0
        self._last_key: tuple[int, str, str] | None = None
        self._last_response: bytes | None = None
        self._tx_free = 0.0
        self.executed = 0          # requests executed (retransmitted duplicates are not re-executed)
        self.link_lost: str | None = None      # why the line went away (LinkLost), if it did
        self.naks_sent = 0

    # -- life cycle -------------------------------------------------------------------------------
    def start(self) -> SerialDevice:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name=f"serial-device {self.port}", daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        self._transport.close()

    def __enter__(self) -> SerialDevice:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- fault injection (tests) ------------------------------------------------------------------
    def drop_next_responses(self, n: int = 1) -> None:
        """Do not send the next ``n`` response transmissions (the host times out)."""
        with self._faults:
            self._drop += n

    def corrupt_next_responses(self, n: int = 1) -> None:
        """Send the next ``n`` response transmissions with a wrong block check character."""
        with self._faults:
            self._corrupt += n

    # -- the thread -------------------------------------------------------------------------------
    def _run(self) -> None:
        try:
            self._serve()
        except LinkLost as exc:              # the line is gone: one line, not a thread's traceback
            self.link_lost = str(exc)
            if not self._stop.is_set():
                log.warning("serial device: the line is gone (%s); the device no longer answers", exc)

    def _serve(self) -> None:
        rx_done = 0.0               # when the latest byte received has arrived on the simulated line (monotonic s)
        while not self._stop.is_set():
            data = self._transport.read(0.02)
            now = time.monotonic()
            if not data:                            # silence: a partial frame is dropped after the gap from its last
                if self._rx.pending and now - rx_done > self._gap:  # byte's arrival on the line, not from its read:
                    self._rx.reset()                # 15000 bytes at 115200 baud arrive over 1.3 s (a frame written in
                continue                            # two pieces was dropped; an audit)
            rx_done = max(now, rx_done) + len(data) * self._char
            for event in self._rx.feed(data):
                self._wait_until(rx_done)
                self._handle(event)

    def _handle(self, event: Request | Bad | Reply) -> None:
        if event.address != self.address:
            return
        if isinstance(event, Reply):
            if not event.ack and self._last_response is not None:
                self._transmit(self._last_response)
            return
        if isinstance(event, Bad):
            self.naks_sent += 1
            self._send(handshake(False, self.address))
            return
        key = (event.seq, event.command, event.data)
        if key != self._last_key or self._last_response is None:
            data = self._commands.execute(event.command, event.data)
            self.executed += 1
            self._last_key, self._last_response = key, frame(self.address, event.seq, event.command, data)
        self._transmit(self._last_response)

    def _transmit(self, response: bytes) -> None:
        with self._faults:
            drop, corrupt = self._drop > 0, self._drop == 0 and self._corrupt > 0
            self._drop -= drop
            self._corrupt -= corrupt
        if drop:
            return
        if corrupt:
            response = response[:-2] + b"%02X" % (int(response[-2:], 16) ^ 0x5A)
        self._send(response)

    def _send(self, data: bytes) -> None:
        """Write ``data`` paced at the baud rate."""
        start = max(time.monotonic(), self._tx_free)
        for i in range(0, len(data), self._chunk):
            part = data[i:i + self._chunk]
            self._wait_until(start + (i + len(part)) * self._char)
            if self._stop.is_set():
                return
            self._transport.write(part, self._stop)
        self._tx_free = start + len(data) * self._char

    def _wait_until(self, deadline: float) -> None:
        delay = deadline - time.monotonic()
        if delay > 0:
            self._stop.wait(delay)

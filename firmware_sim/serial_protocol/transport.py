"""Byte transports the device serves on: a pseudo-terminal, a TCP listener, or any pyserial URL/port.

Each has ``url`` (what the host opens), ``read(timeout) -> bytes`` (``b""`` when nothing came) and
``write(data)``; writes are whole (the caller paces them) and give up when ``stop`` is set.
"""
from __future__ import annotations

import os
import select
import socket
import threading
import tty
from typing import Protocol
from urllib.parse import urlsplit

import serial


class Transport(Protocol):
    url: str

    def read(self, timeout: float) -> bytes: ...

    def write(self, data: bytes, stop: threading.Event) -> None: ...

    def close(self) -> None: ...


class PtyTransport:
    """A pseudo-terminal: the device holds the master, ``url`` is the slave's tty path (e.g. /dev/pts/3)."""

    def __init__(self) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)        # no echo, no line discipline: an 8N1 line as seen by a UART
        os.set_blocking(self._master, False)
        self.url = os.ttyname(self._slave)

    def read(self, timeout: float) -> bytes:
        if not select.select([self._master], [], [], timeout)[0]:
            return b""
        try:
            return os.read(self._master, 65536)
        except (BlockingIOError, InterruptedError):
            return b""

    def write(self, data: bytes, stop: threading.Event) -> None:
        view = memoryview(data)
        while view and not stop.is_set():
            try:
                view = view[os.write(self._master, view):]
            except BlockingIOError:     # the host is not reading: wait for room in the tty buffer
                select.select([], [self._master], [], 0.05)

    def close(self) -> None:
        os.close(self._master)
        os.close(self._slave)


class TcpServerTransport:
    """Listen on ``host:port`` (port 0 = any free one); the host opens ``url`` = ``socket://host:port``.

    One host connection at a time; a new connection replaces a lost one. Bytes written while no host
    is connected are lost, as on an unplugged line.
    """

    def __init__(self, host: str, port: int) -> None:
        self._listener = socket.create_server((host, port))
        self._conn: socket.socket | None = None
        self.url = f"socket://{host}:{self._listener.getsockname()[1]}"

    def read(self, timeout: float) -> bytes:
        if self._conn is None:
            if select.select([self._listener], [], [], timeout)[0]:
                self._conn, _ = self._listener.accept()
                self._conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            return b""
        if not select.select([self._conn], [], [], timeout)[0]:
            return b""
        try:
            data = self._conn.recv(65536)
        except OSError:
            data = b""
        if not data:
            self._drop()
        return data

    def write(self, data: bytes, stop: threading.Event) -> None:
        if self._conn is None:
            return
        try:
            self._conn.sendall(data)
        except OSError:
            self._drop()

    def _drop(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None

    def close(self) -> None:
        self._drop()
        self._listener.close()


class LinkLost(Exception):
    """The line is gone (a ``socket://`` peer that disconnected, an unplugged USB adapter): the device stops."""


class UrlTransport:
    """A real serial port (``/dev/ttyUSB0``) or any pyserial URL (``socket://``, ``rfc2217://``, ``loop://``); a
    line that is gone raises :class:`LinkLost` naming it."""

    def __init__(self, url: str, baudrate: int) -> None:
        try:
            self._port = serial.serial_for_url(url, baudrate=baudrate, timeout=0)
        except (serial.SerialException, ValueError) as e:
            raise ValueError(f"serial device: cannot open {url!r}: {e}") from e
        self.url = url

    def read(self, timeout: float) -> bytes:
        try:
            self._port.timeout = timeout
            first = self._port.read(1)
            return first + self._port.read(self._port.in_waiting) if first else b""
        except serial.SerialException as exc:
            raise LinkLost(f"{self.url}: {exc}") from None

    def write(self, data: bytes, stop: threading.Event) -> None:
        try:
            self._port.write(data)
        except serial.SerialException as exc:
            raise LinkLost(f"{self.url}: {exc}") from None

    def close(self) -> None:
        self._port.close()


def open_transport(port_or_url: str, baudrate: int) -> Transport:
    """``"pty"`` → pseudo-terminal; ``"tcp://HOST:PORT"`` → TCP listener; anything else → pyserial."""
    if port_or_url == "pty":
        return PtyTransport()
    if port_or_url.startswith("tcp://"):
        parts = urlsplit(port_or_url)
        if parts.hostname is None or parts.port is None:
            raise ValueError(f"serial device: {port_or_url!r} must be tcp://HOST:PORT")
        return TcpServerTransport(parts.hostname, parts.port)
    return UrlTransport(port_or_url, baudrate)

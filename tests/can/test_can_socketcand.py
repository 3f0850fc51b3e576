"""The socketcand server with python-can's stock socketcand client over real loopback TCP."""
from __future__ import annotations

import itertools
import os
import subprocess
import sys
import time
from pathlib import Path

import can
import numpy as np
import pytest

from drivers.can import CanHost
from firmware_sim.can_node import CanNode, X_LSB, Y_LSB
from firmware_sim.socketcand_server import SocketcandServer, frame_line, parse_send

ROOT = Path(__file__).resolve().parents[2]
_channels = itertools.count()


def pump(node: CanNode, host: CanHost, until, t_step: float = 0.05, wall_timeout: float = 10.0) -> None:
    """Advance the node and poll the host until ``until()`` holds (or fail after wall_timeout s)."""
    deadline = time.monotonic() + wall_timeout
    while not until():
        assert time.monotonic() < deadline, "socketcand link did not deliver in time"
        node.advance_to(node.now + t_step)
        host.poll(timeout=0.01)


@pytest.fixture
def served():
    channel = f"sc-{next(_channels)}"
    server = SocketcandServer(channel)
    server.start()
    dev_bus = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
    client = can.Bus(interface="socketcand", host="127.0.0.1", port=server.port, channel=channel)
    yield server, dev_bus, client
    client.shutdown()
    dev_bus.shutdown()
    server.stop()


def test_curve_and_commands_through_stock_client(served, device, rng, fakes):
    server, dev_bus, client = served
    node = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=0.1)
    host = CanHost(client)
    pump(node, host, lambda: host.status)                      # heartbeats arrive
    host.select_program(5)
    host.start()
    pump(node, host, lambda: len(host.acks) == 2)
    assert device.calls[0] == ("select_program", 5) and device.calls[1][0] == "start"
    t, x, y = fakes.make_curve(rng, 4000)
    device.finish(t, x, y, [fakes.ElementResult("W1", "window", True)], {"y_max": float(y.max())})
    pump(node, host, lambda: 1 in host.results and host.results[1].process_values)
    (curve,) = host.curves()
    assert curve.program == 5
    np.testing.assert_array_equal(curve.x, np.rint(x / X_LSB) * X_LSB)
    np.testing.assert_allclose(curve.y, y, atol=Y_LSB / 2 + 1e-12)
    assert host.results[1].ok and host.events == []
    assert server.errors == [] and server.fd_dropped == 0


def test_fd_frames_are_not_forwarded_over_socketcand(served, device):
    server, dev_bus, client = served
    node = CanNode(dev_bus, device, bitrate=500_000, fd=True, data_bitrate=2_000_000, heartbeat_period=0.1)
    host = CanHost(client)
    t = np.arange(110) / 10_000.0
    node.publish_live(t, np.zeros(110), np.zeros(110))           # 10 FD frames
    pump(node, host, lambda: server.fd_dropped == 10 and host.counters)
    assert host.take_live()[0].size == 0 and host.status["state"] == "idle"


def test_ascii_frame_format_matches_the_client_parser():
    from can.interfaces.socketcand.socketcand import convert_ascii_message_to_can_message as parse
    for msg in (can.Message(arbitration_id=0x12, data=b"\x00\xff\x10", timestamp=12.0000015, is_extended_id=False),
                can.Message(arbitration_id=0x1ABCDEF0, data=b"", timestamp=3.9999999, is_extended_id=True)):
        back = parse(frame_line(msg))
        assert back.arbitration_id == msg.arbitration_id and back.is_extended_id == msg.is_extended_id
        assert bytes(back.data) == bytes(msg.data)
        assert back.timestamp == pytest.approx(msg.timestamp, abs=1e-6)
    from can.interfaces.socketcand.socketcand import convert_can_message_to_ascii_message as fmt
    sent = can.Message(arbitration_id=0x50, data=bytes([1, 0, 7, 0, 0, 0, 0, 0xAB]), is_extended_id=False)
    got = parse_send(fmt(sent)[2:-2])
    assert got.arbitration_id == 0x50 and bytes(got.data) == bytes(sent.data)
    for bad in ("send 050 3 1 2", "send 050 2 1 zz", "send 1234 1 0", "send 800 0", "open x"):
        with pytest.raises(ValueError, match="send"):
            parse_send(bad)


def test_wrong_channel_and_garbage_are_reported(served):
    server, _, _ = served
    with pytest.raises(can.CanError, match="< ok >"):
        can.Bus(interface="socketcand", host="127.0.0.1", port=server.port, channel="nope")
    deadline = time.monotonic() + 5
    while not server.errors and time.monotonic() < deadline:
        time.sleep(0.01)
    assert "nope" in server.errors[0]


SERVE = """
import importlib.util, sys, time
import can, numpy as np
spec = importlib.util.spec_from_file_location("can_fakes", sys.argv[1])
fakes = sys.modules["can_fakes"] = importlib.util.module_from_spec(spec)
spec.loader.exec_module(fakes)
from firmware_sim.can_node import CanNode
from firmware_sim.socketcand_server import SocketcandServer
server = SocketcandServer("vcan-sub")
port = server.start()
bus = can.Bus(interface="virtual", channel="vcan-sub", preserve_timestamps=True)
device = fakes.FakeDevice()
node = CanNode(bus, device, bitrate=1_000_000, heartbeat_period=0.1)
print(port, flush=True)
t0 = time.monotonic()
while time.monotonic() - t0 < 30:
    if device.last_result is None and any(c[0] == "start" for c in device.calls):
        t, x, y = fakes.make_curve(np.random.default_rng(7), 2000)
        device.finish(t, x, y, [fakes.ElementResult("T", "threshold", False, "low")], {})
    node.advance_to(time.monotonic() - t0)
    time.sleep(0.005)
"""


def test_device_in_another_process(tmp_path, fakes):
    script = tmp_path / "serve.py"
    script.write_text(SERVE)
    proc = subprocess.Popen([sys.executable, str(script), str(Path(__file__).with_name("conftest.py"))],
                            stdout=subprocess.PIPE, text=True, cwd=ROOT,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        port = int(proc.stdout.readline())
        bus = can.Bus(interface="socketcand", host="127.0.0.1", port=port, channel="vcan-sub")
        host = CanHost(bus)
        try:
            host.start()
            deadline = time.monotonic() + 20
            while not (host.curves() and 1 in host.results) and time.monotonic() < deadline:
                host.poll(timeout=0.05)
        finally:
            bus.shutdown()
        (curve,) = host.curves()
        _, x, y = fakes.make_curve(np.random.default_rng(7), 2000)
        np.testing.assert_array_equal(curve.y, np.rint(y / Y_LSB) * Y_LSB)
        assert host.results[1].ok is False and host.results[1].first_fail == 0
        assert host.acks[0]["status"] == "done" and host.events_of("sequence_gap") == []
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def _line(sock, expected: str) -> None:
    got, deadline = b"", time.monotonic() + 5
    while len(got) < len(expected) and time.monotonic() < deadline:
        got += sock.recv(len(expected) - len(got))
    assert got.decode() == expected


def test_echo_unsupported_commands_and_client_frames_as_socketcand(served):
    """``< echo >`` in every state, ``< error unknown command >`` for anything else (the connection stays),
    a bad ``send`` dropped silently; a client's frame reaches the bus stamped with the wall clock."""
    import socket
    server, dev_bus, _ = served
    with socket.create_connection(("127.0.0.1", server.port), timeout=5) as sock:
        _line(sock, "< hi >")
        for command, answer in (("< echo >", "< echo >"), ("< subscribe 0 0 123 >", "< error unknown command >"),
                                (f"< open {server.channel} >", "< ok >"), ("< echo >", "< echo >"),
                                ("< bcmmode >", "< error unknown command >"), ("< rawmode >", "< ok >"),
                                ("< fdsend 050 0 1 00 >", "< error unknown command >"),
                                ("< send 050 3 1 >< echo >", "< echo >")):
            sock.sendall(command.encode())
            _line(sock, answer)
        before = time.time()
        sock.sendall(b"< send 050 2 1 F1 >")
        msg = dev_bus.recv(5.0)
        assert msg.arbitration_id == 0x50 and bytes(msg.data) == b"\x01\xf1"
        assert before - 0.01 <= msg.timestamp <= time.time()
        dev_bus.send(can.Message(arbitration_id=0x123, data=b"\xab", timestamp=1712345678.000123, is_extended_id=False))
        _line(sock, "< frame 123 1712345678.000123 AB >")        # the frame's own stamp, forwarded unchanged
    assert sum("unsupported command" in e for e in server.errors) == 3
    assert any("inconsistent" in e for e in server.errors)


def test_a_client_that_stops_reading_for_a_while_gets_every_frame_after_it():
    """A client that stops reading (a host busy for seconds) fills the TCP buffers: the server waits for it, then goes
    on. With a socket timeout the forwarder's send timed out and it gave up the stream for good (a served
    1000-cycle run stalled: "no CAN traffic for 10 s")."""
    import socket
    channel = f"sc-{next(_channels)}"
    with SocketcandServer(channel, grace=0.0) as server:
        dev_bus = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
        client = socket.socket()
        client.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)       # small: the server's sends block soon
        client.connect(("127.0.0.1", server.port))
        client.settimeout(5.0)
        client.sendall(f"< open {channel} >< rawmode >".encode())
        data = b""
        while data.count(b"< ok >") < 2:                                 # the server's bus is open
            data += client.recv(1024)
        n = 120_000                                                      # 4 MB: beyond the server's send buffer
        for k in range(n):
            dev_bus.send(can.Message(arbitration_id=0x100, data=k.to_bytes(4, "big"), is_extended_id=False))
        time.sleep(0.5)                                                  # not reading: the server's send blocks
        received, last, rest, deadline = 0, b"", b"", time.monotonic() + 60.0
        while received < n and time.monotonic() < deadline:
            rest += client.recv(65536)
            done, _, rest = rest.rpartition(b">")                        # whole lines only, counted once each
            received += done.count(b"< frame 100 ")
            last = done[done.rfind(b"< frame 100 "):] if b"< frame 100 " in done else last
        client.close()
        dev_bus.shutdown()
    assert received == n
    assert int(last.split()[-1], 16) == n - 1                           # in order, none lost


def _random_frames(rng, n: int) -> list[can.Message]:
    """Classic frames of every id format and length, time stamps at the microsecond rounding edges too."""
    out = []
    for k in range(n):
        ext = bool(rng.integers(2))
        t = float(rng.integers(0, 5000)) + float(rng.choice([rng.random(), 0.9999995, 0.0000005, 0.5e-6, 0.0]))
        out.append(can.Message(arbitration_id=int(rng.integers(0, 0x20000000 if ext else 0x800)), is_extended_id=ext,
                               data=rng.integers(0, 256, int(rng.integers(0, 9))).astype(np.uint8).tobytes(),
                               timestamp=t))
    return out


def test_frame_lines_of_a_block_are_frame_line_of_each_frame():
    """The server writes a block's frames in one go, byte for byte as it wrote each (rounding edges, both id
    formats, 0..8 bytes); error, remote and FD frames are left out, as the per-frame forwarder leaves them."""
    from firmware_sim.socketcand_server import frame_lines
    from rig.blockbus import FrameBlock
    rng = np.random.default_rng(7)
    frames = _random_frames(rng, 3000)
    assert frame_lines(FrameBlock.of_messages(frames)) == "".join(frame_line(m) for m in frames)
    others = [can.Message(arbitration_id=1, is_error_frame=True), can.Message(arbitration_id=2, is_remote_frame=True),
              can.Message(arbitration_id=3, is_fd=True, data=bytes(12))]
    assert frame_lines(FrameBlock.of_messages(others + frames[:5])) == "".join(frame_line(m) for m in frames[:5])
    narrow = FrameBlock(np.array([2.0]), np.array([2], np.uint32), np.array([4], np.int16),    # rows 4 bytes wide
                        np.array([[5, 6, 7, 8]], np.uint8), np.zeros(1, np.uint8))
    assert frame_lines(narrow) == "< frame 002 2.000000 05060708 >"
    channel = f"sc-{next(_channels)}"
    sender, reader = can.Bus(interface="blockbus", channel=channel), can.Bus(interface="blockbus", channel=channel)
    try:                                     # the forwarder's batches: whole blocks, at least one, in order
        for k in range(3):
            sender.send_block(FrameBlock.of_messages(frames[10 * k:10 * k + 10]))
        assert reader.recv(0.0).arbitration_id == frames[0].arbitration_id          # one taken frame by frame
        first = reader.recv_blocks(0.0, 0)                                         # limit 0: still one block
        assert [len(b) for b in first] == [9]
        assert [len(b) for b in reader.recv_blocks(0.0, 1)] == [10]
        assert [len(b) for b in reader.recv_blocks(0.0, 15)] == [10] and reader.recv_blocks(0.0) == []
        assert first[0].arbitration_id.tolist() == [m.arbitration_id for m in frames[1:10]]
    finally:
        sender.shutdown()
        reader.shutdown()


def test_block_client_reads_what_the_stock_client_reads():
    """drivers.can.socketcand parses a read's frames at once into the values python-can's converter gives each
    line; anything else (an error message, a field written otherwise, junk between messages) goes through that
    converter in its place."""
    from can.interfaces.socketcand.socketcand import convert_ascii_message_to_can_message as stock
    from drivers.can.socketcand import parse_messages
    from rig.blockbus import frames_of
    rng = np.random.default_rng(11)
    lines = [frame_line(m) for m in _random_frames(rng, 2000)]
    lines[100:100] = ["< error 123 5.000001 >", "< frame 7ff 1.5 01 02 >", "< frame 1234567 2.000000 00 >",
                      "< frame 12 3.000000 0102030405060708090A >"]
    text = ("junk" + "".join(lines)).encode()

    def key(m: can.Message) -> tuple:
        return (m.timestamp, m.arbitration_id, m.is_extended_id, m.is_error_frame, bytes(m.data), m.is_rx)
    expected = [key(m) for m in map(stock, lines) if m is not None]
    got = parse_messages(text)
    assert [key(m) for m in frames_of(got).messages()] == expected
    assert [type(x).__name__ for x in got] == ["FrameBlock", "Message", "Message", "FrameBlock", "Message",
                                               "FrameBlock"]      # runs of frames whole, the others in their place
    plain = "".join(lines[:100]).encode()
    (block,) = parse_messages(plain)
    assert [key(m) for m in block.messages()] == expected[:100]


def test_block_client_through_the_server_keeps_every_frame_in_order():
    """The server's block forwarder and the block client over loopback TCP: every frame, in order, as sent, in
    pieces that split messages anywhere (1 MiB reads of a stream of 60 000 frames)."""
    from drivers.can.drain import drain_block
    from rig.blockbus import FrameBlock
    channel = f"sc-{next(_channels)}"
    with SocketcandServer(channel, grace=0.0, bus_factory=lambda: can.Bus(interface="blockbus", channel=channel)) \
            as server:
        dev_bus = can.Bus(interface="blockbus", channel=channel)
        client = can.Bus(interface="socketcand_blocks", host="127.0.0.1", port=server.port, channel=channel)
        try:
            deadline = time.monotonic() + 10.0
            while server.open_buses < 1 and time.monotonic() < deadline:    # its bus open: what is sent reaches it
                time.sleep(0.01)
            n = 60_000
            ids = np.arange(n, dtype=np.uint32) % 0x800
            data = np.zeros((n, 8), np.uint8)
            data[:, :4] = np.arange(n, dtype=">u4").view(np.uint8).reshape(n, 4)
            sent = FrameBlock(np.arange(n) * 1e-4, ids, np.full(n, 4, np.int16), data, np.zeros(n, np.uint8))
            for k in range(0, n, 1000):
                dev_bus.send_block(sent.take(slice(k, k + 1000)))
            got, deadline = [], time.monotonic() + 30.0
            while sum(map(len, got)) < n and time.monotonic() < deadline:
                got.append(drain_block(client, 0.1))
            block = FrameBlock.concat(got)
        finally:
            client.shutdown()
            dev_bus.shutdown()
    assert len(block) == n
    np.testing.assert_array_equal(block.arbitration_id, ids)
    np.testing.assert_array_equal(block.data[:, :4], data[:, :4])
    np.testing.assert_array_equal(block.timestamp, np.round(sent.timestamp * 1e6) / 1e6)
    assert (block.flags & 0b100000).all()                                  # RX, as the stock client marks them

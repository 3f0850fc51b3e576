"""Host client against the serial device over a real pty (and TCP / pyserial URLs): every command,
retransmission on corrupt frames in both directions, timeouts, exact curves, baud-rate pacing."""
from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pytest
import serial

from drivers.digiforce_serial import DigiForceClient, DigiForceError, DigiForceLinkError, DigiForceTimeout
from drivers.serial_framing import FrameParser, encode_frame, encode_handshake
from firmware_sim.digiforce import Curve
from firmware_sim.serial_device import SerialDevice


def test_every_command_over_a_pty(link) -> None:
    device, client, fake = link
    assert device.port.startswith("/dev/")
    assert client.identify() == fake.identify()
    client.select_program(3)
    assert client.active_program() == (3, 16) and fake.active_program == 3
    assert client.get_program(3) == fake.programs[3] and client.get_program() == fake.programs[3]
    new = {"name": "press fit", "channels": {"x": {"cutoff": 500.0}, "y": {"cutoff": 200.0}}, "elements": []}
    client.set_program(4, new)
    assert fake.programs[4] == new
    client.configure_channel(4, "y", cutoff=50.0)
    client.configure_sampling(4, mode="dx", delta=1e-5)
    client.configure_evaluation(4, [{"kind": "window", "x": [0.001, 0.002], "y": [100.0, 300.0]}],
                                limits={"y_max": [500.0, 900.0]})
    assert fake.programs[4]["channels"] == {"x": {"cutoff": 500.0}, "y": {"cutoff": 50.0}}
    assert fake.programs[4]["sampling"] == {"mode": "dx", "delta": 1e-5}
    assert fake.programs[4]["elements"][0]["y"] == [100.0, 300.0] and fake.programs[4]["limits"]["y_max"][1] == 900.0
    client.tare("y")
    client.tare()
    client.start()
    client.stop()
    client.reset_statistics(2)
    client.reset_statistics()
    assert fake.calls == [("tare", "y"), ("tare", None), ("start", None), ("stop", None),
                          ("reset_statistics", 2), ("reset_statistics", 3)]
    assert client.read_result() == fake.last_result.to_dict(include_curve=False)
    stats = client.read_statistics(2)
    assert stats["program"] == 2 and stats["y_max"]["mean"] == 800.5
    assert stats["y_max"]["std"] is None and stats["y_max"]["cpk"] is None        # not finite: null + flag
    assert stats["non_finite"] == {"/y_max/std": "NaN", "/y_max/cpk": "Infinity"}
    assert client.read_statistics()["program"] == 3
    assert client.status() == fake.status()


def test_curve_of_4000_pairs_is_read_back_exactly(link) -> None:
    device, client, fake = link
    curve = client.read_curve(with_time=True)
    c = fake.last_curve
    t, x, y = c.t, c.x, c.y
    assert len(x) == 4000
    assert np.array_equal(curve.x, x) and np.array_equal(curve.y, y) and np.array_equal(curve.t, t)
    assert curve.y2 is None and curve.info["turning_index"] == 2000 and curve.info["x_reference"] == 0.001
    assert curve.info["sampling"] == {"mode": "time", "delta": 1e-5} and curve.info["overflow"] is False
    assert client.read_curve().t is None
    fake.last_curve = Curve(t[:3], x[:3], y[:3], y[3:6], turning_index=1)   # new curve with y2: latched afresh
    short = client.read_curve()
    assert np.array_equal(short.y, y[:3]) and np.array_equal(short.y2, y[3:6])
    fake.last_curve = Curve(t[:0], x[:0], y[:0], None, turning_index=0)
    assert len(client.read_curve().x) == 0


def test_device_errors_name_the_problem(link) -> None:
    device, client, fake = link
    with pytest.raises(DigiForceError, match=r"PS .*status 03.*program 16 outside 0\.\.15") as e:
        client.select_program(16)
    assert e.value.code == 3
    with pytest.raises(DigiForceError, match="unknown keys.*colour"):
        client.set_program(1, {"name": "x", "colour": "red"})
    with pytest.raises(DigiForceError, match="status 02: TA takes a channel name .*got 'z'"):
        client.tare("z")
    client.start()
    with pytest.raises(DigiForceError, match="already running"):
        client.start()
    fake.last_curve, fake.last_result = None, None
    with pytest.raises(DigiForceError, match="status 04: no curve"):
        client.read_curve()
    with pytest.raises(DigiForceError, match="status 04: no result"):
        client.read_result()


def test_corrupt_responses_are_nakked_and_resent_without_re_execution(link) -> None:
    device, client, fake = link
    client.identify()
    one_exchange = client.bytes_received
    device.corrupt_next_responses(2)
    client.start()
    assert [c[0] for c in fake.calls] == ["start"]      # executed once, sent three times
    assert device.executed == 2
    assert client.bytes_received - one_exchange == 3 * len(encode_frame(5, 2, "ST", "00"))


class CorruptingWrites:
    """Wrap a pyserial port so the next ``n`` request frames leave with one bit flipped."""

    def __init__(self, port: serial.SerialBase, n: int) -> None:
        self._port, self.left = port, n

    def write(self, data: bytes) -> int:
        if self.left and data[0] == 0x02:
            self.left -= 1
            data = data[:6] + bytes([data[6] ^ 0x01]) + data[7:]
        return self._port.write(data)

    def __getattr__(self, name: str):
        return getattr(self._port, name)


def test_corrupt_requests_get_nak_and_are_retransmitted(link) -> None:
    device, client, fake = link
    client._port = CorruptingWrites(client._port, 2)
    client.select_program(7)
    assert device.naks_sent == 2 and device.executed == 1 and fake.active_program == 7


def test_lost_response_times_out_and_is_recovered_without_re_execution(link) -> None:
    device, client, fake = link
    device.drop_next_responses(1)
    t0 = time.monotonic()
    client.start()
    assert time.monotonic() - t0 >= client.timeout
    assert [c[0] for c in fake.calls] == ["start"] and device.executed == 1


def test_silence_ends_in_a_clear_timeout_error(link) -> None:
    device, client, fake = link
    device.drop_next_responses(4)
    t0 = time.monotonic()
    with pytest.raises(DigiForceTimeout, match=rf"{device.port}: command ST \(start\) .* after 4 tries "
                                               r"\(timeout, timeout, timeout, timeout\)"):
        client.start()
    assert 4 * client.timeout <= time.monotonic() - t0 < 4 * client.timeout + 1.0
    assert client.identify() == fake.identify()        # the link works again afterwards


def test_a_port_whose_device_is_gone_is_a_serial_exception_naming_it(fake) -> None:
    """A served machine that stopped while its host read the statistics: pyserial's flush of the dead pty raised a
    bare termios.error, which `rig record` printed as a traceback. Now it is pyserial's SerialException, which the
    host turns into its one-line error naming the link."""
    device = SerialDevice(fake, "pty", baudrate=1_000_000, address=5).start()
    client = DigiForceClient(device.port, baudrate=1_000_000, address=5, timeout=0.2, retries=1)
    try:
        assert client.identify() == fake.identify()
        device.close()                          # its pty is gone
        with pytest.raises(serial.SerialException, match=device.port):
            client.identify()
    finally:
        client.close()
    device = SerialDevice(fake, "pty", baudrate=1_000_000, address=5).start()      # gone while a reply is awaited
    client = DigiForceClient(device.port, baudrate=1_000_000, address=5, timeout=2.0, retries=1)
    try:
        device.drop_next_responses(2)
        closing = threading.Timer(0.2, device.close)
        closing.start()
        with pytest.raises(serial.SerialException):      # pyserial's read, or its in_waiting's OSError wrapped
            client.identify()
        closing.join()
    finally:
        client.close()


def test_persistent_corruption_ends_in_a_link_error(link) -> None:
    device, client, fake = link
    device.corrupt_next_responses(4)
    with pytest.raises(DigiForceLinkError, match=r"command ID \(identify\) .* 4 tries \(corrupt response") as e:
        client.identify()
    assert not isinstance(e.value, DigiForceTimeout) and e.value.tries == 4


def test_baud_rate_is_honoured_at_9600(fake) -> None:
    c = fake.last_curve
    fake.last_curve = Curve(c.t[:25], c.x[:25], c.y[:25], None, turning_index=10)
    y = c.y
    with SerialDevice(fake, "pty", baudrate=9600) as device, \
            DigiForceClient(device.port, baudrate=9600) as client:
        client.identify()                              # warm up
        sent, received = client.bytes_sent, client.bytes_received
        t0 = time.monotonic()
        curve = client.read_curve()                     # CH + one CB block: about 640 bytes
        elapsed = time.monotonic() - t0
        n_bytes = client.bytes_sent - sent - 2 * 3 + client.bytes_received - received   # last ACKs not awaited
    byte_time = n_bytes * 10 / 9600
    assert np.array_equal(curve.y, y[:25]) and byte_time > 0.6
    # never faster than the line allows (the point of the test); later only by scheduling on a busy machine,
    # so the upper bound is loose (a wrong baud rate, e.g. 4800, would double the time)
    assert 0.99 <= elapsed / byte_time <= 1.5, (elapsed, byte_time)


def _raw_exchange(port: serial.Serial, data: bytes, wait: float = 0.3) -> list:
    port.reset_input_buffer()
    port.write(data)
    deadline, got = time.monotonic() + wait, b""
    while time.monotonic() < deadline:
        got += port.read(64)
    return FrameParser().feed(got)


def test_malformed_and_foreign_frames_over_the_pty(link) -> None:
    device, client, fake = link
    client.close()
    with serial.Serial(device.port, 1_000_000, timeout=0.02) as raw:
        good = encode_frame(5, 1, "ID")
        events = _raw_exchange(raw, b"garbage\x03\x06x" + good)
        assert len(events) == 1 and events[0].data == "00" + fake.identify()
        assert [(e.ack, e.address) for e in _raw_exchange(raw, good[:-2] + b"00")] == [(False, 5)]
        assert _raw_exchange(raw, encode_frame(6, 1, "ID")[:-2] + b"00") == []     # other address, bad check
        assert _raw_exchange(raw, encode_frame(6, 2, "ID")) == []                  # other address
        assert [(e.ack, e.address) for e in _raw_exchange(raw, b"\x02051I\x07")] == [(False, 5)]  # control byte
        events = _raw_exchange(raw, encode_frame(5, 3, "XX"))
        assert events[0].data == "01unknown command 'XX'"
        assert _raw_exchange(raw, encode_frame(5, 4, "PS", "abc"))[0].data.startswith("02program number")
        assert _raw_exchange(raw, encode_frame(5, 5, "PW", "1,[1,2]"))[0].data.startswith("02PW configuration")
        assert _raw_exchange(raw, encode_frame(5, 6, "CB", "0"))[0].data.startswith("04")
        first = _raw_exchange(raw, encode_frame(5, 7, "SS"))
        assert first == _raw_exchange(raw, encode_handshake(False, 5))             # NAK → same response again
        frame = encode_frame(5, 8, "ID")                                           # inter-character timeout
        raw.write(frame[:4])
        time.sleep(0.3)
        assert _raw_exchange(raw, frame[4:]) == []
        assert device.executed == 6 and device.naks_sent == 2


def test_tcp_listener_and_socket_url(fake) -> None:
    with SerialDevice(fake, "tcp://127.0.0.1:0", baudrate=1_000_000, address=9) as device:
        assert device.port.startswith("socket://127.0.0.1:")
        with DigiForceClient(device.port, baudrate=1_000_000, address=9) as client:
            assert client.identify() == fake.identify()
            assert np.array_equal(client.read_curve().x, fake.last_curve.x)
        with DigiForceClient(device.port, baudrate=1_000_000, address=9) as client:   # reconnect
            assert client.status()["curves"] == 7


def _null_modem() -> tuple[str, socket.socket]:
    """A TCP 'cable' joining the first two connections to it (device and host both open socket:// URLs)."""
    listener = socket.create_server(("127.0.0.1", 0))

    def run() -> None:
        a, _ = listener.accept()
        b, _ = listener.accept()

        def pump(src: socket.socket, dst: socket.socket) -> None:
            try:
                while data := src.recv(65536):
                    dst.sendall(data)
            except OSError:                 # the other end closed first: the cable is unplugged
                pass
            try:                            # FIN to the other end now: close() alone waits for the other pump's
                dst.shutdown(socket.SHUT_RDWR)    # recv on dst to let go of it (under load it never did in time)
            except OSError:
                pass
            dst.close()
        threading.Thread(target=pump, args=(b, a), daemon=True).start()
        pump(a, b)
    threading.Thread(target=run, daemon=True).start()
    return f"socket://127.0.0.1:{listener.getsockname()[1]}", listener


def test_device_on_a_pyserial_url(fake) -> None:
    url, listener = _null_modem()
    with listener, SerialDevice(fake, url, baudrate=1_000_000) as device, \
            DigiForceClient(url, baudrate=1_000_000) as client:
        assert device.port == url
        assert client.identify() == fake.identify()
        client.select_program(2)
        assert client.get_program() == fake.programs[2]


@pytest.mark.filterwarnings("error::pytest.PytestUnhandledThreadExceptionWarning")
def test_a_line_that_goes_away_stops_the_device_with_one_warning(fake, caplog) -> None:
    """The host's end of a socket:// line disconnects: the device's thread ends with one warning naming the line
    (it died with pyserial's traceback, "socket disconnected")."""
    import logging
    url, listener = _null_modem()
    with listener, caplog.at_level(logging.WARNING, logger="firmware_sim.serial_device"), \
            SerialDevice(fake, url, baudrate=1_000_000) as device:
        host = socket.create_connection(listener.getsockname())
        host.close()                                            # the cable is pulled from the host's side
        device._thread.join(timeout=10)
        assert not device._thread.is_alive() and device.link_lost is not None
    assert device.link_lost.startswith(f"{url}: ") and "disconnected" in device.link_lost
    assert [r.getMessage() for r in caplog.records] == [
        f"serial device: the line is gone ({device.link_lost}); the device no longer answers"]


def test_start_and_stop_times_come_from_the_given_clock(fake) -> None:
    times = iter([1.25, 2.5])
    with SerialDevice(fake, "pty", baudrate=1_000_000, clock=lambda: next(times)) as device, \
            DigiForceClient(device.port, baudrate=1_000_000) as client:
        client.start()
        client.stop()
    assert fake.calls == [("start", 1.25), ("stop", 2.5)]


def test_bad_settings_are_refused_clearly(fake) -> None:
    with pytest.raises(ValueError, match="baud rate"):
        SerialDevice(fake, "pty", baudrate=0)
    with pytest.raises(ValueError, match="address"):
        SerialDevice(fake, "pty", address=255)
    with pytest.raises(ValueError, match="tcp://HOST:PORT"):
        SerialDevice(fake, "tcp://localhost")
    with pytest.raises(ValueError, match="cannot open '/dev/does-not-exist'"):
        SerialDevice(fake, "/dev/does-not-exist")
    with pytest.raises(DigiForceLinkError, match="/dev/does-not-exist: .*cannot open"):
        DigiForceClient("/dev/does-not-exist")
    with pytest.raises(ValueError, match="address"):
        DigiForceClient("loop://", address=0)


def test_a_frame_written_in_pieces_is_timed_by_the_simulated_line(fake) -> None:
    """At 9600 baud 2000 bytes take 2.08 s on the line; the rest of the frame written 0.2 s after them follows with no
    gap there, yet the device dropped the frame (it timed the gap from its read of the bytes; an audit). The gap runs
    from the last byte's arrival on the line: the frame is whole, and answered."""
    with SerialDevice(fake, "pty", baudrate=9600, address=5) as device:
        with serial.Serial(device.port, 9600, timeout=0.05) as raw:
            frame = encode_frame(5, 1, "ID", "x" * 2000)
            raw.write(frame[:2000])
            time.sleep(0.2)                         # well inside the 2.08 s the first piece takes on the line
            raw.write(frame[2000:])
            parser, events, deadline = FrameParser(), [], time.monotonic() + 30.0
            while not events and time.monotonic() < deadline:     # the answer, however long a loaded machine takes
                events = parser.feed(raw.read(64))
    assert [e.data[:2] for e in events] == ["02"] and "ID takes no request data" in events[0].data


def test_tare_of_no_channel_is_malformed_data(link) -> None:
    """TA z was status 03 (value out of range); a name that is no channel is malformed request data, 02."""
    device, client, fake = link
    client.close()
    with serial.Serial(device.port, 1_000_000, timeout=0.02) as raw:
        for seq, name in enumerate(("z", "X", "x,y"), start=1):
            (answer,) = _raw_exchange(raw, encode_frame(5, seq, "TA", name))
            assert answer.data == f"02TA takes a channel name (x, y, y2) or nothing, got {name!r}"

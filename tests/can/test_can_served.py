"""`rig serve` on the wire, seen by a passive socketcand client beside the host: status frames while idle,
Unix time stamps that never go back, one run from device time 0 that the host records in device time,
and the endpoints it announces."""
from __future__ import annotations

import contextlib
import json
import math
import queue
import threading
import time
from pathlib import Path

import can
import cantools
import jsonschema
import numpy as np
import pytest

from firmware_sim.can_node import DBC_PATH
from rig.recorder import read_recording
from rig.runner import record_scene, serve_scene
from rig.runner.config import read_config
from rig.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "data" / "scenes" / "pin_insertion.toml"
DB = cantools.database.load_file(str(DBC_PATH))
ID = {name: DB.get_message_by_name(name).frame_id for name in ("HostCommand", "CommandAck", "Heartbeat", "TxStatus")}


def listen(bus: can.BusABC, frames: list[can.Message], stop: threading.Event) -> None:
    """Collect every frame until the run's last one (TxStatus RunEnded) or ``stop``."""
    while not stop.is_set():
        msg = bus.recv(0.05)
        if msg is None:
            continue
        frames.append(msg)
        if msg.arbitration_id == ID["TxStatus"] and DB.decode_message(msg.arbitration_id, msg.data)["RunEnded"]:
            return


def test_served_machine_idles_then_runs_once_in_device_time(tmp_path: Path) -> None:
    announced: queue.Queue = queue.Queue()
    served: list = []
    server = threading.Thread(target=lambda: served.append(serve_scene(
        SCENE, cycles=1, port=0, wait=60, release_timeout=60, announce=announced.put)), daemon=True)
    server.start()
    ep = announced.get(timeout=60)
    schema = json.loads((ROOT / "docs" / "schemas" / "serve-endpoints.schema.json").read_text(encoding="utf-8"))
    jsonschema.validate(ep, schema, cls=jsonschema.Draft202012Validator)
    serial_cfg = read_config(load_scene(SCENE)).serial
    assert ep["serial_link"]["port"] == ep["serial"] and ep["serial_link"]["baudrate"] == serial_cfg["baudrate"]
    assert ep["serial_link"]["address"] == serial_cfg["address"]

    frames: list[can.Message] = []
    stop = threading.Event()
    with can.Bus(**ep["can"]) as passive:                     # a logger: connects, never sends
        listener = threading.Thread(target=listen, args=(passive, frames, stop), daemon=True)
        listener.start()
        started = time.time()
        while sum(m.arbitration_id == ID["Heartbeat"] for m in list(frames)) < 4 and time.time() < started + 10:
            time.sleep(0.05)
        idle, seen = [m for m in list(frames) if m.arbitration_id == ID["Heartbeat"]], time.time()
        out = tmp_path / "served.mcap"
        summary = record_scene(SCENE, out, can_host=ep["can"]["host"], can_port=ep["can"]["port"],
                               serial_port=ep["serial"], cycles=1, idle_timeout=60)
        server.join(timeout=60)
        listener.join(timeout=10)
        stop.set()
    assert summary.curves == 1 and not server.is_alive() and served[0].curves == 1

    # idle: a heartbeat every 0.1 s of wall time, stamped with the wall clock
    assert len(idle) >= 4
    stamps = np.array([m.timestamp for m in idle])
    assert started - 1.0 < stamps[0] and stamps[-1] < seen + 0.01
    assert np.allclose(np.diff(stamps[:4]), 0.1, atol=0.05)
    beats = [DB.decode_message(m.arbitration_id, m.data) for m in idle]
    assert [b["Seq"] for b in beats[:4]] == [(beats[0]["Seq"] + k) % 256 for k in range(4)]
    assert beats[0]["State"] in ("Idle", "Armed")                  # the scene's program waits for its trigger

    # the run: after the host's command, from the CommandAck on, in whole seconds + device time
    device = [m for m in frames if m.arbitration_id != ID["HostCommand"]]
    assert all(b.timestamp >= a.timestamp for a, b in zip(device, device[1:])), "stamps went back"
    first = next(i for i, m in enumerate(device) if m.arbitration_id == ID["CommandAck"])
    run = device[first:]
    origin = math.floor(run[0].timestamp)
    assert origin >= started and run[0].timestamp - origin < 1e-3
    beat = next(DB.decode_message(m.arbitration_id, m.data) for m in run if m.arbitration_id == ID["Heartbeat"])
    assert beat["Seq"] == 0 and beat["DeviceTime"] == 0.0          # the run's node starts afresh
    assert run[-1].arbitration_id == ID["TxStatus"]

    # the host recorded exactly the run's frames, in device time
    raw = read_recording(out).can_frames
    received = [k for k, i in enumerate(raw["id"]) if i != ID["HostCommand"]]
    assert [int(raw["id"][k]) for k in received] == [m.arbitration_id for m in run]
    assert [raw["data"][k] for k in received] == [bytes(m.data) for m in run]
    np.testing.assert_array_equal(raw["t"][received], [round((m.timestamp - origin) * 1e6) / 1e6 for m in run])


def _serve_in_thread(scene: Path = SCENE, **kwargs) -> tuple[threading.Thread, queue.Queue, list]:
    """serve_scene in a thread: (thread, its endpoints queue, [its machine or its exception, Ctrl-C's too])."""
    announced: queue.Queue = queue.Queue()
    outcome: list = []

    def serve() -> None:
        try:
            outcome.append(serve_scene(scene, port=0, announce=announced.put, **kwargs))
        except BaseException as exc:             # noqa: BLE001 - the test reads it (Ctrl-C is not an Exception)
            outcome.append(exc)
    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    return thread, announced, outcome


def _ack(bus: can.BusABC, timeout: float) -> dict | None:
    """The next CommandAck within ``timeout`` s of wall time, decoded."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        msg = bus.recv(0.1)
        if msg is not None and msg.arbitration_id == ID["CommandAck"]:
            return DB.decode_message(msg.arbitration_id, msg.data)
    return None


def _command(bus: can.BusABC, cmd: str, arg: int, seq: int) -> None:
    data = DB.encode_message(ID["HostCommand"], {"Cmd": cmd, "Arg": arg, "HostSeq": seq})
    bus.send(can.Message(arbitration_id=ID["HostCommand"], data=data, is_extended_id=False))


def test_idle_commands_are_answered_at_once_and_only_a_run_command_starts_the_run(caplog) -> None:
    """Before the run, Identify and a refused SelectProgram get their acks while the unit idles (not when a
    run starts later); an accepted SelectProgram starts the run, whose first frame is its ack at device
    time 0; the host's early Release ends the run there."""
    thread, announced, outcome = _serve_in_thread(cycles=500, wait=60, release_timeout=60)
    ep = announced.get(timeout=60)
    with can.Bus(**ep["can"]) as bus:
        _command(bus, "Identify", 0, 1)
        ident = _ack(bus, 30)
        _command(bus, "SelectProgram", 16, 2)                    # programs are 0…15: refused
        refused = _ack(bus, 30)
        beat = None
        while beat is None:                                       # the unit still idles: its idle heartbeats
            msg = bus.recv(5)
            if msg is not None and msg.arbitration_id == ID["Heartbeat"]:
                beat = msg
        _command(bus, "SelectProgram", 1, 3)
        started = _ack(bus, 30)
        _command(bus, "Release", 0, 4)
        thread.join(timeout=120)
    assert ident is not None and ident["AckStatus"] == "Done" and ident["Cmd"] == 6 and ident["HostSeq"] == 1
    assert refused is not None and refused["AckStatus"] == "Rejected" and refused["HostSeq"] == 2
    assert started is not None and started["AckStatus"] == "Done" and started["HostSeq"] == 3
    assert not thread.is_alive() and not isinstance(outcome[0], Exception)
    assert outcome[0].curves < 500 and "the run was cut short there" in caplog.text    # released early


def test_a_host_that_disconnects_without_releasing_stops_the_server_at_once() -> None:
    """The release timeout is for a host that stays connected and silent; one that leaves is noticed at once."""
    thread, announced, outcome = _serve_in_thread(cycles=3, wait=60, release_timeout=600)
    ep = announced.get(timeout=60)
    with can.Bus(**ep["can"]) as bus:
        _command(bus, "SelectProgram", 1, 1)
        assert _ack(bus, 30) is not None
    thread.join(timeout=120)                                      # far below the 600 s release timeout
    assert not thread.is_alive()
    assert isinstance(outcome[0], Exception) and "the host disconnected" in str(outcome[0])
    assert "without releasing the device" in str(outcome[0])


def test_a_host_that_leaves_while_a_listener_stays_stops_the_run_and_the_listener_hears_why() -> None:
    """The run's host left without Release while a passive logger stayed connected: the served machine ran on to its
    end (any open connection kept it going) and then waited for a Release that could not come. Now the host's
    leaving stops the run at once, and the logger gets the unit's last status naming it (StopCause HostLeft)."""
    thread, announced, outcome = _serve_in_thread(cycles=200, wait=60, release_timeout=60)
    ep = announced.get(timeout=60)
    frames: list[can.Message] = []
    stop = threading.Event()
    with can.Bus(**ep["can"]) as passive:
        logger = threading.Thread(target=listen, args=(passive, frames, stop), daemon=True)
        logger.start()
        with can.Bus(**ep["can"]) as host:
            _command(host, "SelectProgram", 1, 1)
            assert _ack(host, 30) is not None                     # the run has started; the host leaves
        thread.join(timeout=60)
        logger.join(timeout=30)
        stop.set()
    assert not thread.is_alive() and "the host disconnected during the run" in str(outcome[0])
    status = DB.decode_message(frames[-1].arbitration_id, frames[-1].data)
    assert frames[-1].arbitration_id == ID["TxStatus"] and status["RunEnded"] == 1
    assert str(status["StopCause"]) == "HostLeft"
    beats = [DB.decode_message(m.arbitration_id, m.data)["DeviceTime"] for m in frames
             if m.arbitration_id == ID["Heartbeat"]]
    assert beats[-1] < 40.0                                        # far from the 80 s run's end


def test_a_served_machine_waits_for_a_host_that_stops_reading_while_a_passive_logger_keeps_up() -> None:
    """Back-pressure: a host that stopped reading (stalled, suspended) let the served machine compute its whole run
    ahead into an unbounded queue (1500 cycles in 49 s, +105 MB; curves measured but never delivered when serve was
    stopped). Now the machine waits once its host's connection holds SERVE_BACKLOG frames (plus what the sockets
    buffer): a passive logger beside it sees the frames stop far short of the run's end, and then again when the
    host reads on. A logger that only listens holds nothing back."""
    thread, announced, outcome = _serve_in_thread(cycles=500, wait=60, release_timeout=60)     # 200 s of device time
    ep = announced.get(timeout=60)
    seen: list[float] = []
    stop = threading.Event()

    def log_times(bus: can.BusABC) -> None:
        while not stop.is_set():
            try:
                msg = bus.recv(0.05)
            except can.CanError:                  # the server closed the connection at its end
                return
            if msg is not None:
                seen.append(msg.timestamp)

    def stalled() -> float:
        """The passive logger's last stamp once no frame came for 2 s of wall time (the machine waits)."""
        count, quiet = len(seen), time.monotonic()
        while time.monotonic() - quiet < 2.0:
            time.sleep(0.1)
            if len(seen) != count:
                count, quiet = len(seen), time.monotonic()
            assert thread.is_alive(), outcome
        return seen[-1]

    with can.Bus(**ep["can"]) as passive, can.Bus(**ep["can"]) as host:
        logger = threading.Thread(target=log_times, args=(passive,), daemon=True)
        logger.start()
        _command(host, "SelectProgram", 1, 1)                     # the run starts; the host reads nothing more
        first = stalled()
        origin = math.floor(min(t for t in seen if t >= first - 300))
        assert first - origin < 100, "the machine ran on without its host"
        frames, deadline = len(seen), time.monotonic() + 120
        while len(seen) == frames and time.monotonic() < deadline:   # the host reads on (through the sockets'
            host.recv(1.0)                                        # buffers first): the machine goes on
        second = stalled()
        assert len(seen) > frames and second > first and second - origin < 150
        _command(host, "Release", 0, 2)               # taken at once, though the host reads nothing more
        thread.join(timeout=120)
        stop.set()
        logger.join(timeout=10)
    assert not thread.is_alive() and outcome[0].curves < 500


def test_a_release_before_any_run_says_no_run_was_served_and_the_endpoints_name_the_scene_absolutely(tmp_path):
    """`rig serve` given a relative scene path published it as such (a host elsewhere could not open it), and a
    Release before any start printed "no run served" and then "served the run, 0.00 s simulated"."""
    import subprocess
    import sys
    endpoints = tmp_path / "ep.json"
    serve = subprocess.Popen([sys.executable, "-m", "rig.cli", "-q", "serve", "data/scenes/pin_insertion.toml",
                              "--endpoints", str(endpoints), "--wait", "120"], cwd=ROOT,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not endpoints.exists() or not endpoints.read_text():
            assert serve.poll() is None, serve.stderr.read()
            assert time.monotonic() < deadline
            time.sleep(0.05)
        ep = json.loads(endpoints.read_text())
        assert ep["scene"] == str(SCENE)
        with can.Bus(**ep["can"]) as bus:
            _command(bus, "Release", 0, 1)
            assert serve.wait(timeout=120) == 0
        err = serve.stderr.read()
        assert "released the device before starting a run: no run served" in err and "simulated" not in err
    finally:
        serve.kill()
        serve.wait()


def test_a_can_fd_scene_is_refused_by_serve_and_record_before_anything_starts(tmp_path: Path, caplog) -> None:
    """socketcand carries classic frames only: an FD scene served lost every curve frame while the host recorded an
    "OK" run of curves it never got; now both ends refuse it, naming the key and the way out — before the run's
    fidelity is announced (nothing is said about a run that will not start)."""
    import pytest
    from rig.scene import SceneError
    caplog.set_level("INFO")
    fd = tmp_path / "fd.toml"
    fd.write_text(SCENE.read_text().replace("bitrate = 1000000", "bitrate = 500000\nfd = true\ndata_bitrate = 2000000",
                                            1))
    assert read_config(load_scene(fd)).can["fd"]
    with pytest.raises(SceneError, match=r"fd.toml \[links.can\]: fd = true, but rig serve .*classic CAN frames only"):
        serve_scene(fd, announce=lambda endpoints: pytest.fail(f"served: {endpoints}"))
    with pytest.raises(SceneError, match=r"\[links.can\]: fd = true, but rig record .*set fd = false"):
        record_scene(fd, tmp_path / "x.mcap", can_port=1, serial_port=None)
    assert not (tmp_path / "x.mcap").exists()
    assert not [r for r in caplog.records if "fidelity" in r.getMessage()], [r.getMessage() for r in caplog.records]


@pytest.mark.parametrize("scene", [SCENE, ROOT / "data" / "scenes" / "lab_speed.toml"])
def test_a_host_recording_less_than_served_ends_at_the_same_frame_however_the_frames_come(tmp_path, scene) -> None:
    """`rig record --cycles 8` against a longer served run stops listening RUN_END_WAIT s of device time after the
    frames that completed its 8th curve (a duration scene: after its duration). Its cut was taken from the device
    time of whatever batch it had just read, so the recording's end moved with the processes' timing (12.29 s,
    10.42 s, 10.40 s in three runs of one scene). Here the same frames reach the host at once, in blocks of 997 and
    of 50: the same recording every time."""
    import dataclasses
    from rig.blockbus import FrameBlock
    from rig.runner.host import Host
    from rig.runner.session import _config, _recorder, run_scene
    served = tmp_path / "served.mcap"
    cycles = scene == SCENE
    run_scene(scene, served, cycles=14 if cycles else None)      # what a longer served run puts on the bus
    raw = read_recording(served).can_frames
    rx = np.array([d == "rx" for d in raw["dir"]])
    data = np.zeros((int(rx.sum()), 8), np.uint8)
    for row, payload in enumerate(p for p, keep in zip(raw["data"], rx) if keep):
        data[row, :len(payload)] = np.frombuffer(payload, np.uint8)
    frames = FrameBlock(np.asarray(raw["t"])[rx], np.asarray(raw["id"], np.uint32)[rx],
                        np.array([len(p) for p, keep in zip(raw["data"], rx) if keep], np.int16), data,
                        np.zeros(int(rx.sum()), np.uint8))
    ends = []
    for size in (len(frames), 997, 50):
        cfg = _config(scene, 8, None) if cycles else dataclasses.replace(_config(scene, None, None), duration=2.5)
        channel = f"test-cut-{size}"
        with can.Bus(interface="blockbus", channel=channel) as wire, \
                can.Bus(interface="blockbus", channel=channel) as bus, \
                _recorder(cfg, tmp_path / f"host_{size}.mcap", "cross-process") as rec:
            host = Host(cfg, bus, None, rec)
            host.stops_listening = True
            for start in range(0, len(frames), size):
                wire.send_block(frames.take(slice(start, start + size)))
                host.poll()
                if host.done() and host.run_over():
                    break
            assert host.done() and host.run_over() and not host.can.run_ended
            ends.append((host.frames, host.can.device_time, host.curves_recorded))
            host.finish()
    assert ends[0][2] == (8 if cycles else 0) and ends[0][0] < len(frames)
    assert cycles or ends[0][1] <= 2.5 + 2.0          # a duration scene: cut RUN_END_WAIT after its duration
    assert ends[1] == ends[0] and ends[2] == ends[0], ends
    recorded = [read_recording(tmp_path / f"host_{size}.mcap").can_frames for size in (len(frames), 997, 50)]
    for other in recorded[1:]:
        np.testing.assert_array_equal(other["t"], recorded[0]["t"])


def test_a_recording_stopped_by_ctrl_c_holds_the_release_it_sent(tmp_path, monkeypatch) -> None:
    """On Ctrl-C (or SIGTERM, or an error) `rig record` tells the served machine it is done; the Release went on the
    bus but not into /can/raw, whose doc promises every frame, the host's own commands included."""
    from rig.runner.host import Host
    thread, announced, outcome = _serve_in_thread(cycles=500, wait=60, release_timeout=60)
    ep = announced.get(timeout=60)
    poll = Host.poll

    def interrupted_poll(self, timeout=0.0):
        if self.curves_recorded:                  # mid-run: it has curves, and wants 400
            raise KeyboardInterrupt
        return poll(self, timeout)
    monkeypatch.setattr(Host, "poll", interrupted_poll)
    out = tmp_path / "stopped.mcap"
    with pytest.raises(BaseException):
        record_scene(SCENE, out, can_host=ep["can"]["host"], can_port=ep["can"]["port"], serial_port=ep["serial"],
                     cycles=400, idle_timeout=60)
    thread.join(timeout=120)
    rec = read_recording(out, allow_partial=True)
    raw = rec.can_frames
    sent = [DB.decode_message(int(i), d) for i, d, way in zip(raw["id"], raw["data"], raw["dir"]) if way == "tx"]
    assert rec.interrupted and sent[-1]["Cmd"] == "Release" and len(sent) >= 2
    assert not thread.is_alive() and not isinstance(outcome[0], Exception)    # released: serve ended as asked


def test_a_served_run_stopped_by_an_error_delivers_what_it_sent_as_rig_run_records_it(tmp_path) -> None:
    """A bus too slow for the scene's curves stops the run with an error. `rig run` records every frame already on
    the wire; `rig serve` closed its links at once, so its host recorded 7 547, 10 469 or 10 206 frames in three
    identical runs. Now it waits for its hosts to take what it sent: the same frames as in one process. The unit's
    last frame says why its run stopped (TxStatus.StopCause, read here with cantools and the DBC alone): the host
    names the cause instead of "see its console", and both recordings hold it as a run_stopped event."""
    from rig.runner.session import RunError, run_scene
    scene = tmp_path / "slow_bus.toml"
    text = SCENE.read_text()
    assert "bitrate = 1000000" in text
    scene.write_text(text.replace("bitrate = 1000000", "bitrate = 500000", 1))
    one = tmp_path / "one.mcap"
    with pytest.raises(RunError, match="cannot carry the curves"):
        run_scene(scene, one)
    thread, announced, outcome = _serve_in_thread(scene, wait=60, release_timeout=60)
    ep = announced.get(timeout=60)
    two = tmp_path / "two.mcap"
    with pytest.raises(RunError, match=r"stopped its run \(BusOverload: the CAN bus cannot carry"):
        record_scene(scene, two, can_host=ep["can"]["host"], can_port=ep["can"]["port"], serial_port=ep["serial"],
                     idle_timeout=60)
    thread.join(timeout=60)
    assert isinstance(outcome[0], RunError) and "cannot carry the curves" in str(outcome[0])
    recs = [read_recording(p, allow_partial=True) for p in (one, two)]
    a, b = (r.can_frames for r in recs)
    rx_a, rx_b = ([k for k, way in enumerate(f["dir"]) if way == "rx"] for f in (a, b))
    assert len(rx_a) > 5000 and len(rx_b) == len(rx_a)
    np.testing.assert_array_equal(np.asarray(b["t"])[rx_b], np.asarray(a["t"])[rx_a])
    last = rx_a[-1]
    assert a["id"][last] == ID["TxStatus"]
    status = DB.decode_message(ID["TxStatus"], bytes(a["data"][last]))
    assert status["RunEnded"] == 1 and str(status["StopCause"]) == "BusOverload"
    for rec in recs:
        stopped = [e for e in rec.events if e["kind"] == "run_stopped"]
        assert len(stopped) == 1 and stopped[0]["detail"].startswith("BusOverload: ")


def test_a_served_run_stopped_by_its_operator_tells_its_host_why(tmp_path, monkeypatch) -> None:
    """Ctrl-C (or SIGTERM) on `rig serve` closed its links at once: its host could only say "closed the connection
    (see its console)". Now the unit's last status names the stop (StopCause OperatorStop), the served machine waits
    for its host to take it, and the host's error and recording say why."""
    from rig.runner.machine import Machine
    from rig.runner.session import RunError
    step = Machine.step

    def stopped_step(self, *args, **kwargs):
        if self.curves >= 3:                    # mid-run: the operator presses Ctrl-C
            raise KeyboardInterrupt
        return step(self, *args, **kwargs)
    monkeypatch.setattr(Machine, "step", stopped_step)
    thread, announced, outcome = _serve_in_thread(wait=60, release_timeout=60)
    ep = announced.get(timeout=60)
    out = tmp_path / "stopped.mcap"
    with pytest.raises(RunError, match=r"stopped its run \(OperatorStop: the unit's operator stopped it"):
        record_scene(SCENE, out, can_host=ep["can"]["host"], can_port=ep["can"]["port"], serial_port=ep["serial"],
                     cycles=10, idle_timeout=60)
    thread.join(timeout=60)
    assert not thread.is_alive() and isinstance(outcome[0], KeyboardInterrupt)
    rec = read_recording(out, allow_partial=True)
    stopped = [e for e in rec.events if e["kind"] == "run_stopped"]
    assert rec.interrupted and 1 <= len(rec.curves) <= 3 and len(stopped) == 1
    raw = rec.can_frames
    last = max(k for k, way in enumerate(raw["dir"]) if way == "rx")
    status = DB.decode_message(int(raw["id"][last]), bytes(raw["data"][last]))
    assert str(status["StopCause"]) == "OperatorStop" and status["RunEnded"] == 1


def test_a_listener_that_does_not_read_keeps_a_bounded_queue_and_the_drops_are_said(monkeypatch, caplog) -> None:
    """A connection that only listens never holds the served machine back; when it stopped reading, what it had not
    taken grew without bound in rig serve. Now beyond LISTENER_BACKLOG frames its oldest are dropped, counted and
    said once, as a CAN interface's receive queue overflows; a host that reads is not touched."""
    from types import SimpleNamespace
    from rig.blockbus import FrameBlock
    from rig.runner import session
    monkeypatch.setattr(session, "LISTENER_BACKLOG", 500)
    channel = f"room-{time.monotonic_ns()}"
    with can.Bus(interface="blockbus", channel=channel) as machine_bus, contextlib.ExitStack() as stack:
        room = session._HostRoom(machine_bus, channel, SimpleNamespace(t=0.0), limit=60.0)
        listener, host = room.client_bus(), room.client_bus()
        stack.callback(listener.shutdown)
        stack.callback(host.shutdown)
        host.send(can.Message(arbitration_id=0x50, data=bytes(8), is_extended_id=False))   # a host: sent and reads
        host.recv(0)
        for k in range(20):
            machine_bus.send_block(FrameBlock.of_messages([can.Message(timestamp=k + i * 1e-3, arbitration_id=0x200,
                                                                       is_extended_id=False, data=bytes(8))
                                                           for i in range(100)]))
            with caplog.at_level("WARNING", logger="rig.runner.session"):
                assert room(0.0)                  # the listener never holds the machine back
            if k % 10 == 9:                       # the host reads on, 1000 frames behind at times: beyond what a
                host.recv_blocks(0.0)             # listener keeps, within a host's SERVE_BACKLOG — nothing dropped
        assert listener.pending < 600 and listener.dropped == 2001 - listener.pending == room.dropped  # + the command
        assert host.dropped == 0
        said = [r.getMessage() for r in caplog.records if "only listens" in r.getMessage()]
        assert len(said) == 1 and "beyond 500 are dropped" in said[0]


def test_ctrl_c_after_the_served_run_lets_the_host_take_every_curve(tmp_path, monkeypatch, caplog) -> None:
    """Ctrl-C on `rig serve` after its run ended (RunEnded sent) while its host still read the backlog closed the
    links at once: the host lost its last curves and printed a termios traceback reading the statistics. Now the
    served machine waits for its hosts to take what it sent; the host records every curve and stops in one line
    naming the serial link (the statistics can no longer be read)."""
    from rig.runner import session
    from rig.runner.session import RunError

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(session, "_wait_for_release", interrupted)
    thread, announced, outcome = _serve_in_thread(cycles=10, wait=60, release_timeout=60)
    ep = announced.get(timeout=60)
    out = tmp_path / "after.mcap"
    with pytest.raises(RunError, match="serial link .* failed while reading the statistics back"):
        record_scene(SCENE, out, can_host=ep["can"]["host"], can_port=ep["can"]["port"], serial_port=ep["serial"],
                     idle_timeout=60)
    thread.join(timeout=60)
    assert isinstance(outcome[0], KeyboardInterrupt) and "after its run (10 curves served)" in caplog.text
    rec = read_recording(out, allow_partial=True)
    assert len(rec.curves) == 10 and len(rec.results) == 10

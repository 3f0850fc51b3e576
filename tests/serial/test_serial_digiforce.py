"""The serial link in front of the real simulated DigiForce: a measurement driven and read over a pty."""
from __future__ import annotations

import json
import threading

import numpy as np
import pytest

from drivers.digiforce_serial import DigiForceClient, DigiForceError
from firmware_sim.digiforce import DigiForce
from firmware_sim.serial_device import SerialDevice


def _same_json(a: object, b: object) -> bool:
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


def test_measurement_over_serial_matches_the_unit() -> None:
    unit = DigiForce(rng=np.random.default_rng(7))
    lock = threading.Lock()
    t = np.arange(3000) * 1e-4
    x_volts = 2.5 * (1 - np.cos(2 * np.pi * t / t[-1]))        # out and back: forward and return part
    y_ratio = 1e-3 * np.sin(np.pi * t / t[-1]) ** 2
    with SerialDevice(unit, "pty", baudrate=1_000_000, lock=lock) as device, \
            DigiForceClient(device.port, baudrate=1_000_000) as client:
        assert client.identify() == unit.identify()
        active, count = client.active_program()
        assert (active, count) == (unit.active_program, unit.n_programs)
        client.configure_channel(active, "y", cutoff=500.0)
        assert unit.get_program(active)["channels"]["y"]["cutoff"] == client.get_program()["channels"]["y"]["cutoff"]
        with lock:
            unit.feed(t[:10], x_volts[:10], y_ratio[:10])
        client.tare("y")
        client.start()
        with lock:
            unit.feed(t[10:], x_volts[10:], y_ratio[10:])
        client.stop()
        curve = client.read_curve(with_time=True)
        assert len(curve.x) > 100
        assert np.array_equal(curve.t, unit.last_curve.t) and np.array_equal(curve.x, unit.last_curve.x)
        assert np.array_equal(curve.y, unit.last_curve.y)
        assert curve.info["turning_index"] == unit.last_curve.turning_index
        assert _same_json(client.read_result(), unit.last_result.to_dict(include_curve=False))
        assert _same_json(client.read_statistics(), unit.statistics())
        assert client.status()["curves"] == 1 and unit.statistics()["total"] == 1
        client.reset_statistics()
        assert unit.statistics()["total"] == 0
        with pytest.raises(DigiForceError, match=rf"status 03: .*program number must be an integer 0...{count - 1}"):
            client.select_program(count)
        with pytest.raises(DigiForceError, match=r"status 02: TA takes a channel name \(x, y, y2\) or nothing, got .q."):
            client.tare("q")


def test_tare_preconditions_over_serial() -> None:
    """TA needs an input sample since the active program was selected or written, an enabled channel and
    no measurement running (docs/serial-protocol.md, section 4)."""
    unit, lock = DigiForce(), threading.Lock()
    t = np.arange(20) * 1e-4
    with SerialDevice(unit, "pty", baudrate=1_000_000, lock=lock) as device, \
            DigiForceClient(device.port, baudrate=1_000_000) as client:
        with pytest.raises(DigiForceError, match="status 03: .*tare x: no input sample yet"):
            client.tare()
        with lock:
            unit.feed(t[:10], np.full(10, 1.0), np.full(10, 1e-4))
        client.tare()
        assert unit.live_values()["x"][-1] == 0.0 and unit.live_values()["y"][-1] == 0.0
        with pytest.raises(DigiForceError, match="status 03: .*channel must be one of \\['x', 'y'\\], got 'y2'"):
            client.tare("y2")
        client.start()
        with lock:
            unit.feed(t[10:], np.full(10, 2.0), np.full(10, 2e-4))
        with pytest.raises(DigiForceError, match="status 03: .*tare: not allowed while a measurement is running"):
            client.tare("y")
        client.stop()
        client.tare("y")
        client.select_program(1)
        with pytest.raises(DigiForceError, match="status 03: .*tare x: no input sample yet"):
            client.tare("x")


@pytest.mark.parametrize("command, data", [("ID", "junk"), ("ST", "1"), ("SP", "x"), ("SS", " "), ("CH", "0"),
                                           ("RR", "1")])
def test_a_command_without_request_data_refuses_some(command, data) -> None:
    """§4 lists these with no request data; "ST1" started a measurement and "IDjunk" identified (a clean-room client's
    finding). Malformed request data is status 02, and nothing is done."""
    from firmware_sim.serial_protocol.commands import Commands
    unit = DigiForce()
    answer = Commands(unit, None, threading.Lock()).execute(command, data)
    assert answer.startswith("02") and f"{command} takes no request data" in answer
    assert unit.status()["state"] != "measuring"


@pytest.mark.parametrize("data", [" 1", "+1", "1_0", "1 "])
def test_program_numbers_are_decimal_digits_only(data) -> None:
    from firmware_sim.serial_protocol.commands import Commands
    answer = Commands(DigiForce(), None, threading.Lock()).execute("PS", data)
    assert answer.startswith("02") and "program number must be a decimal integer" in answer


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_a_non_finite_token_in_pw_json_is_not_json(token) -> None:
    """Strict RFC 8259: the device parsed NaN and refused the value (03); the payload is not JSON (02)."""
    from firmware_sim.serial_protocol.commands import Commands
    answer = Commands(DigiForce(), None, threading.Lock()).execute("PW", f'3,{{"channels":{{"x":{{"cutoff":{token}}}}}}}')
    assert answer.startswith("02PW configuration is not valid JSON") and "no NaN or Infinity" in answer


@pytest.mark.parametrize("payload, why", [
    ('3,{"channels":{"x":{"cutoff":10,"cutoff":0}}}', "the key 'cutoff' appears twice in one object"),
    ("3," + "[" * 100000 + "]" * 100000, "nested too deeply"),
    ('3,{"name":' + "[" * 500 + "]" * 500 + "}", "nested too deeply"),
    ('3,{"channels":{"x":{"scaling":[[[[[[[[1]]]]]]]]}}}', "nested too deeply (more than 8 levels")])
def test_pw_refuses_repeated_keys_and_deep_nesting_as_not_json(payload, why) -> None:
    """A key twice in one object was accepted, the last value kept; JSON nested 100 000 deep answered 05 (the state
    error: the parser's RecursionError is a RuntimeError), and 500 deep it parsed, then overflowed the stack in the
    program's merge (05 again). All are the request's fault: 02 naming it, and the program unchanged."""
    from firmware_sim.serial_protocol.commands import Commands
    commands = Commands(DigiForce(), None, threading.Lock())
    before = commands.execute("PG", "3")
    answer = commands.execute("PW", payload)
    assert answer.startswith("02PW configuration is not valid JSON") and why in answer
    assert commands.execute("PG", "3") == before


def test_pw_refuses_a_program_pg_could_not_read_back() -> None:
    """A 65 kB program name fits a PW request but makes the program's JSON longer than a PG response carries: PW
    accepted it and PG answered 09 until it was rewritten; PW refuses it (03) and the program stays as it was."""
    from firmware_sim.serial_protocol.commands import MAX_DATA, Commands
    unit = DigiForce()
    commands = Commands(unit, None, threading.Lock())
    before = commands.execute("PG", "3")
    name = "a" * (MAX_DATA - 20)
    answer = commands.execute("PW", f'3,{{"name":"{name}"}}')
    assert answer.startswith("03") and "more than a PG response carries" in answer
    assert commands.execute("PG", "3") == before
    assert commands.execute("PW", '3,{"name":"short"}') == "00"


def test_pw_null_removes_a_limit() -> None:
    """PW merges as a JSON merge patch: a limit, once set, could not be removed (null and [null, null] refused, {}
    changed nothing); null removes it."""
    from firmware_sim.serial_protocol.commands import Commands
    commands = Commands(DigiForce(), None, threading.Lock())
    assert commands.execute("PW", '3,{"limits":{"x_max":[0.01,0.02],"y_min":[-1,1]}}') == "00"
    assert commands.execute("PW", '3,{"limits":{"x_max":null}}') == "00"
    assert json.loads(commands.execute("PG", "3")[2:])["limits"] == {"y_min": [-1.0, 1.0]}


def test_pw_with_an_empty_program_field_writes_the_active_program() -> None:
    """docs/serial-protocol.md: "An empty program field means the active program" — PS, PG, RS and RZ followed it,
    PW answered 02 (a clean-room client)."""
    from firmware_sim.serial_protocol.commands import Commands
    unit = DigiForce()
    commands = Commands(unit, None, threading.Lock())
    assert commands.execute("PS", "2").startswith("00")
    assert commands.execute("PW", ',{"name":"active"}').startswith("00")
    assert unit.get_program(2)["name"] == "active" and unit.get_program(0)["name"] != "active"


def test_the_richest_program_nests_within_the_pw_depth_limit() -> None:
    """The PW depth limit (8) leaves room above a program with every feature (6 levels): PW takes it, PG returns it."""
    from firmware_sim.serial_protocol.commands import MAX_DEPTH, Commands, _depth
    from tests.fuzz.test_fuzz_serial_device import FEATURES
    commands = Commands(DigiForce(), None, threading.Lock())
    assert commands.execute("PW", "3," + json.dumps(FEATURES, separators=(",", ":"))) == "00"
    assert _depth(FEATURES) == _depth(json.loads(commands.execute("PG", "3")[2:])) == 6 < MAX_DEPTH


def test_curve_block_requests_are_checked_in_the_documented_order() -> None:
    """docs/serial-protocol.md: a latched curve (04), for CY one with a second Y (04), then the index: decimal (02),
    within the blocks (03) — the first broken one answers."""
    from firmware_sim.serial_protocol.commands import Commands
    unit = DigiForce()
    commands = Commands(unit, None, threading.Lock())
    assert commands.execute("CB", "x").startswith("04") and commands.execute("CB", "99").startswith("04")
    t = np.arange(300) * 1e-3
    unit.start()
    unit.feed(t, np.sin(t), np.cos(t))
    unit.stop()
    assert commands.execute("CH", "").startswith("00")
    assert commands.execute("CY", "x").startswith("04")                      # no second Y before the index
    assert commands.execute("CB", "x").startswith("02") and commands.execute("CB", "99").startswith("03")
    assert commands.execute("CB", "0").startswith("000,")

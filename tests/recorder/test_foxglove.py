"""The demo recording as Foxglove sees it: every schema keeps to Foxglove's JSON-schema parser rules, every
message is valid against its schema (jsonschema, when installed) and holds no JSON null; per-sample view
channels, foxglove.Log events, log times anchored to the wall clock, every topic documented, the host's
own CAN frames on /can/raw, and only the encoders the scene declares."""
from __future__ import annotations

import re
from pathlib import Path

import cantools
import numpy as np
import orjson
import pytest
from mcap.reader import make_reader

from rig.recorder import read_recording
from rig.runner import run_scene

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "data" / "scenes" / "pin_insertion.toml"
CYCLES = 2


def foxglove_rule_errors(schema: object, path: str = "$") -> list[str]:
    """Where ``schema`` breaks the rules of Foxglove's JSON-schema parser: one string per ``type``; every
    object has ``properties`` whose entries each have a ``type`` (or a ``oneOf`` of number constants, as
    enums); every array has ``items`` with a type. Nested ``additionalProperties`` schemas are checked too."""
    if not isinstance(schema, dict):
        return [f"{path}: not a schema object"]
    errors = []
    kind = schema.get("type")
    if "type" in schema and not isinstance(kind, str):
        errors.append(f"{path}: type {kind!r} is not one string")
    if kind == "object":
        props = schema.get("properties")
        if not isinstance(props, dict):
            errors.append(f"{path}: object without properties")
            props = {}
        for name, sub in props.items():
            enum = isinstance(sub, dict) and "type" not in sub and sub.get("oneOf") and all(
                isinstance(a.get("const"), (int, float)) for a in sub["oneOf"])
            if enum:
                continue
            if not isinstance(sub, dict) or "type" not in sub:
                errors.append(f"{path}.{name}: property without a type")
            errors += foxglove_rule_errors(sub, f"{path}.{name}")
        if isinstance(schema.get("additionalProperties"), dict):
            errors += foxglove_rule_errors(schema["additionalProperties"], f"{path}.*")
    elif kind == "array":
        items = schema.get("items")
        if not isinstance(items, dict) or "type" not in items:
            errors.append(f"{path}: array without typed items")
        else:
            errors += foxglove_rule_errors(items, f"{path}[]")
    return errors


def test_rule_checker_finds_what_foxglove_rejects():
    assert foxglove_rule_errors({"type": "object", "properties": {"v": {"type": "array", "items": {
        "type": ["number", "null"]}}}}) == ["$.v[]: type ['number', 'null'] is not one string"]
    assert foxglove_rule_errors({"type": "object", "properties": {"pv": {
        "type": "object", "additionalProperties": {"type": "number"}}}}) == ["$.pv: object without properties"]
    assert foxglove_rule_errors({"type": "object", "properties": {"a": {"type": "array"}, "b": {}}}) == [
        "$.a: array without typed items", "$.b: property without a type"]
    assert foxglove_rule_errors({"type": "object", "properties": {"level": {"oneOf": [{"const": 1}]}}}) == []


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("foxglove") / "demo.mcap"
    run_scene(SCENE, out, cycles=CYCLES)
    return out


@pytest.fixture(scope="module")
def channels(demo: Path) -> dict[str, dict]:
    """Per topic: schema name and dict, and every message as (log_time, parsed JSON)."""
    out: dict[str, dict] = {}
    with open(demo, "rb") as f:
        reader = make_reader(f)
        for schema, channel, msg in reader.iter_messages():
            entry = out.setdefault(channel.topic, {"name": schema.name, "schema": orjson.loads(schema.data),
                                                   "encoding": schema.encoding, "messages": []})
            entry["messages"].append((msg.log_time, orjson.loads(msg.data)))
    return out


def _nulls(value: object, path: str = "") -> list[str]:
    if value is None:
        return [path or "/"]
    if isinstance(value, dict):
        return [p for k, v in value.items() for p in _nulls(v, f"{path}/{k}")]
    if isinstance(value, list):
        return [p for i, v in enumerate(value) for p in _nulls(v, f"{path}/{i}")]
    return []


def test_every_schema_keeps_to_foxglove_rules(channels):
    assert {"/plant/truth", "/device/curve", "/device/result", "/device/statistics", "/events", "/log", "/can/raw",
            "/view/plant", "/view/device", "/stand/encoder1"} <= set(channels)
    for topic, ch in channels.items():
        assert ch["encoding"] == "jsonschema"
        assert ch["schema"]["type"] == "object", topic
        assert foxglove_rule_errors(ch["schema"]) == [], topic


def test_every_message_is_valid_against_its_schema_without_nulls(channels):
    for topic, ch in channels.items():
        for _, msg in ch["messages"]:
            assert _nulls(msg) == [], topic
    jsonschema = pytest.importorskip("jsonschema")
    for topic, ch in channels.items():
        validator = jsonschema.Draft202012Validator(ch["schema"])
        for _, msg in ch["messages"]:
            errors = [e.message for e in validator.iter_errors(msg)]
            assert errors == [], (topic, errors[:3])


def test_log_times_are_wall_clock_start_plus_simulation_time(demo, channels):
    rec = read_recording(demo)
    start = int(rec.metadata["rig"]["wall_clock_start"])
    assert start > 1_600_000_000 * 10**9                  # a date after 2020, not 1970
    for topic in ("/events", "/view/plant", "/view/device"):
        for log_time, msg in channels[topic]["messages"]:
            assert log_time == start + round(msg["t"] * 1e9), topic
    for log_time, block in channels["/plant/truth"]["messages"]:
        assert log_time == start + round(block["t"][0] * 1e9)
    assert rec.events[0]["t"] == 0.0 and rec.truth["t"][0] == pytest.approx(1e-3)   # simulation times (truth at 1 kHz)


def test_views_are_per_sample_at_most_100_hz_and_equal_the_recorded_values(demo, channels):
    rec = read_recording(demo)
    plant = [m for _, m in channels["/view/plant"]["messages"]]
    t = np.array([m["t"] for m in plant])
    periods = np.floor(t * 100 + 1e-9)                                 # t * 100 may round below a whole period
    assert np.all(np.diff(periods) == 1)                               # one per 10 ms period, none skipped
    np.testing.assert_allclose(t[1:] * 100, periods[1:], rtol=0, atol=1e-9)   # the truth sample at its start
    assert len(plant) == pytest.approx(rec.truth["t"][-1] * 100, abs=2)
    idx = np.searchsorted(rec.truth["t"], t)
    for name in ("s", "F_rod", "cam_angle", "omega"):
        np.testing.assert_array_equal([m[name] for m in plant], rec.truth[name][idx])
    device = [m for _, m in channels["/view/device"]["messages"]]
    curve_t = np.concatenate([c.t for c in rec.curves])
    idx = np.searchsorted(curve_t, [m["t"] for m in device])
    np.testing.assert_array_equal([m["y"] for m in device], np.concatenate([c.y for c in rec.curves])[idx])
    np.testing.assert_array_equal([m["x"] for m in device], np.concatenate([c.x for c in rec.curves])[idx])
    assert len(device) == pytest.approx(sum(c.t[-1] - c.t[0] for c in rec.curves) * 100, abs=2 * CYCLES)


def test_events_are_also_foxglove_logs(channels):
    events = [m for _, m in channels["/events"]["messages"]]
    logs = channels["/log"]["messages"]
    assert channels["/log"]["name"] == "foxglove.Log"
    assert [log["name"] for _, log in logs] == [e["kind"] for e in events]
    for (log_time, log), event in zip(logs, events):
        assert log["timestamp"]["sec"] * 10**9 + log["timestamp"]["nsec"] == log_time
        assert log["level"] == (3 if event["kind"] == "live_dropped" else 2)
        assert log["message"].startswith(f"t={event['t']:.6f} s {event['kind']}")


def test_every_recorded_topic_is_documented(channels):
    doc = (ROOT / "docs" / "recording.md").read_text()
    documented = set(re.findall(r"`(/[a-z0-9_/<>]+)`", doc))
    assert set(channels) <= documented, set(channels) - documented


LAYOUT = ROOT / "data" / "foxglove" / "cam_bar_layout.json"


def _schema_at(schema: dict, fields: list[str]) -> dict | None:
    """The sub-schema a message path's fields name (``x[:]``: the array's items), None where the schema has none."""
    for field in fields:
        name, index = field.removesuffix("[:]"), field.endswith("[:]")
        schema = schema.get("properties", {}).get(name)
        if schema is None:
            return None
        if index:
            if schema.get("type") != "array":
                return None
            schema = schema["items"]
    return schema


def test_the_shipped_layout_plots_paths_the_demo_recording_has(channels):
    """data/foxglove/cam_bar_layout.json (checked in Lichtblick, docs/recording.md): every plot path names a recorded
    topic and a numeric field of its schema (an X–Y plot's series and x-axis arrays of numbers of one message),
    the Log panel the foxglove.Log topic, Raw Messages a recorded topic; every panel is placed in the layout tree."""
    import json
    layout = json.loads(LAYOUT.read_text())
    placed, stack = set(), [layout["layout"]]
    while stack:
        node = stack.pop()
        if isinstance(node, str):
            placed.add(node)
        else:
            stack += [node["first"], node["second"]]
    assert placed == set(layout["configById"])
    for panel, config in layout["configById"].items():
        kind = panel.split("!")[0]
        if kind == "Plot":
            paths = [p["value"] for p in config["paths"]] + ([config["xAxisPath"]["value"]] if "xAxisPath" in config else [])
            for path in paths:
                topic, *fields = path.split(".")
                assert topic in channels, (panel, path)
                leaf = _schema_at(channels[topic]["schema"], fields)
                assert leaf is not None and leaf.get("type") == "number", (panel, path, leaf)
                assert ("[:]" in path) == (config["xAxisVal"] == "currentCustom"), (panel, path)
        elif kind == "RosOut":
            assert channels[config["topicToRender"]]["name"] == "foxglove.Log"
        elif kind == "RawMessages":
            assert config["topicPath"] in channels
        else:
            pytest.fail(f"{panel}: a panel type the layout was not checked with")


def test_can_raw_holds_the_hosts_commands_with_direction_and_channel(demo):
    frames = read_recording(demo).can_frames
    db = cantools.database.load_file(str(ROOT / "data" / "can" / "rig.dbc"))
    command = db.get_message_by_name("HostCommand")
    tx = [i for i, d in enumerate(frames["dir"]) if d == "tx"]
    assert set(frames["dir"]) == {"rx", "tx"} and set(frames["channel"]) == {"rig"}   # the scene's channel
    assert np.all(np.diff(frames["t"]) >= 0)
    assert [int(frames["id"][i]) for i in tx] == [command.frame_id] * len(tx)
    cmds = [db.decode_message(command.frame_id, frames["data"][i])["Cmd"] for i in tx]
    assert (str(cmds[0]), str(cmds[-1])) == ("SelectProgram", "Release") and tx[0] == 0 and tx[-1] == len(frames["t"]) - 1
    assert frames["t"][tx[-1]] == frames["t"][tx[-1] - 1]        # sent at the latest bus time the host knew
    for key in ("brs", "esi", "error"):
        assert frames[key].dtype == bool and not frames[key].any()


def test_only_declared_encoders_are_recorded(demo):
    rec = read_recording(demo)
    assert "/stand/encoder1" in rec.series and "/stand/encoder2" not in rec.series   # the demo declares one
    assert np.isfinite(rec.series["/stand/encoder1"]["angle"]).all()


def test_a_lab_recording_keeps_to_the_same_rules(tmp_path):
    """The reading topics a scene wires (/stand/<message>: encoder, LVDT, torque shaft of the cam lab) load in
    Foxglove as the demo's do: schema rules, valid messages, no nulls."""
    out = tmp_path / "lab.mcap"
    run_scene(ROOT / "data" / "scenes" / "lab_cam.toml", out)
    jsonschema = pytest.importorskip("jsonschema")
    seen = set()
    with open(out, "rb") as f:
        for schema, channel, msg in make_reader(f).iter_messages():
            parsed = orjson.loads(schema.data)
            if channel.topic not in seen:
                seen.add(channel.topic)
                assert schema.encoding == "jsonschema" and foxglove_rule_errors(parsed) == [], channel.topic
            data = orjson.loads(msg.data)
            assert _nulls(data) == [], channel.topic
            assert [e.message for e in jsonschema.Draft202012Validator(parsed).iter_errors(data)] == [], channel.topic
    assert {"/stand/encoder1", "/stand/lab_motion", "/stand/torque", "/plant/truth"} <= seen


def test_schemas_state_each_signals_unit(channels):
    """The fields said "(SI units)" whatever they held (a count and a code too): now the unit of each (the plants'
    truth, the unit's X/Y as wired in the scene: stroke in m, rod force in N; the encoder topic's DBC units)."""
    def described(topic: str) -> dict[str, str]:
        return {k: v.get("description", "") for k, v in channels[topic]["schema"]["properties"].items()}
    truth = described("/plant/truth")
    assert truth["phi"] == "phi, rad" and truth["F_rod"] == "F_rod, N" and truth["s"] == "s, m"
    assert described("/view/plant")["R23"] == "R23, N"
    assert described("/device/live")["x"] == "x, m" and described("/device/live")["y"] == "y, N"
    assert described("/device/curve")["x"] == "X channel, m" and described("/device/curve")["y"] == "Y channel, N"
    encoder = described("/stand/encoder1")
    assert encoder["speed"] == "speed, rad/s" and encoder["count"] == "count (a count or code, no unit)"
    assert not [(t, k) for t in channels for k, v in described(t).items() if "(SI units)" in v]
    curve = channels["/device/curve"]["schema"]["properties"]["theory"]["properties"]
    assert curve["x"]["description"] == "theory x, m" and curve["t"]["description"] == "theory t, s"
    values = channels["/device/result"]["schema"]["properties"]["process_values"]["properties"]
    assert (values["y_min"]["description"], values["x_max"]["description"], values["duration"]["description"]) == \
        ("y_min, N", "x_max, m", "duration, s")
    stats = channels["/device/statistics"]["schema"]["properties"]["values"]["properties"]["y_min"]["properties"]
    assert stats["mean"]["description"] == "mean, N" and stats["cpk"]["description"] == "Cpk (no unit)"

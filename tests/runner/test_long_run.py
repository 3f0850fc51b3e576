"""The data path over long runs and at its limits: 1000 cycles in virtual time, a bus that cannot carry the
curves, the time limit of ``--cycles``."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import orjson
import pytest
from mcap.reader import make_reader

from rig.recorder import read_recording
from rig.runner import run_scene
from rig.runner.session import RunError, _config

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "data" / "scenes" / "pin_insertion.toml"


def _stream(path: Path, topics: list[str]):
    """(topic, message) of a recording, streamed (a long run's file is not read into memory at once)."""
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=topics):
            yield channel.topic, orjson.loads(message.data)


def test_a_thousand_cycles_in_virtual_time_keep_every_value_and_time(tmp_path: Path):
    out = tmp_path / "long.mcap"
    summary = run_scene(SCENE, out, cycles=1000)
    assert summary.curves == 1000
    numbers, starts, results, events, stats = [], [], [], [], []
    for topic, msg in _stream(out, ["/device/curve", "/device/result", "/events", "/device/statistics"]):
        if topic == "/device/curve":
            numbers.append(msg["number"])
            starts.append(msg["t"][0])
        elif topic == "/device/result":
            results.append(msg)
        elif topic == "/events":
            events.append(msg)
        else:
            stats.append(msg)
    assert numbers == list(range(1, 1001))
    gaps = np.diff(starts)                       # one machine cycle (0.4 s at 150 rpm) between curve starts:
    assert np.all((gaps > 0.35) & (gaps < 0.45)), gaps[(gaps <= 0.35) | (gaps >= 0.45)]   # no 16.78 s jumps
    assert 0 < starts[0] and starts[-1] < summary.simulated_time
    assert len(results) == 1000 and all(r["complete"] and len(r["process_values"]) == 9 for r in results)
    kinds = {e["kind"] for e in events}
    assert not kinds & {"sequence_gap", "curve", "result", "incomplete_curve", "result_missing"}, kinds
    backlog = [e["backlog"] for e in events if e["kind"] == "live_dropped"]
    assert backlog and max(backlog) < 0.6        # bounded queue: at most about one curve (0.34 s of wire) waits
    assert stats[-1]["total"] == 1000


def test_a_bus_that_cannot_carry_the_curves_stops_the_run_with_a_clear_error(tmp_path: Path):
    slow = tmp_path / "slow.toml"
    slow.write_text(SCENE.read_text().replace("bitrate = 1000000", "bitrate = 500000", 1))
    out = tmp_path / "slow.mcap"
    with pytest.raises(RunError, match=r"\[links.can\].*cannot carry the curves.*CAN FD"):
        run_scene(slow, out, cycles=20)
    rec = read_recording(out)                    # what was recorded before stays readable, marked as stopped
    assert not rec.truncated and rec.interrupted.startswith("BusTooSlow: ") and 1 <= len(rec.curves) < 20
    cut = [e for e in rec.events if e["kind"] == "incomplete_curve"]   # the curve in transfer is said, as on Ctrl-C
    assert len(cut) == 1 and cut[0]["number"] == len(rec.curves) + 1 and "stop on an error" in str(cut[0]["problems"])


def test_a_run_out_of_time_sends_its_queue_and_its_last_status_says_so(tmp_path: Path):
    """The scene's cycles not in by its max_time: the unit ends its run as a complete one would (what it had queued
    is sent), its last frame says why (TxStatus.StopCause OutOfTime, read with cantools and the DBC alone), and the
    recording holds it as a run_stopped event beside every curve measured before the limit."""
    import cantools
    from firmware_sim.can_node import DBC_PATH
    short = tmp_path / "short.toml"
    short.write_text(SCENE.read_text().replace("cycles = 50 ", "cycles = 50\nmax_time = \"1.3 s\" ", 1))
    out = tmp_path / "short.mcap"
    with pytest.raises(RunError, match="only 3 of 50 curves by"):
        run_scene(short, out)
    rec = read_recording(out)
    assert len(rec.curves) == 3 and len(rec.results) == 3          # the queue was sent: the third curve too
    stopped = [e for e in rec.events if e["kind"] == "run_stopped"]
    assert len(stopped) == 1 and stopped[0]["detail"].startswith("OutOfTime: ")
    db = cantools.database.load_file(str(DBC_PATH))
    raw = rec.can_frames
    last = max(k for k, way in enumerate(raw["dir"]) if way == "rx")
    status = db.decode_message(int(raw["id"][last]), bytes(raw["data"][last]))
    assert status["RunEnded"] == 1 and str(status["StopCause"]) == "OutOfTime"


def test_cycles_from_the_command_line_raise_the_time_limit():
    assert _config(SCENE, None, None).max_time == pytest.approx(3 * 50 + 10)
    assert _config(SCENE, 500, None).max_time == pytest.approx(3 * 500 + 10)
    with pytest.raises(RunError, match="at least 1"):
        _config(SCENE, 0, None)


def test_periodic_frames_that_cannot_fit_the_bus_are_a_scene_error(tmp_path: Path):
    from rig.scene import SceneError
    fast = tmp_path / "fast_encoder.toml"
    fast.write_text(SCENE.read_text().replace('rate = "100 Hz"', 'rate = "10 kHz"', 1))
    with pytest.raises(SceneError, match=r"\[links.can\].*periodic frames alone need 13\d% .*Encoder1 13\d%"):
        run_scene(fast, tmp_path / "fast.mcap", cycles=1)


def test_each_live_drop_report_holds_the_figures_of_one_status(tmp_path: Path):
    """A ``live_dropped`` event's count and total come from the unit's StatusCounters frame and its live factor,
    stale count and backlog from the TxStatus frame of the same status (after the heartbeat whose device time the
    event carries) — checked against /can/raw decoded with cantools and the DBC."""
    import cantools
    out = tmp_path / "drops.mcap"
    run_scene(SCENE, out, cycles=6)
    rec = read_recording(out)
    db = cantools.database.load_file(ROOT / "data" / "can" / "rig.dbc")
    names = {m.frame_id: m.name for m in db.messages}
    statuses, device_time, counters = [], None, None
    for fid, data in zip(rec.can_frames["id"], rec.can_frames["data"]):
        name = names.get(int(fid))
        if name == "Heartbeat":
            device_time = db.decode_message(int(fid), data)["DeviceTime"]        # s (the DBC scales)
        elif name == "StatusCounters":
            counters = db.decode_message(int(fid), data)
        elif name == "TxStatus":
            tx = db.decode_message(int(fid), data)
            statuses.append((round(device_time, 3), counters["LiveDropped"], tx["LiveFactor"], tx["LiveStale"],
                             tx["Backlog"]))
    drops = [e for e in rec.events if e["kind"] == "live_dropped"]
    assert len(drops) >= 3
    previous = 0
    for e in drops:
        status = [s for s in statuses if s[0] == round(e["t"], 3)]
        assert len(status) == 1, e
        _, total, factor, stale, backlog = status[0]
        assert (e["total"], e["count"], e["live_factor"], e["stale"]) == (total, total - previous, factor, stale), e
        assert e["backlog"] == pytest.approx(backlog, abs=1e-9)
        previous = total


def test_heartbeats_report_the_state_at_their_own_device_time(tmp_path: Path):
    """A heartbeat due inside a chunk of samples says what the unit was doing at its DeviceTime (decoded with
    cantools and the DBC alone): measuring exactly inside a curve, LastOk the verdict of the latest curve ended by
    then ("none yet" before the first)."""
    import cantools
    out = tmp_path / "beats.mcap"
    run_scene(SCENE, out, cycles=6)
    rec = read_recording(out)
    db = cantools.database.load_file(ROOT / "data" / "can" / "rig.dbc")
    beat_id = db.get_message_by_name("Heartbeat").frame_id
    beats = [db.decode_message(beat_id, d) for i, d in zip(rec.can_frames["id"], rec.can_frames["data"])
             if int(i) == beat_id]
    spans = [(float(c.t[0]), float(c.t[-1])) for c in rec.curves]
    verdicts = [r["ok"] for r in rec.results]
    assert len(spans) == len(verdicts) == 6 and len(beats) > 20
    checked = 0
    for b in beats[:-1]:                                 # the last: the run's end status
        t = b["DeviceTime"]
        if any(abs(t - edge) < 1.5e-3 for span in spans for edge in span):
            continue                                     # DeviceTime is rounded to 1 ms
        measuring = any(a <= t < e for a, e in spans)
        ended = [ok for (a, e), ok in zip(spans, verdicts) if e <= t]
        assert (b["State"] == "Measuring") == measuring, (t, b)
        assert b["LastOk"] == ("None" if not ended else ("OK" if ended[-1] else "NOK")), (t, b)
        checked += 1
    assert checked > 20

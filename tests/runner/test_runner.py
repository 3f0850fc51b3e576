"""The rig runner end to end: scene → machine → links → host → MCAP, in one process and across processes."""
from __future__ import annotations

import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rig.recorder import read_recording
from rig.runner import run_scene
from rig.runner.config import read_config
from rig.scene import SceneError, load_scene

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "data" / "scenes" / "pin_insertion.toml"
CYCLES = 3


@pytest.fixture(scope="module")
def in_process(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("run") / "pin.mcap"
    summary = run_scene(SCENE, out, cycles=CYCLES)
    assert summary.curves == CYCLES
    return out


def _scene_variant(tmp_path: Path, name: str, **replace: str) -> Path:
    text = SCENE.read_text()
    for old, new in replace.items():
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


def test_in_process_recording_holds_curves_theory_results_statistics(in_process: Path):
    rec = read_recording(in_process)
    assert [c.number for c in rec.curves] == list(range(1, CYCLES + 1)) or len(rec.curves) == CYCLES
    for curve in rec.curves:
        assert curve.t.size > 1000 and curve.x.size == curve.t.size
        # measured stroke reaches the programmed 42 mm; theory is on the same timeline
        assert 0.040 < curve.x.max() < 0.044
        assert np.allclose(curve.theory["x"].max(), 0.042, atol=1e-4)
        assert curve.theory["y"].shape == curve.y.shape
        # the measured force follows the theoretical one to within a few newtons
        assert np.sqrt(np.mean((curve.y - curve.theory["y"]) ** 2)) < 5.0
    assert len(rec.results) == CYCLES and all("ok" in r for r in rec.results)
    assert rec.statistics, "device statistics read over serial are recorded"
    assert rec.statistics[-1]["total"] == CYCLES and rec.statistics[-1]["ok"] == CYCLES
    t = rec.truth["t"]                                     # [recording] truth_rate = "1 kHz": every 10th sample
    assert t.size >= CYCLES * 0.4 * 1_000 * 0.9 and np.allclose(np.diff(t), 1e-3) and np.allclose(t * 1e3, np.round(t * 1e3))
    assert "scene.toml" in str(rec.scene_text) or "[plant]" in rec.scene_text
    assert rec.can_frames is not None


def test_the_recording_says_its_truth_is_the_nominal_machine_where_the_scene_varies_the_plant(in_process, tmp_path):
    """[plant.variation] acts on the device's plant only; /plant/truth is the host's nominal theory. That was said in
    docs/cam-bar.md alone: the recording, its report and the console said nothing while a measured y_min lay beyond
    the truth's minimum. A scene without variation has no such note."""
    from rig.analysis.report import write_report
    caveat = read_recording(in_process).metadata["rig"]["truth_caveat"]
    assert "nominal machine" in caveat and "F_c, F_c_travel, the clearance taken up" in caveat
    html = write_report(in_process, tmp_path / "report").read_text(encoding="utf-8")
    assert html.count("Truth and theory: /plant/truth and the plant events are the nominal machine") == 1
    assert html.count("Truth and theory: as said above") == 1          # the second section refers back to it
    text = SCENE.read_text()
    start = text.index("[plant.variation]")
    plain = tmp_path / "plain.toml"
    plain.write_text(text[:start] + text[text.index("[[plant.cam_program]]"):])
    assert read_config(load_scene(plain)).truth_caveat == ""


def _busy_cores(n: int) -> list[subprocess.Popen]:
    """Processes that keep ``n`` cores busy (the machine under load)."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def test_cross_process_recording_equals_in_process_under_load(in_process: Path, tmp_path: Path, serve_scene):
    """``rig serve`` + ``rig record`` in two processes, with both cores busy, record every value the
    in-process run records: the run ends at the device's last frame and the served process stays until
    the host releases it, so nothing depends on timing."""
    from rig.runner import record_scene
    burners = _busy_cores(2)
    try:
        with serve_scene(SCENE, tmp_path / "endpoints.json", "--cycles", str(CYCLES)) as ep:
            out = tmp_path / "cross.mcap"
            summary = record_scene(SCENE, out, can_host=ep["can"]["host"], can_port=ep["can"]["port"],
                                   serial_port=ep["serial"], cycles=CYCLES, idle_timeout=60.0)
            assert summary.curves == CYCLES
    finally:
        for p in burners:
            p.kill()
            p.wait()
    a, b = read_recording(in_process), read_recording(out)
    assert len(a.curves) == len(b.curves) == CYCLES
    for ca, cb in zip(a.curves, b.curves):
        assert ca.number == cb.number
        for name in ("t", "x", "y", "angle"):
            np.testing.assert_array_equal(getattr(ca, name), getattr(cb, name))
        assert ca.theory.keys() == cb.theory.keys()
        for key in ca.theory:
            np.testing.assert_array_equal(ca.theory[key], cb.theory[key])
    assert a.results == b.results and a.statistics == b.statistics
    for key in ("t", "id", "data", "is_fd"):
        assert list(a.can_frames[key]) == list(b.can_frames[key]), key
    for topic in a.series:
        assert a.series[topic].keys() == b.series[topic].keys(), topic
        for name, values in a.series[topic].items():
            np.testing.assert_array_equal(values, b.series[topic][name], err_msg=f"{topic} {name}")
    assert a.events == b.events


def test_sensor_preload_and_spring_rate_change_the_measurement(in_process: Path, tmp_path: Path):
    base = read_recording(in_process)
    preload = _scene_variant(tmp_path, "preload.toml", **{'sensor_preload = "-25 N"': 'sensor_preload = "0 N"'})
    out = tmp_path / "preload.mcap"
    run_scene(preload, out, cycles=CYCLES)
    shifted = read_recording(out)
    d = np.mean([r["process_values"]["y_min"] for r in shifted.results]) - \
        np.mean([r["process_values"]["y_min"] for r in base.results])
    assert d == pytest.approx(25.0, abs=1.0)      # removing the -25 N preload raises the force by 25 N
    soft = _scene_variant(tmp_path, "soft.toml", **{'k = "1.89 N/mm"': 'k = "1.09 N/mm"'})
    out = tmp_path / "soft.mcap"
    run_scene(soft, out, cycles=CYCLES)
    r_soft = read_recording(out)
    # at level 1 the cam prescribes the motion, so the spring does not change the rod force ...
    y_soft = np.mean([r["process_values"]["y_min"] for r in r_soft.results])
    y_base = np.mean([r["process_values"]["y_min"] for r in base.results])
    assert y_soft == pytest.approx(y_base, abs=0.2)
    # ... but it changes the cam contact force R23 and the follower moment balance by k·l_F²·(ψ − ψ0)
    assert np.mean(r_soft.truth["R23"]) < np.mean(base.truth["R23"]) - 1.0
    assert not np.allclose(r_soft.truth["M_sigma"], base.truth["M_sigma"][:r_soft.truth["M_sigma"].size])


def test_interrupted_run_leaves_a_valid_recording(tmp_path: Path, monkeypatch):
    from rig.runner import host as host_module
    original = host_module.Host.poll

    def poll(self, timeout: float = 0.0) -> int:
        if self.curves_recorded >= 1:      # Ctrl-C in the middle of the run, after the first curve
            raise KeyboardInterrupt
        return original(self, timeout)

    monkeypatch.setattr(host_module.Host, "poll", poll)
    out = tmp_path / "interrupted.mcap"
    with pytest.raises(KeyboardInterrupt):
        run_scene(SCENE, out, cycles=CYCLES)
    rec = read_recording(out)                  # a whole file, marked interrupted
    assert not rec.truncated and rec.interrupted == "KeyboardInterrupt" and not rec.complete
    assert rec.truth["t"].size > 0 and len(rec.curves) == 1 and len(rec.results) == 1


@pytest.mark.parametrize("where", ["write_curve", "write_block"])
def test_a_real_ctrl_c_inside_the_recording_of_a_curve_or_a_block_is_taken_between_steps(tmp_path, monkeypatch, where):
    """SIGINT delivered inside the host's work (after the recorder wrote the second curve, before the host marked it
    recorded; or in the middle of a block of frames): Python once raised there, and the curve was written again on
    the way out (two copies, a false curves_in_one_cycle event [n, n]) or the frames already taken off the bus were
    lost. The run now stops at its next step boundary: every curve once, consecutive, as many as the stop says."""
    import os
    import signal
    from rig.recorder.writer import Recorder
    from rig.runner.session import Interrupted
    original = getattr(Recorder, where)
    calls = []

    def write(self, *args, **kwargs):
        out = original(self, *args, **kwargs)
        calls.append(1)
        if len(calls) == 2 if where == "write_curve" else len(calls) == 40:
            os.kill(os.getpid(), signal.SIGINT)
        return out

    monkeypatch.setattr(Recorder, where, write)
    out = tmp_path / "stopped.mcap"
    with pytest.raises(Interrupted) as stop:
        run_scene(SCENE, out, cycles=20)
    rec = read_recording(out)
    numbers = [c.number for c in rec.curves]
    assert numbers == list(range(1, len(numbers) + 1)) and len(numbers) == stop.value.curves >= 2
    assert not [e for e in rec.events if e["kind"] == "curves_in_one_cycle"]
    assert rec.interrupted == "KeyboardInterrupt" and not rec.truncated
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler     # Python's own handler is back


def test_ctrl_c_inside_a_deferred_block_waits_for_its_check_and_so_does_a_double_tap(monkeypatch):
    """A second Ctrl-C a few ms after the first waits for the check too (raised at once, it landed in the MCAP writer
    as Python's own did); only one after the first has waited STUCK s for a check raises at once."""
    import os
    import signal
    import rig.interrupt as interrupt
    with pytest.raises(KeyboardInterrupt):
        with interrupt.deferred_interrupt() as check:
            os.kill(os.getpid(), signal.SIGINT)
            os.kill(os.getpid(), signal.SIGINT)    # a double tap
            reached = True                       # not raised at once
            check()
    assert reached
    monkeypatch.setattr(interrupt, "STUCK", -1.0)         # every pending stop counts as stuck
    with pytest.raises(KeyboardInterrupt):
        with interrupt.deferred_interrupt():
            os.kill(os.getpid(), signal.SIGINT)
            os.kill(os.getpid(), signal.SIGINT)    # the loop is stuck: the user's second Ctrl-C raises from the handler
            raise AssertionError("not reached")
    with pytest.raises(KeyboardInterrupt):       # a Ctrl-C after the last check is raised at the block's end
        with interrupt.deferred_interrupt():
            os.kill(os.getpid(), signal.SIGINT)


@pytest.mark.parametrize("old, new, message", [
    ('to = "device.y"', 'to = "device.z"', r"\[transducers.rod_force\].*'device.x' and 'device.y'"),
    ('to = "device.y"', 'to = "can.Torque.Torq"', r"\[transducers.rod_force\].*Torque has no signal 'Torq'.*Torque, BrakeForce"),
    ('to = "device.y"', 'to = "can.Nope.X"', r"\[transducers.rod_force\].*no reading message 'Nope'.*Encoder1"),
    ('to = "device.y"', 'to = "can.Torque"', r"\[transducers.rod_force\].*Torque carries no counter"),
    ('to = "can.Encoder1"', 'to = "can.Encoder1.Count"', r"\[transducers.cam_encoder\].*a counter fills.*'can.Encoder1'"),
    ('to = "device.x"', 'to = "device.y"', r"'device.y' is given to more than one transducer"),
    ('signal = "F_rod"', 'signal = "F_nope"', r"no signal 'F_nope'"),
    ('mode = "virtual"', 'mode = "turbo"', r"\[scene\].*'mode'"),
    ('description = "burster_8411"', 'description = "no_such_sensor"', r"no_such_sensor"),
    ('"drive_torque"]', '"drive_torquee"]', r"\[recording\]: 'truth_signals' names 'drive_torquee', which the "
                                             r"plant does not have \(did you mean 'drive_torque'\?\)"),
    ('bitrate = 1000000', 'bitrate = 1000000\ndata_bitrate = 4000000', r"\[links.can\]: key 'data_bitrate' is the "
                                                                      r"data phase of CAN FD: set fd = true"),
    ('delta = "0.1 ms"', 'delta = "0.05 ms"', r"\[device.config.sampling\]: 'delta' = 0.05 ms is finer than the "
                                              r"machine's samples \(0.1 ms at \[scene\] sample_rate = 10000 Hz\)"),
    ('sample_rate = "10 kHz"', 'sample_rate = "9999 Hz"', r"\[scene\]: 'sample_rate' = 9999 Hz: live pairs go out "
                                                          r"stamped on the 100 µs Tick grid"),
])
def test_bad_scene_is_a_clear_error(tmp_path: Path, old: str, new: str, message: str):
    path = _scene_variant(tmp_path, "bad.toml", **{old: new})
    with pytest.raises((SceneError, ValueError, FileNotFoundError), match=message):
        run_scene(path, tmp_path / "bad.mcap", cycles=1)


def test_config_reads_the_demo_scene():
    cfg = read_config(load_scene(SCENE))
    assert cfg.cycles == 50 and cfg.sample_rate == 10_000 and cfg.wired("device.x").signal == "s"
    assert cfg.truth_every == 10


@pytest.mark.parametrize("rate, every", [(None, 1), ("10 kHz", 1), ("2 kHz", 5), ("0.1 kHz", 100)])
def test_truth_rate_is_a_whole_decimation_of_the_sample_rate(tmp_path: Path, rate, every):
    old = 'truth_rate = "1 kHz"'
    path = _scene_variant(tmp_path, "t.toml", **{old: "" if rate is None else f'truth_rate = "{rate}"'})
    assert read_config(load_scene(path)).truth_every == every
    for bad in ("3 kHz", "20 kHz", "0 Hz"):
        path = _scene_variant(tmp_path, "t.toml", **{old: f'truth_rate = "{bad}"'})
        with pytest.raises(SceneError, match=r"\[recording\]: 'truth_rate' must divide the sample rate \(10000 Hz\)"):
            read_config(load_scene(path))


def test_view_rate_is_set_in_the_scene_and_checked(tmp_path: Path):
    """``[recording] view_rate``: a view at 1 kHz keeps every truth sample (truth at 1 kHz) and ten times the 100 Hz
    view's curve samples, so a curve's force peak between two 10 ms picks is in it; a rate that is no positive
    frequency is named."""
    old = 'truth_rate = "1 kHz"'
    path = _scene_variant(tmp_path, "v.toml", **{old: old + '\nview_rate = "1 kHz"'})
    assert read_config(load_scene(path)).recording["view_rate"] == 1000.0
    assert read_config(load_scene(SCENE)).recording["view_rate"] == 100.0
    rec = read_recording(run_scene(path, tmp_path / "v.mcap", cycles=1).output)
    assert rec.metadata["rig"]["view_rate"] == "1000.0"
    assert rec.message_counts["/view/plant"] == rec.truth["t"].size
    (curve,) = rec.curves                                   # one view message per 1 ms the curve touches
    assert rec.message_counts["/view/device"] == np.unique(np.floor(curve.t * 1000 + 1e-9)).size > curve.t.size / 11
    for bad, says in (("0 Hz", "must be above 0 Hz"), ("-5 Hz", "must be above 0 Hz"), ("200 kHz", "at most 100000 Hz"),
                      ("1 m", "wrong dimension; expected something convertible to Hz"), ("fast", "not a quantity")):
        path = _scene_variant(tmp_path, "v.toml", **{old: old + f'\nview_rate = "{bad}"'})
        with pytest.raises(SceneError, match=rf"\[recording\]: key 'view_rate'.*{says}"):
            read_config(load_scene(path))


def test_recorded_values_equal_the_raw_frames_decoded_with_cantools_and_the_dbc_alone(in_process: Path):
    """An independent reading of ``/can/raw``: cantools and the DBC give the same process values, curve
    numbers, start times and X/Y pairs as the recorded results and curves."""
    import cantools
    db = cantools.database.load_file(str(ROOT / "data" / "can" / "rig.dbc"))
    rec = read_recording(in_process)
    frames = rec.can_frames
    values: dict[int, dict[str, float]] = {}
    starts, xs, ends = {}, {}, {}
    high = None
    for fid, data in zip(frames["id"], frames["data"]):
        if fid not in (0x300, 0x301, 0x302, 0x311):
            continue
        msg = db.decode_message(int(fid), data, decode_choices=False)
        if fid == 0x300:
            number, high = msg["CurveNo"], msg["TStartHigh"]
            xs[number] = []
        elif fid == 0x301:
            starts[number] = high + msg["TStart"]
        elif fid == 0x302:
            xs[number].append(msg["X"])
        elif msg["Pv"] == 255:
            ends[msg["CurveNo"]] = (msg["PvMask"], msg["PvCount"])
        else:
            name = next(k for k in msg if k not in ("Seq", "CurveNo", "Pv"))
            values.setdefault(msg["CurveNo"], {})[name] = msg[name]
    names = {"XMax": "x_max", "XMin": "x_min", "YMax": "y_max", "YMin": "y_min", "XAtYMax": "x_at_y_max",
             "YAtXMax": "y_at_x_max", "XEnd": "x_end", "YEnd": "y_end", "Duration": "duration"}
    assert len(rec.results) == CYCLES
    for result, curve in zip(rec.results, rec.curves):
        n = result["number"]
        assert ends[n] == (0x1FF, 9) and result["complete"]            # all 9 announced, all 9 recorded
        assert result["process_values"] == {names[k]: v for k, v in values[n].items()}
        assert curve.t[0] == pytest.approx(starts[n], abs=1e-6)
        np.testing.assert_allclose(curve.x, xs[n], rtol=0, atol=1e-12)


def test_a_served_run_shorter_than_the_scene_is_recorded_and_released(tmp_path: Path, serve_scene, caplog):
    """`rig serve --cycles 3` and a host recording the scene (50 cycles) as the README writes it: the machine's
    last frame (RunEnded) ends the recording with its 3 curves and a warning, and the host releases the served
    process (it exits by itself: the fixture asserts status 0)."""
    from rig.runner import record_scene
    with serve_scene(SCENE, tmp_path / "endpoints.json", "--cycles", "3") as ep:
        out = tmp_path / "short.mcap"
        with caplog.at_level("WARNING"):
            summary = record_scene(SCENE, out, can_host=ep["can"]["host"], can_port=ep["can"]["port"],
                                   serial_port=ep["serial"], idle_timeout=60.0)
    assert summary.curves == 3
    assert "the served machine ended its run after 3 curves" in caplog.text
    rec = read_recording(out)
    assert len(rec.curves) == 3 and [e["kind"] for e in rec.events].count("run_short") == 1


def test_a_served_run_longer_than_asked_is_recorded_to_the_asked_count(tmp_path: Path, serve_scene):
    """`rig serve --cycles 8` and `rig record --cycles 3`: the host waits for the machine's run end a little longer
    (so every run ends at the same frame) but records exactly the 3 curves and results it was asked for (it wrote
    16 of 10), says how many more it saw in a `not_recorded` event, and leaves no curve it cut unsaid."""
    from rig.runner import record_scene
    with serve_scene(SCENE, tmp_path / "endpoints.json", "--cycles", "8") as ep:
        out = tmp_path / "three.mcap"
        summary = record_scene(SCENE, out, can_host=ep["can"]["host"], can_port=ep["can"]["port"],
                               serial_port=ep["serial"], idle_timeout=60.0, cycles=3)
    rec = read_recording(out)
    assert summary.curves == 3 and [c.number for c in rec.curves] == [1, 2, 3]
    assert summary.simulated_time == pytest.approx(rec.last_time, abs=0.15)     # the span the recording holds
    assert [r["number"] for r in rec.results] == [1, 2, 3]
    beyond = [e for e in rec.events if e["kind"] == "not_recorded"]
    assert len(beyond) == 1 and beyond[0]["curves"] >= 1 and "after the 3 this host was asked" in beyond[0]["detail"]
    kinds = {e["kind"] for e in rec.events}
    assert not kinds & {"incomplete_curve", "result_missing"}


def test_record_from_the_endpoints_file_refuses_another_scene(tmp_path: Path, serve_scene, capsys):
    """`rig record --endpoints FILE` connects where `rig serve` said and checks it serves this scene at this
    fidelity: another scene or level is a usage error before anything is recorded; the served one records."""
    from rig.cli import main
    endpoints = tmp_path / "endpoints.json"
    other = _scene_variant(tmp_path, "other.toml", **{'sensor_preload = "-25 N"': 'sensor_preload = "0 N"'})
    with serve_scene(SCENE, endpoints, "--cycles", "2"):
        out = tmp_path / "r.mcap"
        assert main(["-q", "record", str(other), "--endpoints", str(endpoints), "-o", str(out)]) == 2
        assert "the served machine runs" in capsys.readouterr().err and not out.exists()
        assert main(["-q", "record", str(SCENE), "--endpoints", str(endpoints), "-o", str(out), "--fidelity", "2"]) == 2
        assert "at fidelity L1, this host would record L2" in capsys.readouterr().err
        assert main(["-q", "record", str(SCENE), "--endpoints", str(endpoints), "-o", str(out), "--cycles", "2"]) == 0
    assert len(read_recording(out).curves) == 2


def test_connection_options_beside_the_endpoints_file_override_its_entries():
    """`rig record --endpoints FILE --can-host H ...`: each option given wins over the file's entry, the rest
    come from the file (the CAN host was once always taken from the file)."""
    import argparse
    from rig.cli import _connect_as_served
    served = {"can": {"host": "127.0.0.1", "port": 29536, "channel": "can0"}, "serial": "/dev/pts/7"}
    args = argparse.Namespace(can_host="10.0.0.2", can_port=None, can_channel=None, serial="/dev/pts/9")
    _connect_as_served(args, served)
    assert (args.can_host, args.can_port, args.can_channel, args.serial) == ("10.0.0.2", 29536, "can0", "/dev/pts/9")
    args = argparse.Namespace(can_host=None, can_port=4000, can_channel="vcan1", serial=None)
    _connect_as_served(args, served)
    assert (args.can_host, args.can_port, args.can_channel, args.serial) == ("127.0.0.1", 4000, "vcan1", "/dev/pts/7")


def test_a_truth_signal_of_another_model_level_is_a_warning_not_an_error(tmp_path: Path, caplog):
    """The as_drawn scene records level-2 signals; forced to level 1 they do not exist: said once, not silent."""
    import logging
    with caplog.at_level(logging.WARNING):
        run_scene(ROOT / "data" / "scenes" / "pin_insertion_as_drawn.toml", tmp_path / "l1.mcap", cycles=1,
                  fidelity=1)
    said = [r.getMessage() for r in caplog.records if "truth_signals" in r.getMessage()]
    assert len(said) == 1 and "'psi_kin', 'delta_w', 'delta_o'" in said[0] and "(L1): not recorded" in said[0]
    assert "delta_w" not in read_recording(tmp_path / "l1.mcap").truth


def test_an_endpoints_file_with_a_bad_port_is_an_input_error(tmp_path: Path, capsys):
    from rig.cli import main
    bad = tmp_path / "ep.json"
    bad.write_text('{"can": {"host": "127.0.0.1", "port": "abc"}, "serial": "/dev/null", "scene": "x", '
                   '"scene_sha256": "0", "fidelity": 1}')
    assert main(["record", str(SCENE), "--endpoints", str(bad), "-o", str(tmp_path / "x.mcap")]) == 2
    assert '"can" must be {"host": a host name, "port": a TCP port number}' in capsys.readouterr().err


def test_the_simulated_time_beyond_the_scene_is_the_flush_and_the_console_says_so(tmp_path, capsys):
    """A 0.8 s stand scene printed "0.81 s simulated" unexplained: the extra is the bus sending what was queued at
    the scene's end, counted as flush_time and named on the console."""
    from rig.cli import main
    scene = Path(__file__).resolve().parents[2] / "data" / "scenes" / "clutch_leaf_startup.toml"
    summary = run_scene(scene, tmp_path / "a.mcap")
    assert 0.0 < summary.flush_time < 0.1
    assert summary.simulated_time == pytest.approx(0.8 + summary.flush_time, abs=1e-9)
    assert main(["-q", "run", str(scene), "-o", str(tmp_path / "b.mcap"), "--no-report"]) == 0
    assert f"(its last {summary.flush_time * 1e3:.0f} ms: the bus sending" in capsys.readouterr().out


def test_events_are_recorded_in_time_order_the_same_in_one_process_and_across(tmp_path: Path, serve_scene):
    """The theory's events (a level-2 plant: flank bounces) and the link's (live drops) are found at different
    polls: they are written in time order, each logged at its own time, and the recording across processes has the
    same /events (the worn-pins scene wrote bounces at 0.56–0.96 s after a live drop at 1.0 s in one process only)."""
    import json

    from mcap.reader import make_reader

    from rig.runner import record_scene
    scene, cycles = ROOT / "data" / "scenes" / "pin_insertion_worn_pins.toml", 3
    runs = [tmp_path / "in.mcap", tmp_path / "cross.mcap"]
    run_scene(scene, runs[0], cycles=cycles)
    with serve_scene(scene, tmp_path / "endpoints.json", "--cycles", str(cycles)) as ep:
        record_scene(scene, runs[1], can_host=ep["can"]["host"], can_port=ep["can"]["port"], serial_port=ep["serial"],
                     cycles=cycles, idle_timeout=60.0)
    events = []
    for path in runs:
        with open(path, "rb") as f:
            rows = [(m.log_time, json.loads(m.data)) for _, _, m in make_reader(f).iter_messages(topics=["/events"])]
        start = rows[0][0] - round(rows[0][1]["t"] * 1e9)
        assert all(abs(log - start - e["t"] * 1e9) < 2 for log, e in rows)          # each at its own time
        assert [e["t"] for _, e in rows] == sorted(e["t"] for _, e in rows)
        events.append([e for _, e in rows])
    kinds = {e["kind"] for e in events[0]}
    assert {"flank_bounce", "live_dropped"} <= kinds
    assert events[0] == events[1]


def test_a_served_run_out_of_time_ends_with_run_ended_not_a_dropped_link(tmp_path: Path, serve_scene):
    """A served scene whose cycles are not in by its max_time (a host driving a program started by command, or here
    a max_time shorter than the cycles) ended the process and closed the links without RunEnded; it ends the run as
    usual: RunEnded, the host records what came (run_short), Release ends `rig serve`."""
    from rig.runner import record_scene
    scene = _scene_variant(tmp_path, "short.toml", **{"cycles = 50": 'cycles = 5\nmax_time = "1 s"'})
    with serve_scene(scene, tmp_path / "endpoints.json") as ep:
        out = tmp_path / "short.mcap"
        summary = record_scene(scene, out, can_host=ep["can"]["host"], can_port=ep["can"]["port"],
                               serial_port=ep["serial"], idle_timeout=60.0)
    rec = read_recording(out)
    assert 1 <= summary.curves < 5 and len(rec.curves) == summary.curves
    assert [e["kind"] for e in rec.events].count("run_short") == 1


def test_inputs_beyond_their_range_are_an_event(tmp_path: Path):
    """A broken bridge rails the force input: the unit clips those samples to its range and counts them; the run
    says so (an input_overrange event with the count per channel), and a sound run does not."""
    scene = _scene_variant(tmp_path, "open.toml", **{'to = "device.y"': 'to = "device.y"\n'
                                                                       'faults = [{ fault = "open_bridge", at = "0.5 s" }]'})
    run_scene(scene, tmp_path / "open.mcap", cycles=2)
    (over,) = [e for e in read_recording(tmp_path / "open.mcap").events if e["kind"] == "input_overrange"]
    assert set(over["samples"]) == {"y"} and over["samples"]["y"] > 100


def test_two_curves_in_one_machine_cycle_are_an_event(tmp_path: Path):
    """A 10 ms supply loss of the LVDT in mid-stroke ends the curve and starts another in the same machine cycle: the
    run counted it as a cycle without a word; a curves_in_one_cycle event names the two."""
    import json

    from mcap.reader import make_reader
    scene = _scene_variant(tmp_path, "dropout.toml", **{
        'signal = "s"': 'signal = "s"\nfaults = [{ fault = "supply_loss", at = "0.15 s", until = "0.16 s" }, '
                        '{ fault = "supply_loss", at = "0.95 s", until = "0.96 s" }]'})
    run_scene(scene, tmp_path / "dropout.mcap", cycles=5)
    events = read_recording(tmp_path / "dropout.mcap").events
    first, second = [e for e in events if e["kind"] == "curves_in_one_cycle"]
    assert first["numbers"] == [1, 2] and 0.0 < first["cam_angle"] < math.pi and second["numbers"] == [4, 5]
    # found when its curve is recorded, after a later live drop was: still written in time order, at its own time
    with open(tmp_path / "dropout.mcap", "rb") as f:
        rows = [(m.log_time, json.loads(m.data)) for _, _, m in make_reader(f).iter_messages(topics=["/events"])]
    start = rows[0][0] - round(rows[0][1]["t"] * 1e9)
    assert [e["t"] for _, e in rows] == sorted(e["t"] for _, e in rows)
    assert all(abs(log - start - e["t"] * 1e9) < 2 for log, e in rows)


def test_an_encoders_illegal_transitions_reach_the_recording(tmp_path: Path):
    """Glitches on the cam encoder: the counter card counts illegal transitions; they come over CAN with the count,
    are recorded in /stand/encoder1, the first is an encoder_illegal event and the total is in link_summary (the
    frames had no room for them: nothing said the count had gone off)."""
    scene = _scene_variant(tmp_path, "glitch.toml", **{'rate = "100 Hz"': 'rate = "100 Hz"\nfaults = [{ fault = '
                                                       '"glitches", at = "0.5 s", until = "0.8 s", rate = "2 kHz", '
                                                       'width = "2 us" }]'})
    run_scene(scene, tmp_path / "glitch.mcap", cycles=3)
    rec = read_recording(tmp_path / "glitch.mcap")
    illegal = rec.series["/stand/encoder1"]["illegal"]
    t = rec.series["/stand/encoder1"]["t"]
    (first,) = [e for e in rec.events if e["kind"] == "encoder_illegal"]
    (summary,) = [e for e in rec.events if e["kind"] == "link_summary"]
    assert np.all(illegal[t < 0.5] == 0) and illegal[-1] > 0 and np.all(np.diff(illegal) >= 0)
    assert 0.5 <= first["t"] <= 0.82 and first["message"] == "Encoder1"
    assert summary["illegal_transitions"] == {"Encoder1": int(illegal[-1])} and "illegal_saturated" not in summary
    storm = _scene_variant(tmp_path, "storm.toml", **{'rate = "100 Hz"': 'rate = "10 Hz"\nfaults = [{ fault = '
                                                      '"glitches", at = "0.5 s", until = "1.5 s", rate = "200 kHz", '
                                                      'width = "0.1 us" }]'})
    run_scene(storm, tmp_path / "storm.mcap", cycles=3)          # thousands between readings: the field saturates
    (summary,) = [e for e in read_recording(tmp_path / "storm.mcap").events if e["kind"] == "link_summary"]
    assert summary["illegal_transitions"] == {"Encoder1": 255} and summary["illegal_saturated"] == ["Encoder1"]


def test_a_run_stopped_for_a_lost_curve_keeps_the_events_that_say_why(tmp_path: Path, monkeypatch):
    """A curve frame lost on the wire: the run stops with "the host received only 2 complete curves of 3 (see
    /events)"; the events it points to (the sequence gap, the incomplete curve) are in the file, in time order —
    not held back by the host's ordering of events when the run stopped."""
    import rig.runner.host as host_module
    from rig.blockbus import FrameBlock
    from rig.runner.session import RunError
    drain, seen = host_module.drain_block, {"headers": 0, "dropped": False}

    def lossy(bus, timeout=0.0):
        block = drain(bus, timeout)
        keep = np.ones(len(block), bool)
        for i, frame_id in enumerate(block.arbitration_id):
            seen["headers"] += frame_id == 0x300
            if seen["headers"] == 3 and frame_id == 0x302 and not seen["dropped"]:
                keep[i], seen["dropped"] = False, True
        return FrameBlock(block.timestamp[keep], block.arbitration_id[keep], block.dlc[keep], block.data[keep],
                          block.flags[keep])

    monkeypatch.setattr(host_module, "drain_block", lossy)
    with pytest.raises(RunError, match="received only 2 complete curves of 3"):
        run_scene(SCENE, tmp_path / "lossy.mcap", cycles=3)
    events = read_recording(tmp_path / "lossy.mcap").events
    kinds = [e["kind"] for e in events]
    assert {"sequence_gap", "incomplete_curve"} <= set(kinds) and kinds[-1] == "interrupted"
    assert [e["t"] for e in events] == sorted(e["t"] for e in events)


def test_a_second_ctrl_c_while_the_stopped_run_closes_its_recording_does_not_cut_it(tmp_path, monkeypatch):
    """Two SIGINTs a few ms apart: the second landed in the MCAP writer's finish and left the file without its
    summary ("rig: interrupted", nothing named). The closing after a stop now ignores it: the file is whole."""
    import os
    import signal
    from rig.recorder.writer import Recorder
    from rig.runner.session import Interrupted
    write_curve, close = Recorder.write_curve, Recorder.close

    def curve(self, *args, **kwargs):
        out = write_curve(self, *args, **kwargs)
        if self.curves == 2:
            os.kill(os.getpid(), signal.SIGINT)          # the first: the run stops at its next step
        return out

    def closing(self, *args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)              # the second, as the recording closes
        return close(self, *args, **kwargs)

    monkeypatch.setattr(Recorder, "write_curve", curve)
    monkeypatch.setattr(Recorder, "close", closing)
    out = tmp_path / "twice.mcap"
    with pytest.raises(Interrupted) as stop:
        run_scene(SCENE, out, cycles=20)
    rec = read_recording(out)                            # whole: no allow_partial
    assert rec.interrupted == "KeyboardInterrupt" and len(rec.curves) == stop.value.curves >= 2


def test_a_served_machine_that_stops_mid_run_is_named_at_once_not_after_the_idle_timeout(tmp_path):
    """`rig serve` stopped (here killed) while `rig record` still wants curves: python-can's socketcand bus then only
    returns nothing, as a quiet bus does, and the host waited its 10 s idle timeout for "no CAN traffic". It now sees
    the connection closed within a second and says so; what it recorded is kept."""
    import json
    import threading
    from rig.runner import record_scene
    from rig.runner.session import RunError
    endpoints = tmp_path / "endpoints.json"
    serve = subprocess.Popen([sys.executable, "-m", "rig.cli", "-q", "serve", str(SCENE), "--cycles", "400",
                              "--endpoints", str(endpoints), "--wait", "120"], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not endpoints.exists() or not endpoints.read_text():
            assert serve.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        ep = json.loads(endpoints.read_text())
        out = tmp_path / "rec.mcap"
        threading.Timer(3.0, serve.kill).start()
        t0 = time.monotonic()
        with pytest.raises(RunError, match=r"closed the connection \(its rig serve stopped: see its console\) "
                                           r"after \d+ curves"):
            record_scene(SCENE, out, can_host=ep["can"]["host"], can_port=ep["can"]["port"], serial_port=ep["serial"],
                         cycles=400, idle_timeout=60.0)
        assert time.monotonic() - t0 < 30.0                  # not the 60 s idle timeout
        assert read_recording(out, allow_partial=True).curves
    finally:
        serve.kill()
        serve.wait()


def test_a_served_serial_link_that_fails_is_said_in_plain_words():
    """The served machine stopped while the host set the unit up: pyserial's "device reports readiness to read but
    returned no data" reached the console as it was (an audit); it is a run error naming the link and the cause."""
    import serial
    from rig.runner.session import RunError, _serial_link
    with pytest.raises(RunError, match=r"the served machine's serial link /dev/pts/7 failed while setting the unit "
                                       r"up \(device reports .*\): its rig serve stopped"):
        with _serial_link("/dev/pts/7", "setting the unit up"):
            raise serial.SerialException("device reports readiness to read but returned no data")


def test_a_run_stopped_by_any_error_keeps_the_plant_truth_up_to_the_stop(tmp_path, monkeypatch):
    """The host holds its latest 0.5 s theory block back until the machine is past it (a run of cycles must not
    record plant truth from after its end); a run stopped by an error other than a RunError — a model that cannot
    go on — lost that block (truth to 0.5 s of a run stopped at 0.7 s; the review of the change)."""
    from rig.runner import machine as machine_module
    from rig.runner.session import RunError
    from rig.solvers import SolverDivergence
    original = machine_module.Machine.step

    def step(self, **kwargs):
        if self.t >= 0.7:
            raise SolverDivergence("a test's stop", self.t, (0.0,))
        return original(self, **kwargs)

    monkeypatch.setattr(machine_module.Machine, "step", step)
    out = tmp_path / "stopped.mcap"
    with pytest.raises(SolverDivergence):
        run_scene(ROOT / "data" / "scenes" / "clutch_startup.toml", out)
    rec = read_recording(out)
    assert rec.interrupted and rec.truth["t"][-1] == pytest.approx(0.7, abs=0.01)
    # a run of cycles stopped by the bus (a RunError at 1.57 s, the machine at 1.5 s): the truth to 1.5 s, not to the
    # last 0.5 s block a curve needed (1.0 s; an audit)
    drawn = (ROOT / "data" / "scenes" / "pin_insertion_as_drawn.toml").read_text()
    slow = tmp_path / "slow.toml"
    slow.write_text(drawn.replace("bitrate = 1000000", "bitrate = 500000"))
    monkeypatch.undo()
    with pytest.raises(RunError, match="cannot carry the curves"):
        run_scene(slow, tmp_path / "slow.mcap", cycles=40)
    rec = read_recording(tmp_path / "slow.mcap")
    assert rec.truth["t"][-1] == pytest.approx(rec.can_frames["t"][-1], abs=0.011)


def test_an_enabled_y2_with_nothing_wired_reads_an_open_input(tmp_path):
    """Scenes wire X and Y only: a program with Y2 enabled (in the scene, or by a host over serial) stopped the run with
    "feed: channel y2 is enabled … but no y2 samples given" (a clean-room client crashed a served machine so). Y2 now
    reads an open input, 0 V, and the curves are measured."""
    text = (ROOT / "data" / "scenes" / "pin_insertion.toml").read_text()
    y2 = ('[device.config.channels.y2]\nenabled = true\ninput = "process"\nrange = "5 V"\nunit = "V"\n'
          'scaling = { mode = "sensitivity", electrical = "1 V", engineering = "1 V" }\n\n')
    scene = tmp_path / "y2.toml"
    scene.write_text(text.replace("[device.config.control.start]", y2 + "[device.config.control.start]", 1))
    out = tmp_path / "y2.mcap"
    run_scene(scene, out, cycles=2)
    rec = read_recording(out)
    assert len(rec.curves) == 2 and len(rec.results) == 2

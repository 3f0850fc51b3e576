"""Validation gaps (issue 12): unknown sections, counts, plant kinds and output paths are errors naming
what is wrong in one line; exit status 2 for usage and scene errors, 1 for a run that fails."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from rig import cli
from rig.runner.config import read_config
from rig.scene import SceneError, load_scene

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "data" / "scenes"
DEMO = SCENES / "pin_insertion.toml"
CLUTCH = SCENES / "clutch_startup.toml"
STATIC = SCENES / "clutch_static_leaf.toml"


def edited(tmp_path: Path, source: Path, old: str, new: str, name: str = "scene.toml") -> Path:
    text = source.read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


# -- scene sections ---------------------------------------------------------------------------------
@pytest.mark.parametrize("source, old, new, message", [
    (DEMO, "[plant]\n", "[plnt]\n", r"unknown section \[plnt\] \(did you mean \[plant\]\?\)"),
    (DEMO, "[recording]\n", "[recordng]\n", r"unknown section \[recordng\] \(did you mean \[recording\]\?\)"),
    (DEMO, "[speed]\n", "[speed]\n[motor]\na0 = \"1 N*m\"\n", r"section \[motor\] is not used by plant 'cam_bar'"),
    (CLUTCH, "[motor]\n", "[program]\nx = 1\n[motor]\n", r"section \[program\] is not used by plant 'clutch_dynamic'"),
    (STATIC, "[links.can]\n", "[links.cann]\n", r"unknown section \[links.cann\] \(did you mean \[links.can\]\?\)"),
    (DEMO, "[scene]\n", "stray = 1\n[scene]\n", r"unknown top-level key 'stray'"),
    (DEMO, "[plant]\n", "[extra_thing]\na = 1\n[gadget]\nb = 2\n[plant]\n",        # each one named, not the first
     r"unknown section \[extra_thing\]; unknown section \[gadget\]; the sections of a 'cam_bar' scene are"),
])
def test_unknown_sections_name_the_section_and_the_file(tmp_path, source, old, new, message):
    path = edited(tmp_path, source, old, new)
    with pytest.raises(SceneError, match=message) as info:
        read_config(load_scene(path))
    assert str(info.value).startswith(f"{path}: ")


@pytest.mark.parametrize("old, new, message", [
    ('sample_rate = "10 kHz"', 'sample_rate = "inf Hz"', r"\[scene\]: key 'sample_rate' must be a finite quantity"),
    ("cycles = 50", "cycles = nan", r"\[scene\]: key 'cycles' must be a finite quantity"),
    ('plant = "cam_bar"', 'plant = "cam"', r"\[scene\]: key 'plant' must be one of 'cam_bar', 'clutch_dynamic'"),
    ('plant = "cam_bar"', "plant = { a = 1 }", r"\[scene\]: key 'plant' must be one of"),
    ('to = "device.y"', 'to = "device.y"\noverrides = 5', r"\[transducers.rod_force\]: key 'overrides' must be a table"),
    ('to = "device.y"', 'to = "device.y"\nfaults = { fault = "dropout" }', r"\[transducers.rod_force\]: key 'faults' must be an"),
    ('to = "device.y"', 'to = "device.y"\nfaults = [1]', r"\[transducers.rod_force\]: key 'faults\[0\]' must be a table"),
    ('channel = "rig"', 'channel = "rig"\nport = 70000', r"\[links.can\]: key 'port' must be an integer >= 0 and <= 65535"),
    ('channel = "rig"', 'channel = "rig"\nfd = 1', r"\[links.can\]: key 'fd' must be true or false"),
    ('channel = "rig"', 'channel = "rig"\nlive_share = 0', r"\[links.can\]: key 'live_share' must be in \(0, 1\]"),
    ('channel = "rig"', 'channel = ""', r"\[links.can\]: key 'channel' must be a name without white space.*got ''"),
    ('channel = "rig"', 'channel = "my bus"', r"\[links.can\]: key 'channel' must be a name without white space"),
    ("[recording]\n", '[recording]\nencoding = "xml"\n', r"\[recording\]: key 'encoding' must be one of 'json', 'base64'"),
    ("[recording]\n", '[recording]\ncompression = "gzip"\n', r"\[recording\]: key 'compression' must be one of"),
    ('truth_signals = ["phi"', 'truth_signals = [1, "phi"', r"\[recording\]: key 'truth_signals' must be a list"),
])
def test_runner_sections_reject_values_they_cannot_use(tmp_path, old, new, message):
    with pytest.raises(SceneError, match=message):
        read_config(load_scene(edited(tmp_path, DEMO, old, new)))


@pytest.mark.parametrize("scene, old, new, message", [
    ("lab_cam", 'rate = "500 Hz"', 'rate = "0 Hz"', r"\[transducers.cam_encoder\]: key 'rate' must be positive"),
    ("lab_cam", 'rate = "500 Hz"', 'rate = "-500 Hz"', r"key 'rate' must be positive.*got \"-500 Hz\""),
    ("clutch_static_rubber_table", "through_origin = true", 'through_origin = "false"',
     r"\[plant.clutch\]: key 'through_origin' must be true or false \(no quotes\).*got \"false\""),
    ("lab_cam", 'rate = "500 Hz"', 'rate = "500 Hz"\noverrides = { errors_enabled = "false" }',
     r"override 'errors_enabled' must be true or false \(no quotes\), got 'false'"),
])
def test_rates_and_switches_are_checked(tmp_path, scene, old, new, message):
    """A transducer rate of 0 Hz ended in a ZeroDivisionError traceback, -500 Hz ran and filled the sheet with garbage;
    "false" in quotes is a string, which Python takes for true (an audit)."""
    from rig.runner.session import run_scene
    path = edited(tmp_path, SCENES / f"{scene}.toml", old, new)
    with pytest.raises(SceneError, match=message):
        run_scene(path, tmp_path / "x.mcap")


@pytest.mark.parametrize("old, new, runner, message", [
    ('L3 = "260 mm"', 'L3 = "1e308 mm"', False, r"\[plant\]: key 'L3' is beyond any machine \(more than 1e\+30 in SI "
                                               r"units\), got \"1e308 mm\""),      # (an OverflowError traceback)
    ('sample_rate = "10 kHz"', 'sample_rate = "1e12 Hz"', True, r"key 'sample_rate' must be at most 1 MHz"),  # (MemoryE.)
    ('speed = "150 rpm"', 'speed = "1e30 rpm"', False, r"\[speed\]: key 'speed' must be positive and at most 1e6 rpm"),
    ("cycles = 50", "cycles = 99999999999999999999", True, r"key 'cycles' must be an integer >= 1 and <= 1000000000"),
    ("cycles = 50", 'cycles = 50\nmax_time = "1e20 s"', True, r"key 'max_time' must be at most 1e\+09 s"),
    ("seed = 20240611", "seed = 123456789012345678901234567890123", True, None),     # a whole number: no magnitude
])
def test_quantities_beyond_any_machine_are_named(tmp_path, old, new, runner, message):
    """Each was a traceback, a 2.9 TiB allocation or a hang (an audit). The runner's keys are read by read_config,
    the plant's by the cam bar's reader."""
    from rig.plants.cam_bar.scene_io import cam_bar_from_scene
    scene = load_scene(edited(tmp_path, DEMO, old, new))
    check = (lambda: read_config(scene, choose_level=False)) if runner else (lambda: cam_bar_from_scene(scene.path))
    if message is None:
        check()
        return
    with pytest.raises(SceneError, match=message):
        check()


def test_a_scene_with_a_byte_order_mark_reads_and_one_not_in_utf8_is_named(tmp_path):
    text = DEMO.read_text(encoding="utf-8")
    (tmp_path / "bom.toml").write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    assert load_scene(tmp_path / "bom.toml").data == load_scene(DEMO).data
    (tmp_path / "latin1.toml").write_bytes('name = "Géneva"\n'.encode("latin-1"))
    with pytest.raises(SceneError, match=r"latin1.toml: not UTF-8 text \(byte 0xe9 at offset 9\)"):
        load_scene(tmp_path / "latin1.toml")


@pytest.mark.parametrize("command", ["summary", "tolerance"])
@pytest.mark.parametrize("old, new, message", [
    ('sample_rate = "10 kHz"', 'sample_rate = "10 kg"', r"key 'sample_rate': '10 kg' has the wrong dimension"),
    ("cycles = 50", "cycles = 50\nfidelity = 7", r"'fidelity' must be 0, 1, 2"),
    ('questions = ["stroke"', 'questions = ["nope"', r"question 'nope' is not one a cam_bar scene can answer"),
    ('description = "burster_8411"', 'description = "nope_9999"', r"cannot read device description .*nope_9999"),
])
def test_commands_that_do_not_run_the_plant_check_the_whole_scene(tmp_path, capsys, command, old, new, message):
    """rig summary wrote its chart for each of these and exited 0, rig tolerance took most (an audit); rig run
    refuses them all."""
    path = edited(tmp_path, DEMO, old, new)
    extra = ["--png", str(tmp_path / "c.png")] if command == "summary" else ["--samples", "100", "-o", str(tmp_path)]
    assert cli.main(["-q", command, str(path), *extra]) == 2
    assert re.search(message, one_error_line(capsys))
    assert not list(tmp_path.glob("*.png"))


def test_a_scene_port_is_an_integer(tmp_path):
    cfg = read_config(load_scene(edited(tmp_path, DEMO, 'channel = "rig"', 'channel = "rig"\nport = 29536')))
    assert cfg.can["port"] == 29536 and isinstance(cfg.can["port"], int)


def test_every_scene_file_passes():
    for path in sorted(SCENES.glob("*.toml")):
        read_config(load_scene(path))


def test_cli_unknown_section_exits_2_naming_it(tmp_path, capsys):
    path = edited(tmp_path, DEMO, "[recording]\n", "[recordng]\n")
    assert cli.main(["-q", "run", str(path), "-o", str(tmp_path / "x.mcap")]) == 2
    err = one_error_line(capsys)
    assert "[recordng]" in err and str(path) in err
    assert not (tmp_path / "x.mcap").exists()


@pytest.mark.parametrize("old, new, message", [
    ('signal = "F_rod"', 'signal = "F_rood"', "[transducers.rod_force]: the plant has no signal 'F_rood'"),
    ("bitrate = 1000000", "bitrate = 10000", "[links.can]: the periodic frames alone need"),
    ('kind = "window"', 'kind = "windw"',                       # an element's key said as a key ("no. 1.kind" before)
     "[[device.config.elements]] no. 1, key 'kind': 'windw' is not one of 'window'"),
    ('sample_rate = "10 kHz"', 'sample_rate = "400 kHz"',       # the unit's inputs: found in the first chunk before
     "[scene]: 'sample_rate' = 400000 Hz is faster than the acquisition unit takes its inputs (100000 Hz"),
])
def test_wiring_errors_are_found_before_anything_is_written(tmp_path, capsys, old, new, message):
    """What only the plant and the bus can check (a transducer's signal, the bus load) is checked before the summary,
    its chart and the recording: exit 2, nothing left."""
    path = edited(tmp_path, DEMO, old, new)
    out = tmp_path / "out" / "x.mcap"
    assert cli.main(["-q", "run", str(path), "--cycles", "2", "-o", str(out)]) == 2
    assert message in one_error_line(capsys)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("after, fault, message", [
    ('to = "device.y"', '{ fault = "open_bridge", at = "1 s", polarity = 0 }', r"'polarity' must be \+1 or -1, got 0"),
    ('to = "device.y"', '{ fault = "excitation_loss", at = "1 s", level = 2.0 }', r"'level' must be between 0 and 1"),
    ('to = "device.y"', '{ fault = "excitation_loss", at = "1 s", level = inf }', r"'level' must be a finite number"),
    ('to = "device.y"', '{ at = "1 s" }', r"a fault table needs 'fault', its kind"),
    ('to = "can.Encoder1"', '{ fault = "glitches", at = "1 s", width = 3 }', r"'width': 3 has no unit"),
    ('to = "can.Encoder1"', '{ fault = "glitches", at = "1 s", rate = "-5 1/s" }', r"'rate' must not be negative"),
    ('to = "can.Encoder1"', '{ fault = "missed_pulses", at = "1 s", probability = 2.0 }', r"'probability' must be between"),
    ('to = "can.Encoder1"', '{ fault = "missed_pulses", at = "1 s", probability = nan }', r"must be a finite number"),
])
def test_fault_parameters_are_checked_when_the_scene_is_read(tmp_path, after, fault, message):
    """A probability of 2, NaN, a negative rate, a unit-less width (taken as 3 s), a polarity 0 (taken as +1): each
    refused with the transducer's section before anything runs (they ran, or stopped mid-run naming no key)."""
    path = edited(tmp_path, DEMO, after, f"{after}\nfaults = [{fault}]")
    with pytest.raises(SceneError, match=r"\[transducers\.\w+\]: .*" + message):
        from rig.runner.machine import instruments
        instruments(read_config(load_scene(path)))


HOLD = SCENES / "clutch_overload_hold.toml"


@pytest.mark.parametrize("old, new, message", [
    ("shutdown_count = 4", "shutdown_count = 0", r"\[plant\]: key 'shutdown_count' must be an integer >= 1"),
    ('shutdown_window = "100 ms"', 'shutdown_window = "0 ms"', r"\[plant\]: key 'shutdown_window' must be positive"),
    ("n = 3", "n = 2.5", r"\[plant\]: key 'n' must be an integer >= 1"),
    ('a0 = "437.708 N*m"', 'a0 = "-437 N*m"', r"\[motor\]: key 'a0' must not be negative .*got \"-437 N\*m\""),
    ("mu_B = 0.10", 'mu_B = "abc"', r"\[plant\]: key 'mu_B': 'abc' is not a number"),
])
def test_clutch_stand_keys_are_checked_where_the_scene_writes_them(tmp_path, old, new, message):
    """Counts, windows and the motor line are checked with the scene's key (they reached the stand's own checks,
    which name no key, or ran a motor turning backwards)."""
    from rig.plants.clutch.stand import ClutchStand
    with pytest.raises(SceneError, match=message):
        ClutchStand.from_scene(load_scene(edited(tmp_path, HOLD, old, new)))


@pytest.mark.parametrize("extra, message", [
    (["--no-report", "--report-dir", "r"], "argument --report-dir: not allowed with argument --no-report"),
    (["--no-report", "--ok-plots", "2", "--format", "md"], "--format, --ok-plots shape the report, and --no-report "
                                                          "writes none"),
])
def test_report_options_with_no_report_are_refused(tmp_path, capsys, extra, message):
    argv = ["run", str(DEMO), "-o", str(tmp_path / "x.mcap"), *extra]
    try:
        assert cli.main(argv) == 2
    except SystemExit as exc:                     # argparse's own usage error
        assert exc.code == 2
    assert message in one_error_line(capsys) and not (tmp_path / "x.mcap").exists()


@pytest.mark.parametrize("argv, usage", [(["run", "--cyles"], "rig run"),
                                         (["bench", "work-precision", "--quik", "-o", "x"], "rig bench work-precision"),
                                         (["--bogus"], "rig"), (["--bogus", "run"], "rig"),
                                         (["run", "--cyc", "3"], "rig run"), (["--qui", "run"], "rig"),
                                         (["tolerance", "--sampl", "10"], "rig tolerance")])
def test_an_unknown_option_points_at_the_usage_of_its_subcommand(argv, usage, capsys):
    """It pointed at ``rig -h`` for a subcommand's misspelt option, whose usage lists none of the subcommand's; an
    abbreviation is unknown too (argparse took ``--cyc`` for ``--cycles``)."""
    with pytest.raises(SystemExit) as info:
        cli.main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err == f"{usage}: error: unrecognized arguments: {next(a for a in argv if a.startswith('--'))} " \
                  f"({usage} -h: usage)\n"


# -- counts -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [
    ["run", "--cycles", "0"], ["run", "--cycles", "-3"], ["run", "--cycles", "two"],
    ["serve", str(DEMO), "--cycles", "0"], ["record", str(DEMO), "-o", "x.mcap", "--can-port", "1", "--cycles", "0"],
])
def test_cycles_below_one_exit_2_naming_the_option(argv, capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(argv)
    assert info.value.code == 2
    err = one_error_line(capsys)
    assert "argument --cycles" in err and "rig " in err


@pytest.mark.parametrize("argv, option", [
    (["tolerance", "--samples", "1"], "--samples"), (["tolerance", "--workers", "0"], "--workers"),
    (["tolerance", "--samples", "99999999999999999999"], "--samples"),
    (["serve", str(DEMO), "--wait", "-1"], "--wait"), (["serve", str(DEMO), "--port", "70000"], "--port"),
    (["record", str(DEMO), "-o", "x.mcap", "--can-port", "0"], "--can-port"),
])
def test_other_counts_are_checked_too(argv, option, capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(argv)
    assert info.value.code == 2 and f"argument {option}" in one_error_line(capsys)


def test_a_count_may_be_written_in_scientific_notation_when_whole(capsys):
    """``--samples 1e3`` was "expected a whole number"; 1.5e0 and nan still are not counts."""
    assert cli.build_parser().parse_args(["tolerance", "--samples", "1e3"]).samples == 1000
    for text in ("1.5e0", "nan", "1e400"):
        with pytest.raises(SystemExit):
            cli.build_parser().parse_args(["tolerance", "--samples", text])
        assert "expected a whole number" in capsys.readouterr().err


def test_quiet_is_accepted_after_the_command_too(tmp_path, capsys):
    args = cli.build_parser().parse_args(["run", "-q", "--cycles", "2"])
    assert args.quiet and args.cycles == 2
    assert cli.build_parser().parse_args(["-q", "run"]).quiet
    assert not cli.build_parser().parse_args(["run"]).quiet


# -- plant kinds ------------------------------------------------------------------------------------
@pytest.mark.parametrize("command", ["summary", "tolerance", "cam-design", "bench stability", "bench fidelity"])
def test_cam_bar_commands_on_a_clutch_scene_say_so(command, tmp_path, capsys):
    out = {"summary": ["--png", str(tmp_path / "c.png")], "cam-design": ["-o", str(tmp_path / "c.png")]}.get(
        command, ["-o", str(tmp_path / "out")])
    scene = [str(CLUTCH)] if not command.startswith("bench") else ["--scene", str(CLUTCH)]
    assert cli.main([*command.split(), *scene, *out]) == 2
    err = one_error_line(capsys)
    assert f'rig {command} needs plant "cam_bar" in [scene] (a cam-bar scene' in err and "'clutch_dynamic' scene" in err
    assert "F_a1" not in err and not (tmp_path / "out").exists() and not (tmp_path / "c.png").exists()


# -- output paths -----------------------------------------------------------------------------------
@pytest.fixture
def foreign(tmp_path) -> Path:
    """A file rig did not write (think /etc/passwd)."""
    path = tmp_path / "passwd"
    path.write_text("root:x:0:0:root:/root:/bin/bash\n")
    return path


def test_an_existing_foreign_file_is_never_overwritten(foreign, capsys):
    assert cli.main(["-q", "run", "--cycles", "1", "-o", str(foreign)]) == 2
    err = one_error_line(capsys)
    assert f"cannot write the recording to {foreign}: it exists and is not a recording file rig wrote" in err
    assert foreign.read_text() == "root:x:0:0:root:/root:/bin/bash\n"
    assert not foreign.with_suffix(".cycle.png").exists() and not foreign.with_name("passwd.cycle.png").exists()


@pytest.mark.parametrize("argv, message", [
    (lambda t: ["run", "--cycles", "1", "-o", str(t)], "cannot write the recording to {t}: it is a directory"),
    (lambda t: ["run", "--cycles", "1", "-o", str(t / "passwd" / "x.mcap")],
     "cannot write the recording to {t}/passwd/x.mcap: {t}/passwd is a file, not a directory"),
    (lambda t: ["run", "--cycles", "1", "-o", str(t / "x.mcap"), "--report-dir", str(t / "passwd")],
     "cannot write the report to {t}/passwd: it exists and is not a directory"),
    (lambda t: ["record", str(DEMO), "-o", str(t / "passwd"), "--can-port", "1"],
     "cannot write the recording to {t}/passwd: it exists and is not a recording file"),
    (lambda t: ["report", str(t / "passwd"), "-o", str(t / "passwd")],
     "{t}/passwd: not an MCAP file (bad magic bytes)"),                  # the input is named first
    (lambda t: [(t / "r.mcap").write_bytes(b"\x89MCAP0\r\n") and "report", str(t / "r.mcap"), "-o", str(t / "r.mcap")],
     "cannot write the report to {t}/r.mcap: that is the recording"),
    (lambda t: ["summary", "--png", str(t / "passwd")], "cannot write the cycle chart to {t}/passwd: it exists"),
    (lambda t: ["summary", "--png", str(t / "c.txt")], "cannot write the cycle chart to {t}/c.txt: a chart is a PNG "
                                                       "file, its name must end in .png"),
    (lambda t: ["cam-design", "-o", str(t / "cd.txt")], "cannot write the cam-design chart to {t}/cd.txt: a chart is a "
                                                       "PNG file, its name must end in .png (e.g. {t}/cd.png)"),
    (lambda t: ["tolerance", "-o", str(t / "passwd")], "cannot write the tolerance chart to {t}/passwd: it exists"),
    (lambda t: ["serve", str(DEMO), "--endpoints", str(t / "passwd")],
     "cannot write the serve endpoints to {t}/passwd: it exists and is not a serve endpoints file"),    # "a endpoints"
    (lambda t: [(t / "a.mcap").write_bytes(b"\x89MCAP0\r\n") and "export-can", str(t / "a.mcap"), "-o", str(t)],
     "cannot write the CAN trace to {t}: it is a directory"),          # an MCAP file's start: the output is next
])
def test_output_path_errors_name_the_path_in_plain_words(tmp_path, foreign, capsys, argv, message):
    assert cli.main(["-q", *argv(tmp_path)]) == 2
    err = one_error_line(capsys)
    assert message.format(t=tmp_path) in err and "Errno" not in err
    assert foreign.read_text().startswith("root:")


def test_a_directory_without_write_permission_is_named(tmp_path, monkeypatch, capsys):
    from rig import outputs
    monkeypatch.setattr(outputs.os, "access", lambda path, mode: Path(path) != tmp_path)
    assert cli.main(["-q", "run", "--cycles", "1", "-o", str(tmp_path / "sub" / "x.mcap")]) == 2
    assert f"permission denied (cannot create files in {tmp_path})" in one_error_line(capsys)


def test_a_directory_that_takes_no_files_is_named_before_anything_runs(capsys):
    """/proc passes the permission check for root but takes no files: found before the run, not at the chart."""
    assert cli.main(["-q", "run", "--cycles", "1", "-o", "/proc/x.mcap"]) == 2
    assert ("cannot write the recording to /proc/x.mcap: cannot create files in /proc (it is a virtual or read-only "
            "file system that takes no new files)") in one_error_line(capsys)       # not "(no such file or directory)"


def test_rig_replaces_its_own_recordings_and_charts(tmp_path):
    from rig.outputs import PNG_MAGIC, UsageError, writable_dir, writable_file
    from rig.recorder.salvage import MCAP_MAGIC
    for name, magic, what in (("a.mcap", MCAP_MAGIC, "recording"), ("a.png", PNG_MAGIC, "cycle chart")):
        (tmp_path / name).write_bytes(magic + b"...")
        writable_file(tmp_path / name, what, magic)           # no error
        (tmp_path / name).write_bytes(b"")
        writable_file(tmp_path / name, what, magic)           # an empty file holds nothing to lose
        (tmp_path / name).write_bytes(magic[:3])
        writable_file(tmp_path / name, what, magic)           # a cut file of that kind (a killed run's)
        (tmp_path / name).write_bytes(b"x" + magic)
        with pytest.raises(UsageError, match="is not a"):
            writable_file(tmp_path / name, what, magic)       # another file: never overwritten
    writable_file(tmp_path / "new" / "deeper" / "b.mcap", "recording", MCAP_MAGIC)
    writable_dir(tmp_path / "new" / "report", "report")


def test_output_directories_holding_other_files_are_refused(tmp_path, capsys):
    """A directory rig fills with files of its own naming (report, sweep, analysis, studies, bench) must be new,
    empty or marked as rig's: a user's report.html or recordings.csv there is never replaced."""
    from rig.outputs import MARK, UsageError, claim_dir, writable_dir
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "report.html").write_text("<html>mine</html>")
    with pytest.raises(UsageError, match=f"{mine}: it already holds other files"):
        writable_dir(mine, "report")
    writable_dir(mine, "tolerance chart", shared=True)       # a directory of individually checked files
    empty = claim_dir(tmp_path / "rigs" / "report")
    assert (empty / MARK).is_file()
    (empty / "report.html").write_text("<html>rig's</html>")
    writable_dir(empty, "report")                             # rig's own: replaced
    earlier = tmp_path / "earlier"                            # a report directory of a rig before the marker
    earlier.mkdir()
    (earlier / "report.html").write_text("<!DOCTYPE html><html><head><meta charset='utf-8'><title>Rig report: a.mcap")
    (earlier / "curves.csv").write_text("curve,program\n")
    writable_dir(earlier, "report")
    rec = tmp_path / "r.mcap"
    assert cli.main(["-q", "run", "--cycles", "1", "-o", str(rec), "--no-report"]) == 0
    capsys.readouterr()
    assert cli.main(["-q", "report", str(rec), "-o", str(mine)]) == 2
    assert "already holds other files" in one_error_line(capsys)
    assert (mine / "report.html").read_text() == "<html>mine</html>" and not (mine / "curves.csv").exists()
    assert cli.main(["-q", "report", str(rec), "-o", str(tmp_path / "rep")]) == 0
    assert cli.main(["-q", "report", str(rec), "-o", str(tmp_path / "rep")]) == 0     # again: rig's own directory
    for argv, what in ((["cam-design", "-o", str(mine / "report.html")], "cam-design chart"),
                       (["export-can", str(rec), "-o", str(mine / "report.html")], "CAN trace")):
        capsys.readouterr()
        assert cli.main(["-q", *argv]) == 2
        assert f"cannot write the {what} to {mine / 'report.html'}: it exists and is not a" in one_error_line(capsys)
    assert (mine / "report.html").read_text() == "<html>mine</html>"
    trace = tmp_path / "new" / "dir" / "bus.asc"
    assert cli.main(["-q", "export-can", str(rec), "-o", str(trace)]) == 0
    assert cli.main(["-q", "export-can", str(rec), "-o", str(trace)]) == 0            # its own trace: replaced


def test_os_errors_read_as_plain_words():
    assert cli._plain(FileExistsError(17, "File exists", "/etc/passwd")) == "/etc/passwd: file exists"
    assert cli._plain(PermissionError(13, "Permission denied", "/x", None)) == "/x: permission denied"


# -- run failures: exit 1 -----------------------------------------------------------------------------
def test_record_against_a_closed_port_is_one_line_and_exit_1(tmp_path):
    """python-can alone logs every failed attempt for 10 s (~200 000 lines); rig says it once. (That rig never
    enters python-can's retry loop is the next test's, without a clock: a timing bound here would fail on a busy
    machine.)"""
    import socket
    with socket.socket() as s:                   # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "x.mcap"
    proc = subprocess.run([sys.executable, "-m", "rig.cli", "record", str(DEMO), "-o", str(out), "--can-port",
                           str(port)], capture_output=True, text=True, timeout=120, cwd=tmp_path,
                          env={**os.environ, "MPLBACKEND": "Agg"})
    lines = [line for line in proc.stderr.splitlines()     # on a cold cache the fidelity check's compilation
             if not line.startswith("rig: compiling ")]     # is announced first: it depends on the test order
    assert proc.returncode == 1, proc.stderr
    assert len(lines) <= 3, lines[:5]
    assert re.search(rf"cannot connect to socketcand at 127\.0\.0\.1:{port}: connection refused", proc.stderr)
    assert "without --endpoints the scene and fidelity the machine serves are not checked" in lines[0]
    assert not out.exists()


def test_a_refused_port_never_reaches_python_cans_retry_loop(monkeypatch):
    """rig probes the port itself (``connect_timeout`` s of refusals) and opens python-can's client only after a
    socketcand greeting: python-can, which retries a refused connection for 10 s, is never called here."""
    import socket
    import can
    from rig.runner.session import RunError, _socketcand
    monkeypatch.setattr(can, "Bus", lambda *a, **k: pytest.fail("python-can's client was opened"))
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(RunError, match=rf"cannot connect to socketcand at 127\.0\.0\.1:{port}: connection refused"):
        _socketcand("127.0.0.1", port, "vcan0", 0.2)


def test_a_server_that_is_not_socketcand_is_named(tmp_path):
    import socket
    import threading
    from rig.runner.session import RunError, record_scene
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        port = server.getsockname()[1]

        def greet():
            conn, _ = server.accept()
            conn.sendall(b"SSH-2.0-OpenSSH_9.2\r\n")
            conn.close()
        threading.Thread(target=greet, daemon=True).start()
        with pytest.raises(RunError, match=rf"127.0.0.1:{port}: not a socketcand server \(it said b'SSH-2.0"):
            record_scene(DEMO, tmp_path / "x.mcap", can_port=port, serial_port=None, connect_timeout=2.0)
    assert not (tmp_path / "x.mcap").exists()


def test_cycles_on_a_duration_scene_is_a_usage_error(tmp_path, capsys):
    assert cli.main(["-q", "run", str(CLUTCH), "--cycles", "2", "-o", str(tmp_path / "c.mcap")]) == 2
    assert f"--cycles given, but {CLUTCH} runs for a duration" in one_error_line(capsys)


def test_the_console_script_skips_the_teardown_but_not_the_output(tmp_path):
    """``rig`` leaves through os._exit after main (rig.cli.entry): everything printed reaches a pipe and every file
    is complete, and the exit status is main's."""
    png = tmp_path / "cycle.png"
    proc = subprocess.run([sys.executable, "-m", "rig.cli", "summary", str(DEMO), "--png", str(png)],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path, env={**os.environ, "MPLBACKEND": "Agg"})
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.rstrip().endswith(f"cycle chart: {png}") and "b_min" in proc.stdout
    assert png.read_bytes().endswith(b"IEND\xaeB`\x82")                              # the PNG's last chunk
    bad = subprocess.run([sys.executable, "-m", "rig.cli", "run", str(tmp_path / "missing.toml")],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert bad.returncode == 2 and bad.stderr.startswith("rig: error:")


def test_every_option_of_every_command_says_what_it_does():
    from rig.cli import build_parser
    commands = build_parser()._subparsers._group_actions[0].choices
    silent = [f"{name} {'/'.join(a.option_strings)}" for name, sub in commands.items() for a in sub._actions
              if a.option_strings and not a.help]
    assert silent == []


def test_a_serial_rate_too_slow_for_the_set_up_is_refused_and_a_slow_one_is_said(tmp_path, monkeypatch, caplog):
    """123 baud once hung at "0/2 cycles" for minutes (the program written and read back at 12 bytes/s); the scene is
    refused naming the key, and a set-up slower than a few seconds is announced with its duration."""
    text = DEMO.read_text()
    assert "baudrate = 115200" in text
    slow = tmp_path / "slow.toml"
    slow.write_text(text.replace("baudrate = 115200", "baudrate = 123", 1))
    with pytest.raises(SceneError, match=r"\[links.serial\]: key 'baudrate' must be an integer >= 1200 and <= "
                                         r"4000000, got 123"):
        read_config(load_scene(slow))
    import rig.runner.host as host
    from rig.runner import run_scene
    monkeypatch.setattr(host, "SLOW_SETUP", 0.0)         # the demo's 115200 baud then counts as slow
    run_scene(DEMO, tmp_path / "one.mcap", cycles=1)
    assert re.search(r"configuring the unit over serial at 115200 baud: the program alone takes about \d+ s on the "
                     r"line", caplog.text)


# -- files a scene names ------------------------------------------------------------------------------
def test_relative_description_paths_are_relative_to_the_scene_file_not_the_working_directory(tmp_path, monkeypatch):
    from firmware_sim.transducers.description import DEVICES_DIR, read_description, resolve_path
    folder = tmp_path / "sub"
    (folder / "devs").mkdir(parents=True)
    (folder / "devs" / "force.toml").write_text((DEVICES_DIR / "burster_8411.toml").read_text(encoding="utf-8"))
    (folder / "devs" / "unit.toml").write_text((DEVICES_DIR / "digiforce_9310.toml").read_text(encoding="utf-8"))
    path = edited(folder, DEMO, 'description = "burster_8411"', 'description = "devs/force.toml"')
    path.write_text(path.read_text().replace("[device]\n", '[device]\ndescription = "devs/unit.toml"\n', 1))
    monkeypatch.chdir(tmp_path)                       # not the scene's folder: devs/force.toml is not here
    cfg = read_config(load_scene(Path("sub") / path.name))
    force = next(t for t in cfg.transducers if t.name == "rod_force")
    assert Path(force.description) == folder / "devs" / "force.toml"
    assert read_description(resolve_path(force.description))["type"] == "strain_gauge_bridge"
    assert Path(cfg.device["description"]) == folder / "devs" / "unit.toml"
    assert next(t for t in cfg.transducers if t.name == "cam_encoder").description == "encoder_1024"   # a name


def test_a_recorded_scene_resolves_its_paths_where_its_file_was(tmp_path):
    from rig.recorder.reader import Recording
    text = DEMO.read_text(encoding="utf-8")
    whole = Recording(tmp_path / "out" / "run.mcap", text, {"rig": {"scene_file": "/lab/scenes/pin.toml"}})
    assert whole.scene().file("devs/force.toml") == Path("/lab/scenes/devs/force.toml")
    relative = Recording(tmp_path / "out" / "run.mcap", text, {"rig": {"scene_file": "pin.toml"}})
    assert relative.scene().file("devs/force.toml") == tmp_path / "out" / "devs" / "force.toml"


def test_a_report_without_its_lab_sheet_says_so_on_the_console(tmp_path, caplog):
    from types import SimpleNamespace
    from rig.analysis.lab_report import lab_section
    from rig.recorder.reader import Recording
    rec = Recording(tmp_path / "run.mcap", (SCENES / "lab_geneva.toml").read_text(encoding="utf-8"))  # no readings
    with caplog.at_level("WARNING"):
        blocks = lab_section(SimpleNamespace(recording=rec))
    reason = blocks[1].text.removeprefix("No lab sheet: ")
    assert "no edge_time readings" in reason
    assert [r.getMessage() for r in caplog.records if r.levelname == "WARNING"] == [
        f"lab: no sheet in the report ({reason})"]


# -- messages in the scene's own terms ----------------------------------------------------------------
@pytest.mark.parametrize("old, new, message", [
    ('speed = "150 rpm"', 'speed = "-120 rpm"',
     r"\[speed\]: key 'speed' must be positive and at most 1e6 rpm, got \"-120 rpm\"$"),
    ('profile = "constant"', 'profile = "ramp"\nspeed_end = "-120 rpm"\nramp_time = "1 s"',
     r"\[speed\]: key 'speed_end' must be positive and at most 1e6 rpm, got \"-120 rpm\"$"),
])
def test_a_negative_speed_is_named_by_its_key_in_the_unit_written(tmp_path, old, new, message):
    from rig.plants.cam_bar.scene_io import read_speed_profile
    with pytest.raises(SceneError, match=message):
        read_speed_profile(load_scene(edited(tmp_path, DEMO, old, new)))


@pytest.mark.parametrize("old, new, message", [
    ('sample_rate = "10 kHz"', 'sample_rate = "0 Hz"', r"\[scene\]: key 'sample_rate' must be positive, got 0 Hz$"),
    ('chunk = "500 ms"', 'chunk = "-1 s"', r"\[scene\]: key 'chunk' must be positive, got -1 s$"),
    ('chunk = "500 ms"', 'chunk = "0.1 ms"', r"\[scene\]: 'chunk' = 0.0001 s holds 1 samples at 'sample_rate' = "
                                             r"10000 Hz: a chunk needs at least 2$"),
])
def test_the_run_grid_names_the_key_that_is_wrong(tmp_path, old, new, message):
    """(was one message for all three: "'sample_rate' and 'chunk' must be positive, with >= 2 samples per chunk")"""
    from rig.runner.config import read_config
    with pytest.raises(SceneError, match=message):
        read_config(load_scene(edited(tmp_path, DEMO, old, new)))


@pytest.mark.parametrize("angle", ['"90 deg"', '"-30 deg"'])
def test_a_cardan_shaft_angle_out_of_range_says_the_range_and_the_value_as_written(tmp_path, angle):
    from rig.plants.lab_bench import LabBench
    path = edited(tmp_path, SCENES / "lab_cardan.toml", 'shaft_angle = "30 deg"', f"shaft_angle = {angle}")
    with pytest.raises(SceneError) as info:
        LabBench.from_scene(load_scene(path))
    assert str(info.value) == (f"{path} [plant]: key 'shaft_angle' must be at least 0° and below 90° (angle between "
                               f"input and output shaft; at 90° the output shaft cannot turn), got {angle}")


def test_a_seed_that_is_no_number_is_called_a_non_negative_integer(tmp_path):
    with pytest.raises(SceneError, match=r"\[scene\]: key 'seed' must be an integer >= 0 \(seed of every random draw "
                                         r"of the run\), got \"abc\"$"):
        read_config(load_scene(edited(tmp_path, DEMO, "seed = 20240611", 'seed = "abc"')))


@pytest.mark.parametrize("written, bits", [("500000", 500_000), ('"500 kbit/s"', 500_000), ('"1 Mbit/s"', 1_000_000)])
def test_a_bitrate_is_a_number_of_bit_per_second_or_a_bit_rate_with_its_unit(tmp_path, written, bits):
    cfg = read_config(load_scene(edited(tmp_path, DEMO, "bitrate = 1000000", f"bitrate = {written}")))
    assert cfg.can["bitrate"] == bits and isinstance(cfg.can["bitrate"], int)
    with pytest.raises(SceneError, match=r"\[links.can\]: key 'bitrate': '500 ms' has the wrong dimension; expected "
                                         r"something convertible to bit/s"):
        read_config(load_scene(edited(tmp_path, DEMO, "bitrate = 1000000", 'bitrate = "500 ms"')))


def test_output_into_a_closed_pipe_ends_quietly(monkeypatch, capsys, tmp_path):
    """`rig summary | head -1`: the reader stopped reading; no "rig: error: broken pipe", status 141 (128 + SIGPIPE)
    as a shell's own tools end."""
    import sys

    from rig.cli import main

    class Closed:
        def write(self, text: str) -> int:
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self) -> None:
            pass

    monkeypatch.setattr(sys, "stdout", Closed())
    assert main(["summary", "--png", str(tmp_path / "cycle.png")]) == 141
    assert capsys.readouterr().err == ""


def test_curve_plot_options_on_a_scene_without_curves_are_refused(tmp_path, capsys):
    """--ok-plots on a lab scene was accepted without a word (an audit): it measures no curves to plot."""
    lab = Path(DEMO).parent / "lab_cam.toml"
    assert cli.main(["run", str(lab), "--ok-plots", "3", "-o", str(tmp_path / "x.mcap")]) == 2
    assert ("--ok-plots chooses which curves the report plots, and " in one_error_line(capsys)
            and not (tmp_path / "x.mcap").exists())

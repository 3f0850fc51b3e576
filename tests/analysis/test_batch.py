"""rig analyse: many recordings on an executor, one table and one report; the combined statistics are
those of all curves together."""
from __future__ import annotations

import csv
import shutil

import pytest

from rig.analysis.batch import analyse_batch, expand, report_lines
from rig.analysis.sets import process_values
from rig.cli import main
from rig.executors import make_executor
from rig.recorder import read_recording


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """Two demo runs (2 and 3 cycles), a copy of one, a file cut in its only chunk (it holds no message) and one
    cut after its data (a run killed while closing its file: every message is there)."""
    root = tmp_path_factory.mktemp("batch")
    for cycles in (2, 3):
        assert main(["-q", "run", "--no-report", "--cycles", str(cycles), "-o", str(root / f"run{cycles}.mcap")]) == 0
    (root / "sub").mkdir()
    shutil.copy(root / "run2.mcap", root / "sub" / "copy.mcap")
    data = (root / "run3.mcap").read_bytes()
    (root / "cut.mcap").write_bytes(data[: len(data) // 2])
    (root / "short.mcap").write_bytes(data[:-100])
    return root


def test_combined_statistics_are_those_of_all_curves(recordings, dask_scheduler, monkeypatch):
    paths = expand([str(recordings / "run*.mcap"), str(recordings / "**" / "copy.mcap")])
    assert [p.name for p in paths] == ["run2.mcap", "run3.mcap", "copy.mcap"]
    # a folder stands for the recordings under it, at any depth (was "no recording files in DIR")
    assert expand([str(recordings / "sub")]) == [recordings / "sub" / "copy.mcap"]
    assert {p.name for p in expand([str(recordings)])} == {"run2.mcap", "run3.mcap", "copy.mcap", "cut.mcap", "short.mcap"}
    # relative patterns give absolute paths: a worker of a cluster opens them from its own folder
    monkeypatch.chdir(recordings.parent)
    assert expand([f"{recordings.name}/run2.mcap"]) == [recordings / "run2.mcap"] and paths[0].is_absolute()
    with make_executor("serial") as ex:
        serial = analyse_batch(paths, ex)
    with make_executor("dask", scheduler=dask_scheduler) as ex:
        dask = analyse_batch(paths, ex)
    every = [r for p in paths[:2] for r in read_recording(p).results]   # the copy of run2 counts once
    x_max = process_values(every)["x_max"] * 1e3                    # display unit mm
    m, unit = serial.combined[("pin_insertion L1", "p1.x_max")]
    assert unit == "mm" and m.n == 5 == x_max.size
    assert [r.copy_of for r in serial.recordings] == ["", "", str(paths[0])]
    assert float(m.mean[0]) == pytest.approx(x_max.mean(), rel=1e-12)
    assert float(m.std(1)[0]) == pytest.approx(x_max.std(ddof=1), rel=1e-9)
    assert float(m.maximum[0]) == x_max.max()
    d, _ = dask.combined[("pin_insertion L1", "p1.x_max")]
    assert (d.n, float(d.mean[0]), float(d.m2[0])) == (m.n, float(m.mean[0]), float(m.m2[0]))
    assert [(r.path, r.curves, r.ok, r.nok) for r in serial.recordings] == [(r.path, r.curves, r.ok, r.nok)
                                                                            for r in dask.recordings]


def test_rig_analyse_writes_table_and_report_and_names_unreadable_files(recordings, tmp_path, capsys):
    """A truncated file is read as `rig report --partial` reads it: what it holds is analysed, and it is marked
    incomplete with the reason; only a file that yields nothing is unreadable."""
    out = tmp_path / "an"
    capsys.readouterr()
    assert main(["-q", "analyse", str(recordings / "*.mcap"), "-o", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()          # run2 and run3: one seed; the console says it too
    assert sum(line.startswith("Note: 2 runs of pin_insertion L1 were made with seed ") for line in printed) == 1
    rows = list(csv.DictReader((out / "recordings.csv").open()))
    assert [r["recording"].rsplit("/", 1)[1] for r in rows] == ["cut.mcap", "run2.mcap", "run3.mcap", "short.mcap"]
    cut, run2, run3, short = rows
    assert "the recording holds no message: chunk 1 (bytes " in cut["error"] and "is cut by the end of the file" \
        in cut["error"] and "file ends" in cut["error"] and cut["curves"] == "0"
    assert (run2["curves"], run3["curves"]) == ("2", "3") and run3["complete"] == "True" and not run3["why incomplete"]
    assert run3["p1.x_max n"] == "3" and float(run3["p1.x_max mean [mm]"]) > 40
    assert not short["error"] and short["complete"] == "False" and short["curves"] == "3"
    assert short["why incomplete"].startswith("file ends") and "after the data end" in short["why incomplete"]
    assert "nothing of the run is lost" in short["why incomplete"]      # the report's loss lines, not only the cut
    assert short["p1.x_max mean [mm]"] == run3["p1.x_max mean [mm]"]
    report = (out / "report.md").read_text()
    assert short["copy of (not counted)"] == run3["recording"] and not run3["copy of (not counted)"]
    assert "4 recordings" in report and ("3 read (1 incomplete), 1 of them a copy of another run (counted once), "
                                         "1 unreadable; 5 curves") in report
    assert f"* {recordings / 'short.mcap'}: 3 curves; counted: {recordings / 'run3.mcap'}" in report
    incomplete = report[report.index("## Incomplete recordings"):report.index("## Copies of another run")]
    assert f"* {recordings / 'short.mcap'}: file ends" in incomplete and "cut.mcap" not in incomplete
    assert f"* {recordings / 'cut.mcap'}: the recording holds no message" in report      # the path once
    assert main(["analyse", str(tmp_path / "nothing*.mcap")]) == 2
    assert "no recording matches" in capsys.readouterr().err


def test_rig_analyse_of_no_readable_recording_is_an_input_error(recordings, tmp_path, capsys):
    """Nothing could be read (only a file that holds no message): exit status 2, an input error (README), one line."""
    capsys.readouterr()
    assert main(["-q", "analyse", str(recordings / "cut.mcap"), "-o", str(tmp_path / "an")]) == 2
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.startswith(f"rig: error: {recordings / 'cut.mcap'}: the recording holds no "
                                                     "message")              # the file and why, not only "see the table"
    assert "analysed" not in out               # no success line beside the error
    (tmp_path / "cut2.mcap").write_bytes((recordings / "cut.mcap").read_bytes())
    assert main(["-q", "analyse", str(recordings / "cut.mcap"), str(tmp_path / "cut2.mcap"), "-o",
                 str(tmp_path / "an2")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rig: error: none of the 2 files could be read") and "the recording holds no message" in err


def test_recordings_of_different_scenes_or_levels_are_not_one_population(recordings, tmp_path, capsys):
    """The same machine at level 0 and at level 1 (or a start-up and a shock test) are two populations: their values
    are combined per scene and level, and the report says so — not one mean over both."""
    other = tmp_path / "l0.mcap"
    assert main(["-q", "run", "--no-report", "--cycles", "2", "--fidelity", "0", "-o", str(other)]) == 0
    paths = [recordings / "run3.mcap", other]
    with make_executor("serial") as ex:
        result = analyse_batch(paths, ex)
    assert [r.group for r in result.recordings] == ["pin_insertion L1", "pin_insertion L0"]
    for group, path in (("pin_insertion L1", paths[0]), ("pin_insertion L0", paths[1])):
        m, unit = result.combined[(group, "p1.x_max")]
        x_max = process_values(read_recording(path).results)["x_max"] * 1e3
        assert unit == "mm" and m.n == x_max.size and float(m.mean[0]) == pytest.approx(x_max.mean(), rel=1e-12)
    out = tmp_path / "an"
    capsys.readouterr()
    assert main(["-q", "analyse", *map(str, paths), "-o", str(out)]) == 0
    report = (out / "report.md").read_text()
    assert "2 populations (scene, model level and, where one scene name holds several machines, the values that " \
           "tell them apart), each analysed on its own" in report
    assert "| pin_insertion L0 | 1 | 2 | 2 | 0 |" in report and "| pin_insertion L1 | 1 | 3 | 3 | 0 |" in report
    assert "| pin_insertion L0 | p1.x_max | mm | 2 |" in report and "| pin_insertion L1 | p1.x_max | mm | 3 |" in report
    rows = list(csv.DictReader((out / "recordings.csv").open()))
    assert [r["level"] for r in rows] == ["1", "0"]


def test_recordings_of_one_scene_name_but_different_machines_are_not_one_population(recordings, tmp_path):
    """A copy of the demo scene with the insertion force raised to 62 N keeps the name pin_insertion: pooled with the
    40 N runs its y_min read as one machine's σ of 6.6 N. The scenes differ beyond the run's setting (here also the
    seed and cycles, which do not count), so each machine is its own population, named by the value that differs."""
    from rig.cli import DEFAULT_SCENE
    text = DEFAULT_SCENE.read_text(encoding="utf-8")
    assert 'F_c = "40 N"' in text and "seed = 20240611" in text
    scene = tmp_path / "pin_insertion.toml"
    scene.write_text(text.replace('F_c = "40 N"', 'F_c = "62 N"').replace("seed = 20240611", "seed = 7"),
                     encoding="utf-8")
    other = tmp_path / "f62.mcap"
    assert main(["-q", "run", str(scene), "--no-report", "--cycles", "2", "-o", str(other)]) == 0
    paths = [recordings / "run3.mcap", recordings / "run2.mcap", other]
    with make_executor("serial") as ex:
        result = analyse_batch(paths, ex)
    assert [r.group for r in result.recordings] == ["pin_insertion L1 (plant.F_c = 40 N)"] * 2 + \
        ["pin_insertion L1 (plant.F_c = 62 N)"]
    assert result.combined[("pin_insertion L1 (plant.F_c = 40 N)", "p1.y_min")][0].n == 5
    assert result.combined[("pin_insertion L1 (plant.F_c = 62 N)", "p1.y_min")][0].n == 2
    report = "\n".join(report_lines(result))
    assert "Note: the recordings of pin_insertion L1 describe 2 different machines" in report
    with make_executor("serial") as ex:                     # the same machine with other seeds and lengths: one
        assert {r.group for r in analyse_batch(paths[:2], ex).recordings} == {"pin_insertion L1"}
    same = tmp_path / "same" / "pin_insertion.toml"        # the same machine with a value written in other units: one
    same.parent.mkdir()
    assert 'k = "1.89 N/mm"' in text
    same.write_text(text.replace('k = "1.89 N/mm"', 'k = "1890 N/m"'), encoding="utf-8")
    assert main(["-q", "run", str(same), "--no-report", "--cycles", "1", "-o", str(tmp_path / "si.mcap")]) == 0
    with make_executor("serial") as ex:
        groups = [r.group for r in analyse_batch([paths[0], tmp_path / "si.mcap", other], ex).recordings]
    assert groups == ["pin_insertion L1 (plant.F_c = 40 N)"] * 2 + ["pin_insertion L1 (plant.F_c = 62 N)"]


def test_copies_of_a_run_count_once_and_runs_sharing_a_seed_are_said(recordings):
    """A file copied, or cut short, is the same run (scene, seed, wall-clock start): its curves count once, in the
    copy holding most; two runs of one seed repeat one another's values, which the report says."""
    from rig.analysis.batch import report_lines
    paths = [recordings / "run3.mcap", recordings / "short.mcap", recordings / "run2.mcap",
             recordings / "sub" / "copy.mcap"]
    with make_executor("serial") as ex:
        result = analyse_batch(paths, ex)
    assert [r.copy_of for r in result.recordings] == ["", str(paths[0]), "", str(paths[2])]
    assert result.combined[("pin_insertion L1", "p1.x_max")][0].n == 5
    lines = report_lines(result)
    assert lines[2].startswith("4 read (1 incomplete), 2 of them copies of another run (counted once), 0 unreadable; 5 curves")
    assert any(line.startswith("Note: 2 runs of pin_insertion L1 were made with seed ") for line in lines)
    assert "## Copies of another run (same scene, seed and start; counted once) (2)" in lines


def test_a_folder_gives_its_recordings_whatever_the_case_of_their_extension(tmp_path):
    """``UP.MCAP`` in a folder was neither analysed nor mentioned."""
    (tmp_path / "a.mcap").write_bytes(b"x")
    (tmp_path / "UP.MCAP").write_bytes(b"x")
    (tmp_path / "notes.txt").write_bytes(b"x")
    assert sorted(p.name for p in expand([str(tmp_path)])) == ["UP.MCAP", "a.mcap"]


def test_a_file_another_program_wrote_or_a_lost_scene_does_not_stop_the_batch(recordings, tmp_path, capsys):
    """A valid MCAP without anything of rig's is an unreadable row naming why (and `rig report` refuses it); a
    recording whose scene attachment is lost or damaged is analysed (the scene's values used to raise
    AttributeError on None and stop the whole batch)."""
    from mcap.writer import Writer

    from rig.analysis.batch import machine_of
    foreign = tmp_path / "foreign.mcap"
    with open(foreign, "wb") as fh:
        w = Writer(fh)
        w.start()
        channel = w.register_channel(topic="/foo", message_encoding="json",
                                     schema_id=w.register_schema(name="x", encoding="jsonschema", data=b"{}"))
        ros = w.register_channel(topic="/chatter", message_encoding="cdr",          # a ROS 2 message
                                 schema_id=w.register_schema(name="y", encoding="ros2msg", data=b"string data"))
        for i in range(3):      # (a JSON object of numbers, or CDR, was read as a rig block: "chunk does not decode")
            w.add_message(channel, log_time=i, data=b'{"a": 1.0, "b": [1, 2]}', publish_time=i)
            w.add_message(ros, log_time=i, data=b"\x00\x01\x00\x00\x05\x00\x00\x00hell\x00", publish_time=i)
        w.finish()
    from rig.recorder import read_recording
    other = read_recording(foreign, allow_partial=True)
    assert not other.truncated and not other.problems and other.message_counts == {"/foo": 3, "/chatter": 3}
    assert machine_of(None) == {} and machine_of("[scene\nname = ") == {}
    out = tmp_path / "an"
    capsys.readouterr()
    assert main(["-q", "analyse", str(foreign), str(recordings / "run2.mcap"), "-o", str(out)]) == 0
    rows = {r["recording"].rsplit("/", 1)[1]: r for r in csv.DictReader((out / "recordings.csv").open())}
    assert rows["foreign.mcap"]["error"] == ("not a rig recording: no rig metadata, no scene and none of rig's topics "
                                             "(it holds /chatter, /foo)")
    assert rows["run2.mcap"]["curves"] == "2" and not rows["run2.mcap"]["error"]
    assert main(["-q", "report", str(foreign), "-o", str(tmp_path / "rep")]) == 2
    assert "not a rig recording" in capsys.readouterr().err and not (tmp_path / "rep").exists()
    data = bytearray((recordings / "run2.mcap").read_bytes())     # the scene attachment damaged: its machine unknown
    at = data.find(b"[scene]", data.find(b"scene.toml"))
    data[at:at + 7] = b"[[[[[[["
    (tmp_path / "lost.mcap").write_bytes(bytes(data))
    with make_executor("serial") as ex:
        result = analyse_batch([recordings / "run2.mcap", recordings / "run3.mcap", tmp_path / "lost.mcap"], ex)
    groups = [r.group for r in result.recordings]
    assert groups == ["pin_insertion L1"] * 2 + ["pin_insertion L1 (scene lost: machine unknown)"]   # the pair stays
    assert result.recordings[2].curves == 2 and not result.recordings[2].complete      # analysed for what it holds


def test_machines_are_told_apart_by_value_and_their_labels_never_merge_two():
    """Populations were keyed by a label of the first 3 differing keys: two machines differing only beyond them were
    pooled (F_c 61 N with the 40 N demo, σ 10.8 N over two modes), while the demo written in cm/kN was split off
    (list values — the elements, the limit pairs — compared as text). An audit."""
    from rig.analysis.batch import RecordingSummary, _name_variants, machine_of
    demo = machine_of('[plant]\nF_c = "40 N"\n[device.config.limits]\nx_max = ["41.5 mm", "42.5 mm"]\n')
    in_cm = machine_of('[plant]\nF_c = "0.04 kN"\n[device.config.limits]\nx_max = ["4.15 cm", "4.25 cm"]\n')
    assert demo["device.config.limits.x_max[0]"] == "'41.5 mm'"
    rows = [RecordingSummary(f"r{i}.mcap", "s", level="1", machine=m) for i, m in enumerate([demo, in_cm])]
    _name_variants(rows)
    assert rows[0].group == rows[1].group == "s L1"           # one machine, whatever the units written
    base = {"plant.F_c": "'40 N'", "device.a": "1", "device.b": "1", "device.c": "1", "device.d": "1"}
    machines = [base, {**base, "plant.F_c": "'61 N'", "device.a": "2", "device.b": "2", "device.c": "2"},
                {**base, "device.d": "2"}]                    # the third differs from the first in device.d only
    rows = [RecordingSummary(f"m{i}.mcap", "s", level="1", machine=m) for i, m in enumerate(machines)]
    _name_variants(rows)
    assert len({r.group for r in rows}) == 3
    assert rows[0].group.startswith("s L1 (plant.F_c = 40 N, device.a = 1") and "device.d = 1" in rows[0].group
    from rig.analysis.batch import unit_factor
    from rig.analysis.streaming import Moments
    import numpy as np
    assert unit_factor("cm", "mm") == pytest.approx(10.0) and unit_factor("kN", "N") == pytest.approx(1e3)
    assert unit_factor("N·m", "N·mm") == pytest.approx(1e3) and unit_factor("°", "rad") == pytest.approx(np.pi / 180)
    assert np.isnan(unit_factor("mm", "N"))
    a, b = np.array([[41.5], [42.0]]), np.array([[4.2], [4.3]])        # mm, and cm of the same machine
    merged = Moments.of_block(a).merge(Moments.of_block(b).scaled(unit_factor("cm", "mm")))
    whole = Moments.of_block(np.vstack([a, b * 10.0]))
    assert (merged.n, float(merged.mean[0]), float(merged.maximum[0])) == (4, pytest.approx(float(whole.mean[0])), 43.0)
    assert float(merged.m2[0]) == pytest.approx(float(whole.m2[0]))


def test_a_curve_recorded_without_its_result_is_counted_not_judged(tmp_path):
    """A run cut after its fourth curve but before that curve's result: 4 curves recorded, 3 judged. The row's
    ``curves`` counted the judged ones (3), while its reason said 4 were recorded — the totals undercounted."""
    import numpy as np

    from rig.analysis.batch import summarise
    from rig.recorder import Recorder
    path = tmp_path / "cut_result.mcap"
    with Recorder(path, scene_text="[scene]\nseed = 1\n", metadata={"seed": 1}, programs={1: {}}) as rec:
        for k in range(4):
            t = 1.0 + k + np.arange(0, 0.3, 1e-2)
            rec.write_curve(k + 1, 1, t, 0.04 * (t - t[0]), 50.0 * (t - t[0]))
            if k < 3:
                rec.write_result({"number": k + 1, "program": 1, "ok": k != 1, "elements": [],
                                  "process_values": {"y_max": 15.0}}, t=float(t[-1]))
    row = summarise(path)
    assert (row.curves, row.ok, row.nok) == (4, 2, 1)


def test_a_value_shown_in_two_units_gets_distinct_column_names(tmp_path):
    """A stand's speed in rpm in one recording and in rad/s in another: a column group per unit, every header once
    (the count columns had the same name twice)."""
    import numpy as np
    from rig.analysis.batch import BatchResult, RecordingSummary, write_table
    from rig.analysis.streaming import Moments
    m = Moments.of_block(np.array([[1.0], [2.0]]))
    rows = [RecordingSummary("a.mcap", "s", values={"stand.speed": (m, "rpm"), "stand.t": (m, "s")}),
            RecordingSummary("b.mcap", "s", values={"stand.speed": (m, "rad/s")})]
    with write_table(BatchResult(rows, {}), tmp_path / "t.csv").open(newline="") as f:
        header = next(csv.reader(f))
    assert len(header) == len(set(header))
    assert {"stand.speed n [rpm]", "stand.speed n [rad/s]", "stand.t n", "stand.t mean [s]"} <= set(header)


def test_curves_judged_but_not_recorded_are_counted_in_the_table(lost_curves, tmp_path):
    """A recording whose curves 2 and 4 were judged OK by the unit but lost on the way: the row counts them OK (the
    unit's verdict) and says 2 were not recorded, as the report's verdict and the console do."""
    from rig.analysis.batch import BatchResult, summarise, write_table
    row = summarise(lost_curves)
    assert (row.curves, row.ok, row.nok, row.not_recorded) == (5, 5, 0, 2)
    with write_table(BatchResult([row], {}), tmp_path / "t.csv").open(newline="") as f:
        (written,) = csv.DictReader(f)
    assert written["judged not recorded"] == "2" and written["ok"] == "5"


def test_rig_analyse_charts_each_population_per_recording_with_its_limits(recordings, tmp_path):
    """`rig analyse` draws one chart per population: each recording's values against the run's start, the mean and
    ±3σ of all and the program's limits (carried from each recording in its display unit); the report shows them."""
    import matplotlib.image as mpimg

    from rig.analysis.batch_charts import population_figure, write_charts
    paths = [recordings / "run2.mcap", recordings / "run3.mcap"]
    with make_executor("serial") as ex:
        result = analyse_batch(paths, ex)
    program = read_recording(paths[0]).programs[1]
    lsl, usl = program["limits"]["x_max"]                                   # SI in the program, mm on the chart
    assert result.recordings[0].limits["p1.x_max"] == pytest.approx((lsl * 1e3, usl * 1e3), rel=1e-12)
    assert "p1.duration" not in result.recordings[0].limits               # a value without limits has none
    charts = write_charts(result, tmp_path / "charts")
    assert [(c.group, c.path.name, c.omitted) for c in charts] == [("pin_insertion L1", "pin_insertion_L1.png", ())]
    height, width = mpimg.imread(charts[0].path).shape[:2]
    assert width > 600 and height > 600
    fig, omitted = population_figure(result, "pin_insertion L1")
    panel = next(ax for ax in fig.axes if ax.get_title(loc="left").startswith("p1.x_max:"))
    assert panel.get_title(loc="left") == "p1.x_max: n = 5 in 2 recordings" and omitted == ()
    limits = sorted(float(line.get_ydata()[0]) for line in panel.lines if line.get_color() == "tab:red")
    assert limits == pytest.approx([lsl * 1e3, usl * 1e3], rel=1e-12)
    means = sorted(float(y) for line in panel.lines if line.get_marker() == "." for y in line.get_ydata())
    assert means == pytest.approx(sorted(float(r.values["p1.x_max"][0].mean[0]) for r in result.recordings))
    out = tmp_path / "an"
    assert main(["-q", "analyse", *map(str, paths), "-o", str(out)]) == 0
    report = (out / "report.md").read_text()
    assert "![pin_insertion L1](charts/pin_insertion_L1.png)" in report and (out / "charts" / "pin_insertion_L1.png").is_file()
    (out / "charts" / "other_scene_L2.png").write_bytes(b"an earlier analysis's chart")
    assert main(["-q", "analyse", *map(str, paths), "-o", str(out)]) == 0        # the same folder again
    assert [p.name for p in (out / "charts").iterdir()] == ["pin_insertion_L1.png"]   # not another analysis's


def test_batch_chart_without_start_times_uses_the_order_given(recordings, tmp_path):
    """A recording whose metadata (and start time) was lost puts the axis in the order given, not in 1970."""
    from rig.analysis.batch_charts import _abscissa
    with make_executor("serial") as ex:
        result = analyse_batch([recordings / "run2.mcap", recordings / "run3.mcap"], ex)
    x, label = _abscissa(result.recordings)
    assert x.dtype.kind == "M" and label.startswith("run's wall-clock start")
    result.recordings[1].started = ""
    x, label = _abscissa(result.recordings)
    assert list(x) == [1, 2] and label == "recording (in the order given)"

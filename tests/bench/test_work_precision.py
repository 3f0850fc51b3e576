"""rig bench work-precision: the harness on short spans, through its public function and the CLI."""
from __future__ import annotations

import math
import csv
import re
from pathlib import Path

import pytest

from rig import cli
from rig.bench.harness import COLUMNS, METHODS, REF_CONFIRM, Row, wall_at
from rig.bench.workprecision import run_scenes

SCENES = Path(__file__).resolve().parents[2] / "data" / "scenes"
L2 = SCENES / "pin_insertion_l2.toml"
CLUTCH = SCENES / "clutch_startup.toml"
OURS = ("euler", "semi-implicit euler", "rk4", "dp45", "tsit5", "dop853", "rodas4")
PEERS = ("scipy RK45", "scipy DOP853", "scipy Radau", "scipy BDF", "scipy LSODA", "scipy odeint", "cvode",
         "scipy LSODA (no restarts)", "scipy odeint (no restarts)", "cvode (no restarts)")
REQUIRED = OURS + PEERS
STATUS = re.compile(r"^(ok|(diverged|failed|unresolved|inaccurate|timeout|skipped): \S.*)$")


def read_rows(path: Path) -> tuple[list[str], list[dict]]:
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        return header, [dict(zip(header, row)) for row in reader]


@pytest.fixture(scope="module")
def level2_run(tmp_path_factory):
    """Level 2 over its first 80 ms (dwell and the start of the rise), quick sweeps."""
    out = tmp_path_factory.mktemp("wp")
    (result,) = run_scenes([L2], out, quick=True, t_sim=0.08)
    return result, out


def test_csv_has_the_columns_every_method_and_valid_statuses(level2_run):
    _, out = level2_run
    header, rows = read_rows(out / "pin_insertion_l2.csv")
    assert tuple(header) == COLUMNS == ("method", "setting", "error", "wall_s", "nfev", "t_sim", "status")
    assert set(REQUIRED) == set(METHODS) <= {r["method"] for r in rows}
    runs = [r for r in rows if r["method"] != "reference"]
    assert all(STATUS.match(r["status"]) for r in runs), [r["status"] for r in runs if not STATUS.match(r["status"])]
    assert all(float(r["t_sim"]) == 0.08 for r in rows)
    for r in runs:
        if r["status"] == "ok":
            assert float(r["error"]) >= 0.0 and float(r["wall_s"]) > 0.0 and int(r["nfev"]) > 0


def test_reference_is_confirmed_by_two_other_methods(level2_run):
    result, out = level2_run
    _, rows = read_rows(out / "pin_insertion_l2.csv")
    ref = [r for r in rows if r["method"] == "reference"]
    assert len(ref) == 1 and ref[0]["status"] == "reference"
    assert "scipy DOP853" in ref[0]["setting"] and "rodas4" in ref[0]["setting"]
    assert set(result.reference.distances) == {"scipy DOP853 rtol=1e-12", "rodas4 rtol=1e-12"}
    assert 0.0 < float(ref[0]["error"]) == pytest.approx(result.reference.uncertainty, rel=1e-6)
    assert result.reference.uncertainty <= REF_CONFIRM


def test_dp45_error_falls_as_the_tolerance_tightens(level2_run):
    result, _ = level2_run
    dp45 = sorted(((float(r.setting.split("=")[1]), r.error) for r in result.rows if r.method == "dp45"), reverse=True)
    assert len(dp45) >= 4
    errors = [e for _, e in dp45]
    assert errors[-1] < errors[0] / 100
    assert all(b < 2 * a for a, b in zip(errors, errors[1:]))   # no step back up beyond noise


def test_every_peer_follows_the_restarts(level2_run):
    """Each peer at its tightest quick tolerance tracks the reference through the insertion-window restarts."""
    result, _ = level2_run
    for method in PEERS:
        tight = [r for r in result.rows if r.method == method and r.setting == "rtol=1e-08"]
        assert tight and tight[0].status == "ok" and tight[0].error < 1e-5, (method, tight)


def test_chart_is_written_with_every_method_that_has_ok_rows(level2_run):
    """All of them drawn and named, the peers run across the contact onsets too (two were left out when the
    methods outnumbered the colours), each variant in its sibling's colour."""
    from rig.bench.wpchart import figure
    result, out = level2_run
    assert (out / "pin_insertion_l2.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    drawn = {r.method for r in result.rows if r.status == "ok"}
    assert {"scipy odeint (no restarts)", "cvode (no restarts)"} <= drawn
    fig = figure(result)
    for ax in fig.axes:
        lines = {line.get_label(): line for line in ax.get_lines() if not line.get_label().startswith("_")}
        assert set(lines) == drawn
        assert lines["scipy odeint (no restarts)"].get_color() == lines["scipy odeint"].get_color()
        assert lines["scipy odeint (no restarts)"].get_linestyle() == ":"


def test_cli_writes_csv_and_chart_for_a_clutch_scene(tmp_path, capsys):
    out = tmp_path / "wp"
    assert cli.main(["bench", "work-precision", "--scene", str(CLUTCH), "--quick", "--t-sim", "0.05",
                     "-o", str(out)]) == 0
    text, err = capsys.readouterr()              # a progress bar over the runs, not one line per run
    assert "runs" in err and "x real time" not in err and err.count("\n") < 10, err
    header, rows = read_rows(out / "clutch_startup.csv")
    assert tuple(header) == COLUMNS
    assert {r["method"] for r in rows} >= set(REQUIRED)
    assert (out / "clutch_startup.png").read_bytes()[:4] == b"\x89PNG"
    assert "clutch_startup: reference dp45" in text and "ours best" in text
    assert "reference" not in err              # said once, on stdout with the summary (twice before: an audit)


def test_cli_refuses_a_scene_without_a_work_precision_problem(tmp_path, capsys):
    assert cli.main(["-q", "bench", "work-precision", "--scene", str(SCENES / "pin_insertion.toml"),
                     "-o", str(tmp_path)]) == 2
    assert "fidelity = 2" in capsys.readouterr().err


def test_cli_names_a_directory_given_as_the_scene(tmp_path, capsys):
    """A folder was called "does not exist" (an audit)."""
    assert cli.main(["-q", "bench", "work-precision", "--scene", str(SCENES), "--quick", "-o",
                     str(tmp_path / "o")]) == 2
    assert f"scene {SCENES} is a directory, not a scene file" in capsys.readouterr().err


def test_cli_never_overwrites_another_file(tmp_path, capsys):
    """A directory holding files rig did not write is refused before anything runs (rig's rule for output
    directories, as the other benches); in a directory rig wrote before, a foreign file of the chart's name is."""
    (tmp_path / "clutch_startup.csv").write_text("my notes\n")
    assert cli.main(["-q", "bench", "work-precision", "--scene", str(CLUTCH), "-o", str(tmp_path)]) == 2
    assert "it already holds other files" in capsys.readouterr().err
    assert (tmp_path / "clutch_startup.csv").read_text() == "my notes\n"
    (tmp_path / ".mechrig").write_text("rig's\n")
    assert cli.main(["-q", "bench", "work-precision", "--scene", str(CLUTCH), "-o", str(tmp_path)]) == 2
    assert "clutch_startup.csv" in capsys.readouterr().err
    assert (tmp_path / "clutch_startup.csv").read_text() == "my notes\n"


def test_quiet_runs_without_a_progress_bar(tmp_path, capsys, monkeypatch):
    """-q turns the bar off (the bar itself: the clutch CLI test above); the runs are not repeated for it."""
    from rig.bench import workprecision
    asked = {}
    monkeypatch.setattr(workprecision, "run_scenes", lambda *a, **k: asked.update(k) or [])
    assert cli.main(["-q", "bench", "work-precision", "--scene", str(CLUTCH), "--quick", "--t-sim", "0.05",
                     "-o", str(tmp_path / "wp")]) == 0
    assert asked["progress_bars"] is False and capsys.readouterr().err == ""
    assert cli.main(["bench", "work-precision", "--scene", str(CLUTCH), "--quick", "-o", str(tmp_path / "wp")]) == 0
    assert asked["progress_bars"] is True


def test_fixed_step_methods_follow_the_clutch_stick_slip_switches():
    """Fixed-step methods hand a mode switch the state past the root: before, on the clutch's stick–slip events
    they handed the state before it and the switch chattered (SolverDivergence, found by this benchmark)."""
    from rig.bench.harness import measure, reference
    from rig.bench.problems import load_problem
    problem = load_problem(CLUTCH, t_sim=0.2)
    ref = reference(problem)
    rk4 = measure(problem, "rk4", 2e-4, ref, repeats=1)
    euler = measure(problem, "euler", 1e-5, ref, repeats=1)
    assert rk4.status == "ok" and rk4.error < 1e-5, rk4
    assert euler.status == "ok" and euler.error < 1e-2, euler


def test_an_unconfirmed_reference_is_marked_not_charted(level2_run):
    """Confirmations that disagree: the reference row says so and errors below the disagreement are unresolved."""
    from rig.bench.harness import Reference, Result, measure, reference_row
    result, _ = level2_run
    doubtful = Reference(result.reference.y, "dp45 rtol=1e-13", {"scipy DOP853 rtol=1e-12": 1e-4}, 0.1, {})
    assert not doubtful.confirmed
    row = measure(result.problem, "dp45", 1e-8, doubtful, repeats=1)
    assert row.status.startswith("unresolved") and row.error < 1e-3
    assert reference_row(Result(result.problem, doubtful, [row])).status.startswith("reference unconfirmed")


def test_multistep_peers_may_step_across_the_contact_onsets():
    """The flank-switching case: odeint restarted at every contact onset needs more RHS calls than odeint
    stepping across them (each restart is a new start at order 1), at a like error against the reference."""
    from rig.bench.harness import _peer, reference
    from rig.bench.problems import load_problem
    problem = load_problem(SCENES / "pin_insertion_l2_flank_switch.toml")          # 0.2 s: the impacts
    ref = reference(problem)
    errors, calls = {}, {}
    for method in ("scipy odeint", "scipy odeint (no restarts)"):
        y, calls[method] = _peer(problem, method, 1e-7)
        errors[method] = problem.error(y, ref.y)
    assert calls["scipy odeint (no restarts)"] < calls["scipy odeint"]
    assert errors["scipy odeint (no restarts)"] < 1e-5 and errors["scipy odeint"] < 1e-5


def test_peers_take_a_mode_switch_due_at_the_start_of_a_segment():
    """The clutch start-up begins exactly on the stick–slip boundary (g = 0, leaving it at once): odeint
    (events from its output samples) and CVODE (its root finding ignores the initial point) must switch there as
    our driver and solve_ivp do; they used to run on in the old mode and end 0.14 rad off at every tolerance."""
    from rig.bench.harness import _peer, reference
    from rig.bench.problems import load_problem
    problem = load_problem(CLUTCH, t_sim=0.2)
    ref = reference(problem)
    for method in ("scipy odeint", "cvode"):
        y, _ = _peer(problem, method, 1e-8)
        assert problem.error(y, ref.y) < 1e-6, method


def test_a_time_limit_stops_peers_and_skips_the_finer_settings(tmp_path):
    """With a limit no run can meet (1 ns), every peer run stops at its first right-hand-side call, naming the
    limit and the time reached; our compiled run ends and is marked over the limit; each method's finer settings
    are skipped, naming the setting that ran over; nothing of it is charted as ok."""
    (result,) = run_scenes([L2], tmp_path, quick=True, t_sim=0.01, methods=("dp45", "scipy Radau"), limit=1e-9)
    for method in ("dp45", "scipy Radau"):
        rows = [r for r in result.rows if r.method == method]
        assert len(rows) >= 2
        assert rows[0].status.startswith("timeout: ") and "time limit of 1e-09 s" in rows[0].status
        assert all(r.status == f"skipped: {rows[0].setting} ran over the time limit of 1e-09 s" for r in rows[1:])
    radau = next(r for r in result.rows if r.method == "scipy Radau")
    assert "stopped after its time limit" in radau.status and "at t = 0 s" in radau.status
    _, rows = read_rows(tmp_path / "pin_insertion_l2.csv")
    assert all(STATUS.match(r["status"]) for r in rows if r["method"] != "reference")
    assert (tmp_path / "pin_insertion_l2.png").read_bytes()[:4] == b"\x89PNG"


def test_cli_rejects_a_time_limit_that_is_not_positive(tmp_path, capsys):
    assert cli.main(["-q", "bench", "work-precision", "--scene", str(CLUTCH), "--time-limit", "0",
                     "-o", str(tmp_path)]) == 2
    assert "--time-limit must be positive" in capsys.readouterr().err


def test_the_summary_compares_at_the_target_asked_for(tmp_path, capsys):
    """``--target``: the printed summary (cheapest run per method, ours against the peers) at that error."""
    run_scenes([CLUTCH], tmp_path, quick=True, t_sim=0.02, methods=("dp45", "scipy RK45"), target=1e-3)
    text = capsys.readouterr().out
    assert "cheapest run with error <= 0.001 per method" in text and "ours best (dp45" in text
    for bad in ("0", "1", "-1e-6", "nan"):
        assert cli.main(["-q", "bench", "work-precision", "--scene", str(CLUTCH), f"--target={bad}",
                         "-o", str(tmp_path / "x")]) == 2
        assert "--target must be a relative error in (0, 1)" in capsys.readouterr().err


def test_a_method_that_never_reached_the_target_says_why():
    """A peer stopped at the time limit (or skipped after it) is not just "no run reached": the line counts them."""
    from types import SimpleNamespace

    from rig.bench.harness import Result, Row, summary
    rows = [Row("dp45", "rtol 1e-6", 5e-7, 0.001, 100, 0.1, "ok"),
            Row("scipy Radau", "rtol 1e-4", 1e-4, 0.02, 50, 0.1, "ok"),
            Row("scipy Radau", "rtol 1e-6", math.nan, 0.02, None, 0.1, "timeout: stopped after 0.02 s"),
            Row("scipy Radau", "rtol 1e-8", math.nan, 0.0, None, 0.1, "skipped: a looser setting timed out")]
    lines = summary(Result(SimpleNamespace(name="p", t_sim=0.1, quantity="φ_r"), None, rows), 1e-6)
    assert lines[0] == ("p: cheapest run with error <= 1e-06 per method (error: the relative max error in φ_r against "
                        "the reference; t_sim 0.1 s):")
    radau = next(line for line in lines if "scipy Radau" in line)
    assert radau.endswith("no run reached 1e-06 (1 timeout, 1 skipped)")


MEASURED = Path(__file__).resolve().parents[2] / "data" / "work_precision"


@pytest.mark.parametrize("csv_path", sorted(MEASURED.glob("*.csv")), ids=lambda p: p.stem)
def test_a_measured_csv_reads_back_to_the_same_file(tmp_path, csv_path):
    """``read_csv`` inverts ``write_csv``: every committed sweep, read and written again, is byte for byte the same
    file (rows, statuses, the reference's label, distances and failures)."""
    from rig.bench.harness import read_csv, write_csv
    from rig.bench.problems import load_problem
    result = read_csv(csv_path, load_problem(SCENES / f"{csv_path.stem}.toml"))
    write_csv(result, tmp_path / csv_path.name)
    assert (tmp_path / csv_path.name).read_bytes() == csv_path.read_bytes()
    assert result.reference.confirmed and len(result.rows) == sum(1 for _ in csv_path.open()) - 2


def test_from_charts_an_earlier_run_at_another_target_without_measuring(level2_run, tmp_path, capsys, monkeypatch):
    """``--from DIR``: the earlier run's CSV is charted and summarised at --target; nothing is run."""
    import rig.bench.harness as harness
    result, out = level2_run
    monkeypatch.setattr(harness, "work_precision", lambda *a, **k: pytest.fail("--from must not measure"))
    again = tmp_path / "again"
    assert cli.main(["-q", "bench", "work-precision", "--scene", str(L2), "--t-sim", "0.08", "--from", str(out),
                     "--target", "1e-4", "-o", str(again)]) == 0
    text = capsys.readouterr().out
    assert f"measured earlier ({out / 'pin_insertion_l2.csv'})" in text
    assert "cheapest run with error <= 0.0001 per method" in text and "ours best (" in text
    assert (again / "pin_insertion_l2.png").read_bytes()[:4] == b"\x89PNG" and not (again / "pin_insertion_l2.csv").exists()
    from rig.bench.problems import load_problem
    # what the command charted: the times as the CSV holds them (one that rounded apart in memory failed this once)
    read = harness.read_csv(out / "pin_insertion_l2.csv", load_problem(L2, t_sim=0.08))
    assert [r.method for r in read.rows] == [r.method for r in result.rows]
    best = harness.best_runs(read.rows, 1e-4)
    assert all(f"{r.setting:16s} wall {r.wall_s * 1e3:9.2f} ms" in text for r in best.values())


def test_from_refuses_what_it_cannot_chart(level2_run, tmp_path, capsys):
    """A missing CSV, a file that is not a work-precision CSV, a span the file was not measured over, and
    options that only apply to measuring: each a one-line error naming what is wrong."""
    _, out = level2_run
    base = ["-q", "bench", "work-precision", "--scene", str(L2), "-o", str(tmp_path / "o")]
    assert cli.main(base + ["--from", str(tmp_path)]) == 2
    assert f"--from {tmp_path}: no pin_insertion_l2.csv there" in capsys.readouterr().err
    assert cli.main(base + ["--from", str(tmp_path / "nowhere")]) == 2
    assert f"--from {tmp_path / 'nowhere'}: no such directory" in capsys.readouterr().err
    assert cli.main(base + ["--from", str(out)]) == 2            # measured over 0.08 s, the scene spans 0.4 s
    assert "measured over 0.08 s, the problem pin_insertion_l2 spans 0.4 s" in capsys.readouterr().err
    assert cli.main(base + ["--from", str(out), "--t-sim", "0.08", "--quick"]) == 2
    assert "--from measures nothing" in capsys.readouterr().err
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "pin_insertion_l2.csv").write_text("a,b\n1,2\n")
    assert cli.main(base + ["--from", str(foreign)]) == 2
    assert "not a work-precision CSV" in capsys.readouterr().err
    (foreign / "pin_insertion_l2.csv").write_text(",".join(COLUMNS) + "\nreference,x vs y: 1e-12,1e-12,0.1,,0.4,"
                                                  "reference\ndp45,rtol=1e-6,not-a-number?,0.1,5,0.4,ok\n")
    assert cli.main(base + ["--from", str(foreign)]) == 2
    assert f"{foreign / 'pin_insertion_l2.csv'} line 3: could not convert" in capsys.readouterr().err


def test_the_warm_up_takes_every_path_the_measured_runs_take(monkeypatch):
    """Each method once over the whole span at its coarsest quick setting (a short span missed the event and restart
    paths: with a cold numba cache the first euler row timed its compilation, 1.97 s for 0.04 s)."""
    from rig.bench import harness
    from rig.bench.problems import load_problem
    problem = load_problem(Path(__file__).resolve().parents[2] / "data" / "scenes" / "pin_insertion_l2.toml")
    calls = []
    monkeypatch.setattr(harness, "runner", lambda p, method, value, t_end=None, limit=None:
                        (lambda: calls.append((method, value, t_end))))
    harness.warm_up(problem, ("euler", "rk4", "dp45", "scipy Radau"))
    assert calls == [("euler", problem.quick.steps["euler"][0], None), ("rk4", problem.quick.steps["rk4"][0], None),
                     ("dp45", max(problem.quick.tols), None), ("scipy Radau", max(problem.quick.tols), None)]


def test_a_peer_may_not_step_across_restarts_that_re_select_the_mode():
    """The clutch's phase-boundary restarts re-select the cam segment a tappet holds (the problem's reset):
    "(no restarts)" peers that stepped across them solved another equation (error 1.2e-2 at every tolerance) and
    their rows said ok. They are refused, naming why."""
    from rig.bench.harness import _peer
    from rig.bench.problems import load_problem
    problem = load_problem(SCENES / "clutch_startup.toml", t_sim=0.05)
    with pytest.raises(RuntimeError, match=r"scipy odeint \(no restarts\) does not apply: this problem's restarts "
                                           r"re-select its mode"):
        _peer(problem, "scipy odeint (no restarts)", 1e-6)
    y, _ = _peer(problem, "scipy odeint", 1e-6)                  # with the restarts it runs
    assert y.shape[1] == problem.grid.size


def test_odeint_sees_the_events_through_the_compiled_event_kernel_as_through_python():
    """odeint has no root finding: its events are read at the output times. They are evaluated by the problem's
    compiled event kernel (as our solvers evaluate them), not a Python call per output time (5 of odeint's 14 ms on
    level 2), with the same crossings, hence the same states and calls."""
    import numpy as np

    import rig.bench.peers as peers
    from rig.bench.harness import _peer
    from rig.bench.problems import load_problem
    problem = load_problem(SCENES / "pin_insertion_l2_flank_switch.toml", t_sim=0.1)
    compiled = _peer(problem, "scipy odeint", 1e-7)
    python = peers._odeint_backend

    def without(*args, sampled=None):
        return python(*args)
    peers._odeint_backend = without
    try:
        plain = _peer(problem, "scipy odeint", 1e-7)
    finally:
        peers._odeint_backend = python
    assert compiled[1] == plain[1] and np.array_equal(compiled[0], plain[0])


def test_the_wall_time_at_equal_error_is_interpolated_on_the_pareto_front():
    """odeint-like rows (error, wall): the run at 2.4e-6 costs more than the more accurate one at 1.03e-6 (off the front),
    the target 1e-6 lies between 1.43e-7 and 1.03e-6: log–log interpolation there; a method with every run more
    accurate than the target gets its cheapest; one that never reaches it none."""
    def rows(points, method="m"):
        return [Row(method, f"rtol={i}", e, w, None, 0.4, "ok") for i, (e, w) in enumerate(points)]
    odeint = rows([(4.05e-5, 10.06e-3), (6.78e-6, 13.34e-3), (2.43e-6, 17.16e-3), (1.027e-6, 15.0e-3),
                   (1.43e-7, 17.57e-3)])
    f = math.log(1e-6 / 1.43e-7) / math.log(1.027e-6 / 1.43e-7)
    assert wall_at(odeint, "m", 1e-6) == pytest.approx(17.57e-3 * (15.0e-3 / 17.57e-3) ** f, rel=1e-12)
    assert 15.0e-3 < wall_at(odeint, "m", 1e-6) < 15.1e-3
    assert wall_at(rows([(1e-8, 3e-3), (1e-7, 2e-3)]), "m", 1e-6) == 2e-3
    assert wall_at(rows([(1e-5, 3e-3)]), "m", 1e-6) is None
    assert wall_at(odeint + [Row("m", "x", 1e-9, 1e-3, None, 0.4, "diverged: ...")], "m", 1e-6) == wall_at(odeint, "m")

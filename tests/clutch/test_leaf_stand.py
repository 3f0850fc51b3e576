"""The leaf-spring coupling on the dynamic stand (issue 14; MODELS §4.4-4.5): its dynamics, the start-up scene in the
printed units and the thesis-against-rig comparison (comparison.csv)."""
import csv
import math
import re
from pathlib import Path

import numpy as np
import pytest

from rig.analysis.clutch_metrics import Metric, Stimulus
from rig.analysis.report import write_report
from rig.analysis.stand_comparison import compare
from rig.plants.clutch.leaf_dynamics import LeafDynamics
from rig.plants.clutch.loads import LinearMotor, LoadSum, constant
from rig.plants.clutch.variants import LeafSpringClutch
from rig.runner import run_scene
from rig.scene import SceneError, load_scene
from rig.solvers import integrate

SCENES = Path(__file__).resolve().parents[2] / "data" / "scenes"
LEAF = dict(width=0.02, thickness=0.002, span=0.12, r0=0.03, r1=0.05, a1=0.02, n=4, apex=math.radians(45.0))


def test_coupling_is_the_static_leaf_characteristic_periodic_over_the_disengagement_angle():
    leaf = LeafSpringClutch(**LEAF, mu=0.1)
    dyn = LeafDynamics(leaf, LinearMotor(0.0, 0.0), LoadSum([constant(0.0)]), 0.01, 0.005, omega_s=1e-3)
    phi = np.radians([5.0, 20.0, 44.0])
    for p in phi:
        assert dyn.coupling(p, 1.0)[0] == pytest.approx(float(leaf.torque(p, 1.0)), rel=1e-9)   # slipping forward
        assert dyn.coupling(p, -1.0)[0] == pytest.approx(float(leaf.torque(p, -1.0)), rel=1e-9)
        assert dyn.coupling(p + 2 * leaf.apex, 1.0)[0] == pytest.approx(dyn.coupling(p, 1.0)[0], rel=1e-9)
    below, above = dyn.coupling(leaf.apex - 1e-9, 1.0)[0], dyn.coupling(leaf.apex + 1e-9, 1.0)[0]
    assert below > 20.0 and above < -20.0                # the lobe slides off the leaf: the next leaf pushes on


def test_frictionless_free_coupling_conserves_energy_and_disengages():
    """No motor, no load, μ = 0: ½J1ω1² + ½J3ω3² + V(φr) stays constant; started fast enough the halves pass the
    disengagement angle (apex events), started slowly they oscillate."""
    leaf = LeafSpringClutch(**LEAF, mu=0.0)
    dyn = LeafDynamics(leaf, LinearMotor(0.0, 0.0), LoadSum([constant(0.0)]), 0.01, 0.005)
    grid = np.linspace(0.0, leaf.apex, 20001)
    energy_0 = np.concatenate([[0.0], np.cumsum(np.diff(grid) * 0.5 * (leaf.torque(grid[1:], 0) +
                                                                        leaf.torque(grid[:-1], 0)))])

    def energy(y):
        w1 = y[1] + y[3]
        reduced = y[0] - leaf.period * np.round(y[0] / leaf.period)       # φ_r into (−φ_d, φ_d]
        return 0.5 * 0.01 * w1 ** 2 + 0.5 * 0.005 * y[3] ** 2 + np.interp(abs(reduced), grid, energy_0)

    for omega_r, passes in ((5.0, False), (100.0, True)):     # V(φ_d) ≈ 7 J against ½·J_eff·ω_r²
        hits = []
        y0 = (0.0, omega_r, 0.0, 0.0)
        sol = integrate(dyn.problem(y0, lambda rec: hits.append(rec.t) or False), (0.0, 0.3), rtol=1e-10,
                        atol=1e-12)
        e = np.array([energy(y) for y in sol.y.T])
        assert np.max(np.abs(e - e[0])) < 1e-5 * e[0]
        assert bool(hits) == passes


def test_the_compiled_leaf_stand_is_the_2_dof_model_and_runs_with_the_peers():
    """The compiled right-hand side equals J1 ω̇1 = M1 − T_c, J3 ω̇3 = T_c − M3 written out from the leaf's closed form
    and the motor line; the outputs are the same quantities; scipy's RK45 on the same kernel (a work–precision peer)
    and our compiled DP45 agree; a stick–slip brake, which this smooth model cannot hold, is refused by name."""
    from rig.bench.harness import runner
    from rig.bench.problems import load_problem
    from rig.plants.clutch.loads import ShoeBrake
    leaf = LeafSpringClutch(**LEAF, mu=0.1)
    motor = LinearMotor(20.0, 0.1)
    dyn = LeafDynamics(leaf, motor, LoadSum([constant(3.0)]), 0.01, 0.005, J_down=0.002, omega_s=0.5)
    y = (0.3, 2.0, 1.0, 40.0)
    tc = float(leaf.factor * leaf.n * leaf.leaf_force(0.3) * (leaf.a1 * math.sin(0.3) + 0.1 * (leaf.r1 - leaf.a1 * math.cos(0.3))
                                                               * math.tanh(2.0 / 0.5)))
    a1, a3 = (motor.torque(0.1, 42.0) - tc) / 0.01, (tc - 3.0) / 0.005
    assert dyn.rhs(0.1, y) == pytest.approx((2.0, a1 - a3, 40.0, a3), rel=1e-12)
    out = dyn.outputs(np.array([0.1]), np.array(y)[:, None])
    assert (out["T_c"][0], out["M1"][0], out["M3"][0]) == pytest.approx((tc, motor.torque(0.1, 42.0), 3.0), rel=1e-12)
    assert out["M_t"][0] == pytest.approx(3.0 + 0.002 * a3, rel=1e-12)
    problem = load_problem(SCENES / "clutch_leaf_startup.toml", t_sim=0.1)
    ours, peer = runner(problem, "dp45", 1e-9)()[0], runner(problem, "scipy RK45", 1e-9)()[0]
    assert problem.error(ours, peer) < 1e-6 and np.ptp(ours[0]) > 0.1           # φ_r moves through the start-up
    with pytest.raises(ValueError, match='smooth ODE: its brake needs friction = "tanh"'):
        LeafDynamics(leaf, motor, LoadSum([ShoeBrake(0.01, 0.01, 100.0, friction="stick_slip")]), 0.01, 0.005)


def test_leaf_startup_scene_writes_the_comparison(tmp_path):
    out = tmp_path / "leaf.mcap"
    run_scene(SCENES / "clutch_leaf_startup.toml", out)
    write_report(out, tmp_path / "report")
    with open(tmp_path / "report" / "comparison.csv", encoding="utf-8") as f:
        rows = {r["quantity"]: r for r in csv.DictReader(f)}
    assert list(next(iter(rows.values())))[:4] == ["quantity", "unit", "thesis", "rig"]
    peak, when, settle = (rows[k] for k in ("start-up peak torque", "time of the start-up peak",
                                            "settled at the load torque within"))
    assert (peak["unit"], peak["thesis"], when["unit"]) == ("N*m", "14.5", "ms")
    assert float(peak["rig"]) == pytest.approx(14.5, rel=0.15)
    assert float(when["rig"]) == pytest.approx(46.6, rel=0.20)
    assert 0.0 < float(settle["rig"]) <= 450.0
    assert rows["disengagements"]["rig"] == "0" and peak["fitted"] == "1" and settle["fitted"] == "1"
    assert [r["basis"] for r in rows.values()] == ["fitted"] * 4 + ["input"]    # the final torque is the load set
    # the number columns parse as numbers (deviation was text such as "+0.035 N·m (+0.241 %)")
    for r in rows.values():
        assert all(r[k] == "" or math.isfinite(float(r[k])) for k in ("thesis", "rig", "rig beyond", "deviation",
                                                                        "deviation [%]"))
        if r["rig"]:
            assert float(r["deviation"]) == pytest.approx(float(r["rig"]) - float(r["thesis"]),   # rig: 6 digits
                                                          abs=1e-5 * abs(float(r["rig"])) + 1e-9)
    assert float(peak["deviation [%]"]) == pytest.approx(100 * (float(peak["rig"]) / 14.5 - 1), rel=1e-3)
    assert rows["disengagements"]["deviation [%]"] == ""                          # a count: no share
    assert [r["agrees"] for r in rows.values()] == ["yes"] * 5          # 15 %, 20 %, at most, exact count, 5 %
    assert "Thesis against rig" in (tmp_path / "report" / "report.html").read_text(encoding="utf-8")


def test_the_settling_time_does_not_depend_on_how_long_the_run_goes_on(tmp_path):
    """The 0.8 s start-up ends while the stand still creeps to its speed (time constant J/b ≈ 0.19 s): the band
    around the record's last 50 ms once gave another time than at 2 s. The band is the scene's load where the record's
    end lies within it: the same settling time at any length, and for any seed the plant's own within a few ms."""
    from rig.analysis.clutch_metrics import step_metrics
    from rig.analysis.clutch_report import stand_results
    from rig.recorder import read_recording
    times = {}
    for duration, seed in (("0.8 s", 1), ("2 s", 1), ("0.8 s", 2), ("0.8 s", 4)):
        scene = tmp_path / f"leaf_{duration[0]}_{seed}.toml"
        text = (SCENES / "clutch_leaf_startup.toml").read_text(encoding="utf-8")
        assert 'duration = "0.8 s"' in text and "\nseed = 1\n" in text
        scene.write_text(text.replace('duration = "0.8 s"', f'duration = "{duration}"')
                         .replace("\nseed = 1\n", f"\nseed = {seed}\n"), encoding="utf-8")
        out = tmp_path / f"leaf_{duration[0]}_{seed}.mcap"
        run_scene(scene, out)
        rec = read_recording(out, can_frames=False)
        metric = next(m for m in stand_results(rec)[1] if m.name == "start-up: settling time")
        assert "of the scene's load 5 N·m (the record ends at " in metric.reference
        times[duration, seed] = metric.value
        truth = rec.series["/plant/truth"]
        plant = step_metrics(truth["t"], truth["M_t"], band=0.05, initial=0.0, final=5.0, t_step=0.0, dwell=0.05)
        # the torque meter fits the stand (50 N·m range): its offset and noise move the time a few ms, not the
        # 100-380 ms the 500 N·m meter's did (434 ms for seed 1, 708 ms or "not settled" for others; truth 328 ms)
        assert metric.value == pytest.approx(float(plant.settling_time), abs=0.015)
    assert times["0.8 s", 1] == pytest.approx(times["2 s", 1], abs=1e-4) and times["2 s", 1] < 0.45


def test_comparison_rows_name_what_is_missing_and_refuse_bad_rows(tmp_path):
    scene_path = tmp_path / "s.toml"
    scene_path.write_text('[[comparison]]\nquantity = "stop time"\nthesis = "150 ms"\nrig = "stop at 0.3 s: standstill"\n'
                          'part = "time_after"\n\n[[comparison]]\nquantity = "peak"\nthesis = "16.5 N*m"\n'
                          'rig = "max torque"\n')
    stim = [Stimulus(0.3, "stop", "motor off")]
    metrics = [Metric("stop at 0.3 s: standstill", 0.2, "s", "", 0.5), Metric("max torque", 18.0, "N·m", "", 0.1)]
    rows = compare(load_scene(scene_path), stim, metrics)
    assert rows[0].rig == pytest.approx(200.0) and rows[1].rig == pytest.approx(18.0)
    assert compare(load_scene(scene_path), stim, metrics[1:])[0].rig is None
    scene_path.write_text('[[comparison]]\nquantity = "x"\nthesis = "3 furlongs"\nrig = "max torque"\n')
    with pytest.raises(SceneError, match="furlongs"):
        compare(load_scene(scene_path), stim, metrics)


@pytest.mark.parametrize("name", ["clutch_leaf_shock_short", "clutch_leaf_overload_hold", "clutch_leaf_stop"])
def test_prediction_scenes_use_the_start_up_fit_and_fit_nothing(name):
    from rig.plants.clutch.stand import ClutchStand
    scene, startup = load_scene(SCENES / f"{name}.toml"), load_scene(SCENES / "clutch_leaf_startup.toml")
    assert scene.data["plant"]["leaf"] == startup.data["plant"]["leaf"]
    for key in ("J1", "J3", "J_down"):
        assert scene.data["plant"][key] == startup.data["plant"][key]
    assert {k: scene.data["motor"][k] for k in ("a0", "b0")} == {k: startup.data["motor"][k] for k in ("a0", "b0")}
    assert not any(row["fitted"] for row in scene.data["comparison"])
    assert isinstance(ClutchStand.from_scene(scene).dynamics, LeafDynamics)


def test_held_overload_as_the_source_applies_it_does_not_disengage_a_step_does(tmp_path):
    """The 18.75 N·m shock "applied over 127 ms, held 93 ms" (the scene: actuator τ = 42 ms, 220 ms): the assumed
    leaves carry it, no disengagement, and the comparison says the prediction fails; applied as a step (τ = 5 ms,
    93 ms) the same model disengages repeatedly and calls for shutdown — the thesis's result needs the faster shock."""
    out = tmp_path / "hold.mcap"
    run_scene(SCENES / "clutch_leaf_overload_hold.toml", out)
    write_report(out, tmp_path / "report")
    with open(tmp_path / "report" / "comparison.csv", encoding="utf-8") as f:
        rows = {r["quantity"]: r for r in csv.DictReader(f)}
    assert rows["disengagements"]["rig"] == "0" and rows["disengagements"]["agrees"] == "NO"
    assert rows["shutdown"]["rig"] == "0" and rows["shutdown"]["agrees"] == "NO"
    html = (tmp_path / "report" / "report.html").read_text()      # the banner: red, a headline; under it what
    (banner,) = re.findall(r"<div class='banner (\w+)'>Clutch stand: ([^<]*)</div>", html)    # disagrees
    assert banner[0] == "nok" and banner[1].endswith("thesis against rig: 0 of 2 predictions agree with the thesis")
    (details,) = re.findall(r"</div>\s*<p class='warning'>Thesis against rig: ([^<]*)</p>", html)
    assert details.startswith("DISAGREE: disengagements (thesis") and "shutdown (thesis" in details
    # the stand is still running up to speed when the record ends (ω1 44.9 → 52.7 rad/s in its last 50 ms): no final
    # speed, and the words say why (a mean over the ramp was reported as the final speed before)
    from rig.analysis.clutch_report import stand_results
    from rig.recorder import read_recording
    final = {m.name: m for m in stand_results(read_recording(out))[1] if m.name.startswith("final speed")}
    assert set(final) == {"final speed ω1", "final speed ω3"}
    assert all(m.value is None and "still speeding up at the end of the run" in m.reference for m in final.values())
    text = (SCENES / "clutch_leaf_overload_hold.toml").read_text()
    step = tmp_path / "step.toml"
    step.write_text(text.replace('tau = "42 ms"', 'tau = "5 ms"', 1).replace('pulse_duration = "220 ms"',
                                                                             'pulse_duration = "93 ms"', 1))
    run_scene(step, tmp_path / "step.mcap")
    write_report(tmp_path / "step.mcap", tmp_path / "step_report")
    with open(tmp_path / "step_report" / "comparison.csv", encoding="utf-8") as f:
        rows = {r["quantity"]: r for r in csv.DictReader(f)}
    assert float(rows["disengagements"]["rig"]) >= 2 and rows["shutdown"]["rig"] == "1"


def test_agreement_is_judged_by_each_rows_tolerance(tmp_path):
    """"15 %", a value in the thesis's unit, "at most"/"at least" bounds; a count without tolerance exactly; other
    rows without one are not judged; a bad tolerance is a scene error naming it."""
    from rig.analysis.stand_comparison import agreement_text
    scene_path = tmp_path / "s.toml"
    rows = [("peak", "16.5 N*m", "max torque", "15 %"), ("late", "150 ms", "stop at 0.3 s: standstill", "40 ms"),
            ("within", "150 ms", "stop at 0.3 s: standstill", "at most"), ("n", "2", "disengagements", None),
            ("loose", "10 N*m", "max torque", None)]
    scene_path.write_text("".join(f'[[comparison]]\nquantity = "{q}"\nthesis = "{t}"\nrig = "{r}"\npart = '
                                  f'"{"time_after" if "stop" in r else "value"}"\n'
                                  + (f'tolerance = "{tol}"\n' if tol else "") + "\n" for q, t, r, tol in rows))
    stim = [Stimulus(0.3, "stop", "motor off")]
    metrics = [Metric("stop at 0.3 s: standstill", 0.2, "s", "", 0.48), Metric("max torque", 18.0, "N·m", "", 0.1),
               Metric("disengagements", "3", "", "")]
    got = compare(load_scene(scene_path), stim, metrics)
    assert [r.verdict for r in got] == ["yes", "yes", "NO", "NO", "-"]       # 18 vs 16.5 ± 2.5; 180 vs 150 ± 40
    assert agreement_text(got).startswith("2 of 4 predictions agree with the thesis; DISAGREE: within (thesis 150 ms")
    assert [r.tolerance for r in got] == ["15 %", "40 ms", "at most", "exact", ""]
    assert (got[0].deviation, got[3].deviation) == ("+1.5 N·m (+9.09 %)", "+1")
    # a value that follows a disengagement is not judged in a run without one (another event), and says so
    follows = '[[comparison]]\nquantity = "p"\nthesis = "16.5 N*m"\nrig = "max torque"\ntolerance = "15 %"\n'
    for count, verdict in (("0", "n/a"), ("2", "yes")):
        scene_path.write_text(follows + 'after = "disengagements"\n')
        row, = compare(load_scene(scene_path), stim, metrics[:2] + [Metric("disengagements", count, "", "")])
        assert row.verdict == verdict
    assert row.why == "" and "follows disengagements, and this run has none: another event, not judged" in compare(
        load_scene(scene_path), stim, metrics[:2])[0].why
    scene_path.write_text('[[comparison]]\nquantity = "x"\nthesis = "16.5 N*m"\nrig = "max torque"\ntolerance = "3 N"\n')
    with pytest.raises(SceneError, match="tolerance '3 N'"):
        compare(load_scene(scene_path), stim, metrics)


def test_thesis_values_are_placed_on_the_torque_chart():
    """The start-up's thesis values: the peak as a point at its time, the settling limit as a time, the final torque as
    a level (SI: s, N·m)."""
    from rig.analysis.stand_comparison import thesis_marks
    marks = thesis_marks(load_scene(SCENES / "clutch_leaf_startup.toml"), [Stimulus(0.0, "start", "power on")])
    got = {m.kind: m for m in marks}
    assert sorted(m.kind for m in marks) == ["level", "point", "time"]
    assert (got["point"].t, got["point"].torque) == (pytest.approx(0.0466), pytest.approx(14.5))
    assert got["time"].t == pytest.approx(0.45) and got["level"].torque == pytest.approx(5.0)
    assert got["point"].label == "thesis: start-up peak torque 14.5 N·m at 46.6 ms"


def test_a_result_the_run_ended_before_and_a_slip_without_disengagement_are_judged(tmp_path):
    """A stop the run ended before, already past an "at most" bound, disagrees (not n/a); a run without
    disengagement has no "relative slip" but its net relative angle change is the value to judge."""
    from rig.analysis.stand_comparison import agreement_text
    scene_path = tmp_path / "s.toml"
    scene_path.write_text('[[comparison]]\nquantity = "stopped"\nthesis = "150 ms"\nrig = "stop at 0.5 s: standstill"\n'
                          'tolerance = "at most"\n\n[[comparison]]\nquantity = "slip"\nthesis = "360 deg"\n'
                          'rig = "relative slip"\ntolerance = "at least"\n')
    metrics = [Metric("stop at 0.5 s: standstill", None, "s", "still turning", exceeds=0.4),
               Metric("relative angle change", -7.0, "°", "no disengagement")]
    stopped, slip = compare(load_scene(scene_path), [Stimulus(0.5, "stop", "motor off")], metrics)
    assert (stopped.rig, stopped.beyond, stopped.agrees, stopped.verdict) == (None, pytest.approx(400.0), False, "NO")
    assert stopped.rig_text() == "> 400"
    assert (slip.rig, slip.agrees) == (pytest.approx(-7.0), False)
    assert agreement_text([stopped, slip]) == ("0 of 2 predictions agree with the thesis; DISAGREE: stopped (thesis "
                                               "150 ms, rig > 400 ms); slip (thesis 360°, rig -7°)")
    from rig.analysis.stand_comparison import write_csv

    written = list(csv.DictReader(write_csv([stopped, slip], tmp_path / "c.csv").open()))
    assert [(r["rig"], r["rig beyond"]) for r in written] == [("", "400"), ("-7", "")]   # the bound passed, a number
    short = Metric("stop at 0.5 s: standstill", None, "s", "still turning", exceeds=0.1)    # ended before the bound
    assert compare(load_scene(scene_path), [Stimulus(0.5, "stop", "motor off")], [short])[0].verdict == "n/a"


def test_rows_set_by_the_scene_are_not_counted_as_predictions():
    """A row whose rig value follows from what the scene sets (the brake load as the final torque) is shown apart:
    "3 of 3 predictions agree" for a start-up whose parameters were fitted on that very test overstated it."""
    from rig.analysis.stand_comparison import Row, agreement_text
    fitted = Row("peak", "N*m", 14.5, 14.56, True, "", True, "15 %")
    load = Row("final torque", "N*m", 5.0, 5.04, False, "", True, "5 %", input=True)
    predicted = Row("stop", "ms", 150.0, 120.0, False, "", True, "at most")
    assert load.basis == "input" and fitted.basis == "fitted" and predicted.basis == "predicted"
    assert agreement_text([fitted, load, predicted]) == (
        "1 of 1 predictions agree with the thesis; 1 of 1 rows fitted on this run reproduced; 1 row set by the "
        "scene's inputs, shown as set (no check of the model)")
    assert agreement_text([fitted, load]).startswith("1 of 1 rows fitted")


def test_a_comparison_of_inputs_only_says_first_that_it_checks_nothing_of_the_model():
    """clutch_shock_short: its one row is set by its input (the shock size chosen for the regime); the line read
    "1 of 1 rows set by the scene's inputs (no check of the model) as set"."""
    from dataclasses import replace

    from rig.analysis.stand_comparison import Row, agreement_text
    one = Row("disengagements", "", 0.0, 0.0, False, "", True, "exact", input=True)
    assert agreement_text([one]) == ("no check of the model here — its 1 row is set by the scene's inputs, shown as "
                                     "set")
    other = replace(one, quantity="final torque", rig=1.0, agrees=False)
    assert agreement_text([one, other]).startswith("no check of the model here — its 2 rows are set by the scene's "
                                                   "inputs, 1 of them shown as set; DISAGREE: final torque")
    assert agreement_text([other]).startswith("no check of the model here — its 1 row is set by the scene's inputs, "
                                              "not shown as set")
    assert agreement_text([replace(one, agrees=None)]) == "no row judged (no tolerances)"
    missing = replace(one, quantity="steady speed", rig=None, agrees=None, why="no result 'nope' in this run")
    assert agreement_text([missing]) == ("no row judged (no row has a value in this run); n/a in this run: steady "
                                         "speed (no result 'nope' in this run)")     # a misspelt rig = "…" (an audit)


def test_comparison_units_are_written_as_the_console_writes_them():
    from rig.analysis.stand_comparison import Row, agreement_text
    slip = Row("relative slip", "deg", 360.0, -7.119, False, "", agrees=False, tolerance="at least")
    shock = Row("peak", "N*m", 16.5, 30.7, False, "", agrees=False, tolerance="15 %")
    assert slip.deviation == "-367° (-102 %)" and shock.deviation == "+14.2 N·m (+86.1 %)"
    assert "relative slip (thesis 360°, rig -7.119°); peak (thesis 16.5 N·m, rig 30.7 N·m)" in agreement_text([slip, shock])


def test_a_stand_that_settles_into_stiffness_switches_to_the_implicit_method_and_says_so(tmp_path):
    """The start-up's DP45 (its method on the 0.8 s span) meets stiffness once the stand settles (≈ 1.9 s into a
    2.5 s run): the run printed a StiffnessWarning and went on stability-limited. Now it switches to Rodas4 after that
    chunk, records a method_switch event with the reason, warns nothing, and its torque agrees with a run on Rodas4
    from the start."""
    import warnings

    from rig.recorder import read_recording
    from rig.solvers import StiffnessWarning
    text = (SCENES / "clutch_leaf_startup.toml").read_text(encoding="utf-8").replace('duration = "0.8 s"',
                                                                                    'duration = "2.5 s"')
    assert "[plant]\n" in text and "method =" not in text
    torque = {}
    for method in ("DP45", "Rodas4"):
        path = tmp_path / f"{method}.toml"
        path.write_text(text.replace("[plant]\n", f'[plant]\nmethod = "{method}"\n', 1), encoding="utf-8")
        with warnings.catch_warnings():
            warnings.simplefilter("error", StiffnessWarning)
            run_scene(path, tmp_path / f"{method}.mcap")
        rec = read_recording(tmp_path / f"{method}.mcap", can_frames=False)
        switches = [e for e in rec.events if e.get("kind") == "method_switch"]
        assert len(switches) == (1 if method == "DP45" else 0)
        if switches:
            assert 1.0 < switches[0]["t"] < 2.5 and switches[0]["from"] == "DP45" and switches[0]["to"] == "Rodas4"
            assert "stiff" in switches[0]["why"]
        torque[method] = rec.series["/plant/truth"]["T_c"]
    assert np.allclose(torque["DP45"], torque["Rodas4"], rtol=1e-4, atol=1e-4 * np.abs(torque["Rodas4"]).max())


def test_a_motor_that_cannot_turn_the_brake_is_said_and_its_creep_explained(tmp_path, capsys):
    """Stall torque 3 N·m against a 5 N·m shoe brake: the stand cannot start. The regularised (tanh) brake lets it creep
    at ω_s·atanh(3/5) — the model's, not the stand's — and the run says so (an event, a console warning); the fitted
    motor (15 N·m) starts without one."""
    from rig.cli import main
    from rig.recorder import read_recording
    from rig.plants.clutch.stand import ClutchStand
    weak = tmp_path / "weak.toml"
    weak.write_text(re.sub(r'(?m)^a0 = .*$', 'a0 = "3 N*m"', (SCENES / "clutch_leaf_startup.toml").read_text()))
    assert main(["-q", "run", str(weak), "-o", str(tmp_path / "weak.mcap"), "--no-report"]) == 0
    said = capsys.readouterr().out
    creep = 0.5 * math.atanh(3.0 / 5.0)
    assert "stall torque 3 N·m is below the 5 N·m the brake holds at rest: the stand cannot start" in said
    assert f"creep at {creep:.3g} rad/s" in said
    events = [e for e in read_recording(tmp_path / "weak.mcap").events if e["kind"] == "motor_below_load"]
    assert len(events) == 1 and events[0]["creep_speed"] == pytest.approx(creep)
    final = re.search(r"final speed ω3\s+([\d.]+) rad/s", said)
    assert final and float(final.group(1)) == pytest.approx(creep, rel=0.05)      # what the model does: the creep
    fitted = ClutchStand.from_scene(load_scene(SCENES / "clutch_leaf_startup.toml"))
    assert not [e for e in fitted.events if e.kind == "motor_below_load"]

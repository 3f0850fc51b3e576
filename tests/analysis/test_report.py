"""Report from a synthetic recording: HTML and Markdown, PNG plots, CSV export, extension sections."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from rig.analysis import report
from rig.analysis.report import Heading, Text, write_report
from rig.analysis.summary import analyse
from rig.recorder import Recorder, read_recording

OMEGA = 2 * np.pi * 2.5
PROGRAM = {"elements": [
    {"kind": "window", "name": "W1", "x_min": 0.030, "x_max": 0.042, "y_min": 20.0, "y_max": 60.0,
     "entry": "left", "exit": "top"},
    {"kind": "trapezoid", "name": "T1", "axis": "y", "start": 0.0, "end": 0.02, "lower": [-5.0, -5.0],
     "upper": [10.0, 20.0], "entry": "left", "exit": "right"},
    {"kind": "threshold", "name": "S1", "axis": "y", "value": 30.0, "direction": "rising"},
    {"kind": "envelope", "name": "E1", "references": [{"x": [0.0, 0.02, 0.042], "y": [0.0, 5.0, 40.0]}],
     "dx": 0.001, "dy": 5.0},
    {"kind": "hologram", "name": "H1"}],
    "limits": {"y_max": [35.0, 50.0], "x_at_y_max": [None, 0.045]}}


def synthetic(path, n_curves=60):
    rng = np.random.default_rng(11)
    with Recorder(path, scene_text="[scene]\nseed = 11\n", metadata={"seed": 11}, programs={1: PROGRAM}) as rec:
        t = np.arange(0, 0.5, 1e-3)
        rec.write_truth(t, {"s": 0.042 * np.sin(OMEGA * t) ** 2, "F": 40 * np.sin(OMEGA * t)})
        for k in range(n_curves):
            t0 = 1.0 + 0.4 * k
            t = t0 + np.arange(0, 0.3, 2e-3)
            u = (t - t0) / 0.3
            peak = rng.normal(42, 1.5)
            x = 0.042 * u
            y_th = peak * u ** 3
            y = peak * np.clip(u - 0.05, 0, None) ** 3
            rec.write_curve(k + 1, 1, t, x, y, theory={"y": y_th, "angle": OMEGA * (t - t0)}, angle=OMEGA * (t - t0))
            ok = k % 15 != 0
            rec.write_result({"number": k + 1, "program": 1, "ok": ok,
                              "elements": [{"name": "W1", "kind": "window", "ok": ok,
                                            "reason": None if ok else "left through right"}],
                              "process_values": {"y_max": float(y.max()), "x_at_y_max": float(x[np.argmax(y)])}},
                             t=float(t[-1]))
            rec.write_event(float(t[0]), "flank", flank="rise")
        rec.write_event(5.0, "sequence_gap", missing=3)
        rec.write_statistics({"count": n_curves})


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "synthetic.mcap"
    synthetic(path)
    return read_recording(path)


def test_analysis_of_recording(recording):
    a = analyse(recording)
    assert sum(not v["ok"] for v in a["verdicts"]) == 4 and a["verdicts"][0]["failed"][0]["name"] == "W1"
    s = a["sets"][1]
    assert s["n"] == 60 and s["nok_by_element"] == {"W1": 4} and s["warnings"] == []
    y = np.array([r["process_values"]["y_max"] for r in recording.results])
    assert s["values"]["y_max"]["cp"] == pytest.approx(15 / (6 * y.std(ddof=1)))
    assert a["events"] == {"flank": 60, "sequence_gap": 1}
    lag = a["theory"][0]
    assert lag["signal"] == "y" and lag["lag_time"] == pytest.approx(0.05 * 0.3, abs=2e-4)   # 0.015 s shift
    assert lag["lag_angle"] == pytest.approx(OMEGA * 0.015, abs=OMEGA * 2e-4)
    assert lag["rms_after"] < 0.2 * lag["rms_before"]


def test_html_report_verdict_first_nok_curves_then_details(recording, tmp_path):
    path = write_report(recording, tmp_path / "html", fmt="html", ok_plots=1)
    text = path.read_text()
    assert path.name == "report.html" and "<table>" in text
    # the verdict first, then the NOK curves, then the details
    order = [text.index(h) for h in ("<h2>Verdict</h2>", "<h2>NOK curves</h2>", "<h2>Process values, program 1</h2>",
                                      "<h2>All curves, program 1</h2>", "<h2>Plant truth</h2>", "<h2>Exports</h2>")]
    assert order == sorted(order)
    assert "<div class='banner nok'>NOK: 4 of 60 curves failed, 56 OK (program 1)</div>" in text
    assert "<td>35 … 50 N</td>" in text and "<td>≤ 45 mm</td>" in text             # limits in display units
    assert "<td>W1</td><td>left through right</td>" in text                     # what failed and why
    assert "hologram" in text and "unknown kind" in text                        # skipped element noted
    pngs = sorted(path.parent.glob("*.png"))
    names = [p.name.split("_", 1)[1] for p in pngs]
    # NOK curves first (all 4), histograms, Y over X with elements, Y over t and angle, 1 OK curve, measurement −
    # theory, truth
    assert names == ["curve_c1.png", "curve_c16.png", "curve_c31.png", "curve_c46.png", "hist_p1.png", "xy_p1.png",
                     "ys_p1.png", "curve_c2.png", "residuals.png", "truth.png"]
    assert all(p.stat().st_size > 5000 and p.name in text for p in pngs)
    assert "4 of 4 NOK curves plotted." in text and "Individual plots of OK curves: 1 of 56" in text
    with open(path.parent / "curves.csv", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["curve", "program", "i", "t [s]", "x [mm]", "y [N]", "angle [deg]"]
    assert len(rows) == 1 + sum(c.t.size for c in recording.curves)
    c5 = np.array([[float(v) for v in r[3:]] for r in rows[1:] if r[0] == "5"])
    c = recording.curves[4]
    np.testing.assert_allclose(c5, np.column_stack([c.t, 1e3 * c.x, c.y, np.degrees(c.angle)]), rtol=1e-8, atol=1e-12)
    with open(path.parent / "results.csv", encoding="utf-8") as f:
        res = list(csv.DictReader(f))
    assert len(res) == 60 and res[0]["ok"] == "0" and res[0]["verdict"] == "NOK" and res[0]["failed_elements"] == "W1"
    assert res[0]["reason"] == "W1: left through right" and all(r["reason"] for r in res if r["ok"] == "0")
    assert all(r["reason"] == "" for r in res if r["ok"] == "1")
    assert float(res[1]["y_max [N]"]) == pytest.approx(recording.results[1]["process_values"]["y_max"], rel=1e-9)
    assert float(res[1]["x_at_y_max [mm]"]) == pytest.approx(
        1e3 * recording.results[1]["process_values"]["x_at_y_max"], rel=1e-9)


def test_nok_plots_are_limited_and_counted_ok_plots_off_by_default(recording, tmp_path):
    text = write_report(recording, tmp_path, fmt="md", nok_plots=2).read_text()
    assert "2 of 4 NOK curves plotted (the first 2, more with --nok-plots N;" in text
    assert "Individual plots of OK curves: 0 of 56 (more with --ok-plots N)." in text
    assert sorted(p.name.split("_", 1)[1] for p in tmp_path.glob("*curve_c*.png")) == ["curve_c1.png", "curve_c16.png"]
    with pytest.raises(ValueError, match="must be >= 0"):
        write_report(recording, tmp_path, ok_plots=-1)


def test_rig_report_nok_plots_option(recording, tmp_path, capsys):
    """`--nok-plots N` plots N NOK curves (default: the report's NOK_PLOTS, which the help text states)."""
    from rig.analysis.report_blocks import NOK_PLOTS
    from rig.cli import build_parser, main
    assert main(["-q", "report", str(recording.path), "-o", str(tmp_path / "all"), "--format", "md",
                 "--nok-plots", "4"]) == 0
    assert "4 of 4 NOK curves plotted." in (tmp_path / "all" / "report.md").read_text()
    assert main(["-q", "report", str(recording.path), "-o", str(tmp_path / "one"), "--format", "md",
                 "--nok-plots", "1"]) == 0
    assert len(list((tmp_path / "one").glob("*curve_c*.png"))) == 1
    helps = [a.help for p in build_parser()._subparsers._group_actions[0].choices.values() for a in p._actions
             if "--nok-plots" in a.option_strings]
    assert len(helps) == 2 and all(f"default {NOK_PLOTS};" in h for h in helps)


def test_report_uses_the_analysis_it_is_given(recording, tmp_path, monkeypatch):
    a = analyse(recording)

    def no_second_analysis(rec):
        raise AssertionError("write_report analysed the recording again")

    monkeypatch.setattr(report, "analyse", no_second_analysis)
    text = write_report(recording, tmp_path, fmt="md", nok_plots=0, analysis=a).read_text()
    assert "| y_max | 60 | N |" in text and "not compared: the device sent no statistics for this program" in text


def test_markdown_report_from_path_and_extension_section(tmp_path):
    path = tmp_path / "small.mcap"
    synthetic(path, n_curves=10)

    def clutch_section(ctx):
        return [Heading("Clutch"), Text(f"{len(ctx.recording.curves)} curves seen by the extension")]

    report.register_section("clutch-test", clutch_section)
    try:
        out = write_report(path, tmp_path / "md", fmt="md", nok_plots=1)
    finally:
        report.SECTIONS[:] = [s for s in report.SECTIONS if s[0] != "clutch-test"]
    text = out.read_text()
    assert out.name == "report.md" and "## Clutch" in text and "10 curves seen by the extension" in text
    assert text.index("## All curves") < text.index("## Clutch") < text.index("## Theory vs measurement")   # before the tail
    assert "only 10 measurements" in text and "| curve | program | result |" in text
    assert all((out.parent / p.name).exists() for p in out.parent.glob("*.png"))
    assert "![" in text
    with pytest.raises(ValueError, match="'pdf'"):
        write_report(path, tmp_path / "x", fmt="pdf")


def test_console_summary_says_why_curves_failed_in_display_units(recording, capsys):
    from rig import cli
    cli._print_set_summary(analyse(recording))
    out = capsys.readouterr().out
    assert "curves: 60, OK 56, NOK 4" in out and "  NOK curve 1: W1: left through right" in out
    row = next(line for line in out.splitlines() if line.split()[:1] == ["x_at_y_max"])
    x = np.array([r["process_values"]["x_at_y_max"] for r in recording.results])
    assert row.split()[1:4] == ["60", "mm", f"{1e3 * x.mean():.4g}"]              # SI m shown in mm


def test_a_report_written_again_leaves_nothing_of_the_earlier_one(recording, tmp_path):
    """A report directory holds one report: what the earlier report wrote (its manifest) is removed, a stray
    numbered figure of an older rig in a rig directory too; the user's own files stay."""
    from rig.outputs import claim_dir
    out = claim_dir(tmp_path / "rep")
    (out / "999_old_figure.png").write_bytes(b"old")             # an older rig's report, no manifest
    (out / "notes.txt").write_text("mine")
    write_report(recording, out, nok_plots=4)
    first = set((out / report.MANIFEST).read_text().split())
    assert not (out / "999_old_figure.png").exists() and (out / "notes.txt").read_text() == "mine"
    assert {"report.html", "curves.csv", "results.csv"} <= first and "notes.txt" not in first
    assert {"001_curve_c1.png", "004_curve_c46.png"} <= first                     # the 4 NOK curves
    write_report(recording, out, nok_plots=0)                     # fewer figures: the others go
    second = set((out / report.MANIFEST).read_text().split())
    on_disk = {p.name for p in out.iterdir() if not p.name.startswith(".")}
    assert on_disk == second | {"notes.txt"} and "004_curve_c46.png" not in on_disk and "004_residuals.png" in second


def test_live_pairs_dropped_is_the_latest_cumulative_count_even_with_reports_lost():
    from rig.analysis.sets import live_pairs_dropped
    reports = [{"kind": "live_dropped", "t": t, "count": c, "total": tot}
               for t, c, tot in ((1.0, 100, 100), (2.0, 50, 150), (3.0, 70, 220))]
    del reports[1]                                   # a damaged chunk held it: the sum of counts would say 170
    assert live_pairs_dropped(reports) == 220
    assert live_pairs_dropped(reports + [{"kind": "link_summary", "t": 4.0, "live_dropped": 260}]) == 260
    assert live_pairs_dropped([{"kind": "result", "t": 1.0}]) == 0


@pytest.mark.parametrize("end, cycles, truth_end, expected", [
    ({"simulation_time": "20.300405"}, 50, 20.0,
     "the first 1.2 s of the 20.30 s recorded (≈ 3 machine cycles of 0.4 s)"),
    ({}, 50, 20.0, "the first 1.2 s of the 20 s of truth recorded (≈ 3 machine cycles of 0.4 s)"),
    ({"simulation_time": "0.62"}, 0, 0.6, "0.6 s of the 0.62 s recorded"),
    ({"simulation_time": "0.6"}, 0, 0.6, "0.6 s")])
def test_truth_caption_states_the_recorded_simulated_time(tmp_path, end, cycles, truth_end, expected):
    """'over the first 1.29 s of 20 s' read the truth's own span while 20.30 s were simulated (the console's
    figure): the caption uses the run's end record, and says 'of truth recorded' where there is none."""
    from rig.recorder.reader import CurveRecord, Recording
    curves = [CurveRecord(k + 1, 1, 0.4 * k + np.arange(3) * 0.1, np.zeros(3), np.zeros(3)) for k in range(cycles)]
    rec = Recording(tmp_path / "r.mcap", metadata={"rig.end": end} if end else {}, curves=curves)
    t = np.linspace(0.0, truth_end, 201)
    assert report._truth_window(rec, t)[1] == expected


def test_an_overlay_of_thousands_of_curves_keeps_every_peak_in_a_bounded_number_of_points():
    """A long recording's overlay (here 300 curves of 3100 samples, over the budget) is drawn as each curve's min
    and max in runs of samples: at most OVERLAY_POINTS points in all (plus, per curve, the min and max of the
    shorter run left over and one gap), every curve's own extremes still drawn, even in the last samples; a few
    curves are drawn sample for sample."""
    from rig.analysis.plots import OVERLAY_POINTS, _Overlay

    def _joined(items):
        overlay = _Overlay([c[1].size for c in items])
        for x_, y_ in items:
            overlay.add(x_, y_)
        return overlay.arrays()
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 0.31, 3100)
    curves = [(t, np.sin(40 * t) - 3.0 * np.exp(-((t - rng.uniform(0.05, 0.309)) / 2e-4) ** 2)) for _ in range(300)]
    x, y = _joined(curves)
    assert x.size == y.size <= OVERLAY_POINTS + 3 * len(curves)
    assert np.all(np.diff(x[~np.isnan(x)][:100]) > 0)         # in time order
    pieces = np.split(y, np.flatnonzero(np.isnan(y)))
    drawn = [p[~np.isnan(p)] for p in pieces if np.any(~np.isnan(p))]
    assert len(drawn) == len(curves)
    for (_, c), d in zip(curves, drawn):
        assert d.min() == c.min() and d.max() == c.max()          # the narrow dip (a 0.2 ms peak) is kept
    few_x, few_y = _joined(curves[:5])
    assert few_y.size == 5 * (3100 + 1)


def test_a_single_curve_figure_names_its_dashed_theory(tmp_path, monkeypatch):
    """A curve's own figure (--ok-plots / NOK curves) drew its theory dashed with nothing saying what it is."""
    import rig.analysis.plots as plots
    from rig.recorder.reader import CurveRecord
    figures = []
    monkeypatch.setattr(plots, "save", lambda fig, path, **kw: figures.append(fig) or path)
    t = np.linspace(0.0, 0.25, 200)
    curve = CurveRecord(number=1, program=1, t=t, x=0.04 * t / 0.25, y=-30 + 5 * np.sin(20 * t), angle=None,
                        theory={"y": -30 + 5 * np.sin(20 * t + 0.01)})
    plots.curve_panels(curve, [], tmp_path / "c.png")
    labels = [text.get_text() for ax in figures[0].axes if ax.get_legend() for text in ax.get_legend().get_texts()]
    assert labels == ["measured", "theory"]
    figures.clear()
    plots.curve_panels(CurveRecord(number=2, program=1, t=t, x=t, y=t, angle=None, theory={}), [], tmp_path / "d.png")
    assert not any(ax.get_legend() for ax in figures[0].axes)          # no theory: nothing to name


def test_the_envelope_keeps_every_stretch_of_the_signal_to_its_end():
    """The reduced trace of a long signal spans it to the end at the same resolution (5000 samples in 1500 runs of 3
    left 500 samples, the last tenth of a run, to two points before; 5999 a quarter), and holds each run's min and max."""
    from rig.analysis.plots import envelope
    for n in (4500, 5000, 5999, 100_003):
        t = np.linspace(0.0, 1.0, n)
        y = np.sin(40 * t) + (t > 0.9) * np.sin(900 * t)        # a burst in the last tenth
        te, ye = envelope(t, y)
        assert te.size <= 2 * (1500 + 1) and te[0] == t[0] and np.all(np.diff(te) >= 0)
        burst = t > 0.9
        assert np.max(np.diff(te[te > 0.9])) <= 2 * np.ceil(n / 1500) / (n - 1) + 1e-12, n    # no gap in the tail
        assert ye[te > 0.9].max() == y[burst].max() and ye[te > 0.9].min() == y[burst].min(), n


def test_event_fields_read_in_display_units_without_rounding_noise():
    """A lobe-wrap root found at φ_r = 0 within rounding reads "0°" (not "-2.172e-14°"); a real angle keeps its digits."""
    from rig.analysis.event_text import event_details
    from rig.analysis.units import DisplayUnits
    units = DisplayUnits()
    assert event_details({"t": 0.1, "kind": "lobe_wrap", "phi_r": -3.79e-16}, units) == "phi_r 0°"
    assert event_details({"t": 0.1, "kind": "disengagement", "phi_r": 1.0471975511965976, "direction": 1},
                         units) == "phi_r 60°, direction 1"
    assert event_details({"t": 0.1, "kind": "x", "phi_r": 1e-6}, units) == "phi_r 5.73e-05°"
    lift = event_details({"t": 0.1, "kind": "follower_lift", "cam_angle": 1.416, "force": -3.837, "min_t": 0.02134,
                          "min_cam_angle": 1.542}, units)           # min_cam_angle read in rad with no unit (an audit)
    assert lift.startswith("cam_angle 81.13°, force -3.837 N, min_t 0.02134 s, min_cam_angle 88.35°"), lift


def test_the_truth_caption_accounts_for_every_signal(tmp_path):
    """The unwrapped cam angle phi is left out of the truth chart (a ramp that would squeeze the wrapped cam_angle
    flat): the caption says so — it was neither drawn nor listed."""
    from rig.analysis.report_blocks import ReportContext
    from rig.recorder.reader import Recording
    t = np.linspace(0.0, 0.8, 801)
    phi = 15.7 * t
    rec = Recording(tmp_path / "r.mcap", series={"/plant/truth": {"t": t, "phi": phi, "cam_angle": np.mod(phi, 2 * np.pi),
                                                                  "F": 40 * np.sin(phi)}})
    (heading, figure) = report.truth(ReportContext(rec, {}, tmp_path))
    assert "cam_angle" in figure.caption and "F" in figure.caption
    assert "not drawn: phi (the cam angle unwrapped, a ramp; cam_angle is drawn)" in figure.caption


def test_a_process_value_row_is_at_one_precision():
    """mean, min, max and the band with the decimals of three digits of 6σ (a minimum of -19.0023 read "-19" beside a
    band in hundredths); σ at rounding level counts as none (four digits of the mean, not 15 decimals)."""
    from rig.analysis.numbers import fixed, row_places
    places = row_places(-20.1, 0.77)
    assert places == 2 and fixed(-19.0023, places) == "-19.00"
    assert row_places(41.72, 1e-14) == 2 and row_places(0.25503, 0.000751) == 5 and row_places(5.0, 0.0) == 3


def test_a_small_sets_capability_comes_after_its_warning(tmp_path):
    """16 curves (< 50): the "indicative only" warning stands before the capability table it qualifies (it came after
    the table of NOK reasons, below a table that already said "capable"), and only there."""
    path = tmp_path / "small.mcap"
    synthetic(path, n_curves=16)
    text = write_report(read_recording(path), tmp_path / "md", fmt="md").read_text()
    warning = "only 16 measurements in the set (< 50): statistics and capability are indicative only"
    assert text.count(warning) == 1 and text.index(warning) < text.index("Capability of the process")


def test_a_csv_header_unit_without_a_named_label_is_written_with_a_caret():
    """Display units outside the named ones keep pint's compact text for CSV headers — with ^ for powers, as
    "mm/s^2" is written: lab_cam's plant_truth.csv said "a [m/s**2]" and "alpha_in [rad/s**2]"."""
    from rig.analysis.units import unit
    assert unit("m/s^2", "m/s^2").ascii == "m/s^2" and unit("rad/s^2").ascii == "rad/s^2"
    assert unit("m/s^2", "m/s^2").label == "m/s²"


def test_curves_judged_but_not_recorded_make_the_verdict_incomplete_not_ok(lost_curves, tmp_path, capsys):
    """Results of 5 curves all OK, the samples of curves 2 and 4 lost on the way (``incomplete_curve``): the verdict
    says so and is not green (it read "OK: all 5 curves passed" with every curve of a run missing)."""
    from rig.analysis.report_blocks import Banner, ReportContext
    recording = read_recording(lost_curves)
    blocks = report.verdict(ReportContext(recording, analyse(recording), tmp_path))
    (banner,) = [b for b in blocks if isinstance(b, Banner)]
    assert not banner.ok and banner.text.startswith("INCOMPLETE: the unit passed all 5 curves")
    assert "2 curves not recorded, their frames incomplete (curve 2, 4" in banner.text
    from rig.cli import _print_set_summary                # the console says it under its counts too
    _print_set_summary(analyse(recording))
    assert "warning: 2 of these curves not recorded, their frames incomplete (curve 2, 4)" in capsys.readouterr().out

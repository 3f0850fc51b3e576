"""The chart of ``rig cam-design`` (rig.cam_design_chart): a check without a ratio to its limit is no bar."""
from __future__ import annotations

import pytest

SCENE = "data/scenes/pin_insertion.toml"


def _drawn(tmp_path, monkeypatch, checks):
    import rig.analysis.plots as plots
    from rig.cam_design_chart import plot_design
    from rig.mechanisms.cam.design import design_checks
    from rig.plants.cam_bar.scene_io import cam_bar_from_scene
    mech, omega = cam_bar_from_scene(SCENE)
    design = design_checks(mech, omega, n=360)
    if checks is not None:
        design.checks = checks
    drawn = {}
    monkeypatch.setattr(plots, "write_tight", lambda fig, path, **kw: drawn.setdefault("fig", fig) and path)
    plot_design(design, tmp_path / "cam.png")
    return drawn["fig"]


def test_a_check_without_a_ratio_is_a_marker_not_a_bar_past_the_limit(tmp_path, monkeypatch):
    """r_b/h ≥ 0 has no share of its limit: no bar (a bar across the axis read as the worst violation), a hollow
    marker at the start in its verdict's colour and a text saying it has no ratio, the verdict and the comparison."""
    from matplotlib.colors import to_rgb

    from rig.mechanisms.cam.design import Check
    fig = _drawn(tmp_path, monkeypatch, [Check("a", 0.5, 1.0, "mm", "≤"), Check("r_b/h", -0.32, 0.0, "", "≥"),
                                         Check("r_b/h ok", 0.42, 0.0, "", "≥")])
    axes = fig.axes[-1]
    bars = {round(b.get_y() + b.get_height() / 2): b.get_width() for b in axes.patches}
    assert bars == {2: pytest.approx(0.5)}                       # rows from the top: 2, 1, 0; only "a" has a bar
    markers = {round(line.get_ydata()[0]): to_rgb(line.get_markeredgecolor()) for line in axes.lines
               if line.get_marker() == "D"}
    assert markers == {1: pytest.approx(to_rgb("tab:red")), 0: pytest.approx(to_rgb("tab:green"))}
    assert all(line.get_xdata()[0] == 0.0 for line in axes.lines if line.get_marker() == "D")
    texts = [t.get_text() for t in axes.texts]
    assert "FAIL, -0.32 ≥ 0 does not hold (no ratio to its limit)" in texts
    assert "PASS, 0.42 ≥ 0 holds; information only: no ratio to its limit" in texts
    names = {t.get_text(): t.get_style() for t in axes.get_yticklabels()}
    assert names == {"a": "normal", "r_b/h": "italic", "r_b/h ok": "italic"}


def test_the_curve_panels_span_the_page(tmp_path, monkeypatch):
    """The three curves over the cam angle start near the left edge (they left ~30 % of the width blank for the
    check names of the panel below); the check panel keeps its margin for the names."""
    fig = _drawn(tmp_path, monkeypatch, None)
    curves, checks = fig.axes[:3], fig.axes[-1]
    assert all(ax.get_position().x0 < 0.12 for ax in curves)
    assert all(ax.get_position().width > 0.65 for ax in curves)
    assert checks.get_position().x0 > 0.25
    renderer = fig.canvas.get_renderer()
    left = min(t.get_window_extent(renderer).x0 for t in checks.get_yticklabels())
    assert left >= 0.0                                           # the longest check name fits on the page


def test_rig_cam_design_writes_the_chart(tmp_path, capsys):
    from rig.cli import main
    png = tmp_path / "chart.png"
    assert main(["-q", "cam-design", "-o", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"chart: {png}" in capsys.readouterr().out


def test_a_failed_checks_label_states_its_numbers_as_they_stand():
    """A failed pressure angle read "1.32 (39.68 ≤ 30 °)": the relation the check asks for, which its numbers break."""
    from rig.cam_design_chart import row_text
    from rig.mechanisms.cam.design import Check
    assert row_text(Check("pressure angle", 39.68, 30.0, "°", "≤"), 1.32) == "1.32  (39.68 > 30 °: fails)"
    assert row_text(Check("base radius", 11.29, 26.4, "mm", "≥"), 2.34) == "2.34  (11.29 < 26.4 mm: fails)"
    assert row_text(Check("pressure angle", 18.4, 30.0, "°", "≤"), 0.61) == "0.61  (18.4 ≤ 30 °)"

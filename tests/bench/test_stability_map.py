"""rig bench stability on a short span: beyond their stability limits the fixed-step methods stop with a
report (explicit Euler's slow growth included); inside them they converge or are merely inaccurate; the adaptive
methods converge everywhere; no cell is a silent wrong answer."""
from __future__ import annotations

import csv

import pytest

from rig.bench.stability import ADAPTIVE, CLASSES, FIXED, stability_map
from rig.cli import DATA, main

SCENE = DATA / "scenes" / "pin_insertion_l2.toml"


def test_limits_are_reported_and_no_cell_is_silent():
    rows = stability_map(SCENE, t_sim=0.1, steps=[4e-4, 2.5e-5], factors=[1.0, 4.0])
    assert {r["class"] for r in rows} <= set(CLASSES)
    assert len(rows) == 2 * (2 * len(FIXED) + len(ADAPTIVE))
    cell = {(r["method"], r["h"], r["stiffness_factor"]): r for r in rows}
    # h = 0.4 ms against the contact mode (omega_n = 4.2e3 1/s at x1, 7.2e3 at x4, zeta 0.04-0.08): beyond explicit
    # Euler's 2*zeta everywhere, beyond symplectic Euler's 2 at x4 only; RK4 inside its region at x1 (h*omega_n =
    # 1.7) and just beyond it at x4 (h*|lambda| 2.9-3.4 > 2.78..2.83: 36-43 % wrong, it must say so)
    for f in (1.0, 4.0):
        assert cell["euler", 4e-4, f]["class"] == "detected" and cell["euler", 4e-4, f]["message"]
    assert cell["rk4", 4e-4, 1.0]["class"] in ("converged", "inaccurate")
    assert cell["rk4", 4e-4, 4.0]["class"] == "detected" and "RK4 needs h*|lambda|" in cell["rk4", 4e-4, 4.0]["message"]
    assert cell["semi-implicit euler", 4e-4, 4.0]["class"] == "detected"
    assert cell["semi-implicit euler", 4e-4, 1.0]["class"] in ("converged", "inaccurate")
    for f in (1.0, 4.0):     # h = 25 us: h*omega_n = 0.10 / 0.18 > 2*zeta: explicit Euler's slow growth, reported
        assert "the step amplifies the mode" in cell["euler", 2.5e-5, f]["message"]
    assert not [r for r in rows if r["class"] == "silent"]
    for r in (r for r in rows if r["class"] == "detected"):     # each names time, step, cause and the fix, whole
        m = r["message"]
        assert "t = " in m and "h = " in m and ("Rodas4" in m or "reduce h" in m or "smaller step" in m), m


def test_command_writes_csv_and_png(tmp_path):
    assert main(["-q", "bench", "stability", "--quick", "-o", str(tmp_path)]) == 0
    rows = list(csv.DictReader((tmp_path / "stability.csv").open(encoding="utf-8")))
    assert rows and list(rows[0]) == ["method", "h", "stiffness_factor", "cam_speed_rpm", "class", "error", "nfev",
                                  "message"]
    assert (tmp_path / "stability.png").read_bytes().startswith(b"\x89PNG")


def test_cam_speed_axis():
    rows = stability_map(SCENE, t_sim=0.05, steps=[1e-4], factors=[1.0], speeds=[1.0, 2.0])
    assert sorted({float(r["cam_speed_rpm"]) for r in rows}) == pytest.approx([150.0, 300.0])
    assert len(rows) == 2 * (len(FIXED) + len(ADAPTIVE))
    assert not [r for r in rows if r["class"] == "silent"]


def test_a_scene_at_another_level_is_refused_as_work_precision_refuses_it(tmp_path, capsys):
    """Both benches study level 2: a level-1 scene is refused by both, with the same words (stability once drew a
    level-2 map for it)."""
    for bench in ("stability", "work-precision"):
        assert main(["-q", "bench", bench, "--scene", str(DATA / "scenes" / "pin_insertion.toml"), "--quick",
                     "-o", str(tmp_path / bench)]) == 2
        err = capsys.readouterr().err
        assert f"rig bench {bench} studies level 2 of the cam-bar plant; set fidelity = 2" in err, err
        assert not (tmp_path / bench / "stability.csv").exists()

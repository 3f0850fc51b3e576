"""Evaluation elements on hand-made curves: pass, fail with the right reason, documented edge cases."""
import numpy as np
import pytest

from firmware_sim.digiforce import DigiForceError, envelope_band
from firmware_sim.digiforce.geometry import ConvexQuad


WIN = {"kind": "window", "name": "W", "x_min": 1.0, "x_max": 2.0, "y_min": 1.0, "y_max": 2.0}


@pytest.fixture(autouse=True)
def _factory(make_element):
    global MAKE
    MAKE = make_element


def run(cfg, x, y):
    return MAKE(cfg).evaluate(np.asarray(x, float), np.asarray(y, float))


# --- windows -----------------------------------------------------------------------------------------
def test_window_left_to_right_passes_and_reports_entry_exit_values():
    ok, reason, vals = run(WIN | {"entry": "left", "exit": "right"}, [0, 3], [1.2, 1.8])
    assert ok, reason
    assert vals["x_entry"] == pytest.approx(1.0) and vals["y_entry"] == pytest.approx(1.4)
    assert vals["x_exit"] == pytest.approx(2.0) and vals["y_exit"] == pytest.approx(1.6)


def test_window_entering_through_wrong_side_fails_naming_side():
    ok, reason, _ = run(WIN | {"entry": "left", "exit": "right"}, [1.5, 1.5, 3.0], [0.0, 1.5, 1.5])
    assert not ok
    assert reason == "entry left: entered through the bottom side at x = 1.5, y = 1, not through the left"


def test_window_leaving_through_wrong_side_fails():
    ok, reason, _ = run(WIN | {"entry": "left", "exit": "right"}, [0, 1.5, 1.5], [1.5, 1.5, 3.0])
    assert not ok and reason == "exit right: exited through the top side at x = 1.5, y = 2, not through the right"


def test_window_missed_fails():
    ok, reason, _ = run(WIN | {"entry": "left", "exit": "right"}, [0, 3], [0.5, 0.5])
    assert not ok and "never enters" in reason


def test_touching_an_edge_counts_as_inside_entering_and_leaving_there():
    # the curve comes up from below, touches the bottom edge at one pair and goes down again
    x, y = [1.2, 1.5, 1.8], [0.5, 1.0, 0.5]
    ok, reason, vals = run(WIN | {"entry": "bottom", "exit": "bottom"}, x, y)
    assert ok, reason
    assert vals["y_entry"] == vals["y_exit"] == 1.0
    ok, reason, _ = run(WIN | {"entry": "left", "exit": "right"}, x, y)
    assert not ok and "entered through the bottom side at x = 1.5, y = 1" in reason


def test_running_along_an_edge_is_inside():
    # enters through the left side exactly on the bottom-left corner, runs along the bottom edge, leaves right
    ok, reason, _ = run(WIN | {"entry": "left", "exit": "right"}, [0.0, 1.0, 2.0, 3.0], [1.0, 1.0, 1.0, 1.0])
    assert ok, reason


def test_crossing_through_a_corner_belongs_to_both_sides():
    # diagonal through the bottom-left corner (1, 1) and out through the top-right corner (2, 2)
    for entry, exit_ in (("left", "right"), ("bottom", "top"), ("left", "top")):
        ok, reason, _ = run(WIN | {"entry": entry, "exit": exit_}, [0, 3], [0, 3])
        assert ok, (entry, exit_, reason)
    ok, reason, _ = run(WIN | {"entry": "right", "exit": "top"}, [0, 3], [0, 3])
    assert not ok and "left/bottom" in reason


def test_segment_jumping_across_window_between_pairs_counts():
    # no stored pair inside: the polyline still passes through the window
    ok, reason, vals = run(WIN | {"entry": "left", "exit": "right"}, [0.0, 3.0], [1.5, 1.5])
    assert ok and vals["x_entry"] == 1.0 and vals["x_exit"] == 2.0


def test_entering_twice_fails():
    x = [0, 1.5, 1.5, 1.5, 3]
    y = [1.5, 1.5, 2.5, 1.5, 1.5]   # in from the left, out the top, back in from the top, out right
    ok, reason, _ = run(WIN | {"entry": "any", "exit": "any"}, x, y)
    assert not ok and reason.startswith("entry any: the curve entered the window 2 times (exactly once allowed): "
                                        "through the left (x min 1) at x = 1, y = 1.5; through the top (y max 2) "
                                        "at x = 1.5, y = 2")
    check = MAKE(WIN | {"entry": "any", "exit": "any"}).check(np.asarray(x, float), np.asarray(y, float))
    assert check.at == (1.5, 2.0)         # marked where it failed: the second entry, not the allowed first one


def test_block_window_exit_none_requires_ending_inside():
    ok, reason, _ = run(WIN | {"entry": "left", "exit": "none"}, [0, 1.5], [1.5, 1.5])
    assert ok, reason
    ok, reason, _ = run(WIN | {"entry": "left", "exit": "none"}, [0, 3], [1.5, 1.5])
    assert not ok and "must end inside" in reason


def test_curve_starting_inside_fails_entry_side_and_passes_entry_none():
    x, y = [1.5, 3.0], [1.5, 1.5]
    ok, reason, _ = run(WIN | {"entry": "left", "exit": "right"}, x, y)
    assert not ok and "starts inside" in reason
    assert run(WIN | {"entry": "none", "exit": "right"}, x, y)[0]


def test_max_check_y_max_inside_window():
    x = np.linspace(0, 3, 301)
    y = 1.8 - (x - 1.5) ** 2       # peak 1.8 at x = 1.5
    cfg = WIN | {"entry": "ignore", "exit": "ignore", "check": "y_max"}
    assert run(cfg, x, y)[0]
    ok, reason, _ = run(cfg, x, y + 0.5)   # peak 2.3 above the window
    assert not ok and reason == "check y_max: y max 2.3 at x = 1.5 lies above the window (y max 2)"


def test_ignore_sides_needs_only_a_touch():
    cfg = WIN | {"entry": "ignore", "exit": "ignore"}
    assert run(cfg, [0, 3], [2.0, 2.0])[0]          # along the top edge
    ok, reason, _ = run(cfg, [0, 3], [2.0001, 2.0001])
    assert not ok and "does not pass through" in reason


# --- trapezoids ----------------------------------------------------------------------------------------
TRAP_Y = {"kind": "trapezoid", "name": "T", "axis": "y", "start": 1.0, "end": 3.0, "lower": [0.0, 2.0],
          "upper": [1.0, 3.0]}


def test_y_trapezoid_follows_a_rising_band():
    x = np.linspace(0, 4, 81)
    ok, reason, vals = run(TRAP_Y, x, x - 0.5)    # inside the sloped band, in left, out right
    assert ok, reason
    assert vals["y_entry"] == pytest.approx(0.5) and vals["y_exit"] == pytest.approx(2.5)


def test_y_trapezoid_leaving_through_sloped_top_fails():
    x = np.linspace(0, 4, 81)
    ok, reason, _ = run(TRAP_Y, x, 0.5 + 0.0 * x)   # flat: leaves through the rising lower edge
    assert not ok and "exit right: exited through the bottom side at x = 1.5, y = 0.5, not through the right" == reason


def test_x_trapezoid_swaps_axes():
    cfg = {"kind": "trapezoid", "name": "TX", "axis": "x", "start": 0.0, "end": 10.0, "lower": [1.0, 2.0],
           "upper": [2.0, 3.0]}
    y = np.linspace(-1, 11, 121)
    ok, reason, _ = run(cfg, 1.5 + 0.1 * y, y)          # inside the band along Y: bottom in, top out
    assert ok, reason
    ok, reason, _ = run(cfg, 1.5 + 0.0 * y, y)          # X stays 1.5: leaves through the left limit
    assert not ok and reason.startswith("exit top: exited through the left side at x = 1.5, y = 5")


def test_point_on_slanted_edge_is_inside():
    quad = ConvexQuad([(1.0, 0.0), (3.0, 2.0), (3.0, 3.0), (1.0, 1.0)])
    assert quad.contains(2.0, 1.0)[0] and quad.contains(2.0, 2.0)[0]
    assert not quad.contains(2.0, 0.999)[0]


# --- thresholds ------------------------------------------------------------------------------------------
TH = {"kind": "threshold", "name": "S", "axis": "y", "value": 1.0}


def test_threshold_rising_passes_and_reports_crossing_x():
    ok, reason, vals = run(TH | {"direction": "rising"}, [0, 1, 2], [0, 0.5, 1.5])
    assert ok, reason and vals["at"] == pytest.approx(1.5)
    assert vals["at"] == pytest.approx(1.5)


def test_threshold_wrong_direction_fails():
    ok, reason, _ = run(TH | {"direction": "falling"}, [0, 1, 2], [0, 0.5, 1.5])
    assert not ok and "never crosses y = 1 falling" in reason


def test_reaching_threshold_counts_as_crossing():
    assert run(TH | {"direction": "rising"}, [0, 1, 2], [0, 1.0, 0])[0]
    assert not run(TH | {"direction": "rising"}, [0, 1, 2], [0, 0.999, 0])[0]


def test_threshold_range_limits_where_the_crossing_may_be():
    cfg = TH | {"direction": "rising", "range": [2.0, 3.0]}
    ok, reason, _ = run(cfg, [0, 1, 2], [0, 0.5, 1.5])
    assert not ok and "outside the range" in reason
    assert run(cfg, [0, 2, 3], [0, 0.5, 1.5])[0]


def test_x_threshold_falling():
    cfg = {"kind": "threshold", "name": "S", "axis": "x", "value": 1.0, "direction": "falling"}
    ok, _, vals = run(cfg, [2, 0], [0, 4])
    assert ok and vals["at"] == pytest.approx(2.0)


# --- envelopes ------------------------------------------------------------------------------------------
def brute_band(refs, dx, dy, xs):
    """Band at xs by dense sampling of each reference (independent of the vectorised construction)."""
    lo, hi = np.full(len(xs), np.inf), np.full(len(xs), -np.inf)
    for rx, ry in refs:
        fine = np.linspace(rx[0], rx[-1], 200001)
        fy = np.interp(fine, rx, ry)
        for i, g in enumerate(xs):
            m = np.abs(fine - g) <= dx + 1e-12
            if m.any():
                lo[i], hi[i] = min(lo[i], fy[m].min()), max(hi[i], fy[m].max())
    return lo - dy, hi + dy


def test_envelope_band_matches_brute_force_dilation():
    rng = np.random.default_rng(1)
    refs = [(np.linspace(0, 1, 40), rng.normal(0, 1, 40)), (np.linspace(0.1, 1.2, 30), rng.normal(0, 1, 30))]
    grid, lo, hi = envelope_band(refs, 0.05, 0.2)
    blo, bhi = brute_band(refs, 0.05, 0.2, grid)
    assert np.allclose(lo, blo, atol=2e-3) and np.allclose(hi, bhi, atol=2e-3)


def test_envelope_pass_and_fail_named():
    rx = np.linspace(0, 1, 101)
    refs = [{"x": rx.tolist(), "y": (rx ** 2).tolist()}, {"x": rx.tolist(), "y": (rx ** 2 + 0.1).tolist()}]
    cfg = {"kind": "envelope", "name": "E", "references": refs, "dx": 0.0, "dy": 0.05}
    x = rx[::3]                                      # pairs at reference vertices: band edges exact there
    assert run(cfg, x, x ** 2 + 0.05)[0]
    assert run(cfg, x, x ** 2 - 0.05)[0]            # on the lower edge: inside
    ok, reason, _ = run(cfg, x, x ** 2 + 0.16)
    assert not ok and "pair 0" in reason and "above the envelope" in reason
    ok, reason, _ = run(cfg, np.linspace(0, 1.1, 57), np.linspace(0, 1.1, 57) ** 2)
    assert not ok and "outside the envelope's X range" in reason


def test_envelope_dx_widens_steep_parts():
    rx = np.array([0.0, 1.0, 1.0001, 2.0])
    ry = np.array([0.0, 0.0, 10.0, 10.0])             # a step at x = 1
    base = {"kind": "envelope", "name": "E", "references": [{"x": rx.tolist(), "y": ry.tolist()}], "dy": 0.1}
    x, y = np.array([0.5, 0.95, 1.5]), np.array([0.0, 10.0, 10.0])   # step arrives 0.05 early
    assert not run(base | {"dx": 0.0}, x, y)[0]
    assert run(base | {"dx": 0.06}, x, y)[0]


@pytest.mark.parametrize("cfg, message", [
    (WIN | {"x_min": 3.0}, "x_min 3.0 m must be below x_max 2.0 m"),
    (WIN | {"x_min": "43 mm", "x_max": "36 mm"}, 'x_min "43 mm" must be below x_max "36 mm"'),     # as written
    (WIN | {"entry": "north"}, "entry: 'north' is not one of"),
    (WIN | {"x_max": "2 N"}, "wrong dimension"),
    (WIN | {"color": "red"}, "unknown key 'color'"),
    ({"kind": "circle", "name": "C"}, "kind: 'circle' is not one of"),
    (TRAP_Y | {"lower": [0.0, 3.5]}, "lower [0.0 N, 3.5 N] must be below upper [1.0 N, 3.0 N]"),
    (TRAP_Y | {"start": "3 mm", "end": "1 mm"}, 'start "3 mm" must be below end "1 mm"'),
    ({"kind": "envelope", "name": "E", "references": [{"x": [0, 1, 0.5], "y": [0, 1, 2]}]}, "strictly monotonic"),
    (TH | {"part": "middle"}, "part: 'middle' is not one of"),
    (TH | {"range": ["43 mm", "30 mm"]}, 'range: low "43 mm" must be below high "30 mm"'),      # as written, not SI
])
def test_bad_element_configs_are_named(cfg, message, make_element):
    with pytest.raises(DigiForceError, match=message.replace("[", r"\[").replace("]", r"\]").replace("(", r"\(")
                       .replace(")", r"\)")):
        make_element(cfg)


def test_window_limits_accept_units(make_element):
    el = make_element(WIN | {"x_min": "1000 mm", "x_max": "2000 mm", "y_min": "1 N", "y_max": "0.002 kN"})
    assert el.cfg["x_min"] == pytest.approx(1.0) and el.cfg["y_max"] == pytest.approx(2.0)

"""A solver setting taken from work–precision data (another scene's, or a file of this scene's name), checked on
this scene's own problem (:data:`rig.fidelity.SETTING_CHECK`)."""
from __future__ import annotations

import math
from typing import Any, Callable

from rig.bench.harness import FIXED, _ours
from rig.bench.problems import problem_of
from rig.scene import Scene, SceneError
from rig.solvers import SolverDivergence

TIGHTER = 10 ** -0.5       # factor on rtol (and atol) per step when a setting misses the tolerance at this point
CHECK_STEPS = 6           # at most this many tighter settings (3 decades)
CHECK_RTOL = 1e-10        # the check's reference: dp45 at this tolerance


_found: dict[tuple, tuple[dict[str, float], str, bool]] = {}     # per scene content and setting: a sweep asks per point
#: load parameters of [plant.variation] that level 2's dynamics see: the setting is checked at their ±3σ machines too
VARIED = ("F_c", "F_c_travel", "mu")
SIGMAS = 3.0


def at_this_point(scene: Scene, method: str, options: dict[str, float],
                  tolerance: float) -> tuple[dict[str, float], str, bool]:
    """:func:`_check` at the scene's nominal machine and, where ``[plant.variation]`` varies the load per cycle, at
    the machines ±:data:`SIGMAS` σ of each :data:`VARIED` parameter (every cycle runs a different machine: one
    varied by 0.1 mm of F_c_travel read 9.9e-6 against 1e-6 with the nominal machine's setting; an audit) — the
    setting tightened until every one is within ``tolerance``, then checked at all of them again (the error need not
    fall with the tolerance). (options, what the check found in words, whether ``tolerance`` is met everywhere);
    once per scene content, method, options and tolerance (a sweep asks three times per point)."""
    key = (scene.content, method, tuple(sorted(options.items())), tolerance)
    if key not in _found:
        machines = [("", scene)] + _varied(scene)
        measures: dict[str, Any] = {}            # per machine: its reference and the errors already measured
        tried, said, found = dict(options), [], []
        for label, machine in machines:
            tried, text, ok = _check(machine, method, tried, tolerance, measures)
            said.append(label + text)
            found.append(ok)
        if None in found:               # the problem cannot be run there (said, as the run will say what it meets)
            _found[key] = (tried, "; ".join(said), True)
        elif len(machines) > 1:
            worst = max(_measure(machine, method, measures)[0](tried) for _, machine in machines)
            met = worst <= tolerance
            setting = " ".join(f"{k}={v:.3g}" for k, v in tried.items() if k != "atol")
            text = (f"{said[0]}; at the ±{SIGMAS:g}σ machines of [plant.variation] "
                    f"({', '.join(label.split(' ')[0] for label, _ in machines[1::2])}) too: "
                    + (f"{setting}, largest error {worst:.1e}" if met else
                       f"no setting down to {setting} reaches {tolerance:g} at all of them (largest error "
                       f"{worst:.1e}): the run is less accurate than the scene asks"))
            _found[key] = (tried, text, met)
        else:
            _found[key] = (tried, said[0], bool(found[0]))
    options, said, met = _found[key]
    return dict(options), said, met


def _varied(scene: Scene) -> list[tuple[str, Scene]]:
    """The scene's machine with each :data:`VARIED` load parameter its ``[plant.variation]`` varies set to ±SIGMAS σ
    of its nominal value (labelled "F_c +3σ"); none without variation or for a plant other than the cam bar."""
    if scene.section("scene").get("plant") != "cam_bar":
        return []
    from rig.plants.cam_bar.scene_io import mechanism_from_scene
    from rig.plants.cam_bar.variation import LOAD_UNITS
    from rig.sweep import with_overrides
    from rig.units import to_si
    table = scene.section("plant").get("variation") or {}
    mech = mechanism_from_scene(scene)
    out = []
    for name in VARIED:
        if name not in table:
            continue
        sigma = to_si(table[name], LOAD_UNITS[name]) if isinstance(table[name], str) else float(table[name])
        if not sigma:
            continue
        unit = "" if LOAD_UNITS[name] == "1" else f" {LOAD_UNITS[name]}"
        for sign in (1.0, -1.0):
            value = max(getattr(mech, name) + sign * SIGMAS * sigma, 0.0)
            out.append((f"{name} {'+' if sign > 0 else '-'}{SIGMAS:g}σ ",
                        with_overrides(scene, {f"plant.{name}": f"{value!r}{unit}" if unit else value})))
    return out


def _measure(scene: Scene, method: str,
             kept: dict[str, Any] | None = None) -> tuple[Callable[[dict[str, float]], float], str]:
    """The error of a setting of ``method`` on ``scene``'s own problem (one revolution of level 2, the clutch stand's
    span) against dp45 at :data:`CHECK_RTOL`, in e and in the answers the scene asks, as a function of the setting
    (each setting run once); and the answers' names for the words ("", or ", rod_force, …"). ``kept``: measures made
    before, by scene content (the reference is the costly part), added to."""
    if kept is not None and scene.content in kept:
        return kept[scene.content]
    problem = problem_of(scene, checked=False)
    reference = _ours(problem, "dp45", rtol=CHECK_RTOL, atol=CHECK_RTOL * problem.atol_scale)[0]
    answers = _Answers(scene, method, problem.atol_scale)
    errors: dict[tuple, float] = {}

    def error_of(options: dict[str, float]) -> float:
        at = tuple(sorted(options.items()))
        if at not in errors:
            errors[at] = max(problem.error(_ours(problem, method, **options)[0], reference), answers.error(options))
        return errors[at]

    if kept is not None:
        kept[scene.content] = error_of, answers.named
    return error_of, answers.named


def _check(scene: Scene, method: str, options: dict[str, float], tolerance: float,
           measures: dict[str, Any] | None = None) -> tuple[dict[str, float], str, bool | None]:
    """A setting taken from work–precision data, checked on this scene's own problem (one revolution
    of level 2, the clutch stand's span) against dp45 at :data:`CHECK_RTOL`: its error here, and the tolerance
    tightened by :data:`TIGHTER` until the error is within ``tolerance`` (at most :data:`CHECK_STEPS` times) — the
    data's error is not this scene's (the as-tested machine at 300 rpm: 1.5e-5 with the nominal machine's setting).
    Fixed-step settings are checked, not changed. (options, what the check found in words, whether ``tolerance`` is
    met — None: not checked, the problem cannot be run there); ``measures``: as :func:`_measure` keeps them."""
    try:
        error_of, named = _measure(scene, method, measures)
        tried = dict(options)
        for step in range(CHECK_STEPS + 1):
            error = error_of(tried)
            if error <= tolerance or method in FIXED or "rtol" not in tried:
                break
            if step < CHECK_STEPS:
                tried = {k: v * TIGHTER if k in ("rtol", "atol") else v for k, v in tried.items()}
    except (SceneError, SolverDivergence, ValueError) as exc:
        return options, f"not checked at this operating point ({' '.join(str(exc).split())[:160]})", None
    setting = " ".join(f"{k}={v:.3g}" for k, v in tried.items() if k != "atol")
    of = f" (in e{named})" if named else ""
    if error <= tolerance:
        if tried == options:
            return options, f"checked at this operating point: error {error:.1e}{of}", True
        return tried, (f"at this operating point that setting misses {tolerance:g}{of}: tightened to {setting}, "
                       f"error {error:.1e}"), True
    return tried, (f"at this operating point no setting down to {setting} reaches {tolerance:g}{of} (error "
                   f"{error:.1e}): the run is less accurate than the scene asks"), False


class _Answers:
    """The level-2 answers to a cam-bar scene's questions (:mod:`rig.plants.cam_bar.level_answers`: one revolution of
    its nominal machine) at a solver setting against those at :data:`CHECK_RTOL`: the error of the run's answers
    themselves, not only of the deviation e the work–precision data measure (a dwell vibration of 2e-8 m read 5.9e-5
    off at a setting whose error in e was 7.7e-7). Counts must be equal (an error of 1 where they differ)."""

    def __init__(self, scene: Scene, method: str, atol_scale: float):
        from rig.fidelity import RUNNABLE
        plant = scene.section("scene").get("plant")
        asked = [q for q in scene.section("scene").get("questions", []) if q != "stroke"]    # L0's: exact
        self.method = RUNNABLE.get(plant, {}).get(method)
        self.asked = asked if plant == "cam_bar" and self.method is not None else []
        self.named = "".join(f", {q}" for q in self.asked)
        self.scene = scene
        self.reference = self._answers("DP45", {"rtol": CHECK_RTOL, "atol": CHECK_RTOL * atol_scale}) \
            if self.asked else {}

    def _answers(self, method: str, options: dict[str, float]) -> dict[str, float]:
        """Level 2's answers with ``method`` at ``options``; an adaptive method's stiffness test off, as in the
        work–precision runs (DP45 and DOP853 are stability-limited on the contact, still accurate: the check would
        warn where the run itself does not)."""
        from rig.plants.cam_bar.level_answers import LevelRuns
        quiet = {} if "h" in options else {"stiffness": "ignore"}
        return LevelRuns(self.scene, method, {**options, **quiet}).answers(2)

    def error(self, options: dict[str, float]) -> float:
        """The largest relative error of the answers at ``options`` (a fixed-step method's ``h`` or rtol/atol); 1 for a
        count that differs, an answer that is NaN where the reference's is not, or a nonzero one against zero."""
        if not self.asked:
            return 0.0
        got = self._answers(self.method, options)
        worst = 0.0
        for q in self.asked:
            a, r = got[q], self.reference[q]
            if math.isnan(a) or math.isnan(r):
                worst = max(worst, 0.0 if math.isnan(a) and math.isnan(r) else 1.0)
            elif q == "flank_switches" or r == 0.0:
                worst = max(worst, 0.0 if a == r else 1.0)
            else:
                worst = max(worst, abs(a - r) / abs(r))
        return worst

"""A solver setting taken from work–precision data (another scene's, or a file of this scene's name), checked on
this scene's own problem (:data:`rig.fidelity.SETTING_CHECK`)."""
from __future__ import annotations

import math

from rig.bench.harness import FIXED, _ours
from rig.bench.problems import problem_of
from rig.scene import Scene, SceneError
from rig.solvers import SolverDivergence

TIGHTER = 10 ** -0.5       # factor on rtol (and atol) per step when a setting misses the tolerance at this point
CHECK_STEPS = 6           # at most this many tighter settings (3 decades)
CHECK_RTOL = 1e-10        # the check's reference: dp45 at this tolerance


_found: dict[tuple, tuple[dict[str, float], str]] = {}     # per scene content and setting: a sweep asks per point


def at_this_point(scene: Scene, method: str, options: dict[str, float],
                  tolerance: float) -> tuple[dict[str, float], str]:
    """:func:`_check`, once per scene content, method, options and tolerance (a process runs it again for every
    ``rig.fidelity.choose`` of the same scene: a sweep three times per point)."""
    key = (scene.content, method,
           tuple(sorted(options.items())), tolerance)
    if key not in _found:
        _found[key] = _check(scene, method, options, tolerance)
    options, said = _found[key]
    return dict(options), said


def _check(scene: Scene, method: str, options: dict[str, float],
           tolerance: float) -> tuple[dict[str, float], str]:
    """A setting taken from work–precision data, checked on this scene's own problem (one revolution
    of level 2, the clutch stand's span) against dp45 at :data:`CHECK_RTOL`: its error here, and the tolerance
    tightened by :data:`TIGHTER` until the error is within ``tolerance`` (at most :data:`CHECK_STEPS` times) — the
    data's error is not this scene's (the as-tested machine at 300 rpm: 1.5e-5 with the nominal machine's setting).
    Fixed-step settings are checked, not changed. (options, what the check found, in words)."""
    try:
        problem = problem_of(scene, checked=False)
        reference = _ours(problem, "dp45", rtol=CHECK_RTOL, atol=CHECK_RTOL * problem.atol_scale)[0]
        answers = _Answers(scene, method, problem.atol_scale)
        tried = dict(options)
        for step in range(CHECK_STEPS + 1):
            error = max(problem.error(_ours(problem, method, **tried)[0], reference), answers.error(tried))
            if error <= tolerance or method in FIXED or "rtol" not in tried:
                break
            if step < CHECK_STEPS:
                tried = {k: v * TIGHTER if k in ("rtol", "atol") else v for k, v in tried.items()}
    except (SceneError, SolverDivergence, ValueError) as exc:
        return options, f"not checked at this operating point ({' '.join(str(exc).split())[:160]})"
    setting = " ".join(f"{k}={v:.3g}" for k, v in tried.items() if k != "atol")
    of = f" (in e{answers.named})" if answers.named else ""
    if error <= tolerance:
        if tried == options:
            return options, f"checked at this operating point: error {error:.1e}{of}"
        return tried, (f"at this operating point that setting misses {tolerance:g}{of}: tightened to {setting}, "
                       f"error {error:.1e}")
    return tried, (f"at this operating point no setting down to {setting} reaches {tolerance:g}{of} (error "
                   f"{error:.1e}): the run is less accurate than the scene asks")


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

"""Fidelity chosen by the question: the lowest model level that answers a scene's questions, and for a
dynamic level the cheapest solver setting that reaches the scene's tolerance in the work–precision data.

A scene states what it asks (``[scene] questions = ["stroke", "dwell_vibration"]``) and how exactly: the
solver's relative error (``[scene] tolerance``, default 1e-6) and how far a lower model level may be from the
dynamic one (``[scene] model_tolerance``, relative, default 5 %; a count must be equal). The question table gives
the lowest level that can answer at all; where the plant has a check (:data:`CHECKS`, the cam bar's: one
revolution of the nominal machine at the lower level and at level 2), a lower level whose answer is beyond the
model tolerance of level 2's at the scene's operating point is not trusted: the scene runs at level 2, and the
reason says which answer differed by how much. ``[scene] fidelity`` or ``--fidelity N`` force a level instead;
a forced level that cannot answer a stated question, or whose answers the check contradicts, is reported
(warning), not silently used. The work–precision data are ``data/work_precision/<scene-stem>.csv`` (``rig bench
work-precision``; columns method, setting, error, wall_s, nfev, t_sim, status), else the plant's reference problem's
file.
"""
from __future__ import annotations

import csv
import importlib
import logging
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

from rig.scene import Scene, SceneError

log = logging.getLogger(__name__)
DATA = Path(__file__).resolve().parents[1] / "data" / "work_precision"
LEVEL_NAMES = {0: "kinematic", 1: "kinetostatic", 2: "dynamic"}
#: question → lowest level that answers it, per plant kind (the clutch stand has one, dynamic, model)
QUESTIONS: dict[str, dict[str, int]] = {
    "cam_bar": {"stroke": 0, "rod_force": 1, "flank_switches": 1, "dwell_vibration": 2},
    "clutch_dynamic": {"disengagements": 2, "shutdown": 2, "torque": 2, "speed": 2},
    "clutch_static": {"characteristic": 1},
}
WHY = {"stroke": "the stroke is the cam program's kinematics",
       "rod_force": "the rod force needs the kinetostatic load balance",
       "flank_switches": "a flank switch is a sign change of the kinetostatic contact force",
       "dwell_vibration": "vibration in the dwell needs the groove dynamics with clearance",
       "disengagements": "disengagement is a dynamic event of the stand",
       "shutdown": "shutdown follows dynamic disengagements", "torque": "the stand torque is dynamic",
       "speed": "the stand speed is dynamic", "characteristic": "the static characteristic is a load balance"}
#: levels each plant kind has, its default level, and the work–precision data of its reference problem
LEVELS = {"cam_bar": (0, 1, 2), "clutch_dynamic": (2,), "clutch_static": (1,)}
DEFAULT_LEVEL = {"cam_bar": 1, "clutch_dynamic": 2, "clutch_static": 1}
REFERENCE_DATA = {"cam_bar": "pin_insertion_l2", "clutch_dynamic": "clutch_startup"}
#: work–precision method names → names of rig.solvers.METHODS the plant's integration can run
RUNNABLE = {"cam_bar": {"euler": "Euler", "semi-implicit euler": "SymplecticEuler", "rk4": "RK4", "dp45": "DP45", "tsit5": "Tsit5",
                        "dop853": "DOP853", "rodas4": "Rodas4"},
            "clutch_dynamic": {"dp45": "DP45", "tsit5": "Tsit5", "dop853": "DOP853", "rodas4": "Rodas4"}}   # the stand takes rtol/atol
#: atol = rtol · scale of each plant's dynamic problem (its state's magnitude; the work–precision harness's)
ATOL_SCALE = {"cam_bar": 1e-5, "clutch_dynamic": 1e-3}
#: the integration setting of a scene that states no questions or tolerance, or that no data answer: the
#: plant's own (the cam bar's level-2 default; the clutch's [plant] rtol/atol, given as no options here)
DEFAULT_METHOD = {"cam_bar": ("DP45", {"rtol": 1e-7, "atol": 1e-12}), "clutch_dynamic": ("DP45", {})}
NAMES = {"kinematic": 0, "kinetostatic": 1, "dynamic": 2}
#: plant kind → "module:function" comparing a lower level's answers with level 2's at the scene's operating point:
#: ``function(scene, level, questions, method, options) -> [deviation]``, each with ``beyond(tolerance)``,
#: ``describe()`` (:func:`rig.plants.cam_bar.level_answers.compare`)
CHECKS = {"cam_bar": "rig.plants.cam_bar.level_answers:compare"}
#: checks a setting taken from work–precision data on this scene's own problem (by name: the
#: benchmark code builds on this module)
SETTING_CHECK = "rig.bench.setting_check:at_this_point"
MODEL_TOLERANCE = 0.05
_checked: dict[tuple, list] = {}       # compare()'s answers per scene content, level and questions (choose runs often)
_level2_runs = 0                       # level-2 computations a choice made (the check, a setting check): kept on disk
#: levels whose runs are the same for a plant (the cam bar: the force sensor needs the level-1 loads at level 0 too)
SAME_RUN = {"cam_bar": (0, 1)}


@dataclass(frozen=True)
class Fidelity:
    """The level a run uses (0 kinematic, 1 kinetostatic, 2 dynamic), why, and its solver setting
    (``method`` a name of :data:`rig.solvers.METHODS`, ``options`` rtol/atol or h; None below level 2)."""

    level: int
    reason: str
    method: str | None = None
    options: Mapping[str, float] = field(default_factory=dict)
    unanswered: tuple[str, ...] = ()
    short_of: str = ""      # why the scene's tolerance is not met (no setting in the data reaches it), else ""
    caveat: str = ""        # what a forced level below the questions' need means for the run, else ""

    @property
    def method_text(self) -> str:
        """``"DP45 rtol=1e-07 atol=1e-12"``, or ``"none (no integration)"`` below level 2."""
        if self.method is None:
            return "none (no integration)"
        return " ".join([self.method, *(f"{k}={v:g}" for k, v in self.options.items())])

    def describe(self) -> str:
        """One line for the console."""
        return (f"fidelity L{self.level} ({LEVEL_NAMES[self.level]}): {self.reason}; method {self.method_text}"
                + (f"; cannot answer {', '.join(self.unanswered)}" if self.unanswered else ""))


def parse_level(value: Any, what: str) -> int:
    """0/1/2 or "kinematic"/"kinetostatic"/"dynamic" as a level; a :class:`SceneError` naming ``what``."""
    level = NAMES.get(value, value) if isinstance(value, str) else value
    if isinstance(level, bool) or level not in (0, 1, 2):
        raise SceneError(f"{what} must be 0, 1, 2 or one of {', '.join(NAMES)}, got {value!r}")
    return int(level)


def _questions(scene: Scene, plant: str, where: str) -> list[str]:
    asked = scene.section("scene").get("questions", [])
    if not isinstance(asked, list) or not all(isinstance(q, str) for q in asked):
        raise SceneError(f"{where}: 'questions' must be a list of strings, got {asked!r}")
    known = QUESTIONS.get(plant, {})
    for q in asked:
        if q not in known:
            other = [k for k, table in QUESTIONS.items() if q in table]
            hint = f" (a question for a {other[0]} scene)" if other else ""
            raise SceneError(f"{where}: question {q!r} is not one a {plant} scene can answer{hint}; "
                             f"its questions: {', '.join(known) or 'none'}")
    return asked


def _tolerance(scene: Scene, where: str, key: str = "tolerance", default: float = 1e-6) -> float:
    from rig.units import UnitError, to_si
    value = scene.section("scene").get(key, default)
    wanted = f"{where}: '{key}' is a relative error in (0, 1) such as 0.05 or \"5 %\", got {value!r}"
    try:
        tol = to_si(value, "", what=f"{where}: {key}")
    except UnitError:
        raise SceneError(wanted) from None
    if not 0.0 < tol < 1.0:
        raise SceneError(wanted)
    return tol


def _options(setting: str, atol_scale: float) -> dict[str, float]:
    """``"rtol=1e-07"`` / ``"h=2e-05"`` (a work–precision setting) as solver options."""
    out = {}
    for part in setting.split():
        key, _, value = part.partition("=")
        out[key] = float(value)
    if "rtol" in out and "atol" not in out:
        out["atol"] = out["rtol"] * atol_scale
    return out


#: wall times within this fraction of the least are a tie, decided by the fewer RHS calls (a count, the same on every
#: machine): the machine's speed moves by more than that between runs, and a 0.4 % lead chose Tsit5 at 38 % more
#: calls than DP45 on the clutch start-up
TIE = 0.05


def cheapest(path: Path, tolerance: float, runnable: Mapping[str, str],
             atol_scale: float) -> tuple[str, dict[str, float], dict] | None:
    """The runnable row of a work–precision CSV with status ok and error ≤ ``tolerance`` and the least
    wall time — of the rows within :data:`TIE` of it, the one with the fewest RHS calls: (method, options, row);
    None when no row qualifies (nor any runnable row at all)."""
    rows = _rows(path, runnable, lambda error: error <= tolerance)
    if not rows:
        return None
    fastest = min(float(r["wall_s"]) for r in rows)
    tied = [r for r in rows if float(r["wall_s"]) <= fastest * (1.0 + TIE)]
    best = min(tied, key=lambda r: (float(r["nfev"] or math.inf), float(r["wall_s"])))
    return runnable[best["method"]], _options(best["setting"], atol_scale), best


def most_accurate(path: Path, runnable: Mapping[str, str], atol_scale: float) -> tuple[str, dict[str, float], dict] | None:
    """The runnable row of a work–precision CSV with status ok and the least error: (method, options, row)."""
    rows = _rows(path, runnable, lambda error: True)
    if not rows:
        return None
    best = min(rows, key=lambda r: float(r["error"]))
    return runnable[best["method"]], _options(best["setting"], atol_scale), best


def _rows(path: Path, runnable: Mapping[str, str], admits: Callable[[float], bool]) -> list[dict]:
    """The rows of a work–precision CSV with status ok, a runnable method and a finite error ``admits`` accepts."""
    with path.open(newline="", encoding="utf-8") as f:
        return [row for row in csv.DictReader(f) if row.get("status") == "ok" and row.get("method") in runnable
                and math.isfinite(float(row["error"])) and admits(float(row["error"]))]


def _method(scene: Scene, plant: str, tolerance: float,
            data: Path) -> tuple[str, dict[str, float], str, str]:
    """(method, options, why, short_of): the cheapest setting of the work–precision data that reaches ``tolerance``;
    where none does, the most accurate one and ``short_of`` saying so."""
    runnable = RUNNABLE.get(plant, {})
    own = data / f"{Path(scene.path).stem}.csv"
    for path in (own, data / f"{REFERENCE_DATA.get(plant, '')}.csv"):
        if path.is_file():
            found = cheapest(path, tolerance, runnable, ATOL_SCALE[plant])
            if found is not None:
                method, options, row = found
                per_second = float(row["wall_s"]) / float(row["t_sim"])
                why = (f"the cheapest setting with error <= {tolerance:g} in {path.name} (error "
                       f"{float(row['error']):.1e}, {per_second * 1e3:.1f} ms per simulated s)")
                # checked at this operating point, the scene's own data too: a file of its name may have been
                # measured on another machine (an edited copy, a sweep's variant: 1.3e-6 … 2.4e-6 against 1e-6 were
                # trusted unchecked until 2026-11-29, an audit)
                _ran_level2()
                module, _, name = SETTING_CHECK.partition(":")
                options, here, met = getattr(importlib.import_module(module), name)(scene, row["method"], options,
                                                                                   tolerance)
                return method, options, f"{why}; {here}", "" if met else f"fidelity: {here}"
            found = most_accurate(path, runnable, ATOL_SCALE[plant])
            if found is not None:
                method, options, row = found
                short = (f"no setting in {path.name} reaches the scene's tolerance {tolerance:g}: this run uses the "
                         f"most accurate one there, error {float(row['error']):.1e}")
                return method, options, short, short
            method, options = _default_method(scene, plant)
            return method, options, f"no runnable setting in {path.name}; the plant's default", ""
    method, options = _default_method(scene, plant)
    return method, options, "no work-precision data for this scene; the plant's default", ""


def _default_method(scene: Scene, plant: str) -> tuple[str, dict[str, float]]:
    """The plant's default method and options, the method as its scene names it (a clutch stand's [plant] method)."""
    method, options = DEFAULT_METHOD[plant]
    return scene.section("plant").get("method", method), dict(options)


def choose(scene: Scene, plant: str, forced: int | None = None, data: Path = DATA) -> Fidelity:
    """The fidelity of a run of ``scene`` (a ``plant`` kind): ``forced`` (``--fidelity``) first, then
    ``[scene] fidelity``, then the lowest level answering ``[scene] questions``, else the plant's default. A choice
    that ran level 2 to decide (the check against level 2, a setting checked at this operating point: 0.5–1 s) is
    kept on disk for the next command on the same scene (:mod:`rig.fidelity_cache`)."""
    from rig import fidelity_cache
    key = fidelity_cache.key(scene, plant, forced, data)
    kept = fidelity_cache.read(key)
    if kept is not None:
        try:
            return Fidelity(**{**kept, "unanswered": tuple(kept["unanswered"])})
        except (TypeError, KeyError):       # not a choice (damaged, or another version's fields): computed
            pass
    before = _level2_runs
    chosen = _choose(scene, plant, forced, data)
    if _level2_runs > before:
        fidelity_cache.write(key, asdict(chosen))
    return chosen


def _ran_level2() -> None:
    """Count a level-2 computation of a choice (its result is then worth keeping on disk)."""
    global _level2_runs
    _level2_runs += 1


def check_scene(scene: Scene, plant: str) -> None:
    """The scene's [scene] questions, fidelity and tolerances checked as :func:`choose` reads them, without choosing
    (a command that does not run the plant: ``rig summary``, ``rig tolerance`` took ``fidelity = 7`` without a word)."""
    where = f"{scene.path} [scene]"
    _questions(scene, plant, where)
    explicit = scene.section("scene").get("fidelity")
    if explicit is not None:
        _offered(plant, parse_level(explicit, f"{where}: 'fidelity'"), where, "fidelity")
    _tolerance(scene, where)
    _tolerance(scene, where, "model_tolerance", MODEL_TOLERANCE)


def _offered(plant: str, level: int, where: str, given: str | None) -> None:
    """SceneError unless ``plant`` has model ``level``; ``given``: what set it ("fidelity", "--fidelity"; None: the
    questions)."""
    levels = LEVELS.get(plant, (1,))
    if level in levels:
        return
    has = f"only level {levels[0]}" if len(levels) == 1 else f"levels {', '.join(map(str, levels))}"
    if given is None:
        raise SceneError(f"{where}: a {plant} plant has {has}, not {level}")
    raise SceneError(f"{where}: a {plant} plant has {has}; {given} {level} is not one of them")


def _choose(scene: Scene, plant: str, forced: int | None, data: Path) -> Fidelity:
    """:func:`choose`, computed."""
    where = f"{scene.path} [scene]"
    asked = _questions(scene, plant, where)
    levels = LEVELS.get(plant, (1,))
    need = {q: QUESTIONS[plant][q] for q in asked}
    explicit = scene.section("scene").get("fidelity")
    if forced is not None:
        level, reason = parse_level(forced, "--fidelity"), f"forced by --fidelity {forced}"
    elif explicit is not None:
        level, reason = parse_level(explicit, f"{where}: 'fidelity'"), f"[scene] fidelity = {explicit!r}"
    elif asked:
        level = max(need.values())
        top = [q for q in asked if need[q] == level]
        reason = f"lowest level answering {', '.join(asked)} ({'; '.join(WHY[q] for q in top)})"
    else:
        level, reason = DEFAULT_LEVEL.get(plant, 1), "no questions stated; the plant's default level"
    _offered(plant, level, where, "--fidelity" if forced is not None else "fidelity" if explicit is not None else None)
    unanswered = tuple(q for q in asked if need[q] > level)
    caveat = _and(_caveat(plant, level, {q: need[q] for q in unanswered}), _left_out(scene, plant, level))
    # the level whose answers the run gives: the cam bar's level 0 runs level 1's loads (SAME_RUN), so check those
    ran = max(SAME_RUN[plant]) if level in SAME_RUN.get(plant, ()) else level
    if ran < 2 and 2 in levels and plant in CHECKS and any(need[q] <= ran for q in asked):
        tolerance = _tolerance(scene, where, "model_tolerance", MODEL_TOLERANCE)
        deviations = _check(scene, plant, ran, [q for q in asked if need[q] <= ran])
        if isinstance(deviations, str):                 # level 2 failed at this operating point: unchecked, said
            caveat = _and(caveat, f"L{ran}'s answers are not checked against level 2, which failed at this operating "
                                  f"point ({deviations})")
            deviations = []
        beyond = [d for d in deviations if d.beyond(tolerance)]
        said = "; ".join(d.describe() for d in beyond)
        if beyond and forced is None and explicit is None:
            level, unanswered, caveat = 2, (), ""
            reason += (f"; but at this operating point level 2 contradicts it, beyond the model tolerance "
                       f"{_percent(tolerance)}: {said}; so level 2")
        elif beyond:
            caveat = _and(caveat, f"at this operating point level 2 contradicts L{ran}'s answers, beyond the model "
                                  f"tolerance {_percent(tolerance)}: {said}; read them as the lower model's, not the "
                                  "machine's")
        elif deviations:
            whose = "" if ran == level else f" with the level-{ran} answers this run computes"
            reason += (f"; level 2 agrees{whose} within the model tolerance {_percent(tolerance)} at this operating "
                       "point (" + ", ".join(f"{d.question} {d.text()}" for d in deviations) + ")")
    if level < 2:
        return Fidelity(level, reason, unanswered=unanswered, caveat=caveat)
    short_of = ""
    if asked or "tolerance" in scene.section("scene"):
        method, options, why, short_of = _method(scene, plant, _tolerance(scene, where), data)
    else:
        (method, options), why = _default_method(scene, plant), "no questions or tolerance stated; the plant's own setting"
    return Fidelity(level, f"{reason}; {method}: {why}", method, dict(options), unanswered, short_of, caveat)


def _and(*parts: str) -> str:
    """The non-empty ``parts`` joined by "; " (caveats added to one another)."""
    return "; ".join(p for p in parts if p)


def _percent(fraction: float) -> str:
    """``0.05`` as ``"5 %"``."""
    return f"{fraction * 100:.3g} %"


def _check(scene: Scene, plant: str, level: int, questions: list[str]) -> list | str:
    """The plant's :data:`CHECKS` function's deviations of ``level``'s answers to ``questions`` from level 2's (level 2
    with the setting the scene gets there), computed once per scene content; where level 2 cannot be run there (a
    divergence, an impossible position), why, in one line — the lower level is then used unchecked, and said so."""
    from rig.solvers import SolverDivergence
    key = (plant, scene.content, level, tuple(questions))
    if key not in _checked:                  # level 2's setting follows from the scene's content too
        top = choose(scene, plant, forced=2)
        module, _, name = CHECKS[plant].partition(":")
        try:
            _ran_level2()
            _checked[key] = getattr(importlib.import_module(module), name)(scene, level, questions, top.method,
                                                                          top.options)
        except (SolverDivergence, ArithmeticError, ValueError) as exc:
            if isinstance(exc, SceneError):
                raise
            _checked[key] = " ".join(str(exc).split())
    return _checked[key]


def _caveat(plant: str, level: int, unanswered: Mapping[str, int]) -> str:
    """What a level below the questions' need (``unanswered``: question -> level it needs) means for a run of the
    plant: the cam bar's runs at levels 0 and 1 are the same (the force sensor needs the level-1 loads), so its
    measurements stay level 1's; a question that needs level 2 is not simulated at all."""
    if not unanswered:
        return ""
    need = ", ".join(f"{q} (needs L{n})" for q, n in unanswered.items())
    if plant in SAME_RUN and level in SAME_RUN[plant] and max(unanswered.values()) in SAME_RUN[plant]:
        return (f"fidelity L{level} is below what the scene asks: {need}; a {plant} run computes the level-1 loads "
                f"anyway (levels {' and '.join(map(str, SAME_RUN[plant]))} simulate the same run), so its "
                f"measurements are level {max(SAME_RUN[plant])}'s; level {level} only answers less in the summaries")
    return (f"fidelity L{level} is below what the scene asks: {need}; this run does not simulate what they need: "
            f"read nothing about them from it")


def _left_out(scene: Scene, plant: str, level: int) -> str:
    """What of the scene a lower level does not simulate at all, said: the cam bar's motor drive ([plant.drive]:
    start-up, speed ripple) exists at level 2 only — levels 0 and 1 turn the cam at the speed profile's speed."""
    if plant == "cam_bar" and level < 2 and scene.section("plant").get("drive") is not None:
        return ("levels 0 and 1 turn the cam at the speed profile's constant speed: the scene's motor drive "
                "([plant.drive]: the start-up, the speed ripple, the shaft) is simulated at level 2 only")
    return ""


def announce(fidelity: Fidelity) -> None:
    """The choice as one console line; a warning naming the questions a forced level cannot answer."""
    log.info("%s", fidelity.describe().split("; cannot answer")[0])
    if fidelity.short_of:
        log.warning("%s", fidelity.short_of)
    if fidelity.caveat:
        log.warning("%s", fidelity.caveat)

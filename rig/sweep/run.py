"""Running a sweep: grid points grouped into tasks (about 8 per worker), rows back in grid order, a CSV table.

A point's result depends on the point only, so the grouping (which follows the number of workers) cannot
change it."""
from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence

from rig.executors import batches
from rig.outputs import UsageError
from rig.scene import ImpossibleGeometry, Scene, SceneError
from rig.sweep import Param, check_units, grid, with_overrides
from rig.sweep.metrics import METRICS, check_levels, check_metrics, run_plant

if TYPE_CHECKING:
    from rig.executors import Executor


REVOLUTIONS = 2          # cam revolutions per cam-bar point by default (metrics over the last)


@dataclass(frozen=True)
class PointTask:
    """One grid point: the scene, its overrides (dotted key → value) and the metrics wanted."""

    scene: Scene
    overrides: dict[str, Any]
    metrics: tuple[str, ...]
    revolutions: int


def run_points(tasks: list[PointTask]) -> list[tuple[dict[str, float], str]]:
    """:func:`run_point` of several points (one executor task: a level-2 point takes only ~50 ms)."""
    return [run_point(task) for task in tasks]


def run_point(task: PointTask) -> tuple[dict[str, float], str]:
    """The point's metrics, and '' or why its run failed (then every metric is NaN) or why a metric failed (that one
    NaN, named: ``"ok_share: …"``; the others keep their values)."""
    from rig.plants.cam_bar.chain import SingularPositionError
    from rig.solvers import SolverDivergence
    failures = (SceneError, SolverDivergence, SingularPositionError, ValueError)
    try:
        run = run_plant(with_overrides(task.scene, task.overrides), task.revolutions)
    except failures as exc:
        return {m: math.nan for m in task.metrics}, " ".join(str(exc).split())
    values, errors = {}, []
    for m in task.metrics:
        try:
            values[m] = METRICS[m].compute(run)
        except failures as exc:
            values[m] = math.nan
            errors.append(f"{m}: {' '.join(str(exc).split())}")
    return values, "; ".join(errors)


@dataclass(frozen=True)
class SweepResult:
    """The grid (one tuple of values per point, in the order of ``params``), each point's metrics, error and model
    level (:mod:`rig.fidelity`)."""

    params: tuple[Param, ...]
    metrics: tuple[str, ...]
    points: list[tuple[Any, ...]]
    values: list[dict[str, float]]
    errors: list[str]
    levels: list[int]


def run_sweep(scene: Scene, params: Sequence[Param], metrics: Sequence[str], executor: "Executor",
              revolutions: int | None = None, fidelity: int | None = None,
              starting: Callable[[], object] = lambda: None,
              progress: Callable[[int], object] = lambda points: None) -> SweepResult:
    """Every grid point of ``params`` on ``executor``, at the model level ``fidelity`` (``--fidelity``; default:
    each point's own, :func:`rig.fidelity.choose`); scene and metric errors, and metrics a point's level cannot
    answer (:func:`rig.sweep.metrics.check_levels`), are raised before anything runs (:func:`_check_buildable`); a
    point whose run fails gets NaN metrics and its error. ``starting()`` runs when every check has passed, before the
    points run (the command's line naming the executor: an error stays one line); ``progress(k)`` as each task's
    ``k`` points are done."""
    from rig.runner.config import read_config
    from rig.runner.plants import make_plant
    if not params or not metrics:
        raise ValueError("a sweep needs at least one --param and one --metric")
    plant = read_config(scene, choose_level=False).plant      # each point chooses its own level as it is built
    if revolutions is not None and plant != "cam_bar":
        raise ValueError(f"--revolutions counts cam revolutions of a cam-bar scene; {scene.path} is a {plant} scene "
                         "(its run lasts its [scene] duration)")
    revolutions = REVOLUTIONS if revolutions is None else revolutions
    if revolutions < 1:
        raise ValueError(f"a sweep needs at least 1 revolution, got {revolutions}")
    check_metrics(list(metrics), plant)
    check_units(scene, params)
    scene = _forced(scene, params, fidelity)
    points = grid(params)
    tasks = [PointTask(scene, {p.key: v for p, v in zip(params, point)}, tuple(metrics), revolutions)
             for point in points]
    levels = [point_level(task, plant) for task in tasks]
    check_levels(list(metrics), levels, str(scene.path) + (f" with --fidelity {fidelity}" if fidelity is not None
                                                           else ""))
    _check_buildable(tasks, make_plant, read_config, "ok_share" in metrics)
    starting()
    results: list[tuple[dict[str, float], str]] = []

    def result(done: int) -> SweepResult:
        return SweepResult(tuple(params), tuple(metrics), points[:done], [r[0] for r in results],
                           [r[1] for r in results], levels[:done])
    try:
        for part in executor.map(run_points, batches(tasks, executor.workers)):
            results += part
            progress(len(part))
    except KeyboardInterrupt as exc:
        raise SweepInterrupted(result(len(results)), len(points)) from exc
    return result(len(points))


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep: ``result`` holds the points done before it (the first of the grid, in order), of
    ``total``."""

    def __init__(self, result: SweepResult, total: int):
        super().__init__()
        self.result, self.total = result, total


def _forced(scene: Scene, params: Sequence[Param], fidelity: int | None) -> Scene:
    """The scene with ``[scene] fidelity`` set to ``fidelity`` (``--fidelity``; unchanged for None); a ValueError
    when a parameter sweeps that key too."""
    if fidelity is None:
        return scene
    if any(p.key == "scene.fidelity" for p in params):
        raise ValueError("--fidelity and --param scene.fidelity=… both set the model level: give one")
    return with_overrides(scene, {"scene.fidelity": fidelity})


def point_level(task: PointTask, plant: str) -> int:
    """The model level a point runs at (:func:`rig.fidelity.choose` on its scene, as ``rig run`` chooses)."""
    from rig.fidelity import choose
    try:
        return choose(with_overrides(task.scene, task.overrides), plant).level
    except SceneError:
        return choose(task.scene, plant).level      # the override's own error is raised by _check_buildable


def _check_buildable(tasks: list[PointTask], make_plant: Any, read_config: Any, device: bool = False) -> None:
    """Build every point's plant (``device``: and its acquisition unit's program, for ``ok_share``) before anything
    runs: a value the scene refuses (a negative rate, a NaN, a key the scene cannot take, a sample rate the unit's
    program cannot take) is an input error raised here, naming the point, wherever it lies in the grid; a point that
    cannot be built for its physics (an impossible geometry) is left to :func:`run_point`, which records it as a
    failed point — unless no point builds at all, then the first point's error is raised."""
    from rig.plants.cam_bar.chain import SingularPositionError
    first: Exception | None = None
    built = False
    for task in tasks:
        try:
            point = with_overrides(task.scene, task.overrides)
            cfg = read_config(point)
            make_plant(cfg.plant, point, nominal=True)
            if device:
                from rig.runner.machine import instruments
                instruments(cfg)
            built = True
        except ImpossibleGeometry as exc:
            first = first or exc
        except SceneError as exc:
            given = _given(str(exc), task.overrides)
            if given:
                raise UsageError(given) from None
            if len(tasks) == 1:
                raise
            where = ", ".join(f"{k} = {v}" for k, v in task.overrides.items())
            raise SceneError(f"sweep point {where}: {exc}") from None
        except (SingularPositionError, ValueError) as exc:
            first = first or exc
    if not built:
        assert first is not None
        raise first


def _given(message: str, overrides: dict[str, Any]) -> str:
    """The scene reader's ``message`` about a key a ``--param`` set ("… [plant]: key 'J3': 0.02 has no unit …") as
    that option's error ("--param plant.J3=0.02: 0.02 has no unit …": the value given is wrong, not the scene file);
    "" when it is about another key."""
    for key, value in overrides.items():
        section, _, name = key.rpartition(".")
        head = f"[{section}]: key '{name}'"
        if head in message:
            return f"--param {key}={value}: {message.split(head, 1)[1].lstrip(': ')}"
        twice = re.search(rf"\[{re.escape(section)}\]: '(\w+)' is given twice \(as '(\w+)' and '(\w+)'\)", message)
        if twice and name in twice.group(2, 3):
            written = next(k for k in twice.group(2, 3) if k != name)
            return (f"--param {key}={value}: {name!r} is another spelling of {twice[1]!r}, which the scene already "
                    f"writes as {written!r}: sweep {section}.{written} (one spelling per quantity)")
    return ""


def inert_params(result: SweepResult) -> list[str]:
    """The keys of the parameters that changed nothing: among points that differ only in that parameter's value, every
    metric is the same (NaN equal to NaN); a sweep over such a key (an assembly-branch selector, a key the metrics do
    not depend on) says nothing, and the console says so."""
    inert: list[str] = []
    if not any(math.isfinite(v) for values in result.values for v in values.values()):
        return inert                    # every point failed: nothing was measured, so nothing is said to be inert
    for i, param in enumerate(result.params):
        if len(param.values) < 2:
            continue
        groups: dict[tuple, set[tuple]] = {}
        for point, values in zip(result.points, result.values):
            rest = point[:i] + point[i + 1:]
            groups.setdefault(rest, set()).add(tuple(repr(values[m]) for m in result.metrics))
        if all(len(seen) == 1 for seen in groups.values()):
            inert.append(param.key)
    return inert


def levels_text(levels: Sequence[int]) -> str:
    """The model levels of a sweep's points: "2", or "1 and 2" when a parameter varies it."""
    distinct = [str(lv) for lv in sorted(set(levels))]
    return " and ".join([", ".join(distinct[:-1]), distinct[-1]] if len(distinct) > 1 else distinct)


def cell(metric: str, value: float) -> str:
    """A metric's CSV cell: a count or flag (:attr:`Metric.integer`) as a whole number ("2", not "2.0"), other
    values in the metric's display unit with every digit (``repr``); a failed point's NaN as ``nan``."""
    if METRICS[metric].integer and math.isfinite(value):
        return str(int(value))
    return repr(float(METRICS[metric].display(value)))


def write_table(result: SweepResult, path: Path) -> Path:
    """CSV: one row per point, a column per parameter (values as given), ``level`` (the point's model level), per
    metric (in its display unit, :attr:`Metric.display`, named in the header; counts as whole numbers, :func:`cell`)
    and ``error``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        out = csv.writer(f)
        header = [f"{m} [{METRICS[m].display.ascii or 1}]" for m in result.metrics]
        out.writerow([p.key for p in result.params] + ["level"] + header + ["error"])
        for point, level, values, error in zip(result.points, result.levels, result.values, result.errors):
            out.writerow(list(point) + [level] + [cell(m, values[m]) for m in result.metrics] + [error])
    return path

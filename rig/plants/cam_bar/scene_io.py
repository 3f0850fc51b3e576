"""Scene reading for the cam-bar plant: [plant] (with [[plant.cam_program]], [plant.variation]) and [speed].

Other top-level sections belong to other modules and are ignored here; inside [plant], [speed] and each
cam-program table every key is checked (unknown, missing, wrong unit → :class:`rig.scene.SceneError`).
"""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

from rig.motion.program import CamProgram, ProgramError, Segment
from rig.motion.speed import ConstantSpeed, RampSpeed, SinusoidalSpeed, SpeedProfile
from rig.scene import Field, ImpossibleGeometry, Scene, SceneError, read_table
from rig.plants.cam_bar.drive import read_drive
from rig.plants.cam_bar.guide_friction import read_guide
from rig.plants.cam_bar.insertion import read_insertion
from rig.plants.cam_bar.joints import read_joints
from rig.plants.cam_bar.level2_model import CONTACT_DAMPING, Level2Model
from rig.plants.cam_bar.mechanism import NON_NEGATIVE, POSITIVE, PinInsertionMechanism
from rig.plants.cam_bar.variation import CycleVariation, check_draws, plant_generator
from rig.units import UnitError, to_si

PLANT_SCHEMA = {
    "L3": Field("m"), "l3": Field("m"), "m3": Field("kg"), "x_A0": Field("m"), "y_A0": Field("m"),
    "r_R": Field("m"), "l4": Field("m"), "m4": Field("kg"), "e_sk": Field("m"), "s0": Field("m"),
    "l5": Field("m"), "m5": Field("kg"), "s_H": Field("m"), "F_c": Field("N"),
    "F_c_travel": Field("m", 0.005, "slider travel before the top of the rise over which F_c acts"),
    "l_F": Field("m"), "Me_S": Field("N*m"), "Me_0": Field("N*m"),
    "s_S": Field("m", doc="spring-point stroke of the thesis design formula"),
    "s_Srest": Field("m", 0.0, "spring-point rest position of the thesis design formula"),
    "k": Field("N/m", doc="mounted spring rate"),
    "spring_rates": Field(None, doc="list of spring rates to compare, e.g. [\"1.09 N/mm\", ...]"),
    "sensor_preload": Field("N"),
    "sensor_position": Field("1", 0.5, "the rod-force sensor's place along the rod: 0 at the follower joint C, "
                             "1 at the slider joint D", minimum=0.0, maximum=1.0),
    "clearance": Field("m", doc="groove clearance"), "alpha_sk": Field("rad"),
    "roller_width": Field("m", 0.010, "roller/flank contact length for the level-2 contact stiffness (assumption)"),
    "contact_damping": Field("s/m", CONTACT_DAMPING, "Hunt-Crossley damping of the level-2 roller contact "
                             "(assumption; the run's level-2 model, not the machine)"),
    "J3": Field("kg*m^2", None, "follower inertia about B0 (default m3·L3²/3)"),
    "J4": Field("kg*m^2", None, "rod inertia about its centre (default m4·l4²/12)"),
    "a3": Field("m", None, "follower CoG distance from B0 (default L3/2)"),
    "mu": Field("1", 0.1), "g": Field("m/s^2", 9.81), "x_s5": Field("m", 0.02), "e5": Field("m", 0.02),
    "cam_direction": Field("1", 1, "+1 counter-clockwise, -1 clockwise"),
    "cam_program": Field(None, doc="array of tables [[plant.cam_program]]"),
    "variation": Field(None, None, "per-cycle deviations, table [plant.variation] (rig.plants.cam_bar.variation)"),
    "insertion": Field(None, None, "pin force-travel law, table [plant.insertion] (rig.plants.cam_bar.insertion)"),
    "guide": Field(None, None, "level-2 slider-guide friction model, table [plant.guide] "
                   "(rig.plants.cam_bar.guide_friction; the run's level-2 model)"),
    "drive": Field(None, None, "level-2 cam drive (motor, shaft), table [plant.drive] (rig.plants.cam_bar.drive)"),
    "joints": Field(None, None, "level-2 rod pin clearances, table [plant.joints] (rig.plants.cam_bar.joints)"),
}
# the ranges PinInsertionMechanism checks, checked on the scene's values (the error shows the value as written)
PLANT_SCHEMA.update({name: replace(PLANT_SCHEMA[name], positive=True) for name in POSITIVE})
PLANT_SCHEMA.update({name: replace(PLANT_SCHEMA[name], minimum=0.0) for name in NON_NEGATIVE})
SEGMENT_SCHEMA = {"kind": Field(None), "angle": Field("rad"), "law": Field(None, None),
                  "stroke": Field("m", None, "defaults to s_H for rise/return")}
# the ranges the speed profiles check, checked on the scene's values: the error names the key and the value as written
FASTEST = 1e6 * math.tau / 60      # rad/s: 1e6 rpm, beyond any bench (1e30 rpm drew 1e27 cycles per chunk: a hang)
_SPEED = dict(positive=True, maximum=FASTEST, says="must be positive and at most 1e6 rpm")
SPEED_SCHEMAS = {
    "constant": {"profile": Field(None), "speed": Field("rad/s", **_SPEED), "phi0": Field("rad", 0.0)},
    "ramp": {"profile": Field(None), "speed": Field("rad/s", **_SPEED), "speed_end": Field("rad/s", **_SPEED),
             "ramp_time": Field("s", positive=True), "ramp_start": Field("s", 0.0, minimum=0.0),
             "phi0": Field("rad", 0.0)},
    "sinusoidal": {"profile": Field(None), "speed": Field("rad/s", doc="mean speed", **_SPEED),
                   "amplitude": Field("rad/s", minimum=0.0),
                   "frequency": Field("Hz", None, "default: once per revolution", positive=True),
                   "phi0": Field("rad", 0.0)},
}


def read_program(tables: Any, s_h: float, where: str) -> CamProgram:
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise SceneError(f"{where}: 'cam_program' must be an array of tables ([[plant.cam_program]])")
    segments = []
    for i, table in enumerate(tables):
        seg = read_table(table, SEGMENT_SCHEMA, f"{where} cam_program segment {i + 1}")
        stroke = seg["stroke"] if seg["stroke"] is not None else (0.0 if seg["kind"] == "dwell" else s_h)
        segments.append(Segment(str(seg["kind"]), seg["angle"], seg["law"], stroke))
    try:
        return CamProgram(segments)
    except ProgramError as exc:
        raise SceneError(f"{where}: {exc}") from None


def read_speed(table: dict[str, Any], where: str) -> SpeedProfile:
    profile = table.get("profile", "constant")
    if profile not in SPEED_SCHEMAS:
        raise SceneError(f"{where}: unknown speed profile {profile!r} (known: {', '.join(SPEED_SCHEMAS)})")
    v = read_table({"profile": profile, **table}, SPEED_SCHEMAS[profile], where)
    try:
        if profile == "constant":
            return ConstantSpeed(v["speed"], v["phi0"])
        if profile == "ramp":
            return RampSpeed(v["speed"], v["speed_end"], v["ramp_time"], v["ramp_start"], v["phi0"])
        return SinusoidalSpeed(v["speed"], v["amplitude"], v["frequency"], v["phi0"])
    except ValueError as exc:
        raise SceneError(f"{where}: {exc}") from None


def read_speed_profile(scene: Scene) -> SpeedProfile:
    """The speed profile of the scene's [speed] section (the setting the cam turns by)."""
    return read_speed(scene.section("speed"), f"{scene.path} [speed]")


def require_cam_bar(scene: Scene, command: str, also: str = "") -> None:
    """A :class:`SceneError` saying that ``command`` (e.g. "rig tolerance") needs a cam-bar scene (``also``: what else
    it takes, e.g. 'or a lab_bench scene of kind "cam"'), for a scene of another plant (before its [plant] keys are
    read as the cam-bar's and found unknown)."""
    plant = scene.section("scene").get("plant", "cam_bar")
    if plant != "cam_bar":
        raise SceneError(f"{command} needs plant \"cam_bar\" in [scene] (a cam-bar scene such as pin_insertion.toml)"
                         f"{' ' + also if also else ''}; {scene.path} is a {plant!r} scene")


def require_level2(scene: Scene, command: str) -> None:
    """A :class:`SceneError` saying that ``command`` studies level 2 of the cam-bar plant, for a cam-bar scene that
    runs at another level (its numbers would not be those of the scene the user named)."""
    require_cam_bar(scene, command)
    if read_fidelity(scene) != 2:
        raise SceneError(f"{scene.path} [scene]: {command} studies level 2 of the cam-bar plant; set fidelity = 2 "
                         f"(e.g. data/scenes/pin_insertion_l2.toml)")


def cam_bar_from_scene(path: str | Path, command: str = "the cam-bar model") -> tuple["PinInsertionMechanism", float]:
    """A cam-bar scene file → its :class:`PinInsertionMechanism` ([plant]) and nominal cam speed (rad/s, [speed]);
    :class:`SceneError` for a scene of another plant (:func:`require_cam_bar`)."""
    from rig.scene import load_scene
    scene = load_scene(path)
    require_cam_bar(scene, command)
    return mechanism_from_scene(scene), read_speed_profile(scene).nominal_omega


def read_fidelity(scene: Scene) -> int:
    """The level a run of ``scene`` uses (:func:`rig.fidelity.choose`: [scene] fidelity, else the lowest level
    answering [scene] questions, else 1)."""
    from rig.fidelity import choose
    return choose(scene, "cam_bar").level


def read_spring_rates(scene: Scene) -> tuple[float, ...]:
    """The spring rates (N/m) whose flank switches the summary compares ([plant] spring_rates: a study, not the
    machine, whose spring is ``k``)."""
    return _spring_rates(scene.read("plant", PLANT_SCHEMA)["spring_rates"], f"{scene.path} [plant]")


def _spring_rates(rates: Any, where: str) -> tuple[float, ...]:
    if not isinstance(rates, list) or not rates:
        raise SceneError(f"{where}: 'spring_rates' must be a non-empty list of quantities like \"1.19 N/mm\"")
    try:
        return tuple(to_si(r, "N/m", what=f"{where}: spring_rates[{i}]") for i, r in enumerate(rates))
    except UnitError as exc:
        raise SceneError(str(exc)) from None


def read_mechanism_kwargs(scene: Scene) -> dict[str, Any]:
    """Keyword arguments of :class:`PinInsertionMechanism` from the scene (SI)."""
    where = f"{scene.path} [plant]"
    kw = scene.read("plant", PLANT_SCHEMA)
    for name in ("variation", "contact_damping", "guide"):     # the run's setting (read_setting)
        kw.pop(name)
    _spring_rates(kw.pop("spring_rates"), where)                # checked: a study of the summary (read_spring_rates)
    kw["program"] = read_program(kw.pop("cam_program"), kw["s_H"], where)
    kw["insertion"] = read_insertion(kw.pop("insertion"), f"{scene.path} [plant.insertion]")
    kw["cam_drive"] = read_drive(kw.pop("drive"), f"{scene.path} [plant.drive]")
    kw["joints"] = read_joints(kw.pop("joints"), f"{scene.path} [plant.joints]")
    return kw


def read_level2_model(scene: Scene) -> Level2Model:
    """The level-2 model assumptions of the scene's [plant]: ``contact_damping`` and [plant.guide]."""
    kw = scene.read("plant", PLANT_SCHEMA)
    try:
        return Level2Model(kw["contact_damping"], read_guide(kw["guide"], f"{scene.path} [plant.guide]"))
    except ValueError as exc:
        if isinstance(exc, SceneError):
            raise
        raise SceneError(f"{scene.path} [plant]: {exc}") from None


def read_setting(scene: Scene) -> dict[str, Any]:
    """Keyword arguments of :class:`rig.plants.cam_bar.plant.Setting` from the scene: the speed profile [speed], the
    level and level-2 method (:func:`rig.fidelity.choose`), the level-2 model assumptions, the per-cycle variation
    [plant.variation] and its generator (under [scene] seed)."""
    from rig.fidelity import choose
    variation = scene.read("plant", PLANT_SCHEMA)["variation"]
    if variation is not None:
        where = f"{scene.path} [plant.variation]"
        variation = CycleVariation.from_table(variation, where)
        check_draws(variation, mechanism_from_scene(scene), where)
    choice = choose(scene, "cam_bar")
    kw: dict[str, Any] = {"speed": read_speed_profile(scene), "fidelity": choice.level,
                          "level2": read_level2_model(scene)}
    if choice.method is not None:
        kw["method"], kw["method_options"] = choice.method, dict(choice.options)
    if variation is not None:
        kw["variation"] = variation
        seed = scene.section("scene").get("seed")
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise SceneError(f"{scene.path} [scene]: 'seed' must be a non-negative integer for [plant.variation], "
                             f"got {seed!r}")
        kw["rng"] = plant_generator(seed)
    return kw


def drawn_per_cycle(scene: Scene) -> list[str]:
    """What the scene's ``[plant.variation]`` draws per cycle (its parameters with a non-zero σ, and the clearance
    when ``clearance_lambda`` is given); empty without variation."""
    table = scene.read("plant", PLANT_SCHEMA)["variation"]
    if table is None:
        return []
    variation = CycleVariation.from_table(table, f"{scene.path} [plant.variation]")
    return sorted(variation.sigma) + (["the clearance taken up"] if variation.clearance_lambda is not None else [])


def mechanism_from_scene(scene: Scene, **overrides: Any) -> PinInsertionMechanism:
    """The mechanism a scene's [plant] section describes (with [[plant.cam_program]]; the description only, the
    run's setting with its [speed]: :func:`read_setting`); ``overrides`` replace keyword arguments of
    :class:`PinInsertionMechanism`. An impossible geometry is a :class:`SceneError` naming the file."""
    from rig.plants.cam_bar.chain import SingularPositionError
    try:
        return PinInsertionMechanism(**{**read_mechanism_kwargs(scene), **overrides})
    except (ValueError, TypeError) as exc:
        if isinstance(exc, SceneError):
            raise
        kind = ImpossibleGeometry if isinstance(exc, SingularPositionError) else SceneError
        raise kind(f"{scene.path} [plant]: {exc}") from None

"""Scene TOML fuzzing (issue 11, issue 12): the scene files of ``data/scenes`` mutated line by line —
lines deleted, duplicated, swapped; values, units, keys and section headers changed; random keys and
sections added — go through :func:`rig.scene.load_scene`, :func:`rig.runner.config.read_config`, the
plant's construction (:func:`rig.runner.plants.make_plant`) and the machine's (transducers, device
program, CAN node: :class:`rig.runner.machine.Machine`). Each case either gives a machine or raises
:class:`rig.scene.SceneError` whose message names the file and the section (``[plant]``,
``[transducers.x]``, ...) or, for TOML syntax, the line; nothing else escapes, nothing hangs.

Deterministic (``derandomize``, no example database). The cases per outcome are counted by the
``fuzz_cases`` fixture (tests/conftest.py: pytest's terminal summary and ``fuzz-cases.json``).
"""
from __future__ import annotations

import os
import re
import uuid
from pathlib import Path

import can
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rig.runner.config import read_config
from rig.runner.machine import Machine
from rig.runner.plants import make_plant
from rig.scene import SceneError, load_scene

ROOT = Path(__file__).resolve().parents[2]
SCENES = sorted((ROOT / "data" / "scenes").glob("*.toml"))
TEXTS = {p.name: p.read_text(encoding="utf-8") for p in SCENES}
EXAMPLES = int(os.environ.get("MECHRIG_FUZZ_SCENE_EXAMPLES", "2000"))
MACHINE_EXAMPLES = int(os.environ.get("MECHRIG_FUZZ_MACHINE_EXAMPLES", "250"))

UNITS = ["mm", "m", "km", "kg", "g", "N", "kN", "daN*m", "N*m", "N/mm", "s", "ms", "Hz", "kHz", "rpm", "deg",
         "rad", "rad/s", "m/s^2", "GPa", "kg*m^2", "s/m", "1/mm", "/ mm", "%", "furlongz", "", "mm mm", "m**2",
         "degC", "delta_degC", "count"]
NUMBERS = ["0", "-0.0", "1", "-1", "2", "0.5", "-25", "3.5e-3", "1e300", "-1e300", "1e-300", "inf", "-inf", "nan",
           "123456789012345678", "-9223372036854775808", "9223372036854775807", "1e400"]
SCALARS = NUMBERS + ['"abc"', '""', "true", "false", "[]", "[1, 2]", '["1 mm", "2 kg"]', "{}", '{ a = 1 }',
                     "1979-05-27", "07:32:00", '"1 mm"', '"-5 N"', '"0 Hz"', '"nan mm"', '"inf s"', '"1e999 m"',
                     '"x_max"', '"virtual"', '"realtime"', '"cam_bar"', '"clutch_dynamic"', '"clutch_static"',
                     '"blockbus"', '"socketcand"', '"dwell"', '"rise"', '"3-4-5"', '"constant"', '"ramp"',
                     '"leaf_spring"', '"flat_tappet"', "[[1]]", "[{a = 1}]", '{ range_min = -1, range_max = 1 }',
                     '"9**9**9 mm"', '"2**2**2**2**2 m"', '"1/0 m"', '"(1 mm"', '"1 mm + 1 kg"', '"1e5**1e5 N"']
FACTORS = [-1.0, 0.0, 1e-6, 1e-3, 0.5, 2.0, 10.0, 1e3, 1e6]
KEYS = ["name", "plant", "seed", "cycles", "duration", "sample_rate", "chunk", "mode", "fidelity", "max_time",
        "L3", "L3_mm", "L3_kg", "k_N_per_mm", "speed", "profile", "speed_end", "ramp_time", "amplitude",
        "description", "signal", "to", "rate", "overrides", "faults", "program", "config", "interface",
        "bitrate", "fd", "data_bitrate", "live_share", "tx_curves", "port", "enabled", "baudrate", "address",
        "truth_signals", "truth_rate", "encoding", "compression", "variant", "lever_arm", "force", "kind", "angle", "law",
        "stroke", "zz", "x_mm_mm", "_", "a b", '"quoted key"', "F_c_travel_ms", "clearance_lambda"]
SECTIONS = ["scene", "plant", "plnt", "speed", "load", "load.brake", "load.none", "load.zz", "motor", "recording",
            "recordng", "device", "device.config", "links", "links.can", "links.cann", "links.serial",
            "transducers", "transducers.zz", "transducers.rod_force", "plant.variation", "plant.clutch",
            "plant.zz", "zz", "scene.zz", "links.can.zz"]
ARRAY_SECTIONS = ["program", "plant.cam_program", "device.config.elements", "zz", "scene", "transducers.zz"]

VALUE = st.one_of(
    st.sampled_from(SCALARS),
    st.integers(-10**20, 10**20).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(lambda f: repr(f).replace("e+", "e")),
    st.tuples(st.sampled_from(NUMBERS[:10]), st.sampled_from(UNITS)).map(lambda nu: f'"{nu[0]} {nu[1]}"'),
)
MUTATION = st.one_of(
    st.tuples(st.just("delete"), st.integers(0, 10**4)),
    st.tuples(st.just("duplicate"), st.integers(0, 10**4)),
    st.tuples(st.just("swap"), st.integers(0, 10**4), st.integers(0, 10**4)),
    st.tuples(st.just("value"), st.integers(0, 10**4), VALUE),
    st.tuples(st.just("unit"), st.integers(0, 10**4), st.sampled_from(UNITS)),
    st.tuples(st.just("key"), st.integers(0, 10**4), st.sampled_from(KEYS)),
    st.tuples(st.just("add_key"), st.integers(0, 10**4), st.sampled_from(KEYS), VALUE),
    st.tuples(st.just("add_section"), st.integers(0, 10**4), st.sampled_from(SECTIONS)),
    st.tuples(st.just("add_array"), st.integers(0, 10**4), st.sampled_from(ARRAY_SECTIONS)),
    st.tuples(st.just("header"), st.integers(0, 10**4), st.sampled_from(SECTIONS)),
    st.tuples(st.just("scale"), st.integers(0, 10**4), st.sampled_from(FACTORS)),
    st.tuples(st.just("cut"), st.integers(0, 10**6)),
)

ASSIGNMENT = re.compile(r"^(\s*)([A-Za-z0-9_\"\- ]+?)(\s*=\s*)(.*)$")
QUANTITY = re.compile(r'"(\s*[-+0-9.eE]+)\s*([^"]*)"')
NUMBER = re.compile(r"(?<![\w.])-?\d+(\.\d*)?([eE][-+]?\d+)?(?![\w.])")


HEADER = re.compile(r"^\s*\[\[?\s*([^\]]*?)\s*\]")


def section_lines(lines: list[str], prefixes: tuple[str, ...]) -> list[int]:
    """Indices of the lines in sections whose names start with one of ``prefixes`` (headers included)."""
    out, inside = [], False
    for i, line in enumerate(lines):
        header = HEADER.match(line)
        if header:
            inside = header[1].startswith(prefixes)
        if inside:
            out.append(i)
    return out


def mutate(text: str, mutations: list[tuple], focus: tuple[str, ...] = ()) -> str:
    """Apply the mutations in order (line indices are taken modulo the current number of lines, or of
    the lines in the sections named by ``focus`` when it is given and they exist)."""
    lines = text.splitlines()
    for kind, at, *rest in mutations:
        if kind == "cut":
            return "\n".join(lines)[:at % (len(text) + 1)]
        if not lines:
            lines = [""]
        where = section_lines(lines, focus) if focus else []
        i = where[at % len(where)] if where else at % len(lines)
        line = lines[i]
        m = ASSIGNMENT.match(line)
        if kind == "delete":
            del lines[i]
        elif kind == "duplicate":
            lines.insert(i, line)
        elif kind == "swap":
            j = rest[0] % len(lines)
            lines[i], lines[j] = lines[j], lines[i]
        elif kind == "value" and m:
            lines[i] = f"{m[1]}{m[2]}{m[3]}{rest[0]}"
        elif kind == "unit":
            lines[i] = QUANTITY.sub(lambda q: f'"{q[1]} {rest[0]}"', line, count=1)
        elif kind == "scale" and m:
            number = NUMBER.search(m[4])
            if number:
                scaled = repr(float(number[0]) * rest[0]).replace("e+", "e")
                lines[i] = f"{m[1]}{m[2]}{m[3]}{m[4][:number.start()]}{scaled}{m[4][number.end():]}"
        elif kind == "key" and m:
            lines[i] = f"{m[1]}{rest[0]}{m[3]}{m[4]}"
        elif kind == "add_key":
            lines.insert(i, f"{rest[0]} = {rest[1]}")
        elif kind == "add_section":
            lines.insert(i, f"[{rest[0]}]")
        elif kind == "add_array":
            lines.insert(i, f"[[{rest[0]}]]")
        elif kind == "header" and line.lstrip().startswith("["):
            lines[i] = f"[[{rest[0]}]]" if line.lstrip().startswith("[[") else f"[{rest[0]}]"
    return "\n".join(lines) + "\n"


#: rejection kinds by message, first match wins (the report's case counts)
KINDS = [("TOML syntax", "not valid TOML"), ("unknown section", r"unknown section|unknown sub-table"),
         ("section of another plant", "is not used by plant"), ("top-level key", "unknown top-level key"),
         ("unknown key", "unknown key"), ("missing section", r"missing section|missing or malformed \[\[program"),
         ("missing or conflicting keys", r"missing key|give exactly one of|needs both|needs pulse"),
         ("given twice", "given twice"), ("unit: wrong dimension", "wrong dimension"), ("unit: no unit", "has no unit"),
         ("unit: unreadable", r"cannot read|already names the unit|is not a quantity with a unit|is not a unit rig knows"), ("not finite", "finite quantity"),
         ("wrong type", r"must be a table|must be an array|must be a list|must be a string|must be true or false|"
                        r"must be the name|must be a device|must be a host|must be '|expected a number|boolean"),
         ("not one of the choices", r"must be one of|is not one of|unknown type|unknown speed profile"),
         ("integer out of range", "must be an integer"),
         ("value out of range or inconsistent", r".")]
#: where the message says what it is about: a section ``[name]`` (with the file) or a TOML line
NAMES_PLACE = re.compile(r"\[[A-Za-z0-9_.\-\" ]+\]|\(at line \d+|at end of document")


def check(path: Path, text: str, bus: can.BusABC | None = None) -> str:
    """Load, validate and build the scene in ``path`` (plant, and with ``bus`` the whole machine:
    transducers, device program, CAN node); return the outcome (or fail the test)."""
    path.write_text(text, encoding="utf-8")
    try:
        cfg = read_config(load_scene(path))
        make_plant(cfg.plant, cfg.scene)
        if bus is not None:
            Machine(cfg, bus)
    except SceneError as exc:
        message = str(exc)
        assert str(path) in message, f"the message does not name the file: {message}"
        assert NAMES_PLACE.search(message), f"the message names no section or line: {message}"
        assert "\n" not in message.strip() or "not valid TOML" in message, f"not one line: {message!r}"
        return "rejected: " + next(kind for kind, pattern in KINDS if re.search(pattern, message))
    return "accepted"


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fuzz-scene") / "fuzzed.toml"


@pytest.fixture(scope="module")
def bus() -> can.BusABC:
    with can.Bus(interface="blockbus", channel=f"fuzz-scene-{uuid.uuid4().hex}") as bus:
        yield bus


def fuzz_one(fuzz_cases, target: str, path: Path, name: str, text: str, bus: can.BusABC | None) -> None:
    with fuzz_cases.example(target, limit=60.0) as case:
        try:
            outcome = case.within(case.HANG, check, path, text, bus)
        except AssertionError as exc:
            raise AssertionError(f"{exc}\n--- {name} mutated:\n{text}") from None
        except Exception as exc:   # noqa: BLE001  (any other exception is the finding)
            raise AssertionError(f"{type(exc).__name__}: {exc}\n--- {name} mutated:\n{text}") from exc
        case.outcome(outcome)


@pytest.mark.parametrize("name", sorted(TEXTS))
def test_scene_files_load_unmutated(name, tmp_path, bus):
    assert check(tmp_path / name, TEXTS[name], bus) == "accepted"


FUZZ = dict(derandomize=True, database=None, deadline=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.large_base_example])


@settings(max_examples=EXAMPLES, **FUZZ)
@given(name=st.sampled_from(sorted(TEXTS)), mutations=st.lists(MUTATION, min_size=1, max_size=3))
def test_mutated_scenes_load_or_raise_scene_errors_naming_file_and_section(fuzz_cases, scene_file, name, mutations):
    """Anywhere in the file: the plant is built, or a one-line SceneError names the file and the section
    (or the TOML line)."""
    fuzz_one(fuzz_cases, "scene TOML: load_scene, read_config, make_plant", scene_file, name,
             mutate(TEXTS[name], mutations), None)


@settings(max_examples=MACHINE_EXAMPLES, **FUZZ)
@given(name=st.sampled_from(sorted(TEXTS)), mutations=st.lists(MUTATION, min_size=1, max_size=2))
def test_mutated_instrument_sections_build_machines_or_raise_scene_errors(fuzz_cases, scene_file, bus, name,
                                                                          mutations):
    """Mutations in [transducers.*], [device*], [links.*] and [recording]: the whole machine (transducer
    descriptions, device program, CAN node and its bus plan) is built, or a SceneError as above."""
    fuzz_one(fuzz_cases, "scene TOML [transducers/device/links/recording]: ... + Machine", scene_file, name,
             mutate(TEXTS[name], mutations, focus=("transducers", "device", "links", "recording")), bus)

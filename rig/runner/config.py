"""The runner's scene sections: [scene], [transducers.*], [device], [links.can], [links.serial], [recording].

Plant sections ([plant], [speed], [load], ...) belong to the plant modules and are read there.
"""
from __future__ import annotations

import difflib
import functools
import math
from fractions import Fraction
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rig.blockbus import is_interface_name
from rig.fidelity import Fidelity, check_scene, choose
from rig.limits import MAX_CYCLES, MAX_DURATION
from rig.scene import Field, Scene, SceneError, read_table

MAX_SAMPLE_RATE = 1e6      # Hz: the fastest plant/transducer sample rate a scene may ask

SCENE_SCHEMA = {
    "name": Field(None), "description": Field(None, ""),
    "plant": Field(None, doc="plant kind, e.g. 'cam_bar' or 'clutch_dynamic'"),
    "seed": Field("1", doc="seed of every random draw of the run", integer=True, minimum=0),
    "cycles": Field("1", None, "number of device curves (machine cycles) to record", integer=True, minimum=1,
                    maximum=MAX_CYCLES),                # (as rig run --cycles; beyond int64, a traceback)
    "duration": Field("s", None, "simulated time to run when the scene has no cycles", maximum=MAX_DURATION),
    "sample_rate": Field("Hz", 10_000.0, "plant/transducer/acquisition sample rate"),
    "chunk": Field("s", 0.1, "simulated time the plant and transducers advance per runner step: a whole number of "
                   "the unit's transmit cycles ([links.can] tx_period); the unit, its bus and the transducers record "
                   "the same whatever it is, a plant that integrates restarts there (docs/can-protocol.md)"),
    "mode": Field(None, "virtual", "'virtual' (as fast as possible) or 'realtime' (paced to the wall clock)"),
    "fidelity": Field(None, None, "model level (0/1/2 or kinematic/kinetostatic/dynamic); default: chosen by questions"),
    "questions": Field(None, None, "what the run must answer, e.g. [\"stroke\", \"dwell_vibration\"] (rig.fidelity)"),
    "tolerance": Field("1", None, "relative error the answers need (default 1e-6); picks the solver setting"),
    "model_tolerance": Field("1", None, "how far a lower model level may be from level 2 (relative, default 0.05)"),
    "max_time": Field("s", None, "give up when the cycles are not complete by this simulated time",
                      maximum=MAX_DURATION),
}
TRANSDUCER_SCHEMA = {
    "description": Field(None, doc="device description name in data/devices or a path (relative to the scene file)"),
    "signal": Field(None, doc="plant truth signal the transducer measures"),
    "to": Field(None, doc="where its output goes: 'device.x' / 'device.y' (the unit's channels), "
                          "'can.MESSAGE.SIGNAL' (a reading in a DBC signal, e.g. 'can.Torque.Torque') or "
                          "'can.MESSAGE' (a counter's Count and EdgeTime, e.g. 'can.Encoder1')"),
    "overrides": Field(None, {}, "description values to override, with units"),
    "faults": Field(None, [], "list of {fault = ..., at = '.. s', ...} tables"),
    "rate": Field("Hz", None, "publishing rate of its CAN frames (default: once per transmit cycle, [links.can] "
                              "tx_period)", positive=True),
}
DEVICE_SCHEMA = {
    "program": Field("1", 0, "program number the run uses", integer=True, minimum=0),
    "config": Field(None, {}, "program settings merged over the unit's factory program"),
    "description": Field(None, None, "device description name or path, relative to the scene file (default: the "
                                      "DigiForce 9310 file)"),
}
CAN_SCHEMA = {
    "interface": Field(None, "blockbus", "in one process: 'blockbus' (frames in blocks) or python-can's 'virtual'"),
    "channel": Field(None, "rig"),
    "bitrate": Field("bit/s", 500_000, "bit/s, e.g. 500000 or \"500 kbit/s\"", integer=True, minimum=1, plain=True),
    "fd": Field(None, False),
    "data_bitrate": Field("bit/s", None, "of the CAN FD data phase, e.g. \"2 Mbit/s\"", integer=True, minimum=1,
                          plain=True),
    "live_share": Field("1", 0.5, "share of the bus for live data"),
    "tx_period": Field("s", 0.1, "the unit's transmit cycle: each cycle it plans its live data against the bus, sends "
                       "the readings without a rate of their own and takes the host's commands"),
    "tx_curves": Field("1", 4, "curve transfers the unit holds for sending (more: the bus cannot carry the curves)",
                       integer=True, minimum=1),
    "host": Field(None, "127.0.0.1", "socketcand server address (cross-process)"),
    "port": Field("1", 0, "socketcand TCP port (0: any free port)", integer=True, minimum=0, maximum=65535),
}
#: serial rates the unit's interface runs at (baud): the range of RS-232 line drivers; below it the set-up alone
#: (program written and read back, about 2 kB each way) would take minutes
BAUD_RATES = (1200, 4_000_000)
SERIAL_SCHEMA = {
    "enabled": Field(None, True), "port": Field(None, "pty", "'pty', a pyserial URL or a device path"),
    "baudrate": Field("1", 115_200, integer=True, minimum=BAUD_RATES[0], maximum=BAUD_RATES[1]), "address": Field("1", 1, integer=True, minimum=1),
}
RECORDING_SCHEMA = {
    "truth_signals": Field(None, None, "plant truth signals to record (default: all)"),
    "truth_rate": Field("Hz", None, "rate of /plant/truth, every k-th model sample (default: every sample)"),
    "encoding": Field(None, "json", "'json' (viewer-plottable) or 'base64' (compact)"),
    "compression": Field(None, "zstd"),
    "view_rate": Field("Hz", 100.0, "at most this many messages per second on each /view/* channel (the first sample "
                       "of each period; docs/recording.md)", positive=True, maximum=1e5),
}
#: top-level sections the runner reads (the plant's own: rig.runner.plants.PLANT_SECTIONS) and [links.*]
RUNNER_SECTIONS = ("scene", "transducers", "device", "links", "recording")
LINKS = ("can", "serial")
MODES = ("virtual", "realtime")
IN_PROCESS_INTERFACES = ("blockbus", "virtual")
CHANNELS = ("x", "y")


#: the CAN frames' Tick step (s, docs/can-protocol.md): live pairs are sent only at samples on its grid
TICK = 1e-4


def _check_live_grid(sample_rate: float, where: str) -> None:
    """A SceneError when the samples on the Tick grid (n/rate a multiple of 100 µs every ``step`` samples: the live
    view's finest step) are further apart than 10 ms — a rate that rarely meets the grid."""
    ratio = Fraction(sample_rate * TICK).limit_denominator(10_000)
    step = ratio.numerator
    if abs(float(ratio) - sample_rate * TICK) > 1e-9 * sample_rate * TICK or step / sample_rate > 0.01:
        raise SceneError(f"{where}: 'sample_rate' = {sample_rate:g} Hz: live pairs go out stamped on the 100 µs Tick "
                         f"grid of the CAN frames (docs/can-protocol.md), and at this rate too few samples fall on it "
                         f"(a live view slower than 100 pairs/s); choose 10 kHz times a simple fraction (e.g. 5, 10, "
                         f"20 or 50 kHz)")


def _truth_every(rate: float | None, sample_rate: float, where: str) -> int:
    """Decimation k of the recorded truth for ``[recording] truth_rate`` (Hz; ``None``: 1); a SceneError naming
    ``where`` unless the rate divides the sample rate into whole steps."""
    if rate is None:
        return 1
    ratio = sample_rate / rate if rate > 0 else math.inf
    k = round(ratio) if math.isfinite(ratio) else 0
    if k < 1 or abs(ratio - k) > 1e-9 * ratio:
        raise SceneError(f"{where}: 'truth_rate' must divide the sample rate ({sample_rate:g} Hz) into whole steps "
                         f"(e.g. {sample_rate / 10:g} Hz), got {rate:g} Hz")
    return k


@dataclass(frozen=True)
class TransducerSpec:
    """One ``[transducers.NAME]``: the plant ``signal`` it measures and where its output goes (``to``):
    ``channel`` of the unit, or CAN ``message`` and its ``frame_signal`` (None: a counter's Count and EdgeTime)."""

    name: str
    description: str
    signal: str
    to: str
    overrides: dict[str, Any] = field(default_factory=dict)
    faults: list[dict[str, Any]] = field(default_factory=list)
    rate: float | None = None

    @property
    def channel(self) -> str | None:
        return self.to.split(".")[1] if self.to.startswith("device.") else None

    @property
    def message(self) -> str | None:
        return self.to.split(".")[1] if self.to.startswith("can.") else None

    @property
    def frame_signal(self) -> str | None:
        parts = self.to.split(".")
        return parts[2] if parts[0] == "can" and len(parts) == 3 else None


def read_wire(to: Any, where: str) -> str:
    """Check a transducer's ``to`` against the unit's channels and the DBC's device frames (SceneError naming
    what is wrong); returns it."""
    from firmware_sim.can_node import OWN_FRAMES
    if not isinstance(to, str) or not to.startswith(("device.", "can.")):
        raise SceneError(f"{where}: key 'to' must be 'device.x', 'device.y', 'can.MESSAGE' or 'can.MESSAGE.SIGNAL', "
                         f"got {to!r}")
    parts = to.split(".")
    if parts[0] == "device":
        if len(parts) != 2 or parts[1] not in CHANNELS:
            raise SceneError(f"{where}: key 'to' = {to!r}: the unit's channels are 'device.x' and 'device.y'")
        return to
    db = _device_dbc()
    readings = sorted(m.name for m in db.messages if "DEVICE" in m.senders and m.name not in OWN_FRAMES)
    if len(parts) not in (2, 3) or parts[1] not in readings:
        raise SceneError(f"{where}: key 'to' = {to!r}: no reading message {parts[1] if len(parts) > 1 else ''!r} "
                         f"in the DBC (readings: {', '.join(readings)})")
    msg = db.get_message_by_name(parts[1])
    names = [s.name for s in msg.signals if s.name not in ("Seq", "Tick")]
    if len(parts) == 2 and not {"Count", "EdgeTime"} <= set(names):
        raise SceneError(f"{where}: key 'to' = {to!r}: {parts[1]} carries no counter (Count, EdgeTime); "
                         f"name its signal: {', '.join(f'{to}.{n}' for n in names)}")
    if len(parts) == 3 and parts[2] not in names:
        raise SceneError(f"{where}: key 'to' = {to!r}: {parts[1]} has no signal {parts[2]!r} "
                         f"(it has {', '.join(names)})")
    return to


@functools.lru_cache(maxsize=1)
def _device_dbc() -> Any:
    """The DBC the simulated machine sends by (the scene wires transducers into its messages)."""
    from rig.dbc import load_dbc
    return load_dbc()


def frames_of(transducers: tuple[TransducerSpec, ...] | list[TransducerSpec]) -> dict[str, list[TransducerSpec]]:
    """The CAN reading messages the transducers fill, with the transducers wired to each (scene order)."""
    out: dict[str, list[TransducerSpec]] = {}
    for spec in transducers:
        if spec.message is not None:
            out.setdefault(spec.message, []).append(spec)
    return out


@dataclass(frozen=True)
class RunConfig:
    """Everything the runner needs besides the plant, in SI."""

    scene: Scene
    name: str
    plant: str
    seed: int
    cycles: int | None
    duration: float | None
    sample_rate: float
    chunk: float
    mode: str
    max_time: float
    max_time_given: bool
    transducers: tuple[TransducerSpec, ...]
    device: dict[str, Any]
    can: dict[str, Any]
    serial: dict[str, Any]
    recording: dict[str, Any]
    fidelity: Fidelity | None                 # None: not chosen (read_config's choose_level=False)

    @property
    def dt(self) -> float:
        return 1.0 / self.sample_rate

    @property
    def truth_caveat(self) -> str:
        """What the recorded truth is not (empty: it is the plant's): :func:`rig.runner.plants.truth_caveat`."""
        from rig.runner.plants import truth_caveat
        return truth_caveat(self.plant, self.scene)

    @property
    def chunk_samples(self) -> int:
        """Samples the machine advances per step (``chunk`` at ``sample_rate``; at least 2)."""
        return max(2, round(self.chunk * self.sample_rate))

    @property
    def period_samples(self) -> int:
        """Samples per transmit cycle of the unit (``[links.can] tx_period`` at ``sample_rate``; validated whole)."""
        return round(self.can["tx_period"] * self.sample_rate)

    @property
    def truth_every(self) -> int:
        """/plant/truth keeps the model samples whose index is a multiple of this (1: every sample)."""
        return _truth_every(self.recording["truth_rate"], self.sample_rate, "")

    def sample_times(self, first: int, n: int) -> np.ndarray:
        """Times (s) of the ``n`` samples after sample number ``first``: (first + 1 + i) / rate, each the double
        nearest its exact value (0.0003 s, not 3 × 1e-4 = 0.00030000000000000003)."""
        return (first + 1 + np.arange(n)) / self.sample_rate

    @property
    def measures_curves(self) -> bool:
        """Both of the acquisition unit's channels (X, Y) are wired: it measures curves (a stand or lab scene: no)."""
        return self.wired("device.x") is not None and self.wired("device.y") is not None

    def wired(self, to: str) -> TransducerSpec | None:
        """The transducer whose output goes to ``to`` (e.g. 'device.x', 'can.Encoder1'), if any."""
        return next((t for t in self.transducers if t.to == to), None)

    def frames(self) -> dict[str, list[TransducerSpec]]:
        """The CAN reading messages the scene's transducers fill, with the transducers wired to each."""
        return frames_of(self.transducers)


def default_max_time(cycles: int) -> float:
    """Simulated time (s) a run of ``cycles`` curves may take before it gives up: 3 s per cycle + 10 s."""
    return 3.0 * cycles + 10.0


def _of_type(value: Any, types: type | tuple[type, ...], key: str, where: str, what: str) -> Any:
    """``value`` when it is one of ``types`` (bool is not an int here), else a :class:`SceneError`."""
    if not isinstance(value, types) or (isinstance(value, bool) and bool not in (types if isinstance(types, tuple)
                                                                                  else (types,))):
        raise SceneError(f"{where}: key {key!r} must be {what}, got {type(value).__name__} {value!r}")
    return value


def _one_of(value: Any, choices: tuple[str, ...], key: str, where: str) -> str:
    if not isinstance(value, str) or value not in choices:
        raise SceneError(f"{where}: key {key!r} must be one of {', '.join(map(repr, choices))}, got {value!r}")
    return value


def check_sections(scene: Scene, plant: str) -> None:
    """Every top-level section of ``scene`` is one the runner or the plant ``plant`` reads, and every
    [links.*] one of [links.can], [links.serial]; otherwise a :class:`SceneError` naming it and the file."""
    from rig.runner.plants import PLANT_SECTIONS
    own = PLANT_SECTIONS.get(plant, ())
    known = RUNNER_SECTIONS + own
    wrong = []                                  # every section that does not belong, each said once
    for name, value in scene.data.items():
        if name in known:
            continue
        if not isinstance(value, (dict, list)):
            raise SceneError(f"{scene.path}: unknown top-level key {name!r}; keys belong in a section such as "
                             f"[scene] (is a section header missing above it?)")
        others = sorted(k for k, sections in PLANT_SECTIONS.items() if name in sections)
        close = difflib.get_close_matches(name, known, n=1)
        wrong.append(f"section [{name}] is not used by plant {plant!r} (it belongs to {' / '.join(others)})" if others
                     else f"unknown section [{name}]" + (f" (did you mean [{close[0]}]?)" if close else ""))
    if wrong:
        raise SceneError(f"{scene.path}: {'; '.join(wrong)}; the sections of a {plant!r} scene are "
                         f"{', '.join(f'[{k}]' for k in known)}")
    links = scene.section("links", required=False)
    for name in links:
        if name not in LINKS:
            close = difflib.get_close_matches(name, LINKS, n=1)
            raise SceneError(f"{scene.path}: unknown section [links.{name}]"
                             + (f" (did you mean [links.{close[0]}]?)" if close else "")
                             + "; links are [links.can] and [links.serial]")


def _check_period(period: float, chunk: float, rate: float, where: str, scene_where: str) -> None:
    """The transmit cycle a whole number of samples, and the chunk a whole number of cycles: the runner steps the
    unit and its bus cycle by cycle within a chunk."""
    if not period > 0:
        raise SceneError(f"{where}: key 'tx_period' must be positive, got {period:g} s")
    samples = period * rate
    whole = round(samples)
    if whole < 2 or abs(samples - whole) > 1e-6 * samples:
        raise SceneError(f"{where}: key 'tx_period' = {period:g} s must be a whole number (at least 2) of samples at "
                         f"[scene] sample_rate = {rate:g} Hz (it holds {samples:g})")
    chunk_samples = max(2, round(chunk * rate))           # RunConfig.chunk_samples
    if chunk_samples % whole:
        raise SceneError(f"{scene_where}: key 'chunk' = {chunk:g} s must be a whole number of the unit's transmit "
                         f"cycles ([links.can] tx_period = {period:g} s; it holds {chunk_samples / whole:g}): "
                         "the runner steps the unit cycle by cycle within a chunk; change the chunk, or tx_period to a "
                         "divisor of it")


def read_config(scene: Scene, fidelity: int | None = None, *, choose_level: bool = True) -> RunConfig:
    """Validate the runner's sections of ``scene``; errors name the file, section and key. ``fidelity``: the level
    ``--fidelity`` forces (:func:`rig.fidelity.choose`; None: the scene's own choice). ``choose_level=False`` leaves
    the model level unchosen (``fidelity`` None in the result, the argument ignored; the scene's questions, fidelity
    and tolerances still checked) for a command that does not run the plant: the choice may simulate a level-2
    revolution, and compile it on a new machine (tens of seconds)."""
    from firmware_sim.transducers.description import described, resolve_path
    from rig.runner.plants import PLANTS
    where = f"{scene.path} [scene]"
    s = scene.read("scene", SCENE_SCHEMA)
    _one_of(s["plant"], tuple(PLANTS), "plant", where)
    check_sections(scene, s["plant"])
    _of_type(s["name"], str, "name", where, "a string")
    _of_type(s["description"], str, "description", where, "a string")
    _one_of(s["mode"], MODES, "mode", where)
    if (s["cycles"] is None) == (s["duration"] is None):
        raise SceneError(f"{where}: give exactly one of 'cycles' and 'duration'")
    cycles = s["cycles"]
    if s["duration"] is not None and not s["duration"] > 0:
        raise SceneError(f"{where}: key 'duration' must be positive")
    for key, unit in (("sample_rate", "Hz"), ("chunk", "s")):
        if not s[key] > 0:
            raise SceneError(f"{where}: key {key!r} must be positive, got {s[key]:g} {unit}")
    if s["sample_rate"] > MAX_SAMPLE_RATE:     # (1e12 Hz asked 2.9 TiB for one revolution's samples)
        raise SceneError(f"{where}: key 'sample_rate' must be at most {MAX_SAMPLE_RATE / 1e6:g} MHz (the acquisition "
                         f"unit samples at up to 20 kHz), got {s['sample_rate']:g} Hz")
    if s["chunk"] * s["sample_rate"] < 2:
        raise SceneError(f"{where}: 'chunk' = {s['chunk']:g} s holds {s['chunk'] * s['sample_rate']:g} samples at "
                         f"'sample_rate' = {s['sample_rate']:g} Hz: a chunk needs at least 2")
    _check_live_grid(s["sample_rate"], where)
    transducers = []
    for name, table in scene.section("transducers", required=False).items():
        tw = f"{scene.path} [transducers.{name}]"
        if not isinstance(table, dict):
            raise SceneError(f"{tw}: must be a table")
        t = read_table(table, TRANSDUCER_SCHEMA, tw)
        read_wire(t["to"], tw)
        _of_type(t["description"], str, "description", tw, "a device description name or path")
        _of_type(t["signal"], str, "signal", tw, "the name of a plant truth signal")
        _of_type(t["overrides"], dict, "overrides", tw, "a table of description values, e.g. { range_max = \"5 mm\" }")
        faults = _of_type(t["faults"], list, "faults", tw, "an array of tables [{ fault = ..., at = \"1 s\" }, ...]")
        for i, fault in enumerate(faults):
            _of_type(fault, dict, f"faults[{i}]", tw, "a table { fault = ..., at = \"1 s\", ... }")
        transducers.append(TransducerSpec(name, described(scene, t["description"]), t["signal"], t["to"],
                                          dict(t["overrides"]), list(t["faults"]), t["rate"]))
    wires = [t.to for t in transducers]
    for to in set(wires):
        if wires.count(to) > 1:
            raise SceneError(f"{scene.path} [transducers]: 'to' = {to!r} is given to more than one transducer")
    for message, specs in frames_of(transducers).items():
        if len({s.rate for s in specs}) > 1:
            raise SceneError(f"{scene.path} [transducers]: {', '.join(s.name for s in specs)} share CAN message "
                             f"{message} (one frame carries them all) but state different rates")
    device = scene.read("device", DEVICE_SCHEMA, required=False)
    dw = f"{scene.path} [device]"
    _of_type(device["config"], dict, "config", dw, "a table [device.config]")
    if device["description"] is not None:
        _of_type(device["description"], str, "description", dw, "a device description name or path")
        device["description"] = str(resolve_path(described(scene, device["description"])))
    can = scene.read("links.can", CAN_SCHEMA, required=False)
    cw = f"{scene.path} [links.can]"
    if not 0.0 < can["live_share"] <= 1.0:
        raise SceneError(f"{cw}: key 'live_share' must be in (0, 1], got {can['live_share']}")
    if can["data_bitrate"] is not None and not can["fd"]:
        raise SceneError(f"{cw}: key 'data_bitrate' is the data phase of CAN FD: set fd = true, or remove it for "
                         f"classic CAN")
    if can["data_bitrate"] is not None and can["data_bitrate"] < can["bitrate"]:
        raise SceneError(f"{cw}: key 'data_bitrate' = {can['data_bitrate']} bit/s must be at least 'bitrate' = "
                         f"{can['bitrate']} bit/s (the data phase is the faster one)")
    _check_period(can["tx_period"], s["chunk"], s["sample_rate"], cw, where)
    _of_type(can["channel"], str, "channel", cw, "a string")
    if not is_interface_name(can["channel"]):
        raise SceneError(f"{cw}: key 'channel' must be a name without white space, like a CAN interface's (can0, "
                         f"vcan0, rig); got {can['channel']!r}")
    _of_type(can["host"], str, "host", cw, "a host name or address")
    if can["interface"] not in IN_PROCESS_INTERFACES:
        raise SceneError(f"{cw}: key 'interface' must be one of {IN_PROCESS_INTERFACES} "
                         f"(the in-process bus), got {can['interface']!r}")
    serial = scene.read("links.serial", SERIAL_SCHEMA, required=False)
    sw = f"{scene.path} [links.serial]"
    _of_type(serial["port"], str, "port", sw, "'pty', a pyserial URL or a device path")
    recording = scene.read("recording", RECORDING_SCHEMA, required=False)
    rw = f"{scene.path} [recording]"
    from rig.recorder.encoding import ENCODINGS
    from rig.recorder.writer import COMPRESSIONS
    _one_of(recording["encoding"], ENCODINGS, "encoding", rw)
    _one_of(recording["compression"], tuple(COMPRESSIONS), "compression", rw)
    signals = recording["truth_signals"]
    if signals is not None and not (isinstance(signals, list) and all(isinstance(x, str) for x in signals)):
        raise SceneError(f"{rw}: key 'truth_signals' must be a list of signal names, got {signals!r}")
    _truth_every(recording["truth_rate"], s["sample_rate"], rw)
    if not choose_level:                    # the level's keys checked all the same (choose checks them as it reads)
        check_scene(scene, str(s["plant"]))
    max_time = s["max_time"] if s["max_time"] is not None else (
        s["duration"] if s["duration"] is not None else default_max_time(cycles))
    return RunConfig(scene=scene, name=str(s["name"]), plant=str(s["plant"]), seed=s["seed"],
                     cycles=cycles, duration=s["duration"], sample_rate=s["sample_rate"], chunk=s["chunk"],
                     mode=s["mode"], max_time=max_time, max_time_given=s["max_time"] is not None, transducers=tuple(transducers), device=device, can=can,
                     serial=serial, recording=recording,
                     fidelity=choose(scene, str(s["plant"]), fidelity) if choose_level else None)

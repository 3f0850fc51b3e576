"""The runner's scene sections: [scene], [transducers.*], [device], [links.can], [links.serial], [recording].

Plant sections ([plant], [speed], [load], ...) belong to the plant modules and are read there.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from rig.scene import Field, Scene, SceneError, read_table

SCENE_SCHEMA = {
    "name": Field(None), "description": Field(None, ""),
    "plant": Field(None, doc="plant kind, e.g. 'cam_bar' or 'clutch_dynamic'"),
    "seed": Field("1", doc="seed of every random draw of the run"),
    "cycles": Field("1", None, "number of device curves (machine cycles) to record"),
    "duration": Field("s", None, "simulated time to run when the scene has no cycles"),
    "sample_rate": Field("Hz", 10_000.0, "plant/transducer/acquisition sample rate"),
    "chunk": Field("s", 0.02, "simulated time advanced per runner step"),
    "mode": Field(None, "virtual", "'virtual' (as fast as possible) or 'realtime' (paced to the wall clock)"),
    "fidelity": Field(None, None, "fidelity level of the plant, informative"),
    "max_time": Field("s", None, "give up when the cycles are not complete by this simulated time"),
}
TRANSDUCER_SCHEMA = {
    "description": Field(None, doc="device description name in data/devices or a path"),
    "signal": Field(None, doc="plant truth signal the transducer measures"),
    "role": Field(None, doc="where its output goes: 'x', 'y' (device channels), 'encoder1', 'encoder2', "
                            "'torque', 'brake', 'angle', 'strain' (static rig), or 'record' (recorded only)"),
    "overrides": Field(None, {}, "description values to override, with units"),
    "faults": Field(None, [], "list of {fault = ..., at = '.. s', ...} tables"),
    "rate": Field("Hz", None, "publishing rate of encoder/torque/brake readings (default: once per chunk)"),
}
DEVICE_SCHEMA = {
    "program": Field("1", 0, "program number the run uses"),
    "config": Field(None, {}, "program settings merged over the unit's factory program"),
    "description": Field(None, None, "device description name or path (default: the DigiForce 9310 file)"),
}
CAN_SCHEMA = {
    "interface": Field(None, "blockbus", "in one process: 'blockbus' (frames in blocks) or python-can's 'virtual'"),
    "channel": Field(None, "rig"),
    "bitrate": Field("1", 500_000, "bit/s"), "fd": Field(None, False),
    "data_bitrate": Field("1", None, "bit/s of the CAN FD data phase"),
    "live_share": Field("1", 0.5, "share of the bus for live data"),
    "tx_curves": Field("1", 4, "curve transfers the unit holds for sending (more: the bus cannot carry the curves)"),
    "host": Field(None, "127.0.0.1", "socketcand server address (cross-process)"),
    "port": Field("1", 0, "socketcand TCP port (0: any free port)"),
}
SERIAL_SCHEMA = {
    "enabled": Field(None, True), "port": Field(None, "pty", "'pty', a pyserial URL or a device path"),
    "baudrate": Field("1", 115_200), "address": Field("1", 1),
}
RECORDING_SCHEMA = {
    "truth_signals": Field(None, None, "plant truth signals to record (default: all)"),
    "encoding": Field(None, "json", "'json' (viewer-plottable) or 'base64' (compact)"),
    "compression": Field(None, "zstd"),
}
MODES = ("virtual", "realtime")
IN_PROCESS_INTERFACES = ("blockbus", "virtual")
ROLES = ("x", "y", "encoder1", "encoder2", "torque", "brake", "angle", "strain", "record")


@dataclass(frozen=True)
class TransducerSpec:
    name: str
    description: str
    signal: str
    role: str
    overrides: dict[str, Any] = field(default_factory=dict)
    faults: list[dict[str, Any]] = field(default_factory=list)
    rate: float | None = None


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

    @property
    def dt(self) -> float:
        return 1.0 / self.sample_rate

    def role(self, role: str) -> TransducerSpec | None:
        return next((t for t in self.transducers if t.role == role), None)


def default_max_time(cycles: int) -> float:
    """Simulated time (s) a run of ``cycles`` curves may take before it gives up: 3 s per cycle + 10 s."""
    return 3.0 * cycles + 10.0


def _integer(value: float, key: str, where: str, minimum: int = 0) -> int:
    if value != int(value) or value < minimum:
        raise SceneError(f"{where}: key {key!r} must be an integer >= {minimum}, got {value}")
    return int(value)


def read_config(scene: Scene) -> RunConfig:
    """Validate the runner's sections of ``scene``; errors name the file, section and key."""
    where = f"{scene.path} [scene]"
    s = scene.read("scene", SCENE_SCHEMA)
    if s["mode"] not in MODES:
        raise SceneError(f"{where}: key 'mode' must be one of {MODES}, got {s['mode']!r}")
    if (s["cycles"] is None) == (s["duration"] is None):
        raise SceneError(f"{where}: give exactly one of 'cycles' and 'duration'")
    cycles = None if s["cycles"] is None else _integer(s["cycles"], "cycles", where, 1)
    if s["duration"] is not None and not s["duration"] > 0:
        raise SceneError(f"{where}: key 'duration' must be positive")
    if not s["sample_rate"] > 0 or not s["chunk"] > 0 or s["chunk"] * s["sample_rate"] < 2:
        raise SceneError(f"{where}: 'sample_rate' and 'chunk' must be positive, with >= 2 samples per chunk")
    transducers = []
    for name, table in scene.section("transducers", required=False).items():
        tw = f"{scene.path} [transducers.{name}]"
        if not isinstance(table, dict):
            raise SceneError(f"{tw}: must be a table")
        t = read_table(table, TRANSDUCER_SCHEMA, tw)
        if t["role"] not in ROLES:
            raise SceneError(f"{tw}: key 'role' must be one of {ROLES}, got {t['role']!r}")
        transducers.append(TransducerSpec(name, t["description"], t["signal"], t["role"], dict(t["overrides"]),
                                          list(t["faults"]), t["rate"]))
    roles = [t.role for t in transducers if t.role != "record"]
    for role in set(roles):
        if roles.count(role) > 1:
            raise SceneError(f"{scene.path} [transducers]: role {role!r} is given to more than one transducer")
    device = scene.read("device", DEVICE_SCHEMA, required=False)
    device["program"] = _integer(device["program"], "program", f"{scene.path} [device]")
    can = scene.read("links.can", CAN_SCHEMA, required=False)
    can["bitrate"] = _integer(can["bitrate"], "bitrate", f"{scene.path} [links.can]", 1)
    can["tx_curves"] = _integer(can["tx_curves"], "tx_curves", f"{scene.path} [links.can]", 1)
    if can["interface"] not in IN_PROCESS_INTERFACES:
        raise SceneError(f"{scene.path} [links.can]: key 'interface' must be one of {IN_PROCESS_INTERFACES} "
                         f"(the in-process bus), got {can['interface']!r}")
    serial = scene.read("links.serial", SERIAL_SCHEMA, required=False)
    serial["baudrate"] = _integer(serial["baudrate"], "baudrate", f"{scene.path} [links.serial]", 1)
    serial["address"] = _integer(serial["address"], "address", f"{scene.path} [links.serial]", 1)
    recording = scene.read("recording", RECORDING_SCHEMA, required=False)
    max_time = s["max_time"] if s["max_time"] is not None else (
        s["duration"] if s["duration"] is not None else default_max_time(cycles))
    return RunConfig(scene=scene, name=str(s["name"]), plant=str(s["plant"]), seed=_integer(s["seed"], "seed", where),
                     cycles=cycles, duration=s["duration"], sample_rate=s["sample_rate"], chunk=s["chunk"],
                     mode=s["mode"], max_time=max_time, max_time_given=s["max_time"] is not None, transducers=tuple(transducers), device=device, can=can,
                     serial=serial, recording=recording)

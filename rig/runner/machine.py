"""The simulated machine: plant truth → transducers → DigiForce → CAN node (and serial device).

This is the device side of the wire; ``rig serve`` runs it as its own process. It advances in chunks of
simulated time, the unit and its bus in transmit cycles within them; everything random comes from the scene's seed.
"""
from __future__ import annotations

import difflib
import hashlib
import logging
import math
import re
from collections.abc import Callable, Iterable
from typing import Any

import can
import numpy as np

from firmware_sim.can_node import CanNode
from firmware_sim.digiforce import DigiForce
from firmware_sim.transducers import load_transducer
from rig.runner.config import RunConfig, TransducerSpec
from rig.runner.plants import make_plant
from rig.scene import SceneError
from rig.units import to_si

log = logging.getLogger(__name__)


INSTRUMENT_STREAM = 0x696E737472   # spawn key of the instruments' generators under the scene seed ("instr")


def seeded_generators(seed: int, names: list[str]) -> dict[str, np.random.Generator]:
    """One independent generator per name, each a function of the seed and its name alone: a sensor draws the same
    errors wherever its table stands in the scene and whichever others the scene adds (by position, swapping two
    [transducers.*] tables re-drew both, x_max 42.16 → 41.89 mm; an audit)."""
    return {name: np.random.default_rng(np.random.SeedSequence(
        seed, spawn_key=(INSTRUMENT_STREAM, int.from_bytes(hashlib.sha256(name.encode()).digest()[:8], "big"))))
        for name in names}


def instruments(cfg: RunConfig) -> tuple[dict[str, Any], DigiForce]:
    """The scene's transducers (by name, faults injected) and its configured acquisition unit, each with its own
    generator under the scene's seed."""
    names = ["device"] + [t.name for t in cfg.transducers]
    rngs = seeded_generators(cfg.seed, names)
    transducers: dict[str, Any] = {}
    for spec in cfg.transducers:
        where = f"{cfg.scene.path} [transducers.{spec.name}]"
        try:
            sensor = load_transducer(spec.description, rngs[spec.name], **spec.overrides)
            for fault in spec.faults:
                fault = dict(fault)
                if "fault" not in fault:
                    raise SceneError(f"{where}: a fault table needs 'fault', its kind (docs/transducers.md), got "
                                     f"{sorted(fault)}")
                kind = fault.pop("fault")
                at = to_si(fault.pop("at", "0 s"), "s", what=f"{where} fault 'at'")
                until = to_si(fault.pop("until", "inf s"), "s", what=f"{where} fault 'until'")
                sensor.inject(kind, at=at, until=until, units_required=True, **fault)
        except (SceneError, ValueError, KeyError, TypeError) as exc:   # the description's own errors name its file
            message = str(exc)                                          # (and to_si's, this one): say it once
            raise SceneError(message if message.startswith(where) else f"{where}: {message}") from None
        transducers[spec.name] = sensor
    device = DigiForce(cfg.device["description"], rng=rngs["device"])
    program = cfg.device["program"]
    try:
        device.set_program(program, cfg.device["config"], units_required=True)   # a scene: units everywhere
        device.select_program(program)
    except ValueError as exc:
        raise SceneError(f"{cfg.scene.path} {_in_scene_words(str(exc), program)}") from None
    if cfg.measures_curves and cfg.sample_rate > device.desc.max_rate * (1 + 1e-9):     # found before the run, not in its first chunk
        raise SceneError(f"{cfg.scene.path} [scene]: 'sample_rate' = {cfg.sample_rate:g} Hz is faster than the "
                         f"acquisition unit takes its inputs ({device.desc.max_rate:g} Hz, [unit] max_rate of its "
                         f"description): lower sample_rate")
    sampling = device.get_program(program)["sampling"]      # a delta the scene gives must be one the stream has
    given = "delta" in (cfg.device["config"].get("sampling") or {})
    if given and sampling["mode"] == "time" and sampling["delta"] < cfg.dt * (1 - 1e-9):
        raise SceneError(f"{cfg.scene.path} [device.config.sampling]: 'delta' = {sampling['delta'] * 1e3:g} ms is "
                         f"finer than the machine's samples ({cfg.dt * 1e3:g} ms at [scene] sample_rate = "
                         f"{cfg.sample_rate:g} Hz): the unit can only take every sample; raise sample_rate or delta")
    if cfg.measures_curves:
        _warn_beyond_curve_fields(cfg, device.get_program(program))
    _warn_scaling_mismatch(cfg, transducers, device.get_program(program))
    return transducers, device


_SAID: set[str] = set()        # the scene warnings already given in this process


def _warn(said: str) -> None:
    """A scene warning, once per process: the check before the run and its machine both build the instruments."""
    if said not in _SAID:
        _SAID.add(said)
        log.warning("%s", said)


def _warn_scaling_mismatch(cfg: RunConfig, transducers: dict[str, Any], program: dict[str, Any]) -> None:
    """Warn where the unit's channel scaling reads a wired transducer's nominal output as another quantity than the
    one it stands for (a 2 mV/V cell on a channel set for 1.5 mV/V = 1000 N read every force 1.333× too large with
    no word; an audit): the reading of the transducer's range ends through the channel, against those ends. A
    rehearsal of a mis-set unit may mean it: a warning, not an error."""
    from firmware_sim.digiforce.program import scaling_line
    for spec in cfg.transducers:
        sensor, c = transducers.get(spec.name), program["channels"].get(spec.channel or "")
        if c is None or not c.get("enabled", True) or not hasattr(sensor, "nominal"):
            continue
        scale, zero = scaling_line(c["scaling"])
        ends = np.array([sensor.p["range_min"], sensor.p["range_max"]])
        read = (sensor.nominal(ends) - zero) * scale
        if np.max(np.abs(read - ends)) > 0.01 * (ends[1] - ends[0]):
            gain = (read[1] - read[0]) / (ends[1] - ends[0])
            _warn(f"{cfg.scene.path} [transducers.{spec.name}] → device.{spec.channel}: the unit's scaling "
                  f"([device.config.channels.{spec.channel}] scaling) reads the transducer's nominal output at "
                  f"{ends[0]:.4g} … {ends[1]:.4g} {c['unit']} as {read[0]:.4g} … {read[1]:.4g} {c['unit']} (× "
                  f"{gain:.4g}): every reading is off by that; set the channel's scaling to the transducer's "
                  f"(output_at_min/output_at_max of its description or overrides)")


def _warn_beyond_curve_fields(cfg: RunConfig, program: dict[str, Any]) -> None:
    """Warn where a channel measures beyond what the curve frames carry (its DBC field in the channel's SI unit,
    ±0.524 for X: 0.524 m, but only ±30° of an angle channel): there the curves are sent saturated
    (``curve_clipped``); said before the run instead of after it."""
    from rig.dbc import load_dbc
    from firmware_sim.digiforce.program import scaling_line
    block = load_dbc().get_message_by_name("CurveBlock")
    for ch, c in program["channels"].items():
        if not c.get("enabled", True) or ch.upper() not in block.signal_tree:
            continue
        field = block.get_signal_by_name(ch.upper()).maximum
        scale, zero = scaling_line(c["scaling"])
        reach = (c["range"] + abs(zero)) * abs(scale)            # the electrical range ±range through the scaling
        said = (f"{cfg.scene.path} [device.config.channels.{ch}]: the channel measures up to ±{reach:.4g} {c['unit']}, "
                f"the curve frames carry ±{field:.4g} {c['unit']} (CurveBlock.{ch.upper()}): values beyond are sent at "
                f"the limit and counted (curve_clipped events)"
                + ("; an angle channel carries ±30° (the field is sized for metres)" if c["unit"] == "rad" else ""))
        if reach > field * (1 + 1e-9):
            _warn(said)


FLUSH_STEP = 0.005       # s: the end of a run drains the unit's transmit queue in steps this fine (not whole chunks)
_PROBED: dict[tuple, list[str]] = {}   # the truth signals a probe found, by scene content and fidelity (one probe
                                       # per process: a command's check before the run and its machine both ask)


def _in_scene_words(message: str, program: int) -> str:
    """The unit's error about ``program`` ("program 1.limits.y_min: …") where the scene wrote it: "[device.config.limits]
    key 'y_min': …" (a deeper or indexed path under "[device.config]"; another message under "[device]")."""
    m = re.match(rf"program {program}(?:\.([\w.\[\]]+))?((?: \([^)]*\))?(?:\.[\w.\[\]]+)?): (.*)", message,
                 re.DOTALL)
    if m is None:
        return f"[device]: {message}"
    path, which, text = m.groups()                   # which: " (lower)" of a limit pair, " (window 'W1').x_min", ""
    if path is None:
        return f"[device.config]: {text}"
    listed = re.match(r"(\w+)\[(\d+)\](.*)", path)          # elements[0]: the scene's first [[device.config.elements]]
    if listed:
        rest = f", key {listed[3][1:]!r}" if listed[3].startswith(".") else listed[3]      # ".kind" → ", key 'kind'"
        return f"[[device.config.{listed[1]}]] no. {int(listed[2]) + 1}{rest}{which}: {text}"
    section, _, key = path.rpartition(".")
    if section and "." not in section:
        return f"[device.config.{section}] key {key!r}{which}: {text}"
    return f"[device.config] {path}{which}: {text}"


def check_signals(cfg: RunConfig, truth: Iterable[str], warn: bool = True) -> None:
    """A :class:`SceneError` naming the transducer whose ``signal`` the plant's ``truth`` (its signal names) does
    not have, or a ``[recording] truth_signals`` entry that misspells one of its signals (another name it does not
    have at this model level, e.g. a level-2 signal in a forced level-1 run: a warning if ``warn``, it is not
    recorded)."""
    known = sorted(k for k in truth if k != "t")
    for spec in cfg.transducers:
        if spec.signal not in truth:
            raise SceneError(f"{cfg.scene.path} [transducers.{spec.name}]: the plant has no signal "
                             f"{spec.signal!r} (it has {', '.join(known)})")
    absent = [name for name in cfg.recording["truth_signals"] or () if name not in known]
    for name in absent:
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.8)
        if close:                           # a misspelling: an error, not a signal silently not recorded
            raise SceneError(f"{cfg.scene.path} [recording]: 'truth_signals' names {name!r}, which the plant does "
                             f"not have (did you mean {close[0]!r}?); it has {', '.join(known)}")
    if absent and warn:
        log.warning("%s [recording]: 'truth_signals' names %s, which the plant does not have at this model level "
                    "(L%d): not recorded", cfg.scene.path, ", ".join(map(repr, absent)), cfg.fidelity.level)


def _node(cfg: RunConfig, bus: can.BusABC | None, device: Any) -> CanNode:
    c = cfg.can
    return CanNode(bus, device, bitrate=c["bitrate"], fd=bool(c["fd"]), data_bitrate=c["data_bitrate"],
                   live_share=c["live_share"], tx_curves=c["tx_curves"])


def bus_plan(cfg: RunConfig, node: CanNode) -> dict[str, float]:
    """Share of the bus each periodic stream takes (status, each reading message the scene wires); a SceneError
    when they alone need more than the bus (curves and live data come on top)."""
    plan = {"status": sum(node.frame_time_planned(n) for n in ("Heartbeat", "StatusCounters", "TxStatus"))
            / node.heartbeat_period}
    for message, specs in cfg.frames().items():
        plan[message] = (specs[0].rate or 1.0 / cfg.can["tx_period"]) * node.frame_time_planned(message)
    if sum(plan.values()) > 1.0:
        shares = ", ".join(f"{k} {v:.0%}" for k, v in plan.items())
        raise SceneError(f"{cfg.scene.path} [links.can]: the periodic frames alone need {sum(plan.values()):.0%} "
                         f"of the {cfg.can['bitrate']:g} bit/s bus ({shares}): raise the bitrate or lower the "
                         "transducers' publishing rates")
    return plan


def probe_signals(cfg: RunConfig) -> None:
    """:func:`check_signals` on a probe: the nominal plant advanced by one chunk (the varied plant has the same
    signals). The chunk also takes the plant's first-call costs (its compiled kernels loaded from numba's cache:
    30–80 ms for a clutch stand) before any run phase, whose real-time factor they would otherwise spoil."""
    key = (cfg.scene.content, repr(cfg.fidelity), cfg.sample_rate, cfg.chunk)
    known = _PROBED.get(key)
    if known is None:
        probe = make_plant(cfg.plant, cfg.scene, nominal=True, fidelity=cfg.fidelity)
        truth = probe.advance(cfg.sample_times(0, cfg.chunk_samples))
        if hasattr(probe, "prepare"):   # a plant whose first chunks may not reach its compiled kernels loads them here
            probe.prepare()
        check_signals(cfg, truth)
        _PROBED[key] = list(truth)
    else:
        check_signals(cfg, known, warn=False)      # said at the first probe


def check_wiring(cfg: RunConfig) -> None:
    """Check, before anything runs or is written, that every transducer reads a signal the plant has
    (:func:`probe_signals`) and that the periodic frames fit the bus (:func:`bus_plan`)."""
    probe_signals(cfg)
    bus_plan(cfg, _node(cfg, None, None))


class Machine:
    """Plant, transducers and the acquisition unit on a CAN bus, stepped in virtual time."""

    def __init__(self, cfg: RunConfig, bus: can.BusABC) -> None:
        self.cfg = cfg
        probe_signals(cfg)             # before a recorder opens: the bus plan follows on this machine's own node
        self.plant = make_plant(cfg.plant, cfg.scene, fidelity=cfg.fidelity)
        self.transducers, self.device = instruments(cfg)
        for spec in cfg.transducers:
            counter = hasattr(self.transducers[spec.name], "sample")
            if spec.message is not None and counter != (spec.frame_signal is None):
                raise SceneError(f"{cfg.scene.path} [transducers.{spec.name}] to = {spec.to!r}: " + (
                    f"a counter fills a message's Count and EdgeTime: write 'can.{spec.message}'" if counter
                    else "a reading goes into one signal: write 'can.MESSAGE.SIGNAL'"))
            if spec.channel is not None and counter:
                raise SceneError(f"{cfg.scene.path} [transducers.{spec.name}]: a counter cannot feed the unit's "
                                 f"analog channel {spec.channel!r}")
        self.node = _node(cfg, bus, self.device)
        self._xy = cfg.wired("device.x"), cfg.wired("device.y")      # the unit's channels, if wired
        self._frames = cfg.frames()                                    # reading message -> its transducers
        self.bus_plan = bus_plan(cfg, self.node)
        self.t = 0.0
        self._step_index = 0
        self._n = cfg.chunk_samples
        self._period = cfg.period_samples
        # a run of a duration: its samples up to the first transmit cycle's end at or after it (none computed beyond)
        self._last = None if cfg.duration is None else \
            -(-math.ceil((cfg.duration - 1e-9) * cfg.sample_rate) // self._period) * self._period
        self.curves = 0
        self.cycle_curves = 0          # curves queued in the latest transmit cycle

    def _publish_indices(self, rate: float | None, first_sample: int, n: int) -> np.ndarray:
        """Indices in a transmit cycle (whose first sample has global number ``first_sample``) at which readings at
        ``rate`` (Hz; None: once per cycle, at its last sample) are published: global sample numbers that are
        multiples of ``sample_rate / rate``."""
        every = self._period if rate is None else max(1, round(self.cfg.sample_rate / rate))
        return np.arange((-first_sample) % every, n, every)

    def _frame_values(self, spec: TransducerSpec, output: Any, idx: np.ndarray, message: str) -> dict[str, np.ndarray]:
        """What transducer ``spec`` puts in its CAN ``message`` at ``idx``: a counter its latched Count and last
        EdgeTime, and the card's illegal transitions where the message has an ``Illegal`` field (held at the field's
        maximum: a wrap could hide any number of them), any other its reading scaled back to its quantity (SI) with the
        nominal sensitivity, as the instrument's display does."""
        if spec.frame_signal is None:
            values = {"Count": output.count[idx], "EdgeTime": np.nan_to_num(output.edge_time[idx])}
            field = next((s for s in self.node.db.get_message_by_name(message).signals if s.name == "Illegal"), None)
            if field is not None:
                illegal = getattr(output, "illegal", None)
                values["Illegal"] = np.zeros(len(idx)) if illegal is None else np.minimum(illegal[idx], field.maximum)
            return values
        reading = self.transducers[spec.name].to_physical(output[idx])
        return {spec.frame_signal: np.ravel(reading)}

    def step(self, done: Callable[["Machine"], bool] = lambda machine: False) -> dict[str, np.ndarray]:
        """Advance one chunk: the plant and the transducers over the whole chunk at once, then the unit and its bus
        one transmit cycle after the other, as a chunk of one cycle would (the curves that ended in the cycle
        queued, its live pairs planned against the bus, its readings queued, the bus run to the cycle's end): with a
        plant evaluated point by point the chunk changes no recorded value (one that integrates restarts at each
        call). ``done(machine)``, asked after each cycle, ends the step there (the unit
        is not fed past it; the plant and transducers have computed the rest of the chunk, unused). A run of a
        duration ends its last chunk at the first cycle end at or after it. Returns the plant truth of the chunk (SI,
        with its times ``t``). Every output goes where the scene wires it (``to``)."""
        i0 = self._step_index * self._n
        n = self._n if self._last is None else min(self._n, self._last - i0)
        t = self.cfg.sample_times(i0, n)
        self._step_index += 1
        truth = self.plant.advance(t)
        output = {}
        for spec in self.cfg.transducers:
            sensor = self.transducers[spec.name]
            read = sensor.sample if hasattr(sensor, "sample") else sensor.measure
            output[spec.name] = read(t, truth[spec.signal])
        for a in range(0, n, self._period):
            self._cycle(t, output, i0, a, min(a + self._period, n))
            if done(self) or self.node.released:
                break
        return truth

    def _cycle(self, t: np.ndarray, output: dict[str, Any], i0: int, a: int, b: int) -> None:
        """One transmit cycle, the samples ``a:b`` of the chunk whose first sample follows sample number ``i0``."""
        self.cycle_curves = 0
        x, y = self._xy
        part = slice(a, b)
        if x is not None and y is not None:
            # Y2 has no transducer wired (scenes wire X and Y): enabled (a host may, over serial) it reads an open input
            y2 = np.zeros(b - a) if "y2" in self.device.enabled_channels else None
            for result in self.device.feed(t[part], output[x.name][part], output[y.name][part], y2):   # queued when
                self.node.publish_measurement(float(np.asarray(result.curve.t)[-1]), result)           # the curve ends
                self.curves += 1
                self.cycle_curves += 1
            live = self.device.live_values()
            self.node.publish_live(t[part], live["x"], live["y"])
        for message, specs in self._frames.items():
            idx = a + self._publish_indices(specs[0].rate, i0 + a + 1, b - a)
            values: dict[str, np.ndarray] = {}
            for spec in specs:
                values.update(self._frame_values(spec, output[spec.name], idx, message))
            self.node.publish_reading(message, t[idx], values)
        self.node.advance_to(float(t[b - 1]))
        self.t = float(t[b - 1])

    def flush(self, limit: float = 60.0, pace: Callable[[float], object] = lambda t: None,
              cause: str = "Completed") -> None:
        """End the run: let the node send everything still queued (results of the last curve) in virtual
        time, then close it (final status with ``RunEnded`` and ``cause``, a ``StopCause`` of the DBC; nothing follows
        it on the wire). ``pace(t)`` after each chunk (real-time mode: the bus drains its backlog on the wall clock
        too)."""
        t_start, t_end = self.t, self.t + limit
        step = min(self.cfg.chunk, FLUSH_STEP)
        while self.node.has_pending_before(t_start) and self.t < t_end:   # later heartbeats need not wait
            self.t += step
            self.node.advance_to(self.t)
            pace(self.t)
        self.node.close(self.t, cause)

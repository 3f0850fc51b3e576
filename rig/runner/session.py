"""Running a scene: both sides in one process (``rig run``), or each side alone (``rig serve``/``rig record``)."""
from __future__ import annotations

import json
import hashlib
import logging
import math
import os
import socket
import threading
import time
import uuid
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Iterator

import can
from tqdm import tqdm

import rig
from rig.console import progress as progress_bar, quiet_libraries
from rig.fidelity import announce as announce_fidelity
from firmware_sim.serial_device import SerialDevice
from firmware_sim.socketcand_server import SocketcandServer
from rig.numba_clock import compile_seconds, watch
from rig.recorder import Recorder
from rig.recorder.writer import interruption
from firmware_sim.can_node import BusOverload
from rig.runner.config import CAN_SCHEMA, RunConfig, default_max_time, read_config
from rig.runner.errors import BusTooSlow, HostLeft, HostStalled, OutOfTime, RunError
from rig.runner.host import Host
from rig.interrupt import deferred_interrupt, shielded
from rig.runner.machine import Machine
from rig.runner.served import Anchored, IdleStatus, RunClock
from rig.scene import SceneError, load_scene
from rig.stops import stopped, terminated

log = logging.getLogger(__name__)
SERVE_BACKLOG = 20_000   # frames a served machine may have sent that its host's connection has not yet taken (~2.5 s
#                          of a saturated 1 Mbit/s bus); beyond, it waits for its host (TCP's buffers hold more)
LISTENER_BACKLOG = 200_000   # frames held for a connection that does not hold the machine back (a logger that only
#                              listens) and does not read: beyond, its oldest are dropped (a receive queue's overflow)
SERVE_DRAIN = 10.0      # s a served machine waits at its stop (for its hosts) or end (for listeners) for what it sent
SLOW_HOST = 10.0        # s of waiting for a host that does not read before the served machine says so
QUIET = 0.5        # s without frames after which `rig record` looks whether the served machine closed the connection


class Interrupted(KeyboardInterrupt):
    """Ctrl-C during a recorded run. ``recording``: the file holding what was recorded (marked
    interrupted), or None when nothing had been recorded (no new file is left); ``kept``: then the earlier
    recording at the output path, left as it was (None: there was none); ``curves`` and ``simulation_time`` (s):
    what the recording holds."""

    def __init__(self, recording: Path | None, kept: Path | None = None, curves: int = 0,
                 simulation_time: float = 0.0) -> None:
        super().__init__()
        self.recording = recording
        self.kept = kept
        self.curves, self.simulation_time = curves, simulation_time     # what the recording holds (s)


@dataclass
class RunSummary:
    """What a run produced: ``wall_time`` (s) of the whole run, set-up (serial configuration, statistics
    read-back) included; ``run_time`` (s): its run phase, from the go signal to the last curve recorded;
    ``simulated_time`` (s): the simulated time the run phase covered (not the time the machine runs on while the
    statistics are read back), ``flush_time`` (s) of it after the scene's end while the bus carried the last frames;
    ``compile_time`` (s): numba's one-time compilations inside the run phase (a first run in a fresh cache), not
    counted in :attr:`realtime_factor`."""

    output: Path
    curves: int
    simulated_time: float
    wall_time: float
    frames: int
    statistics: dict[str, Any] = field(default_factory=dict)
    run_time: float = 0.0
    compile_time: float = 0.0
    flush_time: float = 0.0

    @property
    def realtime_factor(self) -> float:
        """Simulated time per wall time of the run phase, its one-time numba compilations left out."""
        busy = self.run_time - self.compile_time
        return self.simulated_time / busy if busy > 0 else float("inf")


def _classic_can(cfg: RunConfig, role: str) -> None:
    """Refuse a CAN FD scene where the bus runs over socketcand (``role``: what is starting), whose raw mode carries
    classic frames only: the unit's 64-byte curve and live frames could never reach the host."""
    if cfg.can["fd"]:
        raise SceneError(f"{cfg.scene.path} [links.can]: fd = true, but {role} over socketcand, which carries "
                         "classic CAN frames only (its curve and live frames of 64 bytes would never reach the host): "
                         "set fd = false for a served run, or run the scene in one process with rig run")


def _config(scene_path: str | Path, cycles: int | None, mode: str | None, fidelity: int | None = None,
            classic_can: str | None = None) -> RunConfig:
    """The run's configuration with the command line's changes; ``classic_can`` (the role, for its message): refuse a
    CAN FD scene before the fidelity is announced."""
    cfg = read_config(load_scene(scene_path), fidelity)
    changes: dict[str, Any] = {}
    if cycles is not None:
        if cfg.cycles is None:
            raise RunError(f"{scene_path}: --cycles given, but this scene runs for a duration")
        if cycles < 1:
            raise RunError(f"{scene_path}: --cycles must be at least 1, got {cycles}")
        changes["cycles"] = cycles
        if not cfg.max_time_given:
            changes["max_time"] = default_max_time(cycles)
    if mode is not None:
        changes["mode"] = mode
    if changes:
        cfg = replace(cfg, **changes)
    if cfg.mode == "realtime" and cfg.chunk > cfg.can["tx_period"]:
        cfg = replace(cfg, chunk=cfg.can["tx_period"])    # paced cycle by cycle: the bus keeps to the wall clock
    if classic_can is not None:
        _classic_can(cfg, classic_can)
    announce_fidelity(cfg.fidelity)
    return cfg


def _machine_done(cfg: RunConfig, machine: Machine) -> bool:
    if cfg.cycles is not None:
        if machine.curves < cfg.cycles and machine.t > cfg.max_time:
            why = (f"the scene's [scene] max_time = {cfg.max_time:g} s ends the run first: raise it for this many "
                   f"cycles, or check the device's start/stop settings" if cfg.max_time_given else
                   f"max_time {cfg.max_time:g} s, {cfg.max_time / cfg.cycles:g} s per cycle: check the device's "
                   f"start/stop settings")
            stalls = [e for e in getattr(machine.plant, "events", []) if e.kind == "cam_stalled"]
            if stalls:              # the machine's own cause, not the device's settings (an audit: 190 stalls unsaid)
                why = (f"the cam stalled {len(stalls)} time(s), first at t = {stalls[0].time:.4g} s: its motor cannot "
                       f"carry the mechanism over its peak drive torque ([plant.drive] max_torque, or a load too "
                       f"high), so the machine made no cycles at its speed — see the cam_stalled events")
            raise OutOfTime(f"{cfg.scene.path}: only {machine.curves} of {cfg.cycles} curves by {machine.t:.3f} s "
                           f"of simulated time ({why})")
        return machine.curves >= cfg.cycles
    return machine.t >= cfg.duration - 1e-9


class _Pacer:
    """Keeps simulated time from running ahead of the wall clock in real-time mode, and says when it falls
    behind: one warning the first time the simulation lags more than ``tolerance`` s, a count at the end
    (:meth:`finish`). Behind, it does not wait, so the run catches up when it can."""

    def __init__(self, realtime: bool, tolerance: float = 0.1, clock: Callable[[], float] = time.perf_counter,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self.realtime, self.tolerance, self.clock, self.sleep = realtime, tolerance, clock, sleep
        self.start = clock()
        self.steps = self.behind = 0
        self.worst = 0.0

    def __call__(self, t_sim: float) -> None:
        if not self.realtime:
            return
        self.steps += 1
        ahead = t_sim - (self.clock() - self.start)
        if ahead > 0:
            self.sleep(ahead)
        elif -ahead > self.tolerance:
            self.behind += 1
            self.worst = max(self.worst, -ahead)
            if self.behind == 1:
                log.warning("real time: the simulation falls behind the wall clock (%.2f s behind at %.2f s of "
                            "simulated time); it runs as fast as it can", -ahead, t_sim)

    def finish(self) -> None:
        if self.behind:
            log.warning("real time: behind the wall clock by more than %g s in %d of %d steps (at most %.2f s)",
                        self.tolerance, self.behind, self.steps, self.worst)


def _progress(cfg: RunConfig, enabled: bool) -> tqdm:
    """The run's bar: machine cycles (simulated time as a postfix), or simulated seconds for a scene run
    for a duration; it stays on screen as the run's last line."""
    if cfg.cycles is not None:
        return progress_bar(cfg.cycles, cfg.name, " cycles", enabled, postfix="t = 0.00 s")
    return progress_bar(round(cfg.duration, 3), cfg.name, " s simulated", enabled,
                        bar_format="{l_bar}{bar}| {n:.2f}/{total:.2f} s simulated [{elapsed}<{remaining}{postfix}]")


def _show(bar: tqdm, cfg: RunConfig, cycles: int, t: float, force: bool = False) -> None:
    """Move the bar to ``cycles`` (or to ``t`` for a duration scene) with ``t`` (s simulated) as postfix;
    tqdm redraws at most every ``mininterval`` (0.1 s) unless ``force``."""
    value = cycles if cfg.cycles is not None else round(min(t, cfg.duration), 3)
    if cfg.cycles is not None:
        bar.set_postfix_str(f"t = {t:.2f} s", refresh=False)
    if value != bar.n:
        bar.update(value - bar.n)
    if force:
        bar.refresh()


def _finishing(bar: tqdm, cfg: RunConfig, t: float) -> None:
    """Say on the bar that the run's last phase (statistics read back over serial, or without the serial link the
    recording's end) is under way."""
    bar.set_postfix_str((f"t = {t:.2f} s; " if cfg.cycles is not None else "")
                        + ("reading the device statistics" if cfg.serial["enabled"] else "closing the recording"))


def _finished(bar: tqdm, cfg: RunConfig, t: float, curves: int) -> None:
    bar.set_postfix_str(f"t = {t:.2f} s, {curves} curves recorded" if cfg.cycles is not None else "", refresh=False)


def _drive(cfg: RunConfig, machine: Machine, lock: threading.Lock, bar: tqdm,
           after_step: Callable[[], object], host_gone: Callable[[], bool] = lambda: False,
           room: Callable[[float], bool] = lambda timeout: True) -> float:
    """Step the machine until the scene is done or the host released it (paced in real-time mode), then
    flush its transmit queue; the simulated time (s) that flush took (the bus carrying the last frames).
    ``after_step`` runs after each step (e.g. the in-process host's poll); ``host_gone()`` true (the served host
    disconnected) stops the run with a :class:`RunError`; ``room(timeout)``: whether the link has room for the next
    step's frames, waiting up to ``timeout`` s (a served machine waits for its host: back-pressure, so what it has
    computed and not yet delivered stays bounded). Ctrl-C is taken between steps (:mod:`.interrupt`)."""
    pace = _Pacer(cfg.mode == "realtime")
    try:
        with deferred_interrupt() as check:
            return _steps(cfg, machine, lock, bar, after_step, host_gone, pace, check, room)
    except OutOfTime:               # the run ends as a complete one (its queue sent), its last status saying why
        with lock:
            machine.flush(cause=OutOfTime.stop_cause)
        raise
    except BaseException as exc:    # the unit stops sending and says why (every host records it)
        _abort(machine, lock, exc)
        raise
    finally:
        _show(bar, cfg, machine.curves, machine.t, force=True)
        pace.finish()


SHORT_TX = CAN_SCHEMA["tx_period"].default      # s: the unit's default transmit cycle sends each curve as it ends


def _steps(cfg: RunConfig, machine: Machine, lock: threading.Lock, bar: tqdm, after_step: Callable[[], object],
           host_gone: Callable[[], bool], pace: "_Pacer", check: Callable[[], None],
           room: Callable[[float], bool]) -> float:
    """:func:`_drive`'s loop, ``check()`` for Ctrl-C before each step and before the flush."""
    while not _machine_done(cfg, machine) and not machine.node.released:
        check()
        while not room(0.1) and not host_gone():   # outside the device lock: the serial link answers meanwhile
            check()
        gone = host_gone()                 # before the step: a Release sent just before leaving counts
        with lock:
            try:
                machine.step(done=lambda m: _machine_done(cfg, m))
            except BusOverload as exc:
                burst, held = machine.cycle_curves, cfg.can["tx_curves"]
                if burst >= held:          # the cycle, not the bus: its curves all ended before any could leave
                    period = cfg.can["tx_period"]
                    shorter = (f"shorten [links.can] tx_period (e.g. \"{SHORT_TX * 1e3:g} ms\") so that each curve is "
                               f"sent as it ends, " if period > SHORT_TX else "")       # (1 rpm was told to shorten
                    raise BusTooSlow(                                                   # 100 ms to 100 ms; an audit)
                        f"{cfg.scene.path}: one transmit cycle of the unit ({period:g} s) measured {burst} curves at "
                        f"once, as many as it holds for sending (tx_curves = {held}): if the machine makes that many "
                        f"cycles so fast, {shorter or 'raise [links.can] tx_curves, '}else curves that short are its start/stop "
                        f"trigger firing again and again (a signal chattering about its threshold, e.g. at a crawl) — "
                        f"check the device's start/stop settings ([device.config]) against the signals") from None
                raise BusTooSlow(f"{cfg.scene.path} [links.can]: {exc}") from None
        if gone and not machine.node.released:
            raise _host_left(machine, "during the run")
        after_step()
        _show(bar, cfg, machine.curves, machine.t)
        pace(machine.t)
    check()
    with lock:
        ended = machine.t
        machine.flush(pace=lambda t: (check(), pace(t)))    # realtime: up to a minute of pacing, Ctrl-C taken
        return machine.t - ended


def _stop_cause(exc: BaseException) -> str:
    """The ``TxStatus.StopCause`` of a run stopped by ``exc``: Ctrl-C or SIGTERM ``OperatorStop``, a
    :class:`RunError` its ``stop_cause``, any other error ``Fault``."""
    return "OperatorStop" if isinstance(exc, KeyboardInterrupt) else getattr(exc, "stop_cause", RunError.stop_cause)


def _last_status(machine: Machine) -> str:
    """What the unit's last status said of the run's end, in words (its ``StopCause``, or that none was sent)."""
    if machine.node.ended:
        return f"the unit's last status says StopCause {machine.node.stop_cause}"
    return "the unit could not send its last status"


def _abort(machine: Machine, lock: threading.Lock, exc: BaseException) -> None:
    """The machine's run stopped by ``exc``: its unit discards what it still has queued and sends its final status,
    ``StopCause`` naming why (:func:`_stop_cause`). A failure doing so is a warning: the stop goes on with its own
    error."""
    try:
        with lock:
            machine.node.abort(_stop_cause(exc))
    except Exception as err:  # noqa: BLE001 - the stop's own error is what the user needs
        log.warning("the unit could not send its final status (%s: %s)", type(err).__name__, err)


def _wait_for_go(machine: Machine, timeout: float, idle: Callable[[], None] = lambda: None,
                 lock: threading.Lock | None = None) -> None:
    """Wait until the host's first command (program select over CAN) has reached the machine, or the host
    released it; ``idle()`` runs meanwhile, every 5 ms; ``lock`` guards the device."""
    deadline = time.monotonic() + timeout
    while True:
        with lock or nullcontext():
            if machine.node.handle_commands() or machine.node.released:
                return
        if time.monotonic() > deadline:
            raise RunError(f"no host connected and started a run within {timeout:g} s (of publishing the "
                           f"endpoints)")
        idle()
        time.sleep(0.005)


def _host_left(machine: Machine, when: str) -> RunError:
    return HostLeft(f"the host disconnected {when} without releasing the device ({machine.curves} curves served, "
                    f"{machine.t:.3f} s of device time); stopping")


def _metadata(cfg: RunConfig, mode: str) -> dict[str, Any]:
    return {"scene": cfg.name, "scene_file": str(cfg.scene.path.resolve()), "seed": cfg.seed, "plant": cfg.plant,
            "run_mode": mode, "software_version": rig.__version__, "sample_rate": cfg.sample_rate,
            "cycles": cfg.cycles, "duration": cfg.duration, "fidelity_level": cfg.fidelity.level,
            "fidelity_reason": cfg.fidelity.reason, "method": cfg.fidelity.method_text,
            "fidelity_caveat": cfg.fidelity.caveat, "truth_caveat": cfg.truth_caveat,
            "serial_link": "on" if cfg.serial["enabled"] else "off"}


def _units(cfg: RunConfig) -> dict[str, dict[str, str]]:
    """The SI units the recording's schemas state (:class:`Recorder` ``units``): the plants' truth signals, the
    ``/stand/`` topics' DBC units, the unit's X and Y (those of the plant signals the scene wires to them)."""
    from rig.analysis.export import stand_units
    from rig.analysis.units import SIGNAL_SI
    from rig.recorder import schemas as S
    device = {role: SIGNAL_SI[spec.signal] for role in ("x", "y")
              if (spec := cfg.wired(f"device.{role}")) is not None and spec.signal in SIGNAL_SI}
    return {"": SIGNAL_SI, S.LIVE: device, S.CURVE: device, **stand_units()}


@contextmanager
def _recorder(cfg: RunConfig, output: Path, mode: str) -> Iterator[Recorder]:
    """The run's recorder. On an exception the file is finished marked interrupted, or removed when it
    holds no message — and then an earlier recording at ``output`` (moved aside while the run starts) is put back;
    Ctrl-C becomes :class:`Interrupted` naming what is left."""
    output.parent.mkdir(parents=True, exist_ok=True)
    earlier = output.with_name(f".{output.name}.earlier")
    if output.exists():
        os.replace(output, earlier)
    else:
        earlier.unlink(missing_ok=True)
    try:
        rec = Recorder(output, scene_text=cfg.scene.text, metadata=_metadata(cfg, mode),
                       encoding=cfg.recording["encoding"], compression=cfg.recording["compression"],
                       view_rate=cfg.recording["view_rate"], units=_units(cfg))
    except BaseException:
        _restore(earlier, output)
        raise
    try:
        yield rec
    except BaseException as exc:
        with shielded():                    # a second Ctrl-C must not cut the closing short
            kept = rec.messages > 0
            rec.close(interrupted=interruption(exc))
            restored = None
            if kept:
                earlier.unlink(missing_ok=True)
            else:
                output.unlink(missing_ok=True)
                restored = _restore(earlier, output)
        if isinstance(exc, KeyboardInterrupt) and not isinstance(exc, Interrupted):
            raise Interrupted(output if kept else None, restored, rec.curves, rec.simulation_time) from exc
        raise
    with deferred_interrupt():              # a Ctrl-C while the whole file is finished: after it, not inside it
        rec.close()
    earlier.unlink(missing_ok=True)


def _stop_of_run(exc: KeyboardInterrupt) -> str:
    """What cut a curve in transfer, in its ``incomplete_curve`` event: Ctrl-C's or SIGTERM's stop."""
    return "the termination (SIGTERM) of the run" if terminated(exc) else "the interruption of the run"


def _keep_received(host: Host, drain: bool, why: str) -> None:
    """On Ctrl-C, SIGTERM (``why``: :func:`_stop_of_run`) or a run stopped by an error (``why`` names it): what is
    already on the wire (``drain``: the in-process bus, whose machine has stopped) and received goes into the
    recording, and what the stop cut is said in events (a curve in transfer, the last live drops); a failure doing so
    is a warning, the stop goes on. A second Ctrl-C is ignored meanwhile (:func:`.interrupt.shielded`)."""
    try:
        with shielded():
            try:
                while drain and host.poll():
                    pass
            finally:                        # a failing drain too: the held theory and the events found go in
                host.interrupted(why)
    except Exception as exc:  # noqa: BLE001 - the recording is closed as interrupted either way
        log.warning("could not record what was received before the interruption (%s: %s)", type(exc).__name__, exc)


def _restore(earlier: Path, output: Path) -> Path | None:
    """Put the earlier recording moved aside back at ``output``; its path, or None when there was none."""
    if not earlier.exists():
        return None
    os.replace(earlier, output)
    return output


def _bus(cfg: RunConfig, channel: str) -> can.BusABC:
    """One end of the in-process bus the scene names (``blockbus`` or python-can's ``virtual``)."""
    extra = {"preserve_timestamps": True} if cfg.can["interface"] == "virtual" else {}
    return can.Bus(interface=cfg.can["interface"], channel=channel, **extra)


def run_scene(scene_path: str | Path, output: str | Path, *, cycles: int | None = None, mode: str | None = None,
              progress: bool = False, fidelity: int | None = None) -> RunSummary:
    """Run machine and host in one process: CAN on python-can's ``virtual`` interface, serial on a pty."""
    watch()
    cfg = _config(scene_path, cycles, mode, fidelity)
    if cfg.truth_caveat:                # (in the recording's metadata and its report too)
        log.info("%s", cfg.truth_caveat)
    output = Path(output)
    channel = f"rig-{uuid.uuid4().hex}"
    wall = time.perf_counter()
    with _bus(cfg, channel) as machine_bus, _bus(cfg, channel) as host_bus:
        machine = Machine(cfg, machine_bus)
        lock = threading.Lock()
        serial_dev = (SerialDevice(machine.device, cfg.serial["port"], cfg.serial["baudrate"], cfg.serial["address"],
                                   lock=lock).start() if cfg.serial["enabled"] else None)
        try:
            with _recorder(cfg, output, "in-process") as rec, _progress(cfg, progress) as bar:
                host = Host(cfg, host_bus, serial_dev.port if serial_dev else None, rec)
                host.arm()
                _wait_for_go(machine, 5.0)
                go, compiled = time.perf_counter(), compile_seconds()
                try:
                    flushed = _drive(cfg, machine, lock, bar, host.poll)
                    with deferred_interrupt() as check:
                        while host.poll():
                            check()
                except RunError:               # record what is already on the wire and what the stop cut
                    _keep_received(host, drain=True, why="the run's stop on an error")
                    raise
                except KeyboardInterrupt as exc:
                    _keep_received(host, drain=True, why=_stop_of_run(exc))
                    raise
                except Exception as exc:           # a model that cannot go on, a fault: the run so far is kept
                    _keep_received(host, drain=False, why=f"the run's stop on {type(exc).__name__}")
                    raise
                run_time, simulated = time.perf_counter() - go, machine.t     # the run phase (no read-back)
                compiled = compile_seconds() - compiled
                if not host.done():
                    _keep_received(host, drain=False, why="the run's stop on an error")     # the events it names
                    raise RunError(f"the host received only {host.curves_recorded} complete curves of "
                                   f"{machine.curves} measured (see /events in {output})")
                _finishing(bar, cfg, machine.t)
                with deferred_interrupt():     # the serial read-back writes the statistics: not cut inside
                    stats = host.finish()
                _finished(bar, cfg, machine.t, host.curves_recorded)
        finally:
            if serial_dev is not None:
                serial_dev.close()
    return RunSummary(output, host.curves_recorded, simulated, time.perf_counter() - wall, host.frames, stats, run_time,
                      compiled, flushed)


def serve_scene(scene_path: str | Path, *, mode: str | None = None, port: int | None = None,
                cycles: int | None = None, wait: float = 300.0, release_timeout: float = 300.0,
                announce: Callable[[dict[str, Any]], None] | None = None, progress: bool = False,
                fidelity: int | None = None) -> Machine:
    """Run the simulated machine as its own process: CAN served over socketcand on 127.0.0.1, serial on a pty.

    ``announce`` receives the endpoints (default: print them as one JSON line,
    docs/schemas/serve-endpoints.schema.json). Until a host arms the device (first CAN command) the
    device sends its status frames every heartbeat period of wall time; the run starts then, from device
    time 0, and ends when the host releases it (CAN ``Release`` command, sent when it has read
    everything); the links stay up until then, or ``release_timeout`` s after the scene's last cycle, which
    is reported as an error. The machine waits for a host that does not read (:class:`_HostRoom`), saying so after
    :data:`SLOW_HOST` s and stopping with an error after ``release_timeout`` s. A run stopped early (an error, its
    hosts gone, Ctrl-C, SIGTERM) ends with the unit's last status naming the cause (``TxStatus.StopCause``), and the
    connections get up to :data:`SERVE_DRAIN` s to take what was sent before the links close (listeners at a normal
    end too). Frames are stamped in Unix time (:mod:`rig.runner.served`).
    """
    cfg = _config(scene_path, cycles, mode, fidelity, classic_can="rig serve serves its bus")
    channel = f"rig-{uuid.uuid4().hex}"
    with can.Bus(interface="blockbus", channel=channel) as bus:
        wire = Anchored(bus)
        machine = Machine(cfg, wire)
        lock = threading.Lock()
        room = _HostRoom(bus, channel, machine, release_timeout)
        server = SocketcandServer(channel=cfg.can["channel"], host=cfg.can["host"],
                                  port=cfg.can["port"] if port is None else port, bus_factory=room.client_bus)
        serial_dev = (SerialDevice(machine.device, cfg.serial["port"], cfg.serial["baudrate"], cfg.serial["address"],
                                   lock=lock) if cfg.serial["enabled"] else None)
        try:
            server.start()
            if serial_dev is not None:
                serial_dev.start()
            (announce or (lambda e: print(json.dumps(e), flush=True)))(_endpoints(cfg, server, serial_dev))
            idle = IdleStatus(machine.node, can.Bus(interface="blockbus", channel=channel), lock)
            machine.node.before_run = idle.acknowledge
            try:
                _wait_for_go(machine, wait, idle.advance, lock)
                idle.advance()                          # the last idle answers leave before the run's first frame
            finally:
                idle.close()
            if machine.node.before_run is not None:     # released before it started
                log.warning("the host released the device before starting a run: no run served")
                return machine
            wire.origin = math.ceil(time.time())

            with _progress(cfg, progress) as bar:
                try:
                    _drive(cfg, machine, lock, bar, lambda: None, room.host_left, room)
                except OutOfTime as exc:    # e.g. a host driving a program started by command: the run ends as
                    log.warning("%s; the served run ends here: RunEnded sent (StopCause OutOfTime), the links stay "
                                "up until the host releases the device", exc)       # usual (its queue sent)
                except BaseException as exc:    # an error, Ctrl-C, SIGTERM: said now, not after the wait; the unit's
                    log.warning("the served run stops at %.3f s of device time after %d curves (%s): %s; its hosts "
                                "have up to %g s to take what it sent", machine.t, machine.curves,
                                stopped(exc) if isinstance(exc, KeyboardInterrupt) else exc, _last_status(machine),
                                SERVE_DRAIN)
                    _drain(server)          # last status and what it sent reach the hosts before the links close
                    raise                   # (as `rig run` records what is on the wire)
            if machine.node.released and not _machine_done(cfg, machine):
                log.warning("the host released the device after %d curves (%.3f s of device time), before the end "
                            "of the scene's run (%s): the run was cut short there", machine.curves, machine.t,
                            f"{cfg.cycles} cycles" if cfg.cycles is not None else f"{cfg.duration:g} s")
            try:
                _wait_for_release(machine, lock, release_timeout, room.host_left)
            except KeyboardInterrupt as exc:    # the run has ended (RunEnded sent): its hosts take what was sent
                log.warning("the served machine is %s after its run (%d curves served), before its host released "
                            "it: its hosts have up to %g s to take what it sent; its statistics can no longer be "
                            "read over serial", stopped(exc), machine.curves, SERVE_DRAIN)
                _drain(server)
                raise
            except RunError:                    # no Release (its host left, or the timeout): listeners still get
                _drain(server, _listening)      # the run to its last frame
                raise
            try:                                # a listener still reading gets the run to its last frame (its host,
                _drain(server, _listening)      # done with Release, reads no more)
            except KeyboardInterrupt as exc:    # the run is complete and released: only the listeners' wait is cut
                log.warning("%s while the listeners took the run's last frames: they may lack them", stopped(exc))
        finally:
            undelivered = room.undelivered()    # what connections had not taken when the links close
            if room.dropped or undelivered:
                log.warning("%d frames were not delivered to listening connections that did not read them (%d "
                            "dropped while the machine ran, %d left when rig serve closed)", room.dropped + undelivered,
                            room.dropped, undelivered)
            server.stop()
            if serial_dev is not None:
                serial_dev.close()
    return machine


def _listening(bus: Any) -> bool:
    """Whether a served connection's bus is a listener's — it does not hold the machine back —, not a host's (a host
    has sent a frame, the one that started the run, and reads)."""
    return not (bus.sent and bus.reading)


class _HostRoom:
    """A served machine's back-pressure: the connections' buses (:meth:`client_bus`, the server's bus factory), and,
    on ``channel``, called with a timeout, whether its hosts (connections that sent a frame and read; not a listener)
    have room for its next step — fewer than :data:`SERVE_BACKLOG` frames not taken —, or a command waits on the
    machine's ``bus`` (a Release is taken at once). Waiting on, it says so after :data:`SLOW_HOST` s and raises
    :class:`RunError` after ``limit`` s. A listener (:func:`_listening`) that does not read (a logger that stopped)
    keeps fewer than :data:`LISTENER_BACKLOG` frames plus one received block: its oldest are dropped beyond, counted
    in :attr:`dropped` and said once per connection, as a CAN interface's receive queue overflows."""

    def __init__(self, bus: Any, channel: str, machine: Machine, limit: float) -> None:
        self.bus, self.channel, self.machine, self.limit = bus, channel, machine, limit
        self.clients: list[Any] = []
        self.dropped = 0                    # frames dropped for listeners that did not read
        self._lock = threading.Lock()       # the server's threads add clients while the machine's looks at them
        self._since: float | None = None    # wall time (monotonic) the machine began to wait
        self._said = False

    def client_bus(self) -> can.BusABC:
        client = can.Bus(interface="blockbus", channel=self.channel)
        with self._lock:
            self.clients.append(client)
        return client

    def listeners(self) -> list[Any]:
        """The open connections that do not hold the machine back (:func:`_listening`)."""
        with self._lock:
            return [c for c in self.clients if not c.closed and _listening(c)]

    def host_left(self) -> bool:
        """Whether the run's hosts (connections that sent a frame; the one that started it) have all closed: a
        listener left behind does not keep the run going."""
        with self._lock:
            senders = [c for c in self.clients if c.sent]
            return bool(senders) and all(c.closed for c in senders)

    def undelivered(self) -> int:
        """Frames the open listeners have not taken (a host stops reading once it has sent Release, before the unit's
        ack: not counted)."""
        return sum(c.pending for c in self.listeners())

    def __call__(self, timeout: float) -> bool:
        with self._lock:
            self.clients = [c for c in self.clients if not c.closed or c.sent]   # (hosts kept: host_left)
            hosts = [c for c in self.clients if not _listening(c)]
        for c in self.listeners():
            gone = c.overflow(LISTENER_BACKLOG)
            if gone and c.dropped == gone:
                log.warning("a connection that only listens does not read: its oldest frames beyond %d are dropped "
                            "(as a CAN interface's receive queue overflows; its logger sees Seq gaps); the run goes on",
                            LISTENER_BACKLOG)
            self.dropped += gone
        if self.bus.pending > 0 or all(c.wait_pending_below(SERVE_BACKLOG, timeout) for c in hosts):
            self._since, self._said = None, False
            return True
        now = time.monotonic()
        self._since = now if self._since is None else self._since
        if now - self._since > self.limit:
            raise HostStalled(f"the host has not read for {self.limit:g} s ({SERVE_BACKLOG} frames wait for it: "
                              f"stalled or suspended): the served run stops at {self.machine.t:.3f} s of device time")
        if now - self._since > min(SLOW_HOST, self.limit / 2) and not self._said:
            self._said = True
            log.warning("waiting for the host to read: %d frames it has not taken (the machine computes on as it "
                        "reads; it stops after --release-timeout %g s without)", SERVE_BACKLOG, self.limit)
        return False


def _endpoints(cfg: RunConfig, server: SocketcandServer, serial_dev: SerialDevice | None) -> dict[str, Any]:
    """What a host needs to connect (docs/schemas/serve-endpoints.schema.json)."""
    link = None if serial_dev is None else {"port": serial_dev.port, "baudrate": serial_dev.baudrate,
                                            "bytesize": 8, "parity": "N", "stopbits": 1,
                                            "address": serial_dev.address}
    return {"can": {"interface": "socketcand", "host": server.host, "port": server.port, "channel": cfg.can["channel"]},
            "serial": None if serial_dev is None else serial_dev.port, "serial_link": link,
            "scene": str(cfg.scene.path.resolve()), "scene_sha256": scene_digest(cfg.scene.path),
            "fidelity": cfg.fidelity.level}


def scene_digest(path: str | Path) -> str:
    """SHA-256 (hex) of a scene file's bytes: which scene a served machine runs."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _drain(server: SocketcandServer, which: Callable[[can.BusABC], bool] = lambda bus: True) -> None:
    """Let the connections (those ``which`` selects by their bus) take what the machine sent, up to
    :data:`SERVE_DRAIN` s (a warning if they do not)."""
    if not server.drain(SERVE_DRAIN, which):
        log.warning("not every frame sent reached the connections within %g s (a connection that does not read)",
                    SERVE_DRAIN)


def _wait_for_release(machine: Machine, lock: threading.Lock, timeout: float,
                      host_gone: Callable[[], bool] = lambda: False) -> None:
    """Keep the links up until the host sends Release (it has read the statistics and every frame); a host
    that disconnects instead, or no Release within ``timeout`` s, is a :class:`RunError`."""
    deadline = time.monotonic() + timeout
    while True:
        gone = host_gone()                    # before reading: a Release sent just before leaving counts
        with lock:
            machine.node.handle_commands()
        if machine.node.released:
            return
        if gone:
            raise _host_left(machine, "after the run")
        if time.monotonic() > deadline:
            raise RunError(f"the host did not release the device within {timeout:g} s after the run "
                           f"({machine.curves} curves served); stopping")
        time.sleep(0.02)


def record_scene(scene_path: str | Path, output: str | Path, *, can_host: str = "127.0.0.1", can_port: int,
                 serial_port: str | None, can_channel: str | None = None, cycles: int | None = None,
                 idle_timeout: float = 10.0, connect_timeout: float = 2.0, progress: bool = False,
                 fidelity: int | None = None) -> RunSummary:
    """The host alone: connect to a served machine (socketcand + serial port) and record the scene's run
    (or its first ``cycles`` curves). A server that does not answer within ``connect_timeout`` s is a
    :class:`RunError` naming it."""
    watch()
    cfg = _config(scene_path, cycles, None, fidelity, classic_can="rig record receives its bus")
    output = Path(output)
    wall = time.perf_counter()
    with RunClock(_socketcand(can_host, can_port, can_channel or cfg.can["channel"], connect_timeout)) as bus:
        with _recorder(cfg, output, "cross-process") as rec, _progress(cfg, progress) as bar:
            host = Host(cfg, bus, serial_port, rec)
            host.stops_listening = True         # a longer served run: the recording ends at a frame-defined time
            with _serial_link(serial_port, "setting the unit up"):
                host.arm()
            go, compiled = time.perf_counter(), compile_seconds()
            try:
                with deferred_interrupt() as check:
                    _receive(cfg, host, bar, check, idle_timeout, f"{can_host}:{can_port}", output)
            except (KeyboardInterrupt, Exception) as exc:   # a RunError, a model that cannot go on, a fault
                _keep_received(host, drain=False, why=_stop_of_run(exc) if isinstance(exc, KeyboardInterrupt)
                               else "the recording's stop on an error")
                try:                               # the served machine need not wait for its release timeout
                    host.release()
                except (can.CanError, OSError):
                    pass
                except Exception as exc:  # noqa: BLE001 - recording the frame failed: the stop goes on, said once
                    log.warning("could not record the Release sent at the stop (%s: %s)", type(exc).__name__, exc)
                raise
            _show(bar, cfg, host.curves_recorded, host.truth_t, force=True)
            run_time = time.perf_counter() - go   # simulated: the device time the last frames carried (as in-process;
            # a served run longer than asked for: the span recorded, its 2 s wait for the run end included)
            simulated = max(host.truth_t, host.can.device_time)
            compiled = compile_seconds() - compiled
            _finishing(bar, cfg, simulated)       # the time the summary says (finish() trims the theory to the
            with deferred_interrupt(), _serial_link(serial_port, "reading the statistics back"):    # recorded span)
                stats = host.finish()
            _finished(bar, cfg, simulated, host.curves_recorded)
    return RunSummary(output, host.curves_recorded, simulated, time.perf_counter() - wall, host.frames, stats,
                      run_time, compiled)


@contextmanager
def _serial_link(port: str | None, doing: str) -> Iterator[None]:
    """A served machine's serial port that fails while ``doing`` (pyserial's "device reports readiness to read but
    returned no data"): a :class:`RunError` saying which link and the likely cause."""
    import serial
    try:
        yield
    except serial.SerialException as exc:
        raise RunError(f"the served machine's serial link {port} failed while {doing} ({exc}): its rig serve "
                       f"stopped or the port was taken by another program") from None


def _receive(cfg: RunConfig, host: Host, bar: tqdm, check: Callable[[], None], idle_timeout: float, where: str,
             output: Path) -> None:
    """:func:`record_scene`'s reception loop, until the host has everything (or the served run ended short);
    ``check()`` for Ctrl-C between polls. No CAN traffic for ``idle_timeout`` s is a :class:`RunError`."""
    last = time.monotonic()
    while not host.done() or not host.run_over():
        check()
        if host.poll(0.05):
            last = time.monotonic()
        elif host.can.stopped_early:
            raise RunError(f"the served machine at {where} stopped its run ({host.can.stop_reason}) after "
                           f"{host.curves_recorded} curves recorded (kept in {output}, its run_stopped event)")
        elif host.can.run_ended:       # the served run is shorter than this scene's: keep what it sent
            host.poll(0.05)
            lost = host.curves_incomplete
            served = host.curves_recorded + lost
            short = cfg.cycles is None or served < cfg.cycles
            log.warning("the served machine ended its run after %d curves%s; this host was to record %s: recorded "
                        "what it sent%s", served, " (its --cycles)" if short else "",
                        f"{cfg.cycles} complete curves" if cfg.cycles is not None else f"{cfg.duration:g} s",
                        f", {lost} of its curves incomplete (their frames did not all arrive: the incomplete_curve "
                        "events)" if lost else "")
            if short:
                host.add_event(host.can.device_time, "run_short", curves=served,
                               expected=cfg.cycles if cfg.cycles is not None else cfg.duration)
            break
        elif time.monotonic() - last > QUIET and getattr(host.can.bus, "closed", False):
            if not host.done():
                raise RunError(f"the served machine at {where} closed the connection (its rig serve stopped: see its "
                               f"console) after {host.curves_recorded} curves recorded (kept in {output})")
            host.unit_gone = f"the served machine at {where} closed the connection after this host's curves"
            log.warning("%s; its run had not ended: the unit's statistics are not read", host.unit_gone)
            break
        elif time.monotonic() - last > idle_timeout:
            raise RunError(f"no CAN traffic from {where} for {idle_timeout:g} s; "
                           f"recorded {host.curves_recorded} curves (kept in {output})")
        _show(bar, cfg, host.curves_recorded, host.truth_t)


#: the host's CAN interface to a served machine: python-can's stock socketcand client, receiving in blocks
#: (drivers.can.socketcand, registered with python-can under this name)
SOCKETCAND = "socketcand_blocks"


def _socketcand(host: str, port: int, channel: str, timeout: float) -> can.BusABC:
    """python-can's socketcand client (receiving in blocks: :data:`SOCKETCAND`), once a server at host:port has greeted (``< hi >``) within
    ``timeout`` s; else a one-line :class:`RunError`. (python-can alone retries a refused connection for
    10 s, logging every attempt, and waits forever for the greeting of a server that says nothing.)"""
    where = f"cannot connect to socketcand at {host}:{port}"
    deadline = time.monotonic() + timeout
    while True:
        try:
            with socket.create_connection((host, port), timeout=max(0.1, deadline - time.monotonic())) as probe:
                greeting = probe.recv(64)
            break
        except ConnectionRefusedError:
            if time.monotonic() > deadline:
                raise RunError(f"{where}: connection refused (is `rig serve` running? it prints its port)") from None
            time.sleep(0.1)
        except (TimeoutError, socket.timeout):
            raise RunError(f"{where}: no answer within {timeout:g} s") from None
        except OSError as exc:
            raise RunError(f"{where}: {exc.strerror or exc}") from None
    if not greeting.startswith(b"< hi >"):
        raise RunError(f"{where}: not a socketcand server (it said {greeting[:32]!r} instead of '< hi >')")
    quiet_libraries()
    try:
        return can.Bus(interface=SOCKETCAND, host=host, port=port, channel=channel)
    except (OSError, can.CanError) as exc:
        raise RunError(f"{where}: {exc}") from None

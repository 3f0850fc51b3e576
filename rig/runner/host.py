"""The host: drivers on the links, the theory model, and the recorder.

It sees the machine only through the CAN bus and the serial port, exactly as it would see real
hardware. The "theoretical curve" comes from its own plant model built from the same scene.
"""
from __future__ import annotations

import json
import logging
import math
from typing import Any

import can
import numpy as np

from drivers.can import CanHost
from drivers.can.drain import drain_block
from drivers.digiforce_serial import DigiForceClient
from drivers.encoder import SpeedEstimator, counts_to_angle
from firmware_sim.digiforce.description import load_description
from firmware_sim.digiforce.program import default_program, merge, validate_program
from firmware_sim.transducers.description import read_description, resolve_path
from rig.analysis.units import display_units
from rig.blockbus import RX, FrameBlock
from rig.dbc import at_field_limit
from rig.recorder import Recorder
from rig.recorder.schemas import snake, stand_topic
from rig.runner.config import RunConfig
from rig.runner.plants import make_plant
from rig.runner.reasons import ResultExplainer


log = logging.getLogger(__name__)


def encoder_resolution(spec: Any) -> float:
    """Angle per latched count (rad) of the encoder a scene declares: the host is configured with the
    encoder's data (PPR, decoding) as it would be for real hardware."""
    table = read_description(resolve_path(spec.description))
    ppr = float(spec.overrides.get("ppr", table["ppr"]))
    return counts_to_angle(1, int(ppr), int(float(spec.overrides.get("multiplier", table.get("multiplier", 4)))))


PLANT, LINK, HOST = range(3)   # sources of events, their order at equal times (Host._write_events)
THEORY_BLOCK = 0.5        # s of theory computed per plant call (on a fixed grid: the same calls in every run)
SLOW_SETUP = 5.0          # s of serial set-up beyond which the host says how long it takes
WINDOW = 0.5              # s of device time at most in one piece of a drained batch (< RUN_END_WAIT: see Host.poll)
RUN_END_WAIT = 2.0        # s of device time a host that has all its curves waits for the machine's run to end


class Host:
    """Receives, decodes and records everything the machine sends; configures it over serial.

    It holds only what is still to be recorded: curves until their result has arrived and the theory
    covers them, theory blocks until no curve waiting needs them (bounded memory on any run length).
    """

    def __init__(self, cfg: RunConfig, bus: can.BusABC, serial_port: str | None, recorder: Recorder) -> None:
        self.cfg = cfg
        self.bus = bus
        self.can = CanHost(bus)
        self.rec = recorder
        self.unit_gone = ""                   # why the unit can no longer be reached (a served machine that stopped)
        self.serial = (DigiForceClient(serial_port, baudrate=cfg.serial["baudrate"], address=cfg.serial["address"],
                                       timeout=2.0) if serial_port else None)
        self.theory = make_plant(cfg.plant, cfg.scene, nominal=True, fidelity=cfg.fidelity)
        self.program = cfg.device["program"]
        self.program_config: dict[str, Any] | None = None
        self._explain: ResultExplainer | None = None     # why a curve is NOK (rig.runner.reasons)
        self.truth_t = 0.0                    # s: how far the theory is computed (at the end: how far it is recorded)
        self._held: tuple[np.ndarray, dict[str, np.ndarray]] | None = None   # the latest block, not yet written
        self._frame_t = 0.0                   # s: device time of the latest frame received
        self._curve_end = 0.0                 # s: end of the latest curve recorded
        self._truth: list[dict[str, np.ndarray]] = []   # theory blocks the curves still to come may need
        # the unit measures curves only with both of its channels wired (a stand scene has none): else no block is kept
        self._curves_come = cfg.measures_curves
        self._block_n = max(2, round(THEORY_BLOCK * cfg.sample_rate))
        self._blocks = 0
        self._curves: list[Any] = []                    # complete curves waiting for their result or theory
        self._results: dict[int, Any] = {}              # released results by curve number (mod 65536)
        self._curves_done = 0
        self._beyond = 0                                # curves received after the requested ones (not recorded)
        self._plant_events = 0
        self._last_start: tuple[int, float] | None = None   # (number, theory cam angle phi) of the last curve's start
        self._illegal: dict[str, int] = {}              # counter message -> its card's illegal transitions (> 0)
        self._at_limit: dict[str, int] = {}             # "Message.Signal" -> readings at the CAN field's limit
        self._pending: list[tuple[float, int, int, str, dict[str, Any]]] = []   # events not yet written (add_event)
        self._found = 0                                 # events found so far (their order within a source)
        self._seen_start = 0.0                          # start (s) of the last curve received (curves come in order)
        self._closed = False                            # the reception was closed (_close_reception)
        recorder.held.append(self._write_events)       # a run that stops on any error still writes what was found
        self.stops_listening = False                # served: stop RUN_END_WAIT after it has all (record_scene)
        self._cut_at: float | None = None           # device time (s) past which such a host records no frame
        self._past_cut = False                      # a frame past it has arrived
        self._orphans: set[int] = set()             # numbers of incomplete curves whose result is to be recorded
        self.curves_incomplete = 0                  # curves whose frames did not all arrive (samples not recorded)
        self.frames = 0
        frames = cfg.frames()                                   # the reading messages the scene wires
        self._rad_per_count = {m: encoder_resolution(specs[0]) for m, specs in frames.items()
                               if specs[0].frame_signal is None}
        self._speed = {m: SpeedEstimator(r) for m, r in self._rad_per_count.items()}   # one per counter, across chunks
        self._readings = {m: [s.frame_signal for s in specs] for m, specs in frames.items()
                          if m not in self._rad_per_count}

    # ---------------------------------------------------------------- configuration
    def arm(self) -> None:
        """Configure the unit over serial (program from the scene), then select it over CAN: the go signal."""
        if self.serial is not None:
            written, read_back = json.dumps(self.cfg.device["config"]), json.dumps(self._scene_program())
            setup = (len(written) + len(read_back)) * 10 / self.cfg.serial["baudrate"]
            if setup > SLOW_SETUP:
                log.warning("configuring the unit over serial at %d baud: the program alone takes about %.0f s on "
                            "the line (written and read back); the run starts after it", self.cfg.serial["baudrate"],
                            setup)
            ident = self.serial.identify()
            self.serial.set_program(self.program, self.cfg.device["config"])
            self.serial.select_program(self.program)
            self.program_config = self.serial.get_program(self.program)
            self.rec.write_program(self.program, self.program_config)
            self.rec.write_event(0.0, "device_identified", identity=ident, link="serial")
        self.can.select_program(self.program)

    # ---------------------------------------------------------------- reception
    def poll(self, timeout: float = 0.0) -> int:
        """Receive what is on the bus, record raw and decoded data; returns the number of frames. The batch is taken
        in pieces of at most :data:`WINDOW` s of device time; a host that :attr:`stops_listening` records no frame past
        its cut (:meth:`run_over`): the piece in which it got all it needs ends before the cut, so where the recording
        ends follows from the frames, not from how the bus delivered them."""
        block = drain_block(self.bus, timeout)
        taken = 0
        for part in _pieces(block, WINDOW):
            if self.stops_listening and (cut := self._cut()) is not None:
                past = int(np.searchsorted(np.maximum.accumulate(part.timestamp), cut, side="right"))
                if past < len(part):              # nothing from the first frame past the cut on
                    self._past_cut = True
                    part = part.take(slice(0, past))
            self.can.receive_block(part)
            self._record(part)
            taken += len(part)
            if self._past_cut:
                break
        return taken

    def _record_sent(self) -> None:
        """The commands this host sent (``tx`` in ``/can/raw``), before the frames received after them."""
        self.rec.write_can_frames(self.can.take_sent(), channel=self.cfg.can["channel"])

    def _record(self, block: FrameBlock) -> None:
        self._record_sent()
        if len(block):
            self.rec.write_can_frames(FrameBlock(block.timestamp, block.arbitration_id, block.dlc, block.data,
                                                 block.flags | RX), channel=self.cfg.can["channel"])
            self.frames += len(block)
            self._frame_t = max(self._frame_t, float(block.timestamp[-1]))
        t_live, x_live, y_live = self.can.take_live()
        if len(t_live):
            self.rec.write_live(t_live, x_live, y_live)
        self._record_stand()
        self._collect()
        if self.cfg.cycles is None:
            self._advance_theory(min(self.can.device_time, self.cfg.duration))
        self._record_curves()
        self._record_link_events()
        self._write_events(self._settled())

    def _write_held(self, end: float = math.inf) -> None:
        """Write the held theory block, its samples up to ``end`` (s)."""
        if self._held is None:
            return
        t, signals = self._held
        self._held = None
        keep = t <= end + 0.5 * self.cfg.dt
        if keep.any():
            self.rec.write_truth(t[keep], {name: v[keep] for name, v in signals.items()})

    def _machine_end(self, complete: bool) -> float:
        """Where the machine stopped advancing its plant (s), from what every host sees alike: a run of a duration at
        its duration; a complete run of cycles at the end of the unit's transmit cycle in which its last curve ended
        (the machine stops after that cycle; the bus then only drains — in process or across processes, the same
        time);
        a run stopped early at the latest device time its frames carried."""
        heard = max(self.can.device_time, self._frame_t)
        if self.cfg.cycles is None:
            return min(heard, self.cfg.duration)
        if complete and self._curve_end > 0.0:
            n, rate = self.cfg.period_samples, self.cfg.sample_rate
            return math.ceil(round(self._curve_end * rate) / n) * n / rate
        return heard

    def _end_theory(self, end: float, complete: bool) -> None:
        """The reception ended with the machine at ``end`` (s): the theory recorded up to there (computed on to it,
        the held block cut at it) and the plant events after it dropped — the machine never ran there. After a stop
        the model may be what stopped the run: a failure computing it is left at what was computed."""
        try:
            self._advance_theory(end)
        except Exception as exc:  # noqa: BLE001 - the stop's own cause, raised again: the run's error says it
            if complete:
                raise
            log.debug("the theory stops at %.6g s: %s", self.truth_t, exc)
        self._write_held(end)
        self._pending = [e for e in self._pending if not (e[1] == PLANT and e[0] > end + 0.5 * self.cfg.dt)]
        self.truth_t = min(self.truth_t, end)

    def _settled(self) -> float:
        """Device time (s) up to which every event is found: the frames and the theory have passed it, and, where
        curves come, no curve still to be recorded began before it (the host's events of a curve — a result missing,
        values clipped, two curves in one cycle — are found when the curve is recorded, at its times): the first
        curve waiting for its result, else the last curve received (the next one, in transfer or queued on the unit,
        began after it)."""
        upto = min(self.can.device_time, self.truth_t)
        if self._curves_come:
            upto = min(upto, float(self._curves[0].t[0]) if self._curves else self._seen_start)
        return upto

    def _record_stand(self) -> None:
        """The reading messages the scene wires, as bulk blocks on ``/stand/<message>`` (:func:`stand_topic`):
        a counter's count, edge time, angle and speed (drivers.encoder.SpeedEstimator from the latched edge
        times, never from the reading times, which the bus delays); any other message the signals the scene's
        transducers fill (fields in snake case: BrakeForce → brake_force), in the DBC's units."""
        new = self.can.take_readings()
        by_message: dict[str, list] = {}
        for row in new["counters"]:           # one pass: the rows of each counter message, in order
            by_message.setdefault(row[0], []).append(row)
        for message, rad_per_count in self._rad_per_count.items():
            rows = by_message.get(message)
            if rows:
                t, count, edge, illegal = (np.array(c, dtype=float) for c in list(zip(*rows))[1:])
                speed = self._speed[message].update(t, count.astype(np.int64), edge)
                self.rec.write_block(stand_topic(message), t, {
                    "count": count, "edge_time": edge, "angle": count * rad_per_count, "speed": speed.speed,
                    "speed_time": speed.time, "speed_method": speed.method.astype(float), "illegal": illegal})
                self._illegal_transitions(message, t, illegal)
        for message, signals in self._readings.items():
            if message in new["readings"]:
                t, values = new["readings"][message]
                self.rec.write_block(stand_topic(message), t, {snake(name): values[name] for name in signals})
                for name in signals:
                    self._readings_at_limit(message, name, t, values[name])

    def _illegal_transitions(self, message: str, t: np.ndarray, illegal: np.ndarray) -> None:
        """The first reading of ``message`` whose counter card counted illegal transitions (glitches, edges faster
        than the card follows) is an ``encoder_illegal`` event: from there its count may be off the shaft."""
        if not illegal.size or illegal[-1] <= 0:
            return
        said = message in self._illegal
        self._illegal[message] = int(illegal[-1])
        if said:
            return
        k = int(np.argmax(illegal > 0))
        self.add_event(float(t[k]), "encoder_illegal", LINK, message=message, transitions=int(illegal[k]),
                       detail="the counter card saw illegal transitions (both channels changed at once: a glitch, "
                              "or edges faster than it follows) and kept its count: from here the count may be off "
                              "the shaft (the run's total in link_summary)")

    def _readings_at_limit(self, message: str, signal: str, t: np.ndarray, values: np.ndarray) -> None:
        """Count the readings of a signed ``message.signal`` that sit at its CAN field's limit (the unit saturates a
        value beyond the field's range to it: the reading is the limit, not the quantity); the first is a
        ``reading_at_limit`` event, the run's totals go into ``link_summary.readings_at_limit``."""
        spec = self.can.db.get_message_by_name(message).get_signal_by_name(signal)
        limit = at_field_limit(spec, values)
        n = int(np.count_nonzero(limit))
        if not n:
            return
        key = f"{message}.{signal}"
        said = key in self._at_limit
        self._at_limit[key] = self._at_limit.get(key, 0) + n
        if said:
            return
        k = int(np.argmax(limit))
        value = float(values[k])
        self.add_event(float(t[k]), "reading_at_limit", LINK, message=message, signal=signal, limit=value,
                       unit=spec.unit or "",
                       detail=f"{key} read {value:g} {spec.unit or ''}".rstrip() + ", the limit of its CAN field: the "
                              "quantity was beyond what the frame carries and the unit sent the limit (the run's "
                              "totals in link_summary.readings_at_limit)")

    def _illegal_saturated(self) -> list[str]:
        """The counter messages whose ``Illegal`` field reached its maximum: their card counted at least that many."""
        return sorted(m for m, n in self._illegal.items()
                      if n >= self.can.db.get_message_by_name(m).get_signal_by_name("Illegal").maximum)

    def _advance_theory(self, until: float) -> None:
        """Run the theory model on the machine's sample grid, in fixed blocks, until it covers ``until`` (s);
        record it and its events. A run of a stated duration ends its last block there (nothing past the run is
        computed or recorded); a run of cycles ends wherever the machine stops, so the latest block is held back
        until the next one is computed or the reception ends, and cut there (:meth:`_end_theory`): the recording
        holds no plant signal or event from after the run (a block of 0.5 s ran on past it)."""
        dt, n, end = self.cfg.dt, self._block_n, self.cfg.duration
        keep = self.cfg.recording["truth_signals"]
        while self.truth_t < until - 1e-12 and (end is None or self.truth_t < end - 0.5 * dt):
            first = self._blocks * n
            t = self.cfg.sample_times(first, n)
            if end is not None:
                t = t[t <= end + 0.5 * dt]
            self._blocks += 1
            self._write_held()                    # the machine is past it (a failing next block loses nothing)
            truth = self.theory.advance(t)
            signals = {k: np.asarray(v, dtype=float) for k, v in truth.items()
                       if k != "t" and np.shape(v) == t.shape and (keep is None or k in keep)}
            k = self.cfg.truth_every              # the samples first + 1, … whose index k divides
            kept = slice(-(first + 1) % k, None, k)
            self._held = (t[kept], {name: v[kept] for name, v in signals.items()})
            if self._curves_come:
                self._truth.append({"t": t, **signals})
            self.truth_t = float(t[-1])
        for ev in self.theory.events[self._plant_events:]:
            self.add_event(ev.time, ev.kind, PLANT, **ev.data)
        self._plant_events = len(self.theory.events)

    def _truth_at(self, t: np.ndarray, signal: str) -> np.ndarray | None:
        chunks = [c for c in self._truth if c["t"][-1] >= t[0] and c["t"][0] <= t[-1] and signal in c]
        if not chunks:
            return None
        return np.interp(t, np.concatenate([c["t"] for c in chunks]), np.concatenate([c[signal] for c in chunks]))

    def _collect(self) -> None:
        """Take the finished curves and released results from the driver: complete curves wait for their
        result; an incomplete curve becomes an event (its result is still recorded)."""
        for curve in self.can.take_curves():
            if curve.t is not None and len(curve.t):
                self._seen_start = float(curve.t[0])
            if not self._wanted(len(self._curves)):
                self._beyond += 1              # a served run longer than this host's --cycles: not recorded
            elif curve.complete and curve.t is not None:
                self._curves.append(curve)
            else:
                self.add_event(max(self.can.device_time, 0.0), "incomplete_curve", number=curve.number,
                               problems=list(curve.problems))
                self._orphans.add(curve.number)
                self.curves_incomplete += 1
        for res in self.can.take_results():
            self._results[res.number] = res

    def _wanted(self, waiting: int = 0) -> bool:
        """Whether a curve after the recorded ones and ``waiting`` more is one this host is to record."""
        return self.cfg.cycles is None or self._curves_done + waiting < self.cfg.cycles

    def _record_curves(self, why_no_result: str | None = None) -> None:
        """Record, in order, every curve whose result has arrived; the theory is run on demand to cover it. With
        ``why_no_result`` (the run is over) the curves still waiting are recorded without it, each with a
        ``result_missing`` event saying why."""
        while self._curves:
            curve = self._curves[0]
            result = self._results.pop(curve.number, None)
            if result is None:
                if why_no_result is None and not any(n > curve.number for n in self._results):
                    break              # its result is still on the way
                self.add_event(float(curve.t[-1]), "result_missing", number=curve.number,
                               detail=why_no_result or "a later curve's result arrived first: this curve's "
                                                       "Result frame was lost")
            self._advance_theory(float(curve.t[-1]))
            self._curve_end = max(self._curve_end, float(curve.t[-1]))
            theory = {}
            for role in ("x", "y"):
                spec = self.cfg.wired(f"device.{role}")
                values = None if spec is None else self._truth_at(curve.t, spec.signal)
                if values is not None:
                    theory[role] = values
            angle = self._truth_at(curve.t, "cam_angle")
            if angle is not None:
                theory["angle"] = angle
            self._one_per_cycle(curve)
            self.rec.write_curve(curve.number, curve.program, curve.t, curve.x, curve.y, theory=theory or None,
                                 angle=angle, complete=curve.complete, problems=list(curve.problems))
            if curve.clipped:
                self.add_event(float(curve.t[-1]), "curve_clipped", number=curve.number, pairs=int(curve.clipped),
                               detail="values saturated to the CAN frame's range (or, sampled non-uniformly, times "
                                      "past its 10.49 s): the unit's CurveEnd.Clipped (at most 255)")
            if result is not None:
                self.rec.write_result(self._result_dict(result, curve.program, curve), t=float(curve.t[-1]))
            self._curves.pop(0)
            self._curves_done += 1
            if self._curves_done == self.cfg.cycles:    # all it needs: the cut follows from this curve's frames
                came = result.received if result is not None else max(  # (its result lost: the later one that
                    (r.received for r in self._results.values()), default=0.0)   # showed it)
                self._cut_at = max(float(curve.t[-1]), came) + RUN_END_WAIT
            self._truth = [c for c in self._truth if c["t"][-1] >= curve.t[-1]]     # later curves start later
        for number in sorted(self._orphans & set(self._results)):
            self.rec.write_result(self._result_dict(self._results.pop(number), self.program), t=self.truth_t)
            self._orphans.discard(number)

    def _one_per_cycle(self, curve: Any) -> None:
        """A curve that starts less than half a cam revolution after the one before (the theory's cam angle ``phi``,
        when the scene keeps it) is a ``curves_in_one_cycle`` event: the unit's start/stop trigger fired twice in one
        machine cycle (a dropout of the X input, or a trigger chattering on noise at a crawl), so the run's curves
        are no longer its machine cycles."""
        phi = self._truth_at(curve.t[:1], "phi")
        if phi is None:
            return
        if self._last_start is not None and phi[0] - self._last_start[1] < math.pi:
            self.add_event(float(curve.t[0]), "curves_in_one_cycle", numbers=[self._last_start[0], curve.number],
                           cam_angle=float(phi[0] - self._last_start[1]),
                           detail="this curve began less than half a cam revolution after the one before: the "
                                  "unit's start/stop trigger fired twice in one machine cycle")
        self._last_start = (curve.number, float(phi[0]))

    def _result_dict(self, result: Any, program: int, curve: Any | None = None) -> dict[str, Any]:
        """The ``/device/result`` message: the device's verdict (FailMask per element) with each failed
        element's reason from re-evaluating the received ``curve`` (None: it did not arrive complete) on the
        host (rig.runner.reasons); a disagreement with the device is a ``verdict_mismatch`` event."""
        out, mismatch = self._explainer().explain(result, curve)
        if mismatch is not None:
            when = float(curve.t[-1]) if curve is not None else self.truth_t
            self.add_event(when, "verdict_mismatch", **mismatch)
        msg = {"number": result.number, "program": program, "ok": bool(result.ok), "elements": out,
               "process_values": dict(result.process_values), "complete": bool(result.complete)}
        if result.missing:
            msg["missing"] = list(result.missing)
        if result.memory_full or result.decimated:
            msg["memory_full"], msg["decimated"] = bool(result.memory_full), bool(result.decimated)
        return msg

    def _scene_program(self) -> dict[str, Any]:
        """The scene's program as the unit normalises it: its [device.config] merged over the factory program."""
        desc = load_description(self.cfg.device["description"])
        return validate_program(merge(default_program(self.program, desc), self.cfg.device["config"]), desc)

    def _explainer(self) -> ResultExplainer:
        """Built once: the program read back from the unit (or, without a serial link, the scene's program
        as the unit normalises it) and the display units the scene writes it in."""
        if self._explain is None:
            program = self.program_config if self.program_config is not None else self._scene_program()
            self._explain = ResultExplainer(program, display_units(program, self.cfg.device["config"]))
        return self._explain

    def _close_reception(self, why: str, complete: bool = False) -> None:
        """Everything received so far into the recording (``why``: what ends the reception): a curve cut in
        transfer as an ``incomplete_curve`` event, curves whose result did not come without it, the last live-drop
        report, and the curves of a longer served run beyond this host's ``--cycles`` as one ``not_recorded``
        event; every event found; the theory up to the machine's end (``complete``: the run ended as asked, the
        theory is computed on to there — see :meth:`_end_theory`). Once: later calls do nothing."""
        if self._closed:
            return
        self._closed = True
        self.can.flush(why)
        self._collect()
        self._record_curves(f"the curve arrived but its Result frame did not before {why}")
        self._record_link_events()
        if self._beyond:
            self.add_event(max(self.can.device_time, 0.0), "not_recorded", curves=self._beyond,
                           detail=f"the served machine sent {self._beyond} more curve(s) after the {self.cfg.cycles} "
                                  f"this host was asked to record (--cycles); they are in /can/raw only")
            self._beyond = 0
        self._end_theory(self._machine_end(complete), complete)
        self._write_events()

    def interrupted(self, why: str = "the interruption of the run") -> None:
        """The run was interrupted (Ctrl-C, or stopped by an error: ``why``): what was received is recorded and what
        was cut is said (events)."""
        self._close_reception(why)

    def _record_link_events(self) -> None:
        for ev in self.can.take_events():
            self.add_event(max(ev.time, 0.0), ev.kind, LINK, frame_id=ev.frame_id, count=ev.count, detail=ev.detail)
        for report in self.can.take_drop_reports():
            self.add_event(report.pop("t"), "live_dropped", LINK, **report)

    def add_event(self, t: float, kind: str, source: int = HOST, /, **data: Any) -> None:
        """An event found at time ``t`` (s) by ``source`` (:data:`PLANT`, :data:`LINK`, :data:`HOST`, the default),
        written in time order by :meth:`_write_events`."""
        self._pending.append((float(t), source, self._found, kind, data))
        self._found += 1

    def _write_events(self, upto: float = math.inf) -> None:
        """Write the events found with t ≤ ``upto`` (s) in time order (at equal times: plant, link, host, each in the
        order found). The theory and the frames have both passed ``upto``, so no earlier event can be found later,
        and the order does not depend on how the frames were split into receive blocks (in one process or across
        processes: the same recording)."""
        ready = sorted(e for e in self._pending if e[0] <= upto)
        if ready:
            self._pending = [e for e in self._pending if e[0] > upto]
            for t, _, _, kind, data in ready:
                self.rec.write_event(t, kind, **data)

    # ---------------------------------------------------------------- completion
    @property
    def curves_recorded(self) -> int:
        return self._curves_done

    def done(self) -> bool:
        if self.cfg.cycles is not None:
            return self._curves_done >= self.cfg.cycles
        return self.can.device_time >= self.cfg.duration - 1e-9

    def run_over(self) -> bool:
        """Whether the machine's run is over for this host (asked once it has all it needs): its last frame
        (``RunEnded``) has arrived, or (the served scene runs longer than this host records) a frame past its cut,
        ``RUN_END_WAIT`` s of device time after the frames that completed its last curve (or after its duration).
        Decided from the frames only, so every run ends at the same frame."""
        if self.can.run_ended or self._past_cut:
            return True
        if self._cut() is None:             # (its last curve sets it: a safeguard)
            self._cut_at = self.can.device_time + RUN_END_WAIT
        return self.can.device_time > self._cut()

    def _cut(self) -> float | None:
        """Device time (s) past which a host that :attr:`stops_listening` records nothing: ``RUN_END_WAIT`` after the
        frames that completed its last curve, or after its duration; None while it is still to come."""
        if self._cut_at is None and self.cfg.cycles is None:
            return self.cfg.duration + RUN_END_WAIT
        return self._cut_at

    def finish(self) -> dict[str, Any]:
        """Release what is still waiting, read the unit's statistics over serial and record them with the
        link counters, then tell the unit the host is done (CAN Release)."""
        self._close_reception("the end of the recording", complete=True)
        stats: dict[str, Any] = {}
        # the counters are those of the latest frames: at the bus's device time (past the machine's end while the
        # backlog drained), not before an event already recorded
        end = max(self.truth_t, self.rec.last_event_time, self.can.device_time)
        if self.serial is not None and self.unit_gone:
            self.rec.write_event(end, "statistics_not_read", detail=f"the unit's statistics were not read over serial: "
                                                                    f"{self.unit_gone}")
            self.serial.close()
        elif self.serial is not None:
            stats = self.serial.read_statistics(self.program)
            self.rec.write_statistics(stats, t=end)
            over = {ch: int(n) for ch, n in self.serial.status().get("adc_overflows", {}).items() if n}
            if over:                           # the unit's inputs clipped: the curves hold its range's limit there
                self.rec.write_event(end, "input_overrange", samples=over,
                                     detail="input samples beyond the unit's measuring range, clipped to it (a "
                                            "broken bridge, a sensor beyond its range): curves measured then hold the "
                                            "limit, not the measurement")
            self.serial.close()
        self.rec.write_event(end, "link_summary", frames=self.frames, **{
            k: v for k, v in self.can.counters.items() if isinstance(v, (int, float))},
            **({"illegal_transitions": dict(self._illegal)} if self._illegal else {}),
            **({"illegal_saturated": full} if (full := self._illegal_saturated()) else {}),
            **({"readings_at_limit": dict(self._at_limit)} if self._at_limit else {}))
        if not self.unit_gone:
            self.release()
        self._record_sent()
        return stats

    def release(self) -> None:
        """Tell the unit this host is done (CAN ``Release``), recorded in ``/can/raw`` as the host's last frame
        (also when a run stops on Ctrl-C, SIGTERM or an error: the served machine need not wait for its timeout)."""
        self.can.send_command("release")
        self._record_sent()


def _pieces(block: FrameBlock, span: float) -> list[FrameBlock]:
    """``block`` cut into consecutive pieces of at most ``span`` s each by its running latest time stamp (itself when
    it spans no more; one empty piece for an empty block)."""
    t = np.maximum.accumulate(block.timestamp)      # (another host's command, stamped by its clock, among them)
    if len(block) == 0 or t[-1] - t[0] <= span:
        return [block]
    edges = np.searchsorted(t, np.arange(t[0] + span, t[-1], span), side="right")
    bounds = [0, *edges.tolist(), len(block)]
    return [block.take(slice(a, b)) for a, b in zip(bounds, bounds[1:]) if b > a]

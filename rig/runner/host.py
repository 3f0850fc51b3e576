"""The host: drivers on the links, the theory model, and the recorder.

It sees the machine only through the CAN bus and the serial port, exactly as it would see real
hardware. The "theoretical curve" comes from its own plant model built from the same scene.
"""
from __future__ import annotations

import bisect
import itertools
import tomllib
from pathlib import Path
from typing import Any

import can
import numpy as np

from drivers.can import CanHost
from drivers.can.drain import drain
from drivers.digiforce_serial import DigiForceClient
from drivers.encoder import counts_to_angle
from rig.recorder import Recorder
from rig.runner.config import RunConfig
from rig.runner.plants import make_plant


DEVICES = Path(__file__).resolve().parents[2] / "data" / "devices"


def encoder_resolution(spec: Any) -> float:
    """Angle per latched count (rad) of the encoder a scene declares: the host is configured with the
    encoder's data (PPR, decoding) as it would be for real hardware."""
    if spec is None:
        return float("nan")
    path = Path(spec.description) if spec.description.endswith(".toml") else DEVICES / f"{spec.description}.toml"
    table = tomllib.loads(path.read_text(encoding="utf-8"))["transducer"]
    ppr = float(spec.overrides.get("ppr", table["ppr"]))
    return counts_to_angle(1, int(ppr), int(float(spec.overrides.get("multiplier", table.get("multiplier", 4)))))


class Host:
    """Receives, decodes and records everything the machine sends; configures it over serial."""

    def __init__(self, cfg: RunConfig, bus: can.BusABC, serial_port: str | None, recorder: Recorder) -> None:
        self.cfg = cfg
        self.bus = bus
        self.can = CanHost(bus)
        self.rec = recorder
        self.serial = (DigiForceClient(serial_port, baudrate=cfg.serial["baudrate"], address=cfg.serial["address"],
                                       timeout=2.0) if serial_port else None)
        self.theory = make_plant(cfg.plant, cfg.scene, nominal=True)
        self.program = cfg.device["program"]
        self.program_config: dict[str, Any] | None = None
        self.truth_t = 0.0
        self._truth: list[dict[str, np.ndarray]] = []
        self._truth_ends: list[float] = []     # last time (s) of each truth chunk, increasing
        self._chunk_n = max(2, round(cfg.chunk * cfg.sample_rate))
        self._chunks = 0
        self._curves_done = 0
        self._results_done: set[int] = set()
        self._link_events = 0
        self._plant_events = 0
        self.frames = 0
        self._torque_done = self._encoders_done = self._static_done = 0
        self._rad_per_count = {i: encoder_resolution(cfg.role(f"encoder{i}")) for i in (1, 2)}

    # ---------------------------------------------------------------- configuration
    def arm(self) -> None:
        """Configure the unit over serial (program from the scene), then select it over CAN: the go signal."""
        if self.serial is not None:
            ident = self.serial.identify()
            self.serial.set_program(self.program, self.cfg.device["config"])
            self.serial.select_program(self.program)
            self.program_config = self.serial.get_program(self.program)
            self.rec.write_program(self.program, self.program_config)
            self.rec.write_event(0.0, "device_identified", identity=ident, link="serial")
        self.can.select_program(self.program)

    # ---------------------------------------------------------------- reception
    def poll(self, timeout: float = 0.0) -> int:
        """Receive what is on the bus, record raw and decoded data; returns the number of frames."""
        raw = drain(self.bus, timeout)
        self.can.receive_many(raw)
        if raw:
            self.rec.write_can_frames(raw)
            self.frames += len(raw)
        t_live, x_live, y_live = self.can.take_live()
        if len(t_live):
            self.rec.write_live(t_live, x_live, y_live)
        self._record_stand()
        self._advance_theory(self.can.device_time)
        self._record_curves()
        self._record_link_events()
        return len(raw)

    def _record_stand(self) -> None:
        """Torque-meter and encoder readings (the stand's samples M_t, T_in, T_out) and static-rig readings
        (angle, leaf strain of the roles the scene declares) as bulk blocks."""
        new, self._torque_done = self.can.torque[self._torque_done:], len(self.can.torque)
        if new:
            t, torque, brake = (np.array(c, dtype=float) for c in zip(*new))
            self.rec.write_block("/stand/torque", t, {"torque": torque, "brake_force": brake})
        for enc in (1, 2):
            rows = [r for r in self.can.encoder_log[self._encoders_done:] if r[0] == enc]
            if rows:
                _, t, count, edge = (np.array(c, dtype=float) for c in zip(*rows))
                self.rec.write_block(f"/stand/encoder{enc}", t, {"count": count, "edge_time": edge,
                                                                  "angle": count * self._rad_per_count[enc]})
        self._encoders_done = len(self.can.encoder_log)
        new, self._static_done = self.can.static[self._static_done:], len(self.can.static)
        if new:
            t, angle, strain = (np.array(c, dtype=float) for c in zip(*new))
            fields = {"angle": angle, "strain": strain}
            self.rec.write_block("/stand/static", t, {r: fields[r] for r in fields if self.cfg.role(r) is not None})

    def _advance_theory(self, t_device: float) -> None:
        """Run the theory model on the machine's sample grid up to the device time; record it."""
        dt, n = self.cfg.dt, self._chunk_n
        while (self._chunks + 1) * n * dt <= t_device + 1e-12:
            t = (self._chunks * n + 1 + np.arange(n)) * dt
            self._chunks += 1
            truth = self.theory.advance(t)
            keep = self.cfg.recording["truth_signals"]
            signals = {k: np.asarray(v, dtype=float) for k, v in truth.items()
                       if k != "t" and np.shape(v) == t.shape and (keep is None or k in keep)}
            self.rec.write_truth(t, signals)
            self._truth.append({"t": t, **signals})
            self._truth_ends.append(float(t[-1]))
            self.truth_t = float(t[-1])
        for ev in self.theory.events[self._plant_events:]:
            self.rec.write_event(ev.time, ev.kind, **ev.data)
        self._plant_events = len(self.theory.events)

    def _truth_at(self, t: np.ndarray, signal: str) -> np.ndarray | None:
        first = bisect.bisect_left(self._truth_ends, t[0])       # chunks before it end before t[0]
        chunks = [c for c in itertools.takewhile(lambda c: c["t"][0] <= t[-1], self._truth[first:]) if signal in c]
        if not chunks:
            return None
        tt = np.concatenate([c["t"] for c in chunks])
        return np.interp(t, tt, np.concatenate([c[signal] for c in chunks]))

    def _record_curves(self) -> None:
        curves = self.can.curves()
        for curve in curves[self._curves_done:]:
            result = self.can.results.get(curve.number)
            if result is None or curve.t is None or curve.t[-1] > self.truth_t:
                break        # wait for its result and for the theory to cover it
            theory, angle = {}, None
            for role, key in (("x", "x"), ("y", "y")):
                spec = self.cfg.role(role)
                if spec is not None:
                    values = self._truth_at(curve.t, spec.signal)
                    if values is not None:
                        theory[key] = values
            angle = self._truth_at(curve.t, "cam_angle")
            if angle is not None:
                theory["angle"] = angle
            self.rec.write_curve(curve.number, curve.program, curve.t, curve.x, curve.y, theory=theory or None,
                                 angle=angle, complete=curve.complete, problems=list(curve.problems))
            self.rec.write_result(self._result_dict(result, curve.program), t=float(curve.t[-1]))
            self._curves_done += 1
        for curve in self.can.incomplete_curves():
            if curve.number not in self._results_done:
                self._results_done.add(curve.number)
                self.rec.write_event(self.can.device_time, "incomplete_curve", number=curve.number,
                                     problems=list(curve.problems))

    def _result_dict(self, result: Any, program: int) -> dict[str, Any]:
        elements = (self.program_config or {}).get("elements", [])
        names = [e.get("name", f"element {i}") for i, e in enumerate(elements)]
        out = [{"name": names[i] if i < len(names) else f"element {i}",
                "kind": elements[i].get("kind", "?") if i < len(elements) else "?",
                "ok": not bool(result.fail_mask >> i & 1), "reason": ""} for i in range(max(len(names), 0))]
        return {"number": result.number, "program": program, "ok": bool(result.ok), "elements": out,
                "process_values": dict(result.process_values)}

    def _record_link_events(self) -> None:
        for ev in self.can.events[self._link_events:]:
            self.rec.write_event(max(ev.time, 0.0), ev.kind, frame_id=ev.frame_id, count=ev.count, detail=ev.detail)
        self._link_events = len(self.can.events)

    # ---------------------------------------------------------------- completion
    @property
    def curves_recorded(self) -> int:
        return self._curves_done

    def done(self) -> bool:
        if self.cfg.cycles is not None:
            return self._curves_done >= self.cfg.cycles
        return self.can.device_time >= self.cfg.duration - 1e-9

    def finish(self) -> dict[str, Any]:
        """Read the unit's statistics over serial and record them with the link counters."""
        stats: dict[str, Any] = {}
        if self.serial is not None:
            stats = self.serial.read_statistics(self.program)
            self.rec.write_statistics(stats, t=self.truth_t)
            self.serial.close()
        self.rec.write_event(self.truth_t, "link_summary", frames=self.frames, **{
            k: v for k, v in self.can.counters.items() if isinstance(v, (int, float))})
        return stats

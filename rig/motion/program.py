"""Cam programs: rise / dwell / return segments over one revolution (MODELS §1).

A program maps the cam angle φ (rad, any real value, wrapped to [0, 2π)) to the follower output
s(φ) (here: slider stroke, m) and its derivatives w.r.t. φ; time derivatives follow from the cam
speed: v = ω s', a = ω² s'' + ω̇ s'. The output starts the revolution at level 0.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from math import degrees, tau
from typing import NamedTuple, Sequence

import numpy as np

from rig.motion.laws import MotionLaw
from rig.motion.registry import UnknownLawError, get_law

KINDS = ("rise", "dwell", "return")
SUM_TOLERANCE = 1e-4    # rad: a program's angles summing this close to 360° are scaled to it


class ProgramError(ValueError):
    """A cam program is inconsistent (angles, laws, strokes); the message names the segment."""


@dataclass(frozen=True)
class Segment:
    """One program segment: ``kind`` in rise/dwell/return, ``angle`` (rad), ``law`` name, ``stroke`` (m)."""

    kind: str
    angle: float
    law: str | None = None
    stroke: float = 0.0


class ProgramEvent(NamedTuple):
    """An angle (rad, in [0, 2π)) where s'' jumps by ``jump`` (m/rad²); ``segment`` is 0-based."""

    angle: float
    jump: float
    segment: int


class Motion(NamedTuple):
    """Output and its derivatives w.r.t. cam angle: s (m), s' (m/rad), s'' (m/rad²), s''' (m/rad³)."""

    s: np.ndarray
    s_p: np.ndarray
    s_pp: np.ndarray
    s_ppp: np.ndarray


class TimeMotion(NamedTuple):
    """Output and its time derivatives: s (m), v (m/s), a (m/s²)."""

    s: np.ndarray
    v: np.ndarray
    a: np.ndarray


class CamProgram:
    """A validated list of segments summing to 360° whose rises and returns balance."""

    def __init__(self, segments: Sequence[Segment]):
        if not segments:
            raise ProgramError("a cam program needs at least one segment")
        laws: list[MotionLaw | None] = []
        for i, seg in enumerate(segments):
            where = f"cam program segment {i + 1} ({seg.kind})"
            if seg.kind not in KINDS:
                raise ProgramError(f"{where}: kind must be one of {', '.join(KINDS)}")
            if not seg.angle > 0.0:
                raise ProgramError(f"{where}: angle must be positive, got {degrees(seg.angle):g}°")
            if seg.kind == "dwell":
                if seg.law is not None or seg.stroke != 0.0:
                    raise ProgramError(f"{where}: a dwell takes neither a law nor a stroke")
                laws.append(None)
                continue
            if seg.law is None:
                raise ProgramError(f"{where}: a {seg.kind} needs a motion law")
            try:
                laws.append(get_law(seg.law))
            except UnknownLawError as exc:
                raise ProgramError(f"{where}: {exc}") from None
            if not seg.stroke > 0.0:
                raise ProgramError(f"{where}: stroke must be positive, got {seg.stroke * 1e3:g} mm")
        total = sum(seg.angle for seg in segments)
        if abs(total - tau) > SUM_TOLERANCE:
            raise ProgramError(f"cam program segments sum to {degrees(total):.9g}°, not 360° (off by "
                               f"{degrees(total - tau):+.3g}°; only a sum within {degrees(SUM_TOLERANCE):.2g}° of 360° — "
                               f"angles typed in rad or rounded — is taken as a whole turn)")
        if total != tau:                    # typed in rad (3 × 2.0944 rad) or rounded: scaled to the whole turn
            segments = [replace(seg, angle=seg.angle * tau / total) for seg in segments]
        up = sum(seg.stroke for seg in segments if seg.kind == "rise")
        down = sum(seg.stroke for seg in segments if seg.kind == "return")
        if abs(up - down) > 1e-12:
            raise ProgramError(f"cam program rises total {up * 1e3:g} mm but returns total {down * 1e3:g} mm")
        self.segments = tuple(segments)
        self._laws = laws
        self._start = np.concatenate(([0.0], np.cumsum([seg.angle for seg in segments])[:-1]))
        signs = [1.0 if seg.kind == "rise" else -1.0 if seg.kind == "return" else 0.0 for seg in segments]
        self._h = np.array(signs) * np.array([seg.stroke for seg in segments])
        self._level = np.concatenate(([0.0], np.cumsum(self._h)[:-1]))

    @property
    def starts(self) -> np.ndarray:
        """Start angle of every segment (rad)."""
        return self._start.copy()

    @property
    def start_levels(self) -> np.ndarray:
        """Output (m) at the start of every segment."""
        return self._level.copy()

    @property
    def levels(self) -> tuple[float, float]:
        """(lowest, highest) output over the revolution (m)."""
        lv = np.append(self._level, 0.0)
        return float(lv.min()), float(lv.max())

    def evaluate(self, phi: np.ndarray) -> Motion:
        """s and its derivatives w.r.t. φ at cam angles ``phi`` (rad, any real value)."""
        phi = np.asarray(phi, dtype=float)
        shape = phi.shape
        phi = phi.reshape(-1)
        if phi.size and not (phi.min() >= 0.0 and phi.max() < tau):      # np.mod costs more than the check
            phi = np.mod(phi, tau)
        seg_of = np.searchsorted(self._start, phi, side="right") - 1
        # each segment's angles as one slice: in place when φ increases (a revolution, a run's chunk), else sorted
        order = None if np.all(seg_of[1:] >= seg_of[:-1]) else np.argsort(seg_of, kind="stable")
        if order is not None:
            phi, seg_of = phi[order], seg_of[order]
        bounds = np.searchsorted(seg_of, np.arange(len(self._laws) + 1))
        out = np.zeros((4, phi.size))
        out[0] = self._level[seg_of]
        for i, law in enumerate(self._laws):
            part = slice(bounds[i], bounds[i + 1])
            if law is None or part.start == part.stop:
                continue
            big_phi = self.segments[i].angle
            y, y1, y2, y3 = law.derivatives((phi[part] - self._start[i]) / big_phi)
            h = self._h[i]  # negative for a return: s = level − |h|·y
            out[0, part] = self._level[i] + h * y
            out[1, part] = h / big_phi * y1
            out[2, part] = h / big_phi ** 2 * y2
            out[3, part] = h / big_phi ** 3 * y3
        if order is not None:
            out[:, order] = out.copy()
        return Motion(*(row.reshape(shape) for row in out))

    def at_speed(self, phi: np.ndarray, omega: np.ndarray | float, alpha: np.ndarray | float = 0.0) -> TimeMotion:
        """s, v = ω s', a = ω² s'' + ω̇ s' at cam angle φ (rad), speed ω (rad/s), acceleration ω̇ (rad/s²)."""
        m = self.evaluate(phi)
        return TimeMotion(m.s, omega * m.s_p, omega * omega * m.s_pp + alpha * m.s_p)

    def events(self) -> list[ProgramEvent]:
        """Angles where s'' jumps, from the laws' jump positions and the boundary accelerations."""
        raw = []
        for i, (seg, law) in enumerate(zip(self.segments, self._laws)):
            if law is None:
                continue
            scale = self._h[i] / seg.angle ** 2
            for x, dy2 in law.accel_jumps():
                angle = float(self._start[i] + x * seg.angle)
                raw.append((0.0 if angle > tau - 1e-9 else angle, float(scale * dy2), i))
        merged: list[list] = []
        for angle, jump, i in sorted(raw):  # a segment's end and the next one's start coincide: add the jumps
            if merged and angle - merged[-1][0] < 1e-9:
                merged[-1][1] += jump
            else:
                merged.append([angle, jump, i])
        big = max((abs(m[1]) for m in merged), default=0.0)
        return [ProgramEvent(a, j, i) for a, j, i in merged if abs(j) > 1e-9 * big]

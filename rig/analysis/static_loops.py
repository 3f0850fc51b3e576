"""Static clutch rig: loading/unloading cycles of a torque–angle record and their hysteresis-loop energy.

A *cycle* runs from one valley of the applied (lever) torque to the next, so it holds one loading and
one unloading. Its loop energy is :func:`rig.analysis.clutch_metrics.loop_energy` (∮T dφ, J) of the
path closed at the cycle's end. The theory (:func:`theory_cycle_energy`) builds the same path from the
clutch's static characteristic alone: Coulomb friction makes the relative angle a stop operator, so
the loading path is the running maximum of T_load from the start angle, the unloading path the running
minimum of T_unload from the turning angle (both between the torque extremes). SI units throughout.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.analysis.clutch_metrics import loop_energy
from rig.plants.clutch.variants import StaticCharacteristic

GRID = 20001        # angle grid of the theoretical loading/unloading paths


@dataclass(frozen=True)
class Cycle:
    """One loading/unloading cycle: time span (s) and applied-torque extremes (N·m)."""

    start: float
    end: float
    torque_min: float
    torque_max: float


def cycles(t: np.ndarray, torque: np.ndarray) -> list[Cycle]:
    """Split an applied-torque record (s, N·m) at its valleys into cycles that both load and unload."""
    t, torque = np.asarray(t, dtype=float), np.asarray(torque, dtype=float)
    if t.ndim != 1 or t.shape != torque.shape or t.size < 3:
        raise ValueError(f"applied torque: need matching 1-D t and torque with >= 3 samples, got {t.shape}, "
                         f"{torque.shape}")
    step = np.sign(np.diff(torque))
    moving = np.flatnonzero(step)
    valleys = [int(i) for k, i in enumerate(moving[1:], start=1)
               if step[i] > 0 and step[moving[k - 1]] < 0]           # first rise after a fall
    bounds = [0] + valleys + [t.size - 1]
    out = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        seg = torque[a:b + 1]
        if np.any(np.diff(seg) > 0) and np.any(np.diff(seg) < 0):
            out.append(Cycle(float(t[a]), float(t[b]), float(seg.min()), float(seg.max())))
    return out


def reading_points(t: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The samples (t s, value) at which a held display shows a new value (and the first one).

    A multimeter shows each reading until the next; pairing every held sample with the load at its own
    time would lag the angle by up to one reading period. The first sample of each new value is paired
    with the load at (almost) the time the reading was taken.
    """
    t, value = np.asarray(t, dtype=float), np.asarray(value, dtype=float)
    keep = np.concatenate(([True], value[1:] != value[:-1])) if value.size else np.zeros(0, bool)
    return t[keep], value[keep]


def cycle_energy(t: np.ndarray, phi: np.ndarray, torque: np.ndarray, cycle: Cycle) -> float:
    """Loop energy ∮T dφ (J) of the samples (t s, φ rad, T N·m) inside ``cycle``."""
    inside = (t >= cycle.start) & (t <= cycle.end)
    if np.count_nonzero(inside) < 3:
        raise ValueError(f"cycle {cycle.start:g}..{cycle.end:g} s has fewer than 3 samples")
    return float(loop_energy(phi[inside], torque[inside]))


def theory_cycle_energy(clutch: StaticCharacteristic, phi_start: float, torque_min: float,
                        torque_max: float) -> tuple[float, float, bool]:
    """(energy J, end angle rad, disengaged) of one quasi-static cycle T_min → T_max → T_min from the
    angle ``phi_start`` (rad, inside one lobe) by the characteristic alone.

    Above the loading peak the clutch slips one lobe at the peak torque: the lever does T_peak·period
    more work and the cycle ends one period further (the plant's quasi-static disengagement).
    """
    if not torque_max > torque_min:
        raise ValueError(f"cycle needs torque_max > torque_min, got {torque_min} and {torque_max} N*m")
    lobe, local = divmod(phi_start - clutch.phi_min, clutch.period)
    local += clutch.phi_min
    t_peak = clutch.peak_torque
    slip = torque_max > t_peak
    top = min(torque_max, t_peak)
    up = np.linspace(local, clutch.apex, GRID)
    u = np.maximum(np.maximum.accumulate(clutch.torque(up, 1.0)), torque_min)
    phi_b = clutch.disengagement_angle if slip else _crossing(up, u, top, rising=True)
    keep = up < phi_b
    up, u = np.append(up[keep], phi_b), np.append(u[keep], top)
    down = np.linspace(phi_b, clutch.phi_min, GRID)
    low = np.minimum(np.minimum.accumulate(clutch.torque(down, -1.0)), top)
    phi_e = _crossing(down, low, torque_min, rising=False) if low[-1] <= torque_min else clutch.phi_min
    keep = down > phi_e
    down, low = np.append(down[keep], phi_e), np.append(low[keep], torque_min)
    energy = (np.trapezoid(u, up) - np.trapezoid(low[::-1], down[::-1]) + torque_min * (local - phi_e)
              + (t_peak * clutch.period if slip else 0.0))
    return float(energy), float(phi_e + (lobe + slip) * clutch.period), bool(slip)


def _crossing(phi: np.ndarray, path: np.ndarray, level: float, rising: bool) -> float:
    """Angle (rad) where a monotone path first reaches ``level``, linearly interpolated between grid points."""
    hit = path >= level if rising else path <= level
    if not np.any(hit):
        raise ValueError(f"torque level {level:g} N*m is never reached on the {'loading' if rising else 'unloading'} "
                         f"path")
    i = int(np.argmax(hit))
    if i == 0:
        return float(phi[0])
    a, b = path[i - 1], path[i]
    return float(phi[i - 1] + (level - a) / (b - a) * (phi[i] - phi[i - 1]))

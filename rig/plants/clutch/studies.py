"""Parameter studies of the flat-tappet static characteristic (MODELS.md §4.2).

Families of T(φ) on one lobe half [0, 60°] varying one of r0, r1, r2, k_a, δ around the reference cam
(r0 = 32 mm, r1 = 100 mm, r2 = 28 mm, k_a = 28 N/mm, δ = 5 mm, n = 3), with the peak torque and the
peak (disengagement) angle of every member. The elastic curve (μ_B = 0) is the default, so the
curves vanish at the apex; give ``mu_B`` for the loading branch with friction.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.plants.clutch.flat_tappet import FlatTappetClutch
from rig.plants.clutch.geometry import APEX
from rig.plants.clutch.variants import FlatTappetCharacteristic

#: reference cam of the studies (SI)
REFERENCE = {"r0": 0.032, "r1": 0.100, "r2": 0.028, "k_a": 28e3, "delta": 0.005, "n": 3}

#: family members per varied parameter (SI); all keep a valid profile (r2 < r0, asin argument < 1)
FAMILIES: dict[str, tuple[float, ...]] = {
    "r0": (0.029, 0.0305, 0.032, 0.0335, 0.035),
    "r1": (0.090, 0.095, 0.100, 0.105, 0.110),
    "r2": (0.024, 0.026, 0.028, 0.030, 0.031),
    "k_a": (20e3, 24e3, 28e3, 32e3, 36e3),
    "delta": (0.003, 0.004, 0.005, 0.006, 0.007),
}

#: how each parameter is shown (symbol, display unit, SI → display factor)
_DISPLAY = {"r0": ("r0", "mm", 1e3), "r1": ("r1", "mm", 1e3), "r2": ("r2", "mm", 1e3),
            "k_a": ("k_a", "N/mm", 1e-3), "delta": ("δ", "mm", 1e3)}


@dataclass(frozen=True)
class StudyFamily:
    """One varied parameter: member values (SI), angle grid (rad), curves T (N·m), peaks."""

    parameter: str
    values: np.ndarray        # (members,) SI
    phi: np.ndarray           # (points,) rad
    torque: np.ndarray        # (members, points) N·m
    peak_torque: np.ndarray   # (members,) N·m
    peak_angle: np.ndarray    # (members,) rad


def characteristic(mu_B: float = 0.0, **overrides: float) -> FlatTappetCharacteristic:
    """The reference cam with some parameters replaced (SI)."""
    unknown = set(overrides) - set(REFERENCE)
    if unknown:
        raise ValueError(f"parameter study: unknown parameter(s) {sorted(unknown)}; known: {sorted(REFERENCE)}")
    return FlatTappetCharacteristic(FlatTappetClutch(**{**REFERENCE, **overrides}, mu_B=mu_B))


def parameter_family(parameter: str, values: tuple[float, ...] | None = None, mu_B: float = 0.0,
                     points: int = 241) -> StudyFamily:
    """Curves and peaks for ``parameter`` taking ``values`` (SI; default :data:`FAMILIES`)."""
    if values is None:
        if parameter not in FAMILIES:
            raise ValueError(f"parameter study: no default family for {parameter!r}; known: {sorted(FAMILIES)}")
        values = FAMILIES[parameter]
    phi = np.linspace(0.0, APEX, points)
    direction = 1.0 if mu_B > 0 else 0.0
    members = [characteristic(mu_B, **{parameter: v}) for v in values]
    peaks = np.array([m.branch_peak(direction) for m in members])
    return StudyFamily(parameter=parameter, values=np.asarray(values, dtype=float), phi=phi,
                       torque=np.array([m.torque(phi, direction) for m in members]),
                       peak_torque=peaks[:, 1], peak_angle=peaks[:, 0])


def parameter_studies(mu_B: float = 0.0) -> dict[str, StudyFamily]:
    """All default families, keyed by the varied parameter."""
    return {p: parameter_family(p, mu_B=mu_B) for p in FAMILIES}


def plot_parameter_studies(out_dir: str | Path, mu_B: float = 0.0) -> list[Path]:
    """Write one PNG per family (T in N·m over φ in degrees, peaks marked) and return their paths."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, fam in parameter_studies(mu_B).items():
        symbol, unit, scale = _DISPLAY[name]
        label = f"{symbol} ({unit})"
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        for v, curve, pa, pt in zip(fam.values, fam.torque, fam.peak_angle, fam.peak_torque):
            line, = ax.plot(np.degrees(fam.phi), curve, label=f"{symbol} = {v * scale:g}")
            ax.plot(math.degrees(pa), pt, "o", color=line.get_color(), ms=4)
        ax.set_xlabel("relative angle φ (°)")
        ax.set_ylabel("torque T (N·m)")
        ax.set_title(f"Flat-tappet static characteristic, varying {label}" + (f", μ_B = {mu_B:g}" if mu_B else ""))
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        path = out / f"clutch_study_{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def write_peak_table(out_dir: str | Path, mu_B: float = 0.0) -> Path:
    """CSV of peak torque (N·m) and peak angle (deg) per family member, the varied value in its charts' unit (mm,
    N/mm) named in the row; returns its path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "clutch_study_peaks.csv"
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["parameter", "value", "unit", "peak_torque [N*m]", "peak_angle [deg]"])
        for name, fam in parameter_studies(mu_B).items():
            _, unit, scale = _DISPLAY[name]
            for v, pt, pa in zip(fam.values, fam.peak_torque, fam.peak_angle):
                w.writerow([name, f"{v * scale:.6g}", unit, f"{pt:.6g}", f"{math.degrees(pa):.6g}"])
    return path

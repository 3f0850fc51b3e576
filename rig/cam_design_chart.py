"""The chart of ``rig cam-design``: the curves of a :class:`~rig.mechanisms.cam.design.CamDesign` over the cam angle
and every check against its limit.

Kept outside :mod:`rig.mechanisms.cam` (the checks, which it only reads). Layout: the three curve panels span the
page (their legends in a narrow column on the right); the check panel below has its own left margin for the check
names. A check with a share of its limit (:func:`~rig.mechanisms.cam.design.utilisation`) is a bar of that share
(green PASS, red FAIL, grey information); a check without one — a limit of 0 such as r_b/h ≥ 0, where "limit/value"
means nothing — is no bar: a hollow marker at the axis' start in its verdict's colour, its name in italics and its
text the verdict, the comparison itself and "no ratio to its limit" (a PASS marked as information only).
"""
from __future__ import annotations

from math import degrees
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from rig.mechanisms.cam.design import CamDesign, Check

#: figure-width fractions: the curve panels (legends to the right of them) and the check panel (names to its left)
CURVES_LEFT, CURVES_RIGHT = 0.09, 0.80
CHECKS_LEFT, CHECKS_RIGHT = 0.31, 0.97


def verdict(check: "Check") -> str:
    """'information', 'PASS' or 'FAIL'."""
    return "information" if check.relation == "info" else "PASS" if check.ok else "FAIL"


def colour(check: "Check") -> str:
    return "0.6" if check.relation == "info" else "tab:green" if check.ok else "tab:red"


FAILED = {"≤": ">", "≥": "<", "<": "≥", ">": "≤"}     # the relation a failed check's numbers stand in


def row_text(check: "Check", use: float) -> str:
    """The text beside a check's row: its share of the limit and the comparison, or — without a share — that it
    has none, its verdict and the comparison."""
    relation = "vs" if check.relation == "info" else check.relation
    compared = f"{check.value:.4g} {relation} {check.limit:.4g} {check.unit}".rstrip()
    if np.isfinite(use):                 # a failed check's relation as it stands: 39.68 > 30 °, not "39.68 ≤ 30 °"
        shown = relation if check.ok or check.relation == "info" else FAILED.get(relation, relation)
        return f"{use:.2f}  ({check.value:.4g} {shown} {check.limit:.4g} {check.unit}".rstrip() + \
            (": fails)" if not check.ok and check.relation != "info" else ")")
    if check.relation == "info":
        return f"information: {compared} (no ratio to its limit)"
    if check.ok:
        return f"PASS, {compared} holds; information only: no ratio to its limit"
    return f"FAIL, {compared} does not hold (no ratio to its limit)"


def plot_design(design: "CamDesign", path: str | Path, title: str = "") -> Path:
    """PNG: pressure angle with its limit, pitch-curve radius with the undercut limit, Hertz stress (without a
    permissible stress: the contact force) over the cam angle, and every check's use of its limit (module
    docstring); ``title``: what was checked (the scene's file name), in the chart's title."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rig.analysis.plots import write_tight
    from rig.mechanisms.cam.design import utilisation

    deg = np.degrees(design.phi)
    fig = plt.figure(figsize=(10, 12))
    curves = fig.add_gridspec(3, 1, hspace=0.3, left=CURVES_LEFT, right=CURVES_RIGHT, top=0.94, bottom=0.40)
    axes = [fig.add_subplot(curves[0])]
    axes += [fig.add_subplot(curves[i], sharex=axes[0]) for i in (1, 2)]
    axes[0].plot(deg, np.degrees(design.pressure_angle), label="pressure angle")
    axes[0].axhline(degrees(design.pressure_limit), color="r", ls="--", label="limit")
    axes[0].set_ylabel("pressure angle (°)")
    rho = np.clip(design.rho * 1e3, -300.0, 300.0)
    axes[1].plot(deg, rho, label="ρ pitch curve")
    for sgn in (1, -1) if np.isfinite(design.undercut) else ():     # no roller radius: no limit
        axes[1].axhline(sgn * design.undercut * 1e3, color="r", ls="--", label="±r_R/0.7" if sgn > 0 else None)
    axes[1].set_ylabel("ρ (mm, clipped at ±300)")
    hertz = bool(np.isfinite(design.sigma_allow))     # else no roller width: the contact force instead
    if hertz:
        axes[2].plot(deg, design.sigma_h / 1e6, label="Hertz stress σ_H")
        axes[2].axhline(design.sigma_allow / 1e6, color="r", ls="--", label="permissible (assumed)")
    else:
        axes[2].plot(deg, design.contact_force, label="contact force")
        axes[2].axhline(0.0, color="r", ls="--", label="force closure")
    other = design.contact_force < 0.0
    if other.any():                      # force closure lost: the roller on the other flank or lifted (the jump)
        axes[2].fill_between(deg, 0.0, 1.0, where=other, transform=axes[2].get_xaxis_transform(), color="tab:orange",
                             alpha=0.25, lw=0, label="R23 < 0: other flank" if hertz else "lifts off")
    if hertz and np.isnan(design.sigma_h).any():
        axes[2].fill_between(deg, 0.0, 1.0, where=np.isnan(design.sigma_h), transform=axes[2].get_xaxis_transform(),
                             color="tab:red", alpha=0.25, lw=0, label="loaded wall undercut")
    axes[2].set_ylabel("σ_H (MPa)" if hertz else "contact force (N)")
    for ax in axes:
        ax.grid(True)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    axes[-1].set_xlabel("cam angle φ (°)")
    axes[-1].set_xlim(0.0, 360.0)
    axes[-1].set_xticks(np.arange(0, 361, 60))

    checks = design.checks
    bars = fig.add_subplot(fig.add_gridspec(1, 1, left=CHECKS_LEFT, right=CHECKS_RIGHT, top=0.33, bottom=0.05)[0])
    use = np.array([utilisation(ch) for ch in checks])
    ratio = np.isfinite(use)
    rows = np.arange(len(checks))[::-1]
    right = max(1.6, float(np.nanmax(np.where(ratio, use, np.nan), initial=1.0)) * 1.5)
    bars.barh(rows[ratio], use[ratio], color=[colour(ch) for ch, r in zip(checks, ratio) if r])
    for r, u, ch in zip(rows, use, checks):
        if np.isfinite(u):
            bars.text(max(u, 0.0) + 0.02, r, row_text(ch, u), va="center", fontsize=7,
                      bbox={"facecolor": "white", "edgecolor": "none", "pad": 0.5})
        else:                        # no share of the limit: a marker, not a bar of any length
            bars.plot([0.0], [r], "D", ms=6, mfc="white", mec=colour(ch), mew=1.5, clip_on=False, zorder=3)
            bars.text(0.04, r, row_text(ch, u), va="center", fontsize=7, style="italic",
                      color="tab:red" if not ch.ok else "0.25")
    bars.axvline(1.0, color="r", ls="--", lw=1)
    bars.set_yticks(rows, [ch.name for ch in checks], fontsize=8)
    for label, r in zip(bars.get_yticklabels(), ratio):
        if not r:
            label.set_style("italic")
    bars.set_ylim(-0.6, len(checks) - 0.4)
    bars.set_xlim(0.0, right)
    bars.set_xlabel("use of the limit (value/limit for ≤, limit/value for ≥; ≤ 1 passes)")
    bars.set_title("every check against its limit (bars: green PASS, red FAIL, grey information; ◇ italic: "
                   "no ratio to its limit)", fontsize=9, loc="left")
    fig.suptitle(f"cam design checks: {title}" if title else "cam design checks")   # the scene: charts of two
                                                                                    # scenes looked alike
    return write_tight(fig, path, tight=False)             # the grid specs leave room for names and legends

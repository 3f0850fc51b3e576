"""Cam-design checks of a disc cam with a centric translating roller follower (the course lab's cam, MODELS §2,
§3.6): pressure angle α = atan(s'/(r_b + s)), the pitch curve's radius of curvature against the undercut limit,
force closure from the follower's contact force, and the sizing rows of :func:`.design.sizing_checks`.

Without a base radius (the lab sheet gives none) the curves are drawn at the exact base radius the sizing gives,
and the checks that need the cam's own radius say so instead of passing; without a roller radius there is no
undercut limit to compare the pitch curve with.
"""
from __future__ import annotations

from math import degrees
from typing import Callable

import numpy as np

from rig.mechanisms.cam.curvature import curvature_radius
from rig.mechanisms.cam.design import LOAD_COEFFICIENT, CamDesign, Check, required_base_radius, sizing_checks
from rig.mechanisms.cam.limits import pressure_angle_limit, undercut_radius
from rig.mechanisms.checks import finite, finite_array, positive, whole
from rig.motion.program import CamProgram

GUIDE_MU = 0.1      # guide friction of the H/h optimum when the scene gives none (assumption, as the cam-bar's μ)


def pitch_radius(program: CamProgram, base_radius: float, phi: np.ndarray) -> np.ndarray:
    """Signed radius of curvature (m) of the roller centre's path in the cam frame, + where it curves round the cam
    centre (a dwell: r_b + s). The centre at q = (0, r_b + s(φ)) on the follower's axis, seen from the cam turned by
    φ: p = R(φ)·q, whose curvature is that of u = q' + Jq, w = q'' + 2Jq' − q (J the quarter turn)."""
    m = program.evaluate(phi)
    r = base_radius + m.s
    return curvature_radius(-r, m.s_p, -2.0 * m.s_p, m.s_pp - r)


def translating_design(program: CamProgram, omega: float, contact_force: Callable[[np.ndarray], np.ndarray],
                       base_radius: float | None = None, roller_radius: float | None = None, mu: float | None = None,
                       load_coefficient: float = LOAD_COEFFICIENT, n: int = 3600) -> CamDesign:
    """All checks of a centric translating roller follower on ``program`` turning at ``omega`` (rad/s);
    ``contact_force(phi)`` (N) the force pressing the roller on the cam at those angles (< 0: it lifts off);
    ``base_radius``/``roller_radius`` (m) the cam's, when known; ``mu`` the guide friction (default
    :data:`GUIDE_MU`, an assumption)."""
    finite(omega, "cam speed omega (rad/s)")
    if base_radius is not None:
        positive(base_radius, "base radius (m)")
    if roller_radius is not None:
        positive(roller_radius, "roller radius (m)")
    if mu is not None and finite(mu, "guide friction mu") < 0.0:
        raise ValueError(f"guide friction mu must be >= 0, got {mu!r}")
    positive(load_coefficient, "load coefficient")
    n = whole(n, 8, "angles n")
    phi = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    a_lim = pressure_angle_limit("translating")
    sizing = sizing_checks(program, GUIDE_MU if mu is None else mu, load_coefficient,
                           " (assumption: the scene gives no guide friction)" if mu is None else "")
    r_b = base_radius if base_radius is not None else required_base_radius(program, a_lim)
    m = program.evaluate(phi)
    alpha = np.arctan(m.s_p / (r_b + m.s))
    rho = pitch_radius(program, r_b, phi)
    cut = undercut_radius(roller_radius) if roller_radius is not None else float("nan")
    force = finite_array(contact_force(phi), "contact force (N)")
    out = CamDesign(phi, np.abs(alpha), a_lim, rho, cut, np.full(n, np.nan), float("nan"), force)
    c = out.checks
    i = int(np.argmax(np.abs(alpha)))
    at = f"at φ = {degrees(phi[i]):.1f}°, centric translating roller follower"
    if base_radius is not None:
        c.append(Check("max pressure angle", degrees(abs(alpha[i])), degrees(a_lim), "°", "≤",
                       f"{at}, r_b = {base_radius * 1e3:g} mm"))
    else:
        c.append(Check("max pressure angle at the exact base radius", degrees(abs(alpha[i])), degrees(a_lim), "°",
                       "info", f"{at}; the scene gives no base_radius: the cam's own pressure angle is not checked "
                               f"(drawn at r_b = {r_b * 1e3:.2f} mm)"))
    k = int(np.argmin(force))
    lifts = force[k] < 0.0
    c.append(Check("min contact force (force closure)", float(force[k]), 0.0, "N", "≥",
                   f"at φ = {degrees(phi[k]):.1f}°, at the scene's speed, spring and weight"
                   + ("; the follower lifts off the cam there (a jump)" if lifts else "")))
    convex = rho > 0.0
    j = int(np.argmin(np.where(convex, rho, np.inf)))
    where = f"at φ = {degrees(phi[j]):.1f}°, pitch curve at r_b = {r_b * 1e3:.2f} mm"
    if roller_radius is not None and base_radius is not None:
        c.append(Check("min convex pitch radius", rho[j] * 1e3, cut * 1e3, "mm", "≥",
                       f"{where}, undercut limit r_R/0.7, r_R = {roller_radius * 1e3:g} mm"))
    else:
        c.append(Check("min convex pitch radius", rho[j] * 1e3, 0.0, "mm", "info",
                       f"{where}; the scene gives no {'roller_radius' if base_radius is not None else 'base_radius'}"
                       ": no undercut check (the roller must stay below 0.7·ρ)"))
    c.extend(sizing)
    return out


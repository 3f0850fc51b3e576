"""Cam-design checks of the pin-insertion mechanism (MODELS §2, §3.6): each with its value, limit and verdict.

Pressure angle and contact force come from the level-1 kinetostatics at the nominal speed with the mounted spring;
curvature from the pitch curve (:mod:`.pitch`); Hertz stress on the flank that carries the load. The
translating-follower sizing (Flocke, guide, H/h) is applied to the program's rise or return that needs the largest base
radius (a return read backwards as a rise) as a design alternative, and so is an oscillating flat-faced follower on the
same follower swing. Series synthesis inverts the follower–rod–slider chain (an offset slider-crank) for the programmed
slider law.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from math import degrees, inf, isclose, isfinite, tau
from typing import TYPE_CHECKING

import numpy as np

from rig.mechanisms.cam.flat_follower import FlatFollower
from rig.mechanisms.cam.hertz import STEEL_E, STEEL_NU, effective_modulus, hertz_line_stress
from rig.mechanisms.cam.limits import pressure_angle_limit, undercut_radius
from rig.mechanisms.cam.pitch import PitchCurve, flank_radius, pitch_curve
from rig.mechanisms.cam.sizing import SizeModel, exact_base_radius, flocke_base_radius, pressure_angles
from rig.mechanisms.cam.synthesis import SliderCrank, round_trip_error, synthesize
from rig.plants.cam_bar.chain import SingularPositionError
from rig.motion.program import CamProgram, Segment
from rig.motion.laws import MotionLaw, ReversedLaw
from rig.motion.registry import get_law

if TYPE_CHECKING:
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism

SIGMA_ALLOW = 1200e6        # Pa, assumption: permissible contact stress of a hardened steel cam (no source value)
LOAD_COEFFICIENT = 0.5      # Φ_L = Q/F for the H/h optimum, assumption (no source value)
ROUND_TRIP_TOL = 1e-10
ROUNDING = 1e-12          # relative: a check's value this close to its limit is on it


@dataclass(frozen=True)
class Check:
    """One row: ``value`` and ``limit`` in display units ``unit``; ``relation`` '≤' or '≥', or 'info' for a
    figure compared with the limit but not a verdict; ``note`` says how."""

    name: str
    value: float
    limit: float
    unit: str
    relation: str
    note: str = ""

    @property
    def ok(self) -> bool:
        """The relation holds, a value on its limit within rounding included (a radius sized to the limit exactly,
        :func:`rig.mechanisms.cam.sizing.exact_base_radius`, checks back a few ulp above it)."""
        if self.relation == "info":
            return True
        if self.value <= self.limit if self.relation == "≤" else self.value >= self.limit:
            return True
        return isfinite(self.value) and isclose(self.value, self.limit, rel_tol=ROUNDING, abs_tol=0.0)


@dataclass
class CamDesign:
    """Curves over one revolution (SI, rad) and the check rows; ``sigma_h`` NaN where the loaded wall is undercut,
    ``contact_force`` R23 on the working flank (N, < 0: on the other flank)."""

    phi: np.ndarray
    pressure_angle: np.ndarray
    pressure_limit: float
    rho: np.ndarray
    undercut: float
    sigma_h: np.ndarray
    sigma_allow: float
    contact_force: np.ndarray
    checks: list[Check] = field(default_factory=list)


def _governing_segment(program: CamProgram,
                       alpha: float) -> tuple[Segment, MotionLaw, dict[str, float], float]:
    """The rise or return that needs the largest centric base radius at pressure angle ``alpha`` (rad), its law as a
    rise (a return reversed: :class:`~rig.motion.laws.ReversedLaw`), every moving segment's exact radius (m) by its
    name ('rise', 'return'; numbered where a kind recurs: 'rise 1', 'rise 2', …), and the governing segment's lower
    level above the program's lowest (m). A segment's pressure angle is tan α = s'/(r_b + s) with s the follower's
    whole lift, so a segment that starts higher needs that much less radius (a second rise stacked on a first one
    was sized from its own bottom: 5 mm too much, an audit)."""
    lowest = program.levels[0]
    moving = [(seg, get_law(seg.law) if seg.kind == "rise" else ReversedLaw(get_law(seg.law)),
               level - lowest - (seg.stroke if seg.kind == "return" else 0.0))    # the segment's lower level
              for seg, level in zip(program.segments, program.start_levels) if seg.kind in ("rise", "return")]
    if not moving:
        raise ValueError("the cam program has no rise")
    kinds = [seg.kind for seg, _, _ in moving]
    names = [kind if kinds.count(kind) == 1 else f"{kind} {kinds[:i + 1].count(kind)}" for i, kind in enumerate(kinds)]
    radii = {name: exact_base_radius(law, seg.stroke, seg.angle, alpha) - below
             for name, (seg, law, below) in zip(names, moving)}
    i = int(np.argmax(list(radii.values())))
    return *moving[i][:2], radii, moving[i][2]


def design_checks(mech: "PinInsertionMechanism", omega: float, high_speed: bool = True, n: int = 3600,
                  sigma_allow: float = SIGMA_ALLOW, load_coefficient: float = LOAD_COEFFICIENT,
                  E: float = STEEL_E, nu: float = STEEL_NU) -> CamDesign:
    """All checks for ``mech`` turning at ``omega`` (rad/s) over ``n`` cam angles; ``high_speed`` picks the 30°
    (else 45°) limit."""
    phi = np.linspace(0.0, tau, n, endpoint=False)
    ks = mech.kinetostatics(phi, omega)
    pc = pitch_curve(mech, phi)
    a_lim = pressure_angle_limit("oscillating", high_speed)
    cut = undercut_radius(mech.r_R)
    # R23n > 0 turns the follower towards larger ψ, which moves the roller towards the cam centre (§3.1 coordinates,
    # docs/cam-bar.md): the wall that pushes it so is the outer one, at r + r_R, concave to the roller
    outer = (ks.R23n >= 0.0) == (_towards_centre(mech, phi) > 0.0)
    wall = flank_radius(pc.rho, mech.r_R, outer)
    fits = 1.0 / mech.r_R + 1.0 / wall > 0.0        # else the wall's offset curve loops there (undercut): no contact
    sigma = np.full(phi.size, np.nan)
    sigma[fits] = hertz_line_stress(ks.R23n[fits], mech.roller_width, mech.r_R, wall[fits],
                                    effective_modulus(E, nu, E, nu))
    out = CamDesign(phi, ks.pressure_angle, a_lim, pc.rho, cut, sigma, sigma_allow, ks.R23n)
    c = out.checks
    i = int(np.argmax(ks.pressure_angle))
    c.append(Check("max pressure angle", degrees(ks.pressure_angle[i]), degrees(a_lim), "°", "≤",
                   f"at φ = {degrees(phi[i]):.1f}°, oscillating follower, {'high' if high_speed else 'low'} speed"))
    c.append(_flank_check(phi, ks.R23n, mech.clearance))
    convex = pc.rho > 0.0
    i = int(np.argmin(np.where(convex, pc.rho, np.inf)))
    c.append(Check("min convex pitch radius", pc.rho[i] * 1e3, cut * 1e3, "mm", "≥",
                   f"at φ = {degrees(phi[i]):.1f}°, undercut limit r_R/0.7, r_R = {mech.r_R * 1e3:g} mm"))
    if not convex.all():
        i = int(np.argmin(np.where(convex, np.inf, -pc.rho)))
        c.append(Check("min concave pitch radius", -pc.rho[i] * 1e3, cut * 1e3, "mm", "≥",
                       f"at φ = {degrees(phi[i]):.1f}°, outer flank of the groove"))
    i = int(np.nanargmax(sigma)) if fits.any() else 0
    where = (f"at φ = {degrees(phi[i]):.1f}°, |R23| = {abs(ks.R23n[i]):.1f} N on the "
             f"{'outer (concave) wall, r + r_R' if outer[i] else 'inner (convex) wall, r − r_R'}"
             f"{'' if ks.R23n[i] >= 0.0 else ' (the other flank: R23 < 0)'}, width {mech.roller_width * 1e3:g} mm, steel "
             f"E = {E / 1e9:g} GPa, ν = {nu:g} (assumptions)")
    if not fits.all():
        j = int(np.argmin(fits))
        where = (f"the loaded wall is undercut from φ = {degrees(phi[j]):.1f}° ({np.count_nonzero(~fits)} of {phi.size} "
                 f"angles: its radius {wall[j] * 1e3:.4g} mm against the {mech.r_R * 1e3:g} mm roller, the offset "
                 f"curve loops — no contact geometry there); elsewhere {np.nanmax(sigma, initial=0.0) / 1e6:.5g} MPa "
                 + where)
    c.append(Check("max Hertz stress", sigma[i] / 1e6 if fits.all() else np.inf, sigma_allow / 1e6, "MPa", "≤",
                   where))
    c.extend(sizing_checks(mech.program, mech.mu, load_coefficient))
    c.append(_flat_follower_check(mech, phi, pc))
    c.append(_synthesis_check(mech, phi))
    return out


def _flank_check(phi: np.ndarray, normal: np.ndarray, clearance: float) -> Check:
    """Force closure (MODELS §2): the contact force on the working flank R23 stays > 0; where it changes sign the
    roller crosses the groove's clearance to the other flank (the jump)."""
    i = int(np.argmin(normal))
    note = "the roller stays on the working flank" if normal[i] >= 0.0 else ""
    if normal[i] < 0.0:
        neg = np.flatnonzero(normal < 0.0)
        runs = np.split(neg, np.flatnonzero(np.diff(neg) > 1) + 1)
        spans = ", ".join(f"{degrees(phi[r[0]]):.1f}–{degrees(phi[r[-1]]):.1f}°" for r in runs)
        note = (f"R23 < 0 over φ = {spans}: the roller crosses the {clearance * 1e3:g} mm clearance to the other "
                f"flank (a jump; level 2 simulates it)")
    return Check("min contact force on the working flank", float(normal[i]), 0.0, "N", "≥", f"at φ = "
                 f"{degrees(phi[i]):.1f}°, level 1 at the scene's speed and spring; {note}")


def _towards_centre(mech: "PinInsertionMechanism", phi: np.ndarray) -> np.ndarray:
    """+1 where a growing ψ moves the roller towards the cam centre, −1 where away: the sign of dr/dψ reversed,
    r = |B_R − A0| the roller centre's distance from the cam centre."""
    st = mech.state(phi)
    wx, wy = mech.l3 * st.trig.cp - mech.x_A0, mech.l3 * st.trig.sp - mech.y_A0
    dr_dpsi = (wx * -mech.l3 * st.trig.sp + wy * mech.l3 * st.trig.cp) / np.hypot(wx, wy)
    return -np.sign(dr_dpsi)


def required_base_radius(program: CamProgram, alpha: float) -> float:
    """The smallest centric base radius (m) keeping |pressure angle| ≤ ``alpha`` (rad) on every rise and return."""
    return max(_governing_segment(program, alpha)[2].values())


def sizing_checks(program: CamProgram, mu: float, load: float, mu_note: str = "") -> list[Check]:
    """The translating roller-follower sizing rows of ``program`` (Flocke, exact base radius, the H/h optimum with
    guide friction ``mu`` and load coefficient ``load``; ``mu_note`` says where μ comes from when not the scene)."""
    a_lim = pressure_angle_limit("translating")
    seg, law, radii, below = _governing_segment(program, a_lim)
    h, big_phi = seg.stroke, seg.angle
    rf = flocke_base_radius(law, h, big_phi, a_lim) - below
    re = max(radii.values())
    name = next(k for k, v in radii.items() if v == re)
    what = (f"centric translating roller follower on the {name} ({seg.law}, h = {h * 1e3:g} mm, "
            f"Φ = {degrees(big_phi):g}°{', read backwards as a rise' if seg.kind == 'return' else ''}"
            f"{f', from a lift of {below * 1e3:g} mm' if below > 0.0 else ''})")
    flocke = degrees(pressure_angles(law, h, big_phi, rf + below).max())
    verdict = ("evaluated at s'_max it is too small" if not isclose(flocke, degrees(a_lim), rel_tol=1e-9) else
               "exact for this law (its steepest pressure angle lies at s'_max)")
    others = ", ".join(f"{k} {v * 1e3:.2f} mm" for k, v in radii.items() if k != name)
    rows = [Check("Flocke base radius: max pressure angle", flocke, degrees(a_lim), "°", "info",
                  f"r_b = {rf * 1e3:.2f} mm for {what}: {verdict}"),
            Check("exact base radius: max pressure angle", degrees(pressure_angles(law, h, big_phi, re + below).max()),
                  degrees(a_lim), "°", "≤", f"r_b = {re * 1e3:.2f} mm (max over the {name}, not at s'_max), the "
                  f"segment that needs the largest radius{f' (the others: {others})' if others else ''}")]
    model = SizeModel(law, big_phi, mu, load)
    opt, scan = model.optimum(), model.scan()
    rows.append(Check("optimum pressure angle (dH/dα = 0)", degrees(opt.alpha), degrees(model.alpha_lock), "°", "≤",
                      f"H/h = {opt.total:.4f}, r_b/h = {opt.base:.4f}, b/h = {opt.guide:.4f} (μ = {mu:g}{mu_note}, "
                      f"Φ_L = {load:g}; scan: {degrees(scan.alpha):.3f}°, H/h = {scan.total:.4f}); "
                      "limit: self-locking angle"))
    rows.append(Check("optimum: centric base radius r_b/h", opt.base, 0.0, "", "≥",
                      "a negative value means the formula is outside its range at this α"))
    return rows


def _flat_follower_check(mech: "PinInsertionMechanism", phi: np.ndarray, pc: PitchCurve) -> Check:
    """The same follower swing on an oscillating flat-faced follower: R_b,min without cusps vs this cam."""
    st = mech.state(phi)
    r_top = float(st.r[np.argmax(st.s)])
    sign = 1.0 if r_top >= st.r[np.argmin(st.s)] else -1.0  # lift = swing that moves the follower outwards
    psi_low = float(st.psi[np.argmin(sign * st.psi)])        # lift 0 on the base circle: the least lift, ≥ 0 all round

    def law(f: np.ndarray):
        s = mech.state(f)
        return sign * (s.psi - psi_low), sign * s.psi_p, sign * s.psi_pp

    pivot = float(np.hypot(mech.x_A0, mech.y_A0))
    rb_cam = float(np.min(np.hypot(pc.x, pc.y))) - mech.r_R
    sense = "counter-clockwise" if mech.cam_direction > 0 else "clockwise"
    try:
        rb_min = FlatFollower(pivot, 0.0, law, float(mech.cam_direction)).min_base_radius(phi)
    except ValueError as exc:       # no cusp-free radius below the pivot: a failed check (it ended rig cam-design
        return Check("flat-faced follower: base radius", rb_cam * 1e3, inf, "mm", "≥",      # with no table; an audit)
                     f"no cusp-free flat-faced follower for this swing: {exc} (A = {pivot * 1e3:.2f} mm, e = 0)")
    return Check("flat-faced follower: base radius", rb_cam * 1e3, rb_min * 1e3, "mm", "≥",
                 f"present cam's smallest profile radius vs the cusp-free minimum for the same swing "
                 f"(A = {pivot * 1e3:.2f} mm, e = 0, the cam turning {sense} as the scene's cam_direction)")


def _synthesis_check(mech: "PinInsertionMechanism", phi: np.ndarray) -> Check:
    st = mech.state(phi)
    crank = SliderCrank(mech.L3, mech.l4, mech.e_sk, mech.chain.rod_side)
    x = mech.s0 - st.s
    try:
        law = synthesize(crank, x, -st.s_p, -st.s_pp)
    except SingularPositionError as exc:         # a chain at (or within a step of) a dead centre: a failed check
        return Check("series synthesis round trip", inf, ROUND_TRIP_TOL * 1e3, "mm", "≤",
                     f"slider law → follower law (slider-crank L3/l4/e_sk): {exc}")
    dpsi = float(np.max(np.abs(np.angle(np.exp(1j * (law.q - st.psi))))))
    return Check("series synthesis round trip", round_trip_error(crank, law, x) * 1e3, ROUND_TRIP_TOL * 1e3, "mm",
                 "≤", f"slider law → follower law (slider-crank L3/l4/e_sk) → slider law; follower law vs the "
                      f"chain: max |Δψ| = {degrees(dpsi):.2e}°")


def format_checks(design: CamDesign) -> str:
    """Table: check, value, limit, unit, PASS/FAIL, note."""
    lines = [f"{'check':<42} {'value':>11} {'':4} {'limit':>11} {'unit':<4} {'':4}  note"]
    for ch in design.checks:
        verdict = "info" if ch.relation == "info" else "PASS" if ch.ok else "FAIL"
        rel = "vs" if ch.relation == "info" else ch.relation
        lines.append(f"{ch.name:<42} {ch.value:11.5g} {rel:^4} {ch.limit:11.5g} {ch.unit:<4} {verdict:4}  {ch.note}")
    return "\n".join(lines)


def utilisation(check: Check) -> float:
    """How much of its limit a check uses: value/limit for '≤', limit/value for '≥' (≤ 1 passes); NaN where the
    ratio means nothing (a limit of 0 — "≥ 0" would read 0 whatever the value —, a negative side)."""
    num, den = (check.value, check.limit) if check.relation in ("≤", "info") else (check.limit, check.value)
    return num / den if num >= 0 and den > 0 and check.limit != 0 else float("nan")

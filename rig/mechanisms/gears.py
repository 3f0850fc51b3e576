"""Profile-shifted external spur gear pair (MODELS §5): inv α_w = inv α0 + 2(x1 + x2)/(z1 + z2)·tan α0,
a = m(z1 + z2)/2 · cos α0 / cos α_w, and the usual diameters (ISO 21771 / DIN 3960 conventions, addendum
coefficient 1, dedendum 1.25)."""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from math import acos, cos, degrees, hypot, pi, radians, sin, sqrt, tan
from typing import NamedTuple

from scipy.optimize import brentq

from rig.mechanisms.checks import degrees_hint, finite, whole

MODULE_MAX = 0.1      # m: the largest gear module taken for one (larger ones are mm given as m)
TEETH_MAX = 10_000    # teeth of one gear (10^9 read a false interference from rounding; an audit)
MODULE_MIN = 1e-5     # m: the smallest (0.01 mm; watch gears start at 0.05 mm)
TIP_THICKNESS_MIN = 0.2     # tip thickness s_a / m below which a tooth is called nearly pointed (warned)


class ThinToothWarning(UserWarning):
    """A gear's tooth tip is thinner than :data:`TIP_THICKNESS_MIN`·m (valid, but nearly pointed)."""


def involute(alpha: float) -> float:
    """inv α = tan α − α (rad), α in [0, 90°) (NaN and 90° read nan and 1.6e16; an audit)."""
    if not 0.0 <= finite(alpha, "involute angle α (rad)") < pi / 2:
        raise ValueError(f"involute angle α must lie in [0, 90°), got {alpha!r} rad")
    return tan(alpha) - alpha


def inverse_involute(value: float) -> float:
    """α (rad) with inv α = ``value`` (rad), 0 ≤ value < inv(90° − 1e-9 rad) ≈ 1e9 (a root in [0, π/2))."""
    top = involute(pi / 2 - 1e-9)
    if not 0.0 <= finite(value, "inverse_involute value inv α (rad)") < top:
        raise ValueError(f"inverse_involute value inv α must lie in [0, {top:.3g}) rad (the involute function of "
                         f"[0, 90°)), got {value!r} rad")
    return brentq(lambda a: involute(a) - value, 0.0, pi / 2 - 1e-9, xtol=1e-15, rtol=1e-15)


class GearGeometry(NamedTuple):
    """Lengths in m, angles in rad. ``centre_distance_modification`` y·m = a − a0; ``tip_reduction`` k·m
    (tooth-height reduction keeping the tip clearance); ``tooth_thickness`` on the reference circles (negative for a
    gear shifted so far negative that its whole tooth lies inside the reference circle: a formal value then, the
    tooth itself is checked at its tip); ``tip_thickness`` s_a on the tip circles."""

    working_pressure_angle: float
    centre_distance: float
    reference_centre_distance: float
    centre_distance_modification: float
    tip_reduction: float
    reference_diameters: tuple[float, float]
    base_diameters: tuple[float, float]
    working_diameters: tuple[float, float]
    tip_diameters: tuple[float, float]
    root_diameters: tuple[float, float]
    tooth_thickness: tuple[float, float]
    contact_ratio: float
    tip_thickness: tuple[float, float]


@dataclass(frozen=True)
class SpurGearPair:
    """Teeth ``z1``, ``z2``, ``module`` m (m), profile-shift coefficients ``x1``, ``x2``, ``pressure_angle``
    α0 (rad, default 20°)."""

    z1: int
    z2: int
    module: float
    x1: float = 0.0
    x2: float = 0.0
    pressure_angle: float = radians(20.0)

    def __post_init__(self) -> None:
        for name in ("z1", "z2"):
            object.__setattr__(self, name, whole(getattr(self, name), 5, f"SpurGearPair {name} (teeth)", TEETH_MAX))
        for name in ("module", "x1", "x2", "pressure_angle"):
            finite(getattr(self, name), f"SpurGearPair {name}")
        if not MODULE_MIN <= self.module <= MODULE_MAX:      # (1e-200 m read a contact ratio of −3.5; an audit)
            raise ValueError(f"SpurGearPair module is in metres, from {MODULE_MIN:g} to {MODULE_MAX:g} m (gear modules "
                             f"run from 0.05 to 50 mm), got {self.module!r} m"
                             + (f": did you mean {self.module:g} mm = {self.module * 1e-3:g} m?"
                                if self.module > MODULE_MAX else ""))
        if not 0 < self.pressure_angle < radians(45):
            raise ValueError(f"SpurGearPair pressure_angle must lie in (0, 45°), got {self.pressure_angle!r} rad"
                             + degrees_hint(self.pressure_angle))
        for z, x, name in ((self.z1, self.x1, "x1"), (self.z2, self.x2, "x2")):
            x_min = 1.0 - z * sin(self.pressure_angle) ** 2 / 2     # no undercut: x ≥ 1 − z sin²α0 / 2
            if x < x_min - 1e-12:
                z_min = 2 * (1 - x) / sin(self.pressure_angle) ** 2
                raise ValueError(f"SpurGearPair {name} = {x:g} undercuts the {z}-tooth gear (needs {name} >= "
                                 f"{x_min:.3f}, or at {name} = {x:g} at least {z_min:.2f} teeth: z ≥ 2(1 − x)/sin²α0); "
                                 "undercut flanks (e.g. the practical 14-tooth limit at x = 0) are not modelled: their "
                                 "form circle and contact ratio need the generating trochoid")

    def geometry(self) -> GearGeometry:
        """The pair's geometry; a pointed tooth tip, meshing interference (a tip reaching the mate inside its base
        circle or below its generated involute, the form circle) or a contact ratio below 1 is a ValueError naming
        it."""
        m, a0_ = self.module, self.pressure_angle
        z1, z2, x1, x2 = self.z1, self.z2, self.x1, self.x2
        inv_w = involute(a0_) + 2 * (x1 + x2) / (z1 + z2) * tan(a0_)
        if inv_w <= 0.0:
            raise ValueError(f"SpurGearPair: profile shifts x1 = {x1:g}, x2 = {x2:g} (sum {x1 + x2:g}) leave no working "
                             f"pressure angle (inv α_w = {inv_w:.3g} ≤ 0): the shift sum must exceed "
                             f"{-involute(a0_) * (z1 + z2) / (2 * tan(a0_)):.3f}")
        aw = inverse_involute(inv_w)
        a_ref = m * (z1 + z2) / 2
        a = a_ref * cos(a0_) / cos(aw)
        ym = a - a_ref
        km = (x1 + x2) * m - ym                        # tip reduction keeping the tip clearance 0.25 m
        d = (m * z1, m * z2)
        db = tuple(di * cos(a0_) for di in d)
        dw = (2 * a * z1 / (z1 + z2), 2 * a * z2 / (z1 + z2))
        da = (d[0] + 2 * m * (1 + x1) - 2 * km, d[1] + 2 * m * (1 + x2) - 2 * km)
        df = (d[0] - 2 * m * (1.25 - x1), d[1] - 2 * m * (1.25 - x2))
        s = tuple(m * (pi / 2 + 2 * x * tan(a0_)) for x in (x1, x2))
        gears = ((z1, x1), (z2, x2))
        tips = [0.0, 0.0]                              # tip thickness s_a (m)
        # Roll lengths (m) along the line of action from each base-circle tangent point T_i: the involute the rack
        # cuts starts at form_i (its straight flank ends 1·m deep, the undercut limit's convention: form_i ≥ 0
        # without undercut), on the form circle d_Ff; the tip lies sqrt(r_a² − r_b²) out.
        form = tuple(d[i] / 2 * sin(a0_) - (1 - x) * m / sin(a0_) for i, (_, x) in enumerate(gears))
        d_form = tuple(2 * hypot(db[i] / 2, form[i]) for i in (0, 1))
        for i, (z, x) in enumerate(gears):
            if da[i] <= d_form[i]:
                raise ValueError(f"SpurGearPair: gear {i + 1} ({z} teeth, x = {x:g}) has its tip circle "
                                 f"({da[i] * 1e3:.3f} mm) inside its form circle ({d_form[i] * 1e3:.3f} mm, where the "
                                 f"cut involute starts; base circle {db[i] * 1e3:.3f} mm): no involute flank; the "
                                 "shifts (and the tip reduction they cause) are too large")
            s_a = tips[i] = da[i] * (s[i] / d[i] + involute(a0_) - involute(acos(db[i] / da[i])))
            if s_a <= 0:
                raise ValueError(f"SpurGearPair: gear {i + 1} ({z} teeth, x = {x:g}) has a pointed tooth "
                                 f"(tip thickness {s_a * 1e3:.3f} mm)")
        # Meshing interference: gear j's tip meets gear i at T1T2 − tip_j from T_i (T1T2 = a·sin α_w); before
        # form_i it cuts into the fillet, before T_i into the base circle, where there is no involute.
        line = a * sin(aw)
        tip_roll = tuple(sqrt((da[i] - db[i]) * (da[i] + db[i])) / 2 for i in (0, 1))    # (no cancellation)
        clashes = []
        for i, j in ((0, 1), (1, 0)):
            start = line - tip_roll[j]
            if start < form[i] - 1e-9 * m:
                where = (f"inside its base circle (d_b = {db[i] * 1e3:.3f} mm): involute interference" if start < 0
                         else f"below its form circle (d_Ff = {d_form[i] * 1e3:.3f} mm, {form[i] * 1e3:.3f} mm from "
                              f"T{i + 1}): fillet interference")
                clashes.append(f"gear {j + 1}'s tip (d_a = {da[j] * 1e3:.3f} mm) runs sqrt(r_a{j + 1}² − r_b{j + 1}²) = "
                               f"{tip_roll[j] * 1e3:.3f} mm along the line of action and meets gear {i + 1} "
                               f"({gears[i][0]} teeth, x = {gears[i][1]:g}) {start * 1e3:.3f} mm from T{i + 1}, {where}")
        if clashes:
            raise ValueError(f"SpurGearPair interferes: T1T2 = a·sin α_w = {line * 1e3:.3f} mm (a = {a * 1e3:.3f} mm, "
                             f"α_w = {degrees(aw):.2f}°); " + "; ".join(clashes) + "; the pair has no valid contact ratio")
        pb = pi * m * cos(a0_)
        eps = (tip_roll[0] + tip_roll[1] - line) / pb
        if eps < 1.0:
            raise ValueError(f"SpurGearPair: contact ratio {eps:.3f} < 1 (the teeth lose mesh): the profile shifts "
                             f"x1 = {x1:g}, x2 = {x2:g} (sum {x1 + x2:g}) spread the gears to a working pressure angle "
                             f"of {degrees(aw):.1f}°; a smaller shift sum keeps them in mesh")
        for i, ((z, x), s_a) in enumerate(zip(gears, tips)):        # valid, but nearly pointed: said once it is valid
            if s_a < TIP_THICKNESS_MIN * m:
                warnings.warn(f"SpurGearPair: gear {i + 1} ({z} teeth, x = {x:g}) has a nearly pointed tooth: tip "
                              f"thickness {s_a * 1e3:.4g} mm = {s_a / m:.3g}·m, below the usual {TIP_THICKNESS_MIN:g}·m "
                              "(design practice asks 0.2–0.4·m); a smaller shift thickens the tip",
                              ThinToothWarning, stacklevel=2)
        return GearGeometry(aw, a, a_ref, ym, km, d, db, dw, da, df, s, eps, tuple(tips))


"""Cam design (MODELS §2, §3.6): pressure-angle limits, pitch-curve curvature and undercut, Hertz contact
stress, translating-follower sizing (Flocke, guide length, H/h and its optimum), the oscillating flat-faced
follower's cusp test and series synthesis through a linkage. SI units inside; the CLI prints mm, °, MPa."""
from rig.mechanisms.cam.curvature import curvature_radius
from rig.mechanisms.cam.flat_follower import FlatFollower, FlatFollowerProfile
from rig.mechanisms.cam.hertz import effective_modulus, hertz_line_stress
from rig.mechanisms.cam.limits import pressure_angle_limit, undercut_radius
from rig.mechanisms.cam.sizing import (SizeModel, TotalSize, centric_base_ratio, exact_base_radius,
                                       flocke_base_radius, guide_ratio, pressure_angles)
from rig.mechanisms.cam.synthesis import (DoubleSlider, FollowerLaw, FourBar, Linkage, SliderCrank, SlottedLink,
                                          round_trip_error, synthesize)

__all__ = ["DoubleSlider", "FlatFollower", "FlatFollowerProfile", "FollowerLaw", "FourBar", "Linkage", "SizeModel",
           "SliderCrank", "SlottedLink", "TotalSize", "centric_base_ratio", "curvature_radius", "effective_modulus",
           "exact_base_radius", "flocke_base_radius", "guide_ratio", "hertz_line_stress", "pressure_angle_limit",
           "pressure_angles", "round_trip_error", "synthesize", "undercut_radius"]

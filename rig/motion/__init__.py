"""Motion laws, cam programs and cam speed profiles (MODELS §1)."""
from rig.motion.laws import Coefficients, MotionLaw, PiecewiseSineLaw, PolynomialLaw
from rig.motion.program import CamProgram, Motion, ProgramError, ProgramEvent, Segment, TimeMotion
from rig.motion.registry import UnknownLawError, available_laws, get_law, register_law
from rig.motion.speed import ConstantSpeed, Drive, RampSpeed, SinusoidalSpeed, SpeedProfile

__all__ = ["CamProgram", "Coefficients", "ConstantSpeed", "Drive", "Motion", "MotionLaw", "PiecewiseSineLaw",
           "PolynomialLaw", "ProgramError", "ProgramEvent", "RampSpeed", "Segment", "SinusoidalSpeed",
           "SpeedProfile", "TimeMotion", "UnknownLawError", "available_laws", "get_law", "register_law"]

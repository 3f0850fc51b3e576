"""The mechanism library of the sources (MODELS §5): Cardan joints, Geneva drive, profile-shifted spur gears,
belt, ratchet and friction-wheel drives, mobility and gear trains (Willis). Angles in rad, lengths in m,
speeds in rad/s; each class checks its input and names the parameter that is impossible."""
from rig.mechanisms.cardan import Cardan, DoubleCardan
from rig.mechanisms.drives import Belt, FrictionWheels, Ratchet
from rig.mechanisms.gears import SpurGearPair, involute, inverse_involute
from rig.mechanisms.geneva import Geneva
from rig.mechanisms.structure import mobility, willis

__all__ = ["Belt", "Cardan", "DoubleCardan", "FrictionWheels", "Geneva", "Ratchet", "SpurGearPair", "involute",
           "inverse_involute", "mobility", "willis"]

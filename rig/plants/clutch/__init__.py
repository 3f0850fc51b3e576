"""Elastic-and-safety clutch plants: flat-tappet geometry, statics and 2-DOF dynamics (MODELS.md §4)."""
from rig.plants.clutch.flat_tappet import CLUTCH_SCHEMA, FlatTappetClutch
from rig.plants.clutch.geometry import APEX, LOBE, GeometryError, PhaseLimits, phase_limits

__all__ = ["APEX", "CLUTCH_SCHEMA", "FlatTappetClutch", "GeometryError", "LOBE", "PhaseLimits", "phase_limits"]

"""The pin-insertion cam-bar mechanism: L0 kinematics, L1 kinetostatics, spring design (MODELS §3)."""
from rig.plants.cam_bar.chain import SingularPositionError
from rig.plants.cam_bar.kinetostatics import JammingError, Kinetostatics, Vec
from rig.plants.cam_bar.mechanism import (ChainPosition, PinInsertionMechanism, SpringDesign, State,
                                          default_program)
from rig.plants.cam_bar.timeline import Event

__all__ = ["ChainPosition", "Event", "JammingError", "Kinetostatics", "PinInsertionMechanism",
           "SingularPositionError", "SpringDesign", "State", "Vec", "default_program"]

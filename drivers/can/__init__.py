"""Host side of the CAN link (DBC ``data/can/rig.dbc``): receive, decode, check, reassemble, command."""
from drivers.can.host import CanHost, CurveResult, LinkEvent
from drivers.can.reassembly import Curve

__all__ = ["CanHost", "Curve", "CurveResult", "LinkEvent"]

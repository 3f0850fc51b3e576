"""Host side of the CAN link (DBC ``data/can/rig.dbc``): receive, decode, check, reassemble, command. The names below
are imported on first use (:mod:`rig.lazy`), so that the light modules (e.g. :mod:`.process_values`) do not import
the CAN stack."""
from rig.lazy import exports

_WHERE = {"Curve": "drivers.can.reassembly",
          **dict.fromkeys(("CanHost", "CurveResult", "LinkEvent"), "drivers.can.host")}
__all__ = list(_WHERE)
__getattr__ = exports(__name__, _WHERE)

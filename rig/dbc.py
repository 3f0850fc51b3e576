"""The project's CAN database (``data/can/rig.dbc``), parsed once per process by cantools.

The host's driver and the simulated device each read the DBC as real software would; inside one process they
share the parsed, read-only database instead of parsing it twice."""
from __future__ import annotations

import functools
from pathlib import Path

import cantools

DBC_PATH = Path(__file__).resolve().parents[1] / "data" / "can" / "rig.dbc"


@functools.lru_cache(maxsize=4)
def load_dbc(path: str | Path = DBC_PATH) -> cantools.database.Database:
    """The DBC at ``path``, parsed once per process (read only: everything that uses it shares it)."""
    return cantools.database.load_file(str(path))

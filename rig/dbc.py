"""The project's CAN database (``data/can/rig.dbc``), parsed once per process by cantools.

The host's driver and the simulated device each read the DBC as real software would; inside one process they
share the parsed, read-only database instead of parsing it twice."""
from __future__ import annotations

import functools
from pathlib import Path

import cantools
import numpy as np

DBC_PATH = Path(__file__).resolve().parents[1] / "data" / "can" / "rig.dbc"


@functools.lru_cache(maxsize=4)
def load_dbc(path: str | Path = DBC_PATH) -> cantools.database.Database:
    """The DBC at ``path``, parsed once per process (read only: everything that uses it shares it)."""
    return cantools.database.load_file(str(path))


def at_field_limit(signal: cantools.database.Signal, values: np.ndarray) -> np.ndarray:
    """Where the physical ``values`` of the signed DBC ``signal`` sit at its field's raw limits (−2^(n−1) or
    2^(n−1) − 1 counts, within half a count): a sender that saturates a quantity beyond the field sends the limit.
    All False for an unsigned signal (a counter or a time stamp, which wraps)."""
    values = np.asarray(values, dtype=float)
    if not signal.is_signed:
        return np.zeros(values.shape, bool)
    raw = (values - signal.offset) / signal.scale
    top = 2.0 ** (signal.length - 1)
    return (raw <= -top + 0.5) | (raw >= top - 1.5)

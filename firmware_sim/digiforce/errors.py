"""The one exception type of the acquisition unit."""
from __future__ import annotations


class DigiForceError(ValueError):
    """A command, program setting or input the unit refuses; the message names what is wrong."""

"""The error of a recording that cannot be read (its own module: the reader and the curve store both raise it)."""
from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rig.recorder.reader import Recording


class RecordingError(ValueError):
    """A recording is unreadable, truncated or corrupt; ``partial`` holds what could be recovered."""

    def __init__(self, message: str, partial: "Recording | None" = None):
        super().__init__(message)
        self.partial = partial

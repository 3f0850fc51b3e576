"""MCAP recorder and reader for rig runs (self-describing JSON-schema channels Foxglove loads, per-sample
view channels, log times = wall-clock start + simulation time)."""
from rig.recorder.reader import CurveRecord, Recording, RecordingError, read_recording
from rig.recorder.writer import Recorder

__all__ = ["Recorder", "read_recording", "Recording", "RecordingError", "CurveRecord"]

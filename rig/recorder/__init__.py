"""MCAP recorder and reader for rig runs (self-describing JSON-schema channels, simulation-time log times)."""
from rig.recorder.reader import CurveRecord, Recording, RecordingError, read_recording
from rig.recorder.writer import Recorder

__all__ = ["Recorder", "read_recording", "Recording", "RecordingError", "CurveRecord"]

"""MCAP recorder and reader for rig runs (self-describing JSON-schema channels Foxglove loads, per-sample
view channels, log times = wall-clock start + simulation time). The names below are imported on first use
(:mod:`rig.lazy`): reading a recording does not import the writer, naming its error imports neither."""
from rig.lazy import exports

_WHERE = {"Recorder": "rig.recorder.writer", "RecordingError": "rig.recorder.errors",
          **dict.fromkeys(("CurveRecord", "Recording", "read_recording"), "rig.recorder.reader")}
__all__ = list(_WHERE)
__getattr__ = exports(__name__, _WHERE)

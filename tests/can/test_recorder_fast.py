"""The recorder's fast paths against plain references: orjson block encoding against the stdlib json of
the same values (undefined ones as 0 with their JSON Pointers in ``nulls``), bulk /can/raw rows from
python-can messages against the tuple form."""
from __future__ import annotations

import json
import math

import can
import numpy as np
import pytest

from rig.recorder import Recorder
from rig.recorder.encoding import decode_block, dumps, encode_block
from rig.recorder.reader import read_recording


def _reference_json(values: dict) -> object:
    """The stdlib json of these arrays: non-finite values as 0, their JSON Pointers listed in ``nulls``."""
    out = {k: [float(x) if math.isfinite(x) else 0.0 for x in np.asarray(v, dtype=float).tolist()]
           for k, v in values.items()}
    out["nulls"] = [f"/{k}/{i}" for k, v in values.items() for i, x in enumerate(np.asarray(v, float)) if
                    not math.isfinite(x)]
    return out


def test_json_block_equals_stdlib_json_of_the_same_numbers():
    rng = np.random.default_rng(5)
    t = 3.2 + np.arange(700) * 1e-4
    a = rng.normal(0, 1e-3, 700)
    a[[3, 10, 11]] = [np.nan, np.inf, -np.inf]
    b = rng.normal(0, 1e4, 1400)[::2]                      # not contiguous
    data = encode_block(t, {"a": a, "b": b}, "json")
    assert json.loads(data) == _reference_json({"t": t, "a": a, "b": b})
    back = decode_block(data)
    assert np.array_equal(back["t"], t) and np.array_equal(back["b"], b)
    assert np.isnan(back["a"][[3, 10, 11]]).all() and np.array_equal(np.delete(back["a"], [3, 10, 11]),
                                                                      np.delete(a, [3, 10, 11]))


def test_dumps_writes_non_finite_list_items_as_null():
    assert json.loads(dumps({"v": [1.5, float("nan"), float("-inf"), 2, None, True, "x"]})) == \
        {"v": [1.5, None, None, 2, None, True, "x"]}


def test_can_frames_from_messages_equal_the_tuple_form(tmp_path):
    frames = [can.Message(timestamp=0.001 * i, arbitration_id=0x200 + i % 3, data=bytes([i % 256, 2 * i % 256, 7]),
                          is_extended_id=False, is_fd=i % 2 == 1) for i in range(2500)]
    frames.append(can.Message(timestamp=3.0, arbitration_id=0x18FF0001, data=bytes(range(64)), is_fd=True))
    paths = tmp_path / "msg.mcap", tmp_path / "tuple.mcap"
    with Recorder(paths[0], block_size=1000) as rec:
        rec.write_can_frames(frames[:1700])
        rec.write_can_frames(frames[1700:])
    with Recorder(paths[1], block_size=1000) as rec:
        rec.write_can_frames([(m.timestamp, m.arbitration_id, bytes(m.data), m.is_fd) for m in frames])
    a, b = (read_recording(p).can_frames for p in paths)
    assert a["data"] == b["data"] == [bytes(m.data) for m in frames]
    for key in ("t", "id", "dir", "channel", "is_fd", "brs", "esi", "is_extended", "error"):
        assert np.array_equal(a[key], b[key])
    assert a["dir"] == ["rx"] * 2501 and a["channel"] == [""] * 2501
    assert a["is_extended"].tolist() == [False] * 2500 + [True]


def test_can_frames_out_of_order_or_negative_are_named(tmp_path):
    with Recorder(tmp_path / "bad.mcap") as rec:
        rec.write_can_frames([(1.0, 1, b"", False)])
        with pytest.raises(ValueError, match="before the previous frame"):
            rec.write_can_frames([(1.5, 1, b"", False), (1.2, 1, b"", False)])
    with Recorder(tmp_path / "neg.mcap") as rec, pytest.raises(ValueError, match="-1.0"):
        rec.write_can_frames([can.Message(timestamp=-1.0, arbitration_id=1)])

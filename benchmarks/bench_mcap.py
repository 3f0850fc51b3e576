"""MCAP throughput of rig.recorder vs the raw mcap library writing/reading the same blocks.

A *sample* here is one value of one signal at one instant (time stamps are not counted): the truth
stream has 3 signals, so 1 instant = 3 samples. Targets: write >= 2 M samples/s, read >= 5 M samples/s.
Run: python benchmarks/bench_mcap.py
"""
from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from rig.recorder import Recorder, read_recording  # noqa: E402
from rig.recorder.encoding import encode_block  # noqa: E402

N = 600_000          # instants
BLOCK = 1000
SIGNALS = ("x", "v", "F")


def data() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    rng = np.random.default_rng(1)
    t = np.arange(N) * 1e-4
    return t, {"x": np.sin(7 * t), "v": 7 * np.cos(7 * t), "F": 40 + rng.normal(0, 0.5, N)}


def rig_write(path: Path, t, sig, encoding: str, compression: str) -> float:
    t0 = time.perf_counter()
    with Recorder(path, block_size=BLOCK, encoding=encoding, compression=compression, view_rate=None) as rec:
        for i in range(0, N, 10_000):      # the runner hands over chunks of a few thousand samples (blocks only)
            rec.write_truth(t[i:i + 10_000], {k: v[i:i + 10_000] for k, v in sig.items()})
    return time.perf_counter() - t0


def raw_write(path: Path, t, sig, encoding: str, compression: str) -> float:
    comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}[compression]
    t0 = time.perf_counter()
    with open(path, "wb") as f:
        w = Writer(f, compression=comp)
        w.start()
        sid = w.register_schema("block", "jsonschema", b"{}")
        cid = w.register_channel("/plant/truth", "json", sid)
        for i in range(0, N, BLOCK):
            body = encode_block(t[i:i + BLOCK], {k: v[i:i + BLOCK] for k, v in sig.items()}, encoding)
            w.add_message(cid, int(t[i] * 1e9), body, int(t[i] * 1e9))
        w.finish()
    return time.perf_counter() - t0


def rig_read(path: Path) -> float:
    t0 = time.perf_counter()
    rec = read_recording(path)
    assert rec.truth["F"].size == N
    return time.perf_counter() - t0


def raw_read(path: Path) -> float:
    from rig.recorder.encoding import decode_array
    t0 = time.perf_counter()
    parts = []
    with open(path, "rb") as f:
        for _, _, msg in make_reader(f).iter_messages(log_time_order=False):
            parts.append({k: decode_array(v) for k, v in json.loads(msg.data).items()})
    assert sum(p["F"].size for p in parts) == N
    return time.perf_counter() - t0


def main() -> None:
    t, sig = data()
    samples = N * len(SIGNALS)
    print(f"{N} instants x {len(SIGNALS)} signals = {samples} samples, blocks of {BLOCK}")
    with tempfile.TemporaryDirectory() as tmp:
        for encoding, compression in (("json", "zstd"), ("json", "lz4"), ("base64", "zstd"), ("base64", "lz4")):
            a, b = Path(tmp) / "rig.mcap", Path(tmp) / "raw.mcap"
            tw, rw = rig_write(a, t, sig, encoding, compression), raw_write(b, t, sig, encoding, compression)
            tr, rr = rig_read(a), raw_read(b)
            size = a.stat().st_size / samples
            print(f"[{encoding:6s} {compression:4s}] write {samples / tw / 1e6:6.2f} M samples/s "
                  f"(raw mcap {samples / rw / 1e6:6.2f}, ratio {rw / tw:4.2f}, target 2: {samples / tw / 2e6:4.2f}x) | "
                  f"read {samples / tr / 1e6:6.2f} M samples/s (raw mcap {samples / rr / 1e6:6.2f}, "
                  f"ratio {rr / tr:4.2f}, target 5: {samples / tr / 5e6:4.2f}x) | {size:4.1f} B/sample")


if __name__ == "__main__":
    main()

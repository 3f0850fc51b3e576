"""Raw signal values straight from a DBC message's bit layout, for one payload or many at once.

The layout is read from the DBC (start bit, length, signedness of every signal), so the DBC stays the
single source of the frame format; the result equals cantools' ``decode(data, scaling=False,
decode_choices=False)``. Only what the hot path needs is supported: little-endian integer signals of
a message without multiplexing, each within 8 bytes from its first byte (:func:`supports` tells).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class _Signal:
    name: str
    start: int                     # bit position of the least significant bit (Intel numbering)
    length: int                    # bits
    signed: bool


def supports(message) -> bool:
    """Whether :class:`FrameLayout` can decode this cantools message."""
    return not message.is_multiplexed() and all(
        s.byte_order == "little_endian" and not s.is_float and s.length < 64 and s.start % 8 + s.length <= 64
        for s in message.signals)


class FrameLayout:
    """Bit layout of one DBC message (a cantools ``Message``); decodes raw integer signal values."""

    def __init__(self, message) -> None:
        if not supports(message):
            raise ValueError(f"{message.name} (0x{message.frame_id:03X}): layout decoding needs little-endian "
                             "integer signals of at most 8 bytes span and no multiplexing")
        self.name, self.frame_id, self.length = message.name, message.frame_id, message.length
        self.signals = tuple(_Signal(s.name, s.start, s.length, s.is_signed) for s in message.signals)
        sig = self.signals
        self._bytes = np.array([[s.start // 8 + k for k in range(8)] for s in sig])   # 8 bytes from each first byte
        self._shift = np.array([s.start % 8 for s in sig], dtype=np.uint64)
        self._mask = np.array([(1 << s.length) - 1 for s in sig], dtype=np.uint64)
        self._top = np.array([s.length - 1 for s in sig], dtype=np.int64)
        self._signed_wrap = np.array([1 << s.length if s.signed else 0 for s in sig], dtype=np.int64)
        self._scalar = tuple((s.name, s.start, (1 << s.length) - 1, 1 << (s.length - 1) if s.signed else 0,
                              1 << s.length) for s in sig)        # (name, shift, mask, sign bit or 0, wrap)

    def decode_one(self, data: bytes | bytearray) -> dict[str, int]:
        """Raw values of one payload of :attr:`length` bytes."""
        if len(data) != self.length:
            raise ValueError(f"{self.name} (0x{self.frame_id:03X}): {len(data)} data bytes, DBC says {self.length}")
        word = int.from_bytes(data, "little")
        out = {}
        for name, start, mask, sign, wrap in self._scalar:
            value = (word >> start) & mask
            out[name] = value - wrap if value & sign else value
        return out

    def decode(self, payload: np.ndarray) -> dict[str, np.ndarray]:
        """Raw values (int64 arrays) of ``n`` payloads given as an ``(n, length)`` uint8 array."""
        payload = np.asarray(payload, dtype=np.uint8)
        if payload.ndim != 2 or payload.shape[1] != self.length:
            raise ValueError(f"{self.name} (0x{self.frame_id:03X}): payloads must be (n, {self.length}) bytes, "
                             f"got shape {payload.shape}")
        padded = np.zeros((payload.shape[0], self.length + 8), dtype=np.uint8)
        padded[:, :self.length] = payload
        words = np.ascontiguousarray(padded[:, self._bytes]).view("<u8")[..., 0]      # (n, signals)
        value = ((words >> self._shift) & self._mask).astype(np.int64)
        value -= ((value >> self._top) & 1) * self._signed_wrap
        return {s.name: value[:, i] for i, s in enumerate(self.signals)}

"""Bit budget of a CAN bus: exact frame lengths in bits and the wire time they take.

Classic CAN (ISO 11898-1, base/extended format): the frame length is counted field by field; the
stuff bits are either the worst case (``stuffing="worst"``, the bound of Davis et al. 2007:
``floor((g + 8n - 1) / 4)`` over the ``g + 8n`` stuffable bits) or counted exactly from the frame's
real bit pattern including its CRC-15 (``stuffing="exact"``).

CAN FD: the arbitration phase (SOF .. BRS, plus ACK, delimiters, EOF and intermission) runs at the
nominal bitrate; the data phase (ESI, DLC, data, stuff count, CRC with its fixed stuff bits, CRC
delimiter) at the data bitrate when the bitrate switch is used. Dynamic stuff bits are counted at
the worst case: at most 4 in the arbitration phase (standard id), the rest in the data phase.
"""
from __future__ import annotations

from dataclasses import dataclass

_EOF_IFS = 1 + 1 + 7 + 3          # ACK slot, ACK delimiter, end of frame, intermission
FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)


def _crc15(bits: list[int]) -> int:
    crc = 0
    for bit in bits:
        nxt = bit ^ ((crc >> 14) & 1)
        crc = (crc << 1) & 0x7FFF
        if nxt:
            crc ^= 0x4599
    return crc


def _bits(value: int, width: int) -> list[int]:
    return [(value >> (width - 1 - i)) & 1 for i in range(width)]


def _classic_stuffable_bits(arbitration_id: int, data: bytes, extended: bool) -> list[int]:
    """SOF .. end of CRC of a classic data frame, as transmitted before stuffing."""
    dlc = len(data)
    if extended:
        head = ([0] + _bits(arbitration_id >> 18, 11) + [1, 1] + _bits(arbitration_id & 0x3FFFF, 18)
                + [0, 0, 0] + _bits(dlc, 4))            # SRR, IDE, id ext, RTR, r1, r0, DLC
    else:
        head = [0] + _bits(arbitration_id, 11) + [0, 0, 0] + _bits(dlc, 4)   # RTR, IDE, r0, DLC
    body = head + [b for byte in data for b in _bits(byte, 8)]
    return body + _bits(_crc15(body), 15)


def _count_stuff_bits(bits: list[int]) -> int:
    stuffed, run, last = 0, 0, None
    for bit in bits:
        if bit == last:
            run += 1
        else:
            last, run = bit, 1
        if run == 5:
            stuffed += 1
            last, run = 1 - bit, 1          # the stuff bit is the complement and starts a new run
    return stuffed


@dataclass(frozen=True)
class BusTiming:
    """Bitrates of a bus: ``bitrate`` (nominal, bit/s), ``data_bitrate`` (CAN FD data phase, bit/s)."""

    bitrate: float = 500_000.0
    fd: bool = False
    data_bitrate: float | None = None
    stuffing: str = "worst"

    def __post_init__(self) -> None:
        if not self.bitrate > 0:
            raise ValueError(f"CAN bitrate must be positive, got {self.bitrate}")
        if self.data_bitrate is not None and not self.data_bitrate >= self.bitrate:
            raise ValueError(f"CAN FD data_bitrate {self.data_bitrate} must be >= the nominal bitrate {self.bitrate}")
        if self.data_bitrate is not None and not self.fd:
            raise ValueError("data_bitrate is only meaningful for CAN FD (fd=True)")
        if self.stuffing not in ("worst", "exact"):
            raise ValueError(f"stuffing must be 'worst' or 'exact', got {self.stuffing!r}")

    @property
    def fast_bitrate(self) -> float:
        """Bitrate of the FD data phase (the nominal bitrate when there is no bitrate switch)."""
        return self.data_bitrate if self.data_bitrate is not None else self.bitrate

    def classic_bits(self, arbitration_id: int, data: bytes, extended: bool = False) -> int:
        """Bits on the wire of a classic data frame, from SOF to the end of the intermission."""
        n = len(data)
        if n > 8:
            raise ValueError(f"classic CAN frame 0x{arbitration_id:X} has {n} data bytes (max 8)")
        g = 54 if extended else 34          # stuffable control bits: SOF .. DLC plus CRC-15
        if self.stuffing == "exact":
            stuff = _count_stuff_bits(_classic_stuffable_bits(arbitration_id, bytes(data), extended))
        else:
            stuff = (g + 8 * n - 1) // 4
        return g + 8 * n + stuff + 1 + _EOF_IFS   # + CRC delimiter

    def fd_bits(self, n: int, extended: bool = False) -> tuple[int, int]:
        """(nominal-rate bits, data-rate bits) of a CAN FD frame with ``n`` data bytes (worst-case stuffing)."""
        if n not in FD_LENGTHS:
            raise ValueError(f"{n} is not a valid CAN FD data length {FD_LENGTHS}")
        arb = 1 + (31 if extended else 12) + 4   # SOF, id (+RRS or SRR, IDE, ext id), 4 control bits
        stuffable = arb + 1 + 4 + 8 * n          # + ESI, DLC, data
        dynamic = (stuffable - 1) // 4
        arb_stuff = min(dynamic, (arb - 1) // 4)
        crc = 17 if n <= 16 else 21
        fixed = -(-(4 + crc) // 4)               # a fixed stuff bit before and every 4 bits after
        data_phase = 1 + 4 + 8 * n + (dynamic - arb_stuff) + 4 + crc + fixed + 1
        return arb + arb_stuff + _EOF_IFS, data_phase

    def frame_time(self, arbitration_id: int, data: bytes, is_fd: bool = False, extended: bool = False) -> float:
        """Wire time (s) of one data frame."""
        if is_fd:
            if not self.fd:
                raise ValueError(f"frame 0x{arbitration_id:X} is CAN FD but the bus is classic CAN")
            nominal, fast = self.fd_bits(len(data), extended)
            return nominal / self.bitrate + fast / self.fast_bitrate
        return self.classic_bits(arbitration_id, data, extended) / self.bitrate

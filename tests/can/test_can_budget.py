"""Frame bit lengths against closed forms and an independent bit-level construction."""
from __future__ import annotations

import pytest

from firmware_sim.can_budget import BusTiming, _classic_stuffable_bits


@pytest.mark.parametrize("n", range(9))
def test_classic_worst_case_matches_davis_formula(n):
    # Davis, Burns, Bril, Lukkien (2007): standard frames 55 + 10 n bits, extended 80 + 10 n bits
    t = BusTiming(500_000)
    assert t.classic_bits(0x123, bytes(n)) == 55 + 10 * n
    assert t.classic_bits(0x1234567, bytes(n), extended=True) == 80 + 10 * n
    assert t.frame_time(0x123, bytes(n)) == pytest.approx((55 + 10 * n) / 500_000)


def _crc15_remainder(bits):
    reg = 0
    for b in bits:        # polynomial division of the whole message incl. its CRC: remainder 0
        reg = (reg << 1) | b
        if reg & 0x8000:
            reg ^= 0xC599
    return reg & 0x7FFF


def _stuff(bits):
    out, run, last = [], 0, None
    for b in bits:
        out.append(b)
        run = run + 1 if b == last else 1
        last = b
        if run == 5:
            out.append(1 - b)
            last, run = 1 - b, 1
    return out


def test_exact_stuffing_against_bit_level_construction(rng):
    exact = BusTiming(1_000_000, stuffing="exact")
    worst = BusTiming(1_000_000)
    for _ in range(200):
        n = int(rng.integers(0, 9))
        fid = int(rng.integers(0, 0x800))
        data = bytes(rng.integers(0, 256, n).tolist()) if rng.random() < 0.7 else bytes([0] * n)
        raw = _classic_stuffable_bits(fid, data, False)
        assert _crc15_remainder(raw) == 0                       # the CRC field is right
        wire = _stuff(raw)
        s = "".join(map(str, wire))
        assert "000000" not in s and "111111" not in s           # stuffed stream is legal
        bits = exact.classic_bits(fid, data)
        assert bits == len(wire) + 1 + 12                        # + CRC delimiter, ACK, EOF, IFS
        assert 47 + 8 * n <= bits <= worst.classic_bits(fid, data)


def test_fd_frame_lengths():
    t = BusTiming(500_000, fd=True, data_bitrate=2_000_000)
    nominal, fast = t.fd_bits(64)
    # Field by field: 17 arbitration bits + 4 stuff + 12 (ACK, delimiters, EOF, IFS) at 500 kbit/s;
    # ESI, DLC, 512 data bits, 129 dynamic stuff bits, stuff count 4, CRC-21, 7 fixed stuff bits,
    # CRC delimiter at 2 Mbit/s
    assert (nominal, fast) == (33, 1 + 4 + 512 + 129 + 4 + 21 + 7 + 1)
    assert t.frame_time(0x302, bytes(64), is_fd=True) == pytest.approx(33 / 500e3 + 679 / 2e6)
    # within 1 % of the worst-case bound of Bordoloi & Samii (2014) for 64 data bytes: 32 + 28 + 5 + 10 n bits
    assert nominal + fast == pytest.approx(32 + 28 + 5 + 640, rel=0.01)
    assert t.fd_bits(8)[1] < t.fd_bits(16)[1] < t.fd_bits(20)[1]   # CRC-17 -> CRC-21 above 16 bytes
    # 64-byte FD frames move more than 5x the payload per second of 8-byte classic frames here
    classic = BusTiming(500_000).frame_time(0x301, bytes(8))
    assert (64 / t.frame_time(0x302, bytes(64), True)) / (8 / classic) > 5


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="max 8"):
        BusTiming(500_000).classic_bits(0x100, bytes(9))
    with pytest.raises(ValueError, match="classic CAN"):
        BusTiming(500_000).frame_time(0x100, bytes(64), is_fd=True)
    with pytest.raises(ValueError, match="valid CAN FD data length"):
        BusTiming(500_000, fd=True).fd_bits(13)
    with pytest.raises(ValueError, match="data_bitrate"):
        BusTiming(1_000_000, fd=True, data_bitrate=500_000)
    with pytest.raises(ValueError, match="positive"):
        BusTiming(0)

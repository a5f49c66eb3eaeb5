"""Checksums of the vendor frames, at C speed (no per-byte interpreter loop).

CRC-32/MPEG-2 (polynomial 0x04C11DB7, seed 0xFFFFFFFF, no reflection, no final XOR; check value 0x0376E6E7 for
``b"123456789"``) is what the STIM300 and the KVH 1750/1775 append. It is zlib's reflected CRC-32 seen in a
mirror: reflect every input byte, run zlib's CRC-32, reflect the 32-bit result and undo zlib's final XOR.
"""
from __future__ import annotations

import zlib

import numpy as np

_REFLECT8 = bytes(int(f"{b:08b}"[::-1], 2) for b in range(256))


def crc32_mpeg2(data: bytes | bytearray | memoryview) -> int:
    """CRC-32/MPEG-2 of ``data``."""
    reflected = zlib.crc32(bytes(data).translate(_REFLECT8))
    return int(f"{reflected:032b}"[::-1], 2) ^ 0xFFFFFFFF


def sum8(data: bytes | bytearray | memoryview) -> int:
    """The low byte of the sum of the bytes (the Xsens checksum makes the sum over BID … checksum 0)."""
    return sum(data) & 0xFF


def xor8(data: bytes | bytearray | memoryview) -> int:
    """The XOR of the bytes."""
    return int(np.bitwise_xor.reduce(np.frombuffer(bytes(data), np.uint8), initial=0))

"""The serial frame of the RS-422 link (protocol/README.md documents it byte by byte).

Little-endian, self-synchronising::

    offset size  field
    0      2     sync word 0xAA 0x55
    2      1     protocol version (1)
    3      1     message type (1 = IMU increments; 2 = aiding, reserved; others: counted, skipped)
    4      2     payload length N (u16)
    6      2     sequence counter (u16, +1 per frame, wraps)
    8      8     timestamp (u64, ns on the IMU clock, end of the sample interval)
    16     2     header check: the low 16 bits of CRC-32 of bytes 2 .. 15
    18     N     payload
    18+N   4     CRC-32 (zlib / IEEE 802.3) of bytes 2 .. 18+N-1 (everything after the sync word)

The header check lets the decoder reject a false sync word at once: without it a corrupt length
field would make it wait for up to a maximal frame of bytes before the CRC could say no, and
the good frames behind it would be late.

IMU payload (type 1, N = 28): Δθ x, y, z as i32 in units of 2⁻³¹ rad, Δv x, y, z as i32 in units
of 2⁻²⁴ m/s (body axes Right-Front-Up), then a u32 status / built-in-test word (0 = healthy).

:class:`FrameDecoder` takes bytes in any pieces, finds frames, and counts what it drops.
"""
from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field

import numpy as np

from .counters import Counters
from .sequence import SequenceTracker

SYNC = b"\xaa\x55"
VERSION = 1
HEADER = struct.Struct("<2sBBHHQH")
CRC = struct.Struct("<I")
MSG_IMU = 1
MSG_AIDING = 2
IMU_PAYLOAD = struct.Struct("<6iI")
DTHETA_LSB_RAD = 2.0**-31
DV_LSB_MPS = 2.0**-24
INT32_MAX = 2**31 - 1
MAX_PAYLOAD = 1024
"""Longest payload any message type may declare; a longer length field is a corrupt header."""
PAYLOAD_SIZES = {MSG_IMU: IMU_PAYLOAD.size}


STATUS_GYRO_FAULT = 1 << 0
STATUS_ACC_FAULT = 1 << 1
STATUS_SATURATED = 1 << 2
"""Status word bits the IMU sets; any non-zero word marks the sample unhealthy."""


@dataclass(frozen=True, slots=True)
class Frame:
    msg_type: int
    seq: int
    time_ns: int
    payload: bytes


@dataclass(frozen=True, slots=True)
class ImuMessage:
    """One IMU sample: t (s), Δθ (3,) rad, Δv (3,) m/s, status word, and whether a value hit full scale."""

    t: float
    dtheta: tuple[float, float, float]
    dv: tuple[float, float, float]
    status: int
    saturated: bool


def encode_frame(msg_type: int, seq: int, time_ns: int, payload: bytes) -> bytes:
    """A complete frame (sync word to CRC)."""
    head = struct.pack("<BBHHQ", VERSION, msg_type, len(payload), seq & 0xFFFF, time_ns)
    body = head + struct.pack("<H", zlib.crc32(head) & 0xFFFF) + payload
    return SYNC + body + CRC.pack(zlib.crc32(body))


def quantise_imu(dtheta: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Increments as the wire's integers (rounded, clipped to full scale): (N, 3) int64 each."""
    limit = (-INT32_MAX, INT32_MAX)
    return (np.clip(np.rint(np.asarray(dtheta) / DTHETA_LSB_RAD), *limit).astype(np.int64),
            np.clip(np.rint(np.asarray(dv) / DV_LSB_MPS), *limit).astype(np.int64))


def encode_imu(seq: int, t: float, dtheta: np.ndarray, dv: np.ndarray, status: int = 0) -> bytes:
    """An IMU frame for one sample: t (s), Δθ (3,) rad, Δv (3,) m/s."""
    qa, qv = quantise_imu(np.reshape(dtheta, (1, 3)), np.reshape(dv, (1, 3)))
    payload = IMU_PAYLOAD.pack(*(int(v) for v in qa[0]), *(int(v) for v in qv[0]), status)
    return encode_frame(MSG_IMU, seq, time_ns_of(t), payload)


def time_ns_of(t: float) -> int:
    return round(t * 1e9)


def decode_imu(frame: Frame) -> ImuMessage:
    """The IMU message of a type-1 frame (its length was checked by the decoder)."""
    *values, status = IMU_PAYLOAD.unpack(frame.payload)
    saturated = any(abs(v) >= INT32_MAX for v in values)
    return ImuMessage(frame.time_ns * 1e-9, tuple(v * DTHETA_LSB_RAD for v in values[:3]),
                      tuple(v * DV_LSB_MPS for v in values[3:]), status, saturated)


@dataclass(slots=True)
class DecoderCounters(Counters):
    """What the decoder saw: good frames and every kind of drop."""

    frames: int = 0
    bytes_skipped: int = 0       # bytes outside any frame (garbage, resynchronisation)
    bad_header: int = 0          # a sync word whose header check fails (false sync, corrupt header)
    bad_crc: int = 0
    bad_length: int = 0          # a length field no message type allows
    bad_version: int = 0
    unknown_type: int = 0        # well-formed frames of a type this daemon does not handle (not dropped)



@dataclass(slots=True)
class FrameDecoder:
    """Stream decoder: ``feed`` bytes in any pieces, get the complete, valid, in-sequence frames.

    Resynchronises on the sync word after garbage; a frame with a bad CRC, version or length is
    dropped by skipping its first sync byte, so a real frame hidden inside it is still found.
    Memory is bounded: the buffer never holds more than one maximal frame plus the last piece.
    """

    counters: DecoderCounters = field(default_factory=DecoderCounters)
    sequence: SequenceTracker = field(default_factory=SequenceTracker)
    _buffer: bytearray = field(default_factory=bytearray)

    def feed(self, data: bytes) -> list[Frame]:
        self._buffer += data
        frames: list[Frame] = []
        buf = self._buffer
        pos = 0
        while True:
            start = buf.find(SYNC, pos)
            if start < 0:
                # keep a trailing 0xAA: it may be the first half of a sync word
                keep = 1 if buf.endswith(SYNC[:1]) else 0
                self.counters.bytes_skipped += len(buf) - pos - keep
                pos = len(buf) - keep
                break
            self.counters.bytes_skipped += start - pos
            pos = start
            if len(buf) - pos < HEADER.size:
                break
            _, version, msg_type, length, seq, time_ns, check = HEADER.unpack_from(buf, pos)
            if zlib.crc32(memoryview(buf)[pos + 2:pos + HEADER.size - 2]) & 0xFFFF != check:
                self.counters.bad_header += 1
                pos += 1
                continue
            if version != VERSION:
                self.counters.bad_version += 1
                pos += 1
                continue
            if length > MAX_PAYLOAD or PAYLOAD_SIZES.get(msg_type, length) != length:
                self.counters.bad_length += 1
                pos += 1
                continue
            end = pos + HEADER.size + length + CRC.size
            if len(buf) < end:
                break
            (crc,) = CRC.unpack_from(buf, end - CRC.size)
            if zlib.crc32(memoryview(buf)[pos + 2:end - CRC.size]) != crc:
                self.counters.bad_crc += 1
                pos += 1
                continue
            frame = Frame(msg_type, seq, time_ns, bytes(buf[pos + HEADER.size:end - CRC.size]))
            pos = end
            if self.sequence.accept(seq):
                if msg_type not in PAYLOAD_SIZES:
                    self.counters.unknown_type += 1
                self.counters.frames += 1
                frames.append(frame)
        del buf[:pos]
        return frames

    def all_counters(self) -> dict[str, int]:
        """Decoder and sequence counters in one map (the status topic's names)."""
        return {**self.counters.as_dict(), **self.sequence.counters()}

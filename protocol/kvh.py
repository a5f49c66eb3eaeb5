"""KVH 1750 and 1775 IMU binary output (docs/imu-formats.md, "KVH 1750 and 1775").

Big-endian frames that begin FE 81 FF and a format byte: the 1750's 36 bytes (FE 81 FF 55: Δθ x, y, z and
acceleration x, y, z as float32, status, sequence number, temperature i16, CRC) and the 1775's type C, 38 bytes
(FE 81 FF 57: the same floats, one float that by sequence number mod 4 is the temperature or magnetometer x, y, z,
status, sequence, CRC). The CRC is CRC-32/MPEG-2 of every byte before it, header included. Values are in the
sensor's axes (its label's x, y, z): gyros set to delta angles (rad per sample: =ROTFMT,DELTA and =ROTUNITS,RAD),
accelerometers in g averaged over the sample, so Δv = a · 9.80665 m/s² / rate. The temperature and magnetometer
values are not decoded. The sequence number runs 0–127. Each status bit says one axis is valid (gyros bits 0–2,
accelerometers bits 4–6): a sample's status is the bits of the axes not valid (0: all valid).
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .counters import Counters, count
from .crc import crc32_mpeg2
from .framing import next_sync
from .vendor import SensorSamples

STANDARD_GRAVITY = 9.80665
"""m/s² per g, the unit of the accelerometer output."""
SYNC = b"\xfe\x81\xff"
"""The header's first three bytes; the fourth names the format."""
SEQUENCE_MODULUS = 128
VALID_BITS = 0x77
"""The status bits of a healthy sensor: gyro x, y, z (bits 0–2), accelerometer x, y, z (bits 4–6)."""
_VALUES = struct.Struct(">6f")   # Δθ x, y, z (rad), acceleration x, y, z (g) from byte 4
_CRC = struct.Struct(">I")


@dataclass(frozen=True, slots=True)
class KvhFormat:
    """One model's frame: its format byte (the header's fourth), size (header to CRC) and where the status byte
    is (the sequence number follows it)."""

    model: str
    format_byte: int
    size: int
    status_at: int
    name: str


KVH_FORMATS = {"1750": KvhFormat("1750", 0x55, 36, 28, "1750 frames (FE 81 FF 55)"),
               "1775": KvhFormat("1775", 0x57, 38, 32, "1775 type C frames (FE 81 FF 57)")}
"""The frame of each model."""
_BY_FORMAT_BYTE = {f.format_byte: f for f in KVH_FORMATS.values()}


def _crc_ok(buf: bytearray, pos: int, fmt: KvhFormat) -> bool:
    end = pos + fmt.size - _CRC.size
    return crc32_mpeg2(memoryview(buf)[pos:end]) == _CRC.unpack_from(buf, end)[0]


@dataclass(slots=True)
class KvhCounters(Counters):
    """What the KVH decoder saw."""

    frames: int = count("valid frames of the configured model")
    bytes_skipped: int = count("bytes outside any frame (garbage, resynchronisation)")
    bad_crc: int = count("frames of the configured model whose CRC fails")
    bad_sequence: int = count("frames (valid CRC) whose sequence number is beyond 0–127 (dropped)")
    bad_value: int = count("frames (valid CRC) holding a gyro or accelerometer value that is not a finite number "
                           "(dropped)")
    wrong_format: int = count("whole frames (valid CRC) of the other KVH model's format than imu.format (dropped)")


@dataclass(slots=True)
class KvhDecoder:
    """KVH ``model`` ("1750" or "1775") frames from a sensor sampling at ``rate_hz`` → samples: Δθ (rad) and Δv
    (m/s) in sensor axes, the sequence number and the status (the bits of the axes not valid; 0: healthy).

    Memory is bounded: the buffer holds at most one frame plus the last piece."""

    model: str
    rate_hz: float
    counter_modulus: ClassVar[int] = SEQUENCE_MODULUS
    counter_step: ClassVar[int] = 1
    tick_s: float = field(init=False)
    counts: KvhCounters = field(default_factory=KvhCounters)
    _format: KvhFormat = field(init=False)
    _told: bool = False
    _buffer: bytearray = field(default_factory=bytearray)

    def __post_init__(self) -> None:
        self._format = KVH_FORMATS[self.model]
        self.tick_s = 1.0 / self.rate_hz

    def feed(self, data: bytes) -> SensorSamples:
        """The samples of the frames ``data`` completes (bytes in any pieces)."""
        buf = self._buffer
        buf += data
        rows, notices = [], []
        pos = 0
        while True:
            pos, skipped, found = next_sync(buf, pos, SYNC)
            self.counts.bytes_skipped += skipped
            if not found:
                break
            if len(buf) - pos <= len(SYNC):
                break
            fmt = _BY_FORMAT_BYTE.get(buf[pos + len(SYNC)])
            if fmt is None:   # another message (a built-in test result) or garbage
                self.counts.bytes_skipped += 1
                pos += 1
                continue
            if len(buf) - pos < fmt.size:
                break
            if not _crc_ok(buf, pos, fmt):
                if fmt is self._format:
                    self.counts.bad_crc += 1
                self.counts.bytes_skipped += 1
                pos += 1
                continue
            if fmt is self._format:
                self._take(buf, pos, rows)
            else:
                self.counts.wrong_format += 1
                if not self._told:
                    self._told = True
                    notices.append(f"KVH sends {fmt.name} but imu.format is kvh{self.model}: set it to "
                                   f"kvh{fmt.model}")
            pos += fmt.size
        del buf[:pos]
        return SensorSamples.of(rows, notices)

    def _take(self, buf: bytearray, pos: int, rows: list) -> None:
        """The sample of the valid frame at ``pos``, unless it holds what no sensor sends."""
        values = _VALUES.unpack_from(buf, pos + 4)
        status, sequence = buf[pos + self._format.status_at], buf[pos + self._format.status_at + 1]
        if sequence >= SEQUENCE_MODULUS:
            self.counts.bad_sequence += 1
        elif not all(math.isfinite(v) for v in values):
            self.counts.bad_value += 1
        else:
            self.counts.frames += 1
            g_dt = STANDARD_GRAVITY / self.rate_hz
            rows.append((sequence, values[:3], tuple(a * g_dt for a in values[3:]), ~status & VALID_BITS))

    def counters(self) -> dict[str, int]:
        return self.counts.as_dict()


@dataclass(slots=True)
class KvhEncoder:
    """The bench's KVH ``model``: frames for samples at ``rate_hz``, values rounded to float32 as the sensor sends
    them; temperature and magnetometer read 0. Sample ``index`` carries sequence number ``index`` mod 128;
    ``status`` is the bits of the axes to mark not valid (of :data:`VALID_BITS`)."""

    model: str
    rate_hz: float
    _format: KvhFormat = field(init=False)

    def __post_init__(self) -> None:
        self._format = KVH_FORMATS[self.model]

    def encode(self, index: int, dtheta: np.ndarray, dv: np.ndarray, status: int = 0) -> bytes:
        """One frame: Δθ (3,) rad and Δv (3,) m/s in sensor axes."""
        fmt = self._format
        out = bytearray(fmt.size)
        out[:4] = SYNC + bytes([fmt.format_byte])
        acc_g = np.asarray(dv, dtype=float) * self.rate_hz / STANDARD_GRAVITY
        _VALUES.pack_into(out, 4, *np.asarray(dtheta, dtype=float), *acc_g)
        out[fmt.status_at] = VALID_BITS & ~status
        out[fmt.status_at + 1] = index % SEQUENCE_MODULUS
        _CRC.pack_into(out, fmt.size - _CRC.size, crc32_mpeg2(out[:fmt.size - _CRC.size]))
        return bytes(out)

"""Sensonor STIM300 normal-mode datagrams (incremental angle and velocity output), docs/imu-formats.md "STIM300".

A datagram is its identifier byte, then per sensor group (gyros, accelerometers, inclinometers, as the identifier
says) three 24-bit big-endian two's complement fields X, Y, Z and a status byte, then (0xA4–0xA7) per group three
16-bit temperatures and a status byte, then the counter (u8, 2000 ticks per second), the latency (u16, µs; not
used) and CRC-32/MPEG-2 over the datagram up to the CRC plus zero dummy bytes to a multiple of 4 bytes. Values are
in the sensor's own axes (its housing labels x, y, z): Δθ from the gyros' incremental angle (°/sample, LSB 2⁻²¹°),
Δv from the accelerometers' incremental velocity (m/s/sample, LSB by the accelerometer variant). The sensor can end
each datagram with CR LF (its line termination setting): the decoder takes a CR LF after a datagram with or
without it.

There is no sync word: the decoder looks for an identifier byte and takes the datagram when its CRC holds,
else moves on one byte.
"""
from __future__ import annotations

import re
import struct
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .counters import Counters, count
from .crc import crc32_mpeg2
from .vendor import SensorSamples

STIM300_CONTENT = {0x90: ("rate",), 0x91: ("rate", "acc"), 0x92: ("rate", "incl"), 0x93: ("rate", "acc", "incl"),
                   0xA4: ("rate",), 0xA5: ("rate", "acc"), 0xA6: ("rate", "incl"), 0xA7: ("rate", "acc", "incl")}
"""The sensor groups each normal-mode datagram carries; 0xA4–0xA7 add the groups' temperatures."""
STIM300_DATAGRAMS = tuple(STIM300_CONTENT)
"""Normal-mode datagram identifiers."""
STIM300_DV_LSB = {5: 2.0**-23, 10: 2.0**-22, 30: 2.0**-21, 80: 2.0**-19}
"""Incremental velocity LSB (m/s) by accelerometer variant (g)."""
DTHETA_LSB_DEG = 2.0**-21
"""Incremental angle LSB (°)."""
TICK_HZ = 2000
"""Counter ticks per second."""
CRLF = b"\r\n"
FIELD_MAX = 2**23 - 1
_I24X3 = struct.Struct(">bHbHbH")   # three 24-bit fields, each a signed high byte and an unsigned low 16 bits
_CRC = struct.Struct(">I")


def content_name(datagram: int) -> str:
    """What a datagram carries, as the datasheet's table names it ("rate, acc, incl, temperatures")."""
    return ", ".join(STIM300_CONTENT[datagram] + (("temperatures",) if datagram >= 0xA4 else ()))


@dataclass(frozen=True, slots=True)
class Stim300Layout:
    """Where a datagram's fields are (byte offsets from its identifier) and its size, identifier to CRC."""

    datagram: int
    acc_at: int | None
    status_at: tuple[int, ...]
    counter_at: int
    size: int

    @property
    def crc_at(self) -> int:
        return self.size - _CRC.size

    def crc_ok(self, buf: bytearray, pos: int) -> bool:
        """Whether the datagram at ``pos`` holds its CRC (over the datagram and the dummy bytes)."""
        body = bytes(buf[pos:pos + self.crc_at])
        return crc32_mpeg2(body + bytes(-len(body) % 4)) == _CRC.unpack_from(buf, pos + self.crc_at)[0]


def stim300_layout(datagram: int) -> Stim300Layout:
    """The layout of a normal-mode datagram (:data:`STIM300_DATAGRAMS`)."""
    groups = STIM300_CONTENT[datagram]
    at, offsets, status = 1, {}, []
    for group in groups:
        offsets[group] = at
        status.append(at + 9)
        at += 10
    if datagram >= 0xA4:
        for _ in groups:
            status.append(at + 6)
            at += 7
    return Stim300Layout(datagram, offsets.get("acc"), tuple(status), at, at + 3 + _CRC.size)


def _scales(datagram: int, acc_range_g: int, rate_hz: float) -> tuple[Stim300Layout, float, int]:
    """The layout, the Δv LSB (m/s) and the counter ticks per sample; ValueError for what cannot be aligned."""
    if datagram not in STIM300_CONTENT:
        raise ValueError(f"STIM300 datagram {datagram:#04x} is not a normal-mode datagram")
    layout = stim300_layout(datagram)
    if layout.acc_at is None:
        raise ValueError(f"STIM300 datagram {datagram:#04x} ({content_name(datagram)}) carries no accelerometers: "
                         "an alignment needs them (0x91, 0x93, 0xA5 or 0xA7)")
    if acc_range_g not in STIM300_DV_LSB:
        raise ValueError(f"STIM300 accelerometer variant {acc_range_g} g unknown (one of {list(STIM300_DV_LSB)})")
    return layout, STIM300_DV_LSB[acc_range_g], round(TICK_HZ / rate_hz)


@dataclass(slots=True)
class Stim300Counters(Counters):
    """What the STIM300 decoder saw."""

    frames: int = count("valid datagrams of the configured identifier")
    bytes_skipped: int = count("bytes outside any datagram (garbage, resynchronisation)")
    bad_crc: int = count("the configured identifier byte without a valid datagram behind it (a corrupt datagram, "
                         "or the byte in garbage)")
    wrong_datagram: int = count("whole datagrams (valid CRC) of another normal-mode identifier than "
                                "imu.stim300.datagram (dropped)")


@dataclass(slots=True)
class Stim300Decoder:
    """STIM300 datagrams of identifier ``datagram`` from a sensor of accelerometer variant ``acc_range_g`` (g)
    sampling at ``rate_hz`` → samples: Δθ (rad) and Δv (m/s) in sensor axes, the counter (u8, 2000 ticks per
    second) and the datagram's status bytes (the first, the gyros', in the low byte; 0: healthy).

    Memory is bounded: the buffer holds at most one datagram of the longest layout plus the last piece."""

    rate_hz: float
    datagram: int = 0x93
    acc_range_g: int = 10
    counter_modulus: ClassVar[int] = 256
    tick_s: ClassVar[float] = 1.0 / TICK_HZ
    counter_step: int = field(init=False)
    counts: Stim300Counters = field(default_factory=Stim300Counters)
    _layout: Stim300Layout = field(init=False)
    _dv_lsb_mps: float = field(init=False)
    _layouts: dict[int, Stim300Layout] = field(init=False)
    _told: set[int] = field(default_factory=set)   # wrong identifiers already noticed
    _after_datagram: bool = False   # a CR LF may follow
    _buffer: bytearray = field(default_factory=bytearray)

    def __post_init__(self) -> None:
        self._layout, self._dv_lsb_mps, self.counter_step = _scales(self.datagram, self.acc_range_g, self.rate_hz)
        self._layouts = {d: stim300_layout(d) for d in STIM300_DATAGRAMS}

    def feed(self, data: bytes) -> SensorSamples:
        """The samples of the datagrams ``data`` completes (bytes in any pieces)."""
        buf = self._buffer
        buf += data
        rows, notices = [], []
        pos = 0
        while True:
            if self._after_datagram:
                tail = bytes(buf[pos:pos + 2])
                if len(tail) < 2 and CRLF.startswith(tail):
                    break   # the line termination may still come
                self._after_datagram = False
                if tail == CRLF:
                    pos += 2
            found = _CANDIDATE.search(buf, pos)
            start = len(buf) if found is None else found.start()
            self.counts.bytes_skipped += start - pos
            pos = start
            if found is None:
                break
            layout = self._layouts[buf[pos]]
            if len(buf) - pos < layout.size:
                break
            if not layout.crc_ok(buf, pos):
                if layout.datagram == self.datagram:
                    self.counts.bad_crc += 1
                self.counts.bytes_skipped += 1
                pos += 1
                continue
            if layout.datagram == self.datagram:
                self.counts.frames += 1
                rows.append(self._sample(buf, pos))
            else:
                self.counts.wrong_datagram += 1
                if layout.datagram not in self._told:
                    self._told.add(layout.datagram)
                    notices.append(f"STIM300 sends datagram {layout.datagram:#04x} ({content_name(layout.datagram)}) "
                                   f"but imu.stim300.datagram is {self.datagram:#04x}: set it to "
                                   f"{layout.datagram:#04x}")
            pos += layout.size
            self._after_datagram = True
        del buf[:pos]
        return SensorSamples.of(rows, notices)

    def _sample(self, buf: bytearray, pos: int) -> tuple[int, tuple, tuple, int]:
        layout = self._layout
        gyro = _fields(buf, pos + 1)
        acc = _fields(buf, pos + layout.acc_at)
        status = int.from_bytes(bytes(buf[pos + at] for at in layout.status_at), "little")
        return (buf[pos + layout.counter_at], tuple(np.radians(np.multiply(gyro, DTHETA_LSB_DEG))),
                tuple(v * self._dv_lsb_mps for v in acc), status)

    def counters(self) -> dict[str, int]:
        return self.counts.as_dict()


_CANDIDATE = re.compile(b"[" + b"".join(re.escape(bytes([d])) for d in STIM300_DATAGRAMS) + b"]")
"""Any normal-mode identifier byte: where a datagram may begin."""


def _fields(buf: bytearray, at: int) -> tuple[int, int, int]:
    hx, lx, hy, ly, hz, lz = _I24X3.unpack_from(buf, at)
    return (hx << 16 | lx, hy << 16 | ly, hz << 16 | lz)


@dataclass(slots=True)
class Stim300Encoder:
    """The bench's STIM300: datagrams of identifier ``datagram`` for samples at ``rate_hz``, the fields rounded to
    the sensor's LSB and clipped to its 24-bit full scale; inclinometers, temperatures and latency read 0. Sample
    ``index`` carries counter ``index · 2000 / rate_hz`` (mod 256); ``status`` goes into the status bytes (the
    gyros' in the low byte)."""

    rate_hz: float
    datagram: int = 0x93
    acc_range_g: int = 10
    _layout: Stim300Layout = field(init=False)
    _dv_lsb_mps: float = field(init=False)
    _counter_step: int = field(init=False)

    def __post_init__(self) -> None:
        self._layout, self._dv_lsb_mps, self._counter_step = _scales(self.datagram, self.acc_range_g, self.rate_hz)

    def encode(self, index: int, dtheta: np.ndarray, dv: np.ndarray, status: int = 0) -> bytes:
        """One datagram: Δθ (3,) rad and Δv (3,) m/s in sensor axes."""
        layout = self._layout
        out = bytearray(layout.size)
        out[0] = self.datagram
        _put_fields(out, 1, np.degrees(np.asarray(dtheta, dtype=float)) / DTHETA_LSB_DEG)
        _put_fields(out, layout.acc_at, np.asarray(dv, dtype=float) / self._dv_lsb_mps)
        for k, at in enumerate(layout.status_at):
            out[at] = status >> (8 * k) & 0xFF
        out[layout.counter_at] = index * self._counter_step % 256
        body = bytes(out[:layout.crc_at])
        _CRC.pack_into(out, layout.crc_at, crc32_mpeg2(body + bytes(-len(body) % 4)))
        return bytes(out)


def _put_fields(out: bytearray, at: int, lsbs: np.ndarray) -> None:
    for k, value in enumerate(np.clip(np.rint(lsbs), -FIELD_MAX - 1, FIELD_MAX).astype(np.int64)):
        out[at + 3 * k:at + 3 * k + 3] = int(value).to_bytes(3, "big", signed=True)

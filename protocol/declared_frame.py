"""A fixed-length IMU frame declared field by field in ``[imu.frame]`` (docs/imu-formats.md, "Declared frame").

The frame is the sync bytes, then the fields in order, ``length`` bytes in all, every field in one byte order. A
field is ``"NAME TYPE [SCALE]"``: the SCALE (default 1) is what one unit of the raw value is worth:

- ``dtheta_x`` … ``dtheta_z``: the angle increment, rad after scaling; or ``gyro_x`` … ``gyro_z``: the rate, rad/s
  after scaling, taken over one sample period (× 1/rate_hz);
- ``dv_x`` … ``dv_z``: the velocity increment, m/s; or ``acc_x`` … ``acc_z``: the specific force, m/s², × 1/rate_hz;
- ``counter``: the sample counter (an integer type; it wraps at 2**bits); its SCALE, if given, is its tick in s,
  else one unit is one sample period;
- ``status``: the sensor's status bits (integer; 0 healthy); ``pad N``: N bytes skipped;
- ``checksum``: the checksum (integer) of the bytes from ``checksum_from`` up to the checksum field.

TYPE: ``i8`` ``i16`` ``i24`` ``i32`` ``i64``, ``u8`` … ``u64``, ``f32``, ``f64``. All axes are the sensor's own.
:meth:`FrameSpec.parse` turns the table into one :class:`struct.Struct` once; a table that does not add up is a
:class:`FrameSpecError` naming its key.
"""
from __future__ import annotations

import binascii
import math
import struct
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .counters import Counters, count
from .crc import crc32_mpeg2, sum8, xor8
from .framing import next_sync
from .vendor import SensorSamples

if TYPE_CHECKING:
    from ..service.config import Config, FrameConfig, ImuConfig

AXES = ("x", "y", "z")
INTEGER_TYPES = {f"{sign}{bits}": (sign == "i", bits // 8) for sign in "iu" for bits in (8, 16, 24, 32, 64)}
"""Integer TYPE → (signed, bytes)."""
FLOAT_CODES = {"f32": "f", "f64": "d"}
INTEGER_CODES = {1: "b", 2: "h", 4: "i", 8: "q"}
INCREMENTS = {"dtheta": "gyro", "dv": "acc"}
"""Each increment's name stem → that of the rate that gives it over one sample period."""
SINGLE_FIELDS = ("counter", "status", "checksum")


def _crc16_ccitt(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/CCITT-FALSE (polynomial 0x1021, seed 0xFFFF, no reflection, no final XOR; 0x29B1 for b"123456789")."""
    return binascii.crc_hqx(data, 0xFFFF)


CHECKSUMS: dict[str, tuple[Callable[[bytes | bytearray | memoryview], int], int]] = {
    "crc32": (zlib.crc32, 4), "crc32-mpeg2": (crc32_mpeg2, 4), "crc16-ccitt": (_crc16_ccitt, 2),
    "sum8": (sum8, 1), "xor8": (xor8, 1)}
"""Each ``checksum`` kind but none: its function and the checksum field's size in bytes."""


class FrameSpecError(ValueError):
    """An ``[imu.frame]`` table that does not describe a frame; ``key`` is the key at fault."""

    def __init__(self, key: str, message: str) -> None:
        super().__init__(message)
        self.key = key


@dataclass(frozen=True, slots=True)
class Field:
    """One declared field: its name, TYPE, SCALE (None: not given), offset in the frame (bytes) and index among
    the unpacked values."""

    name: str
    type: str
    scale: float | None
    offset: int
    index: int

    @property
    def size(self) -> int:
        return INTEGER_TYPES[self.type][1] if self.type in INTEGER_TYPES else int(self.type[1:]) // 8

    @property
    def factor(self) -> float:
        return 1.0 if self.scale is None else self.scale


@dataclass(frozen=True, slots=True)
class Checksum:
    """The frame's checksum: its function, the field's struct (at ``offset``) and the first byte covered."""

    function: Callable[[bytes | bytearray | memoryview], int]
    layout: struct.Struct
    offset: int
    first: int


@dataclass(frozen=True, slots=True)
class FrameSpec:
    """A parsed ``[imu.frame]``: the sync bytes, the frame's ``struct`` (the fields after the sync bytes), the
    increment fields in axis order with the factor that turns each raw value into rad or m/s, and the counter's
    wrap, tick and step."""

    sync: bytes
    length: int
    endian: str
    layout: struct.Struct
    fields: tuple[Field, ...]
    dtheta: tuple[tuple[Field, float], ...]
    dv: tuple[tuple[Field, float], ...]
    counter: Field
    status: Field | None
    checksum: Checksum | None
    counter_modulus: int
    tick_s: float
    counter_step: int

    @classmethod
    def parse(cls, frame: FrameConfig, rate_hz: float) -> FrameSpec:
        """The spec of ``frame`` at the sample rate ``rate_hz``; :class:`FrameSpecError` (one line, naming the key)
        if it does not add up."""
        try:
            sync = bytes.fromhex(frame.sync)
        except ValueError:
            raise FrameSpecError("sync", f"{frame.sync!r} is not hex bytes (\"A5 5A\")") from None
        if not sync:
            raise FrameSpecError("sync", "at least one sync byte is needed to find the frames")
        declared, codes, offset = _fields(frame.fields, len(sync))
        if offset != frame.length:
            sizes = " + ".join(str(f.size) for f in declared)
            raise FrameSpecError("length", f"{frame.length} bytes declared, but the sync bytes and fields make "
                                 f"{offset} ({len(sync)} + {sizes})")
        by_name = {f.name: f for f in declared}
        increments = {}
        for stem, rate_stem in INCREMENTS.items():
            axes = []
            for axis in AXES:
                names = (f"{stem}_{axis}", f"{rate_stem}_{axis}")
                got = [by_name[name] for name in names if name in by_name]
                if len(got) != 1:
                    raise FrameSpecError("fields", f"no {names[0]} or {names[1]}: each axis needs one" if not got
                                         else f"{names[0]} and {names[1]}: each axis takes one of them")
                f = got[0]
                axes.append((f, f.factor / rate_hz if f.name == names[1] else f.factor))
            increments[stem] = tuple(axes)
        counter = by_name.get("counter")
        if counter is None:
            raise FrameSpecError("fields", "no counter field: the samples are stamped from it")
        tick_s = 1.0 / rate_hz if counter.scale is None else counter.scale
        step = round(1.0 / (rate_hz * tick_s))
        if step < 1:
            raise FrameSpecError("fields", f"counter tick {tick_s:g} s is longer than the sample period "
                                 f"{1 / rate_hz:g} s")
        prefix = "<" if frame.endian == "little" else ">"
        return cls(sync, frame.length, frame.endian, struct.Struct(prefix + "".join(codes)), tuple(declared),
                   increments["dtheta"], increments["dv"], counter, by_name.get("status"),
                   _checksum(frame, by_name.get("checksum"), prefix), 1 << (8 * counter.size), tick_s, step)


def _fields(texts: tuple[str, ...], offset: int) -> tuple[list[Field], list[str], int]:
    """The declared fields (their offsets from ``offset``, the sync bytes' length), their struct codes and the
    frame's length."""
    declared, codes, seen = [], [], set()
    for text in texts:
        parts = text.split()
        if len(parts) not in (2, 3):
            raise FrameSpecError("fields", f"{text!r}: expected \"NAME TYPE [SCALE]\"")
        name, kind = parts[:2]
        if name == "pad":
            if not kind.isdigit() or not 1 <= int(kind) <= 1024 or len(parts) == 3:
                raise FrameSpecError("fields", f"{text!r}: expected \"pad N\" with N bytes (1–1024)")
            codes.append(f"{kind}x")
            offset += int(kind)
            continue
        stem, _, axis = name.partition("_")
        if name not in SINGLE_FIELDS and not ((stem in INCREMENTS or stem in INCREMENTS.values()) and axis in AXES):
            raise FrameSpecError("fields", f"{text!r}: unknown name {name!r} (dtheta_x…z, gyro_x…z, dv_x…z, "
                                 f"acc_x…z, counter, status, pad, checksum)")
        if name in seen:
            raise FrameSpecError("fields", f"{text!r}: {name} declared twice")
        seen.add(name)
        if kind not in INTEGER_TYPES and kind not in FLOAT_CODES:
            raise FrameSpecError("fields", f"{text!r}: unknown type {kind!r} (i8…i64, u8…u64, f32, f64)")
        if name in SINGLE_FIELDS and kind in FLOAT_CODES:
            raise FrameSpecError("fields", f"{text!r}: a {name} is an integer (i8…i64, u8…u64)")
        if name in ("counter", "status") and kind.endswith("64"):
            raise FrameSpecError("fields", f"{text!r}: a {name} has at most 32 bits")
        try:
            scale = float(parts[2]) if len(parts) == 3 else None
        except ValueError:
            raise FrameSpecError("fields", f"{text!r}: scale {parts[2]!r} is not a number") from None
        if scale is not None and not (math.isfinite(scale) and scale > 0.0):
            raise FrameSpecError("fields", f"{text!r}: the scale must be a finite number above 0")
        if name in ("status", "checksum") and scale is not None:
            raise FrameSpecError("fields", f"{text!r}: a {name} takes no scale")
        f = Field(name, kind, scale, offset, len(declared))
        codes.append(_code(kind))
        declared.append(f)
        offset += f.size
    return declared, codes, offset


def _code(kind: str) -> str:
    """The struct code of a TYPE; a 24-bit integer is unpacked as 3 bytes (converted by :func:`_value`)."""
    if kind in FLOAT_CODES:
        return FLOAT_CODES[kind]
    signed, size = INTEGER_TYPES[kind]
    if size == 3:
        return "3s"
    code = INTEGER_CODES[size]
    return code if signed else code.upper()


def _checksum(frame: FrameConfig, checksum: Field | None, prefix: str) -> Checksum | None:
    """The frame's checksum (its field's byte order ``prefix``); None: ``checksum = "none"``."""
    if frame.checksum == "none":
        if checksum is not None:
            raise FrameSpecError("checksum", "none, but a checksum field is declared")
        return None
    if frame.checksum not in CHECKSUMS:
        raise FrameSpecError("checksum", f"{frame.checksum!r} is not one of none, {', '.join(CHECKSUMS)}")
    function, size = CHECKSUMS[frame.checksum]
    if checksum is None:
        raise FrameSpecError("fields", f"checksum {frame.checksum} needs a checksum field (\"checksum u{8 * size}\")")
    if checksum.type != f"u{8 * size}":
        raise FrameSpecError("fields", f"checksum {frame.checksum} needs a field of type u{8 * size}, got "
                             f"{checksum.type}")
    if not 0 <= frame.checksum_from < checksum.offset:
        raise FrameSpecError("checksum_from", f"{frame.checksum_from} is not a byte before the checksum field (at "
                             f"{checksum.offset})")
    return Checksum(function, struct.Struct(prefix + _code(checksum.type)), checksum.offset, frame.checksum_from)


def _value(raw: int | float | bytes, f: Field, endian: str) -> int | float:
    """A field's unpacked value as a number (a 24-bit integer comes as 3 bytes)."""
    if isinstance(raw, bytes):
        return int.from_bytes(raw, endian, signed=INTEGER_TYPES[f.type][0])
    return raw


def _raw(value: float, f: Field, endian: str) -> int | float | bytes:
    """A number as the field's packed value: an integer rounded and clipped to the type's range (a 24-bit one as
    3 bytes)."""
    if f.type in FLOAT_CODES:
        return value
    signed, size = INTEGER_TYPES[f.type]
    low, high = (-(1 << (8 * size - 1)), (1 << (8 * size - 1)) - 1) if signed else (0, (1 << (8 * size)) - 1)
    number = min(max(round(value), low), high)
    return number.to_bytes(3, endian, signed=signed) if size == 3 else number


def _wrapped(value: int, f: Field) -> int:
    """An integer wrapped into the field's bits (two's complement for a signed type), as a counter wraps."""
    signed, size = INTEGER_TYPES[f.type]
    value %= 1 << (8 * size)
    return value - (1 << (8 * size)) if signed and value >= 1 << (8 * size - 1) else value


@dataclass(slots=True)
class FrameCounters(Counters):
    """What the declared-frame decoder saw."""

    frames: int = count("valid frames, in sequence")
    bytes_skipped: int = count("bytes outside any frame (garbage, resynchronisation)")
    bad_checksum: int = count("frames whose checksum fails")
    bad_value: int = count("frames holding an increment that is not a finite number (NaN, infinite: dropped)")


@dataclass(slots=True)
class DeclaredFrameDecoder:
    """Declared frames → :class:`~.vendor.SensorSamples` in the sensor's axes, on the frame's counter."""

    spec: FrameSpec
    counts: FrameCounters = field(default_factory=FrameCounters)
    _buffer: bytearray = field(default_factory=bytearray)

    @classmethod
    def from_config(cls, config: Config) -> DeclaredFrameDecoder:
        return cls(FrameSpec.parse(config.imu.frame, config.imu.rate_hz))

    @property
    def counter_modulus(self) -> int:
        return self.spec.counter_modulus

    @property
    def tick_s(self) -> float:
        return self.spec.tick_s

    @property
    def counter_step(self) -> int:
        return self.spec.counter_step

    def feed(self, data: bytes) -> SensorSamples:
        self._buffer += data
        spec, buf, pos = self.spec, self._buffer, 0
        endian, check = spec.endian, spec.checksum
        counters, statuses, values = [], [], []
        while True:
            pos, skipped, found = next_sync(buf, pos, spec.sync)
            self.counts.bytes_skipped += skipped
            if not found:
                break
            if len(buf) - pos < spec.length:
                break
            frame = bytes(buf[pos:pos + spec.length])
            if check is not None and check.function(frame[check.first:check.offset]) != check.layout.unpack_from(
                    frame, check.offset)[0]:
                self.counts.bad_checksum += 1
                pos += 1
                continue
            raw = spec.layout.unpack_from(frame, len(spec.sync))
            pos += spec.length
            counters.append(int(_value(raw[spec.counter.index], spec.counter, endian)) % spec.counter_modulus)
            statuses.append(0 if spec.status is None else int(_value(raw[spec.status.index], spec.status, endian)))
            values.append([_value(raw[f.index], f, endian) * factor for f, factor in spec.dtheta + spec.dv])
        del buf[:pos]
        increments = np.array(values, dtype=float).reshape(-1, 6)
        keep = np.isfinite(increments).all(axis=1)
        self.counts.bad_value += int((~keep).sum())
        self.counts.frames += int(keep.sum())
        return SensorSamples(np.array(counters, dtype=np.int64)[keep], increments[keep, :3], increments[keep, 3:],
                             np.array(statuses, dtype=np.int64)[keep])

    def counters(self) -> dict[str, int]:
        return self.counts.as_dict()


@dataclass(slots=True)
class DeclaredFrameEncoder:
    """The bench's IMU in a declared frame: frame k carries counter k × ``counter_step`` (wrapped), the increments
    quantised to the fields' types and scales."""

    spec: FrameSpec

    @classmethod
    def from_imu(cls, imu: ImuConfig) -> DeclaredFrameEncoder:
        return cls(FrameSpec.parse(imu.frame, imu.rate_hz))

    def encode(self, index: int, dtheta: np.ndarray, dv: np.ndarray, status: int = 0) -> bytes:
        """Sample ``index``'s frame: Δθ (3,) rad, Δv (3,) m/s in sensor axes, ``status`` wrapped into its field
        (dropped if the frame has none)."""
        spec = self.spec
        values: list[int | float | bytes] = [_raw(0, f, spec.endian) for f in spec.fields]
        for (f, factor), x in zip(spec.dtheta + spec.dv, np.concatenate((dtheta, dv)), strict=True):
            values[f.index] = _raw(float(x) / factor, f, spec.endian)
        wrapped = [(spec.counter, index * spec.counter_step)] + ([(spec.status, status)] if spec.status else [])
        for f, number in wrapped:
            values[f.index] = _raw(_wrapped(number, f), f, spec.endian)
        frame = bytearray(spec.sync + spec.layout.pack(*values))
        check = spec.checksum
        if check is not None:
            check.layout.pack_into(frame, check.offset, check.function(frame[check.first:check.offset]))
        return bytes(frame)

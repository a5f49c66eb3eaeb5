"""Xsens MTi MTData2 messages (message id 0x36) with DeltaQ, DeltaV and SampleTimeFine.

An Xbus message from the device::

    FA          preamble
    FF          bus id (the master device)
    MID         message id (0x36 MTData2; others: acknowledgements, errors, configuration)
    LEN         data length (u8); 0xFF: an extended length (u16, big-endian) follows
    DATA        LEN bytes
    CS          checksum: the low byte of the sum of every byte from the bus id through CS is 0

MTData2 data is a run of items, each an XDI (u16, big-endian), a size (u8) and that many bytes, every value
big-endian. The XDI's low two bits give the floating-point format (0 float32, 1 fp12.20, 2 fp16.32, 3 float64),
bits 2–3 the coordinate system of navigation-frame outputs (not of DeltaQ and DeltaV: those are in the sensor
axes). The decoder takes:

- DeltaQ (0x8030): the quaternion increment (w, x, y, z) over the sample interval, sensor axes; turned into the
  rotation vector Δθ = 2·atan2(|v|, w)·v/|v| (rad), exact at any angle.
- DeltaV (0x4010): the velocity increment (m/s) over the sample interval, sensor axes.
- SampleTimeFine (0x1060): u32 in 10 kHz ticks: the counter the samples are stamped from.
- StatusWord (0xE020, if present): u32; the clipping flags of the accelerometers and gyroscopes and the clipping
  indication (:data:`STATUS_FAULTS`) are the sample's status. The self-test and orientation-valid flags are set
  when good and are not supported by every unit (IMU-only models and the 600 series leave them 0): not mapped.

PacketCounter (0x1020) and every other item are skipped: SampleTimeFine counts the samples and the time between.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .counters import Counters, count
from .crc import sum8
from .framing import next_sync
from .vendor import SensorSamples

if TYPE_CHECKING:
    from ..service.config import Config, ImuConfig

PREAMBLE = 0xFA
BUS_ID = 0xFF
SYNC = bytes((PREAMBLE, BUS_ID))
MID_MTDATA2 = 0x36
EXTENDED_LENGTH = 0xFF
MAX_DATA = 2048
"""Longest data field decoded (bytes); a longer length field is taken for a corrupt one (bounds the buffer)."""

XDI_PACKET_COUNTER = 0x1020
XDI_SAMPLE_TIME_FINE = 0x1060
XDI_DELTA_V = 0x4010
XDI_DELTA_Q = 0x8030
XDI_STATUS_WORD = 0xE020
XDI_TYPE_MASK = 0xFFF0
XDI_FORMAT_MASK = 0x0003
FLOAT_FORMATS = {0x0: "f", 0x3: "d"}
"""The floating-point formats decoded, by the XDI's low two bits (float32, float64)."""
FORMAT_NAMES = {0x1: "fp12.20", 0x2: "fp16.32"}

SAMPLE_TIME_TICK_S = 1e-4
"""One SampleTimeFine tick (10 kHz)."""
STATUS_SELFTEST_OK = 1 << 0
STATUS_ORIENTATION_VALID = 1 << 1
STATUS_CLIP_ACC = 0x7 << 8
STATUS_CLIP_GYR = 0x7 << 11
STATUS_CLIPPING_DETECTED = 1 << 19
STATUS_FAULTS = STATUS_CLIP_ACC | STATUS_CLIP_GYR | STATUS_CLIPPING_DETECTED
"""The StatusWord bits that mark an increment as unhealthy: an accelerometer or gyroscope axis clipped (bits 8–13)
or clipping seen during the interval (bit 19)."""

NEEDED = {XDI_SAMPLE_TIME_FINE: "Timestamp > Sample Time Fine", XDI_DELTA_Q: "Angular Velocity > Delta q",
          XDI_DELTA_V: "Acceleration > Delta v"}
"""The outputs a message must hold, by XDI, with where MT Manager's Output Configuration enables them."""

_ITEM_HEAD = struct.Struct(">HB")
_U32 = struct.Struct(">I")


@dataclass(slots=True)
class XsensCounters(Counters):
    """What the MTData2 decoder saw."""

    frames: int = count("valid frames, in sequence")
    bytes_skipped: int = count("bytes outside any frame (garbage, resynchronisation)")
    bad_checksum: int = count("frames whose checksum fails")
    bad_length: int = count("a length field beyond any frame, or data items that overrun their message or hold "
                            "the wrong size for their format")
    other_messages: int = count("well-formed Xsens messages of another message id (skipped)")
    missing_output: int = count("MTData2 messages without SampleTimeFine, DeltaQ or DeltaV (dropped)")
    unsupported_format: int = count("MTData2 messages with DeltaQ or DeltaV in fixed point (dropped)")
    bad_value: int = count("frames holding an increment that is not a finite number (NaN, infinite: dropped)")


@dataclass(slots=True)
class XsensDecoder:
    """MTData2 messages → :class:`~.vendor.SensorSamples` in the sensor's axes, counter SampleTimeFine (u32, 100 µs
    ticks; ``counter_step`` ticks per sample at the configured rate)."""

    counter_step: int
    counter_modulus: int = 1 << 32
    tick_s: float = SAMPLE_TIME_TICK_S
    counts: XsensCounters = field(default_factory=XsensCounters)
    _buffer: bytearray = field(default_factory=bytearray)

    @classmethod
    def from_config(cls, config: Config) -> XsensDecoder:
        return cls(counter_step_of(config.imu.rate_hz))

    def feed(self, data: bytes) -> SensorSamples:
        self._buffer += data
        buf, pos = self._buffer, 0
        rows: list[tuple[int, tuple[float, ...], tuple[float, ...], int]] = []
        notices: dict[str, None] = {}
        while True:
            pos, skipped, found = next_sync(buf, pos, SYNC)
            self.counts.bytes_skipped += skipped
            if not found:
                break
            if len(buf) - pos < 4:
                break
            mid, length, head = buf[pos + 2], buf[pos + 3], 4
            if length == EXTENDED_LENGTH:
                if len(buf) - pos < 6:
                    break
                length, head = buf[pos + 4] << 8 | buf[pos + 5], 6
            if length > MAX_DATA:
                self.counts.bad_length += 1
                pos += 1
                continue
            end = pos + head + length + 1
            if len(buf) < end:
                break
            if sum8(buf[pos + 1:end]):
                self.counts.bad_checksum += 1
                pos += 1
                continue
            message = bytes(buf[pos + head:end - 1])
            pos = end
            if mid != MID_MTDATA2:
                self.counts.other_messages += 1
                continue
            row = self._sample(message, notices)
            if row is not None:
                rows.append(row)
        del buf[:pos]
        return _samples(rows, list(notices), self.counts)

    def _sample(self, data: bytes, notices: dict[str, None]
                ) -> tuple[int, tuple[float, ...], tuple[float, ...], int] | None:
        """(SampleTimeFine, DeltaQ (w, x, y, z), DeltaV (3,) m/s, status) of one MTData2 message; None: dropped
        (counted, with a line for the operator in ``notices``)."""
        items = _items(data)
        if items is None:
            self.counts.bad_length += 1
            return None
        missing = [where for xdi, where in NEEDED.items() if xdi not in items]
        if missing:
            self.counts.missing_output += 1
            notices[f"Xsens MTData2 without {', '.join(missing)}: enable it in MT Manager (Device Settings > "
                    f"Output Configuration); messages dropped"] = None
            return None
        fixed = [FORMAT_NAMES[xdi & XDI_FORMAT_MASK] for xdi in (items[XDI_DELTA_Q][0], items[XDI_DELTA_V][0])
                 if xdi & XDI_FORMAT_MASK in FORMAT_NAMES]
        if fixed:
            self.counts.unsupported_format += 1
            notices[f"Xsens DeltaQ/DeltaV in {fixed[0]}: set Float32 or Float64 in MT Manager's Output "
                    f"Configuration; messages dropped"] = None
            return None
        dq, dv = _floats(*items[XDI_DELTA_Q], 4), _floats(*items[XDI_DELTA_V], 3)
        stf = _u32(items[XDI_SAMPLE_TIME_FINE][1])
        word = _u32(items[XDI_STATUS_WORD][1]) if XDI_STATUS_WORD in items else 0
        if dq is None or dv is None or stf is None or word is None:
            self.counts.bad_length += 1
            return None
        return stf, dq, dv, word & STATUS_FAULTS

    def counters(self) -> dict[str, int]:
        return self.counts.as_dict()


def counter_step_of(rate_hz: float) -> int:
    """SampleTimeFine ticks per sample at ``rate_hz``."""
    return max(round(1.0 / (rate_hz * SAMPLE_TIME_TICK_S)), 1)


def _items(data: bytes) -> dict[int, tuple[int, bytes]] | None:
    """The data items of an MTData2 message by XDI type (format bits cleared): (full XDI, payload); None: an item
    overruns the message."""
    items, at = {}, 0
    while at < len(data):
        if at + _ITEM_HEAD.size > len(data):
            return None
        xdi, size = _ITEM_HEAD.unpack_from(data, at)
        at += _ITEM_HEAD.size + size
        if at > len(data):
            return None
        items[xdi & XDI_TYPE_MASK] = (xdi, data[at - size:at])
    return items


def _floats(xdi: int, payload: bytes, n: int) -> tuple[float, ...] | None:
    """``n`` big-endian floats in the XDI's format; None: the payload does not hold them."""
    code = f">{n}{FLOAT_FORMATS[xdi & XDI_FORMAT_MASK]}"
    return struct.unpack(code, payload) if len(payload) == struct.calcsize(code) else None


def _u32(payload: bytes) -> int | None:
    return _U32.unpack(payload)[0] if len(payload) == _U32.size else None


def _samples(rows: list[tuple[int, tuple[float, ...], tuple[float, ...], int]], notices: list[str],
               counts: XsensCounters) -> SensorSamples:
    """Rows of (counter, DeltaQ, DeltaV, status) as samples: Δθ from DeltaQ; a row with a NaN or infinite value
    counted as ``bad_value`` and dropped (finite absurd values are the sample gate's)."""
    counter = np.array([r[0] for r in rows], dtype=np.int64)
    dq = np.array([r[1] for r in rows], dtype=float).reshape(-1, 4)
    dv = np.array([r[2] for r in rows], dtype=float).reshape(-1, 3)
    status = np.array([r[3] for r in rows], dtype=np.int64)
    keep = np.isfinite(dq).all(axis=1) & np.isfinite(dv).all(axis=1)
    counts.bad_value += int((~keep).sum())
    counts.frames += int(keep.sum())
    return SensorSamples(counter[keep], rotation_vector(dq[keep]), dv[keep], status[keep], notices)


def rotation_vector(q: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) rad of quaternions (N, 4) (w, x, y, z; any norm, finite): 2·atan2(|v|, w)·v/|v|,
    with q and -q the same rotation (the angle kept within ±π); a zero quaternion gives no rotation."""
    biggest = np.abs(q).max(axis=1, initial=0.0)[:, None]
    q = np.where(q[:, :1] < 0, -q, q) / np.where(biggest > 0, biggest, 1.0)   # scaled: |v| cannot overflow
    norm = np.linalg.norm(q[:, 1:], axis=1)
    angle = 2.0 * np.arctan2(norm, q[:, 0])
    return q[:, 1:] * np.where(norm > 0, angle / np.where(norm > 0, norm, 1.0), 0.0)[:, None]


def quaternion_of(dtheta: np.ndarray) -> np.ndarray:
    """The quaternion (w, x, y, z) of a rotation vector (3,) rad."""
    angle = float(np.linalg.norm(dtheta))
    if angle == 0.0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    return np.concatenate(([np.cos(angle / 2)], np.sin(angle / 2) * np.asarray(dtheta) / angle))


def xbus_message(mid: int, data: bytes) -> bytes:
    """A whole Xbus message to the master's bus id: preamble to checksum, the extended length when needed."""
    length = bytes((len(data),)) if len(data) < EXTENDED_LENGTH else bytes((EXTENDED_LENGTH,)) + struct.pack(
        ">H", len(data))
    body = bytes((BUS_ID, mid)) + length + data
    return bytes((PREAMBLE,)) + body + bytes(((-sum8(body)) & 0xFF,))


def data_item(xdi: int, payload: bytes) -> bytes:
    """One MTData2 data item."""
    return _ITEM_HEAD.pack(xdi, len(payload)) + payload


@dataclass(slots=True)
class XsensEncoder:
    """The bench's MTi: MTData2 with PacketCounter, SampleTimeFine (``counter_step`` ticks per sample), DeltaQ and
    DeltaV as float32 and a StatusWord, in the sensor's axes."""

    counter_step: int

    @classmethod
    def from_imu(cls, imu: ImuConfig) -> XsensEncoder:
        return cls(counter_step_of(imu.rate_hz))

    def encode(self, index: int, dtheta: np.ndarray, dv: np.ndarray, status: int = 0) -> bytes:
        """Sample ``index``'s message: Δθ (3,) rad, Δv (3,) m/s; ``status`` 0 healthy, else its clipping bits
        (:data:`STATUS_FAULTS`) or, holding none, the clipping indication."""
        word = STATUS_SELFTEST_OK | STATUS_ORIENTATION_VALID
        if status:
            word |= status & STATUS_FAULTS or STATUS_CLIPPING_DETECTED
        data = (data_item(XDI_PACKET_COUNTER, struct.pack(">H", index & 0xFFFF))
                + data_item(XDI_SAMPLE_TIME_FINE, _U32.pack(index * self.counter_step & 0xFFFFFFFF))
                + data_item(XDI_DELTA_Q, struct.pack(">4f", *quaternion_of(dtheta)))
                + data_item(XDI_DELTA_V, struct.pack(">3f", *np.asarray(dv, dtype=float)))
                + data_item(XDI_STATUS_WORD, _U32.pack(word)))
        return xbus_message(MID_MTDATA2, data)

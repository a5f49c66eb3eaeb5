"""The serial frame of the RS-422 link (protocol/README.md documents it byte by byte).

Little-endian, self-synchronising::

    offset size  field
    0      2     sync word 0xAA 0x55
    2      1     protocol version (1)
    3      1     message type (1 = IMU increments; 2 = aiding epoch; others: counted, passed on)
    4      2     payload length N (u16)
    6      2     sequence counter (u16, +1 per frame of the same type, wraps; one counter per type, and
                 for aiding frames one per aiding kind)
    8      8     timestamp (u64, ns on the IMU clock: end of the sample interval / instant of the aiding epoch)
    16     2     header check: the low 16 bits of CRC-32 of bytes 2 .. 15
    18     N     payload
    18+N   4     CRC-32 (zlib / IEEE 802.3) of bytes 2 .. 18+N-1 (everything after the sync word)

The header check lets the decoder reject a false sync word at once: without it a corrupt length
field would make it wait for up to a maximal frame of bytes before the CRC could say no, and
the good frames behind it would be late.

IMU payload (type 1, N = 28): Δθ x, y, z as i32 in units of 2⁻³¹ rad, Δv x, y, z as i32 in units
of 2⁻²⁴ m/s (body axes Right-Front-Up), then a u32 status / built-in-test word (0 = healthy).

Aiding payload (type 2, N = 1 + 8 n): a u8 kind code (1 odo, 2 gnss, 3 master), then the kind's
n values as float64, in the column order of its pinned aiding log (``messages.AIDING_FIELDS``):
odo v_b (3), N = 25; gnss lat_deg, lon_deg, h_m, v_enu (3), N = 49; master q (4), v_enu (3),
lat_deg, lon_deg, h_m, N = 81. The header timestamp is the instant the values hold for.

:class:`FrameDecoder` takes bytes in any pieces, finds frames, and counts what it drops. Each
message type carries its own sequence counter, and each aiding kind its own (an IMU and its aiding
sources number their frames independently), so aiding frames interleaved with IMU frames are never IMU
sequence gaps, nor an odometer's frames between a receiver's.
"""
from __future__ import annotations

import math
import struct
import sys
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ._frames import ImuRun
from .buffers import read_sized
from .counters import Counters, count
from .framing import next_sync
from .messages import AIDING_FIELDS, AidingSample, MessageError
from .plausibility import aiding_problem
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
IMU_FRAME_BYTES = HEADER.size + IMU_PAYLOAD.size + CRC.size
IMU_ROW_COLUMNS = 9
"""A decoded IMU frame's row: t (s), Δθ (3) rad, Δv (3) m/s, the status word, saturated (1.0: a value at full
scale)."""
_FAST = sys.byteorder == "little"   # the compiled pass reads the little-endian fields as the host's integers


def _crc32_table() -> np.ndarray:
    """CRC-32's table as zlib computes it: entry n is the register after byte n from a zero register (zlib's
    ``crc32(bytes([n]), 0xFFFFFFFF)`` un-inverted), so the compiled pass checks what zlib.crc32 checks."""
    return np.array([zlib.crc32(bytes([n]), 0xFFFFFFFF) ^ 0xFFFFFFFF for n in range(256)], dtype=np.uint32)


def _offset(prefix: str) -> int:
    """The byte offset in the header of the field after the ``HEADER`` format's ``prefix``."""
    return struct.calcsize("<" + prefix)


IMU_RUN = ImuRun(SYNC, VERSION, MSG_IMU, HEADER.size, _offset("2sBB"), _offset("2sBBH"), _offset("2sBBHH"),
                 _offset("2sBBHHQ"), IMU_PAYLOAD.size, CRC.size, DTHETA_LSB_RAD, DV_LSB_MPS, INT32_MAX, _crc32_table())
"""The compiled pass over runs of plain IMU frames (protocol/_frames.pyx), with this module's layout."""
MAX_PAYLOAD = 1024
"""Longest payload any message type may declare; a longer length field is a corrupt header."""
AIDING_KIND_CODES = {"odo": 1, "gnss": 2, "master": 3}
"""The aiding payload's first byte: which pinned aiding kind the epoch is."""
AIDING_KINDS = {code: kind for kind, code in AIDING_KIND_CODES.items()}
AIDING_VALUES = {kind: sum(AIDING_FIELDS[kind].values()) for kind in AIDING_KIND_CODES}
"""How many float64 values each aiding kind carries (odo 3, gnss 6, master 10)."""
AIDING_PAYLOAD_SIZES = {kind: 1 + 8 * n for kind, n in AIDING_VALUES.items()}
PAYLOAD_SIZES: dict[int, frozenset[int]] = {MSG_IMU: frozenset({IMU_PAYLOAD.size}),
                                            MSG_AIDING: frozenset(AIDING_PAYLOAD_SIZES.values())}
"""Payload lengths each known message type allows; any other length is counted as ``bad_length``."""


STATUS_GYRO_FAULT = 1 << 0
STATUS_ACC_FAULT = 1 << 1
STATUS_SATURATED = 1 << 2
"""Status word bits the IMU sets; any non-zero word marks the sample unhealthy."""


class AidingPayloadError(MessageError):
    """A type-2 payload that is not a valid aiding epoch (unknown kind, wrong length, non-finite value)."""


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


def encode_imu_frames(seq: int, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray) -> bytes:
    """IMU frames for N samples at once (t (N,) s, Δθ (N, 3) rad, Δv (N, 3) m/s, healthy), numbered from ``seq``:
    the bytes of :func:`encode_imu` for each, joined, with numpy filling the fields (a fast writer's)."""
    n = len(t)
    qa, qv = quantise_imu(dtheta, dv)
    frame = np.zeros((n, IMU_FRAME_BYTES), np.uint8)
    frame[:, 0:2] = np.frombuffer(SYNC, np.uint8)
    frame[:, 2], frame[:, 3] = VERSION, MSG_IMU
    frame[:, 4:6] = np.array([IMU_PAYLOAD.size], "<u2").view(np.uint8)
    frame[:, 6:8] = ((seq + np.arange(n)) & 0xFFFF).astype("<u2").view(np.uint8).reshape(n, 2)
    frame[:, 8:16] = np.array([time_ns_of(float(x)) for x in t], "<u8").view(np.uint8).reshape(n, 8)
    frame[:, 18:42] = np.hstack((qa, qv)).astype("<i4").view(np.uint8).reshape(n, 24)
    rows = [bytearray(r) for r in frame]
    for r in rows:
        r[16:18] = struct.pack("<H", zlib.crc32(r[2:16]) & 0xFFFF)
        r[46:50] = CRC.pack(zlib.crc32(r[2:46]))
    return b"".join(rows)


def time_ns_of(t: float) -> int:
    return round(t * 1e9)


def decode_imu(frame: Frame) -> ImuMessage:
    """The IMU message of a type-1 frame (its length was checked by the decoder)."""
    *values, status = IMU_PAYLOAD.unpack(frame.payload)
    saturated = any(abs(v) >= INT32_MAX for v in values)
    return ImuMessage(frame.time_ns * 1e-9, tuple(v * DTHETA_LSB_RAD for v in values[:3]),
                      tuple(v * DV_LSB_MPS for v in values[3:]), status, saturated)


def _flat_aiding_values(kind: str, values: Mapping[str, Sequence[float] | float] | Sequence[float]) -> list[float]:
    """The kind's values in wire order, from a map of its fields (as in AidingSample) or a flat sequence."""
    fields = AIDING_FIELDS[kind]
    if isinstance(values, Mapping):
        if set(values) != set(fields):
            raise AidingPayloadError(f"aiding {kind}: expected the fields {', '.join(fields)}, got "
                                     f"{', '.join(map(str, values)) or 'none'}")
        flat = []
        for name, count in fields.items():
            value = values[name]
            items = list(np.ravel(np.asarray(value, dtype=float)))
            if len(items) != count:
                raise AidingPayloadError(f"aiding {kind}: {name} needs {count} value(s), got {len(items)}")
            flat += items
    else:
        flat = list(np.ravel(np.asarray(values, dtype=float)))
        if len(flat) != AIDING_VALUES[kind]:
            raise AidingPayloadError(f"aiding {kind}: expected {AIDING_VALUES[kind]} values, got {len(flat)}")
    return [float(v) for v in flat]


def encode_aiding(seq: int, t: float, kind: str,
                  values: Mapping[str, Sequence[float] | float] | Sequence[float]) -> bytes:
    """An aiding frame (type 2) for one epoch of ``kind`` (odo, gnss, master) valid at t (s, IMU clock).

    ``values``: a map of the kind's fields (``AidingSample.values``, scalars or sequences) or the
    flat values in the pinned log column order. Refuses (AidingPayloadError) an unknown kind, a
    wrong number of values or a non-finite one: the wire never carries what the decoder rejects.
    """
    if kind not in AIDING_KIND_CODES:
        raise AidingPayloadError(f"unknown aiding kind {kind!r} (known: {', '.join(AIDING_KIND_CODES)})")
    flat = _flat_aiding_values(kind, values)
    if not all(math.isfinite(v) for v in flat):
        raise AidingPayloadError(f"aiding {kind}: values must be finite, got {flat}")
    payload = struct.pack(f"<B{len(flat)}d", AIDING_KIND_CODES[kind], *flat)
    return encode_frame(MSG_AIDING, seq, time_ns_of(t), payload)


def decode_aiding(frame: Frame) -> AidingSample:
    """The aiding epoch of a type-2 frame: kind, seq, t (s, IMU clock) and the kind's fields.

    Raises :class:`AidingPayloadError` (a :class:`~.messages.MessageError`) for an empty payload,
    an unknown kind code, a length that does not fit the kind, a non-finite value or a physically impossible one
    (:func:`~.plausibility.aiding_problem`).
    """
    payload = frame.payload
    if not payload:
        raise AidingPayloadError("aiding payload is empty (expected a kind code and its values)")
    code = payload[0]
    kind = AIDING_KINDS.get(code)
    if kind is None:
        known = ", ".join(f"{c} {k}" for c, k in AIDING_KINDS.items())
        raise AidingPayloadError(f"unknown aiding kind code {code} (known: {known})")
    if len(payload) != AIDING_PAYLOAD_SIZES[kind]:
        raise AidingPayloadError(f"aiding {kind}: payload of {len(payload)} bytes, expected "
                                 f"{AIDING_PAYLOAD_SIZES[kind]} (kind code + {AIDING_VALUES[kind]} float64)")
    flat = struct.unpack_from(f"<{AIDING_VALUES[kind]}d", payload, 1)
    values: dict[str, tuple[float, ...]] = {}
    at = 0
    for name, width in AIDING_FIELDS[kind].items():
        values[name] = flat[at:at + width]
        at += width
        if not all(math.isfinite(v) for v in values[name]):
            raise AidingPayloadError(f"aiding {kind}: {name} not finite {values[name]}")
    problem = aiding_problem(kind, values)
    if problem is not None:
        raise AidingPayloadError(f"aiding {kind}: {problem}")
    return AidingSample(kind, frame.seq, frame.time_ns * 1e-9, values)


@dataclass(slots=True)
class DecoderCounters(Counters):
    """What the decoder saw: good frames and every kind of drop."""

    frames: int = count("valid frames, in sequence")
    bytes_skipped: int = count("bytes outside any frame (garbage, resynchronisation)")
    bad_header: int = count("a sync word whose header check fails (false sync, corrupt header)")
    bad_crc: int = count("frames whose CRC-32 fails")
    bad_length: int = count("a length field no message type allows")
    bad_version: int = count("frames of another protocol version")
    unknown_type: int = count("well-formed frames of a type this daemon does not handle (passed on, not dropped)")



@dataclass(slots=True)
class FrameDecoder:
    """Stream decoder: ``feed`` bytes in any pieces, get the complete, valid, in-sequence frames.

    Resynchronises on the sync word after garbage; a frame with a bad CRC, version or length is
    dropped by skipping its first sync byte, so a real frame hidden inside it is still found.
    Memory is bounded: the buffer never holds more than one maximal frame plus the last piece.

    Each message type has its own sequence counter: ``sequence`` follows the IMU frames (type 1,
    counters ``seq_*``), ``aiding_sequences`` the aiding frames (type 2) of each kind code (the
    payload's first byte; counters ``aiding_seq_*``, summed over the kinds); frames of other types
    are passed on unchecked (counted as ``unknown_type``).
    """

    counters: DecoderCounters = field(default_factory=DecoderCounters)
    sequence: SequenceTracker = field(default_factory=SequenceTracker)
    aiding_sequences: dict[int, SequenceTracker] = field(default_factory=dict)
    _buffer: bytearray = field(default_factory=bytearray)

    def feed(self, data: bytes) -> list[Frame]:
        """The frames ``data`` completes, every type, in stream order."""
        return self._scan(data, fast=False)   # type: ignore[return-value]   # only frames without the fast path

    def feed_rows(self, data: bytes) -> tuple[np.ndarray, list[Frame]]:
        """What ``data`` completes: the IMU samples as rows (N, 9: t s, Δθ (3) rad, Δv (3) m/s, status word,
        saturated 1.0/0.0, as :func:`decode_imu` gives them) in stream order, and the frames of the other types.

        The same frames and counters as :meth:`feed`; runs of plain IMU frames are decoded by the compiled pass
        (protocol/_frames.pyx), the rest as :meth:`feed` decodes it."""
        runs: list[np.ndarray] = []
        others: list[Frame] = []
        for item in self._scan(data, fast=_FAST):
            if isinstance(item, np.ndarray):
                runs.append(item)
            elif item.msg_type == MSG_IMU:
                m = decode_imu(item)
                runs.append(np.array([[m.t, *m.dtheta, *m.dv, m.status, float(m.saturated)]]))
            else:
                others.append(item)
        rows = runs[0] if len(runs) == 1 else np.concatenate(runs) if runs else np.empty((0, IMU_ROW_COLUMNS))
        return rows, others

    def _scan(self, data: bytes, fast: bool) -> list[Frame | np.ndarray]:
        """Frames in stream order; with ``fast``, each run of plain in-sequence IMU frames as one array of rows."""
        self._buffer += data
        out: list[Frame | np.ndarray] = []
        buf = self._buffer
        pos = used = 0
        # one array for every run of this call (each run a view of it): room for as many frames as the bytes hold
        rows = read_sized(len(buf) // IMU_FRAME_BYTES, IMU_ROW_COLUMNS) if fast else None
        while True:
            if rows is not None and self.sequence.last is not None:
                n, pos, last = IMU_RUN.run(buf, pos, self.sequence.last, rows[used:])
                if n:
                    self.sequence.follow(last)
                    self.counters.frames += n
                    out.append(rows[used:used + n])
                    used += n
            pos, skipped, found = next_sync(buf, pos, SYNC)
            self.counters.bytes_skipped += skipped
            if not found:
                break
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
            if length > MAX_PAYLOAD or length not in PAYLOAD_SIZES.get(msg_type, (length,)):
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
            if msg_type == MSG_IMU:
                accepted = self.sequence.accept(seq)
            elif msg_type == MSG_AIDING:
                # at most 256 trackers: the kind code is one byte (an empty payload: its own, refused later)
                kind = frame.payload[0] if frame.payload else -1
                accepted = self.aiding_sequences.setdefault(kind, SequenceTracker()).accept(seq)
            else:
                accepted = True
                self.counters.unknown_type += 1
            if accepted:
                self.counters.frames += 1
                out.append(frame)
        del buf[:pos]
        return out

    def all_counters(self) -> dict[str, int]:
        """Decoder and sequence counters in one map (the status topic's names)."""
        aiding: dict[str, int] = SequenceTracker().counters("aiding_seq_")
        for tracker in self.aiding_sequences.values():
            for name, seen in tracker.counters("aiding_seq_").items():
                aiding[name] += seen
        return {**self.counters.as_dict(), **self.sequence.counters(), **aiding}

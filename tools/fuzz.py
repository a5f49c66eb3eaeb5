"""Long random-input runs of the readers (a benchmark-style command; the suite runs hypothesis).

``fuzz_serial`` feeds the serial decoder random pieces: pure noise, valid frames (IMU and aiding)
with random bit flips, truncations and splices, and noise with sync words planted in it. Any
exception escaping the decoder or the IMU payload decoder is a failure, as is one from the aiding
payload decoder other than its documented ``AidingPayloadError``; everything else must be counted.
"""
from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass

import numpy as np
from sinsalign.protocol import messages
from sinsalign.protocol.serial_frame import (
    AIDING_VALUES,
    MSG_AIDING,
    MSG_IMU,
    SYNC,
    AidingPayloadError,
    FrameDecoder,
    decode_aiding,
    decode_imu,
    encode_aiding,
    encode_imu,
)


@dataclass(frozen=True, slots=True)
class FuzzReport:
    inputs: int
    bytes_fed: int
    frames_out: int
    escaped: int
    seconds: float
    counters: dict[str, int]
    first_failure: str | None


def _pieces(rng: np.random.Generator, valid: list[bytes], n: int):
    for _ in range(n):
        kind = rng.integers(5)
        if kind == 0:
            yield rng.bytes(int(rng.integers(0, 120)))
        elif kind == 1:
            frame = bytearray(valid[rng.integers(len(valid))])
            for _ in range(int(rng.integers(1, 4))):
                frame[rng.integers(len(frame))] ^= 1 << int(rng.integers(8))
            yield bytes(frame)
        elif kind == 2:
            frame = valid[rng.integers(len(valid))]
            yield frame[:int(rng.integers(1, len(frame)))]
        elif kind == 3:
            noise = bytearray(rng.bytes(int(rng.integers(2, 80))))
            at = int(rng.integers(0, len(noise) - 1))
            noise[at:at + 2] = SYNC
            yield bytes(noise)
        else:
            yield valid[rng.integers(len(valid))]


def fuzz_serial(inputs: int = 1_000_000, seed: int = 0) -> FuzzReport:
    rng = np.random.default_rng(seed)
    valid = [encode_imu(k, 0.005 * (k + 1), rng.normal(0, 1e-3, 3), rng.normal(0, 0.1, 3)) for k in range(256)]
    valid += [encode_aiding(k, 0.005 * (k + 1), kind, rng.normal(0, 10, n))
              for k in range(32) for kind, n in AIDING_VALUES.items()]
    decoder = FrameDecoder()
    escaped = frames = fed = 0
    first = None
    start = time.perf_counter()
    for piece in _pieces(rng, valid, inputs):
        fed += len(piece)
        try:
            for frame in decoder.feed(piece):
                frames += 1
                if frame.msg_type == MSG_IMU:
                    decode_imu(frame)
                elif frame.msg_type == MSG_AIDING:
                    with contextlib.suppress(AidingPayloadError):   # the documented rejection (bad_aiding)
                        decode_aiding(frame)
        except Exception as exc:   # the point of the run: nothing may escape
            escaped += 1
            first = first or f"{type(exc).__name__}: {exc} on {piece.hex()}"
            decoder = FrameDecoder()
    return FuzzReport(inputs, fed, frames, escaped, time.perf_counter() - start, decoder.all_counters(), first)


def fuzz_messages(inputs: int = 200_000, seed: int = 0) -> FuzzReport:
    """Random bytes and mutated valid msgpack messages into every message decoder."""
    rng = np.random.default_rng(seed)
    sample = messages.ImuSample(1, 0.005, (1e-5, 0.0, 0.0), (0.0, 0.0, 0.049), 0)
    valid = messages.pack(messages.imu_message(sample))
    decoders = (messages.decode_imu, messages.decode_attitude, messages.decode_status,
                lambda d: messages.decode_aiding("gnss", d))
    escaped = rejected = 0
    first = None
    start = time.perf_counter()
    for k in range(inputs):
        data = bytearray(valid if k % 2 else rng.bytes(int(rng.integers(0, 64))))
        if k % 2:
            data[rng.integers(len(data))] = int(rng.integers(256))
        for decode in decoders:
            try:
                decode(bytes(data))
            except messages.MessageError:
                rejected += 1
            except Exception as exc:
                escaped += 1
                first = first or f"{type(exc).__name__}: {exc} on {bytes(data).hex()}"
    return FuzzReport(inputs, 0, 0, escaped, time.perf_counter() - start, {"rejected": rejected}, first)

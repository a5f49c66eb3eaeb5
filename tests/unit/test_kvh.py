"""KVH 1750 and 1775 (type C) frames: the CRC and frames built from the published layout, the bench encoder's round
trip, any chunking, every fault the decoder meets (and the counter gaps the caller's clock counts), fuzz."""
from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sinsalign.protocol.crc import crc32_mpeg2
from sinsalign.protocol.kvh import KVH_FORMATS, STANDARD_GRAVITY, KvhDecoder, KvhEncoder
from sinsalign.service.serial_formats import VendorFrames

RATE_HZ = 1000.0
FRAME_1750 = bytes.fromhex("FE81FF55 3A83126F BB03126F 3F000000 00000000 3E800000 BF800000 77 05 0019 D49AE792")
"""A 1750 frame from the layout: Δθ 1e-3, −2e-3, 0.5 rad; acceleration 0, 0.25, −1 g; all axes valid (0x77);
sequence 5; 25 °C; CRC-32/MPEG-2 of the first 32 bytes."""
FRAME_1775 = bytes.fromhex("FE81FF57 3A83126F BB03126F 3F000000 00000000 3E800000 BF800000 41FC0000 77 04 78B034F2")
"""A 1775 type C frame: the same values, sequence 4 (so the multiplexed float, 31.5, is the temperature); CRC of
the first 34 bytes."""
MODELS = ("1750", "1775")


def frame(model: str, values: tuple, status: int = 0x77, sequence: int = 0) -> bytes:
    """A frame with any values (non-finite ones too) and a valid CRC."""
    fmt = KVH_FORMATS[model]
    body = bytes.fromhex("FE81FF") + bytes([fmt.format_byte]) + struct.pack(">6f", *values)
    body += bytes(fmt.status_at - len(body)) + bytes([status, sequence]) + bytes(fmt.size - fmt.status_at - 6)
    return body + struct.pack(">I", crc32_mpeg2(body))


def frames(model: str, n: int, start: int = 0, seed: int = 0) -> tuple[list[bytes], np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    dtheta, dv = rng.uniform(-1e-3, 1e-3, (n, 3)), rng.uniform(-0.05, 0.05, (n, 3))
    enc = KvhEncoder(model, RATE_HZ)
    return [enc.encode(start + k, dtheta[k], dv[k]) for k in range(n)], dtheta, dv


def test_crc_check_value():
    assert crc32_mpeg2(b"123456789") == 0x0376E6E7


@pytest.mark.parametrize(("model", "raw", "sequence"), [("1750", FRAME_1750, 5), ("1775", FRAME_1775, 4)])
def test_a_frame_built_from_the_layout_decodes_to_its_values(model, raw, sequence):
    assert len(raw) == KVH_FORMATS[model].size
    got = KvhDecoder(model, RATE_HZ).feed(raw)
    assert got.counter.tolist() == [sequence] and got.status.tolist() == [0]
    np.testing.assert_allclose(got.dtheta[0], [1e-3, -2e-3, 0.5], rtol=1e-7)
    np.testing.assert_array_equal(got.dv[0], np.array([0.0, 0.25, -1.0]) * STANDARD_GRAVITY / RATE_HZ)


@pytest.mark.parametrize(("model", "raw"), [("1750", FRAME_1750), ("1775", FRAME_1775)])
def test_the_encoder_writes_those_frames(model, raw):
    """Byte for byte but for the temperature (and magnetometer), which the bench sends as 0."""
    fmt = KVH_FORMATS[model]
    out = KvhEncoder(model, RATE_HZ).encode(raw[fmt.status_at + 1], np.array([1e-3, -2e-3, 0.5]),
                                            np.array([0.0, 0.25, -1.0]) * STANDARD_GRAVITY / RATE_HZ)
    assert out[:28] == raw[:28] and out[fmt.status_at:fmt.status_at + 2] == raw[fmt.status_at:fmt.status_at + 2]
    assert struct.unpack(">I", out[-4:])[0] == crc32_mpeg2(out[:-4])


@pytest.mark.parametrize("model", MODELS)
def test_round_trip_within_float32(model):
    raw, dtheta, dv = frames(model, 300)
    got = KvhDecoder(model, RATE_HZ).feed(b"".join(raw))
    np.testing.assert_allclose(got.dtheta, dtheta, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(got.dv, dv, rtol=1e-6, atol=1e-12)
    assert got.counter.tolist() == [k % 128 for k in range(300)] and not got.status.any()


def decode(model: str, data: bytes, cuts: list[int]) -> tuple[np.ndarray, np.ndarray, dict]:
    dec = KvhDecoder(model, RATE_HZ)
    parts = [dec.feed(data[a:b]) for a, b in zip([0, *cuts], [*cuts, len(data)], strict=True)]
    return np.concatenate([p.counter for p in parts]), np.concatenate([p.dv for p in parts]), dec.counters()


@pytest.mark.parametrize("model", MODELS)
def test_the_same_samples_whatever_the_chunking(model):
    raw, _, _ = frames(model, 4)
    data = b"\xfe\x81" + raw[0] + b"\xfe" + b"".join(raw[1:]) + b"\xfe\x81"   # header-like bytes at the cuts
    whole = decode(model, data, [])
    assert len(whole[0]) == 4 and whole[2]["bytes_skipped"] == 3
    for cut in range(1, len(data)):
        got = decode(model, data, [cut])
        np.testing.assert_array_equal(got[0], whole[0])
        np.testing.assert_array_equal(got[1], whole[1])
        assert got[2] == whole[2]
    bytewise = decode(model, data, list(range(1, len(data))))
    np.testing.assert_array_equal(bytewise[1], whole[1])
    assert bytewise[2] == whole[2]


@pytest.mark.parametrize("model", MODELS)
def test_a_bad_crc_drops_that_frame_and_finds_the_next(model):
    raw, _, _ = frames(model, 4)
    raw[2] = raw[2][:-1] + bytes([raw[2][-1] ^ 0x01])
    dec = KvhDecoder(model, RATE_HZ)
    assert dec.feed(b"".join(raw)).counter.tolist() == [0, 1, 3]
    assert dec.counters()["bad_crc"] == 1 and dec.counters()["bytes_skipped"] == len(raw[2])


@pytest.mark.parametrize("model", MODELS)
def test_a_truncated_frame_is_dropped_and_the_next_found(model):
    raw, _, _ = frames(model, 3)
    dec = KvhDecoder(model, RATE_HZ)
    assert dec.feed(raw[0] + raw[1][:17] + raw[2]).counter.tolist() == [0, 2]
    assert dec.counters()["bad_crc"] == 1 and dec.counters()["bytes_skipped"] == 17


@pytest.mark.parametrize("model", MODELS)
def test_garbage_between_frames_is_skipped_byte_for_byte(model):
    raw, _, _ = frames(model, 4)
    junk = [b"", bytes.fromhex("FE81FF56 0102"), bytes.fromhex("FE8100AA") + bytes(7), bytes(range(250, 256)) * 9]
    dec = KvhDecoder(model, RATE_HZ)
    assert dec.feed(b"".join(j + r for j, r in zip(junk, raw, strict=True))).counter.tolist() == [0, 1, 2, 3]
    assert dec.counters()["bytes_skipped"] == sum(map(len, junk)) and dec.counters()["bad_crc"] == 0


@pytest.mark.parametrize("model", MODELS)
def test_sequence_gaps_and_wraps_are_counted_by_the_callers_clock(model):
    raw, _, _ = frames(model, 400)
    sent = [k for k in range(400) if k not in (200, 201)]
    now = [0.0]
    stream = VendorFrames(KvhDecoder(model, RATE_HZ), np.eye(3), clock=lambda: now[0])
    times = []
    for k in sent:
        now[0] = 5.0 + k / RATE_HZ
        times += stream.feed(raw[k]).samples[:, 0].tolist()
    np.testing.assert_allclose(times, [5.0 + k / RATE_HZ for k in sent], atol=1e-9)
    assert stream.counters()["seq_gaps"] == 2 and stream.counters()["seq_repeats"] == 0


@pytest.mark.parametrize("model", MODELS)
def test_status_bits_of_invalid_axes_flag_the_sample(model):
    values = (0.0,) * 6
    got = KvhDecoder(model, RATE_HZ).feed(b"".join(frame(model, values, status, k) for k, status in
                                                   enumerate((0x77, 0xFF, 0x76, 0x07, 0x00))))
    assert got.status.tolist() == [0, 0, 0x01, 0x70, 0x77]   # reserved bits 3 and 7 are not the axes'
    enc = KvhEncoder(model, RATE_HZ)
    assert enc.encode(0, np.zeros(3), np.zeros(3), status=1)[KVH_FORMATS[model].status_at] == 0x76


@pytest.mark.parametrize(("model", "other"), [("1750", "1775"), ("1775", "1750")])
def test_the_other_models_frames_are_told_once_without_crc_noise(model, other):
    raw, _, _ = frames(other, 200)
    dec = KvhDecoder(model, RATE_HZ)
    first, rest = dec.feed(b"".join(raw[:100])), dec.feed(b"".join(raw[100:]))
    name = {"1750": "1750 frames (FE 81 FF 55)", "1775": "1775 type C frames (FE 81 FF 57)"}[other]
    assert first.notices == [f"KVH sends {name} but imu.format is kvh{model}: set it to kvh{other}"]
    assert rest.notices == [] and len(first.counter) == len(rest.counter) == 0
    assert dec.counters()["wrong_format"] == 200 and dec.counters()["bad_crc"] == 0


@pytest.mark.parametrize("model", MODELS)
def test_what_no_sensor_sends_is_dropped_and_counted(model):
    dec = KvhDecoder(model, RATE_HZ)
    got = dec.feed(frame(model, (0.0,) * 6, sequence=128) + frame(model, (np.nan, 0, 0, 0, 0, 0))
                   + frame(model, (0, 0, 0, np.inf, 0, 0)) + frame(model, (0.0,) * 6, sequence=9))
    assert got.counter.tolist() == [9]
    assert dec.counters()["bad_sequence"] == 1 and dec.counters()["bad_value"] == 2


@pytest.mark.parametrize("model", MODELS)
def test_full_scale_floats_decode(model):
    big = float(np.finfo(np.float32).max)
    got = KvhDecoder(model, RATE_HZ).feed(frame(model, (big, -big, 1e-45, -big, big, 0.0), 0, 127))
    assert got.counter.tolist() == [127] and got.status.tolist() == [0x77]
    np.testing.assert_array_equal(got.dtheta[0], [big, -big, np.float32(1e-45)])


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(MODELS), st.lists(st.binary(max_size=300), max_size=12))
def test_random_bytes_never_raise_and_memory_stays_bounded(model, pieces):
    dec = KvhDecoder(model, RATE_HZ)
    for piece in pieces:
        dec.feed(b"\xfe\x81\xff" + piece)   # header starts make the decoder wait for frames
        assert len(dec._buffer) < max(f.size for f in KVH_FORMATS.values())


@settings(max_examples=100, deadline=None)
@given(st.sampled_from(MODELS), st.lists(st.binary(max_size=80), min_size=1, max_size=10), st.integers(1, 64))
def test_valid_frames_in_garbage_are_all_found(model, junk, piece):
    raw, _, dv = frames(model, len(junk), seed=len(junk))
    data = b"".join(j + r for j, r in zip(junk, raw, strict=True)) + bytes(40)
    dec = KvhDecoder(model, RATE_HZ)
    got = [dec.feed(data[k:k + piece]) for k in range(0, len(data), piece)]
    np.testing.assert_allclose(np.concatenate([g.dv for g in got]), dv, rtol=1e-6, atol=1e-12)
    assert dec.counters()["frames"] == len(junk)

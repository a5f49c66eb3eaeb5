"""The declared frame (docs/imu-formats.md, "Declared frame"): the checksums' published check values, a frame built
byte by byte, a real sensor's frame declared, the round trip with the bench encoder, any chunking, the decoder's
faults, every spec error with its key, and a fuzz."""
from __future__ import annotations

import struct
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sinsalign.protocol.crc import crc32_mpeg2
from sinsalign.protocol.declared_frame import (
    CHECKSUMS,
    DeclaredFrameDecoder,
    DeclaredFrameEncoder,
    FrameSpec,
    FrameSpecError,
)
from sinsalign.service.config import ConfigError, FrameConfig, config_from_mapping
from sinsalign.service.serial_formats import VENDOR_DECODERS, VendorFrames, serial_format_for
from sinsalign.tools.virtual_imu import VENDOR_ENCODERS
from support.vendor_formats import DECLARED

RATE_HZ = 200.0
SMALL = {"sync": "A5 5A", "length": 22, "endian": "big", "checksum": "crc16-ccitt", "checksum_from": 2,
         "fields": ["counter u8", "gyro_x i24 1e-6", "gyro_y i24 1e-6", "gyro_z i24 1e-6", "acc_x i16 0.01",
                    "acc_y i16 0.01", "acc_z i16 0.01", "status u8", "pad 1", "checksum u16"]}
"""Big-endian rates: gyro in µrad/s as i24, accelerometer in cm/s² as i16, CRC-16/CCITT-FALSE from the counter."""
KVH1750 = {"sync": "FE 81 FF 55", "length": 36, "endian": "big", "checksum": "crc32-mpeg2", "checksum_from": 0,
           "fields": ["dtheta_x f32", "dtheta_y f32", "dtheta_z f32", "acc_x f32 9.80665", "acc_y f32 9.80665",
                      "acc_z f32 9.80665", "pad 1", "counter u8", "pad 2", "checksum u32"]}
"""The KVH 1750 frame (ROTFMT=DELTA, ROTUNITS=RAD; accelerations in g) declared: its status byte sets bits for valid
sensors and the temperature is not an increment, so both are padding."""


def config(frame: dict[str, Any], rate_hz: float = RATE_HZ) -> Any:
    return config_from_mapping({"imu": {"format": "frame", "rate_hz": rate_hz, "frame": frame}})


def spec_of(frame: dict[str, Any]) -> FrameSpec:
    return FrameSpec.parse(FrameConfig(**{**frame, "fields": tuple(frame["fields"])}), RATE_HZ)


def codec(frame: dict[str, Any]) -> tuple[DeclaredFrameDecoder, DeclaredFrameEncoder]:
    c = config(frame)
    return VENDOR_DECODERS["frame"](c), VENDOR_ENCODERS["frame"](c.imu)


def stream(frame: dict[str, Any], n: int, start: int = 0) -> tuple[bytes, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    dtheta, dv = rng.uniform(-0.01, 0.01, (n, 3)), rng.uniform(-0.1, 0.1, (n, 3))
    encoder = codec(frame)[1]
    return b"".join(encoder.encode(start + k, dtheta[k], dv[k]) for k in range(n)), dtheta, dv


# ---- checksums and known bytes ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind, check", [("crc32", 0xCBF43926), ("crc32-mpeg2", 0x0376E6E7),
                                         ("crc16-ccitt", 0x29B1), ("sum8", 0xDD), ("xor8", 0x31)])
def test_each_checksum_gives_its_published_check_value(kind, check):
    # the CRC catalogue's check values for b"123456789" (reveng: CRC-32/ISO-HDLC, CRC-32/MPEG-2, CRC-16/IBM-3740)
    assert CHECKSUMS[kind][0](b"123456789") == check


def test_the_spec_is_one_struct():
    spec = spec_of(DECLARED)
    assert spec.layout.format == "<HiiiiiiBI" and spec.layout.size + len(spec.sync) == 33
    assert (spec.counter_modulus, spec.tick_s, spec.counter_step) == (1 << 16, 1 / RATE_HZ, 1)
    assert spec_of(SMALL).layout.format == ">B3s3s3shhhB1xH"


def test_a_frame_built_byte_by_byte():
    raw = bytes.fromhex("A5 5A" "07" "01 86 A0" "FF FF FF" "FE 79 60" "03 D5" "FF FF" "00 00" "02" "00" "CB EE")
    got = codec(SMALL)[0].feed(raw)
    assert got.counter.tolist() == [7] and got.status.tolist() == [2]
    # 0.1, -1e-6, -0.1 rad/s and 9.81, -0.01, 0 m/s² over 1/200 s
    np.testing.assert_allclose(got.dtheta[0], [5e-4, -5e-9, -5e-4], rtol=1e-12)
    np.testing.assert_allclose(got.dv[0], [0.04905, -5e-5, 0.0], rtol=1e-12)


def test_a_kvh_1750_frame_declared_decodes_to_its_values():
    body = struct.pack(">4s6fBBh", bytes.fromhex("FE81FF55"), 2e-5, -1e-5, 3e-4, 0.0, 0.01, 1.0, 0x77, 42, 31)
    raw = body + struct.pack(">I", crc32_mpeg2(body))
    dec = codec(KVH1750)[0]
    got = dec.feed(raw)
    assert got.counter.tolist() == [42] and got.status.tolist() == [0]
    np.testing.assert_allclose(got.dtheta[0], [2e-5, -1e-5, 3e-4], rtol=1e-7)
    np.testing.assert_allclose(got.dv[0], [0.0, 0.01 * 9.80665 / RATE_HZ, 9.80665 / RATE_HZ], rtol=1e-7)
    assert dec.counter_modulus == 256 and dec.tick_s == 1 / RATE_HZ


def test_the_kvh_1750_test_vector_decodes_as_the_kvh1750_format_documents_it():
    # docs/imu-formats.md, "KVH 1750 and 1775": the same frame through the declared table at 1000 Hz
    raw = bytes.fromhex("FE 81 FF 55 3A 83 12 6F BB 03 12 6F 3F 00 00 00 00 00 00 00 3E 80 00 00 BF 80 00 00 77 05"
                        " 00 19 D4 9A E7 92")
    got = VENDOR_DECODERS["frame"](config(KVH1750, rate_hz=1000.0)).feed(raw)
    assert got.counter.tolist() == [5]
    np.testing.assert_allclose(got.dtheta[0], [0.001, -0.002, 0.5], rtol=1e-7)
    np.testing.assert_allclose(got.dv[0], [0.0, 0.00245166, -0.00980665], atol=5e-9)


# ---- round trip and chunking -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("frame, lsb_rad, lsb_mps", [(DECLARED, 2**-31, 2**-24),
                                                     (SMALL, 1e-6 / RATE_HZ, 0.01 / RATE_HZ), (KVH1750, 1e-9, 1e-9)])
def test_the_encoder_round_trips_through_the_decoder(frame, lsb_rad, lsb_mps):
    raw, dtheta, dv = stream(frame, 300, start=65400)
    got = codec(frame)[0].feed(raw)
    modulus = spec_of(frame).counter_modulus
    assert got.counter.tolist() == [k % modulus for k in range(65400, 65700)]
    np.testing.assert_allclose(got.dtheta, dtheta, atol=lsb_rad / 2 * 1.0001)
    np.testing.assert_allclose(got.dv, dv, atol=lsb_mps / 2 * 1.0001)


def test_the_encoder_clips_integers_to_full_scale_and_carries_the_status():
    dec, enc = codec(DECLARED)
    got = dec.feed(enc.encode(0, np.array([5.0, -5.0, 0.0]), np.zeros(3), status=0x1FF))
    np.testing.assert_allclose(got.dtheta[0], [(2**31 - 1) * 2**-31, -1.0, 0.0])
    assert got.status.tolist() == [0xFF]


def _same(frame: dict[str, Any], pieces: list[bytes]) -> list:
    dec = codec(frame)[0]
    outs = [dec.feed(p) for p in pieces]
    return [np.concatenate([getattr(o, name) for o in outs]).tolist() for name in ("counter", "dtheta", "dv")]


@pytest.mark.parametrize("frame", [DECLARED, SMALL])
def test_the_same_samples_whatever_the_chunking(frame):
    raw, _, _ = stream(frame, 4)
    raw = b"\xa5" + raw[:9] + raw + b"\xa5"
    whole = _same(frame, [raw])
    assert len(whole[0]) == 4
    for cut in range(len(raw) + 1):
        assert _same(frame, [raw[:cut], raw[cut:]]) == whole, cut
    assert _same(frame, [raw[i:i + 1] for i in range(len(raw))]) == whole


# ---- faults ----------------------------------------------------------------------------------------------------------

def test_bad_checksum_truncation_and_garbage_are_counted_and_the_next_frame_found():
    raw, _, _ = stream(DECLARED, 4)
    f = [raw[k * 33:(k + 1) * 33] for k in range(4)]
    dec = codec(DECLARED)[0]
    got = dec.feed(f[0] + f[1][:-1] + bytes([f[1][-1] ^ 1]) + b"junk\xa5" + f[2][:20] + f[3])
    assert got.counter.tolist() == [0, 3]
    c = dec.counters()
    # skipped: the bad and the truncated frame but their first bytes (counted as the failed frame), the garbage
    assert c["bad_checksum"] == 2 and c["frames"] == 2 and c["bytes_skipped"] == 32 + 5 + 19


def test_counter_gaps_and_status_through_vendor_frames():
    raw, dtheta, _ = stream(DECLARED, 8)
    enc = codec(DECLARED)[1]
    now = iter([50.0, 50.03])
    frames = VendorFrames(codec(DECLARED)[0], np.eye(3), clock=lambda: next(now))
    first = frames.feed(raw[:3 * 33] + raw[6 * 33:])   # frames 3, 4, 5 lost
    second = frames.feed(enc.encode(8, np.zeros(3), np.zeros(3), status=4))
    # one period (5 ms) between samples, four across the three lost
    np.testing.assert_allclose(np.diff(first.samples[:, 0]), [0.005, 0.005, 0.02, 0.005], atol=1e-9)
    assert second.samples[:, 7].tolist() == [4]
    np.testing.assert_allclose(first.samples[1, 1:4], dtheta[1], atol=2**-31)
    assert frames.counters()["seq_gaps"] == 3 and frames.counters()["frames"] == 6


def test_nan_and_infinite_increments_are_dropped_absurd_finite_ones_passed_on():
    dec, enc = codec(KVH1750)
    raw = (enc.encode(0, np.array([np.nan, 0, 0]), np.zeros(3)) + enc.encode(1, np.zeros(3), np.array([0, np.inf, 0]))
           + enc.encode(2, np.array([1e38, 0, 0]), np.zeros(3)))
    got = dec.feed(raw)
    assert got.counter.tolist() == [2] and dec.counters()["bad_value"] == 2
    assert got.dtheta[0, 0] == float(np.float32(1e38))


def test_the_configured_format_builds_this_decoder():
    assert isinstance(serial_format_for(config(DECLARED)).decoder, DeclaredFrameDecoder)


# ---- spec errors -----------------------------------------------------------------------------------------------------

def _with(fields: list[str] | None = None, **keys: Any) -> dict[str, Any]:
    return {**DECLARED, **keys, **({"fields": fields} if fields is not None else {})}


def _swap(old: str, *new: str) -> list[str]:
    i = DECLARED["fields"].index(old)
    return DECLARED["fields"][:i] + list(new) + DECLARED["fields"][i + 1:]


SPEC_ERRORS = [
    (_with(sync="A5 5G"), "sync", "'A5 5G' is not hex bytes"),
    (_with(sync=""), "sync", "at least one sync byte"),
    (_with(length=34), "length", "34 bytes declared, but the sync bytes and fields make 33 (2 + 2 + 4 + 4 + 4 + 4 + 4"),
    (_with(_swap("status u8", "temp u8")), "fields", "'temp u8': unknown name 'temp'"),
    (_with(_swap("status u8", "status u12")), "fields", "'status u12': unknown type 'u12'"),
    (_with(_swap("status u8", "status")), "fields", "'status': expected \"NAME TYPE [SCALE]\""),
    (_with(_swap("status u8", "dv_x u8")), "fields", "'dv_x u8': dv_x declared twice"),
    (_with(_swap("status u8", "gyro_x u8")), "fields", "dtheta_x and gyro_x: each axis takes one of them"),
    (_with(_swap("dv_z i32 5.960464477539063e-08", "pad 4")), "fields", "no dv_z or acc_z: each axis needs one"),
    (_with(_swap("counter u16", "pad 2")), "fields", "no counter field"),
    (_with(_swap("counter u16", "counter f32"), length=35), "fields", "'counter f32': a counter is an integer"),
    (_with(_swap("counter u16", "counter u64"), length=39), "fields", "'counter u64': a counter has at most 32 bits"),
    (_with(_swap("counter u16", "counter u16 0.01")), "fields", "counter tick 0.01 s is longer than the sample "
                                                                "period 0.005 s"),
    (_with(_swap("dtheta_x i32 4.656612873077393e-10", "dtheta_x i32 abc")), "fields", "scale 'abc' is not a number"),
    (_with(_swap("dtheta_x i32 4.656612873077393e-10", "dtheta_x i32 -1")), "fields", "finite number above 0"),
    (_with(_swap("status u8", "status u8 2")), "fields", "a status takes no scale"),
    (_with(_swap("status u8", "pad x")), "fields", "'pad x': expected \"pad N\""),
    (_with(_swap("checksum u32", "pad 4")), "fields", "checksum crc32 needs a checksum field (\"checksum u32\")"),
    (_with(_swap("checksum u32", "checksum u16", "pad 2")), "fields", "needs a field of type u32, got u16"),
    (_with(_swap("checksum u32", "checksum i32")), "fields", "needs a field of type u32, got i32"),
    (_with(checksum="none"), "checksum", "none, but a checksum field is declared"),
    (_with(checksum_from=29), "checksum_from", "29 is not a byte before the checksum field (at 29)"),
]


@pytest.mark.parametrize("frame, key, message", SPEC_ERRORS)
def test_a_spec_that_does_not_add_up_is_one_line_naming_its_key(frame, key, message):
    with pytest.raises(FrameSpecError) as info:
        spec_of(frame)
    assert info.value.key == key and message in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(ConfigError) as config_info:
        config(frame)
    assert str(config_info.value) == f"imu.frame.{key}: {info.value}"


def test_an_unknown_checksum_kind_is_refused():
    with pytest.raises(FrameSpecError, match="'md5' is not one of none, crc32"):
        FrameSpec.parse(replace(config(DECLARED).imu.frame, checksum="md5"), RATE_HZ)
    with pytest.raises(ConfigError, match=r"^imu\.frame\.checksum: 'md5' is not one of"):
        config(_with(checksum="md5"))


def test_the_frame_table_is_checked_only_for_the_frame_format():
    assert config_from_mapping({"imu": {"format": "xsens"}}).imu.frame.length == 0
    with pytest.raises(ConfigError, match=r"^imu\.frame\.sync: at least one sync byte"):
        config_from_mapping({"imu": {"format": "frame"}})


# ---- fuzz ------------------------------------------------------------------------------------------------------------

@settings(max_examples=200, deadline=None)
@given(st.lists(st.binary(max_size=120), max_size=12))
def test_random_bytes_never_raise_and_memory_stays_bounded(pieces):
    dec = codec(SMALL)[0]
    for piece in pieces:
        got = dec.feed(piece)
        assert np.isfinite(got.dtheta).all() and np.isfinite(got.dv).all()
        assert len(dec._buffer) < SMALL["length"] + len(piece)


garbage = st.binary(max_size=30).map(lambda b: b.replace(b"\xa5", b"\x00"))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(garbage, st.booleans()), min_size=1, max_size=10), st.integers(1, 40))
def test_valid_frames_among_garbage_are_all_found(parts, piece):
    dec, enc = codec(DECLARED)
    raw = b"".join(junk + (enc.encode(k, np.full(3, 1e-4 * k), np.zeros(3)) if good else b"")
                   for k, (junk, good) in enumerate(parts))
    got = np.concatenate([dec.feed(raw[i:i + piece]).counter for i in range(0, len(raw), piece)] + [[]])
    assert got.tolist() == [k for k, (_, good) in enumerate(parts) if good]


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(width=32, allow_nan=True, allow_infinity=True), min_size=6, max_size=6))
def test_any_float_values_are_passed_on_if_finite_or_counted(values):
    body = struct.pack(">4s6fBBh", bytes.fromhex("FE81FF55"), *values, 0, 1, 0)
    dec = codec(KVH1750)[0]
    got = dec.feed(body + struct.pack(">I", crc32_mpeg2(body)))
    finite = bool(np.isfinite(values).all())
    assert len(got.counter) == int(finite) and dec.counters()["bad_value"] == int(not finite)

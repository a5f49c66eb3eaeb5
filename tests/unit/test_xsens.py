"""Xsens MTData2 (docs/imu-formats.md, "Xsens MTData2"): published messages, the checksum rule, a message built byte
by byte, the round trip with the bench encoder, any chunking, the decoder's faults and a fuzz.

The published vectors are MTi-300 captures decoded by MT Manager, documented in the xsens-mti C library
(github.com/Scottapotamas/xsens-mti, docs/mtmanager_packets.md): the MTData2 data field of each (its messages'
preamble, bus id, MID, length and checksum follow from the Xbus rule and are rebuilt here).
"""
from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sinsalign.protocol.axes import axis_map
from sinsalign.protocol.crc import sum8
from sinsalign.protocol.xsens import (
    MAX_DATA,
    MID_MTDATA2,
    STATUS_FAULTS,
    XDI_DELTA_Q,
    XDI_DELTA_V,
    XDI_SAMPLE_TIME_FINE,
    XDI_STATUS_WORD,
    XsensDecoder,
    XsensEncoder,
    data_item,
    quaternion_of,
    rotation_vector,
    xbus_message,
)
from sinsalign.service.config import config_from_mapping
from sinsalign.service.serial_formats import VENDOR_DECODERS, VendorFrames, serial_format_for
from sinsalign.tools.virtual_imu import VENDOR_ENCODERS

RATE_HZ = 400.0
CONFIG = config_from_mapping({"imu": {"format": "xsens", "rate_hz": RATE_HZ}})

MTI300_AT_REST = bytes.fromhex(
    "10 20 02 A6 55 10 60 04 00 57 47 2E 20 10 10 3F 7F 7D C4 BC 10 10 7D 3B A1 57 70 BD 7E C6 56 40 20 0C BD A2 1A"
    " F8 BE 2A 8E 96 41 1D 27 A2 40 10 0C B9 4F C8 00 B9 DA 24 00 3C C9 28 80 40 30 0C 3C 02 C8 9C 3C 35 F6 C8 3C DB"
    " 0C 00 80 20 0C BB B1 7D 81 BB 96 32 00 3C 01 E8 41 80 30 10 3F 80 00 00 B6 E3 30 01 B6 C0 40 00 37 26 48 00 C0"
    " 20 0C BE 99 9C 24 3F B6 1B 56 3F 16 6A EB 30 10 04 00 01 86 DE E0 20 04 00 40 00 03")
"""Packet 1 (139 bytes, 400 Hz, at rest): PacketCounter 42581, SampleTimeFine 5719854, Acceleration (-0.07915300,
-0.16655955, 9.82217598) m/s², DeltaV (-0.00019816, -0.00041607, 0.02455544), RateOfTurn (-0.00541657,
-0.00458360, 0.00792891) rad/s, DeltaQ (1, -0.00000677, -0.00000573, 0.00000991), StatusWord 0x00400003."""
MTI300_SHAKEN = bytes.fromhex(
    "10 20 02 FB 85 10 60 04 01 A4 98 DE 20 10 10 3F 2A 14 63 BE D7 EF A7 3C DE E5 08 3F 1D CE C9 40 20 0C C1 F2 46"
    " C3 C1 EC E0 76 C2 8F 85 3F 40 10 0C BD 93 2C CC BD 92 0A 16 BE 3A 6E EC 40 30 0C 42 51 94 64 C2 7B 5A 5A C1 CC"
    " C0 AE 80 20 0C 40 85 4D 6D C1 25 55 9E C0 90 8E 1F 80 30 10 3F 7F F8 98 3B AA 9E E5 BC 53 9E C0 BB B9 06 0C C0"
    " 20 0C 3E DC 74 39 BE 75 2B 48 3F AF 9A 3F 30 10 04 00 01 86 DE E0 20 04 00 48 14 01")
"""Packet 5 (a violent shake): SampleTimeFine 27564254, DeltaV (-0.07186279, -0.07130830, -0.18206376), DeltaQ
(0.99988699, 0.00520693, -0.01291627, -0.00564647), StatusWord 0x00481401 (accelerometer z and gyroscope y
clipped, clipping indication, orientation no longer valid)."""
MTI300_NO_INCREMENTS = bytes.fromhex(
    "10 20 02 46 82 10 60 04 01 C4 FC 3E 20 10 10 3F 71 CE 6C BE A5 6B CF 3C 61 3B D8 BD 69 1D 25 E0 20 04 00 40 00 03")
"""Packet 6: PacketCounter, SampleTimeFine, Quaternion and StatusWord only."""


def decoder() -> XsensDecoder:
    return VENDOR_DECODERS["xsens"](CONFIG)


def mtdata2(stf: int, dq: tuple[float, ...], dv: tuple[float, ...], word: int | None = None) -> bytes:
    items = (data_item(XDI_SAMPLE_TIME_FINE, struct.pack(">I", stf)) + data_item(XDI_DELTA_Q, struct.pack(">4f", *dq))
             + data_item(XDI_DELTA_V, struct.pack(">3f", *dv)))
    return xbus_message(MID_MTDATA2, items + (b"" if word is None else data_item(XDI_STATUS_WORD,
                                                                                 struct.pack(">I", word))))


def stream(n: int, start: int = 0) -> tuple[bytes, np.ndarray, np.ndarray]:
    """n encoded samples of a turning, accelerating sensor (Δθ up to 0.05 rad, Δv up to 0.2 m/s)."""
    rng = np.random.default_rng(7)
    dtheta, dv = rng.uniform(-0.05, 0.05, (n, 3)), rng.uniform(-0.2, 0.2, (n, 3))
    encoder = VENDOR_ENCODERS["xsens"](CONFIG.imu)
    return b"".join(encoder.encode(start + k, dtheta[k], dv[k]) for k in range(n)), dtheta, dv


# ---- published messages and the checksum rule ------------------------------------------------------------------------

def test_the_published_mti300_message_at_rest_decodes_to_its_mt_manager_values():
    got = decoder().feed(xbus_message(MID_MTDATA2, MTI300_AT_REST))
    assert len(MTI300_AT_REST) == 139 and got.counter.tolist() == [5719854]
    np.testing.assert_allclose(got.dv[0], [-0.00019816, -0.00041607, 0.02455544], atol=5e-9)
    # Δθ of DeltaQ (1, -6.77e-6, -5.73e-6, 9.91e-6) is twice its vector part; it is RateOfTurn over one period
    np.testing.assert_allclose(got.dtheta[0], [-1.354143e-5, -1.145899e-5, 1.982227e-5], rtol=1e-6)
    np.testing.assert_allclose(got.dtheta[0] * RATE_HZ, [-0.00541657, -0.00458360, 0.00792891], rtol=2e-4)
    assert got.status.tolist() == [0]   # 0x00400003: self-test ok, orientation valid, sync-out marker


def test_the_published_shaken_message_carries_its_clipping_flags_as_status():
    got = decoder().feed(xbus_message(MID_MTDATA2, MTI300_SHAKEN))
    assert got.counter.tolist() == [27564254]
    assert got.status.tolist() == [0x00081400]   # acc z (bit 10), gyr y (bit 12), clipping indication (bit 19)
    np.testing.assert_allclose(got.dv[0], [-0.07186279, -0.07130830, -0.18206376], atol=5e-9)
    vector = np.array([0.00520693, -0.01291627, -0.00564647])
    angle = 2 * np.arctan2(np.linalg.norm(vector), 0.99988699)
    np.testing.assert_allclose(got.dtheta[0], angle * vector / np.linalg.norm(vector), rtol=1e-6)


def test_a_message_without_the_increments_is_dropped_with_the_outputs_to_enable():
    dec = decoder()
    got = dec.feed(xbus_message(MID_MTDATA2, MTI300_NO_INCREMENTS) * 3)
    assert len(got.counter) == 0 and dec.counters()["missing_output"] == 3
    assert got.notices == ["Xsens MTData2 without Angular Velocity > Delta q, Acceleration > Delta v: enable it in "
                           "MT Manager (Device Settings > Output Configuration); messages dropped"]


def test_the_checksum_makes_the_sum_from_the_bus_id_zero_as_in_published_messages():
    # GoToConfig, GoToConfigAck and the OutputConfiguration ack as the xsens-mti library documents them
    published = ["FA FF 30 00 D1", "FA FF 31 00 D0", "FA FF C1 08 10 20 FF FF 10 60 FF FF 9C"]
    for text in published:
        raw = bytes.fromhex(text)
        assert sum8(raw[1:]) == 0
        assert xbus_message(raw[2], raw[4:-1]) == raw
    dec = decoder()
    assert len(dec.feed(b"".join(bytes.fromhex(t) for t in published)).counter) == 0
    assert dec.counters()["other_messages"] == 3 and dec.counters()["bad_checksum"] == 0


def test_a_message_built_byte_by_byte():
    raw = bytes.fromhex(
        "FA FF 36 30"
        "10 60 04 00 01 02 03"                                # SampleTimeFine 66051
        "80 30 10 00 00 00 00 00 00 00 00 00 00 00 00 3F 80 00 00"   # DeltaQ (0, 0, 0, 1): π about z
        "40 10 0C 3F 00 00 00 C0 00 00 00 41 1C E8 0A"        # DeltaV (0.5, -2, 9.80665)
        "E0 20 04 00 00 08 00"                                # StatusWord: gyroscope x clipped
        "EC")
    assert sum8(raw[1:]) == 0
    got = decoder().feed(raw)
    assert got.counter.tolist() == [66051] and got.status.tolist() == [0x800]
    np.testing.assert_allclose(got.dtheta[0], [0.0, 0.0, np.pi], rtol=1e-15)
    np.testing.assert_allclose(got.dv[0], [0.5, -2.0, 9.80665], rtol=1e-7)


def test_an_extended_length_message_and_unknown_items_are_read():
    filler = data_item(0xA010, bytes(150)) * 2   # items the decoder does not take: skipped
    raw = xbus_message(MID_MTDATA2, filler + mtdata2(40, (1, 0, 0, 0), (0, 0, 0.1))[4:-1])
    assert raw[3] == 0xFF and struct.unpack(">H", raw[4:6])[0] == 2 * 153 + 7 + 19 + 15
    got = decoder().feed(raw)
    assert got.counter.tolist() == [40]


# ---- Δθ from the quaternion ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("angle", [1e-12, 1e-6, 0.01, 1.0, 3.0, np.pi])
def test_the_rotation_vector_is_exact_at_any_angle(angle):
    axis = np.array([2.0, -3.0, 6.0]) / 7.0
    q = quaternion_of(angle * axis)
    for sign in (1.0, -1.0):   # q and -q are one rotation
        np.testing.assert_allclose(rotation_vector(sign * q[None, :])[0], angle * axis, rtol=1e-12, atol=1e-15)


def test_a_quaternion_of_any_norm_gives_its_rotation():
    q = quaternion_of(np.array([0.0, 0.02, 0.0]))
    for norm in (1e-30, 1.0, 1e38, 1e300):
        np.testing.assert_allclose(rotation_vector(norm * q[None, :])[0], [0.0, 0.02, 0.0], rtol=1e-12)
    assert rotation_vector(np.zeros((1, 4))).tolist() == [[0.0, 0.0, 0.0]]


# ---- round trip and chunking -----------------------------------------------------------------------------------------

def test_the_encoder_round_trips_through_the_decoder_as_float32():
    raw, dtheta, dv = stream(50)
    got = decoder().feed(raw)
    step = round(10000 / RATE_HZ)
    assert got.counter.tolist() == [k * step for k in range(50)] and not got.status.any()
    np.testing.assert_allclose(got.dtheta, dtheta, atol=1e-8)
    np.testing.assert_allclose(got.dv, dv, atol=2e-8)


def test_the_encoder_status_is_decoded_as_a_fault():
    encoder = VENDOR_ENCODERS["xsens"](CONFIG.imu)
    raw = b"".join(encoder.encode(k, np.zeros(3), np.zeros(3), status) for k, status in enumerate((0, 1, 0x2000)))
    assert decoder().feed(raw).status.tolist() == [0, 1 << 19, 0x2000]


def test_the_counter_wraps_at_32_bits():
    raw = b"".join(XsensEncoder(25).encode(k, np.zeros(3), np.zeros(3)) for k in (171798690, 171798691, 171798692))
    assert decoder().feed(raw).counter.tolist() == [4294967250, 4294967275, 4]


def _same(pieces: list[bytes]) -> list:
    dec = decoder()
    outs = [dec.feed(p) for p in pieces]
    return [np.concatenate([getattr(o, name) for o in outs]).tolist() for name in ("counter", "dtheta", "dv")]


def test_the_same_samples_whatever_the_chunking():
    raw, _, _ = stream(4)
    raw = b"\x00\xfa" + raw[:20] + raw + b"\xfa\xff"
    whole = _same([raw])
    assert len(whole[0]) == 4
    for cut in range(len(raw) + 1):
        assert _same([raw[:cut], raw[cut:]]) == whole, cut
    assert _same([raw[i:i + 1] for i in range(len(raw))]) == whole


# ---- faults ----------------------------------------------------------------------------------------------------------

def test_bad_checksum_truncation_and_garbage_are_counted_and_the_next_message_found():
    raw, _, _ = stream(4)
    size = len(raw) // 4
    m = [raw[k * size:(k + 1) * size] for k in range(4)]
    bad = m[1][:-1] + bytes([m[1][-1] ^ 0x01])
    dec = decoder()
    got = dec.feed(m[0] + bad + b"garbage\xfa" + m[2][: size // 2] + m[3])
    c = dec.counters()
    assert got.counter.tolist() == [0, 3 * 25]
    # skipped: the bad and the truncated message but their first bytes (counted as the failed message), the garbage
    assert c["bad_checksum"] == 2 and c["frames"] == 2 and c["bytes_skipped"] == (size - 1) + 8 + (size // 2 - 1)


def test_a_length_beyond_any_message_is_refused_at_once():
    dec = decoder()
    raw, _, _ = stream(1)
    header = bytes.fromhex("FA FF 36 FF") + struct.pack(">H", MAX_DATA + 1)
    assert dec.feed(header + raw).counter.tolist() == [0]
    assert dec.counters()["bad_length"] == 1


def test_items_that_overrun_their_message_are_a_bad_length():
    body = mtdata2(0, (1, 0, 0, 0), (0, 0, 0))[4:-1]
    dec = decoder()
    assert len(dec.feed(xbus_message(MID_MTDATA2, body[:-2]) + xbus_message(MID_MTDATA2, body + b"\x10")).counter) == 0
    assert dec.counters()["bad_length"] == 2


@pytest.mark.parametrize("low_bits, name", [(1, "fp12.20"), (2, "fp16.32")])
def test_fixed_point_increments_are_dropped_with_a_notice(low_bits, name):
    body = (data_item(XDI_SAMPLE_TIME_FINE, bytes(4)) + data_item(XDI_DELTA_Q | low_bits, bytes(4 * (3 + low_bits)))
            + data_item(XDI_DELTA_V, bytes(12)))
    dec = decoder()
    got = dec.feed(xbus_message(MID_MTDATA2, body))
    assert len(got.counter) == 0 and dec.counters()["unsupported_format"] == 1
    assert got.notices == [f"Xsens DeltaQ/DeltaV in {name}: set Float32 or Float64 in MT Manager's Output "
                           f"Configuration; messages dropped"]


def test_float64_increments_are_decoded():
    body = (data_item(XDI_SAMPLE_TIME_FINE, struct.pack(">I", 9))
            + data_item(XDI_DELTA_Q | 3, struct.pack(">4d", *quaternion_of(np.array([1e-9, 0, 0]))))
            + data_item(XDI_DELTA_V | 3, struct.pack(">3d", 0.1, 0.2, 1 / 3)))
    got = decoder().feed(xbus_message(MID_MTDATA2, body))
    np.testing.assert_allclose(got.dtheta[0], [1e-9, 0, 0], rtol=1e-12)
    assert got.dv[0].tolist() == [0.1, 0.2, 1 / 3]


def test_nan_and_infinite_increments_are_dropped_absurd_finite_ones_passed_on():
    dec = decoder()
    got = dec.feed(mtdata2(0, (1, 0, 0, 0), (np.nan, 0, 0)) + mtdata2(25, (np.inf, 0, 0, 0), (0, 0, 0))
                   + mtdata2(50, (1, 0, 0, 0), (1e38, -1e38, 3e38)))
    assert got.counter.tolist() == [50] and dec.counters()["bad_value"] == 2
    assert got.dv[0].tolist() == [float(np.float32(v)) for v in (1e38, -1e38, 3e38)]


def test_counter_gaps_status_and_axes_through_vendor_frames():
    raw, dtheta, _ = stream(10)
    size = len(raw) // 10
    kept = [k for k in range(10) if k not in (4, 5, 6)]
    flagged = XsensEncoder(25).encode(10, dtheta[0], np.zeros(3), status=1)
    now = iter([100.0, 100.02, 100.05])
    frames = VendorFrames(decoder(), axis_map(("-y", "x", "z")), clock=lambda: next(now))
    first = frames.feed(b"".join(raw[k * size:(k + 1) * size] for k in kept[:4]))
    second = frames.feed(b"".join(raw[k * size:(k + 1) * size] for k in kept[4:]))
    third = frames.feed(flagged)
    # one period (25 ticks of 100 µs) between samples, four across the three lost
    t = np.concatenate((first.samples[:, 0], second.samples[:, 0]))
    np.testing.assert_allclose(np.diff(t), [0.0025] * 3 + [0.01] + [0.0025] * 2, atol=1e-9)
    assert third.samples[:, 7].tolist() == [1 << 19]
    np.testing.assert_allclose(first.samples[0, 1:4], [-dtheta[0, 1], dtheta[0, 0], dtheta[0, 2]], atol=1e-8)
    counters = frames.counters()
    assert counters["seq_gaps"] == 3 and counters["frames"] == 8 and counters["seq_repeats"] == 0


def test_the_configured_format_builds_this_decoder():
    assert isinstance(serial_format_for(CONFIG).decoder, XsensDecoder)
    assert decoder().counter_step == 25 and decoder().counter_modulus == 1 << 32 and decoder().tick_s == 1e-4


def test_status_faults_are_the_clipping_flags():
    assert STATUS_FAULTS == 0x3F00 | 0x80000


# ---- fuzz ------------------------------------------------------------------------------------------------------------

@settings(max_examples=200, deadline=None)
@given(st.lists(st.binary(max_size=300), max_size=12))
def test_random_bytes_never_raise_and_memory_stays_bounded(pieces):
    dec = decoder()
    for piece in pieces:
        got = dec.feed(piece)
        assert np.isfinite(got.dtheta).all() and np.isfinite(got.dv).all()
        assert len(dec._buffer) <= 6 + MAX_DATA + 1 + len(piece)


garbage = st.binary(max_size=40).map(lambda b: b.replace(b"\xfa", b"\x00"))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(garbage, st.booleans()), min_size=1, max_size=10), st.integers(1, 50))
def test_valid_messages_among_garbage_are_all_found(parts, piece):
    encoder = XsensEncoder(25)
    raw = b"".join(junk + (encoder.encode(k, np.full(3, 1e-3 * k), np.zeros(3)) if good else b"")
                   for k, (junk, good) in enumerate(parts))
    dec = decoder()
    got = np.concatenate([dec.feed(raw[i:i + piece]).counter for i in range(0, len(raw), piece)] + [[]])
    assert got.tolist() == [25 * k for k, (_, good) in enumerate(parts) if good]


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(width=32, allow_nan=True, allow_infinity=True), min_size=7, max_size=7))
def test_any_float_values_are_passed_on_if_finite_or_counted(values):
    dq, dv = tuple(values[:4]), tuple(values[4:])
    dec = decoder()
    got = dec.feed(mtdata2(1, dq, dv))
    finite = bool(np.isfinite(values).all())
    assert len(got.counter) == int(finite) and dec.counters()["bad_value"] == int(not finite)
    assert np.isfinite(got.dtheta).all() and (np.abs(got.dtheta) <= np.pi + 1e-12).all()

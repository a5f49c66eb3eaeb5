"""STIM300 normal-mode datagrams: the CRC and a datagram built from the datasheet's layout, the bench encoder's round
trip, any chunking, every fault the decoder meets (and the counter gaps the caller's clock counts), fuzz."""
from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sinsalign.protocol.crc import crc32_mpeg2
from sinsalign.protocol.stim300 import (
    DTHETA_LSB_DEG,
    STIM300_DATAGRAMS,
    STIM300_DV_LSB,
    Stim300Decoder,
    Stim300Encoder,
    stim300_layout,
)
from sinsalign.service.config import ConfigError, config_from_mapping
from sinsalign.service.serial_formats import VendorFrames

RATE_HZ = 200.0
DATAGRAM_93 = bytes.fromhex("93 000001 FFFFFF 200000 00 400000 C00000 000100 00 000000 000000 000000 00 2A 01F4 "
                            "11831476")
"""0x93 built from the datasheet's layout: gyro x +1 LSB, y −1 LSB, z 2²¹ LSB (1°); accelerometer x 2²² LSB
(1 m/s at 10 g), y −2²², z 256; inclinometers 0; statuses 0; counter 42; latency 500 µs; CRC over the 34 bytes
and 2 dummy zero bytes."""
ACC_DATAGRAMS = (0x91, 0x93, 0xA5, 0xA7)


def crc_bitwise(data: bytes) -> int:
    """CRC-32/MPEG-2 bit by bit (MSB first, seed all ones, no final XOR): the reference the fast one must match."""
    crc = 0xFFFFFFFF
    for byte in data:
        crc ^= byte << 24
        for _ in range(8):
            crc = (crc << 1 ^ (0x04C11DB7 if crc & 0x80000000 else 0)) & 0xFFFFFFFF
    return crc


def frames(n: int, datagram: int = 0x93, seed: int = 0, start: int = 0) -> tuple[list[bytes], np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    dtheta, dv = rng.uniform(-1e-3, 1e-3, (n, 3)), rng.uniform(-0.1, 0.1, (n, 3))
    enc = Stim300Encoder(RATE_HZ, datagram)
    return [enc.encode(start + k, dtheta[k], dv[k]) for k in range(n)], dtheta, dv


def test_crc_check_value_and_the_bitwise_reference():
    assert crc32_mpeg2(b"123456789") == crc_bitwise(b"123456789") == 0x0376E6E7
    assert crc32_mpeg2(DATAGRAM_93[:34] + bytes(2)) == crc_bitwise(DATAGRAM_93[:34] + bytes(2)) == 0x11831476


def test_a_datagram_built_from_the_datasheet_decodes_to_its_values():
    got = Stim300Decoder(RATE_HZ).feed(DATAGRAM_93)
    assert got.counter.tolist() == [42] and got.status.tolist() == [0] and got.notices == []
    np.testing.assert_array_equal(got.dtheta[0], np.radians([2.0**-21, -(2.0**-21), 1.0]))
    np.testing.assert_array_equal(got.dv[0], [1.0, -1.0, 256 * 2.0**-22])


def test_the_encoder_writes_that_datagram_byte_for_byte():
    """At 2000 Hz a sample is one counter tick: sample 42 carries counter 42."""
    enc = Stim300Encoder(2000.0)
    raw = enc.encode(42, np.radians([2.0**-21, -(2.0**-21), 1.0]), np.array([1.0, -1.0, 256 * 2.0**-22]))
    assert raw[:32] == DATAGRAM_93[:32] and raw[32:34] == b"\x00\x00"   # the bench sends latency 0
    assert crc_bitwise(raw[:34] + bytes(2)) == struct.unpack(">I", raw[34:])[0]


def test_layouts_sizes_and_dummy_bytes_match_the_datasheet_table():
    sizes = {0x90: 18, 0x91: 28, 0x92: 28, 0x93: 38, 0xA4: 25, 0xA5: 42, 0xA6: 42, 0xA7: 59}
    dummies = {0x90: 2, 0x91: 0, 0x92: 0, 0x93: 2, 0xA4: 3, 0xA5: 2, 0xA6: 2, 0xA7: 1}
    assert {d: stim300_layout(d).size for d in STIM300_DATAGRAMS} == sizes
    assert {d: -stim300_layout(d).crc_at % 4 for d in STIM300_DATAGRAMS} == dummies
    assert STIM300_DV_LSB == {5: 2.0**-23, 10: 2.0**-22, 30: 2.0**-21, 80: 2.0**-19}


def test_a_temperature_datagram_takes_every_status_byte():
    """0xA7: gyro, acc, incl fields with their statuses, then three temperature groups with theirs."""
    body = (bytes([0xA7]) + bytes.fromhex("000001 000000 000000 00 400000 000000 000000 00") + bytes(10)
            + bytes.fromhex("2380 2380 2380 00 2380 2380 2380 40 2380 2380 2380 00") + bytes([7]) + bytes(2))
    raw = body + struct.pack(">I", crc_bitwise(body + bytes(1)))
    got = Stim300Decoder(RATE_HZ, 0xA7).feed(raw)
    assert got.counter.tolist() == [7] and got.status.tolist() == [0x40 << 32]
    np.testing.assert_array_equal(got.dtheta[0], np.radians([2.0**-21, 0, 0]))
    np.testing.assert_array_equal(got.dv[0], [1.0, 0, 0])


@pytest.mark.parametrize("acc_range_g", sorted(STIM300_DV_LSB))
@pytest.mark.parametrize("datagram", ACC_DATAGRAMS)
def test_round_trip_within_one_lsb(datagram, acc_range_g):
    rng = np.random.default_rng(datagram + acc_range_g)
    dtheta, dv = rng.uniform(-0.03, 0.03, (50, 3)), rng.uniform(-0.4, 0.4, (50, 3))
    enc, dec = Stim300Encoder(RATE_HZ, datagram, acc_range_g), Stim300Decoder(RATE_HZ, datagram, acc_range_g)
    got = dec.feed(b"".join(enc.encode(k, dtheta[k], dv[k]) for k in range(50)))
    assert np.abs(got.dtheta - dtheta).max() <= np.radians(DTHETA_LSB_DEG)
    assert np.abs(got.dv - dv).max() <= STIM300_DV_LSB[acc_range_g]
    assert got.counter.tolist() == [10 * k % 256 for k in range(50)] and not got.status.any()


def decode(data: bytes, cuts: list[int], datagram: int = 0x93) -> tuple[np.ndarray, np.ndarray, dict]:
    dec = Stim300Decoder(RATE_HZ, datagram)
    parts = [dec.feed(data[a:b]) for a, b in zip([0, *cuts], [*cuts, len(data)], strict=True)]
    return (np.concatenate([p.counter for p in parts]), np.concatenate([p.dtheta for p in parts]), dec.counters())


@pytest.mark.parametrize("crlf", [b"", b"\r\n"])
def test_the_same_samples_whatever_the_chunking(crlf):
    raw, _, _ = frames(4)
    data = crlf.join(raw) + crlf
    whole = decode(data, [])
    assert len(whole[0]) == 4 and whole[2]["bytes_skipped"] == 0
    for cut in range(1, len(data)):
        got = decode(data, [cut])
        np.testing.assert_array_equal(got[0], whole[0])
        np.testing.assert_array_equal(got[1], whole[1])
        assert got[2] == whole[2]
    bytewise = decode(data, list(range(1, len(data))))
    np.testing.assert_array_equal(bytewise[1], whole[1])
    assert bytewise[2] == whole[2]


def test_a_bad_crc_drops_that_datagram_and_finds_the_next():
    raw, dtheta, _ = frames(4)
    raw[1] = raw[1][:5] + bytes([raw[1][5] ^ 0x10]) + raw[1][6:]
    dec = Stim300Decoder(RATE_HZ)
    got = dec.feed(b"".join(raw))
    np.testing.assert_allclose(got.dtheta, dtheta[[0, 2, 3]], atol=1e-8)
    assert dec.counters()["bad_crc"] == 1 and dec.counters()["frames"] == 3
    assert dec.counters()["bytes_skipped"] == len(raw[1])


def test_a_truncated_datagram_is_dropped_and_the_next_found():
    raw, _, _ = frames(4)
    dec = Stim300Decoder(RATE_HZ)
    got = dec.feed(raw[0] + raw[1][:20] + raw[2] + raw[3])
    assert got.counter.tolist() == [0, 20, 30] and dec.counters()["bad_crc"] == 1
    assert dec.counters()["bytes_skipped"] == 20


def test_garbage_between_datagrams_is_skipped_byte_for_byte():
    raw, _, _ = frames(5)
    rng = np.random.default_rng(7)
    junk = [rng.integers(0, 256, n, dtype=np.uint8).tobytes() for n in (0, 1, 37, 200, 3)]
    dec = Stim300Decoder(RATE_HZ)
    got = dec.feed(b"".join(j + r for j, r in zip(junk, raw, strict=True)))
    assert got.counter.tolist() == [0, 10, 20, 30, 40]
    assert dec.counters()["bytes_skipped"] == sum(map(len, junk)) and dec.counters()["frames"] == 5


def test_counter_gaps_and_wraps_are_counted_by_the_callers_clock():
    """200 Hz: 10 ticks per sample, the u8 wraps every 25.6 samples; three datagrams never arrive."""
    raw, _, _ = frames(80)
    sent = [k for k in range(80) if k not in (40, 41, 42)]
    now = [0.0]
    stream = VendorFrames(Stim300Decoder(RATE_HZ), np.eye(3), clock=lambda: now[0])
    times = []
    for k in sent:
        now[0] = 100.0 + k / RATE_HZ + 0.002
        times += stream.feed(raw[k]).samples[:, 0].tolist()
    np.testing.assert_allclose(times, [100.002 + k / RATE_HZ for k in sent], atol=1e-9)
    counters = stream.counters()
    assert counters["seq_gaps"] == 3 and counters["seq_repeats"] == 0


def test_a_status_byte_flags_the_sample():
    enc, dec = Stim300Encoder(RATE_HZ), Stim300Decoder(RATE_HZ)
    zero = np.zeros(3)
    got = dec.feed(enc.encode(0, zero, zero) + enc.encode(1, zero, zero, status=0x01)
                   + enc.encode(2, zero, zero, status=0x10 << 8))
    assert got.status.tolist() == [0, 0x01, 0x1000]
    raw = enc.encode(3, zero, zero, status=0x80)
    assert raw[10] == 0x80 and raw[20] == raw[30] == 0


def test_a_wrong_datagram_id_is_told_once_without_crc_noise():
    """The sensor sends 0x91 (values that hold 0x93 bytes), the configuration says 0x93."""
    raw, _, _ = frames(300, datagram=0x91)
    assert any(0x93 in r[1:] for r in raw)
    dec = Stim300Decoder(RATE_HZ, 0x93)
    first, rest = dec.feed(b"".join(raw[:150])), dec.feed(b"".join(raw[150:]))
    assert first.notices == ["STIM300 sends datagram 0x91 (rate, acc) but imu.stim300.datagram is 0x93: set it to "
                             "0x91"]
    assert rest.notices == [] and len(first.counter) == len(rest.counter) == 0
    counters = dec.counters()
    assert counters["wrong_datagram"] == 300 and counters["bad_crc"] == 0 and counters["frames"] == 0


def test_a_datagram_without_accelerometers_is_refused():
    with pytest.raises(ValueError, match="no accelerometers"):
        Stim300Decoder(RATE_HZ, 0x92)
    with pytest.raises(ConfigError, match=r"imu\.stim300\.datagram: 0x90 carries no accelerometers"):
        config_from_mapping({"imu": {"format": "stim300", "stim300": {"datagram": 0x90}}})


def test_full_scale_fields_decode():
    body = bytes([0x93]) + bytes.fromhex("7FFFFF 800000 7FFFFF FF 800000 7FFFFF 800000 FF") + bytes(10) + bytes(3)
    got = Stim300Decoder(RATE_HZ).feed(body + struct.pack(">I", crc_bitwise(body + bytes(2))))
    np.testing.assert_array_equal(got.dtheta[0], np.radians(np.array([2**23 - 1, -(2**23), 2**23 - 1]) * 2.0**-21))
    np.testing.assert_array_equal(got.dv[0], np.array([-(2**23), 2**23 - 1, -(2**23)]) * 2.0**-22)
    assert got.status.tolist() == [0xFFFF]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.binary(max_size=300), max_size=12))
def test_random_bytes_never_raise_and_memory_stays_bounded(pieces):
    dec = Stim300Decoder(RATE_HZ, 0xA7)
    for piece in pieces:
        dec.feed(piece)
        assert len(dec._buffer) < max(stim300_layout(d).size for d in STIM300_DATAGRAMS)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.binary(max_size=80), st.booleans()), min_size=1, max_size=10), st.integers(1, 64))
def test_valid_datagrams_in_garbage_are_all_found(parts, piece):
    """Garbage may hold identifier bytes (false starts): every datagram is still found, whatever the pieces."""
    raw, dtheta, _ = frames(len(parts), seed=len(parts))
    data = b"".join(junk + (r + b"\r\n" if crlf else r) for (junk, crlf), r in zip(parts, raw, strict=True))
    data += bytes(64)   # a false start in the last garbage waits for a longest datagram's bytes
    dec = Stim300Decoder(RATE_HZ)
    got = [dec.feed(data[k:k + piece]) for k in range(0, len(data), piece)]
    np.testing.assert_allclose(np.concatenate([g.dtheta for g in got]), dtheta, atol=1e-8)
    assert dec.counters()["frames"] == len(parts)

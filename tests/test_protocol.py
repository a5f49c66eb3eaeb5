"""Wire formats: the serial frame (test vectors, resynchronisation, every drop counted, fuzz),
the msgpack messages and the Zenoh key expressions."""
from __future__ import annotations

import contextlib
import json
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sinsalign.protocol import messages
from sinsalign.protocol.keys import UnitKeys
from sinsalign.protocol.sequence import SequenceTracker
from sinsalign.protocol.serial_frame import (
    DTHETA_LSB_RAD,
    DV_LSB_MPS,
    MSG_IMU,
    FrameDecoder,
    decode_imu,
    encode_frame,
    encode_imu,
)
from sinsalign.service.config import ConfigError, config_from_mapping

VECTORS = json.loads((Path(__file__).parent / "vectors" / "serial_frames.json").read_text())
IMU_VECTORS = [v for v in VECTORS if "dtheta_rad" in v]


def frames(n: int, start_seq: int = 0) -> list[bytes]:
    rng = np.random.default_rng(n)
    return [encode_imu(start_seq + k, 0.005 * (k + 1), rng.normal(0, 1e-4, 3), rng.normal(0, 0.05, 3))
            for k in range(n)]


def test_first_vector_byte_by_byte():
    raw = bytes.fromhex(IMU_VECTORS[0]["hex"])
    assert raw[:2] == b"\xaa\x55" and raw[2] == 1 and raw[3] == MSG_IMU
    assert struct.unpack_from("<HHQ", raw, 4) == (28, 0, 5_000_000)
    assert struct.unpack_from("<H", raw, 16)[0] == zlib.crc32(raw[2:16]) & 0xFFFF
    assert struct.unpack_from("<6iI", raw, 18) == (0, 0, 0, 0, 0, round(0.049033 / DV_LSB_MPS), 0)
    assert struct.unpack_from("<I", raw, 46)[0] == zlib.crc32(raw[2:46])
    assert len(raw) == 50


@pytest.mark.parametrize("vector", IMU_VECTORS, ids=lambda v: v["name"])
def test_vectors_encode_to_the_checked_in_bytes_and_decode_back(vector):
    raw = encode_imu(vector["seq"], vector["t"], np.array(vector["dtheta_rad"]), np.array(vector["dv_mps"]),
                     vector["status"])
    assert raw.hex() == vector["hex"]
    (frame,) = FrameDecoder().feed(raw)
    m = decode_imu(frame)
    assert frame.seq == vector["seq"] and m.t == pytest.approx(vector["t"], abs=1e-9) and m.status == vector["status"]
    full_scale = (2**31 - 1)
    expect_theta = np.clip(vector["dtheta_rad"], -full_scale * DTHETA_LSB_RAD, full_scale * DTHETA_LSB_RAD)
    expect_dv = np.clip(vector["dv_mps"], -full_scale * DV_LSB_MPS, full_scale * DV_LSB_MPS)
    assert np.abs(np.array(m.dtheta) - expect_theta).max() <= DTHETA_LSB_RAD / 2
    assert np.abs(np.array(m.dv) - expect_dv).max() <= DV_LSB_MPS / 2
    assert m.saturated == ("saturated" in vector["name"])


def test_unknown_message_types_are_counted_and_passed_on():
    vector = next(v for v in VECTORS if v.get("msg_type") == 2)
    decoder = FrameDecoder()
    (frame,) = decoder.feed(bytes.fromhex(vector["hex"]))
    assert frame.msg_type == 2 and decoder.counters.unknown_type == 1


def test_garbage_between_frames_and_any_split_lose_nothing():
    good = frames(20)
    garbage = [bytes([0xAA]), b"\x00\xff\x55", bytes([0xAA, 0x55, 0x01]), b"noise\xaa"]
    stream = b"".join(g + f for g, f in zip(garbage * 5, good, strict=True))
    for split in (1, 2, 7, 48, 49, 1000):
        decoder = FrameDecoder()
        out = [f for k in range(0, len(stream), split) for f in decoder.feed(stream[k:k + split])]
        assert [f.seq for f in out] == list(range(20))
        assert decoder.counters.frames == 20 and decoder.counters.bad_crc == 0


@pytest.mark.parametrize(("fault", "counter"), [
    (lambda f: f[:20] + bytes([f[20] ^ 0x01]) + f[21:], "bad_crc"),          # a flipped payload bit
    (lambda f: f[:4] + struct.pack("<H", 27) + f[6:], "bad_header"),          # corrupt length field
    (lambda f: f[:30], "bad_crc"),          # truncated: the next frame's bytes fail the CRC
    (lambda f: f[:2] + b"\x02" + f[3:], "bad_header"),
])
def test_each_bad_frame_is_dropped_counted_and_the_next_frame_still_decodes(fault, counter):
    good = frames(3)
    decoder = FrameDecoder()
    out = decoder.feed(good[0] + fault(good[1]) + good[2])
    assert [f.seq for f in out] == [0, 2]
    assert getattr(decoder.counters, counter) >= 1
    assert decoder.sequence.gaps == 1


def test_sequence_gaps_repeats_and_a_restarted_counter():
    decoder = FrameDecoder()
    a = frames(10)
    out = decoder.feed(a[0] + a[1] + a[1] + a[4] + a[3])
    assert [f.seq for f in out] == [0, 1, 4]
    assert decoder.sequence.counters() == {"seq_gaps": 2, "seq_repeats": 1, "seq_backwards": 1, "seq_resets": 0}
    tracker = SequenceTracker()
    assert [tracker.accept(s) for s in (30000, 30001, 5, 6, 7, 8)] == [True, True, False, False, True, True]
    assert tracker.resets == 1 and tracker.backwards == 2
    wrap = SequenceTracker()
    assert all(wrap.accept(s & 0xFFFF) for s in range(65530, 65545)) and wrap.gaps == 0


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=200), max_size=30))
def test_fuzz_random_bytes_never_raise_and_the_buffer_stays_bounded(pieces):
    decoder = FrameDecoder()
    for piece in pieces:
        decoder.feed(piece)
        assert len(decoder._buffer) <= 18 + 1024 + 4 + len(piece)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.binary(max_size=60).map(lambda b: b.replace(b"\xaa", b"\x00")), min_size=10, max_size=10),
       st.integers(1, 97))
def test_fuzz_every_frame_survives_garbage_without_sync_bytes(garbage, split):
    good = frames(10)
    stream = b"".join(g + f for g, f in zip(garbage, good, strict=True))
    decoder = FrameDecoder()
    out = [f for k in range(0, len(stream), split) for f in decoder.feed(stream[k:k + split])]
    assert [f.seq for f in out] == list(range(10))
    assert decoder.counters.bytes_skipped == sum(len(g) for g in garbage)


def test_frames_are_self_delimiting_for_other_types():
    raw = encode_frame(9, 0, 0, b"\x01\x02\x03")
    decoder = FrameDecoder()
    (frame,) = decoder.feed(raw + encode_frame(MSG_IMU, 1, 5, bytes(28)))[:1]
    assert frame.payload == b"\x01\x02\x03" and decoder.counters.unknown_type == 1


# ---- msgpack messages --------------------------------------------------------------------
def test_imu_message_round_trip_and_version_field():
    sample = messages.ImuSample(5, 0.025, (1e-5, 2e-5, 3e-5), (0.0, 0.0, 0.049), 0)
    data = messages.pack(messages.imu_message(sample))
    assert messages.unpack_map(data)["v"] == messages.VERSION
    assert messages.decode_imu(data) == sample


@pytest.mark.parametrize(("message", "reason"), [
    (b"\xc1", "not msgpack"),
    (messages.pack([1, 2]), "expected a map"),
    (messages.pack({"v": 2}), "unsupported schema version"),
    (messages.pack({"v": 1, "seq": 1, "t": float("nan"), "dtheta": [0, 0, 0], "dv": [0, 0, 0], "status": 0}),
     "t: not finite"),
    (messages.pack({"v": 1, "seq": -1, "t": 0.1, "dtheta": [0, 0, 0], "dv": [0, 0, 0], "status": 0}), "seq"),
    (messages.pack({"v": 1, "seq": 1, "t": 0.1, "dtheta": [0, 0], "dv": [0, 0, 0], "status": 0}), "dtheta"),
    (messages.pack({"v": 1, "seq": 1, "t": "0.1", "dtheta": [0, 0, 0], "dv": [0, 0, 0], "status": 0}), "t:"),
    (messages.pack({"v": 1, "seq": 1, "t": 0.1, "dtheta": [0, 0, True], "dv": [0, 0, 0], "status": 0}), "dtheta"),
])
def test_malformed_messages_give_a_clear_reason(message, reason):
    with pytest.raises(messages.MessageError, match=reason):
        messages.decode_imu(message)


def test_aiding_messages_of_each_kind_round_trip_and_are_checked():
    gnss = messages.AidingSample("gnss", 3, 12.5, {"lat_deg": (30.0,), "lon_deg": (114.0,), "h_m": (500.0,),
                                                    "v_enu": (1.0, 50.0, 0.0)})
    assert messages.decode_aiding("gnss", messages.pack(messages.aiding_message(gnss))) == gnss
    odo = messages.AidingSample("odo", 0, 1.0, {"v_b": (0.0, 20.0, 0.0)})
    assert messages.decode_aiding("odo", messages.pack(messages.aiding_message(odo))) == odo
    with pytest.raises(messages.MessageError, match="v_b"):
        messages.decode_aiding("odo", messages.pack({"v": 1, "seq": 0, "t": 1.0, "v_b": [0, 20]}))
    with pytest.raises(messages.MessageError, match="unknown aiding kind"):
        messages.decode_aiding("lidar", messages.pack({"v": 1}))


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_fuzz_message_decoders_raise_only_message_errors(data):
    for decode in (messages.decode_imu, messages.decode_attitude, messages.decode_status,
                   lambda d: messages.decode_aiding("master", d)):
        with contextlib.suppress(messages.MessageError):
            decode(data)


# ---- key expressions ---------------------------------------------------------------------
def test_keys_of_a_unit_with_a_configurable_prefix():
    keys = UnitKeys("lab/bench2", "imu7")
    assert (keys.imu, keys.attitude, keys.status, keys.alive, keys.state, keys.aid("gnss")) == (
        "lab/bench2/imu7/imu", "lab/bench2/imu7/attitude", "lab/bench2/imu7/status", "lab/bench2/imu7/alive",
        "lab/bench2/imu7/state", "lab/bench2/imu7/aid/gnss")
    for bad in ("a/*", "", "a//b", "x$y"):
        with pytest.raises(ValueError):
            UnitKeys(bad, "u")
    with pytest.raises(ConfigError, match=r"^zenoh\.unit"):
        config_from_mapping({"zenoh": {"unit": "a/b"}})
    with pytest.raises(ConfigError, match=r"^zenoh\.listen: expected a list of strings"):
        config_from_mapping({"zenoh": {"listen": "tcp/127.0.0.1:7447"}})

"""Wire formats: the serial frame (test vectors, resynchronisation, every drop counted, fuzz),
the msgpack messages and the Zenoh key expressions."""
from __future__ import annotations

import contextlib
import json
import math
import struct
import zlib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sinsalign.protocol import messages
from sinsalign.protocol.keys import UnitKeys
from sinsalign.protocol.results import ResultRecord
from sinsalign.protocol.sequence import SequenceTracker
from sinsalign.protocol.serial_frame import (
    AIDING_KIND_CODES,
    DTHETA_LSB_RAD,
    DV_LSB_MPS,
    MSG_AIDING,
    MSG_IMU,
    PAYLOAD_SIZES,
    AidingPayloadError,
    Frame,
    FrameDecoder,
    decode_aiding,
    decode_imu,
    encode_aiding,
    encode_frame,
    encode_imu,
    encode_imu_frames,
)
from sinsalign.service.config import ConfigError, config_from_mapping

VECTORS = json.loads((Path(__file__).parents[1] / "vectors" / "serial_frames.json").read_text())
IMU_VECTORS = [v for v in VECTORS if "dtheta_rad" in v]
AIDING_VECTORS = [v for v in VECTORS if "kind" in v]
REJECTED_AIDING_VECTORS = [v for v in VECTORS if v.get("msg_type") == MSG_AIDING and "error" in v]


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
    vector = next(v for v in VECTORS if v.get("msg_type") not in (None, MSG_IMU, MSG_AIDING))
    decoder = FrameDecoder()
    (frame,) = decoder.feed(bytes.fromhex(vector["hex"]))
    assert frame.msg_type == vector["msg_type"] and decoder.counters.unknown_type == 1


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


def exact_rows(decoder: FrameDecoder, data: bytes) -> tuple[list[tuple[float, ...]], list[Frame]]:
    """What :meth:`FrameDecoder.feed_rows` must give, from the exact path: decode_imu of each IMU frame."""
    rows, others = [], []
    for frame in decoder.feed(data):
        if frame.msg_type == MSG_IMU:
            m = decode_imu(frame)
            rows.append((m.t, *m.dtheta, *m.dv, float(m.status), float(m.saturated)))
        else:
            others.append(frame)
    return rows, others


def test_frames_encoded_at_once_are_each_frame_s_bytes():
    rng = np.random.default_rng(3)
    t = 1e6 + np.cumsum(rng.uniform(1e-4, 1e-2, 300))
    dtheta, dv = rng.normal(0, 1e-3, (300, 3)), rng.normal(0, 0.1, (300, 3))
    dtheta[5] = 10.0   # beyond full scale: clipped as encode_imu clips it
    assert encode_imu_frames(65_400, t, dtheta, dv) == b"".join(
        encode_imu(65_400 + k, t[k], dtheta[k], dv[k]) for k in range(300))


FULL_SCALE = (-2**31, 2**31 - 1)
PIECE_KINDS = ("imu", "imu", "imu", "repeat", "skip", "garbage", "flip", "aiding", "other", "saturated")


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from(PIECE_KINDS), min_size=1, max_size=60), st.integers(1, 173),
       st.integers(0, 2**16 - 1), st.integers(0, 2**63))
def test_fuzz_the_compiled_run_gives_the_exact_path_s_rows_frames_and_counters(kinds, split, seq0, time0_ns):
    """Runs of plain IMU frames go through protocol/_frames.pyx; everything around them (garbage, a flipped bit, a
    repeated or skipped counter, aiding and unknown frames, a value at full scale, huge times) through the exact
    path: the same rows, bit for bit, the same frames and counters, whatever the pieces."""
    rng = np.random.default_rng(len(kinds) * split)
    pieces, seq, time_ns = [], seq0, time0_ns
    for kind in kinds:
        payload = struct.pack("<6iI", *rng.integers(-2**31, 2**31, 6), int(rng.integers(0, 2)))
        if kind == "saturated":
            payload = struct.pack("<6iI", FULL_SCALE[int(rng.integers(0, 2))], *rng.integers(-9, 9, 5), 0)
        frame = encode_frame(MSG_IMU, seq, time_ns % 2**64, payload)
        if kind == "repeat":
            pieces += [frame, frame]
        elif kind == "skip":
            seq += 1
            pieces.append(encode_frame(MSG_IMU, seq, time_ns % 2**64, payload))
        elif kind == "garbage":
            pieces.append(rng.integers(0, 256, int(rng.integers(1, 60))).astype(np.uint8).tobytes() + frame)
        elif kind == "flip":
            at = int(rng.integers(2, len(frame)))
            pieces += [frame[:at] + bytes([frame[at] ^ 0x10]) + frame[at + 1:], frame]
        elif kind == "aiding":
            pieces += [encode_aiding(int(rng.integers(0, 9)), 1.0, "odo", (0.0, 1.0, 0.0)), frame]
        elif kind == "other":
            pieces += [encode_frame(7, 0, 0, b"xyz"), frame]
        else:
            pieces.append(frame)
        seq, time_ns = (seq + 1) & 0xFFFF, time_ns + int(rng.integers(1, 10**7))
    stream = b"".join(pieces)
    fast, exact = FrameDecoder(), FrameDecoder()
    got_rows, got_others, want_rows, want_others = [], [], [], []
    for k in range(0, len(stream), split):
        rows, others = fast.feed_rows(stream[k:k + split])
        assert rows.shape[1:] == (9,)
        got_rows += [tuple(r) for r in rows.tolist()]
        got_others += others
        more_rows, more_others = exact_rows(exact, stream[k:k + split])
        want_rows += more_rows
        want_others += more_others
    assert got_rows == want_rows and got_others == want_others
    assert fast.all_counters() == exact.all_counters()
    assert fast._buffer == exact._buffer


# ---- aiding message (type 2) ------------------------------------------------------------
AIDING_EXAMPLES = {
    "odo": {"v_b": (0.0, 12.5, -0.03)},
    "gnss": {"lat_deg": (32.0,), "lon_deg": (118.8,), "h_m": (25.5,), "v_enu": (1.25, -0.5, 0.0)},
    "master": {"q": (0.5, 0.5, -0.5, 0.5), "v_enu": (10.0, 20.0, -0.25), "lat_deg": (-33.865143,),
               "lon_deg": (151.2099,), "h_m": (58.0,)},
}


def aiding_frame(payload: bytes, seq: int = 0, time_ns: int = 1_000_000_000) -> Frame:
    return Frame(MSG_AIDING, seq, time_ns, payload)


def test_aiding_vector_byte_by_byte():
    vector = next(v for v in AIDING_VECTORS if v["kind"] == "master")
    raw = bytes.fromhex(vector["hex"])
    assert raw[:2] == b"\xaa\x55" and raw[2] == 1 and raw[3] == MSG_AIDING
    assert struct.unpack_from("<HHQ", raw, 4) == (81, 65535, round(vector["t"] * 1e9))
    assert struct.unpack_from("<H", raw, 16)[0] == zlib.crc32(raw[2:16]) & 0xFFFF
    assert raw[18] == 3                      # kind code: master
    v = vector["values"]
    assert struct.unpack_from("<10d", raw, 19) == (*v["q"], *v["v_enu"], *v["lat_deg"], *v["lon_deg"], *v["h_m"])
    assert struct.unpack_from("<I", raw, 18 + 81)[0] == zlib.crc32(raw[2:18 + 81])
    assert len(raw) == 18 + 81 + 4


@pytest.mark.parametrize("vector", AIDING_VECTORS, ids=lambda v: v["name"])
def test_aiding_vectors_encode_to_the_checked_in_bytes_and_decode_back(vector):
    raw = encode_aiding(vector["seq"], vector["t"], vector["kind"], vector["values"])
    assert raw.hex() == vector["hex"]
    decoder = FrameDecoder()
    (frame,) = decoder.feed(raw)
    epoch = decode_aiding(frame)
    assert (epoch.kind, epoch.seq, epoch.t) == (vector["kind"], vector["seq"], pytest.approx(vector["t"], abs=1e-9))
    assert epoch.values == {k: tuple(v) for k, v in vector["values"].items()}     # float64: exact
    assert decoder.counters.as_dict() == {"frames": 1, "bytes_skipped": 0, "bad_header": 0, "bad_crc": 0,
                                          "bad_length": 0, "bad_version": 0, "unknown_type": 0}


@pytest.mark.parametrize("vector", REJECTED_AIDING_VECTORS, ids=lambda v: v["name"])
def test_rejected_aiding_vectors_pass_the_frame_decoder_and_fail_decode_aiding(vector):
    (frame,) = FrameDecoder().feed(bytes.fromhex(vector["hex"]))
    assert frame.payload.hex() == vector["payload_hex"]
    with pytest.raises(AidingPayloadError, match=vector["error"]):
        decode_aiding(frame)


@pytest.mark.parametrize("kind", list(AIDING_EXAMPLES))
def test_aiding_round_trip_for_each_kind_from_fields_or_flat_values(kind):
    values = AIDING_EXAMPLES[kind]
    flat = [x for field in values.values() for x in field]
    raw = encode_aiding(70000, 123.456789, kind, values)     # the counter wraps to 16 bits
    assert raw == encode_aiding(70000, 123.456789, kind, flat)
    assert len(raw) == 18 + 1 + 8 * len(flat) + 4 and raw[18] == AIDING_KIND_CODES[kind]
    (frame,) = FrameDecoder().feed(raw)
    assert decode_aiding(frame) == messages.AidingSample(kind, 70000 & 0xFFFF, 123456789000 * 1e-9, values)
    # the same fields as the Zenoh aiding message of that kind
    assert list(decode_aiding(frame).values) == list(messages.AIDING_FIELDS[kind])


def test_frame_decoder_accepts_exactly_the_aiding_lengths():
    assert PAYLOAD_SIZES[MSG_AIDING] == {25, 49, 81}
    for length in (0, 1, 24, 26, 48, 50, 80, 82, 28):
        decoder = FrameDecoder()
        assert decoder.feed(encode_frame(MSG_AIDING, 0, 0, bytes(length))) == []
        assert decoder.counters.bad_length == 1


@pytest.mark.parametrize(("payload", "reason"), [
    (b"", "aiding payload is empty"),
    (bytes([0]) + bytes(24), "unknown aiding kind code 0"),
    (bytes([4]) + bytes(80), "unknown aiding kind code 4 \\(known: 1 odo, 2 gnss, 3 master\\)"),
    (bytes([255]) + bytes(48), "unknown aiding kind code 255"),
    (bytes([1]) + bytes(80), r"aiding odo: payload of 81 bytes, expected 25"),
    (bytes([3]) + bytes(48), r"aiding master: payload of 49 bytes, expected 81"),
    (bytes([2]) + bytes(24), r"aiding gnss: payload of 25 bytes, expected 49"),
    (struct.pack("<B3d", 1, 0.0, math.inf, 0.0), "aiding odo: v_b not finite"),
    (struct.pack("<B6d", 2, math.nan, 0, 0, 0, 0, 0), "aiding gnss: lat_deg not finite"),
    (struct.pack("<B10d", 3, 1, 0, 0, 0, 0, 0, 0, 0, 0, -math.inf), "aiding master: h_m not finite"),
])
def test_bad_aiding_payloads_are_rejected_with_a_clear_reason(payload, reason):
    with pytest.raises(AidingPayloadError, match=reason) as info:
        decode_aiding(aiding_frame(payload))
    assert isinstance(info.value, messages.MessageError) and isinstance(info.value, ValueError)


@pytest.mark.parametrize(("kind", "values", "reason"), [
    ("lidar", [0.0, 0.0, 0.0], "unknown aiding kind 'lidar'"),
    ("odo", [0.0, 1.0], "aiding odo: expected 3 values, got 2"),
    ("odo", {"v_b": (0.0, 1.0)}, "aiding odo: v_b needs 3 value"),
    ("gnss", {"lat_deg": 1.0, "lon_deg": 2.0, "h_m": 3.0}, "aiding gnss: expected the fields"),
    ("odo", [0.0, float("nan"), 0.0], "aiding odo: values must be finite"),
])
def test_encode_aiding_refuses_what_the_decoder_would_reject(kind, values, reason):
    with pytest.raises(AidingPayloadError, match=reason):
        encode_aiding(0, 1.0, kind, values)


@settings(max_examples=500, deadline=None)
@given(st.one_of(st.binary(max_size=120),
                 st.builds(lambda code, body: bytes([code]) + body, st.sampled_from([0, 1, 2, 3, 4, 255]),
                           st.sampled_from([24, 48, 80]).flatmap(lambda n: st.binary(min_size=n, max_size=n)))),
       st.integers(0, 0xFFFF), st.integers(0, 2**64 - 1))
def test_fuzz_decode_aiding_raises_only_its_documented_error(payload, seq, time_ns):
    try:
        epoch = decode_aiding(Frame(MSG_AIDING, seq, time_ns, payload))
    except AidingPayloadError:
        return
    assert epoch.kind in AIDING_KIND_CODES and len(payload) == 1 + 8 * sum(messages.AIDING_FIELDS[epoch.kind].values())
    assert all(math.isfinite(x) for field in epoch.values.values() for x in field)


def test_interleaved_aiding_frames_have_their_own_sequence_and_are_no_imu_gaps():
    imu = frames(6)
    aid = [encode_aiding(500 + k, 0.005 * k + 0.001, "odo", [0.0, 1.0 * k, 0.0]) for k in range(4)]
    stream = imu[0] + aid[0] + imu[1] + aid[1] + aid[1] + imu[2] + imu[3] + aid[3] + imu[4] + imu[5]
    decoder = FrameDecoder()
    out = decoder.feed(stream)
    assert [(f.msg_type, f.seq) for f in out if f.msg_type == MSG_IMU] == [(MSG_IMU, k) for k in range(6)]
    assert [f.seq for f in out if f.msg_type == MSG_AIDING] == [500, 501, 503]
    counters = decoder.all_counters()
    assert {k: v for k, v in counters.items() if k.startswith("seq_")} == {
        "seq_gaps": 0, "seq_repeats": 0, "seq_backwards": 0, "seq_resets": 0}
    assert {k: v for k, v in counters.items() if k.startswith("aiding_seq_")} == {
        "aiding_seq_gaps": 1, "aiding_seq_repeats": 1, "aiding_seq_backwards": 0, "aiding_seq_resets": 0}
    assert counters["frames"] == 9 and counters["unknown_type"] == 0


def test_each_aiding_kind_numbers_its_own_frames():
    """An odometer at 100 Hz and a receiver at 10 Hz each count their frames: interleaved on one line they are no
    gaps or steps back of each other; a receiver's lost frame is one gap, a repeated odometer frame one repeat."""
    odo = [encode_aiding(k, 0.01 * k, "odo", [0.0, 20.0, 0.0]) for k in range(20)]
    gnss = [encode_aiding(7000 + k, 0.1 * k, "gnss", [45.0, 126.0, 150.0, 0.0, 20.0, 0.0]) for k in range(3)]
    stream = b"".join(odo[:10]) + gnss[0] + b"".join(odo[10:15]) + odo[14] + gnss[2] + b"".join(odo[15:])
    decoder = FrameDecoder()
    out = decoder.feed(stream)
    assert [f.seq for f in out if f.payload[0] == AIDING_KIND_CODES["gnss"]] == [7000, 7002]
    assert [f.seq for f in out if f.payload[0] == AIDING_KIND_CODES["odo"]] == list(range(20))
    assert {k: v for k, v in decoder.all_counters().items() if k.startswith("aiding_seq_")} == {
        "aiding_seq_gaps": 1, "aiding_seq_repeats": 1, "aiding_seq_backwards": 0, "aiding_seq_resets": 0}


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
    # a log row [t, values…] in the pinned column order is the epoch aiding_row turns back into that row
    assert messages.aiding_sample("gnss", 3, [12.5, 30.0, 114.0, 500.0, 1.0, 50.0, 0.0]) == gnss
    for kind, width in (("odo", 3), ("gnss", 6), ("master", 10)):
        row = [0.5 * k for k in range(1 + width)]
        assert messages.aiding_row(messages.aiding_sample(kind, 0, row)) == row
    with pytest.raises(messages.MessageError, match="expected t and 6 values, got 6"):
        messages.aiding_sample("gnss", 0, [1.0, 30.0, 114.0, 500.0, 1.0, 50.0])


def test_attitude_messages_carry_the_mounting_in_transfer_alignment_only():
    record = ResultRecord(1.0, "fine", (1.0, 0.0, 0.0, 0.0), 0.0, 0.0, 0.0, 0.1, 0.1, False, 1.0, 0.5, 10)
    assert "mount_q" not in messages.decode_attitude(messages.pack(messages.attitude_message("u", record)))
    mounted = replace(record, mount_q=(0.96, 0.2, 0.14, -0.14), mount_sigma_deg=0.01)
    m = messages.decode_attitude(messages.pack(messages.attitude_message("u", mounted)))
    assert (m["mount_q"], m["mount_sigma_deg"]) == ([0.96, 0.2, 0.14, -0.14], 0.01)
    wire = messages.attitude_message("u", mounted)
    for bad, reason in (({"mount_q": [1.0, 0.0, 0.0]}, "mount_q"), ({"mount_q": [1.0, 0.0, 0.0, "0"]}, "mount_q"),
                        ({"mount_sigma_deg": None}, "mount_sigma_deg"), ({"mount_sigma_deg": math.inf}, "not finite")):
        with pytest.raises(messages.MessageError, match=reason):
            messages.decode_attitude(messages.pack({**wire, **bad}))
    with pytest.raises(messages.MessageError, match="mount_q"):   # both, or neither
        messages.decode_attitude(messages.pack({**messages.attitude_message("u", record), "mount_sigma_deg": 0.01}))


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


def test_screening_rejections_are_not_faults_but_a_burst_of_them_is_an_alarm():
    """A χ² gate turns away ~0.1 % of good fixes: one rejection leaves the health ok; a glitch (ten in a
    second) or a steady share above 5 % makes the status degraded."""
    before = {"gnss_vel_accepted": 100, "gnss_vel_rejected": 1, "gnss_coarse_rejected": 0}
    isolated = {"gnss_vel_accepted": 110, "gnss_vel_rejected": 2, "gnss_coarse_rejected": 1}
    glitch = {"gnss_vel_accepted": 110, "gnss_vel_rejected": 12, "gnss_coarse_rejected": 1}
    coarse_burst = {"gnss_vel_accepted": 110, "gnss_vel_rejected": 1, "gnss_coarse_rejected": 10}
    assert messages.faults(isolated) == {} and messages.screening_alarm(before, isolated) == []
    assert messages.screening_alarm(before, glitch) == ["gnss_vel_rejected"]
    assert messages.screening_alarm(before, coarse_burst) == ["gnss_coarse_rejected"]
    assert messages.faults({"odo_rejected": 3, "seq_gaps": 1}) == {"seq_gaps": 1}


_ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True)


@settings(max_examples=400, deadline=None)
@given(st.lists(_ANY_FLOAT, min_size=11, max_size=11), st.sampled_from(["coarse", "fine", "aligned", "disturbed"]),
       st.booleans(), _ANY_FLOAT, st.integers(0, 10**15))
def test_a_record_s_line_is_the_json_encoder_s(numbers, phase, converged, trace_P, n_obs):
    """The directly formatted line of a plain record is the JSON encoder's, byte for byte; one holding a number that
    is not finite is refused as the encoder path refuses it, and is not :attr:`ResultRecord.finite`."""
    t, w, x, y, z, pitch, roll, heading, heading_sigma, level_sigma, rho = numbers
    record = ResultRecord(t, phase, (w, x, y, z), pitch, roll, heading, heading_sigma, level_sigma, converged, rho,
                          trace_P, n_obs)
    assert record.finite == all(math.isfinite(v) for v in numbers)   # the sum's shortcut: 1e308 + 1e308 too
    if all(math.isfinite(v) for v in numbers):
        assert record.to_json() == record._encoded()
        assert json.loads(record.to_json())["trace_P"] == (trace_P if math.isfinite(trace_P) else None)
    else:
        with pytest.raises(ValueError, match="not finite; not written"):
            record.to_json()


@pytest.mark.parametrize(("numbers", "mount_q", "finite"), [
    ([1.7e308] * 11, None, True),                       # their sum overflows: each one is still finite
    ([1.0] * 11, (1.0, 0.0, 0.0, math.nan), False),      # transfer alignment's mounting counts too
    ([1.0] * 11, (1.0, 0.0, 0.0, 0.0), True),
    ([1.0] * 10 + [-math.inf], None, False)])
def test_a_record_is_finite_when_every_number_is(numbers, mount_q, finite):
    t, w, x, y, z, pitch, roll, heading, heading_sigma, level_sigma, rho = numbers
    record = ResultRecord(t, "fine", (w, x, y, z), pitch, roll, heading, heading_sigma, level_sigma, False, rho,
                          math.inf, 0, mount_q, None if mount_q is None else 0.1)
    assert record.finite == finite


@settings(max_examples=50, deadline=None)
@given(st.binary(min_size=0, max_size=200))
def test_the_compiled_pass_s_crc_table_from_zlib_checks_what_zlib_checks(data):
    """The fast path's CRC-32 table is built from zlib's (serial_frame._crc32_table), not written twice."""
    from sinsalign.protocol.serial_frame import IMU_RUN
    assert IMU_RUN.crc32(np.frombuffer(data, np.uint8).copy()) == zlib.crc32(data)

"""One stream, one answer, whatever the chunking: the daemon's decode → gate → pipeline path (service/ingest.py).

GIVEN decoded samples with saturated values, gaps and time going backwards, WHEN the sample gate admits them in
calls split anywhere, THEN it restarts the alignment at the same samples for the same reasons, with the same
counters, and a cut that ends a call restarts the segment the next call begins. GIVEN a serial byte stream of
200 s of a simulated swing base with every serial fault injected (saturation, short bridged and long restarting
gaps, repeated frames, time going backwards, garbage bytes, a bad CRC), WHEN the daemon's ingest reads it in one
piece, a frame per read (a real IMU's pacing), a byte per read, in large reads or in pieces of random sizes,
THEN the records (every field, to the bit) and every counter are the same.
"""
from __future__ import annotations

import itertools
from collections.abc import Iterable, Iterator
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sinsalign.protocol.results import ResultRecord
from sinsalign.protocol.serial_frame import STATUS_GYRO_FAULT, encode_aiding, encode_frame, encode_imu
from sinsalign.service.config import config_from_mapping
from sinsalign.service.ingest import Ingest
from sinsalign.service.sample_gate import SampleGate, Segment, sample_rows
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import daemon_sections, seed_run

# ---- the sample gate ------------------------------------------------------------------------
GATE_RATE_HZ = 200.0
FULL_SCALE = (5.0, 0.0, 0.0)   # rad in one sample: beyond the wire's full scale, as decode_imu flags it


def sample(k: int, saturated: bool = False, t: float | None = None) -> tuple:
    """Sample k of a quiet 200-Hz base: t = k / 200 s (unless given), small increments."""
    t = k / GATE_RATE_HZ if t is None else t
    return (t, FULL_SCALE if saturated else (1e-6 * k, 0.0, 0.0), (0.0, 0.0, 0.05 * k), 0, saturated)


def test_a_saturated_sample_alone_in_its_call_restarts_the_segment_the_next_call_begins():
    gate = SampleGate(GATE_RATE_HZ)
    (first,) = gate.admit(sample_rows([sample(k) for k in range(1, 4)]))
    assert not first.restart
    assert gate.admit(sample_rows([sample(4, saturated=True)])) == []   # a real IMU's pacing: the frame alone in a read
    (after,) = gate.admit(sample_rows([sample(5)]))
    assert after.restart and after.reason == "saturated sample at t = 0.020000 s: alignment restarted"
    assert after.rows[:, 0].tolist() == [5 / GATE_RATE_HZ]
    (later,) = gate.admit(sample_rows([sample(6), sample(7)]))
    assert not later.restart and later.reason is None        # one restart, carried once
    assert (gate.counters.saturated, gate.counters.restarts) == (1, 1)


GATE_STREAMS: dict[str, list[tuple]] = {
    "saturated sample last of a call": [sample(1), sample(2), sample(3, saturated=True), sample(4), sample(5)],
    "two saturated samples in a row": [sample(1), sample(2, saturated=True), sample(3, saturated=True), sample(4),
                                       sample(5)],
    "saturated sample, then a gap": [sample(1), sample(2, saturated=True), sample(20), sample(21)],
    "long gap": [sample(1), sample(2), sample(20), sample(21)],
    "short gap, bridged": [sample(1), sample(2), sample(5), sample(6)],
    "long gap, then a saturated sample": [sample(1), sample(20), sample(21, saturated=True), sample(22)],
    "time going backwards, then a gap": [sample(1), sample(2), sample(1, t=0.001), sample(12), sample(13)],
    "saturated sample at the end": [sample(1), sample(2), sample(3, saturated=True)],
}


def splits(items: list) -> Iterator[list[list]]:
    """Every way of cutting ``items`` into consecutive non-empty calls (2^(n-1) of them)."""
    for cuts in itertools.product((False, True), repeat=len(items) - 1):
        calls, call = [], [items[0]]
        for item, cut in zip(items[1:], cuts, strict=True):
            if cut:
                calls.append(call)
                call = []
            call.append(item)
        yield [*calls, call]


def alignment_runs(segments: Iterable[Segment]) -> list[tuple[str | None, list[list[float]]]]:
    """The segments joined into what one pipeline sees between restarts: (why it restarted before them, rows)."""
    runs: list[tuple[str | None, list[list[float]]]] = []
    for segment in segments:
        if segment.restart or not runs:
            runs.append((segment.reason, []))
        runs[-1][1].extend(segment.rows.tolist())
    return runs


def admitted_in_calls(calls: list[list[tuple]], **ranges: float) -> tuple[list, dict[str, int], str | None]:
    gate = SampleGate(GATE_RATE_HZ, max_bridge_samples=5, **ranges)
    segments = [segment for call in calls for segment in gate.admit(sample_rows(call))]
    return alignment_runs(segments), gate.counters.as_dict(), gate.last_error


@pytest.mark.parametrize("name", list(GATE_STREAMS))
def test_the_gate_restarts_at_the_same_samples_for_the_same_reasons_however_the_calls_split_them(name):
    samples = GATE_STREAMS[name]
    whole = admitted_in_calls([samples])
    for calls in splits(samples):
        assert admitted_in_calls(calls) == whole, calls


def test_two_saturated_samples_in_a_row_are_two_cuts_and_one_restart_of_the_alignment():
    runs, counters, _ = admitted_in_calls([[s] for s in GATE_STREAMS["two saturated samples in a row"]])
    assert [reason for reason, _ in runs] == [None, "saturated sample at t = 0.015000 s: alignment restarted"]
    assert (counters["saturated"], counters["restarts"]) == (2, 2)


GATE_EVENTS = ("plain", "plain", "plain", "plain", "gap", "long gap", "repeat", "back", "clock back", "saturated",
               "flagged", "implausible", "jitter")


def hostile_samples(events: list[str]) -> list[tuple]:
    """A 200-Hz stream with each event where the list says (one sample, or the samples the event makes)."""
    out, k = [], 1
    for event in events:
        if event == "gap":
            k += 3
        elif event == "long gap":
            k += 40
        elif event == "repeat" and out:
            out.append(out[-1])
        elif event == "back" and out:
            out.append(sample(k - 3))
        elif event == "clock back":
            k = max(1, k - 200)
        if event == "saturated":
            out.append(sample(k, saturated=True))
        elif event == "flagged":
            out.append((*sample(k)[:3], 4, False))
        elif event == "implausible":
            out.append((1e308 if k % 2 else k / GATE_RATE_HZ, (1e308, 0.0, 0.0), (0.0, 0.0, 0.0), 0, False))
        elif event == "jitter":
            out.append(sample(k, t=(k + 0.4) / GATE_RATE_HZ))
        else:
            out.append(sample(k))
        k += 1
    return out


@settings(max_examples=150, deadline=None)
@given(st.lists(st.sampled_from(GATE_EVENTS), min_size=1, max_size=80), st.integers(1, 50))
def test_the_gate_s_whole_runs_admit_what_the_sample_by_sample_rules_do(events, split):
    """Runs of plain samples go in as whole arrays: the same segments, rows (to the bit), counters and last error as
    the rules applied one sample at a time (the run detection switched off), in calls of any size."""
    samples = hostile_samples(events)
    calls = [samples[k:k + split] for k in range(0, len(samples), split)]
    ranges = {"max_dtheta_rad": 1.0, "max_dv_mps": 100.0}
    whole_runs = admitted_in_calls(calls, **ranges)
    original = SampleGate._plain
    try:
        SampleGate._plain = lambda self, t, refused: np.zeros(len(t), bool)
        one_by_one = admitted_in_calls(calls, **ranges)
    finally:
        SampleGate._plain = original
    assert whole_runs == one_by_one


# ---- the daemon's ingest, on a serial stream ------------------------------------------------------
SECONDS, RATE_HZ = 200.0, 50.0
SCENARIO = replace(seed_run("seed000-swing", 0, SECONDS), rate_hz=RATE_HZ)
CONFIG = config_from_mapping(daemon_sections(SCENARIO))
(CHUNK,) = simulate(SCENARIO.motion, SCENARIO.site, SCENARIO.errors, RATE_HZ, SECONDS, 11, chunk_samples=100_000)


def at(t_s: float) -> int:
    """The index of the sample at t_s (s)."""
    return round(t_s * RATE_HZ) - 1


def frame(k: int, t: float | None = None, dtheta: tuple | None = None, status: int = 0) -> bytes:
    """IMU frame of sample k (sequence number k), with its own time, increments and status unless given."""
    return encode_imu(k, float(CHUNK.t[k]) if t is None else t, CHUNK.dtheta[k] if dtheta is None else dtheta,
                      CHUNK.dv[k], status)


def bad_crc(raw: bytes) -> bytes:
    return raw[:-1] + bytes([raw[-1] ^ 0xFF])


FAULTS: dict[int, tuple[list[bytes], int]] = {
    # sample index: (what goes on the line in its place, each piece its own write; the next sample sent)
    at(20.0): ([bytes(range(1, 100)), b"\xaa\x55" + bytes(30), frame(at(20.0)), b"\xaa"], at(20.0) + 1),
    at(30.0): ([bad_crc(frame(at(30.0)))], at(30.0) + 1),
    at(40.0): ([frame(at(40.0), dtheta=FULL_SCALE)], at(40.0) + 1),
    at(50.0): ([frame(at(50.0)), encode_aiding(0, float(CHUNK.t[at(50.0)]), "odo", [0.0, 0.0, 0.0]),
                encode_frame(2, 1, 0, bytes([7]) + bytes(24)), encode_frame(9, 0, 0, bytes(4))], at(50.0) + 1),
    at(60.0): ([], at(60.0) + 3),
    at(80.0): ([frame(at(80.0)), frame(at(80.0))], at(80.0) + 1),
    at(100.0): ([frame(at(100.0), t=float(CHUNK.t[at(100.0)]) - 1.0)], at(100.0) + 1),
    at(110.0): ([frame(at(110.0), status=STATUS_GYRO_FAULT)], at(110.0) + 1),
    at(120.0): ([frame(at(120.0), dtheta=FULL_SCALE), frame(at(120.0) + 1, dtheta=FULL_SCALE)], at(120.0) + 2),
    at(140.0): ([frame(at(140.0), dtheta=FULL_SCALE)], at(140.0) + 100),
    at(160.0): ([], at(160.0) + 100),
    at(SECONDS): ([frame(at(SECONDS), dtheta=FULL_SCALE)], at(SECONDS) + 1),
}
"""20 s garbage (with a false sync word and a lone first sync byte), 30 s a bad CRC, 40 s a saturated sample, 50 s
aiding frames the unaided mode does not use (one bad) and a frame of an unknown type, 60 s a gap of 3 samples
(bridged), 80 s a repeated frame, 100 s time going backwards, 110 s a flagged status, 120 s two saturated samples in a
row, 140 s a saturated sample and a gap of 99, 160 s a gap of 100 (restarts), the last sample saturated."""


def stream_pieces() -> list[bytes]:
    """The serial stream as a real IMU writes it: a frame per write, the faults of :data:`FAULTS` in place."""
    pieces, k = [], 0
    while k < len(CHUNK.t):
        raw, k = FAULTS.get(k, ([frame(k)], k + 1))
        pieces += raw
    return pieces


PIECES = stream_pieces()
STREAM = b"".join(PIECES)


def ingested(reads: Iterable[bytes]) -> tuple[list[ResultRecord], dict[str, int]]:
    """The records and every counter of a fresh ingest fed ``reads``, one read at a time, as the daemon's loop."""
    ingest = Ingest(CONFIG, report=lambda text: None)
    records = [record for data in reads for record in ingest.feed_bytes(data)]
    return records, ingest.all_counters()


def cut(data: bytes, sizes: Iterable[int]) -> Iterator[bytes]:
    """``data`` in consecutive reads of the given sizes (bytes), repeated until it is all read."""
    at_byte = 0
    for size in itertools.cycle(sizes):
        if at_byte >= len(data):
            return
        yield data[at_byte:at_byte + size]
        at_byte += size


@pytest.fixture(scope="module")
def in_one_read() -> tuple[list[ResultRecord], dict[str, int]]:
    return ingested([STREAM])


def assert_same(result: tuple[list[ResultRecord], dict[str, int]],
                reference: tuple[list[ResultRecord], dict[str, int]]) -> None:
    records, counters = result
    # repr: every field to the bit (round-trip float repr), NaN equal to NaN
    assert [repr(r) for r in records] == [repr(r) for r in reference[0]]
    assert counters == reference[1]


def test_the_fault_stream_is_what_the_faults_say(in_one_read):
    records, counters = in_one_read
    lost = 1 + 3 + 99 + 100   # the bad CRC, the gaps
    assert {k: v for k, v in counters.items() if v} == {
        "frames": len(CHUNK.t) - lost + 3, "bytes_skipped": 180, "bad_header": 1, "bad_crc": 1, "unknown_type": 1,
        "seq_gaps": lost, "seq_repeats": 1, "samples_in": len(CHUNK.t) - lost, "samples_in_serial": len(CHUNK.t) - lost,
        "samples_used": len(CHUNK.t) - lost - 1 - 5 + 5, "aiding_frames": 1, "bad_aiding": 1, "aiding_unused": 1,
        "time_not_increasing": 1, "samples_bridged": 1 + 3 + 1, "gaps_bridged": 3, "restarts": 6, "saturated": 5,
        "status_flagged": 1}
    # no record where no sample was admitted: the saturated ones, the long gaps
    assert sorted(set(range(1, int(SECONDS) + 1)) - {r.t for r in records}) == [40, 120, 140, 141, 160, 161, 200]
    n_obs = {r.t: r.n_obs for r in records}
    assert [n_obs[t] for t in (39.0, 42.0, 119.0, 121.0, 139.0, 142.0)] == [390, 20, 790, 9, 189, 0]   # restarted


@pytest.mark.parametrize("reads", ["a frame per read", "a byte per read", "64-kB reads"])
def test_the_stream_gives_the_same_records_and_counters_however_it_is_read(in_one_read, reads):
    chunked = {"a frame per read": PIECES, "a byte per read": cut(STREAM, [1]), "64-kB reads": cut(STREAM, [65536])}
    assert_same(ingested(chunked[reads]), in_one_read)


READ_SIZES = st.lists(st.one_of(st.integers(1, 60), st.integers(61, 4096), st.integers(4097, 200_000)),
                      min_size=1, max_size=12)
"""Read sizes (bytes), used in turn: parts of a frame, a few frames, large bursts."""


@settings(max_examples=8, deadline=None)
@given(sizes=READ_SIZES)
def test_reads_of_random_sizes_give_the_same_records_and_counters(in_one_read, sizes):
    assert_same(ingested(cut(STREAM, sizes)), in_one_read)

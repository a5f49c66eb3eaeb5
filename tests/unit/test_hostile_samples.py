"""Values that are well-formed but absurd never stop the alignment.

GIVEN a live alignment (the daemon's ingest, sans I/O, and a daemon on real Zenoh), WHEN one sample carries an
increment no IMU can measure (Δθ 1e308, Δv −1e300), an aiding epoch an impossible value (an odometer at 1e308 m/s, a
latitude of 95°, a master quaternion of norm 7), the IMU's clock goes back or one time stamp is wild, or the
estimator itself fails (raises, or puts out NaN), THEN that input is counted and dropped (the gap bridged) or the
alignment restarts, counted and told, and the records go on, every number in them finite.
"""
from __future__ import annotations

import math
import time

import numpy as np
import pytest
import zenoh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sinsalign.protocol import messages
from sinsalign.protocol.serial_frame import AIDING_KIND_CODES, MSG_AIDING, AidingPayloadError, Frame, decode_aiding
from sinsalign.service.ingest import Ingest
from support.daemon_harness import RunningDaemon, daemon_config, free_port, imu_data, wait_until

SECONDS = 12.0


@pytest.fixture(scope="module")
def data():
    return imu_data(SECONDS)


def live_ingest(tmp_path, reports: list[str]) -> Ingest:
    config = daemon_config(tmp_path, free_port(), daemon={"record_path": ""})
    return Ingest(config, reports.append)


def as_samples(t, dtheta, dv) -> np.ndarray:
    """Rows as a decoder hands them over: status 0, none saturated."""
    return np.column_stack((t, dtheta, dv, np.zeros((len(t), 2))))


def feed_in_pieces(ingest: Ingest, samples: list, piece: int = 97) -> list:
    records = []
    for start in range(0, len(samples), piece):
        records += ingest.feed_samples(samples[start:start + piece])
    return records


def assert_goes_on(records: list, t_end: float) -> None:
    assert records and all(r.finite for r in records)
    assert records[-1].t >= t_end - 1.0


@pytest.mark.parametrize("field,value", [("dtheta", 1e308), ("dv", -1e300), ("dtheta", 0.5)])
def test_an_increment_beyond_the_imus_range_is_dropped_and_bridged(tmp_path, data, field, value):
    t, dtheta, dv = (a.copy() for a in data)
    k = len(t) // 2
    (dtheta if field == "dtheta" else dv)[k, 1] = value
    reports: list[str] = []
    ingest = live_ingest(tmp_path, reports)
    records = feed_in_pieces(ingest, as_samples(t, dtheta, dv))
    counters = ingest.all_counters()
    assert (counters["implausible"], counters["samples_bridged"], counters["restarts"]) == (1, 1, 0)
    assert counters["estimator_restarts"] == 0
    assert any("beyond the IMU's range" in r for r in reports)
    assert_goes_on(records, t[-1])


def test_the_stated_range_sets_the_limit(tmp_path, data):
    """0.5 rad in one 200-Hz sample is 5700°/s: beyond 2000°/s, within a range stated as 20000°/s."""
    t, dtheta, dv = (a.copy() for a in data)
    dtheta[len(t) // 2, 1] = 0.5
    config = daemon_config(tmp_path, free_port(), daemon={"record_path": ""}, imu={"gyro_range_deg_s": 20000.0})
    ingest = Ingest(config, lambda text: None)
    feed_in_pieces(ingest, as_samples(t, dtheta, dv))
    assert ingest.all_counters()["implausible"] == 0


def test_a_clock_that_goes_back_restarts_the_alignment_and_a_wild_time_stamp_costs_a_restart_not_the_run(
        tmp_path, data):
    t, dtheta, dv = data
    half = len(t) // 2
    # the sensor restarts: its time begins again at the first sample's
    restarted = np.r_[t[:half], t[half:] - t[half] + t[0]]
    reports: list[str] = []
    ingest = live_ingest(tmp_path, reports)
    records = feed_in_pieces(ingest, as_samples(restarted, dtheta, dv))
    counters = ingest.all_counters()
    assert counters["clock_resets"] == 1 and counters["restarts"] == 1
    assert any("time went back" in r for r in reports)
    assert_goes_on(records, restarted[-1])
    # one stamp 1e9 s on (a clock could read it): the stream comes back behind it, one restart
    wild = t.copy()
    wild[half] = 1e9
    ingest = live_ingest(tmp_path, [])
    records = feed_in_pieces(ingest, as_samples(wild, dtheta, dv))
    assert ingest.all_counters()["clock_resets"] == 1
    assert_goes_on(records, t[-1])
    # one stamp 1e12 s on, beyond any clock: dropped and bridged like an absurd increment
    wild[half] = 1e12
    ingest = live_ingest(tmp_path, [])
    records = feed_in_pieces(ingest, as_samples(wild, dtheta, dv))
    counters = ingest.all_counters()
    assert (counters["implausible"], counters["clock_resets"], counters["restarts"]) == (1, 0, 0)
    assert_goes_on(records, t[-1])


def test_a_repeated_sample_is_still_a_counted_drop(tmp_path, data):
    t, dtheta, dv = data
    samples = as_samples(t, dtheta, dv)
    samples = np.insert(samples, 200, samples[199], axis=0)
    ingest = live_ingest(tmp_path, [])
    feed_in_pieces(ingest, samples)
    counters = ingest.all_counters()
    assert (counters["time_not_increasing"], counters["clock_resets"], counters["restarts"]) == (1, 0, 0)


@pytest.mark.parametrize("failure", ["raises", "nan"])
def test_an_estimator_that_fails_is_restarted_counted_and_the_records_go_on(tmp_path, data, failure):
    t, dtheta, dv = data
    reports: list[str] = []
    ingest = live_ingest(tmp_path, reports)
    samples = as_samples(t, dtheta, dv)
    records = feed_in_pieces(ingest, samples[: len(t) // 2])
    broken = ingest.pipeline
    real = broken.process

    def failing(*args, **kwargs):
        if failure == "raises":
            raise np.linalg.LinAlgError("Eigenvalues did not converge")
        out = real(*args, **kwargs)
        return [type(r)(**{**r.as_dict(), "heading_sigma_deg": math.nan}) for r in out] or [records[-1].__class__(
            **{**records[-1].as_dict(), "q": (math.nan,) * 4})]

    broken.process = failing
    records += feed_in_pieces(ingest, samples[len(t) // 2:])
    assert ingest.pipeline is not broken
    assert ingest.all_counters()["estimator_restarts"] == 1
    assert any("alignment failed" in r and "restarted" in r for r in reports)
    assert_goes_on(records, t[-1])
    assert "estimator_restarts" in messages.faults(ingest.all_counters())


ABSURD_AIDING = [
    ("odo", {"v_b": [1e308, 0.0, 0.0]}, "speed"),
    ("gnss", {"lat_deg": 95.0, "lon_deg": 118.0, "h_m": 10.0, "v_enu": [0.0, 0.0, 0.0]}, "latitude"),
    ("gnss", {"lat_deg": 32.0, "lon_deg": 118.0, "h_m": -1e308, "v_enu": [0.0, 0.0, 0.0]}, "height"),
    ("master", {"q": [7.0, 0.0, 0.0, 0.0], "v_enu": [0.0, 0.0, 0.0], "lat_deg": 32.0, "lon_deg": 118.0,
                "h_m": 0.0}, "norm"),
    ("master", {"q": [1.0, 0.0, 0.0, 0.0], "v_enu": [0.0, 5e3, 0.0], "lat_deg": 32.0, "lon_deg": 118.0,
                "h_m": 0.0}, "speed"),
]


@pytest.mark.parametrize("kind,fields,why", ABSURD_AIDING)
def test_an_impossible_aiding_epoch_is_refused_on_zenoh_and_on_serial(kind, fields, why):
    with pytest.raises(messages.MessageError, match=why):
        messages.decode_aiding(kind, messages.pack({"v": 1, "seq": 0, "t": 1.0, **fields}))
    flat = [v for value in fields.values() for v in (value if isinstance(value, list) else [value])]
    payload = bytes([AIDING_KIND_CODES[kind]]) + np.array(flat, dtype="<f8").tobytes()
    with pytest.raises(AidingPayloadError, match=why):
        decode_aiding(Frame(MSG_AIDING, 0, 1_000_000_000, payload))


def test_a_plausible_aiding_epoch_still_passes():
    fields = {"q": [0.6, 0.8, 0.0, 0.0], "v_enu": [100.0, 0.0, 0.0], "lat_deg": -90.0, "lon_deg": 180.0, "h_m": 1e4}
    assert messages.decode_aiding("master", messages.pack({"v": 1, "seq": 0, "t": 1.0, **fields})).values["q"][1] == 0.8


def test_a_peer_publishing_absurd_samples_on_the_imu_key_does_not_stop_the_daemon(tmp_path, data):
    t, dtheta, dv = data
    run = RunningDaemon(tmp_path, zenoh={"imu_input": True}, daemon={"record_path": ""})
    try:
        publisher = run.subscriber.session.declare_publisher(run.daemon.keys.imu,
                                                             congestion_control=zenoh.CongestionControl.BLOCK)
        for k in range(len(t)):
            bad = k % 400 == 200
            sample = messages.ImuSample(k, float(t[k]), (1e308, 0.0, 0.0) if bad else tuple(dtheta[k]),
                                        (0.0, -1e300, 0.0) if bad else tuple(dv[k]), 0)
            publisher.put(messages.pack(messages.imu_message(sample)))
        wait_until(lambda: run.daemon.counters.samples_in_zenoh == len(t))
        wait_until(lambda: run.subscriber.attitude and run.subscriber.attitude[-1]["t"] >= t[-1] - 1.0)
        time.sleep(0.3)
    finally:
        run.stop()
    counters = run.subscriber.status[-1]["counters"]
    assert counters["internal_errors"] == 0 and counters["estimator_restarts"] == 0
    assert counters["implausible"] == len(range(200, len(t), 400))
    assert all(math.isfinite(a["heading_deg"]) for a in run.subscriber.attitude)


FLOATS = st.one_of(st.floats(allow_nan=False, allow_infinity=False), st.sampled_from([1e308, -1e308, 5e-324, -0.0]))
FAULTS = st.lists(st.tuples(st.integers(0, 399), st.integers(0, 6), FLOATS), max_size=12)
"""(sample, column, value) replacements in the first 2 s of a 4-s stream: column 0 the time, 1-3 Δθ, 4-6 Δv."""


def run_with_faults(tmp_path, data, faults) -> None:
    t, dtheta, dv = (a[:800].copy() for a in data)
    rows = np.column_stack((t, dtheta, dv))
    for k, column, value in faults:
        rows[k, column] = value
    ingest = live_ingest(tmp_path, [])
    records = feed_in_pieces(ingest, as_samples(rows[:, 0], rows[:, 1:4], rows[:, 4:7]), piece=37)
    assert all(r.finite for r in records)
    assert records and records[-1].t >= t[-1] - 1.0     # the last 2 s are clean: the alignment publishes again
    assert ingest.all_counters()["estimator_restarts"] == 0


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(faults=FAULTS)
def test_absurd_values_anywhere_in_a_stream_never_stop_the_alignment(tmp_path, data, faults):
    run_with_faults(tmp_path, data, faults)


@pytest.mark.slow
@settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(faults=FAULTS)
def test_absurd_values_anywhere_in_a_stream_never_stop_the_alignment_long(tmp_path, data, faults):
    """1000 streams of 800 samples: 5.6·10⁶ values through the gate and the pipeline, up to 12 of them absurd."""
    run_with_faults(tmp_path, data, faults)

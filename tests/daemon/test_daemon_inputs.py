"""The daemon's inputs through real parts: a pty with pyserial and Zenoh sessions on loopback.

GIVEN a daemon with both a serial port and the Zenoh IMU topic configured, WHEN samples arrive on
either, THEN both reach the pipeline (per-input counters, records equal to the offline replay).
GIVEN aiding frames (type 2) interleaved with the IMU frames on the serial link, THEN they are
decoded and counted, the configured kind's go to its track (the others counted as unused), a bad
one is counted and dropped, and none of them counts as an IMU sequence gap. GIVEN a moving vehicle
with its odometer on Zenoh, late, or a flight with its GNSS fixes late on Zenoh or as serial aiding
frames (coarse stage alone, or on into the Kalman stage), or a slave IMU with its master INS's epochs
late (transfer alignment), THEN the samples wait for their aiding, the records equal the replay of
the recording with the aiding log, nothing counts as a fault, the GNSS-aided heading and the slave's
attitude and mounting (carried in every record of that mode) are right against the simulated truth.
"""
from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest
import zenoh
from sinsalign.protocol import messages
from sinsalign.protocol.serial_frame import MSG_AIDING, encode_aiding, encode_frame, encode_imu
from sinsalign.service.aiding import MAX_INTERVAL_S, AidingFeed, AidingTrack, AidingWait
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.service.config import Config
from sinsalign.tools.sim.aiding import (
    gnss_epochs,
    master_epochs,
    odometer_epochs,
    with_gnss_faults,
    write_body_velocity_log,
    write_gnss_log,
    write_master_log,
)
from sinsalign.tools.sim.imu import ImuChunk, simulate
from sinsalign.tools.sim.scenarios import Scenario, daemon_sections, get_scenario
from sinsalign.tools.virtual_imu import AidingPlayback, FramePlayer, PtyPair, encode_samples, write_all
from support.daemon_harness import RunningDaemon, assert_same_as_replay, imu_data, wait_until

SECONDS = 20.0
HALF = 2000   # samples: the first 10 s over serial, the rest over Zenoh


@pytest.fixture
def running(tmp_path, pty_pair):
    """Start a daemon on the pty with ``running(**sections)``; stopped after the test, even a failed one."""
    started: list[RunningDaemon] = []

    def start(**sections) -> RunningDaemon:
        started.append(RunningDaemon(tmp_path, pty_pair.port_name, **sections))
        return started[-1]

    yield start
    for run in started:
        if run.thread.is_alive():
            run.stop()


def write_stream(fd: int, data: bytes) -> None:
    """Frames written into the pty as fast as the daemon reads them (4-kB writes, each may wait for room)."""
    for at in range(0, len(data), 4096):
        write_all(fd, data[at:at + 4096])


def wait_for_status(subscriber, **counters: int) -> None:
    """Wait for a status message that arrives from now on and shows ``counters`` (at most a status period when
    the daemon is done)."""
    seen = len(subscriber.status)
    wait_until(lambda: len(subscriber.status) > seen
               and all(subscriber.status[-1]["counters"].get(name) == value for name, value in counters.items()))


def test_serial_and_zenoh_inputs_together_both_reach_the_pipeline(tmp_path, pty_pair, running):
    run = running(zenoh={"imu_input": True})
    config, daemon, subscriber = run.config, run.daemon, run.subscriber
    t, dtheta, dv = imu_data(SECONDS)
    n = len(t)
    # the first half as serial frames into the pty ...
    FramePlayer(pty_pair.master_fd, speed=50.0).play(t[:HALF], dtheta[:HALF], dv[:HALF])
    wait_until(lambda: daemon.counters.samples_in_serial == HALF)
    # ... then the rest as msgpack on the Zenoh IMU key, while the serial port stays open and idle
    publisher = subscriber.session.declare_publisher(daemon.keys.imu, congestion_control=zenoh.CongestionControl.BLOCK)
    for seq, k in enumerate(range(HALF, n)):
        sample = messages.ImuSample(seq, float(t[k]), tuple(dtheta[k]), tuple(dv[k]), 0)
        publisher.put(messages.pack(messages.imu_message(sample)))
    subscriber.wait_for(int(SECONDS / config.output.period_s), timeout_s=15)
    wait_for_status(subscriber, samples_used=n)
    run.stop()
    counters = subscriber.status[-1]["counters"]
    assert (counters["samples_in_serial"], counters["samples_in_zenoh"]) == (HALF, n - HALF)
    assert counters["samples_in"] == counters["samples_used"] == n
    assert messages.faults(counters) == {}
    assert len(subscriber.attitude) == int(SECONDS / config.output.period_s)
    assert_same_as_replay(subscriber.attitude, tmp_path / "recorded.csv", tmp_path, config)


AIDING_EPOCHS = {
    "odo": [0.0, 0.01, 0.0],
    "gnss": [32.0, 118.8, 25.5, 0.0, 0.0, 0.0],
    "master": [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 32.0, 118.8, 25.5],
}


def test_serial_aiding_frames_are_decoded_counted_and_are_no_imu_sequence_gaps(pty_pair, running):
    run = running(aiding={"inputs": ["odo"]})
    daemon, subscriber = run.daemon, run.subscriber
    t, dtheta, dv = imu_data(5.0)
    n = len(t)
    kinds = list(AIDING_EPOCHS)
    stream, expected, aid_seq = [], [], 100
    for k in range(n):
        stream.append(encode_imu(k, float(t[k]), dtheta[k], dv[k]))
        if k % 20 == 10:   # an aiding epoch every 0.1 s, between two IMU samples, each type its own counter
            kind = kinds[len(expected) % 3]
            t_aid = float(t[k]) + 0.0025
            stream.append(encode_aiding(aid_seq, t_aid, kind, AIDING_EPOCHS[kind]))
            expected.append((kind, aid_seq, t_aid))
            aid_seq += 1
        if k == n // 2:    # a well-formed frame whose aiding payload is not: kind code 7
            stream.append(encode_frame(MSG_AIDING, aid_seq, 0, bytes([7]) + bytes(24)))
            aid_seq += 1
    write_stream(pty_pair.master_fd, b"".join(stream))
    wait_until(lambda: daemon.counters.samples_used == n)
    wait_for_status(subscriber, samples_used=n)
    run.stop()
    counters = subscriber.status[-1]["counters"]
    assert counters["samples_used"] == counters["samples_in_serial"] == n
    assert counters["aiding_frames"] == len(expected) == 50 and counters["bad_aiding"] == 1
    assert counters["frames"] == n + len(expected) + 1
    odo = [e for e in expected if e[0] == "odo"]
    # the odometer epochs go to the configured odo track, the other kinds are counted as unused
    assert counters["odo_epochs"] == len(odo) == 17 and counters["aiding_unused"] == len(expected) - len(odo)
    assert daemon.ingest.tracks["odo"].latest_time == pytest.approx(odo[-1][2], abs=1e-9)
    assert all(counters.get(k, 0) == 0 for k in ("seq_gaps", "seq_repeats", "odo_repeats", "odo_out_of_order",
                                                  "odo_non_finite", "odo_gaps"))
    assert "unknown aiding kind code 7" in subscriber.status[-1]["last_error"]


# ---- aided modes: a moving vehicle, its aiding late -------------------------------------------
def test_the_daemon_tells_when_the_data_are_far_noisier_than_its_datasheet(tmp_path, pty_pair, running):
    """GIVEN [sensor] figures ten times quieter than the IMU on the line (the 200 s of the seed-000 swing as serial
    frames), THEN the status's last_error names the noise the data show and says σ takes it (the pipeline's
    verdict once the residual shows it surely louder, tests/unit/test_noise_check.py), and nothing counts as a fault."""
    scenario = get_scenario("seed000-swing")
    sections = daemon_sections(scenario)
    sections["sensor"] = {**sections["sensor"], "acc_vrw_ug_rthz": sections["sensor"]["acc_vrw_ug_rthz"] / 10}
    run = running(**sections)
    chunk = simulated_run(scenario, 200.0)
    write_stream(pty_pair.master_fd, encode_samples(chunk.t, chunk.dtheta, chunk.dv, 0))
    wait_until(lambda: run.daemon.counters.samples_used == len(chunk.t))
    wait_for_status(run.subscriber, samples_used=len(chunk.t))
    run.stop()
    status = run.subscriber.status[-1]
    assert "accelerometer noise" in status["last_error"] and "σ uses the measured figure" in status["last_error"]
    assert messages.faults(status["counters"]) == {}


@pytest.mark.parametrize("stated_hz", [400.0, 100.0])
def test_the_daemon_aligns_nothing_on_samples_that_do_not_step_at_its_imu_rate(tmp_path, pty_pair, running,
                                                                                stated_hz):
    """GIVEN imu.rate_hz twice (or half) the rate of the IMU on the line (60 s of the seed-000 swing at 200 Hz),
    THEN after the first 101 samples the alignment restarts and takes no sample (no attitude), every sample after the
    first (held for its step until the verdict) is counted as `rate_mismatch`, health degrades, and last_error names
    both periods and the key to set. At twice the rate every sample would otherwise seem to follow a lost one and be
    bridged: a heading 165° off."""
    scenario = get_scenario("seed000-swing")
    sections = daemon_sections(scenario)
    sections["imu"] = {**sections.get("imu", {}), "rate_hz": stated_hz}
    run = running(**sections)
    chunk = simulated_run(scenario, 60.0)
    n = len(chunk.t)
    write_stream(pty_pair.master_fd, encode_samples(chunk.t, chunk.dtheta, chunk.dv, 0))
    wait_until(lambda: run.daemon.ingest.counters.samples_in == n)
    wait_for_status(run.subscriber, samples_in=n)
    run.stop()
    statuses = run.subscriber.status
    counters = statuses[-1]["counters"]
    assert counters["rate_mismatch"] == n - 1 and counters["restarts"] == 1   # the first window held, then dropped
    assert counters["samples_used"] - counters["samples_bridged"] <= 101
    assert statuses[-1]["last_error"].startswith(
        f"samples come every 5 ms (200 Hz, the median of 100 steps), where imu.rate_hz = {stated_hz:g} says "
        f"{1e3 / stated_hz:g} ms: no sample is aligned until they do (set imu.rate_hz to the IMU's rate)")
    assert any(s["health"] == "degraded" for s in statuses)
    assert all(record["t"] <= 101 / 200.0 for record in run.subscriber.attitude)


@pytest.mark.parametrize("new_hz", [400.0, 100.0])
def test_the_daemon_stops_aligning_within_2_s_when_the_imu_rate_changes_late(tmp_path, pty_pair, running, new_hz):
    """GIVEN an IMU at the configured 200 Hz for 90 s of the seed-000 swing that then changes its output rate to
    400 Hz (or 100 Hz) on the live line, THEN the alignment restarts within 2 s of data naming both rates, takes no
    sample after (no attitude, `rate_mismatch` counted, nothing more bridged), and no record before is beyond 3σ.
    Checked only on the first 100 steps, the 400-Hz stream was reported converged 2.3° off under σ 0.1°, the
    100-Hz one had every other sample invented by bridging (54 000) and 8.5° of heading error."""
    scenario = get_scenario("seed000-swing")
    change_s, fast_hz = 90.0, max(200.0, new_hz)
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, fast_hz, change_s + 10.0, 1,
                        chunk_samples=10**6)
    # the IMU's own outputs at each rate: the fast simulation's increments summed over each output interval
    before = chunk.t <= change_s + 1e-9
    parts = [(chunk.t[before], chunk.dtheta[before], chunk.dv[before], int(fast_hz / 200.0)),
             (chunk.t[~before], chunk.dtheta[~before], chunk.dv[~before], int(fast_hz / new_hz))]
    t, dtheta, dv = (np.concatenate([summed(part[k], part[3], k == 0) for part in parts]) for k in range(3))
    run = running(**daemon_sections(scenario))
    write_stream(pty_pair.master_fd, encode_samples(t, dtheta, dv, 0))
    wait_until(lambda: run.daemon.ingest.counters.samples_in == len(t))
    wait_for_status(run.subscriber, samples_in=len(t))
    run.stop()
    status = run.subscriber.status[-1]
    counters = status["counters"]
    assert counters["restarts"] == 1 and counters["rate_mismatch"] >= len(t) - np.searchsorted(t, change_s + 2.0)
    assert status["last_error"].startswith(f"samples come every {1e3 / new_hz:g} ms ({new_hz:g} Hz, the median of "
                                           "100 steps), where imu.rate_hz = 200 says 5 ms")
    assert counters["samples_bridged"] <= 100
    records = run.subscriber.attitude
    assert max(r["t"] for r in records) <= change_s + 2.0
    record_t, phi = attitude_errors_deg(scenario, records)
    heading_sigma = np.array([r["heading_sigma_deg"] for r in records])
    level_sigma = np.array([r["level_sigma_deg"] for r in records])
    beyond = (np.abs(phi[:, 2]) > 3.0 * heading_sigma) | (np.abs(phi[:, :2]).max(axis=1) > 3.0 * level_sigma)
    # the coarse stage's first seconds (the swing's own figures, not converged) aside: from 30 s to the last record
    assert not (beyond & (record_t >= 30.0)).any() and not (beyond & [r["converged"] for r in records]).any()


def summed(values: np.ndarray, factor: int, is_time: bool) -> np.ndarray:
    """Consecutive samples' times (the last of each ``factor``) or increments (their sum)."""
    grouped = values[:len(values) // factor * factor].reshape(-1, factor, *values.shape[1:])
    return grouped[:, -1] if is_time else grouped.sum(axis=1)


def simulated_run(scenario: Scenario, seconds: float) -> ImuChunk:
    """Seed 1 of ``scenario``: ``seconds`` of IMU samples in one chunk (t in s, Δθ in rad, Δv in m/s)."""
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, seconds, 1,
                        chunk_samples=10**6)
    return chunk


def send_late(publisher: zenoh.Publisher, kind: str, epochs: np.ndarray, speed: float,
              late_s: float) -> threading.Thread:
    """A started thread publishing aiding epochs (N, 1 + values: t in s, then the kind's pinned log columns)
    at ``speed`` × real time, ``late_s`` seconds of data behind IMU frames played from now."""
    def send() -> None:
        time.sleep(late_s / speed)
        start = time.monotonic()
        for seq, row in enumerate(epochs):
            delay = row[0] / speed - (time.monotonic() - start)
            if delay > 0:
                time.sleep(delay)
            publisher.put(messages.pack(messages.aiding_message(messages.aiding_sample(kind, seq, row))))

    sender = threading.Thread(target=send)
    sender.start()
    return sender


def frames_with_aiding(chunk: ImuChunk, kind: str, epochs: np.ndarray, late_s: float) -> bytes:
    """IMU frames (type 1) with an aiding frame (type 2) of ``kind`` for each epoch (N, 1 + values) interleaved
    ``late_s`` seconds of data after its time stamp (after the last IMU frame if that is later)."""
    aiding = AidingPlayback(kind, epochs, late_s)
    return encode_samples(chunk.t, chunk.dtheta, chunk.dv, 0, [aiding]) + aiding.rest()


def test_the_daemon_aligns_a_moving_vehicle_with_odometer_epochs_arriving_late_over_zenoh(tmp_path, pty_pair,
                                                                                          running):
    """IMU frames on the pty, the odometer on …/aid/odo two seconds of data behind: the samples wait for
    their aiding, and the records equal the offline replay of the recording with the odometer log."""
    scenario = get_scenario("seed003-20").for_seed(1)
    seconds, speed = 125.0, 10.0   # the default 120-s window, then the Kalman stage
    chunk = simulated_run(scenario, seconds)
    epochs = odometer_epochs(scenario, 1)[:round(seconds * 100)]
    run = running(**daemon_sections(scenario), aiding={"inputs": ["odo"], "max_wait_s": 10.0})
    daemon, subscriber = run.daemon, run.subscriber
    publisher = subscriber.session.declare_publisher(daemon.keys.aid("odo"),
                                                     congestion_control=zenoh.CongestionControl.BLOCK)
    sender = send_late(publisher, "odo", epochs, speed, late_s=2.0)
    FramePlayer(pty_pair.master_fd, speed=speed).play(chunk.t, chunk.dtheta, chunk.dv)
    sender.join()
    n_records = int(seconds / run.config.output.period_s)
    subscriber.wait_for(n_records, timeout_s=30)
    wait_for_status(subscriber, samples_used=len(chunk.t), odo_epochs=len(epochs))
    run.stop()
    counters = subscriber.status[-1]["counters"]
    assert counters["odo_epochs"] == len(epochs) and counters["samples_used"] == len(chunk.t)
    assert messages.faults(counters) == {}
    assert len(subscriber.attitude) == n_records
    assert subscriber.attitude[-1]["phase"] in ("fine", "aligned")
    write_body_velocity_log(tmp_path / "odo.csv", epochs[:, 0], epochs[:, 1:])
    assert_same_as_replay(subscriber.attitude, tmp_path / "recorded.csv", tmp_path, run.config,
                          {"odo": str(tmp_path / "odo.csv")})


def run_aided(tmp_path: Path, pty_pair: PtyPair, running, scenario: Scenario, kind: str, epochs: np.ndarray,
              seconds: float, speed: float, late_s: float, transport: str,
              aiding: dict) -> tuple[list[dict], dict[str, int], Config]:
    """``seconds`` of seed 1 of ``scenario`` through a daemon in the aided mode ``kind`` (its [aiding] table
    ``aiding`` besides ``inputs``), the aiding ``epochs`` (N, 1 + values) ``late_s`` of data behind the IMU
    frames on the pty: on …/aid/<kind> with the frames played at ``speed`` × real time (``transport``
    "zenoh"), or as serial aiding frames among the IMU frames, written as fast as the daemon reads them
    ("serial"). Checks that every epoch and sample was used and each output epoch published; returns the
    records, the last status counters and the daemon's configuration (for the replay)."""
    chunk = simulated_run(scenario, seconds)
    run = running(**daemon_sections(scenario), aiding={"inputs": [kind], **aiding})
    daemon, subscriber = run.daemon, run.subscriber
    if transport == "zenoh":
        publisher = subscriber.session.declare_publisher(daemon.keys.aid(kind),
                                                         congestion_control=zenoh.CongestionControl.BLOCK)
        sender = send_late(publisher, kind, epochs, speed, late_s)
        FramePlayer(pty_pair.master_fd, speed=speed).play(chunk.t, chunk.dtheta, chunk.dv)
        sender.join()
    else:
        write_stream(pty_pair.master_fd, frames_with_aiding(chunk, kind, epochs, late_s))
    n_records = int(seconds / run.config.output.period_s)
    subscriber.wait_for(n_records, timeout_s=20)
    wait_for_status(subscriber, samples_used=len(chunk.t), **{f"{kind}_epochs": len(epochs)})
    run.stop()
    counters = subscriber.status[-1]["counters"]
    assert counters[f"{kind}_epochs"] == len(epochs) and counters["samples_used"] == len(chunk.t)
    assert counters["aiding_frames"] == (len(epochs) if transport == "serial" else 0)
    assert len(subscriber.attitude) == n_records
    return subscriber.attitude, counters, run.config


GNSS_SECONDS, GNSS_SPEED, GNSS_LATE_S = 24.0, 10.0, 2.0
"""Seed-004 flight played for 24 s of data at ×10, the fixes 2 s of data late."""


def fly_with_gnss(tmp_path: Path, pty_pair: PtyPair, running, transport: str,
                  handover_s: float) -> tuple[list[dict], dict[str, int], Scenario]:
    """The seed-004 flight through the daemon (:func:`run_aided`), its GNSS fixes (50 Hz, antenna 1 m from the
    IMU on every axis) ``GNSS_LATE_S`` of data late; the Kalman stage from ``handover_s`` (s) of data. Checks
    that nothing counted as a fault and the records equal the offline replay with the GNSS log; returns the
    records, the last status counters and the scenario."""
    scenario = get_scenario("seed004").for_seed(1)
    epochs = gnss_epochs(scenario, 1)[:round(GNSS_SECONDS * scenario.gnss.rate_hz)]
    assert len(epochs) == 1200
    lever_b = scenario.gnss.lever_b
    records, counters, config = run_aided(tmp_path, pty_pair, running, scenario, "gnss", epochs, GNSS_SECONDS,
                                          GNSS_SPEED, GNSS_LATE_S, transport,
                                          {"gnss": {"lever_m": list(lever_b), "handover_s": handover_s},
                                           "max_wait_s": 10.0})
    assert messages.faults(counters) == {}
    write_gnss_log(tmp_path / "gnss.csv", epochs, lever_b)
    assert_same_as_replay(records, tmp_path / "recorded.csv", tmp_path, config, {"gnss": str(tmp_path / "gnss.csv")})
    return records, counters, scenario


def attitude_errors_deg(scenario: Scenario, records: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    """Output epochs t (N,) in s and the misalignment φ (N, 3: E, N, U) of the records against the truth, degrees."""
    t = np.array([m["t"] for m in records])
    return t, misalignment(dcm_from_quat(np.array([m["q"] for m in records])), scenario.motion.attitude(t)) / DEG


@pytest.mark.parametrize("transport", ["zenoh", "serial"])
def test_the_daemon_aligns_a_flight_with_gnss_fixes_arriving_late(tmp_path, pty_pair, running, transport):
    """GNSS fixes late on …/aid/gnss or as serial aiding frames: the samples wait for their fixes, the records
    equal the offline replay with the GNSS log, and the heading is right against the truth early (only with
    the lever arm compensated) and late (only with the columns in their order)."""
    # aiding.gnss.handover_s beyond the run: the VIF coarse stage alone, whatever the Kalman stage's default
    records, counters, scenario = fly_with_gnss(tmp_path, pty_pair, running, transport, handover_s=60.0)
    assert counters["gnss_vel_accepted"] == counters["gnss_pos_accepted"] == 0
    t, phi = attitude_errors_deg(scenario, records)
    late = t >= 20.0
    # seed 1 measured: -0.21° at 5 s (a 1-m lever arm ignored: -1.65°; its x sign flipped: -1.27°), at most
    # 0.081° from 20 s (velocity before position or vE, vN swapped: > 100°; fixes 0.1 s late: 0.45°; vU sign
    # flipped: 0.34°) and level at most 0.018° from 20 s (vU sign flipped: 0.15°; lat and lon swapped: 0.083°;
    # the lever's x sign flipped: 0.079°)
    assert abs(phi[t == 5.0, 2][0]) < 0.6
    assert np.abs(phi[late, 2]).max() < 0.2 and np.abs(phi[late, :2]).max() < 0.05


def test_the_daemon_runs_the_gnss_kalman_stage_on_serial_aiding_frames(tmp_path, pty_pair, running):
    """The Kalman stage from 12 s, live: its GNSS velocity and position updates are counted as work, not
    faults, its records equal the replay's, and the heading stays right from 20 s (seed 1: at most 0.071°)."""
    records, counters, scenario = fly_with_gnss(tmp_path, pty_pair, running, "serial", handover_s=12.0)
    assert counters["gnss_vel_accepted"] > 0 and counters["gnss_pos_accepted"] > 0
    assert records[-1]["phase"] in ("fine", "aligned")
    t, phi = attitude_errors_deg(scenario, records)
    assert np.abs(phi[t >= 20.0, 2]).max() < 0.2


def test_the_daemon_takes_a_1_hz_receiver_one_fix_at_a_time_without_faults(tmp_path, pty_pair, running):
    """GIVEN a 1-Hz GNSS receiver with the default configuration (max_gap_s and max_wait_s 0.5: the samples wait
    for the stream's own interval plus max_wait_s), fixes 0.3 s of data late as serial aiding frames, THEN its 1-s
    intervals are no gaps, no fault is counted (the 9 observations before the first fix await it), the Kalman stage
    takes each fix once (one update per fix, not one per 0.1-s step), the records equal the replay's and the heading
    is right. (With the wait at max_wait_s alone, half of every interval went unaided.)"""
    scenario = get_scenario("seed004").with_aid_rate(1.0).for_seed(1)
    epochs = gnss_epochs(scenario, 1)[:round(GNSS_SECONDS)]
    records, counters, config = run_aided(tmp_path, pty_pair, running, scenario, "gnss", epochs, GNSS_SECONDS,
                                          GNSS_SPEED, 0.3, "serial",
                                          {"gnss": {"lever_m": list(scenario.gnss.lever_b), "handover_s": 12.0}})
    assert messages.faults(counters) == {} and counters["gnss_observations_awaiting_aid"] == 9
    fixes_in_kalman_stage = int((epochs[:, 0] > 12.0).sum())
    assert counters["gnss_vel_accepted"] + counters.get("gnss_vel_rejected", 0) == fixes_in_kalman_stage
    assert counters["gnss_pos_accepted"] + counters.get("gnss_pos_rejected", 0) == fixes_in_kalman_stage
    write_gnss_log(tmp_path / "gnss.csv", epochs, scenario.gnss.lever_b)
    assert_same_as_replay(records, tmp_path / "recorded.csv", tmp_path, config, {"gnss": str(tmp_path / "gnss.csv")})
    t, phi = attitude_errors_deg(scenario, records)
    sigma = np.array([m["heading_sigma_deg"] for m in records])
    # seed 1 measured: 2.6° at 5 s, 0.45° at 20 s (twelve fixes before the hand-over), 0.13° at 24 s, at most 1.17σ
    assert (np.abs(phi[t >= 5.0, 2]) <= 3.0 * sigma[t >= 5.0]).all() and abs(phi[-1, 2]) < 0.2


def test_a_gnss_mode_without_a_fix_yet_is_starting_not_degraded_across_a_restart(pty_pair, running):
    """GIVEN the GNSS mode and IMU frames but no fix (a receiver still searching), 3 s, a 1-s outage of the IMU
    (the alignment restarts) and 2 s more, THEN every status is "starting" and says no epoch has come yet, save the
    outage's (degraded: the IMU's gap and restart are faults); the observations that waited are counted over both
    pipelines as work, and none is counted as unaided (a fault)."""
    scenario = get_scenario("seed004")
    max_wait_s = 0.2
    run = running(**daemon_sections(scenario), aiding={"inputs": ["gnss"], "max_wait_s": max_wait_s})
    chunk = simulated_run(scenario, 6.0)
    first, rest = slice(0, 300), slice(400, 600)
    write_stream(pty_pair.master_fd, encode_samples(chunk.t[first], chunk.dtheta[first], chunk.dv[first], 0))
    wait_until(lambda: run.daemon.counters.samples_used == 300)
    time.sleep(0.3)   # a status period
    write_stream(pty_pair.master_fd, encode_samples(chunk.t[rest], chunk.dtheta[rest], chunk.dv[rest], 400))
    wait_until(lambda: run.daemon.counters.samples_used == 500)
    time.sleep(0.3)
    run.stop()
    statuses = [s for s in run.subscriber.status if s["counters"].get("samples_used")]
    assert {s["health"] for s in statuses} == {"starting", "degraded"} and statuses[-1]["health"] == "starting"
    assert all(s["last_error"].startswith("no gnss epoch yet after") for s in statuses if s["health"] == "starting")
    counters = statuses[-1]["counters"]
    assert messages.faults(counters) == {"seq_gaps": 100, "restarts": 1}
    # every 0.1-s observation before the outage (the restart hands the old pipeline what waited), and after it
    # those of the samples released: all but the last max_wait_s of data (the control step's end takes them)
    assert counters["gnss_observations_awaiting_aid"] == 30 + round((6.0 - max_wait_s - 4.0) / 0.1)
    assert counters["gnss_unaided_observations"] == 0


def test_fixes_off_the_imus_clock_are_named_and_degrade_health_after_the_grace(pty_pair, running):
    """GIVEN GNSS fixes that arrive all along but are stamped 100 s behind the IMU (another clock, or a latency in
    the wrong unit), THEN the status says the epochs arrive but none covers the IMU's time, health is "starting"
    for the grace of 30 s of IMU data (a receiver's warm start) and "degraded" after it."""
    scenario = get_scenario("seed004")
    run = running(**daemon_sections(scenario), aiding={"inputs": ["gnss"]})
    chunk = simulated_run(scenario, 35.0)
    epochs = gnss_epochs(scenario.for_seed(1), 1)[:round(35.0 * scenario.gnss.rate_hz)]
    aiding = AidingPlayback("gnss", epochs, -100.0 + 0.1)   # sent in step with the IMU frames, stamped t - 100 s
    stream = encode_samples(chunk.t + 100.0, chunk.dtheta, chunk.dv, 0, [aiding]) + aiding.rest()
    frames_10_s = stream.index(encode_imu(1000, chunk.t[1000] + 100.0, chunk.dtheta[1000], chunk.dv[1000]))
    write_stream(pty_pair.master_fd, stream[:frames_10_s])
    wait_until(lambda: run.daemon.counters.samples_used == 1000)
    time.sleep(0.3)
    write_stream(pty_pair.master_fd, stream[frames_10_s:])
    wait_until(lambda: run.daemon.counters.samples_used == len(chunk.t))
    time.sleep(0.3)
    run.stop()
    # a status between the first fix and the first IMU sample has nothing to say yet (no IMU time to compare)
    statuses = [s for s in run.subscriber.status
                if s["counters"].get("gnss_epochs") and s["counters"].get("samples_used")]
    assert statuses[0]["health"] == "starting" and statuses[-1]["health"] == "degraded"
    assert all("gnss epochs arrive" in s["last_error"] and "none covers the IMU's time" in s["last_error"]
               for s in statuses)
    assert statuses[-1]["counters"]["gnss_epochs"] == len(epochs)


def test_after_the_aid_began_a_dead_receiver_is_a_fault_across_a_restart(pty_pair, running):
    """GIVEN fixes for the first 3 s, then none (the receiver died), and an IMU outage that restarts the alignment,
    THEN the observations after the fixes stop are unaided (a fault) before and after the restart, none of them
    awaits the aid, health degrades (a fault counter rose) but never goes back to "starting", and the status names
    the silence (it kept the last event's text, the restart's)."""
    scenario = get_scenario("seed004")
    run = running(**daemon_sections(scenario), aiding={"inputs": ["gnss"]})
    chunk = simulated_run(scenario, 9.0)
    epochs = gnss_epochs(scenario.for_seed(1), 1)
    aiding = AidingPlayback("gnss", epochs[epochs[:, 0] <= 3.0], 0.1)
    first, rest = slice(0, 400), slice(500, 900)
    write_stream(pty_pair.master_fd, encode_samples(chunk.t[first], chunk.dtheta[first], chunk.dv[first], 0, [aiding])
                 + aiding.rest())
    wait_until(lambda: run.daemon.counters.samples_used == 400)
    time.sleep(0.3)
    write_stream(pty_pair.master_fd, encode_samples(chunk.t[rest], chunk.dtheta[rest], chunk.dv[rest], 500))
    wait_until(lambda: run.daemon.counters.samples_used == 800)
    time.sleep(0.3)
    run.stop()
    statuses = [s for s in run.subscriber.status if s["counters"].get("gnss_epochs")]
    counters = statuses[-1]["counters"]
    assert counters["restarts"] == 1 and counters["gnss_observations_awaiting_aid"] == 0
    assert counters["gnss_unaided_observations"] >= 10 + 30   # 3-4 s before the outage, 5-8.5 s after it
    assert "starting" not in {s["health"] for s in statuses} and "degraded" in {s["health"] for s in statuses}
    # the status says what is missing while it is, across the restart (whose own report came later)
    stopped = "gnss epochs stopped after t = 3.00 s"
    assert statuses[-1]["last_error"].startswith(stopped) and run.daemon.last_error != statuses[-1]["last_error"]


def test_a_sample_waits_for_the_streams_own_interval_plus_max_wait_s():
    """Before the first epoch max_wait_s (nothing earlier can be interpolated); after it the stream's interval is
    added, MAX_INTERVAL_S until a second epoch shows it and at most that; a sample after a 1-Hz fix waits for the next
    one, not max_wait_s; a 0.5-Hz receiver's first interval is waited for too (with 1 s assumed, its samples up to
    0.9 s went unaided once at start)."""
    slow = AidingWait([AidingTrack(1, max_gap_s=3.0)], max_wait_s=0.5)
    slow.tracks[0].push(np.array([[0.0, 1.0]]))
    slow.push(np.column_stack((np.arange(1, 241) / 100.0, np.zeros((240, 6)))))   # to 2.4 s, the fix at 2 s late
    assert len(slow.release()[0]) == 0
    slow.tracks[0].push(np.array([[2.0, 2.0]]))
    out, aid = slow.release()
    assert out[-1, 0] == 2.0 and np.allclose(aid[:, 1], 1.0 + out[:, 0] / 2.0)
    wait = AidingWait([AidingTrack(1)], max_wait_s=0.5)
    assert wait.wait_s(wait.tracks[0]) == 0.5
    wait.tracks[0].push(np.array([[0.0, 1.0]]))
    assert wait.wait_s(wait.tracks[0]) == 0.5 + MAX_INTERVAL_S
    wait.tracks[0].push(np.array([[1.0, 2.0]]))
    assert wait.wait_s(wait.tracks[0]) == 1.5
    wait.push(np.column_stack((np.arange(101, 241) / 100.0, np.zeros((140, 6)))))   # 1.01-2.40 s
    out, _ = wait.release()
    assert len(out) == 0                                     # 0.9 s of data after 2.4 s: the next fix is not due
    wait.tracks[0].push(np.array([[2.0, 3.0]]))
    out, aid = wait.release()
    assert out[-1, 0] == 2.0 and np.allclose(aid[:, 1], 1.0 + out[:, 0])   # interpolated between the fixes
    wait.push(np.column_stack((np.arange(241, 361) / 100.0, np.zeros((120, 6)))))   # to 3.6 s: the fix at 3 s late
    out, aid = wait.release()
    assert out[-1, 0] == 2.1 and np.isnan(aid[:, 1]).all()  # overdue by max_wait_s: those go unaided
    for interval in (0.02, 0.1):
        fast = AidingWait([AidingTrack(1)], max_wait_s=0.5)
        fast.tracks[0].push(np.column_stack((np.arange(20) * interval, np.ones(20))))
        assert fast.wait_s(fast.tracks[0]) == pytest.approx(0.5 + interval)
    lone = AidingWait([AidingTrack(1)], max_wait_s=0.5)          # a fix, ten minutes without sky, one fix
    lone.tracks[0].push(np.array([[0.0, 1.0], [600.0, 1.0]]))
    assert lone.wait_s(lone.tracks[0]) == 0.5 + MAX_INTERVAL_S   # not 600.5 s: the output must not stop that long


def test_a_sample_waits_for_every_stream_of_the_mode_each_for_its_own_interval():
    """Two streams (an odometer at 100 Hz, a receiver at 10 Hz): a sample leaves once both hold an epoch at or after
    it, or once it is overdue for the one that lags; its aiding is both tracks' rows side by side."""
    odo, gnss = AidingTrack(1), AidingTrack(1)
    wait = AidingWait([odo, gnss], max_wait_s=0.5)
    odo.push(np.column_stack((np.arange(0, 101) / 100.0, np.arange(0, 101) / 100.0)))     # 0-1 s
    gnss.push(np.column_stack((np.arange(0, 6) / 10.0, 10.0 + np.arange(0, 6) / 10.0)))  # 0-0.5 s
    wait.push(np.column_stack((np.arange(1, 101) / 100.0, np.zeros((100, 6)))))           # 0.01-1 s
    out, aid = wait.release()
    assert out[-1, 0] == 0.5 and aid.shape == (50, 4)                       # the receiver's newest fix holds them
    assert np.allclose(aid[:, 1], out[:, 0]) and np.allclose(aid[:, 3], 10.0 + out[:, 0])
    assert np.array_equal(aid[:, 0], np.arange(1, 51)) and np.array_equal(aid[:, 2], np.floor(out[:, 0] * 10 + 1e-9))
    wait.push(np.column_stack((np.arange(101, 201) / 100.0, np.zeros((100, 6)))))         # to 2 s, no fix since 0.5 s
    out, aid = wait.release()
    # overdue for the receiver after 2 − (0.5 + its 0.1-s interval) = 1.4 s; the odometer's values end at 1 s
    assert out[-1, 0] == pytest.approx(1.4) and np.isnan(aid[:, 3]).all()
    assert np.isfinite(aid[out[:, 0] <= 1.0, 1]).all() and np.isnan(aid[out[:, 0] > 1.0, 1]).all()


def test_the_wait_gives_back_every_sample_once_in_order_whatever_the_pushes():
    """The held samples live in one store that grows in doublings (not re-concatenated on every push): pushes of 1 to
    700 rows, past the store's first size, come back whole, in order, and a released block is the caller's (a later
    push does not overwrite it)."""
    rng = np.random.default_rng(4)
    rows = np.column_stack((np.arange(1, 3001) / 200.0, rng.normal(size=(3000, 6))))
    wait = AidingWait([AidingTrack(1)], max_wait_s=2.0)   # no epoch ever: a sample leaves 2 s of data after it
    released, start = [], 0
    for size in (1, 700, 3, 500, 1, 650, 145, 1000):
        wait.push(rows[start:start + size])
        start += size
        out, aid = wait.release()
        assert np.isnan(aid[:, 1]).all() and (len(out) == 0 or out[-1, 0] <= rows[start - 1, 0] - 2.0 + 1e-6)
        released.append(out)
        assert wait.held == start - sum(len(r) for r in released)
    assert released[1].size and released[1][0, 0] == rows[0, 0]   # still the first rows after later pushes
    out, _ = wait.release(everything=True)
    assert np.array_equal(np.concatenate([*released, out]), rows) and wait.held == 0

def test_a_burst_of_gnss_glitches_in_the_kalman_stage_raises_the_screening_alarm_live(tmp_path, pty_pair, running):
    """GIVEN a 2-s GNSS glitch (20 m/s east, 50 m north) after the Kalman stage has started, THEN the gate turns
    the glitch fixes away (counted as screening, not faults), a status reports health "degraded" for the burst,
    and the heading stays right."""
    scenario = get_scenario("seed004").for_seed(1)
    epochs = with_gnss_faults(gnss_epochs(scenario, 1)[:round(GNSS_SECONDS * scenario.gnss.rate_hz)],
                              glitches=[(16.0, 2.0, 20.0, 50.0)])
    started = []

    def start(**sections) -> RunningDaemon:
        started.append(running(**sections))
        return started[-1]

    records, counters, _ = run_aided(tmp_path, pty_pair, start, scenario, "gnss", epochs, GNSS_SECONDS, GNSS_SPEED,
                                     GNSS_LATE_S, "serial", {"gnss": {"lever_m": list(scenario.gnss.lever_b),
                                                                      "handover_s": 12.0}, "max_wait_s": 10.0})
    assert counters["gnss_vel_rejected"] >= 10 and counters["gnss_pos_rejected"] >= 10
    assert messages.faults(counters) == {}
    assert "degraded" in [s["health"] for s in started[0].subscriber.status]
    t, phi = attitude_errors_deg(scenario, records)
    assert np.abs(phi[t >= 20.0, 2]).max() < 0.2


MASTER_SECONDS, MASTER_SPEED, MASTER_LATE_S = 15.0, 10.0, 2.0
"""Seed-002 transfer alignment played for 15 s of data at ×10, the master's epochs 2 s of data late."""
@pytest.mark.parametrize("transport", ["zenoh", "serial"])
def test_the_daemon_aligns_a_slave_imu_against_a_master_ins_arriving_late(tmp_path, pty_pair, running, transport):
    """The master's epochs (10 Hz) late on …/aid/master or as serial aiding frames: the samples wait for them,
    the records equal the offline replay with the master log and carry the mounting, phase 2 starts within 2 s,
    and the slave's attitude and the mounting are right against the truth."""
    scenario = get_scenario("seed002").for_seed(1)
    master = scenario.master
    epochs = master_epochs(scenario, 1)[:round(MASTER_SECONDS * master.rate_hz)]
    assert len(epochs) == 150
    records, counters, config = run_aided(tmp_path, pty_pair, running, scenario, "master", epochs, MASTER_SECONDS,
                                          MASTER_SPEED, MASTER_LATE_S, transport,
                                          {"max_wait_s": 10.0, "master": {"att_std_deg": master.att_noise_deg,
                                                                          "vel_std_mps": master.vel_noise_mps}})
    # the track's and the estimators' counters are in the status; phase 2's matching counts as work
    assert {f"master_{name}" for name in ("repeats", "out_of_order", "non_finite", "gaps", "unaided_queries",
                                          "unaided_observations", "vel_accepted", "vel_rejected", "att_accepted",
                                          "att_rejected")} <= counters.keys()
    assert counters["master_unaided_queries"] == 9        # the samples before the first epoch (0.1 s)
    assert counters["master_vel_accepted"] > 100 and counters["master_att_accepted"] > 100
    # seed 1: the χ² gate (16.3) turns away 2 of 136 master velocities, at 4.4 and 4.7 s (first wing rock):
    # screening, not faults, and below the alarm's rate
    assert messages.faults(counters) == {} and counters["master_vel_rejected"] <= 2
    write_master_log(tmp_path / "master.csv", epochs, master.att_noise_deg, master.vel_noise_mps)
    assert_same_as_replay(records, tmp_path / "recorded.csv", tmp_path, config,
                          {"master": str(tmp_path / "master.csv")})
    # the mounting C_bs^bm travels in every record of this mode (the subscriber's decode_attitude checked it)
    mount_q = np.array([m["mount_q"] for m in records])
    mount_sigma = np.array([m["mount_sigma_deg"] for m in records])
    assert np.abs(np.linalg.norm(mount_q, axis=1) - 1.0).max() < 1e-9 and (mount_sigma > 0.0).all()
    assert next(m["t"] for m in records if m["phase"] != "coarse") <= 2.0
    assert records[-1]["phase"] in ("fine", "aligned")
    t, phi = attitude_errors_deg(scenario, records)
    mount_error = np.abs(misalignment(dcm_from_quat(mount_q), scenario.motion.mounting)).max(axis=1) / DEG
    # seed 1 measured: from 5 s heading at most 0.0095°; from 10 s level at most 0.012° and the mounting 0.012° off
    # (σ 0.010°), from 5 s at most 1.96 of its σ
    late = t >= 10.0
    assert np.abs(phi[t >= 5.0, 2]).max() < 0.03 and np.abs(phi[late, :2]).max() < 0.04
    assert mount_error[late].max() < 0.04 and (mount_error <= 3.0 * mount_sigma)[t >= 5.0].all()


def test_a_sample_at_the_newest_aiding_epoch_gets_its_values_live_as_in_the_replay():
    """The daemon lets a sample go once its track holds an epoch at or after it: a sample at the time of the
    newest epoch (the first one, or the first after a gap) must then have that epoch's values, as it has in
    the replay, whose feed already holds the epochs after it."""
    epochs = np.array([[0.1, 1.0], [0.2, 2.0], [1.5, 3.0], [1.6, 4.0]])   # a gap (> max_gap_s) before 1.5 s
    at = np.array([0.1, 1.5])
    replayed = AidingFeed(AidingTrack(1, max_gap_s=0.5), iter([epochs])).aid_at(at)[:, 1]
    wait, live = AidingWait([AidingTrack(1, max_gap_s=0.5)], max_wait_s=10.0), []
    for row in epochs:
        wait.push(np.array([[row[0], 0, 0, 0, 0, 0, 0.0]]))   # an IMU sample at the epoch's time, then the epoch
        wait.tracks[0].push(row)
        rows, values = wait.release()
        live += [v for t, v in zip(rows[:, 0], values[:, 1], strict=True) if t in at]
    assert replayed.tolist() == [1.0, 3.0]
    assert live == replayed.tolist()

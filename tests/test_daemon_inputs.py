"""The daemon's inputs through real parts: a pty with pyserial and Zenoh sessions on loopback.

GIVEN a daemon with both a serial port and the Zenoh IMU topic configured, WHEN samples arrive on
either, THEN both reach the pipeline (per-input counters, records equal to the offline replay).
GIVEN aiding frames (type 2) interleaved with the IMU frames on the serial link, THEN they are
decoded and counted, the configured kind's go to its track (the others counted as unused), a bad
one is counted and dropped, and none of them counts as an IMU sequence gap. GIVEN a moving vehicle
with its odometer on Zenoh, late, THEN the samples wait for it and the records equal the replay.
"""
from __future__ import annotations

import time

import numpy as np
import pytest
import zenoh
from daemon_harness import RunningDaemon
from sinsalign.protocol import messages
from sinsalign.protocol.serial_frame import MSG_AIDING, encode_aiding, encode_frame, encode_imu
from sinsalign.tools.virtual_imu import FramePlayer, PtyPair, write_all
from test_daemon_e2e import assert_same_as_replay, samples

SECONDS = 20.0
HALF = 2000   # samples: the first 10 s over serial, the rest over Zenoh


@pytest.fixture
def pty_pair():
    pair = PtyPair()
    yield pair
    pair.close()


def imu_data(seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    chunks = samples(seconds)
    return tuple(np.concatenate([getattr(c, name) for c in chunks]) for name in ("t", "dtheta", "dv"))


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


def wait_until(condition, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.02)


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
    time.sleep(0.3)   # a status period
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
    data = b"".join(stream)
    for at in range(0, len(data), 4096):
        write_all(pty_pair.master_fd, data[at:at + 4096])
    wait_until(lambda: daemon.counters.samples_used == n)
    time.sleep(0.3)   # a status period
    run.stop()
    counters = subscriber.status[-1]["counters"]
    assert counters["samples_used"] == counters["samples_in_serial"] == n
    assert counters["aiding_frames"] == len(expected) == 50 and counters["bad_aiding"] == 1
    assert counters["frames"] == n + len(expected) + 1
    odo = [e for e in expected if e[0] == "odo"]
    # the odometer epochs go to the configured odo track, the other kinds are counted as unused
    assert counters["odo_epochs"] == len(odo) == 17 and counters["aiding_unused"] == len(expected) - len(odo)
    assert daemon.tracks["odo"].latest_time == pytest.approx(odo[-1][2], abs=1e-9)
    assert all(counters.get(k, 0) == 0 for k in ("seq_gaps", "seq_repeats", "odo_repeats", "odo_out_of_order",
                                                  "odo_non_finite", "odo_gaps"))
    assert "unknown aiding kind code 7" in subscriber.status[-1]["last_error"]


def test_the_daemon_aligns_a_moving_vehicle_with_odometer_epochs_arriving_late_over_zenoh(tmp_path, pty_pair,
                                                                                          running):
    """IMU frames on the pty, the odometer on …/aid/odo two seconds of data behind: the samples wait for
    their aiding, and the records equal the offline replay of the recording with the odometer log."""
    import threading

    from sinsalign.service.align.conventions import DEG
    from sinsalign.tools.sim.aiding import odometer_epochs, write_body_velocity_log
    from sinsalign.tools.sim.imu import simulate
    from sinsalign.tools.sim.scenarios import get_scenario
    scenario = get_scenario("seed003-20").for_seed(1)
    seconds, speed = 125.0, 25.0   # the default 120-s window, then the Kalman stage
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, seconds, 1,
                        chunk_samples=10**6)
    epochs = odometer_epochs(scenario, 1)[:round(seconds * 100)]
    run = running(site={"lat_deg": scenario.site.lat / DEG, "lon_deg": scenario.site.lon / DEG,
                        "height_m": scenario.site.height_m},
                  imu={"rate_hz": scenario.rate_hz}, sensor=scenario.grade.datasheet(),
                  aiding={"inputs": ["odo"], "max_wait_s": 10.0})
    daemon, subscriber = run.daemon, run.subscriber
    publisher = subscriber.session.declare_publisher(daemon.keys.aid("odo"),
                                                     congestion_control=zenoh.CongestionControl.BLOCK)

    def send_odometer():
        time.sleep(2.0 / speed)   # two seconds of data late
        start = time.monotonic()
        for seq, row in enumerate(epochs):
            delay = row[0] / speed - (time.monotonic() - start)
            if delay > 0:
                time.sleep(delay)
            sample = messages.AidingSample("odo", seq, float(row[0]), {"v_b": tuple(row[1:])})
            publisher.put(messages.pack(messages.aiding_message(sample)))

    sender = threading.Thread(target=send_odometer)
    sender.start()
    FramePlayer(pty_pair.master_fd, speed=speed).play(chunk.t, chunk.dtheta, chunk.dv)
    sender.join()
    n_records = int(seconds / run.config.output.period_s)
    subscriber.wait_for(n_records, timeout_s=30)
    time.sleep(0.3)
    run.stop()
    counters = subscriber.status[-1]["counters"]
    assert counters["odo_epochs"] == len(epochs) and counters["samples_used"] == len(chunk.t)
    assert messages.faults(counters) == {}
    assert len(subscriber.attitude) == n_records
    assert subscriber.attitude[-1]["phase"] in ("fine", "aligned")
    write_body_velocity_log(tmp_path / "odo.csv", epochs[:, 0], epochs[:, 1:])
    import json

    from sinsalign.tools.replay import replay
    replay(tmp_path / "recorded.csv", tmp_path / "replayed.jsonl", run.config, progress=False,
           aids={"odo": str(tmp_path / "odo.csv")})
    offline = [json.loads(line) for line in (tmp_path / "replayed.jsonl").read_text().splitlines()]
    # equal to within 1e-4 σ: the live path differs from the replay by up to ~2e-6° in some runs (not
    # bit-identical as the fixed-site daemon is; cause not found yet, see the README's known issues)
    from sinsalign.service.align.conventions import dcm_from_quat, misalignment
    assert [m["t"] for m in subscriber.attitude] == [r["t"] for r in offline]
    difference = np.abs(misalignment(dcm_from_quat(np.array([m["q"] for m in subscriber.attitude])),
                                     dcm_from_quat(np.array([r["q"] for r in offline])))).max(axis=1) / DEG
    sigma = np.array([r["heading_sigma_deg"] for r in offline])
    worst = int(np.argmax(difference / sigma))
    assert (difference <= 1e-4 * sigma).all(), (worst, difference[worst], sigma[worst], difference.max())
    assert [m["phase"] for m in subscriber.attitude] == [r["phase"] for r in offline]

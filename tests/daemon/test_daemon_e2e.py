"""End to end through real parts: a pty with pyserial, Zenoh sessions on loopback, the daemon loop.

GIVEN a simulated IMU played as serial frames into a pseudo-terminal (or as msgpack on the Zenoh
IMU key), WHEN the daemon aligns it, THEN a subscriber receives every attitude record, equal to
the offline replay of the daemon's own recording of its input, and the counters account for
every frame.
"""
from __future__ import annotations

import time

import numpy as np
import pytest
import zenoh
from sinsalign.protocol import messages
from sinsalign.service.config import config_from_mapping
from sinsalign.tools.virtual_imu import FramePlayer
from support.daemon_harness import SECONDS, RunningDaemon, assert_same_as_replay, free_port, samples


def test_serial_frames_at_20x_real_time_reach_subscribers_equal_to_offline_replay(tmp_path, pty_pair):
    run = RunningDaemon(tmp_path, pty_pair.port_name)
    config, subscriber = run.config, run.subscriber
    chunks = samples()
    n = sum(len(c.t) for c in chunks)
    player = FramePlayer(pty_pair.master_fd, speed=20.0)
    start = time.monotonic()
    player.play_chunks((c.t, c.dtheta, c.dv) for c in chunks)
    play_s = time.monotonic() - start
    subscriber.wait_for(int(SECONDS / config.output.period_s))
    time.sleep(0.3)   # a status period
    run.stop()
    assert play_s < SECONDS / 10          # it really ran near ×20 (4000 frames/s)
    counters = subscriber.status[-1]["counters"]
    # no frame lost, none dropped: the counters prove it
    assert counters["frames"] == n == counters["samples_used"] == player.frames_written
    assert sum(counters[k] for k in ("bytes_skipped", "bad_header", "bad_crc", "bad_length", "seq_gaps", "seq_repeats",
                                     "time_not_increasing")) == 0
    assert len(subscriber.attitude) == int(SECONDS / config.output.period_s)
    assert subscriber.status[-1]["health"] in ("ok", "no_input")
    assert_loop_figures_whole(subscriber.status, n)
    assert_same_as_replay(subscriber.attitude, tmp_path / "recorded.csv", tmp_path, config)
    assert (tmp_path / "recorded.csv").stat().st_mode & 0o077 == 0   # owner-only recording


def assert_loop_figures_whole(statuses: list[dict], samples_in: int) -> None:
    """The statuses' ``loop`` figures: every read with samples in one period, each period's order p50 ≤ p99 ≤ max,
    the largest since the start the largest of the periods."""
    loops = [status["loop"] for status in statuses]
    assert 0 < sum(loop["reads"] for loop in loops) <= samples_in
    busy = [loop for loop in loops if loop["reads"]]
    assert all(0.0 < loop["p50_ms"] <= loop["p99_ms"] <= loop["max_ms"] <= loop["max_ms_since_start"]
               for loop in busy)
    # a read's CPU time is within its time (two clocks: 10 us of slack)
    assert all(0.0 < loop["max_cpu_ms"] <= loop["max_ms"] + 0.01 for loop in busy)
    assert loops[-1]["max_ms_since_start"] == max(loop["max_ms"] for loop in busy) < 1000.0
    assert all(loop["p50_ms"] is None for loop in loops if not loop["reads"])


def test_zenoh_imu_input_gives_the_same_as_offline_replay(tmp_path):
    run = RunningDaemon(tmp_path, zenoh={"imu_input": True})
    config, subscriber = run.config, run.subscriber
    publisher = subscriber.session.declare_publisher(run.daemon.keys.imu,
                                                     congestion_control=zenoh.CongestionControl.BLOCK)
    seq = 0
    for c in samples(20.0):
        for k in range(len(c.t)):
            sample = messages.ImuSample(seq, float(c.t[k]), tuple(c.dtheta[k]), tuple(c.dv[k]), 0)
            publisher.put(messages.pack(messages.imu_message(sample)))
            seq += 1
    publisher.put(b"\x93garbage")          # a malformed message is counted, not fatal
    subscriber.wait_for(int(20.0 / config.output.period_s))
    time.sleep(0.3)
    run.stop()
    counters = subscriber.status[-1]["counters"]
    assert counters["samples_used"] == seq and counters["bad_messages"] == 1
    assert_loop_figures_whole(subscriber.status, seq)
    assert_same_as_replay(subscriber.attitude, tmp_path / "recorded.csv", tmp_path, config)


def test_queryable_answers_state_and_configuration_and_liveliness_is_declared(tmp_path):
    run = RunningDaemon(tmp_path)
    daemon, subscriber = run.daemon, run.subscriber
    alive = []
    deadline = time.monotonic() + 5.0
    while not alive and time.monotonic() < deadline:   # declarations reach a new peer a moment after open()
        alive = [r.ok.key_expr for r in subscriber.session.liveliness().get(daemon.keys.alive, timeout=1.0)
                 if r.ok is not None]
        time.sleep(0.05)
    replies = [r.ok for r in subscriber.session.get(daemon.keys.state, timeout=2.0) if r.ok is not None]
    run.stop()
    assert [str(k) for k in alive] == [daemon.keys.alive]
    state = messages.unpack_map(replies[0].payload.to_bytes())
    assert state["config"]["zenoh"]["unit"] == "bench" and state["status"]["health"] in ("starting", "no_input")


def test_demo_command_runs_the_live_bench_end_to_end(tmp_path, capsys):
    from sinsalign.cli import main
    assert main(["demo", "--no-watch", "--duration", "20", "--speed", "20", "--out-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "frames received 4000, used 4000; drops and faults: none" in out
    assert (tmp_path / "recorded.csv").exists()


def test_demo_of_an_aided_scenario_plays_its_aiding_frames_and_the_daemon_runs_that_mode(tmp_path, capsys):
    """seed004 in the demo: the virtual IMU interleaves the GNSS fixes as serial aiding frames 0.2 s late, the daemon
    runs the GNSS-aided mode on them, and the heading is right against the truth at 30 s."""
    from sinsalign.tools.demo import run_demo, summary
    result = run_demo("seed004", 1, 20.0, tmp_path, show=False, duration_s=30.0)
    assert result.aiding == ("gnss",)
    assert result.counters["gnss_epochs"] == 1500 and result.counters["samples_used"] == 3000
    assert result.counters["frames"] == 4500 and messages.faults(result.counters) == {}
    assert abs(result.phi_deg[-1, 2]) < 0.1      # seed 1: +0.004°
    assert "aided by gnss" in summary(result, "seed004")


def test_demo_of_a_vehicle_with_odometer_and_gnss_plays_both_streams_and_the_daemon_takes_both(tmp_path, capsys):
    """seed003-odo-gnss in the demo: the virtual IMU interleaves the odometer's 100-Hz and the receiver's 10-Hz
    epochs as serial aiding frames, the daemon waits for both and runs the combined mode (its Kalman stage from the
    first seconds); its heading at 30 s is within 0.05° of the truth, as the same run in memory gives to the serial
    frame's quantisation of the increments (1e-6°)."""
    from sinsalign.tools.demo import run_demo
    from sinsalign.tools.evaluate import run_once
    from sinsalign.tools.sim.scenarios import seed_run
    result = run_demo("seed003-odo-gnss", 1, 20.0, tmp_path, show=False, duration_s=30.0)
    assert result.aiding == ("odo", "gnss")
    c = result.counters
    assert (c["odo_epochs"], c["gnss_epochs"], c["samples_used"], c["frames"]) == (3000, 300, 3000, 6300)
    assert messages.faults(c) == {} and c["gnss_unaided_observations"] == 0
    assert c["odo_accepted"] > 250 and c["gnss_vel_accepted"] > 250   # 10-Hz updates from the first seconds
    assert abs(result.phi_deg[-1, 2]) < 0.05
    offline = run_once(seed_run("seed003-odo-gnss", 1, 30.0), 1, config_from_mapping({}), live=True)
    assert np.allclose(result.phi_deg, offline.phi_deg[:len(result.t)], atol=1e-4)


def test_serve_without_an_input_is_a_clear_configuration_error(capsys):
    from sinsalign.cli import main
    assert main(["serve", "-l", f"tcp/127.0.0.1:{free_port()}"]) == 2
    assert "no input" in capsys.readouterr().err


def test_sigterm_stops_serve_cleanly_and_flushes_the_recording(tmp_path, pty_pair):
    import os
    import signal
    import subprocess
    import sys
    port = free_port()
    record = tmp_path / "raw.csv"
    proc = subprocess.Popen([sys.executable, "-m", "sinsalign", "serve", "--serial", pty_pair.port_name, "-l",
                             f"tcp/127.0.0.1:{port}", "--record", str(record)], stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 20.0
    while not record.exists() and time.monotonic() < deadline:   # the file appears once the daemon is up
        time.sleep(0.05)
    time.sleep(0.3)
    chunk = samples(5.0)[0]
    FramePlayer(pty_pair.master_fd, speed=50.0).play(chunk.t[:1000], chunk.dtheta[:1000], chunk.dv[:1000])
    time.sleep(0.5)
    os.kill(proc.pid, signal.SIGTERM)
    _, err = proc.communicate(timeout=15)
    assert proc.returncode == 0, err
    assert "stopped after 1000 samples" in err
    rows = [line for line in record.read_text().splitlines() if line and not line.startswith(("#", "t,"))]
    assert len(rows) == 1000


@pytest.mark.slow
def test_soak_an_accelerated_hour_keeps_memory_and_latency_flat():
    """An hour of 200-Hz data with attitude for every sample: every window's frame gets its attitude, the RSS after
    the first report grows by less than 1 MiB, and the last window's p99 latency is not a trend away from the
    first's."""
    from sinsalign.tools.soak import percentiles_ms, soak
    samples = soak(hours=1.0, report_every_s=600.0, window_s=5.0)
    assert all(s.received == s.frames == 1000 for s in samples)
    assert samples[-1].rss_mib - samples[1].rss_mib < 1.0
    p99 = [percentiles_ms(s.latency_ms)[1] for s in samples]
    assert p99[-1] < 3 * max(p99[1], 2.0)


def test_the_null_relay_returns_every_frame_s_time_as_an_attitude_message():
    """The soak's floor (``soak --floor``): each frame played through the relay comes back on the attitude key,
    stamped with its own time, and no status is published (no own figures to mistake for the daemon's)."""
    from sinsalign.tools.daemon_process import DaemonProcess
    from sinsalign.tools.sim.scenarios import get_scenario
    scenario = get_scenario("static")
    dt = 1.0 / scenario.rate_hz
    t = np.arange(1, 201) * dt
    with DaemonProcess(scenario.site, scenario.rate_hz, dt, relay=True) as relay:
        latency_ms = relay.play_paced(t, np.zeros((len(t), 3)), np.zeros((len(t), 3)), settle_s=1.2)
        assert sorted(relay.arrivals) == list(np.round(t, 6)) and relay.loops == []
    assert len(latency_ms) == len(t) and (latency_ms > 0.0).all()


def test_the_benchmark_s_live_rows_measure_a_daemon_that_got_every_frame():
    """``benchmark --live``'s daemon rows on a short run: every paced frame's attitude arrived, the daemon's own share
    is in order (p99 of a period ≤ its max; CPU within the time), and the flat-out frames were all taken."""
    from sinsalign.tools.benchmark import bench_live
    live = bench_live(seconds=2.0, flat_out_s=0.5)
    assert live.received == live.frames == 400
    assert 0.0 < live.latency_p50_ms <= live.latency_p99_ms <= live.latency_max_ms
    p99_ms, max_ms, cpu_ms = live.own_ms
    assert 0.0 < p99_ms <= max_ms and 0.0 < cpu_ms <= max_ms + 0.01
    assert live.max_ingest_frames_s > 0.0 and 0.0 < live.cpu_share < 2.0

"""Every IMU serial format end to end: the bench's emulated IMU on a pty, the daemon, Zenoh on loopback.

GIVEN the seed-000 swing played by the bench in each ``[imu] format`` (a vendor's with its axes turned, its
counter for time and its own quantisation), WHEN the daemon aligns it, THEN no frame is lost or dropped, and
every attitude record from 5 s on holds, after the same sample, the attitude the project's own pipeline gives on
the same quantised increments to within 0.001° (decoding, axes and the counter's time stamps on the host clock
change nothing); and the vendor's quantisation itself moves the attitude from the project's frame's by no more
than 4σ of what the two roundings move it (:func:`quantisation_bound_deg`).

GIVEN a KVH 1775 at 200 Hz played in real time (its counter for time, ``counter_only`` false), WHEN the daemon is
configured for 250 Hz, THEN within 2 s of data the alignment stops on the host's clock (every window of counter
stamps steps at 4 ms and passes): every sample after is counted as `rate_mismatch`, no attitude comes after, health
degrades and last_error names both rates; WHEN it is configured for 200 Hz, THEN nothing is dropped or restarted.
"""
from __future__ import annotations

import itertools
import time

import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.service.align.earth import Site
from sinsalign.service.config import Config
from sinsalign.service.pipeline import build_pipeline
from sinsalign.service.serial_formats import serial_format_for
from sinsalign.tools.sim.scenarios import get_scenario
from sinsalign.tools.virtual_imu import FramePlayer, PtyPair, imu_encoder
from support.daemon_harness import RunningDaemon, samples, swing_samples, wait_until
from support.vendor_formats import VENDOR_IMUS

SECONDS = 40.0
RATE_HZ = 200.0
SETTLED_S = 5.0
SPEED = 20.0
LSB = {"sinsalign": (2.0**-31, 2.0**-24), "stim300": (2.0**-21 * DEG, 2.0**-22),
       "kvh1750": (2.0**-24 * 8e-4, 2.0**-24 * 0.05), "kvh1775": (2.0**-24 * 8e-4, 2.0**-24 * 0.05),
       "xsens": (2.0**-24 * 8e-4, 2.0**-24 * 0.05), "frame": (2.0**-31, 2.0**-24)}
"""The rounding step of one increment (Δθ in rad, Δv in m/s) in each format: the project's frame's 2⁻³¹ rad and
2⁻²⁴ m/s (the declared frame's are the same); the STIM300's LSBs of 2⁻²¹° and 2⁻²² m/s (10 g); a float32's 2⁻²⁴
of the swing's largest increments (8e-4 rad, 0.05 m/s)."""


def quantisation_bound_deg(name: str, t_s: np.ndarray) -> np.ndarray:
    """4σ of the attitude the rounding of the format's and of the project's frame moves after ``t_s`` of coarse
    alignment. Rounding noise is LSB/√12 a sample, √N after N; the heading's lever on it is the Earth's rotation:
    ω_ie cos L · t for the gyros' angle, and the velocity it turns gravity through, g ω_ie cos L t²/2, for the
    accelerometers' (which dominates in the first seconds)."""
    earth = 7.292115e-5 * np.cos(get_scenario("seed000-swing").site.lat)
    spread = np.sqrt(t_s * RATE_HZ / 12.0)
    variance = sum((lsb_dtheta * spread / (earth * t_s)) ** 2 + (lsb_dv * spread / (9.8 * earth * t_s**2 / 2)) ** 2
                   for lsb_dtheta, lsb_dv in (LSB[name], LSB["sinsalign"]))
    return 4.0 * np.sqrt(variance) / DEG


def aligned_run(tmp_path, imu: dict) -> tuple[list[dict], dict[str, int], int, Config]:
    """The attitude records (one per sample) and counters of the daemon reading the bench's IMU in ``imu``'s
    format, the frames written, and the configuration."""
    pty = PtyPair()
    try:
        run = RunningDaemon(tmp_path, pty.port_name, imu=imu, output={"period_s": 1.0 / RATE_HZ},
                            daemon={"record_path": ""})
        player = FramePlayer(pty.master_fd, speed=SPEED, encode=imu_encoder(run.config.imu))
        player.play_chunks((c.t, c.dtheta, c.dv) for c in samples(SECONDS))
        run.subscriber.wait_for(player.frames_written, timeout_s=30.0)
        time.sleep(0.3)
        run.stop()
        return run.subscriber.attitude, run.daemon.all_counters(), player.frames_written, run.config
    finally:
        pty.close()


def quantised_offline(config: Config) -> np.ndarray:
    """q (N, 4) per sample of the pipeline on the increments the format's frames carry (encoded by the bench,
    decoded as the daemon decodes, in body axes), with the simulator's time stamps."""
    chunks = samples(SECONDS)
    t = np.concatenate([c.t for c in chunks])
    encode = imu_encoder(config.imu)
    ticks = itertools.count()
    decoder = serial_format_for(config, lambda: float(next(ticks)))
    raw = b"".join(encode(k, 0.0, dtheta, dv) for k, (dtheta, dv) in
                   enumerate(zip(np.concatenate([c.dtheta for c in chunks]), np.concatenate([c.dv for c in chunks]),
                                 strict=True)))
    rows = decoder.feed(raw).samples
    assert len(rows) == len(t)
    s = config.site
    pipeline = build_pipeline(config, Site(s.lat_deg * DEG, s.lon_deg * DEG, s.height_m), RATE_HZ, live=True)
    return np.array([r.q for r in pipeline.process(t, rows[:, 1:4], rows[:, 4:7], None)])


def settled_errors_deg(records: list[dict], q_reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The attitude difference (°, largest axis) between ``records`` and the reference, sample by sample counted
    from the end, from ``SETTLED_S`` on (in the coarse stage's first seconds, σ of degrees, the last digit moves
    the heading by more), and the time since the start of each."""
    m = min(len(records), len(q_reference)) - int(SETTLED_S * RATE_HZ)
    C = dcm_from_quat(np.array([r["q"] for r in records[-m:]]))
    errors = np.abs(misalignment(C, dcm_from_quat(q_reference[-m:]))).max(axis=1) / DEG
    return errors, SECONDS - np.arange(m)[::-1] / RATE_HZ


@pytest.fixture(scope="module")
def native(tmp_path_factory):
    return aligned_run(tmp_path_factory.mktemp("native"), {"format": "sinsalign"})


@pytest.mark.parametrize("name", list(VENDOR_IMUS))
def test_each_imu_format_gives_the_attitude_of_its_increments(tmp_path, native, name):
    native_records, _, n, _ = native
    records, counters, written, config = aligned_run(tmp_path, {**VENDOR_IMUS[name], "counter_only": True})
    assert written == n and counters["samples_used"] == n == counters["frames"]
    assert counters["seq_gaps"] == counters["seq_repeats"] == counters["bytes_skipped"] == 0
    assert counters["samples_bridged"] == counters["restarts"] == counters["time_not_increasing"] == 0
    assert len(records) >= n - 2
    errors, _ = settled_errors_deg(records, quantised_offline(config))
    assert errors.max() < 1e-3
    # the rounding's effect: within its bound at the end, and from 5 s on within the bound at 5 s (the heading's
    # response to it on the swing is not the plain average the bound models)
    errors, t_s = settled_errors_deg(records, np.array([r["q"] for r in native_records]))
    bound = quantisation_bound_deg(name, t_s)
    assert errors.max() < bound[0] and errors[-1] < bound[-1]
    assert [r["phase"] for r in records[-1000:]] == [r["phase"] for r in native_records[-1000:]]


REAL_TIME_S = 5.0
"""Seconds of a KVH played in real time: three verdicts of the host's clock after the first at 1.5 s."""


def real_time_kvh(tmp_path, pty_pair: PtyPair, rate_hz: float) -> tuple[RunningDaemon, int]:
    """The daemon, configured for a KVH 1775 at ``rate_hz``, reading one at 200 Hz played in real time; stopped once
    its last status shows every frame read. The frames written."""
    run = RunningDaemon(tmp_path, pty_pair.port_name, imu={"format": "kvh1775", "rate_hz": rate_hz},
                        daemon={"record_path": ""})
    try:
        player = FramePlayer(pty_pair.master_fd, speed=1.0, encode=imu_encoder(run.config.imu))
        player.play(*swing_samples(REAL_TIME_S, 5))
        assert wait_until(lambda: run.subscriber.status
                          and run.subscriber.status[-1]["counters"]["frames"] == player.frames_written, 3.0)
    finally:
        run.stop()
    return run, player.frames_written


def test_a_kvh_at_another_rate_than_configured_stops_the_alignment_on_the_hosts_clock(tmp_path, pty_pair):
    run, written = real_time_kvh(tmp_path, pty_pair, 250.0)
    counters = run.daemon.all_counters()
    assert counters["restarts"] == 1 and counters["samples_used"] <= 2.0 * RATE_HZ   # stopped within 2 s of data
    assert counters["rate_mismatch"] == written - counters["samples_used"] and counters["seq_gaps"] == 0
    ingest = run.daemon.ingest   # no attitude after the stop: none beyond 2 s of data, 1.6 s of the counter's time
    assert ingest.t_last - ingest.t_first <= 2.0 * RATE_HZ / 250.0
    assert run.subscriber.attitude and max(r["t"] for r in run.subscriber.attitude) <= ingest.t_last
    status = run.subscriber.status[-1]
    text = status["last_error"]
    assert text.startswith("samples come at ") and text.endswith(
        " Hz by the host's clock (the IMU's counter stamps them at imu.rate_hz = 250): no sample is aligned until "
        "they do (set imu.rate_hz to the IMU's rate)")
    assert float(text.split()[3]) == pytest.approx(RATE_HZ, rel=0.05)
    assert any(s["health"] == "degraded" for s in run.subscriber.status)


def test_a_kvh_at_its_configured_rate_in_real_time_raises_no_alarm(tmp_path, pty_pair):
    run, written = real_time_kvh(tmp_path, pty_pair, RATE_HZ)
    counters = run.daemon.all_counters()
    assert counters["samples_used"] == written == counters["frames"]
    assert counters["rate_mismatch"] == counters["restarts"] == counters["seq_gaps"] == 0
    assert run.daemon.ingest.gate.rate.settled
    assert not any((s["last_error"] or "").startswith("samples come") for s in run.subscriber.status)

"""Soak: hours of simulated 200-Hz data through the live daemon, attitude for every sample.

The daemon runs in its own process reading a pty (``DaemonProcess``) and publishes attitude for every sample, the
most work a sample can ask of it. Frames of a static base with sensor noise are generated on the fly. Each report
interval of simulated time is written flat out (the pty's back-pressure paces the writer to the daemon) but for its
last ``window_s``, which is written at the IMU's own rate, one frame at a time, as a real 200-Hz line delivers it:
each of those frames' write time pairs with its attitude's arrival at a separate Zenoh subscriber (frame → attitude
latency), the daemon's statuses say its own share of it (read → published: the ``loop`` figures), and the daemon's RSS
is read after the window. Growth in memory or latency over the day shows as a trend;
the day itself takes minutes.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from sinsalign.protocol.serial_frame import encode_imu_frames

from .daemon_process import DaemonProcess
from .sim.imu import true_increments
from .sim.scenarios import get_scenario
from .virtual_imu import write_all

FLAT_OUT_PIECE_S = 10.0
"""Simulated seconds of frames per write while flat out."""
QUIET_S = 1.5
"""Idle line between the flat-out frames and the window: longer than the daemon's status period (1 s), so that the
statuses published in the window count the window's reads only."""
SETTLE_S = 1.2
"""After the window's last frame: its attitude, and the status of the period that holds it."""


@dataclass(frozen=True, slots=True)
class SoakSample:
    """One report: the daemon after ``hours`` of simulated data."""

    hours: float            # simulated time
    wall_s: float
    rss_mib: float          # the daemon's resident memory after the window
    latency_ms: np.ndarray  # frame written → attitude received, each frame of the window that got one (ms)
    frames: int             # frames in the window
    own_p99_ms: float       # the daemon's own read → published time: the largest of its status periods' p99 (ms)
    own_max_ms: float       # and its largest (ms)
    own_max_cpu_ms: float   # the largest CPU time of the daemon's loop thread on one read (ms)

    @property
    def received(self) -> int:
        return len(self.latency_ms)


def percentiles_ms(latency_ms: np.ndarray) -> tuple[float, float, float]:
    """p50, p99 and max of latencies (ms); NaN for none."""
    if not len(latency_ms):
        return (float("nan"),) * 3
    return float(np.percentile(latency_ms, 50)), float(np.percentile(latency_ms, 99)), float(latency_ms.max())


def soak(hours: float = 24.0, report_every_s: float = 3600.0, window_s: float = 10.0, seed: int = 0,
         on_sample: Callable[[SoakSample], None] | None = None, floor: bool = False,
         realtime_priority: int = 0) -> list[SoakSample]:
    """``hours`` of a noisy static base at 200 Hz through ``sinsalign serve``; a :class:`SoakSample` every
    ``report_every_s`` of simulated time, its last ``window_s`` played at the IMU's rate. ``floor``: through the null
    relay instead (tools/null_relay.py: the machine's and the transport's share alone; no statuses, no own figures).
    ``realtime_priority``: the daemon's (or relay's) ``daemon.realtime_priority``; the soak itself keeps its own."""
    scenario = get_scenario("static")
    rate = scenario.rate_hz
    dt = 1.0 / rate
    dtheta0, dv0 = true_increments(scenario.motion, scenario.site, np.zeros(1), dt)
    gyro_std, acc_std = scenario.errors.increment_noise_std(dt)
    rng = np.random.default_rng(seed)

    def frames(first: int, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return ((first + np.arange(1, count + 1)) * dt, dtheta0 + gyro_std * rng.standard_normal((count, 3)),
                dv0 + acc_std * rng.standard_normal((count, 3)))

    samples: list[SoakSample] = []
    per_report, per_window, per_piece = round(report_every_s * rate), round(window_s * rate), round(
        FLAT_OUT_PIECE_S * rate)
    with DaemonProcess(scenario.site, rate, dt, relay=floor, realtime_priority=realtime_priority) as daemon:
        daemon.watching = False
        start, written = time.monotonic(), 0
        for report in range(round(hours * 3600.0 / report_every_s)):
            window_start = (report + 1) * per_report - per_window
            while written < window_start:
                count = min(per_piece, window_start - written)
                write_all(daemon.pty.master_fd, encode_imu_frames(written, *frames(written, count)), timeout_s=30.0)
                written += count
            time.sleep(QUIET_S)   # the flat-out frames taken: the window's frames meet an idle line, as at 200 Hz
            latency = daemon.play_paced(*frames(written, per_window), seq=written, settle_s=SETTLE_S)
            daemon.watching = False
            written += per_window
            sample = SoakSample(written * dt / 3600.0, time.monotonic() - start, daemon.rss_mib(), latency,
                                per_window, *daemon.own_figures())
            samples.append(sample)
            if on_sample:
                on_sample(sample)
    return samples

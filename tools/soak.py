"""Soak: hours of simulated 200-Hz data through the live daemon as fast as it takes them.

The daemon runs in its own process reading a pty (``DaemonProcess``); frames of a static base
with sensor noise are generated on the fly and written flat out (the pty's back-pressure paces
the writer to the daemon). Every simulated ``report_every_s`` the daemon's RSS and the latency
of its 1-Hz attitude (epoch frame written → attitude received) are sampled, so growth in either
shows as a trend.
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


@dataclass(frozen=True, slots=True)
class SoakSample:
    hours: float          # simulated time
    wall_s: float
    rss_mib: float
    latency_p50_ms: float
    latency_p99_ms: float


def soak(hours: float = 24.0, report_every_s: float = 3600.0, seed: int = 0,
         on_sample: Callable[[SoakSample], None] | None = None) -> list[SoakSample]:
    scenario = get_scenario("static")
    rate = scenario.rate_hz
    dt = 1.0 / rate
    block = int(rate)   # one second of frames per write
    dtheta0, dv0 = true_increments(scenario.motion, scenario.site, np.zeros(1), dt)
    gyro_std, acc_std = scenario.errors.increment_noise_std(dt)
    rng = np.random.default_rng(seed)
    samples: list[SoakSample] = []
    with DaemonProcess(scenario.site, rate, 1.0) as daemon:
        start = time.monotonic()
        written: dict[float, float] = {}
        next_report = report_every_s
        for second in range(int(hours * 3600)):
            dtheta = dtheta0 + gyro_std * rng.standard_normal((block, 3))
            dv = dv0 + acc_std * rng.standard_normal((block, 3))
            first = second * block
            frames = encode_imu_frames(first, (first + np.arange(1, block + 1)) * dt, dtheta, dv)
            write_all(daemon.pty.master_fd, frames, timeout_s=10.0)
            written[float(second + 1)] = time.monotonic()   # the epoch frame is the last of the block
            if second + 1 >= next_report:
                next_report += report_every_s
                time.sleep(0.2)
                latency = np.array([daemon.arrivals[t] - w for t, w in written.items() if t in daemon.arrivals])
                written.clear()
                daemon.arrivals.clear()
                sample = SoakSample((second + 1) / 3600.0, time.monotonic() - start, daemon.rss_mib(),
                                    float(np.percentile(latency, 50) * 1e3) if len(latency) else float("nan"),
                                    float(np.percentile(latency, 99) * 1e3) if len(latency) else float("nan"))
                samples.append(sample)
                if on_sample:
                    on_sample(sample)
    return samples

"""Benchmarks (numbers, not pass/fail): replay throughput, per-sample latency, memory over a 24 h stream."""
from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from statistics import median
from typing import TYPE_CHECKING, TypeVar

import numpy as np
from rich.progress import Progress
from sinsalign.protocol.imu_binary import SUFFIX
from sinsalign.protocol.imu_log import open_imu_log
from sinsalign.service.aiding import AidingTrack
from sinsalign.service.align.conventions import DEG
from sinsalign.service.align.earth import Site
from sinsalign.service.config import Config, ConfigError, config_from_mapping
from sinsalign.service.pipeline import AlignmentPipeline, build_pipeline

from .convert import convert
from .evaluate import COARSE_ONLY
from .sim.aiding import odometer_epochs
from .sim.files import write_simulation
from .sim.imu import simulate, true_increments
from .sim.scenarios import get_scenario

if TYPE_CHECKING:
    from .daemon_process import DaemonProcess

T = TypeVar("T")
RSS_FRAMES = 2_400_000
"""Frames of the daemon's memory row (3.3 h at 200 Hz)."""
RSS_WARM_UP_FRAMES = 200_000
"""Frames the daemon takes before its RSS is taken as the start of the memory row (buffers, caches, the allocator)."""
FLAT_OUT_MAX_FRAMES_S = 200_000
"""The most frames per second the flat-out rows can write (encoded beforehand, so that the writer is not the bound)."""


def rss_mib() -> float:
    """Resident set size of this process (MiB), from /proc."""
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * resource.getpagesize() / 2**20


YARDSTICK_ADDITIONS = 5_000_000


def bench_yardstick(repeat: int) -> list[float]:
    """Seconds of a fixed piece of interpreter work (:data:`YARDSTICK_ADDITIONS` additions in a Python loop),
    ``repeat`` times: one core's speed at the moment, to read the other rows by (a virtual machine's neighbours slow it
    down without showing in its load). It lives in the processor's first cache: a replay slower at the same yardstick
    lost the memory's or the second core's time to the neighbours."""
    seconds = []
    for _ in range(repeat):
        start = time.perf_counter()
        total = 0
        for k in range(YARDSTICK_ADDITIONS):
            total += k
        seconds.append(time.perf_counter() - start)
    return seconds


def bench_pipeline(duration_s: float, repeat: int, config: Config | None = None,
                   scenario_name: str = "seed000-swing") -> list[float]:
    """Frames/s of the pipeline alone (``config``: the default configuration if None) over ``duration_s`` of a
    scenario simulated once, ``repeat`` times, given its samples as a log reader gives them: blocks of rows (t, Δθ,
    Δv), whose columns the pipeline reads in place."""
    config = config or Config()
    scenario = replace(get_scenario(scenario_name), duration_s=duration_s)
    blocks = [np.column_stack((c.t, c.dtheta, c.dv))
              for c in simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, duration_s, 1)]
    samples = sum(len(block) for block in blocks)
    rates = []
    for _ in range(repeat):
        pipeline = AlignmentPipeline(config, scenario.site, scenario.rate_hz, scenario.grade.datasheet())
        start = time.perf_counter()
        for block in blocks:
            pipeline.process(block[:, 0], block[:, 1:4], block[:, 4:7])
        rates.append(samples / (time.perf_counter() - start))
    return rates


def bench_latency(n_samples: int = 24000) -> dict[str, float]:
    """Per-sample cost of the live path (one sample per call), microseconds: p50, p99, max.

    120 s at 200 Hz of the seed-001 swing: OPREQ, the hand-over, the compass loops and the
    stored-data passes sliced between live samples (the store fills at 80 s).
    """
    scenario = get_scenario("seed001-swing")
    dt = 1.0 / scenario.rate_hz
    t = np.arange(1, n_samples + 1) * dt
    dtheta, dv = true_increments(scenario.motion, scenario.site, t - dt, dt)
    pipeline = AlignmentPipeline(Config(), scenario.site, scenario.rate_hz, live=True)
    cost = np.empty(n_samples)
    for k in range(n_samples):
        start = time.perf_counter()
        pipeline.process(t[k:k + 1], dtheta[k:k + 1], dv[k:k + 1])
        cost[k] = time.perf_counter() - start
    us = cost * 1e6
    return {"p50_us": float(np.percentile(us, 50)), "p99_us": float(np.percentile(us, 99)),
            "max_us": float(us.max()), "budget_200hz_us": 5000.0}


def bench_aided_latency(speed_mps: int = 80, seconds: float = 180.0) -> dict[str, float]:
    """Per-sample cost of the velocity-aided live path at 100 Hz (one sample and its odometer reading per
    call, through the aiding track as in the daemon), microseconds, over the seed-003 drive: the
    multistage re-runs of the growing window (every second until 120 s) and then the Kalman stage."""
    scenario = replace(get_scenario(f"seed003-{speed_mps}"), duration_s=seconds).for_seed(1)
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, seconds, 1,
                        chunk_samples=round(seconds * scenario.rate_hz))
    epochs = odometer_epochs(scenario, 1)
    pipeline = build_pipeline(Config(), scenario.site, scenario.rate_hz, scenario.grade.datasheet(), ["odo"],
                              live=True)
    track = AidingTrack(3)
    n = len(chunk.t)
    cost = np.empty(n)
    for k in range(n):
        start = time.perf_counter()
        track.push(epochs[k:k + 1])
        pipeline.process(chunk.t[k:k + 1], chunk.dtheta[k:k + 1], chunk.dv[k:k + 1], track.aid_at(chunk.t[k:k + 1]))
        track.release(float(chunk.t[k]))
        cost[k] = time.perf_counter() - start
    us = cost * 1e6
    period_us = 1e6 / scenario.rate_hz
    return {"mean_us": float(us.mean()), "p50_us": float(np.percentile(us, 50)), "p99_us": float(np.percentile(us, 99)),
            "max_us": float(us.max()), "max_at_s": float(chunk.t[int(np.argmax(us))]), "period_us": period_us,
            "mean_share": float(us.mean() / period_us)}


def bench_stream_memory(hours: float = 24.0, rate_hz: float = 200.0,
                        progress: bool = True) -> list[tuple[float, float]]:
    """Stream ``hours`` of a static base (generated on the fly) through the pipeline; (hour, RSS MiB) samples."""
    site = Site(32.0 * DEG)
    dt = 1.0 / rate_hz
    chunk = int(60 * rate_hz)
    dtheta0, dv0 = true_increments(get_scenario("static").motion, site, np.zeros(1), dt)
    rng = np.random.default_rng(0)
    pipeline = AlignmentPipeline(Config(), site, rate_hz)
    n_chunks = int(hours * 60)
    samples = []
    with Progress(disable=not progress, transient=True) as bar:
        task = bar.add_task(f"{hours:g} h stream", total=n_chunks)
        for i in range(n_chunks):
            t = (np.arange(chunk) + 1 + i * chunk) * dt
            pipeline.process(t, dtheta0 + 1e-7 * rng.standard_normal((chunk, 3)),
                             dv0 + 2.5e-6 * rng.standard_normal((chunk, 3)))
            if i % 60 == 0 or i == n_chunks - 1:
                samples.append(((i + 1) / 60.0, rss_mib()))
            bar.advance(task)
    return samples


@dataclass(frozen=True, slots=True)
class LiveBench:
    """The daemon as a separate process reading a pty, measured from outside."""

    rate_hz: float
    frames: int
    received: int
    latency_p50_ms: float
    latency_p99_ms: float
    latency_max_ms: float
    own_ms: tuple[float, float, float]   # the daemon's own read → published: p99 (largest period's), max, max CPU
    cpu_share: float              # of one core, daemon process, over the playing time
    max_ingest_frames_s: float    # frames/s the daemon kept up with when fed flat out
    rss_mib: float                # the daemon's resident memory at the end
    rss_growth_mib: float         # over the ``rss_frames`` written flat out after the first RSS_WARM_UP_FRAMES


def bench_live(seconds: float = 20.0, flat_out_s: float = 5.0, output_period_s: float | None = None,
               rss_frames: int = 0) -> LiveBench:
    """Virtual IMU → pty → ``sinsalign serve`` (own process) → Zenoh subscriber, on loopback.

    With ``output_period_s`` None attitude is published for every sample (the worst case), so each
    frame's write time pairs with the arrival of its attitude: latency p50/p99/max. Then frames
    are written as fast as the pty takes them to find the sustained ingest rate (counted in
    published records: with a longer output period, the status counters would be needed). Then ``rss_frames``
    more written flat out (0: none), the daemon's RSS taken after the first :data:`RSS_WARM_UP_FRAMES` of them and at
    the end.
    """
    from sinsalign.protocol.serial_frame import IMU_FRAME_BYTES, encode_imu_frames

    from .daemon_process import DaemonProcess
    from .virtual_imu import write_all

    scenario = get_scenario("seed000-swing")
    dt = 1.0 / scenario.rate_hz
    with DaemonProcess(scenario.site, scenario.rate_hz, output_period_s or dt) as daemon:
        t = np.arange(1, int(seconds * scenario.rate_hz) + 1) * dt
        dtheta, dv = true_increments(scenario.motion, scenario.site, t - dt, dt)
        cpu0, wall0 = daemon.cpu_seconds(), time.monotonic()
        latency = daemon.play_paced(t, dtheta, dv, settle_s=1.2)   # the attitudes, and the status after the last
        cpu_share = (daemon.cpu_seconds() - cpu0) / (time.monotonic() - wall0)
        own = daemon.own_figures()
        latency = latency if len(latency) else np.array([np.nan])
        received = daemon.count
        # flat out: every frame as fast as the pty accepts it, for flat_out_s seconds of writing (the frames encoded
        # beforehand: the writer must not be the bound), counted by the daemon's own decoded samples (its state
        # query), whatever its output period
        spare = round(flat_out_s * FLAT_OUT_MAX_FRAMES_S)
        frames = encode_imu_frames(len(t), t[-1] + dt * np.arange(1, spare + 1), np.tile(dtheta[0], (spare, 1)),
                                   np.tile(dv[0], (spare, 1)))
        before, start, n = daemon.samples_in(), time.monotonic(), 0
        while time.monotonic() - start < flat_out_s and n < spare:
            write_all(daemon.pty.master_fd, frames[n * IMU_FRAME_BYTES:(n + 2000) * IMU_FRAME_BYTES])
            n = min(n + 2000, spare)
        deadline = time.monotonic() + 10.0
        while (done := daemon.samples_in() - before) < n and time.monotonic() < deadline:
            time.sleep(0.02)
        ingest = done / (time.monotonic() - start)
        growth = (_rss_growth(daemon, rss_frames, len(t) + n, t[-1] + n * dt, dt, dtheta[0], dv[0]) if rss_frames
                  else 0.0)
        rss = daemon.rss_mib()
    return LiveBench(scenario.rate_hz, len(t), received, float(np.percentile(latency, 50)),
                     float(np.percentile(latency, 99)), float(latency.max()), own, cpu_share, ingest, rss, growth)


def _rss_growth(daemon: DaemonProcess, frames: int, seq: int, t_last: float, dt: float, dtheta: np.ndarray,
                dv: np.ndarray) -> float:
    """The daemon's RSS growth (MiB) over ``frames`` written flat out after the first :data:`RSS_WARM_UP_FRAMES`
    (numbered from ``seq``, a still base after ``t_last``), each piece encoded as it goes."""
    from sinsalign.protocol.serial_frame import encode_imu_frames

    from .virtual_imu import write_all

    before, rss_start, piece = daemon.samples_in(), None, 100_000
    for first in range(0, frames, piece):
        count = min(piece, frames - first)
        if rss_start is None and first >= RSS_WARM_UP_FRAMES:
            rss_start = daemon.rss_mib()
        write_all(daemon.pty.master_fd, encode_imu_frames(
            seq + first, t_last + dt * (first + np.arange(1, count + 1)), np.tile(dtheta, (count, 1)),
            np.tile(dv, (count, 1))), timeout_s=30.0)
    deadline = time.monotonic() + 30.0
    while daemon.samples_in() - before < frames and time.monotonic() < deadline:
        time.sleep(0.05)
    return 0.0 if rss_start is None else daemon.rss_mib() - rss_start


@dataclass(slots=True)
class Rows:
    """The benchmark's table: one row per measure, with the machine's load (1-min average, the highest seen while
    the measure ran: another process on a 2-core machine shows here)."""

    lines: list[str] = field(default_factory=list)
    load: float = 0.0
    """The load of the last measure (for a second row of the same run)."""

    def measure(self, run: Callable[[], T]) -> T:
        """``run()``, its load kept for the rows of its result."""
        before = os.getloadavg()[0]
        result = run()
        self.load = max(before, os.getloadavg()[0])
        return result

    def row(self, label: str, best: str, middle: str) -> None:
        self.lines.append(f"| {label} | {best} | {middle} | {self.load:.2f} |")

    def table(self, title: str) -> str:
        return "\n".join([title, "", "| measure | best | median | load |", "|---|---|---|---|", *self.lines])


def _frames(values: list[float]) -> tuple[str, str]:
    return f"{max(values):,.0f} frames/s", f"{median(values):,.0f} frames/s"


def bench_process_replay(log: Path, repeat: int, options: tuple[str, ...] = ()) -> list[float]:
    """Frames/s of ``sinsalign replay LOG`` as a user runs it (its own process: start-up, imports, reading, the
    pipeline, the results), ``repeat`` times after one run that warms the operating system's file cache and Python's
    bytecode cache (written as Python writes it by default: PYTHONDONTWRITEBYTECODE, where this environment sets it,
    is not passed on)."""
    samples = sum(len(t) for t, _, _ in open_imu_log(log).blocks())
    env = {name: value for name, value in os.environ.items() if name != "PYTHONDONTWRITEBYTECODE"}
    command = [sys.executable, "-m", "sinsalign", "replay", str(log), "--out", str(log.with_suffix(".jsonl")),
               "--no-progress", *options]
    subprocess.run(command, check=True, capture_output=True, env=env)
    rates = []
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True, env=env)
        rates.append(samples / (time.perf_counter() - start))
    return rates


def _logs(seconds: float, tmp: Path) -> tuple[Path, Path]:
    """The seed-000 swing for ``seconds`` as a CSV log and in its binary form."""
    scenario = replace(get_scenario("seed000-swing"), duration_s=seconds)
    csv = write_simulation(scenario, 1, tmp / f"{seconds:g}").imu_csv
    binary = csv.with_suffix(SUFFIX)
    convert(csv, binary)
    return csv, binary


def report(seconds: float, repeat: int, live: bool, live_seconds: float, stream_hours: float,
           long_seconds: float = 3600.0) -> str:
    """``sinsalign benchmark``'s table: the whole-process replay of a ``seconds``-long and a ``long_seconds``-long
    200-Hz log (CSV default and coarse only, the binary form), the pipeline alone, the live path's latency
    fixed-base and velocity-aided, the live daemon's (``live``: its own process behind a pty for ``live_seconds``)
    and the memory of a ``stream_hours``-long stream (0: skipped); best and median of ``repeat``."""
    if 0.0 < stream_hours < 1.0 / 60.0:
        raise ConfigError(f"--stream-hours {stream_hours:g}: at least one minute of data (1/60 h), or 0 to skip")
    rows = Rows()
    with tempfile.TemporaryDirectory() as tmp, Progress(transient=True) as bar:
        task = bar.add_task("benchmark", total=None)
        yardstick = rows.measure(lambda: bench_yardstick(repeat))
        rows.row(f"yardstick: {YARDSTICK_ADDITIONS / 1e6:g} M additions in a Python loop (one core's speed now)",
                 f"{min(yardstick) * 1e3:.0f} ms", f"{median(yardstick) * 1e3:.0f} ms")
        for length in dict.fromkeys((seconds, long_seconds)):
            csv, binary = _logs(length, Path(tmp))
            rows.row(f"`replay`, {length:g}-s 200-Hz log, whole process, default",
                     *_frames(rows.measure(lambda csv=csv: bench_process_replay(csv, repeat))))
            rows.row("the same, `--no-fine`",
                     *_frames(rows.measure(lambda csv=csv: bench_process_replay(csv, repeat, ("--no-fine",)))))
            rows.row("the same log in its binary form, default",
                     *_frames(rows.measure(lambda binary=binary: bench_process_replay(binary, repeat))))
            bar.advance(task)
        for label, config in (("default", None), ("coarse stage only", config_from_mapping(COARSE_ONLY))):
            rows.row(f"pipeline alone, {seconds:g}-s log, {label}",
                     *_frames(rows.measure(lambda config=config: bench_pipeline(seconds, repeat, config))))
        lat = rows.measure(bench_latency)
        rows.row("live path, one sample per call (seed-001 swing, 200 Hz): p50 / p99 / max",
                 "{p50_us:.0f} / {p99_us:.0f} / {max_us:.0f} µs".format(**lat), "—")
        aided = rows.measure(bench_aided_latency)
        rows.row("velocity-aided live path at 100 Hz (seed-003, 80 m/s, 180 s): mean / p99 / max",
                 "{mean_us:.0f} / {p99_us:.0f} / {max_us:.0f} µs".format(**aided), "—")
        if live:
            every = rows.measure(lambda: bench_live(live_seconds))
            rows.row("daemon ← pty at 200 Hz, attitude every sample: frame → attitude p50 / p99 / max",
                     f"{every.latency_p50_ms:.2f} / {every.latency_p99_ms:.2f} / {every.latency_max_ms:.2f} ms",
                     f"{every.received}/{every.frames} received")
            rows.row("the daemon's own share of it (read → published, its status's loop figures): p99 / max / max CPU",
                     "{:.2f} / {:.2f} / {:.2f} ms".format(*every.own_ms), "—")
            rows.row("daemon flat out through the pty, attitude every sample",
                     f"{every.max_ingest_frames_s:,.0f} frames/s",
                     f"CPU {100 * every.cpu_share:.0f} % of a core at 200 Hz")
            default = rows.measure(lambda: bench_live(live_seconds, output_period_s=1.0, rss_frames=RSS_FRAMES))
            rows.row("daemon flat out through the pty, the default 1-Hz output",
                     f"{default.max_ingest_frames_s:,.0f} frames/s",
                     f"CPU {100 * default.cpu_share:.1f} % of a core at 200 Hz")
            rows.row(f"daemon RSS over {RSS_FRAMES / 1e6:g} M frames flat out, growth after the first "
                     f"{RSS_WARM_UP_FRAMES:,}", f"{default.rss_growth_mib:+.2f} MiB",
                     f"{default.rss_mib:.0f} MiB at the end")
        if stream_hours > 0:
            samples = rows.measure(lambda: bench_stream_memory(stream_hours, progress=False))
            rows.row(f"pipeline RSS over a {stream_hours:g}-h stream, growth after the first hour",
                     f"{samples[-1][1] - samples[0][1]:+.2f} MiB", f"{samples[-1][1]:.1f} MiB at the end")
    return rows.table(f"sinsalign benchmark on {os.cpu_count()} cores ({repeat} repeats; load: the 1-min average)")

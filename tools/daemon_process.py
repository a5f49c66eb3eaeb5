"""``sinsalign serve`` in its own process, reading a fresh pty, watched by a Zenoh subscriber.

For the benchmarks and the soak: the daemon is measured from outside, as a user would see it
(CPU and RSS from /proc, attitude arrival times from a separate Zenoh session).
"""
from __future__ import annotations

import gc
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import zenoh
from sinsalign.protocol import messages
from sinsalign.protocol.keys import UnitKeys
from sinsalign.service.align.conventions import DEG
from sinsalign.service.align.earth import Site
from sinsalign.service.config import ZenohConfig
from sinsalign.service.zenoh_session import open_session

from .demo import free_loopback_port
from .virtual_imu import FramePlayer, PtyPair


class DaemonProcess:
    """Start with ``with DaemonProcess(site, rate_hz, output_period_s) as d:``; write frames to ``d.pty``.

    ``relay``: the null relay (tools/null_relay.py) on the same configuration instead of the daemon, the floor of its
    latency on this machine. ``realtime_priority``: its ``daemon.realtime_priority`` (0: the normal scheduler)."""

    def __init__(self, site: Site, rate_hz: float, output_period_s: float, relay: bool = False,
                 realtime_priority: int = 0) -> None:
        self.port = free_loopback_port()
        self.pty = PtyPair()
        self._tmp = tempfile.TemporaryDirectory()
        config_path = Path(self._tmp.name) / "serve.toml"
        config_path.write_text(
            f'[site]\nlat_deg = {site.lat / DEG}\n[imu]\nrate_hz = {rate_hz}\n'
            f'[serial]\npath = "{self.pty.port_name}"\n[zenoh]\nlisten = ["tcp/127.0.0.1:{self.port}"]\n'
            f'unit = "bench"\n[output]\nperiod_s = {output_period_s}\n'
            f'[daemon]\nrealtime_priority = {realtime_priority}\n')
        command = ["sinsalign.tools.null_relay", str(config_path)] if relay else \
            ["sinsalign", "serve", "--config", str(config_path)]
        self.process = subprocess.Popen([sys.executable, "-m", *command], stderr=subprocess.DEVNULL)
        self.arrivals: dict[float, float] = {}   # attitude t (s, rounded) → monotonic arrival time
        self.loops: list[dict] = []   # the statuses' loop figures (the daemon's own latency) while watching
        self.count = 0
        self.watching = True   # keep each attitude's arrival time (False: only count, as when written flat out)
        time.sleep(1.5)   # imports, the port and the session
        self.session = open_session(ZenohConfig(connect=(f"tcp/127.0.0.1:{self.port}",)))
        keys = UnitKeys("sinsalign", "bench")
        self._subs = (self.session.declare_subscriber(keys.attitude, self._on_attitude),
                      self.session.declare_subscriber(keys.status, self._on_status))
        time.sleep(0.5)

    def _on_attitude(self, sample: zenoh.Sample) -> None:
        arrival = time.monotonic()
        self.count += 1
        if self.watching:
            self.arrivals[round(messages.decode_attitude(sample.payload.to_bytes())["t"], 6)] = arrival

    def _on_status(self, sample: zenoh.Sample) -> None:
        if self.watching:
            self.loops.append(messages.decode_status(sample.payload.to_bytes())["loop"])

    def play_paced(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, seq: int = 0,
                   settle_s: float = 0.2) -> np.ndarray:
        """Write samples (t (N,) s, Δθ, Δv (N, 3)) as frames numbered from ``seq`` at their own rate, one frame per
        write as a real line delivers them, stamping each write as it begins; after ``settle_s`` for the last
        attitudes, the frame → attitude latency (ms) of each frame whose attitude arrived (the daemon publishing every
        sample). The statuses' ``loop`` figures published meanwhile are in :attr:`loops`."""
        player = FramePlayer(self.pty.master_fd, 1.0, seq=seq)
        stamps = np.empty(len(t))
        self.arrivals.clear()
        self.loops.clear()
        self.watching = True
        gc.collect()
        gc.freeze()   # this process's collector must not delay the subscriber's arrival stamps
        try:
            for k in range(len(t)):
                player.play(t[k:k + 1], dtheta[k:k + 1], dv[k:k + 1])
                # When the write began, not now: the reader can publish the attitude before this thread runs again.
                stamps[k] = player.write_started
            time.sleep(settle_s)
        finally:
            gc.unfreeze()
        keys = np.round(t, 6)
        return np.array([self.arrivals[key] - stamp for key, stamp in zip(keys, stamps, strict=True)
                         if key in self.arrivals]) * 1e3

    def own_figures(self) -> tuple[float, float, float]:
        """The daemon's own read → published time over the statuses of the last :meth:`play_paced` (ms): the largest
        p99 of their periods, the largest time and the largest CPU time of one read (NaN without any read)."""
        busy = [loop for loop in self.loops if loop["reads"]]
        p99, most, cpu = (max((loop[key] for loop in busy), default=float("nan"))
                          for key in ("p99_ms", "max_ms", "max_cpu_ms"))
        return p99, most, cpu

    def samples_in(self) -> int:
        """The samples the daemon has decoded from the pty so far (its state query's ``samples_in_serial``)."""
        for reply in self.session.get(UnitKeys("sinsalign", "bench").state, timeout=2.0):
            if reply.ok is not None:
                return int(messages.unpack_map(reply.ok.payload.to_bytes())["status"]["counters"]["samples_in_serial"])
        raise TimeoutError("the daemon did not answer its state query")

    def cpu_seconds(self) -> float:
        with open(f"/proc/{self.process.pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def rss_mib(self) -> float:
        with open(f"/proc/{self.process.pid}/status") as f:
            line = next(line for line in f if line.startswith("VmRSS:"))
        return int(line.split()[1]) / 1024.0

    def __enter__(self) -> DaemonProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        for sub in self._subs:
            sub.undeclare()
        self.session.close()
        self.process.terminate()
        self.process.wait(timeout=10)
        self.pty.close()
        self._tmp.cleanup()

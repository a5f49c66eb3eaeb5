"""Shared by the daemon tests: a configuration on free loopback ports, a subscriber session, start-up, the
simulated samples they play, the comparison with the offline replay, and waiting for a condition."""
from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import numpy as np
from sinsalign.protocol import messages
from sinsalign.protocol.keys import UnitKeys
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.service.config import Config, ZenohConfig, config_from_mapping
from sinsalign.service.daemon import Daemon
from sinsalign.service.zenoh_session import open_session
from sinsalign.tools.demo import free_loopback_port
from sinsalign.tools.replay import replay
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import get_scenario

SCENARIO = "seed000-swing"
SECONDS = 40.0


free_port = free_loopback_port


def daemon_config(tmp_path: Path, port: int, **sections) -> Config:
    scenario = get_scenario(SCENARIO)
    grade = scenario.grade.datasheet()
    base = {"site": {"lat_deg": scenario.site.lat / DEG, "lon_deg": scenario.site.lon / DEG},
            "imu": {"rate_hz": scenario.rate_hz}, "sensor": grade,
            "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"], "unit": "bench"},
            "daemon": {"record_path": str(tmp_path / "recorded.csv"), "status_period_s": 0.2},
            "output": {"period_s": 0.5}}
    for name, table in sections.items():
        base[name] = {**base.get(name, {}), **table}
    return config_from_mapping(base)


class Subscriber:
    """A separate Zenoh session (a client program) collecting attitude and status messages."""

    def __init__(self, port: int, keys: UnitKeys) -> None:
        self.session = open_session(ZenohConfig(connect=(f"tcp/127.0.0.1:{port}",)))
        self.attitude: list[dict] = []
        self.status: list[dict] = []
        self._subs = [self.session.declare_subscriber(keys.attitude, lambda s: self.attitude.append(
                          messages.decode_attitude(s.payload.to_bytes()))),
                      self.session.declare_subscriber(keys.status, lambda s: self.status.append(
                          messages.decode_status(s.payload.to_bytes())))]

    def wait_for(self, n_attitude: int, timeout_s: float = 20.0) -> None:
        deadline = time.monotonic() + timeout_s
        while len(self.attitude) < n_attitude and time.monotonic() < deadline:
            time.sleep(0.02)

    def close(self) -> None:
        self.session.close()


def run_daemon(daemon: Daemon) -> threading.Thread:
    """Start the loop once the subscriber's declarations have reached the daemon (no early record lost)."""
    deadline = time.monotonic() + 5.0
    while not daemon.attitude_subscribed and time.monotonic() < deadline:
        time.sleep(0.01)
    thread = threading.Thread(target=daemon.run, daemon=True)
    thread.start()
    return thread


class RunningDaemon:
    """A daemon (serial on ``serial_path`` if given) with a subscriber, started; ``stop()`` ends both."""

    def __init__(self, tmp_path: Path, serial_path: str | None = None, reconnect_max_s: float = 2.0,
                 **sections) -> None:
        from sinsalign.service.serial_port import SerialPort
        from sinsalign.service.zenoh_session import open_session
        self.port = free_port()
        if serial_path:
            sections["serial"] = {**sections.get("serial", {}), "path": serial_path}
        self.config = daemon_config(tmp_path, self.port, **sections)
        port = SerialPort(serial_path, self.config.serial.baud, reconnect_max_s) if serial_path else None
        self.daemon = Daemon(self.config, open_session(self.config.zenoh), port)
        self.subscriber = Subscriber(self.port, self.daemon.keys)
        self.thread = run_daemon(self.daemon)

    def stop(self) -> None:
        self.daemon.stop()
        self.thread.join(timeout=5)
        self.subscriber.close()
        assert not self.thread.is_alive()


def wait_until(condition, timeout_s: float = 10.0) -> bool:
    """Poll ``condition`` every 20 ms until it holds or ``timeout_s`` passed; whether it holds at the end."""
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.02)
    return bool(condition())


def swing_samples(seconds: float, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``seconds`` of the seed-000 swing (seed ``seed``) in one piece: t (N,) s, Δθ (N, 3) rad, Δv (N, 3) m/s."""
    scenario = get_scenario(SCENARIO)
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, seconds, seed,
                        chunk_samples=100_000)
    return chunk.t, chunk.dtheta, chunk.dv


def samples(seconds: float = SECONDS):
    scenario = get_scenario(SCENARIO)
    return list(simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, seconds, 7,
                         chunk_samples=2000))


def imu_data(seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    chunks = samples(seconds)
    return tuple(np.concatenate([getattr(c, name) for c in chunks]) for name in ("t", "dtheta", "dv"))


def assert_same_as_replay(received: list[dict], recording: Path, tmp_path: Path, config: Config,
                          aids: dict[str, str] | None = None) -> None:
    """The daemon's records against the offline replay of its recording (with the aiding logs ``aids``, kind →
    path): the same epochs and phases and, to the last digits, the same attitudes."""
    out = tmp_path / "replayed.jsonl"
    replay(recording, out, config, progress=False, aids=aids)
    offline = [json.loads(line) for line in out.read_text().splitlines()]
    assert [m["t"] for m in received] == [r["t"] for r in offline]
    C_live = dcm_from_quat(np.array([m["q"] for m in received]))
    C_offline = dcm_from_quat(np.array([r["q"] for r in offline]))
    assert np.abs(misalignment(C_live, C_offline)).max() / DEG < 1e-9
    assert [m["phase"] for m in received] == [r["phase"] for r in offline]

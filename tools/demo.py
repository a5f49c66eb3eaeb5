"""``sinsalign demo``: the live bench in one process, then the heading error against the truth.

A virtual IMU plays a simulated scenario as serial frames into a pseudo-terminal (with its aiding
sensor's epochs as serial aiding frames, for a scenario that has one: the daemon then runs that
aided mode); the daemon reads the pty with pyserial, aligns, and publishes over Zenoh (peer mode
on loopback, multicast scouting off); a watch client in a second Zenoh session shows it live. At the end the attitude
the watch client received is compared with the simulated truth and the run's physical limit.
"""
from __future__ import annotations

import socket
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from sinsalign.protocol import messages
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.service.config import config_from_mapping
from sinsalign.service.daemon import Daemon
from sinsalign.service.serial_port import SerialPort
from sinsalign.service.zenoh_session import open_session

from .evaluate import run_limit_deg
from .sim.aiding import daemon_aiding, scenario_aids
from .sim.imu import simulate
from .sim.scenarios import daemon_sections, seed_run
from .virtual_imu import AidingPlayback, FramePlayer, PtyPair
from .watch import WatchClient, watch


def free_loopback_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass(frozen=True, slots=True)
class DemoResult:
    t: np.ndarray                 # epochs received (s)
    phase: list[str]
    phi_deg: np.ndarray           # (N, 3) misalignment against truth
    sigma_deg: np.ndarray
    converged: np.ndarray
    limit_deg: np.ndarray         # (3,)
    counters: dict[str, int]
    aiding: tuple[str, ...] = ()  # the aiding kinds played (the bias limit is then not the floor: no limit shown)


AIDING_LATE_S = 0.2
"""How far behind the IMU frames the demo's aiding epochs reach the line (s of data): a sensor's latency."""


def run_demo(scenario_name: str, seed: int, speed: float, out_dir: Path, show: bool = True,
             duration_s: float | None = None) -> DemoResult:
    scenario = seed_run(scenario_name, seed, duration_s)
    out_dir.mkdir(parents=True, exist_ok=True)
    port = free_loopback_port()
    aids = scenario_aids(scenario, seed)
    aiding = [AidingPlayback(aid.kind, aid.epochs, AIDING_LATE_S) for aid in aids]
    config = config_from_mapping({
        **daemon_sections(scenario),
        "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"], "unit": "demo"},
        "daemon": {"record_path": str(out_dir / "recorded.csv")},
        # the samples wait for their aiding: allow for the latency at any playing speed
        **({"aiding": {**daemon_aiding(aids), "max_wait_s": 10.0}} if aids else {})})
    pty = PtyPair()
    watcher_config = replace(config.zenoh, listen=(), connect=(f"tcp/127.0.0.1:{port}",))
    with open_session(config.zenoh) as daemon_session, open_session(watcher_config) as watch_session:
        daemon = Daemon(config, daemon_session, SerialPort(pty.port_name, config.serial.baud))
        client = WatchClient(watch_session, daemon.keys)
        received: list[dict] = []
        collector = watch_session.declare_subscriber(daemon.keys.attitude, lambda s: received.append(
            messages.decode_attitude(s.payload.to_bytes())))
        deadline = time.monotonic() + 5.0
        while not daemon.attitude_subscribed and time.monotonic() < deadline:
            time.sleep(0.01)
        chunks = list(simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, scenario.duration_s,
                               seed))
        truth_t = np.concatenate([c.t for c in chunks])
        truth_C = np.concatenate([c.C_b_n_true for c in chunks])
        daemon_thread = threading.Thread(target=daemon.run, daemon=True)
        daemon_thread.start()
        done = threading.Event()

        def play() -> None:
            try:
                FramePlayer(pty.master_fd, speed, aiding).play_chunks((c.t, c.dtheta, c.dv) for c in chunks)
                time.sleep(0.5)
            finally:
                done.set()

        threading.Thread(target=play, daemon=True).start()
        try:
            if show:
                watch(client, stop=done)
            else:
                done.wait()
        finally:
            status = daemon.status()
            daemon.stop()
            daemon_thread.join(timeout=5)
            collector.undeclare()
            client.close()
            pty.close()
    t = np.array([m["t"] for m in received])
    index = np.searchsorted(truth_t, t - 1e-9)
    phi = misalignment(dcm_from_quat(np.array([m["q"] for m in received])), truth_C[index]) / DEG
    return DemoResult(t, [m["phase"] for m in received], phi, np.array([m["heading_sigma_deg"] for m in received]),
                      np.array([m["converged"] for m in received]), run_limit_deg(scenario, truth_t),
                      status["counters"], tuple(aid.kind for aid in aids))


def summary(result: DemoResult, scenario_name: str) -> str:
    # an aided mode observes the biases the bias limit assumes unknown: its error is shown against the truth alone
    fixed = not result.aiding
    lines = ["   t (s)  phase    error φ_U (°)" + ("  error − limit (°)" if fixed else "") + "   σ (°)   converged"]
    marks = [m for m in (10, 20, 30, 60, 100, 150, 200, 300, 450, 600) if m in set(np.round(result.t, 6))]
    for mark in marks:
        k = int(np.flatnonzero(np.isclose(result.t, mark))[0])
        minus_limit = f"  {result.phi_deg[k, 2] - result.limit_deg[2]:+16.4f}" if fixed else ""
        lines.append(f"  {mark:6.0f}  {result.phase[k]:7s}  {result.phi_deg[k, 2]:+13.4f}{minus_limit}  "
                     f"{result.sigma_deg[k]:7.4f}   {bool(result.converged[k])}")
    c = result.counters
    odd = ", ".join(f"{k} {v}" for k, v in messages.faults(c).items())
    screened = ", ".join(f"{k} {c[k]}" for k in sorted(messages.SCREENED & c.keys()) if c[k])
    about = (f"physical limit heading {result.limit_deg[2]:+.4f}°, level E {result.limit_deg[0]:+.4f}° N "
             f"{result.limit_deg[1]:+.4f}°" if fixed else f"aided by {' and '.join(result.aiding)} (serial aiding "
             f"frames, {AIDING_LATE_S:g} s late); " +
             ", ".join(f"{c.get(f'{kind}_epochs', 0)} {kind} epochs taken" for kind in result.aiding))
    lines += ["", f"{scenario_name}: {about}",
              f"frames received {c.get('frames', 0)}, used {c.get('samples_used', 0)}; "
              f"drops and faults: {odd or 'none'}" + (f"; screened out by the gates: {screened}" if screened else "")]
    return "\n".join(lines)


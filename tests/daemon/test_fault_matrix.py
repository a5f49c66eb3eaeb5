"""The fault matrix (docs/reference.md, "Faults and what the daemon does"): each fault through the real pty or
Zenoh path.

GIVEN the daemon aligning a simulated swing base fed at ×40 real time, WHEN one fault is injected
after 20 s of data, THEN the daemon keeps running, the status counters say exactly what happened,
and it is `aligned` again by the end of the 110-s run once good data has resumed.
"""
from __future__ import annotations

import os
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import zenoh
from sinsalign.protocol import messages
from sinsalign.protocol.serial_frame import encode_imu
from sinsalign.tools.virtual_imu import FramePlayer, PtyPair, write_all
from support.daemon_harness import RunningDaemon, Subscriber, swing_samples

SECONDS, FAULT_AT_S, SPEED = 110.0, 20.0, 40.0
FAST = {"fine": {"enabled": False}, "output": {"period_s": 1.0}}
"""OPREQ alone: `aligned` (= converged, with no fine stage) about 32 s after a start, so that an
110-s run is aligned again at its end even after a restart at 20 s."""


T, DTHETA, DV = swing_samples(SECONDS, 3)
K = int(FAULT_AT_S * 200)


def frame(k: int, seq: int | None = None, t: float | None = None, dtheta=None, dv=None) -> bytes:
    return encode_imu(k if seq is None else seq, T[k] if t is None else t,
                      DTHETA[k] if dtheta is None else dtheta, DV[k] if dv is None else dv)


class Bench:
    """Daemon on a pty (or Zenoh IMU input) plus a subscriber, on free loopback ports."""

    def __init__(self, tmp_path: Path, port_path: str | None = None, zenoh_imu: bool = False) -> None:
        sections = dict(FAST)
        if zenoh_imu:
            sections["zenoh"] = {"imu_input": True}
        self.pty = None if zenoh_imu else PtyPair()
        self.run = RunningDaemon(tmp_path, port_path or (self.pty.port_name if self.pty else None),
                                 reconnect_max_s=0.2, **sections)
        self.port, self.daemon, self.subscriber = self.run.port, self.run.daemon, self.run.subscriber
        self.player = FramePlayer(self.pty.master_fd, SPEED) if self.pty else None

    def play(self, start: int, end: int) -> None:
        self.player.seq = start   # frame k carries sequence number k
        self.player.play(T[start:end], DTHETA[start:end], DV[start:end])

    def write(self, raw: bytes) -> None:
        write_all(self.pty.master_fd, raw)

    def finish(self) -> tuple[dict, dict]:
        """Wait for the last record, stop; (last status counters, last attitude)."""
        self.subscriber.wait_for(int(SECONDS), timeout_s=15)
        deadline = time.monotonic() + 5
        while (not self.subscriber.attitude or self.subscriber.attitude[-1]["t"] < SECONDS) \
                and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.3)
        self.run.subscriber = self.subscriber   # a test may have replaced it
        self.run.stop()
        if self.pty:
            self.pty.close()
        return self.subscriber.status[-1]["counters"], self.subscriber.attitude[-1]


def fault_free_rest(bench: Bench, counters: dict, attitude: dict, **expected: int) -> None:
    for name, value in expected.items():
        assert counters[name] == value, (name, counters)
    zero = set(counters) - set(expected) - messages.NOT_FAULTS
    assert {k: counters[k] for k in zero if counters[k] and not k.startswith("serial_")} == {}
    assert attitude["t"] == SECONDS and attitude["phase"] == "aligned", attitude


SERIAL_FAULTS: dict[str, tuple[Callable[[], bytes], dict[str, int]]] = {
    "garbage between frames": (lambda: frame(K) + bytes(range(1, 100)) + frame(K + 1),
                               {"bytes_skipped": 99}),
    "bad CRC": (lambda: frame(K)[:-1] + bytes([frame(K)[-1] ^ 0xFF]) + frame(K + 1),
                {"bad_crc": 1, "bytes_skipped": 49, "seq_gaps": 1, "samples_bridged": 1, "gaps_bridged": 1}),
    # the rest of a rejected frame, after its first byte, is skipped as garbage
    "truncated frame": (lambda: frame(K)[:30] + frame(K + 1),
                        {"bad_crc": 1, "bytes_skipped": 29, "seq_gaps": 1, "samples_bridged": 1, "gaps_bridged": 1}),
    "wrong length": (lambda: frame(K)[:4] + b"\x1b\x00" + frame(K)[6:] + frame(K + 1),
                     {"bad_header": 1, "bytes_skipped": 49, "seq_gaps": 1, "samples_bridged": 1, "gaps_bridged": 1}),
    "saturated values": (lambda: frame(K, dtheta=np.array([5.0, 0.0, 0.0])) + frame(K + 1),
                         {"saturated": 1, "restarts": 1}),
    "sequence gap": (lambda: frame(K + 3), {"seq_gaps": 3, "samples_bridged": 3, "gaps_bridged": 1}),
    "repeated frame": (lambda: frame(K) + frame(K) + frame(K + 1) + frame(K + 2) + frame(K + 3),
                       {"seq_repeats": 1}),
    "time going backwards": (lambda: frame(K, t=T[K] - 1.0) + frame(K + 1),
                             {"time_not_increasing": 1, "samples_bridged": 1, "gaps_bridged": 1}),
    "long outage": (lambda: frame(K + 400), {"seq_gaps": 400, "restarts": 1}),
}
RESUME = {"garbage between frames": K + 2, "bad CRC": K + 2, "truncated frame": K + 2, "wrong length": K + 2,
          "saturated values": K + 2, "sequence gap": K + 4, "repeated frame": K + 4, "time going backwards": K + 2,
          "long outage": K + 401}


@pytest.mark.parametrize("fault", list(SERIAL_FAULTS))
def test_serial_fault(tmp_path, fault):
    make, expected = SERIAL_FAULTS[fault]
    bench = Bench(tmp_path)
    bench.play(0, K)
    bench.write(make())
    bench.play(RESUME[fault], len(T))
    counters, attitude = bench.finish()
    fault_free_rest(bench, counters, attitude, **expected)


SATURATED = np.array([5.0, 0.0, 0.0])   # rad in one sample: beyond the wire's full scale
PACED = 5
"""Frames on either side of the saturated one written one at a time, each read alone, at a real IMU's pace."""


def write_alone(bench: Bench, raw: bytes, written: int) -> None:
    """One frame as its own write once the daemon has decoded the ``written`` frames before it: a read brings it
    alone, as every frame at a real IMU's pace."""
    decoder = bench.daemon.ingest.serial_format.decoder
    deadline = time.monotonic() + 5
    while decoder.counters.frames < written and time.monotonic() < deadline:
        time.sleep(0.001)
    bench.write(raw)


@pytest.mark.parametrize("read", ["with the next frame", "alone"])
def test_a_saturated_frame_restarts_the_alignment_whatever_read_brings_it(tmp_path, read):
    bench = Bench(tmp_path)
    if read == "alone":
        bench.play(0, K - PACED)
        for k in range(K - PACED, K + PACED + 1):
            write_alone(bench, frame(k, dtheta=SATURATED if k == K else None), k)
        bench.play(K + PACED + 1, len(T))
    else:
        bench.play(0, K)
        bench.write(frame(K, dtheta=SATURATED) + frame(K + 1))
        bench.play(K + 2, len(T))
    counters, attitude = bench.finish()
    n_obs = {m["t"]: m["n_obs"] for m in bench.subscriber.attitude}
    assert n_obs[FAULT_AT_S + 1] < n_obs[FAULT_AT_S] / 10    # a fresh pipeline, not the old one going on
    fault_free_rest(bench, counters, attitude, saturated=1, restarts=1)


def test_non_finite_values_over_zenoh_are_dropped_counted_and_bridged(tmp_path):
    bench = Bench(tmp_path, zenoh_imu=True)
    publisher = bench.subscriber.session.declare_publisher(bench.daemon.keys.imu,
                                                           congestion_control=zenoh.CongestionControl.BLOCK)
    for k in range(len(T)):
        dtheta = [float("nan"), 0.0, 0.0] if k == K else list(DTHETA[k])
        message = {"v": 1, "seq": k, "t": float(T[k]), "dtheta": dtheta, "dv": list(DV[k]), "status": 0}
        publisher.put(messages.pack(message))
        if k % 4000 == 0:
            time.sleep(0.05)
    counters, attitude = bench.finish()
    fault_free_rest(bench, counters, attitude, bad_messages=1, zenoh_seq_gaps=1, samples_bridged=1, gaps_bridged=1)


def test_serial_port_vanishes_and_comes_back(tmp_path):
    link = Path(tempfile.mkdtemp(dir=tmp_path)) / "imu"
    first = PtyPair()
    os.symlink(first.port_name, link)
    bench = Bench(tmp_path, port_path=str(link))
    bench.player = FramePlayer(first.master_fd, SPEED)
    bench.play(0, K)
    time.sleep(0.3)
    first.close()                       # the adapter is unplugged …
    time.sleep(0.5)
    second = PtyPair()                  # … and plugged back in under the same stable path
    os.remove(link)
    os.symlink(second.port_name, link)
    deadline = time.monotonic() + 10
    while bench.daemon.serial.reconnects == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    bench.pty, bench.player = second, FramePlayer(second.master_fd, SPEED)
    bench.play(K + 200, len(T))         # the IMU ran on: a second of frames never arrived
    counters, attitude = bench.finish()
    assert counters["serial_disconnects"] == 1 and counters["serial_reconnects"] == 1
    fault_free_rest(bench, counters, attitude, seq_gaps=200, restarts=1)


def test_a_subscriber_that_stops_reading_does_not_stall_the_daemon(tmp_path):
    bench = Bench(tmp_path)
    stuck = threading.Event()
    slow = Subscriber(bench.port, bench.daemon.keys)      # a second client whose callback never returns
    blocker = slow.session.declare_subscriber(bench.daemon.keys.attitude, lambda s: stuck.wait(30.0))
    bench.play(0, len(T))
    counters, attitude = bench.finish()
    stuck.set()
    blocker.undeclare()
    slow.close()
    fault_free_rest(bench, counters, attitude)
    assert len(bench.subscriber.attitude) == SECONDS    # the healthy client missed nothing


def test_a_zenoh_peer_that_restarts_gets_attitude_again(tmp_path):
    bench = Bench(tmp_path)
    bench.play(0, K)
    bench.subscriber.session.close()                    # the client program restarts …
    time.sleep(0.2)
    bench.subscriber = Subscriber(bench.port, bench.daemon.keys)
    deadline = time.monotonic() + 5
    while not bench.daemon.attitude_subscribed and time.monotonic() < deadline:
        time.sleep(0.01)
    bench.play(K, len(T))
    counters, attitude = bench.finish()
    assert bench.subscriber.attitude[0]["t"] <= FAULT_AT_S + 2
    fault_free_rest(bench, counters, attitude)

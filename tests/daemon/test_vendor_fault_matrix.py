"""The fault matrix of the vendor IMU formats, through the real pty (docs/reference.md, "Faults and what the
daemon does").

GIVEN the daemon aligning a simulated swing base played at ×40 as a vendor's frames (its counter for time),
WHEN a frame with a bad checksum, a truncated frame, a counter gap of three frames and a frame with a status flag
come in the stream, THEN every lost frame is a counter gap whose increments are bridged, the flagged sample is
counted and used, nothing restarts, and the run ends `aligned`.
"""
from __future__ import annotations

import pytest
from sinsalign.tools.virtual_imu import VENDOR_ENCODERS, FramePlayer, PtyPair, write_all
from support.daemon_harness import RunningDaemon, swing_samples, wait_until
from support.vendor_formats import VENDOR_IMUS

SECONDS, SPEED = 80.0, 40.0
T, DTHETA, DV = swing_samples(SECONDS, 3)
K = 20 * 200
"""The first fault's sample (20 s of data); the others follow a second apart."""
FAST = {"fine": {"enabled": False}, "output": {"period_s": 1.0}}
"""OPREQ alone: `aligned` (= converged, with no fine stage) some 32 s after the start."""


def corrupt(raw: bytes) -> bytes:
    return raw[:-1] + bytes([raw[-1] ^ 0x5A])


@pytest.mark.parametrize("name", list(VENDOR_IMUS))
def test_vendor_faults_are_counted_bridged_and_the_alignment_goes_on(tmp_path, name):
    pty = PtyPair()
    try:
        run = RunningDaemon(tmp_path, pty.port_name, reconnect_max_s=0.2, daemon={"record_path": ""},
                            imu={**VENDOR_IMUS[name], "counter_only": True}, **FAST)
        encoder = VENDOR_ENCODERS[name](run.config.imu)
        player = FramePlayer(pty.master_fd, SPEED, encode=lambda k, _t, dtheta, dv: encoder.encode(k, dtheta, dv))

        def play(start: int, end: int) -> None:
            player.seq = start   # frame k carries counter k
            player.play(T[start:end], DTHETA[start:end], DV[start:end])

        def frame(k: int, status: int = 0) -> bytes:
            return encoder.encode(k, DTHETA[k], DV[k], status)

        play(0, K)
        write_all(pty.master_fd, corrupt(frame(K)))                        # bad checksum: lost
        play(K + 1, K + 200)
        write_all(pty.master_fd, frame(K + 200)[: len(frame(K + 200)) // 2])   # truncated: lost
        play(K + 201, K + 400)
        play(K + 403, K + 600)                                             # three frames never sent
        write_all(pty.master_fd, frame(K + 600, status=1))                 # flagged, used
        play(K + 601, len(T))
        run.subscriber.wait_for(int(SECONDS), timeout_s=15)
        # the last record can go out while the read after it is still in the pty
        wait_until(lambda: run.daemon.all_counters()["frames"] >= len(T) - 5, timeout_s=5)
        run.stop()
    finally:
        pty.close()
    counters = run.daemon.all_counters()
    assert counters["seq_gaps"] == 5 and counters["samples_bridged"] == 5 and counters["gaps_bridged"] == 3
    assert counters["status_flagged"] == 1 and counters["restarts"] == 0 and counters["seq_repeats"] == 0
    assert counters["frames"] == len(T) - 5
    last = run.subscriber.attitude[-1]
    assert last["t"] >= SECONDS - 1.0 and last["phase"] == "aligned", last

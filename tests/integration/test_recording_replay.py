"""A daemon's recording replays to the daemon's own records, bit for bit, across restarts.

GIVEN a daemon on a real pty with a recording, WHEN its IMU stream has a 2-s outage (the gate restarts the
alignment), a saturated sample (another restart) and then a clock that goes back (the sensor restarted: a third),
THEN the recording marks each restart and ``replay`` of it gives exactly the records the daemon published: the
same epochs, phases, quaternions, angles and σ, to the last bit.
"""
from __future__ import annotations

import json
import time

import numpy as np
from sinsalign.protocol.imu_log import RESTART_MARKER
from sinsalign.protocol.serial_frame import DTHETA_LSB_RAD
from sinsalign.tools.convert import convert
from sinsalign.tools.replay import replay
from sinsalign.tools.virtual_imu import FramePlayer, PtyPair
from support.daemon_harness import RunningDaemon, imu_data, wait_until

WIRE_ONLY = {"v", "unit"}


def test_the_replay_of_a_recording_equals_the_daemon_across_an_outage_a_saturation_and_a_clock_reset(tmp_path):
    t, dtheta, dv = imu_data(24.0)
    dtheta = dtheta.copy()
    saturated = 2400
    dtheta[saturated, 0] = 2**31 * DTHETA_LSB_RAD          # full scale: the frame says saturated
    kept = np.r_[0:1000, 1400:len(t)]                        # 2 s lost after 5 s
    t_sent = t[kept].copy()
    reset = int(np.searchsorted(t_sent, 16.0))
    t_sent[reset:] -= 14.0                                   # the sensor's clock starts again near 2 s
    pty = PtyPair()
    run = RunningDaemon(tmp_path, pty.port_name)
    try:
        for part in (slice(0, reset), slice(reset, None)):   # a player per time base; one frame counter
            FramePlayer(pty.master_fd, speed=40.0, seq=part.start).play(t_sent[part], dtheta[kept][part],
                                                                        dv[kept][part])
        wait_until(lambda: run.daemon.counters.samples_in_serial == len(kept), timeout_s=20.0)
        time.sleep(0.5)
    finally:
        run.stop()
        pty.close()
    counters = run.subscriber.status[-1]["counters"]
    assert (counters["restarts"], counters["clock_resets"], counters["saturated"]) == (3, 1, 1)
    recording = tmp_path / "recorded.csv"
    assert recording.read_text().count(RESTART_MARKER) == 3
    live = [{k: v for k, v in m.items() if k not in WIRE_ONLY} for m in run.subscriber.attitude]
    binary = tmp_path / "recorded.sbin"
    convert(recording, binary)
    for log in (recording, binary):       # the CSV and its binary form
        out = tmp_path / "replayed.jsonl"
        replay(log, out, run.config, progress=False)
        offline = [json.loads(line) for line in out.read_text().splitlines()]
        assert len(live) > 30 and live == offline

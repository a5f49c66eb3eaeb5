"""``sinsalign bench``: a virtual IMU that plays a simulated scenario (or an IMU log) as serial frames into a pty or
a given port, paced by the samples' time stamps, with the scenario's aiding epochs as aiding frames if asked."""
from __future__ import annotations

import json
import os
import sys
import time

from sinsalign.protocol.imu_log import open_imu_log
from sinsalign.service.align.conventions import DEG
from sinsalign.service.config import ImuConfig

from .sim.aiding import daemon_aiding, scenario_aids
from .sim.imu import simulate
from .sim.scenarios import seed_run
from .virtual_imu import AidingPlayback, FramePlayer, PtyPair, imu_encoder


def run_bench(log: str | None, scenario: str, seed: int, duration_s: float | None, aid: bool, aid_late_s: float,
              port: str | None, speed: float, start_delay_s: float, imu: ImuConfig | None = None) -> int:
    """Play ``log``, or seed ``seed`` of ``scenario`` (``duration_s`` long if given; with its aiding epochs
    ``aid_late_s`` late if ``aid``), into ``port`` or a new pty, ``start_delay_s`` after saying where, at ×``speed``,
    in the frames of ``imu.format`` (the project's by default); 0, or 2 when the scenario has no aiding sensor to
    play."""
    imu = imu or ImuConfig()
    if log:
        chunks = open_imu_log(log).blocks()
        what = log
    else:
        s = seed_run(scenario, seed, duration_s)
        duration = s.duration_s
        chunks = ((c.t, c.dtheta, c.dv) for c in simulate(s.motion, s.site, s.errors, s.rate_hz, duration, seed))
        what = f"{scenario} seed {seed} (site lat {s.site.lat / DEG:.3f}°, "\
               f"{s.rate_hz:g} Hz: serve with --config giving [site] and [imu] to match)"
    aiding = []
    if aid:
        sensors = [] if log else scenario_aids(s, seed)
        if not sensors:
            print(f"--aid: {log or scenario} has no simulated aiding sensor (seed003-*, seed004, seed002 "
                  "have)", file=sys.stderr)
            return 2
        aiding = [AidingPlayback(sensor.kind, sensor.epochs[sensor.epochs[:, 0] <= duration], aid_late_s)
                  for sensor in sensors]
        table = ", ".join(f"{k} = {json.dumps(v)}" for k, v in daemon_aiding(sensors).items())
        kinds = " ".join(f"--aid {sensor.kind}" for sensor in sensors)
        what += (f", with its {' and '.join(sensor.kind for sensor in sensors)} epochs {aid_late_s:g} s late "
                 f"(serve {kinds}, [aiding] {table})")
    pty = None
    if port:
        fd = os.open(port, os.O_WRONLY | os.O_NOCTTY | os.O_NONBLOCK)
        name = port
    else:
        pty = PtyPair()
        fd, name = pty.master_fd, pty.port_name
    if imu.format != "sinsalign":
        what += f", as {imu.format} frames (serve --imu-format {imu.format} with the same [imu] table)"
    print(f"virtual IMU on {name}: playing {what} at ×{speed:g} in {start_delay_s:g} s", file=sys.stderr)
    time.sleep(start_delay_s)   # the reader's open() flushes what came before it
    player = FramePlayer(fd, speed, aiding, imu_encoder(imu))
    try:
        player.play_chunks(chunks)
    except KeyboardInterrupt:
        pass
    finally:
        print(f"wrote {player.frames_written} frames", file=sys.stderr)
        time.sleep(0.5)   # let the reader drain before the pty disappears
        if pty is not None:
            pty.close()
        else:
            os.close(fd)
    return 0

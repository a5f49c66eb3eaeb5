"""``sinsalign bench``: a virtual IMU that plays a simulated scenario (or an IMU log) as serial frames into a pty or
a given port, paced by the samples' time stamps, with the scenario's aiding epochs as aiding frames if asked, or its
GNSS receiver as NMEA or UBX on a port of its own (``--aid-format``)."""
from __future__ import annotations

import json
import os
import sys
import time

import numpy as np
from sinsalign.protocol.imu_log import open_imu_log
from sinsalign.service.align.conventions import DEG
from sinsalign.service.config import GnssConfig, ImuConfig

from .receiver_encoders import nmea_epoch, ubx_epoch
from .sim.aiding import ScenarioAid, daemon_aiding, scenario_aids
from .sim.imu import simulate
from .sim.scenarios import seed_run
from .virtual_imu import AidingPlayback, FramePlayer, PtyPair, imu_encoder


def receiver_playback(sensor: ScenarioAid, epochs: np.ndarray, aid_format: str, late_s: float) -> AidingPlayback:
    """The scenario's GNSS receiver in its own output (``nmea`` or ``ubx``); NAV-PVT states the accuracies the
    scenario's log states (the configuration's defaults where it states none)."""
    if aid_format == "nmea":
        return AidingPlayback("gnss", epochs, late_s, lambda _j, row: nmea_epoch(row))
    defaults = GnssConfig()
    pos_m = sensor.log_keys.get("pos_std_m", defaults.pos_std_m)
    vel_mps = sensor.log_keys.get("vel_std_mps", defaults.vel_std_mps)
    return AidingPlayback("gnss", epochs, late_s, lambda _j, row: ubx_epoch(row, pos_m, vel_mps))


def _open_port(path: str | None) -> tuple[int, str, PtyPair | None]:
    """(fd to write, the name to read, the pty made if no ``path``): a given device, or a new pty."""
    if path:
        return os.open(path, os.O_WRONLY | os.O_NOCTTY | os.O_NONBLOCK), path, None
    pty = PtyPair()
    return pty.master_fd, pty.port_name, pty


def run_bench(log: str | None, scenario: str, seed: int, duration_s: float | None, aid: bool, aid_late_s: float,
              port: str | None, speed: float, start_delay_s: float, imu: ImuConfig | None = None,
              aid_format: str = "sinsalign", aid_port: str | None = None) -> int:
    """Play ``log``, or seed ``seed`` of ``scenario`` (``duration_s`` long if given; with its aiding epochs
    ``aid_late_s`` late if ``aid``), into ``port`` or a new pty, ``start_delay_s`` after saying where, at ×``speed``,
    in the frames of ``imu.format`` (the project's by default); with ``aid_format`` ``nmea`` or ``ubx`` the GNSS
    receiver in that output on ``aid_port`` or a pty of its own. 0, or 2 when the scenario has no aiding sensor to
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
    aiding: list[AidingPlayback] = []
    receiver, receiver_fd, receiver_pty = None, -1, None
    if aid:
        sensors = [] if log else scenario_aids(s, seed)
        if not sensors:
            print(f"--aid: {log or scenario} has no simulated aiding sensor (seed003-*, seed004, seed002 "
                  "have)", file=sys.stderr)
            return 2
        if aid_format != "sinsalign" and not any(sensor.kind == "gnss" for sensor in sensors):
            print(f"--aid-format {aid_format}: {scenario} has no GNSS receiver to play", file=sys.stderr)
            return 2
        for sensor in sensors:
            epochs = sensor.epochs[sensor.epochs[:, 0] <= duration]
            if sensor.kind == "gnss" and aid_format != "sinsalign":
                receiver = receiver_playback(sensor, epochs, aid_format, aid_late_s)
            else:
                aiding.append(AidingPlayback(sensor.kind, epochs, aid_late_s))
        table = daemon_aiding(sensors)
        kinds = " ".join(f"--aid {sensor.kind}" for sensor in sensors)
        if receiver is not None:
            receiver_fd, receiver_name, receiver_pty = _open_port(aid_port)
            # stamped by their arrival: the --aid-late the epochs come after their time is the receiver's latency
            table["gnss"] = {**table["gnss"], "input": aid_format, "serial": receiver_name, "latency_s": aid_late_s}
            print(f"virtual GNSS receiver ({aid_format}) on {receiver_name}", file=sys.stderr)
        text = ", ".join(f"{k} = {json.dumps(v)}" for k, v in table.items())
        what += (f", with its {' and '.join(sensor.kind for sensor in sensors)} epochs {aid_late_s:g} s late "
                 f"(serve {kinds}, [aiding] {text})")
    fd, name, pty = _open_port(port)
    if imu.format != "sinsalign":
        what += (f", as {imu.format} frames (serve --imu-format {imu.format} with the same [imu] table"
                 f"{' and counter_only = true: faster than real time' if speed > 1.0 else ''})")
    print(f"virtual IMU on {name}: playing {what} at ×{speed:g} in {start_delay_s:g} s", file=sys.stderr)
    time.sleep(start_delay_s)   # the reader's open() flushes what came before it
    player = FramePlayer(fd, speed, aiding, imu_encoder(imu), receiver, receiver_fd)
    try:
        player.play_chunks(chunks)
    except KeyboardInterrupt:
        pass
    finally:
        print(f"wrote {player.frames_written} frames", file=sys.stderr)
        time.sleep(0.5)   # let the reader drain before the pty disappears
        for made, written in ((pty, fd), (receiver_pty, receiver_fd)):
            if made is not None:
                made.close()
            elif written >= 0:
                os.close(written)
    return 0

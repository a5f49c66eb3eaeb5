"""A daemon without the alignment: the soak's yardstick for what the machine and the transport alone cost a frame.

``python -m sinsalign.tools.null_relay CONFIG`` reads the serial port of a ``sinsalign serve`` configuration as the
daemon reads it (the same port class, the same frame decoder) and publishes, for each IMU frame, an attitude message
through the daemon's own outputs (the same key, encoding and put): a fixed attitude stamped with the frame's time. A
subscriber's frame → attitude latency through it is the floor of the daemon's: the operating system's wake-ups of both
processes and of Zenoh's threads, the serial read, the decoding and the puts, without the checks, the alignment and the
records.
"""
from __future__ import annotations

import signal
import sys
import threading
from dataclasses import replace

from sinsalign.protocol.keys import UnitKeys
from sinsalign.protocol.results import ResultRecord
from sinsalign.protocol.serial_frame import FrameDecoder
from sinsalign.service.config import load_config
from sinsalign.service.realtime import request_realtime
from sinsalign.service.serial_port import SerialPort
from sinsalign.service.zenoh_outputs import ZenohOutputs
from sinsalign.service.zenoh_session import open_session

FIXED = ResultRecord(t=0.0, phase="coarse", q=(1.0, 0.0, 0.0, 0.0), pitch_deg=0.0, roll_deg=0.0, heading_deg=0.0,
                     heading_sigma_deg=180.0, level_sigma_deg=1.0, converged=False, rho=0.0, trace_P=0.0, n_obs=0)


def relay(config_path: str) -> None:
    """Relay frame times to attitude messages, through the daemon's own outputs, until SIGTERM or SIGINT."""
    config = load_config(config_path)
    request_realtime(config.daemon.realtime_priority)   # as the daemon: before the session's threads
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    port = SerialPort(config.serial.path, config.serial.baud)
    decoder = FrameDecoder()
    with open_session(config.zenoh) as session:
        outputs = ZenohOutputs(session, UnitKeys(config.zenoh.prefix, config.zenoh.unit), dict)
        while not stop.is_set():
            rows, _ = decoder.feed_rows(port.read())
            outputs.records([replace(FIXED, t=t) for t in rows[:, 0].tolist()])
        outputs.close()
    port.close()


if __name__ == "__main__":
    relay(sys.argv[1])

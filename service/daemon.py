"""The alignment daemon: inputs → decoder → sample checks → pipeline → outputs.

What lies between the bytes and samples received and the records published needs no I/O: :class:`~.ingest.Ingest`
does it, fed by the loop. Around it sit thin shells, one job each: the serial port (serial_port.py), the Zenoh
inputs (zenoh_inputs.py) and outputs (zenoh_outputs.py), the NMEA 0183 and ROS 2 outputs
(nmea_outputs.py, ros_outputs.py), the recording (recording.py) and the status's health rule
(health.py).

One loop thread does everything in order, driven by the IMU frames' own timestamps: read what
arrived (serial port and/or the Zenoh IMU topic), decode, check every sample (time must move
forward, values finite), feed the pipeline, publish each attitude record as it comes out, and
publish the status at ``daemon.status_period_s`` of wall time. In an aided mode
(``aiding.inputs``: ``odo``, ``gnss``, both, or ``master``) the epochs of each kind (``…/aid/<kind>`` on Zenoh,
serial aiding frames) go to its track, and each IMU sample waits for its aiding (at most each stream's usual
interval plus ``aiding.max_wait_s`` of data time) before the pipeline takes them. A GNSS receiver's own output
(NMEA, UBX: ``[aiding.gnss] input``) is decoded from the IMU's line or from its own port (``[aiding.gnss] serial``,
read without waiting before the IMU's), its epochs put on the IMU's clock by their arrival time (arrival_clock.py).
Every drop is counted in the status; nothing received over the wire is executed or changes the configuration. The
Zenoh side also holds a liveliness token and answers a read-only query with the current state and the effective
configuration.
"""
from __future__ import annotations

import logging
import threading
import time

import numpy as np
import zenoh

from ..protocol import messages
from ..protocol.keys import UnitKeys
from ..protocol.results import ResultRecord
from .config import Config, ConfigError
from .health import health
from .ingest import Ingest, SampleCounters
from .loop_timing import LoopTiming
from .nmea_outputs import NmeaOutputs
from .recording import open_recording
from .ros_outputs import RosImuOutput
from .serial_port import SerialPort
from .zenoh_inputs import ZenohInputs
from .zenoh_outputs import ZenohOutputs

log = logging.getLogger("sinsalign.daemon")
UNIT_CHECK_S = 1.0
"""How long a start connected to other Zenoh nodes, or configured to connect to some, looks for another daemon's
liveliness token of the same unit (s): the connection and then the tokens arrive some 50 ms after the session
opens, later on a loaded machine. Without any peer to expect there is nothing to wait for."""


def gnss_port(config: Config) -> SerialPort | None:
    """The GNSS receiver's own port (``[aiding.gnss] serial``), opened, or None when it shares the IMU's line."""
    g = config.aiding.gnss
    if not g.serial:
        return None
    if g.input == "sinsalign":
        raise ConfigError("aiding.gnss.serial: a receiver's own port takes its own output (input = \"nmea\" or "
                          "\"ubx\"); the project's aiding frames come on the IMU's line")
    return SerialPort(g.serial, g.baud, config.serial.reconnect_max_s)


class Daemon:
    """Runs until :meth:`stop`; build it with an open Zenoh session and an optional serial port."""

    def __init__(self, config: Config, session: zenoh.Session, serial_port: SerialPort | None = None) -> None:
        self.config = config
        self.session = session
        self.serial = serial_port
        self.keys = UnitKeys(config.zenoh.prefix, config.zenoh.unit)
        self.ingest = Ingest(config, self._error, self._record_raw, self._record_restart)
        self.gnss_serial = gnss_port(config)
        self.last_error: str | None = None
        self.last_record: ResultRecord | None = None
        self._started = time.monotonic()
        self._last_input = None
        self._counters_at_status: dict[str, int] = {}
        self._stop = threading.Event()
        self._refuse_a_served_unit()   # before anything is opened: the other daemon's recording stays whole
        ros = RosImuOutput(session, self.keys, config.ros2) if config.ros2.enabled else None
        self.nmea = NmeaOutputs(config.nmea) if config.nmea.udp or config.nmea.serial else None
        self._recording = open_recording(config.daemon.record_path, config) if config.daemon.record_path else None
        self.outputs = ZenohOutputs(session, self.keys, self.state)
        self._record_outputs = [self.outputs, *(output for output in (self.nmea, ros) if output is not None)]
        self.inputs = ZenohInputs(session, self.keys, config.zenoh.imu_input, self.ingest.aid_kinds, self.counters,
                                  self._error)
        self._next_status = time.monotonic()
        self.loop_timing = LoopTiming()

    @property
    def counters(self) -> SampleCounters:
        """The sample counters: the ingest's, which the Zenoh inputs and the loop add to."""
        return self.ingest.counters

    # ---- inputs -------------------------------------------------------------------------
    def _read_inputs(self) -> tuple[np.ndarray, tuple[float, float]]:
        """Decoded samples from every input, in arrival order, and when the first read returned: (monotonic s, the
        loop thread's CPU time s), the start of the daemon's own share of their latency (:class:`LoopTiming`).

        The serial port first (its read waits up to 20 ms for data), then the Zenoh IMU inbox,
        drained without waiting when a serial port paces the loop, or waited on for up to 20 ms
        when Zenoh is the only input. Serial aiding frames go to :attr:`Ingest.aiding_inbox`.
        """
        # the receiver's own port first, without waiting, and its bytes stamped with the IMU's arrival after them:
        # the IMU frames sent before them are then read, so an epoch never seems to lead the IMU (at the bench's
        # ×speed a later read of the receiver would)
        receiver = self.gnss_serial.read(wait=False) if self.gnss_serial is not None else b""
        if self.serial is not None:
            data = self.serial.read()
            read_at = time.monotonic(), time.thread_time()
            serial = self.ingest.decode_serial(data, read_at[0])
        else:
            serial = None
        zenoh_rows = self.inputs.imu_samples(0.0 if serial is not None else 0.02)
        arrival_s = time.monotonic()
        if serial is None:
            read_at = arrival_s, time.thread_time()
        self.ingest.arrival_clock.observe(zenoh_rows[:, 0], arrival_s)
        if receiver:
            self.ingest.decode_receiver(receiver, arrival_s)
        if serial is None or not len(zenoh_rows):
            return (zenoh_rows if serial is None else serial), read_at
        return np.concatenate((serial, zenoh_rows)), read_at

    # ---- loop ---------------------------------------------------------------------------
    def step(self) -> list[ResultRecord]:
        """One pass of the loop: read, check, align, publish; returns the records published."""
        samples, (read_at, read_cpu_s) = self._read_inputs()
        records = self.ingest.feed_samples(samples, self.inputs.aiding_epochs(), defer_control=True)
        for output in self._record_outputs:
            output.records(records)
        if len(samples):
            self._last_input = now = time.monotonic()
            self.loop_timing.add(now - read_at, time.thread_time() - read_cpu_s)
        self.ingest.settle()   # the control step the records did not wait for
        if records:
            self.last_record = records[-1]
        self.counters.records_published += len(records)
        now = time.monotonic()
        if now >= self._next_status:
            self._next_status = now + self.config.daemon.status_period_s
            self.outputs.status(self.status(advance=True))
            if self._recording is not None:
                self._recording.flush()
        return records

    def run(self) -> None:
        """Loop until :meth:`stop` (or SIGINT/SIGTERM in ``sinsalign serve``), then close cleanly."""
        log.info("serving %s (attitude on %s, status on %s)", self._inputs_text(), self.keys.attitude,
                 self.keys.status)
        log.info("alignment: %s", self.ingest.pipeline.stages_text())
        try:
            while not self._stop.is_set():
                try:
                    self.step()
                except Exception as exc:   # a bug must not take the daemon down: count, log, go on
                    self.counters.internal_errors += 1
                    self._error(f"internal error: {type(exc).__name__}: {exc}")
                    log.exception("internal error in the loop (counted; the loop goes on)")
                    time.sleep(0.01)
        finally:
            self.close()

    @property
    def attitude_subscribed(self) -> bool:
        """Some subscriber matches the attitude key (``sinsalign demo`` waits for its watch client)."""
        return self.outputs.attitude_subscribed

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        self.outputs.status(self.status(advance=True))
        self.inputs.close()
        for output in self._record_outputs:
            output.close()
        for port in (self.serial, self.gnss_serial):
            if port is not None:
                port.close()
        if self._recording is not None:
            self._recording.close()
            self._recording = None
        log.info("stopped after %d samples, %d records", self.counters.samples_used,
                 self.counters.records_published)

    # ---- status, state, recording -----------------------------------------------------------
    def all_counters(self) -> dict[str, int]:
        counters = self.ingest.all_counters()
        zenoh_counters = self.inputs.counters()
        counters |= {**zenoh_counters, "inbox_overflow": counters["inbox_overflow"] + zenoh_counters["inbox_overflow"]}
        for prefix, port in (("serial", self.serial), ("gnss_serial", self.gnss_serial)):
            if port is not None:
                counters |= {f"{prefix}_disconnects": port.disconnects, f"{prefix}_reconnects": port.reconnects,
                             f"{prefix}_foreign_devices": port.foreign_devices}
        if self.nmea is not None:
            counters |= self.nmea.counters.as_dict()
        return counters

    def status(self, advance: bool = False) -> dict:
        """The status message; ``advance`` (the periodic status) makes its counters the baseline the next one's
        health is judged against (a state query must not swallow a rise)."""
        counters = self.all_counters()
        ingest = self.ingest
        awaiting = ingest.pipeline.awaiting_aid
        now = time.monotonic()
        waited_s = (ingest.t_last - ingest.t_first if ingest.t_last is not None else 0.0) if awaiting else None
        state = health(now - self._started, None if self._last_input is None else now - self._last_input, waited_s,
                       self._counters_at_status, counters)
        if advance:
            self._counters_at_status = counters
        last_error = ingest.aid_wait_text() if awaiting else ingest.aid_stopped_text()
        last_error = last_error or self.last_error or (self.serial.last_error if self.serial is not None else None)
        phase = self.last_record.phase if self.last_record is not None else "coarse"
        return messages.status_message(self.keys.unit, now - self._started, state, phase,
                                       ingest.t_last, last_error, counters, self.loop_timing.summary(advance))

    def state(self) -> dict:
        """The answer to a state query: the status now, the last attitude and the configuration in effect."""
        return {"v": messages.VERSION, "unit": self.keys.unit, "status": self.status(),
                "attitude": (messages.attitude_message(self.keys.unit, self.last_record)
                             if self.last_record is not None else None),
                "config": self.config.as_dict()}

    def _error(self, text: str) -> None:
        if text != self.last_error:
            log.warning(text)
        self.last_error = text

    def _refuse_a_served_unit(self) -> None:
        """Raise ConfigError if another daemon's liveliness token for this unit is on the network: two daemons on one
        unit id would interleave one attitude stream. (A peer that connects later is not seen here.)"""
        info = self.session.info
        expected = bool(self.config.zenoh.connect or list(info.peers_zid()) or list(info.routers_zid()))
        deadline = time.monotonic() + (UNIT_CHECK_S if expected else 0.0)
        while not any(reply.ok is not None for reply in self.session.liveliness().get(self.keys.alive, timeout=0.1)):
            if time.monotonic() >= deadline:
                return
            time.sleep(0.02)   # the peers' tokens arrive just after the session opens
        raise ConfigError(f"zenoh.unit {self.keys.unit!r}: another daemon already serves it on this Zenoh network "
                          f"(its liveliness token {self.keys.alive} is up): give this one another unit id")

    def _inputs_text(self) -> str:
        inputs = [f"{what} {port.path} @ {port.baud} Bd" for what, port in (("serial", self.serial),
                  ("GNSS receiver", self.gnss_serial)) if port is not None]
        return " + ".join(inputs + self.inputs.texts()) or "no input"

    def _record_restart(self, reason: str) -> None:
        """A restart into the recording, if one is open: its replay starts over at the same sample."""
        if self._recording is not None:
            self._recording.restart(reason)

    def _record_raw(self, rows: np.ndarray) -> None:
        """Admitted rows (N, 7: t in s, Δθ in rad, Δv in m/s) into the recording, if one is open."""
        if self._recording is not None:
            self._recording.rows(rows)

"""The alignment daemon: inputs → decoder → sample checks → pipeline → Zenoh publishers.

One loop thread does everything in order, driven by the IMU frames' own timestamps: read what
arrived (serial port and/or the Zenoh IMU topic), decode, check every sample (time must move
forward, values finite), feed the pipeline, publish each attitude record as it comes out, and
publish the status at ``daemon.status_period_s`` of wall time. In an aided mode
(``aiding.inputs``: ``odo``, ``gnss`` or ``master``) the epochs of that kind (``…/aid/<kind>`` on Zenoh, serial
aiding frames) go to its track, and each IMU sample waits for its aiding (at most the stream's usual
interval plus ``aiding.max_wait_s`` of data time) before the pipeline takes both. Every drop is counted in the
status; nothing received over the wire is executed or changes the configuration. The Zenoh side
also holds a liveliness token and answers a read-only query with the current state and the
effective configuration.
"""
from __future__ import annotations

import logging
import os
import queue
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import numpy as np
import zenoh

from ..protocol import messages
from ..protocol.counters import Counters
from ..protocol.imu_log import IMU_COLUMNS, write_header, write_rows
from ..protocol.keys import UnitKeys
from ..protocol.results import ResultRecord
from ..protocol.sequence import SequenceTracker
from ..protocol.serial_frame import MSG_AIDING, MSG_IMU, Frame, FrameDecoder, decode_aiding, decode_imu
from .aided_pipeline import build_pipeline
from .aiding import AidingTrack, AidingWait
from .align.conventions import DEG
from .align.earth import Site
from .config import Config
from .pipeline import AlignmentPipeline
from .sample_gate import SampleGate
from .serial_port import SerialPort

log = logging.getLogger("sinsalign.daemon")
NO_INPUT_S = 1.0
AID_START_GRACE_S = 30.0
"""IMU data (s) an aided mode may run without a usable aiding value before health degrades: a GNSS receiver's
warm start; a stream that never comes, comes for another kind, or is stamped off the IMU's clock shows after it."""
INBOX_LIMIT = 100_000
AIDING_INBOX_LIMIT = 10_000
"""Serial aiding epochs held in ``Daemon.aiding_inbox`` until the aided modes take them (then dropped, counted)."""
MSGPACK = zenoh.Encoding("application/msgpack")


def summed(before: dict[str, int], now: dict[str, int]) -> dict[str, int]:
    """Counters ``before`` a restart plus the new pipeline's ``now``, key by key (a key in either)."""
    return {**before, **{key: before.get(key, 0) + count for key, count in now.items()}}


@dataclass(slots=True)
class SampleCounters(Counters):
    """Checks on decoded samples, whatever their input."""

    samples_in: int = 0
    samples_in_serial: int = 0      # of samples_in, decoded from serial IMU frames
    samples_in_zenoh: int = 0       # of samples_in, from the Zenoh IMU topic
    samples_used: int = 0
    aiding_frames: int = 0          # valid serial aiding epochs (type 2) received
    bad_aiding: int = 0             # type-2 payloads decode_aiding rejected (unknown kind, length, non-finite)
    bad_messages: int = 0
    aiding_unused: int = 0          # aiding epochs of a kind the configuration does not use
    inbox_overflow: int = 0
    records_published: int = 0
    internal_errors: int = 0



class Daemon:
    """Runs until :meth:`stop`; build it with an open Zenoh session and an optional serial port."""

    def __init__(self, config: Config, session: zenoh.Session, serial_port: SerialPort | None = None) -> None:
        self.config = config
        self.session = session
        self.serial = serial_port
        self.keys = UnitKeys(config.zenoh.prefix, config.zenoh.unit)
        s = config.site
        self.site = Site(s.lat_deg * DEG, s.lon_deg * DEG, s.height_m)
        self.aid_kinds = config.aiding.inputs
        self.pipeline = self._new_pipeline()
        ad = config.aiding
        self.tracks = {kind: AidingTrack.configured(kind, ad) for kind in self.aid_kinds}
        # one aided mode at a time (build_pipeline refuses other combinations): the samples wait for its kind
        self._wait = (AidingWait(self.tracks[self.pipeline.aid_kind], ad.max_wait_s) if self.pipeline.aid_width
                      else None)
        self.gate = SampleGate(config.imu.rate_hz, config.daemon.max_bridge_samples)
        self.decoder = FrameDecoder()
        self.zenoh_sequence = SequenceTracker(modulus=1 << 32)
        self.counters = SampleCounters()
        self.last_error: str | None = None
        self._reported: dict[str, str | None] = {"gate": None, "disturbance": None, "alignment": None,
                                                 "aiding": None}
        self._disturbances_before = 0
        self._aiding_before: dict[str, int] = {}   # the aiding counters of the pipelines before restarts
        self.last_record: ResultRecord | None = None
        self.t_first: float | None = None   # the first sample's time: how long an aided mode has run without aid
        self.t_last: float | None = None
        self._pipeline_lock = threading.Lock()   # the status (a Zenoh query's thread too) sees a restart whole
        self._started = time.monotonic()
        self._last_input = None
        self._counters_at_status: dict[str, int] = {}
        self._stop = threading.Event()
        self._inbox: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        # Hook for the aided modes: (kind, epoch) of every valid serial aiding frame, in arrival
        # order, not yet used by the pipeline; a consumer takes them (`inbox, self.aiding_inbox =
        # self.aiding_inbox, []`). At most AIDING_INBOX_LIMIT are held (the rest: `inbox_overflow`).
        self.aiding_inbox: list[tuple[str, messages.AidingSample]] = []
        self._recording: TextIO | None = self._open_recording(config.daemon.record_path)
        self._attitude_pub = session.declare_publisher(self.keys.attitude, encoding=MSGPACK)
        self._status_pub = session.declare_publisher(self.keys.status, encoding=MSGPACK)
        self._token = session.liveliness().declare_token(self.keys.alive)
        self._queryable = session.declare_queryable(self.keys.state, self._on_query)
        self._imu_sub = (session.declare_subscriber(self.keys.imu, self._on_imu)
                         if config.zenoh.imu_input else None)
        self._aid_inbox: queue.SimpleQueue[tuple[str, bytes]] = queue.SimpleQueue()
        self._aid_subs = [session.declare_subscriber(self.keys.aid(kind), self._aid_callback(kind))
                          for kind in self.aid_kinds]
        self._next_status = time.monotonic()

    def _new_pipeline(self) -> AlignmentPipeline:
        return build_pipeline(self.config, self.site, self.config.imu.rate_hz,
                              aids=self.aid_kinds, live=True)

    def _restart_pipeline(self) -> None:
        """A fresh pipeline after an outage: the old one's counts carry on in the status, and an aid that had begun
        stays begun (an observation without it is a dropout, not a wait)."""
        pipeline = self._new_pipeline()
        pipeline.carry_aid_start(self.pipeline)
        with self._pipeline_lock:
            self._disturbances_before += self.pipeline.disturbances
            self._aiding_before = summed(self._aiding_before, self.pipeline.aiding_counters())
            self.pipeline = pipeline

    # ---- inputs -------------------------------------------------------------------------
    def _aid_callback(self, kind: str):
        def on_aid(sample: zenoh.Sample) -> None:   # a Zenoh thread: hand the bytes over
            if self._aid_inbox.qsize() >= INBOX_LIMIT:
                self.counters.inbox_overflow += 1
                return
            self._aid_inbox.put((kind, sample.payload.to_bytes()))
        return on_aid

    def _take_aiding_epochs(self) -> None:
        """Every aiding epoch that arrived (Zenoh and serial) into its kind's track; others counted."""
        epochs, self.aiding_inbox = self.aiding_inbox, []
        while True:
            try:
                kind, data = self._aid_inbox.get_nowait()
            except queue.Empty:
                break
            try:
                epochs.append((kind, messages.decode_aiding(kind, data)))
            except messages.MessageError as exc:
                self.counters.bad_aiding += 1
                self._error(f"aiding message on {self.keys.aid(kind)} dropped: {exc}")
        for kind, epoch in epochs:
            if kind in self.tracks:
                self.tracks[kind].push(np.array([messages.aiding_row(epoch)]))
            else:
                self.counters.aiding_unused += 1

    def _on_imu(self, sample: zenoh.Sample) -> None:
        # a Zenoh thread: only hand the bytes over; decoding happens in the loop
        if self._inbox.qsize() >= INBOX_LIMIT:
            self.counters.inbox_overflow += 1
            return
        self._inbox.put(sample.payload.to_bytes())

    def _read_inputs(self) -> list[tuple[float, tuple, tuple, int, bool]]:
        """Decoded samples (t, Δθ, Δv, status, saturated) from every input, in arrival order.

        The serial port first (its read waits up to 20 ms for data), then the Zenoh IMU inbox,
        drained without waiting when a serial port paces the loop, or waited on for up to 20 ms
        when Zenoh is the only input. Serial aiding frames go to :attr:`aiding_inbox`.
        """
        out = []
        if self.serial is not None:
            out += self._read_serial()
        if self._imu_sub is not None:
            try:
                first = self._inbox.get_nowait() if self.serial is not None else self._inbox.get(timeout=0.02)
            except queue.Empty:
                return out
            out += self._decode_zenoh(self._drain(first))
        return out

    def _read_serial(self) -> list[tuple[float, tuple, tuple, int, bool]]:
        out = []
        for frame in self.decoder.feed(self.serial.read()):
            if frame.msg_type == MSG_IMU:
                m = decode_imu(frame)
                out.append((m.t, m.dtheta, m.dv, m.status, m.saturated))
            elif frame.msg_type == MSG_AIDING:
                self._take_aiding(frame)
        self.counters.samples_in_serial += len(out)
        return out

    def _take_aiding(self, frame: Frame) -> None:
        try:
            epoch = decode_aiding(frame)
        except messages.MessageError as exc:
            self.counters.bad_aiding += 1
            self._error(f"serial aiding frame dropped: {exc}")
            return
        self.counters.aiding_frames += 1
        if len(self.aiding_inbox) >= AIDING_INBOX_LIMIT:
            self.counters.inbox_overflow += 1
            return
        self.aiding_inbox.append((epoch.kind, epoch))

    def _decode_zenoh(self, items: list[bytes]) -> list[tuple[float, tuple, tuple, int, bool]]:
        out = []
        for data in items:
            try:
                m = messages.decode_imu(data)
            except messages.MessageError as exc:
                self.counters.bad_messages += 1
                self._error(f"IMU message dropped: {exc}")
                continue
            if self.zenoh_sequence.accept(m.seq):
                out.append((m.t, m.dtheta, m.dv, m.status, False))
        self.counters.samples_in_zenoh += len(out)
        return out

    def _drain(self, first: bytes) -> list[bytes]:
        items = [first]
        while True:
            try:
                items.append(self._inbox.get_nowait())
            except queue.Empty:
                return items

    # ---- loop ---------------------------------------------------------------------------
    def _feed(self, rows: np.ndarray | None, everything: bool = False) -> list[ResultRecord]:
        """Samples (N, 7) into the pipeline; in the aided mode they wait for their aiding first."""
        if self._wait is None:
            return [] if rows is None else self.pipeline.process(rows[:, 0], rows[:, 1:4], rows[:, 4:7])
        if rows is not None:
            self._wait.push(rows)
        ready, aid = self._wait.release(everything)
        if len(ready) == 0:
            return []
        return self.pipeline.process(ready[:, 0], ready[:, 1:4], ready[:, 4:7], aid)

    def step(self) -> list[ResultRecord]:
        """One pass of the loop: read, check, align, publish; returns the records published."""
        samples = self._read_inputs()
        self._take_aiding_epochs()
        records: list[ResultRecord] = []
        if samples:
            self.counters.samples_in += len(samples)
            self._last_input = time.monotonic()
            for segment in self.gate.admit(samples):
                if segment.restart:
                    self._error(segment.reason)
                    records += self._feed(None, everything=True)   # what waited for aiding, to the old pipeline
                    self._restart_pipeline()
                t = segment.rows[:, 0]
                self.counters.samples_used += len(t)
                self.t_first = float(t[0]) if self.t_first is None else self.t_first
                self.t_last = float(t[-1])
                self._record_raw(t, segment.rows[:, 1:4], segment.rows[:, 4:7])
                records += self._feed(segment.rows)
            for source, text in (("gate", self.gate.last_error), ("disturbance", self.pipeline.last_disturbance),
                                 ("alignment", self.pipeline.last_notice), ("aiding", self._aid_stopped_text())):
                if text and text != self._reported[source]:   # report each new event once
                    self._reported[source] = text
                    self._error(text)
        elif self._wait is not None and self._wait.held:
            records += self._feed(None)   # aiding that came after the last samples lets them go
        for record in records:
            self._attitude_pub.put(messages.pack(messages.attitude_message(self.keys.unit, record)))
            self.last_record = record
        self.counters.records_published += len(records)
        now = time.monotonic()
        if now >= self._next_status:
            self._next_status = now + self.config.daemon.status_period_s
            self._status_pub.put(messages.pack(self.status(advance=True)))
            if self._recording is not None:
                self._recording.flush()
        return records

    def run(self) -> None:
        """Loop until :meth:`stop` (or SIGINT/SIGTERM in ``sinsalign serve``), then close cleanly."""
        log.info("serving %s (attitude on %s, status on %s)", self._inputs_text(), self.keys.attitude,
                 self.keys.status)
        log.info("alignment: %s", self.pipeline.stages_text())
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
        return self._attitude_pub.matching_status.matching

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        self._status_pub.put(messages.pack(self.status(advance=True)))
        for entity in (self._imu_sub, *self._aid_subs, self._queryable, self._token, self._status_pub,
                       self._attitude_pub):
            if entity is not None:
                entity.undeclare()
        if self.serial is not None:
            self.serial.close()
        if self._recording is not None:
            self._recording.close()
            self._recording = None
        log.info("stopped after %d samples, %d records", self.counters.samples_used,
                 self.counters.records_published)

    # ---- status, state, recording -----------------------------------------------------------
    def all_counters(self) -> dict[str, int]:
        with self._pipeline_lock:
            pipeline_counts = {"disturbances": self._disturbances_before + self.pipeline.disturbances,
                               **summed(self._aiding_before, self.pipeline.aiding_counters())}
        counters = {**self.decoder.all_counters(), **self.counters.as_dict(), **self.gate.counters.as_dict(),
                    **self.zenoh_sequence.counters("zenoh_seq_"), **pipeline_counts}
        for kind, track in self.tracks.items():
            counters |= track.counters.as_dict(f"{kind}_")
        if self.serial is not None:
            counters |= {"serial_disconnects": self.serial.disconnects, "serial_reconnects": self.serial.reconnects}
        return counters

    def status(self, advance: bool = False) -> dict:
        """The status message; ``advance`` (the periodic status) makes its counters the baseline the next one's
        health is judged against (a state query must not swallow a rise)."""
        counters = self.all_counters()
        errors = messages.fault_count(counters)
        awaiting = self.pipeline.awaiting_aid
        if self._last_input is None:
            health = "starting" if time.monotonic() - self._started < NO_INPUT_S else "no_input"
        elif time.monotonic() - self._last_input > NO_INPUT_S:
            health = "no_input"
        else:   # a receiver before its first fix is no fault, for a while: the aided alignment has not begun
            rose = errors > messages.fault_count(self._counters_at_status)
            overdue = awaiting and self.t_last is not None and self.t_last - self.t_first > AID_START_GRACE_S
            health = ("degraded" if rose or overdue or messages.screening_alarm(self._counters_at_status, counters)
                      else "starting" if awaiting else "ok")
        if advance:
            self._counters_at_status = counters
        last_error = self._aid_wait_text() if awaiting else self._aid_stopped_text()
        last_error = last_error or self.last_error or (self.serial.last_error if self.serial is not None else None)
        phase = self.last_record.phase if self.last_record is not None else "coarse"
        return messages.status_message(self.keys.unit, time.monotonic() - self._started, health, phase, self.t_last,
                                       last_error, counters)

    def _aid_wait_text(self) -> str | None:
        """What an aided mode without a usable aiding value yet waits for, once IMU data have come."""
        if self.t_last is None:
            return None
        kind = self.pipeline.aid_kind
        track = self.tracks[kind]
        if track.latest_time is None:
            return (f"no {kind} epoch yet after {self.t_last - self.t_first:.1f} s of IMU data: the aided alignment "
                    f"starts with the first (check the receiver, --aid {kind}, its topic or serial frames)")
        return (f"{kind} epochs arrive ({track.counters.epochs}, the newest at t = {track.latest_time:.2f} s) but "
                f"none covers the IMU's time yet (t = {self.t_last:.2f} s): a clock offset or aiding.{kind}_latency_s?")

    def _aid_stopped_text(self) -> str | None:
        """What an aided mode misses while its stream, once begun, has been silent for longer than the wait."""
        if self._wait is None or self.t_last is None or self.pipeline.awaiting_aid:
            return None
        kind = self.pipeline.aid_kind
        latest = self.tracks[kind].latest_time
        if latest is None or self.t_last - latest <= self._wait.wait_s:
            return None
        return (f"{kind} epochs stopped after t = {latest:.2f} s: the alignment goes on without them (check the "
                f"receiver, its topic or serial frames)")

    def _on_query(self, query: zenoh.Query) -> None:
        state = {"v": messages.VERSION, "unit": self.keys.unit, "status": self.status(),
                 "attitude": (messages.attitude_message(self.keys.unit, self.last_record)
                              if self.last_record is not None else None),
                 "config": self.config.as_dict()}
        query.reply(self.keys.state, messages.pack(state), encoding=MSGPACK)

    def _error(self, text: str) -> None:
        if text != self.last_error:
            log.warning(text)
        self.last_error = text

    def _inputs_text(self) -> str:
        inputs = [f"serial {self.serial.path} @ {self.serial.baud} Bd"] if self.serial is not None else []
        if self._imu_sub is not None:
            inputs.append(f"Zenoh {self.keys.imu}")
        aiding = [f"{kind} aiding (Zenoh {self.keys.aid(kind)}, serial aiding frames)" for kind in self.aid_kinds]
        return " + ".join(inputs + aiding) or "no input"

    def _open_recording(self, path: str) -> TextIO | None:
        if not path:
            return None
        # owner-only: a recording of the raw input is the customer's data
        fd = os.open(Path(path), os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        stream = os.fdopen(fd, "w", encoding="utf-8")
        s, sensor = self.config.site, self.config.sensor
        write_header(stream, {"lat_deg": s.lat_deg, "lon_deg": s.lon_deg, "height_m": s.height_m,
                              "rate_hz": self.config.imu.rate_hz, "gyro_bias_deg_h": sensor.gyro_bias_deg_h,
                              "gyro_arw_deg_rth": sensor.gyro_arw_deg_rth, "acc_bias_ug": sensor.acc_bias_ug,
                              "acc_vrw_ug_rthz": sensor.acc_vrw_ug_rthz}, IMU_COLUMNS)
        return stream

    def _record_raw(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray) -> None:
        if self._recording is not None:
            write_rows(self._recording, np.column_stack((t, dtheta, dv)))

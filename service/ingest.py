"""The daemon's path from received data to attitude records, without its I/O: decoder → sample gate → pipeline.

Serial bytes go through the serial format's decoder (serial_formats.py: IMU samples out, aiding epochs to their
tracks), every decoded sample through the :class:`~.sample_gate.SampleGate`, and what it admits into the alignment
pipeline (in an aided mode after the :class:`~.aiding.AidingWait`); a restart the gate asks for starts a fresh
pipeline whose counts carry on. Every stage keeps its state between calls,
so one byte stream gives the same records and counters in whatever pieces it is read.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from ..protocol import messages
from ..protocol.counters import Counters, count
from ..protocol.results import ResultRecord
from .aiding import AidingTrack, AidingWait
from .align.conventions import DEG
from .align.earth import Site
from .arrival_clock import ArrivalClock
from .config import Config
from .gnss_receiver import gnss_receiver_for
from .pipeline import AlignmentPipeline, build_pipeline
from .restarting import RestartingPipeline
from .sample_gate import gate_for
from .serial_formats import Decoded, SerialFormat, serial_format_for

AIDING_INBOX_LIMIT = 10_000
"""Serial aiding epochs held in ``Ingest.aiding_inbox`` until the aided modes take them (then dropped, counted)."""


@dataclass(slots=True)
class SampleCounters(Counters):
    """Checks on decoded samples, whatever their input."""

    samples_in: int = count("IMU samples decoded, from every input")
    samples_in_serial: int = count("of samples_in, decoded from serial IMU frames")
    samples_in_zenoh: int = count("of samples_in, from the Zenoh IMU topic")
    samples_used: int = count("samples the gate admitted into the alignment")
    aiding_frames: int = count("valid serial aiding epochs received (type-2 frames, a GNSS receiver's epochs)")
    bad_aiding: int = count("aiding epochs refused for what they hold (unknown kind, length, non-finite, beyond what "
                            "a sensor reports), serial or Zenoh")
    bad_messages: int = count("Zenoh IMU messages refused (not msgpack, wrong fields, non-finite)")
    aiding_unused: int = count("aiding epochs of a kind the configuration does not take")
    inbox_overflow: int = count("messages or aiding epochs dropped because an inbox was full")
    records_published: int = count("attitude records published")
    internal_errors: int = count("exceptions in the loop (a bug: logged with its traceback, the loop goes on)")


class Ingest:
    """Decoder, sample gate, aiding tracks and pipeline of one daemon, fed by :meth:`feed_bytes` (serial bytes in
    ``serial_format``, the configured one by default) or :meth:`feed_samples` (samples decoded from any input);
    ``report`` gets every event for the operator (once each), ``record_rows`` every admitted row (N, 7: t in s, Δθ in
    rad, Δv in m/s) before the pipeline takes it."""

    def __init__(self, config: Config, report: Callable[[str], None],
                 record_rows: Callable[[np.ndarray], None] | None = None,
                 record_restart: Callable[[str], None] | None = None,
                 serial_format: SerialFormat | None = None) -> None:
        self.config = config
        s = config.site
        self.site = Site(s.lat_deg * DEG, s.lon_deg * DEG, s.height_m)
        self.aid_kinds = config.aiding.inputs
        self.alignment = RestartingPipeline(self._new_pipeline, report)
        ad = config.aiding
        self.tracks = {kind: AidingTrack.configured(kind, ad) for kind in self.aid_kinds}
        # the samples wait for every kind the mode takes (build_pipeline refuses combinations without one)
        self._wait = (AidingWait([self.tracks[kind] for kind in self.pipeline.aid_kinds], ad.max_wait_s)
                      if self.pipeline.aid_width else None)
        self.gate = gate_for(config)
        self.serial_format = serial_format or serial_format_for(config)
        # a GNSS receiver's own output ([aiding.gnss] input): its epochs go onto the IMU's clock by arrival time
        self.arrival_clock = ArrivalClock()
        self.receiver = gnss_receiver_for(config.aiding.gnss, self.arrival_clock)
        self._receiver_on_imu_line = self.receiver is not None and not config.aiding.gnss.serial
        self.counters = SampleCounters()
        # Hook for the aided modes: (kind, epoch) of every valid serial aiding frame, in arrival order, not yet
        # in its track; :meth:`feed_samples` takes them. At most AIDING_INBOX_LIMIT are held (the rest:
        # `inbox_overflow`).
        self.aiding_inbox: list[tuple[str, messages.AidingSample]] = []
        self.t_first: float | None = None   # the first sample's time (s): how long an aided mode has run without aid
        self.t_last: float | None = None    # the newest admitted sample's time (s)
        self._report = report
        self._record_rows = record_rows
        self._record_restart = record_restart
        self._defer_control = False   # this pass's (feed_samples)

    def _new_pipeline(self) -> AlignmentPipeline:
        return build_pipeline(self.config, self.site, self.config.imu.rate_hz, aids=self.aid_kinds, live=True)

    @property
    def pipeline(self) -> AlignmentPipeline:
        """The alignment pipeline now (a restart replaces it)."""
        return self.alignment.pipeline

    def _restart(self, reason: str) -> None:
        """Start the alignment over, marked in the recording so that its replay does the same."""
        if self._record_restart is not None:
            self._record_restart(reason)
        self.alignment.restart()

    # ---- inputs -------------------------------------------------------------------------
    def decode_serial(self, data: bytes, arrival_s: float | None = None) -> np.ndarray:
        """The IMU samples (N, :data:`~.sample_gate.SAMPLE_COLUMNS`) that ``data`` completes (any piece of the serial
        stream, in the configured format, arrived at ``arrival_s``: host monotonic clock, s, now if None); its aiding
        epochs, and a receiver's on the IMU's line, go to :attr:`aiding_inbox`, the pace of a vendor's counter stamps
        on the host's clock (``Decoded.pace``) to the gate's rate check."""
        arrival_s = time.monotonic() if arrival_s is None else arrival_s
        decoded = self.serial_format.feed(data)
        if decoded.pace is not None:   # counter stamps on the host's clock: a rate their steps cannot show
            self.gate.rate.host_pace(decoded.pace)
        self.arrival_clock.observe(decoded.samples[:, 0], arrival_s)
        self._hold(decoded)
        if self._receiver_on_imu_line:
            self._hold(self.receiver.feed(data, arrival_s))
        self.counters.samples_in_serial += len(decoded.samples)
        return decoded.samples

    def decode_receiver(self, data: bytes, arrival_s: float) -> None:
        """Bytes of the GNSS receiver's own port (``[aiding.gnss] serial``), arrived at ``arrival_s`` (host
        monotonic clock, s): its epochs go to :attr:`aiding_inbox`."""
        self._hold(self.receiver.feed(data, arrival_s))

    def _hold(self, decoded: Decoded) -> None:
        """A decoder's notices and refusals reported (refusals counted), its aiding epochs into the inbox."""
        for text in decoded.notices:
            self.alignment.report_new("input", text)
        for text in decoded.refused:
            self.counters.bad_aiding += 1
            self._report(text)
        for epoch in decoded.aiding:
            self.counters.aiding_frames += 1
            if len(self.aiding_inbox) >= AIDING_INBOX_LIMIT:
                self.counters.inbox_overflow += 1
            else:
                self.aiding_inbox.append((epoch.kind, epoch))

    def _take_aiding_epochs(self, epochs: Iterable[tuple[str, messages.AidingSample]]) -> None:
        """The serial aiding epochs held, then ``epochs`` (another input's), each into its kind's track; others
        counted."""
        held, self.aiding_inbox = self.aiding_inbox, []
        for kind, epoch in (*held, *epochs):
            if kind in self.tracks:
                self.tracks[kind].push(np.array([messages.aiding_row(epoch)]))
            else:
                self.counters.aiding_unused += 1

    # ---- alignment ----------------------------------------------------------------------
    def feed_bytes(self, data: bytes) -> list[ResultRecord]:
        """Serial bytes as a read gave them (any piece of the stream) → the records they complete."""
        return self.feed_samples(self.decode_serial(data))

    def feed_samples(self, samples: np.ndarray, epochs: Iterable[tuple[str, messages.AidingSample]] = (),
                     defer_control: bool = False) -> list[ResultRecord]:
        """Decoded samples of one pass (N, :data:`~.sample_gate.SAMPLE_COLUMNS`), in arrival order, and the aiding
        ``epochs`` that came with them from other than the serial port (after the serial ones, into their tracks) →
        the records they complete. Without samples, aiding that came after the last ones lets those waiting for it
        go. ``defer_control``: a control step that ends the pass is left for :meth:`settle` (the records go out
        first; the next pass settles it anyway)."""
        self._take_aiding_epochs(epochs)
        self._defer_control = defer_control
        if len(samples) == 0:
            return self._feed(None) if self._wait is not None and self._wait.held else []
        records: list[ResultRecord] = []
        self.counters.samples_in += len(samples)
        for segment in self.gate.admit(samples):
            if segment.restart:
                self._report(segment.reason)
                records += self._feed(None, everything=True)   # what waited for aiding, to the old pipeline
                self._restart(segment.reason)
                if len(segment.rows) == 0:
                    continue
            t = segment.rows[:, 0]
            self.counters.samples_used += len(t)
            self.t_first = float(t[0]) if self.t_first is None else self.t_first
            self.t_last = float(t[-1])
            if self._record_rows is not None:
                self._record_rows(segment.rows)
            records += self._feed(segment.rows)
        self._report_events()
        return records

    def settle(self) -> None:
        """The control step a pass with ``defer_control`` left, with its events (a failure restarts the alignment,
        marked in the recording)."""
        failure = self.alignment.settle()
        if failure is not None and self._record_restart is not None:
            self._record_restart(failure)
        self._report_events()

    def _report_events(self) -> None:
        """The gate's, the pipeline's and the aiding's new events, each once."""
        self.alignment.report_new("gate", self.gate.last_error)
        self.alignment.report_events()
        self.alignment.report_new("aiding", self.aid_stopped_text())

    def _feed(self, rows: np.ndarray | None, everything: bool = False) -> list[ResultRecord]:
        """Samples (N, 7) into the pipeline; in the aided mode they wait for their aiding first."""
        if self._wait is None:
            return [] if rows is None else self._process(rows, None)
        if rows is not None:
            self._wait.push(rows)
        ready, aid = self._wait.release(everything)
        if len(ready) == 0:
            return []
        return self._process(ready, aid)

    def _process(self, rows: np.ndarray, aid: np.ndarray | None) -> list[ResultRecord]:
        """The pipeline's records of ``rows`` (N, 7) with their aiding; a failed step restarts it, counted, and is
        marked in the recording after these rows."""
        records, failure = self.alignment.process(rows[:, 0], rows[:, 1:4], rows[:, 4:7], aid, self._defer_control)
        if failure is not None and self._record_restart is not None:
            self._record_restart(failure)
        return records

    # ---- state --------------------------------------------------------------------------
    def all_counters(self) -> dict[str, int]:
        """Decoder, sample, gate, pipeline (summed over restarts) and aiding track counters, by status name."""
        pipeline_counts = self.alignment.counters()
        counters = {**self.serial_format.counters(), **self.counters.as_dict(), **self.gate.counters.as_dict(),
                    **pipeline_counts, **(self.receiver.counters() if self.receiver is not None else {})}
        for kind, track in self.tracks.items():
            counters |= track.counters.as_dict(f"{kind}_")
        return counters

    def aid_wait_text(self) -> str | None:
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

    def aid_stopped_text(self) -> str | None:
        """What an aided mode misses while a stream, once begun, has been silent for longer than the wait."""
        if self._wait is None or self.t_last is None or self.pipeline.awaiting_aid:
            return None
        for kind in self.pipeline.aid_kinds:
            track = self.tracks[kind]
            latest = track.latest_time
            if latest is not None and self.t_last - latest > self._wait.wait_s(track):
                return (f"{kind} epochs stopped after t = {latest:.2f} s: the alignment goes on without them (check "
                        f"the receiver, its topic or serial frames)")
        return None

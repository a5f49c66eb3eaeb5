"""What arrives on the serial line, decoded: a format turns the bytes of any read into IMU sample rows and aiding
epochs, and keeps its own counters.

The ingest core (ingest.py) takes a format and never looks inside it. The project's own frame
(protocol/serial_frame.py) is :class:`SinsalignFrames`; a vendor's frame (a STIM300 datagram, a KVH or Xsens
message, a declared frame) is a protocol decoder (protocol/vendor.py) inside :class:`VendorFrames`, which stamps
the sensor's counter into time and turns the sensor's axes into the body's. :func:`serial_format_for` picks
the configured one (``[imu] format``).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..protocol import messages
from ..protocol.axes import axis_map
from ..protocol.counter_clock import CounterClock
from ..protocol.declared_frame import DeclaredFrameDecoder
from ..protocol.kvh import KvhDecoder
from ..protocol.serial_frame import MSG_AIDING, FrameDecoder, decode_aiding
from ..protocol.stim300 import Stim300Decoder
from ..protocol.vendor import VendorDecoder
from ..protocol.xsens import XsensDecoder
from .config import Config
from .rate_check import HostPace
from .sample_gate import SAMPLE_COLUMNS


@dataclass(slots=True)
class Decoded:
    """What one read gave: IMU samples (N, :data:`~.sample_gate.SAMPLE_COLUMNS`), aiding epochs in arrival order,
    a line per unit that was dropped for what it held (its frame was whole: counted as ``bad_aiding``), lines
    for the operator (a configuration the stream contradicts), and ``pace``: the counter's seconds per host second
    over the span of reads this one completed (:class:`~.rate_check.HostPace`, for the sample gate's rate check;
    None: no span completed, or the samples carry no counter time on a real-time line)."""

    samples: np.ndarray
    aiding: list[messages.AidingSample] = field(default_factory=list)
    refused: list[str] = field(default_factory=list)
    notices: list[str] = field(default_factory=list)
    pace: float | None = None


class SerialFormat(Protocol):
    """A serial input format: bytes in any pieces in, :class:`Decoded` out, the same whatever the pieces."""

    def feed(self, data: bytes) -> Decoded: ...

    def counters(self) -> dict[str, int]: ...


class SinsalignFrames:
    """The project's own frame: IMU increments (type 1) and aiding epochs (type 2) on one line, each checked by its
    CRC and sequence counter (:class:`~sinsalign.protocol.serial_frame.FrameDecoder`)."""

    def __init__(self) -> None:
        self.decoder = FrameDecoder()

    def feed(self, data: bytes) -> Decoded:
        samples, frames = self.decoder.feed_rows(data)
        out = Decoded(samples)
        for frame in frames:
            if frame.msg_type == MSG_AIDING:
                try:
                    out.aiding.append(decode_aiding(frame))
                except messages.MessageError as exc:
                    out.refused.append(f"serial aiding frame dropped: {exc}")
        return out

    def counters(self) -> dict[str, int]:
        """The decoder's and its sequence counters (protocol/README.md, "Decoder rules and counters")."""
        return self.decoder.all_counters()


class VendorFrames:
    """A vendor IMU's frames: the protocol ``decoder``'s samples, stamped from its counter on the host clock
    (``clock``, s; anchored once, :class:`~sinsalign.protocol.counter_clock.CounterClock`; ``counter_only``: from
    the counter's steps alone) and turned from the sensor's axes into the body's (``C_s_b``,
    :func:`~sinsalign.protocol.axes.axis_map`). Unless ``counter_only`` (a bench faster than real time), the pace of
    the stamps on the arrival clock goes out with the samples (``Decoded.pace``): a counter stepping once a sample
    is stamped at the configured rate whatever the IMU's."""

    def __init__(self, decoder: VendorDecoder, C_s_b: np.ndarray,
                 clock: Callable[[], float] = time.monotonic, counter_only: bool = False) -> None:
        self.decoder = decoder
        self.C_s_b = C_s_b
        self.counter_clock = CounterClock(decoder.counter_modulus, decoder.tick_s, decoder.counter_step,
                                          counter_only)
        self._clock = clock
        self._pace = None if counter_only else HostPace()

    def feed(self, data: bytes) -> Decoded:
        arrival_s = self._clock()
        got = self.decoder.feed(data)
        t = self.counter_clock.stamp(got.counter, arrival_s)
        keep = ~np.isnan(t)   # a repeated counter: dropped (counted by the clock)
        rows = np.zeros((int(keep.sum()), SAMPLE_COLUMNS))
        rows[:, 0] = t[keep]
        rows[:, 1:4] = got.dtheta[keep] @ self.C_s_b.T
        rows[:, 4:7] = got.dv[keep] @ self.C_s_b.T
        rows[:, 7] = got.status[keep]
        pace = self._pace.observe(float(rows[-1, 0]), arrival_s) if self._pace is not None and len(rows) else None
        return Decoded(rows, notices=got.notices, pace=pace)

    def counters(self) -> dict[str, int]:
        """The decoder's counters and its counter's sequence counters (``seq_*``)."""
        return {**self.decoder.counters(), **self.counter_clock.counters()}


VENDOR_DECODERS: dict[str, Callable[[Config], VendorDecoder]] = {
    "stim300": lambda c: Stim300Decoder(c.imu.rate_hz, c.imu.stim300.datagram, c.imu.stim300.acc_range_g),
    "kvh1750": lambda c: KvhDecoder("1750", c.imu.rate_hz),
    "kvh1775": lambda c: KvhDecoder("1775", c.imu.rate_hz),
    "xsens": XsensDecoder.from_config,
    "frame": DeclaredFrameDecoder.from_config,
}
"""The vendor decoder of each ``[imu] format`` but ``sinsalign``, built from the configuration."""


def serial_format_for(config: Config, clock: Callable[[], float] = time.monotonic) -> SerialFormat:
    """The serial format ``[imu] format`` names, with the configured axes (``[imu] axes``); a vendor's counter is
    stamped on ``clock`` (s), the host's monotonic clock by default."""
    name = config.imu.format
    if name == "sinsalign":
        return SinsalignFrames()
    return VendorFrames(VENDOR_DECODERS[name](config), axis_map(config.imu.axes), clock, config.imu.counter_only)

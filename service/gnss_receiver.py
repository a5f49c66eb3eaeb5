"""A GNSS receiver's own output (``[aiding.gnss] input = "nmea"`` or ``"ubx"``) as the daemon's gnss epochs.

The receiver's decoder (protocol/gnss_nmea.py, protocol/gnss_ubx.py) gives fixes stamped with the host time their
bytes arrived at and with the receiver's own time of fix. The IMU's :class:`~.arrival_clock.ArrivalClock` puts the
arrival on the IMU's clock; a second one maps the receiver's time onto those IMU arrival times by their least lag,
so epochs that came in one read keep their spacing and the reads' jitter stays out. The gnss track takes
``[aiding.gnss] latency_s`` off the result as off every gnss epoch (service/aiding.py). An epoch before the first
IMU sample has no IMU time: dropped, counted. One beyond what a receiver can report (a latitude of 95°, 1e6 kn) is
refused with its reason (the daemon counts it as ``bad_aiding``).

The filter weighs every gnss epoch by the configured ``vel_std_mps`` and ``pos_std_m`` (one noise per stream: the
aiding tracks carry values, not their noise). A UBX receiver states its accuracy per epoch (hAcc, vAcc, sAcc): an
epoch stating more than :data:`ACCURACY_FACTOR` times the configured noise would be weighed as far better than it
is, so it is dropped, counted (``gnss_rx_inaccurate``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..protocol.counters import Counters, count
from ..protocol.gnss_fix import GnssFix, ReceiverDecoder
from ..protocol.gnss_nmea import NmeaDecoder
from ..protocol.gnss_ubx import UbxDecoder
from ..protocol.messages import AidingSample
from ..protocol.plausibility import aiding_problem
from .arrival_clock import ArrivalClock
from .config import GnssConfig
from .sample_gate import SAMPLE_COLUMNS
from .serial_formats import Decoded

RECEIVER_DECODERS = {"nmea": NmeaDecoder, "ubx": UbxDecoder}
"""The decoder of each ``[aiding.gnss] input`` but ``sinsalign`` (the project's aiding frames and messages)."""
ACCURACY_FACTOR = 3.0
"""A UBX epoch whose stated hAcc or vAcc exceeds this many ``pos_std_m``, or sAcc this many ``vel_std_mps``, is
dropped: weighed at the configured noise it would count 9 times too much."""


@dataclass(slots=True)
class ReceiverInputCounters(Counters):
    """What the receiver's epochs met on their way to the gnss track (status names prefixed ``gnss_rx_``)."""

    before_imu: int = count("receiver epochs that arrived before the first IMU sample: no IMU time (dropped)")
    inaccurate: int = count("UBX epochs whose stated accuracy is beyond 3 × the configured noise (dropped)")


class GnssReceiver:
    """A receiver ``decoder`` whose fixes go onto the IMU's ``clock``, held to ``gnss``'s noise (module
    docstring)."""

    def __init__(self, decoder: ReceiverDecoder, clock: ArrivalClock, gnss: GnssConfig) -> None:
        self.decoder = decoder
        self.clock = clock
        self.receiver_clock = ArrivalClock()   # the receiver's time (unwrapped) against its IMU arrival times
        self.gnss = gnss
        self._time: tuple[float, float] | None = None   # the latest fix's (receiver time, unwrapped time), s
        self._counters = ReceiverInputCounters()
        self._seq = 0

    def feed(self, data: bytes, arrival_s: float) -> Decoded:
        """The gnss epochs (IMU clock) of the fixes ``data`` completes, arrived at ``arrival_s`` (host clock, s),
        and a line per epoch refused for what it holds."""
        out = Decoded(np.empty((0, SAMPLE_COLUMNS)))
        fixes = self.decoder.feed(data, arrival_s)
        for fix, t in zip(fixes, self._imu_times(fixes, arrival_s), strict=True):
            values = {"lat_deg": (fix.lat_deg,), "lon_deg": (fix.lon_deg,), "h_m": (fix.h_m,), "v_enu": fix.v_enu}
            finite = all(math.isfinite(v) for vs in values.values() for v in vs)
            problem = aiding_problem("gnss", values) if finite else "a value is not finite"
            if problem is not None:
                out.refused.append(f"gnss receiver epoch dropped: {problem}")
            elif t is None:
                self._counters.before_imu += 1
            elif self._inaccurate(fix):
                self._counters.inaccurate += 1
            else:
                out.aiding.append(AidingSample("gnss", self._seq, t, values))
                self._seq += 1
        return out

    def _imu_times(self, fixes: list[GnssFix], arrival_s: float) -> list[float | None]:
        """The IMU times (s) of ``fixes``, which arrived together at ``arrival_s`` (host clock): their receiver times
        at the least lag behind their IMU arrival time. The newest of a read has the least lag of it; the others
        keep their spacing before it."""
        arrival = self.clock.source_time(arrival_s)
        if arrival is None or not fixes:
            return [None] * len(fixes)
        period = self.decoder.time_period_s
        times = []
        for fix in fixes:
            if self._time is None:
                unwrapped = fix.time_s
            else:   # the receiver's time wraps (a UTC day, a GPS week): the step from the last, the short way round
                step = (fix.time_s - self._time[0]) % period
                unwrapped = self._time[1] + (step - period if step > period / 2 else step)
            self._time = (fix.time_s, unwrapped)
            times.append(unwrapped)
        self.receiver_clock.observe(np.array(times), arrival)
        return [self.receiver_clock.arrival_time(t) for t in times]

    def _inaccurate(self, fix: GnssFix) -> bool:
        """Whether the receiver states an accuracy beyond :data:`ACCURACY_FACTOR` × the configured noise."""
        stated = ((fix.h_acc_m, self.gnss.pos_std_m), (fix.v_acc_m, self.gnss.pos_std_m),
                  (fix.s_acc_mps, self.gnss.vel_std_mps))
        return any(acc is not None and acc > ACCURACY_FACTOR * std for acc, std in stated)

    def counters(self) -> dict[str, int]:
        """The decoder's counters and this input's, prefixed ``gnss_rx_``."""
        return {f"gnss_rx_{k}": v for k, v in {**self.decoder.counters(), **self._counters.as_dict()}.items()}


def gnss_receiver_for(gnss: GnssConfig, clock: ArrivalClock) -> GnssReceiver | None:
    """The receiver ``[aiding.gnss] input`` names, or None for the project's own aiding frames and messages."""
    decoder = RECEIVER_DECODERS.get(gnss.input)
    return None if decoder is None else GnssReceiver(decoder(), clock, gnss)

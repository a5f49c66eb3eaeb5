"""What a GNSS receiver decoder (gnss_nmea.py, gnss_ubx.py) gives: the fixes a read completed, and its counters.

A decoder is sans-I/O: bytes in any pieces and the host time they arrived at in, the same fixes out whatever the
pieces. It ignores whatever is not its own (the IMU's frames on a shared line), counts what is its own but
unusable, and leaves the time mapping, the plausibility limits and the noise to the service
(service/gnss_receiver.py).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from .counters import Counters, count


@dataclass(frozen=True, slots=True)
class GnssFix:
    """One receiver epoch: the host time the read that completed it arrived at (``arrival_s``, s), the receiver's
    own time of the fix (``time_s``, s, wrapping at the decoder's ``time_period_s``), the antenna's geodetic
    position (WGS-84 lat_deg, lon_deg, h_m above the ellipsoid), its velocity over ground v_enu (m/s, East, North,
    Up) and, where the receiver states them, its accuracy estimates (m horizontal and vertical, m/s speed; None
    otherwise)."""

    arrival_s: float
    time_s: float
    lat_deg: float
    lon_deg: float
    h_m: float
    v_enu: tuple[float, float, float]
    h_acc_m: float | None = None
    v_acc_m: float | None = None
    s_acc_mps: float | None = None


@dataclass(slots=True)
class ReceiverCounters(Counters):
    """What a receiver decoder dropped (status names prefixed ``gnss_rx_``)."""

    checksum_errors: int = count("receiver messages (NMEA sentences, UBX NAV-PVT) whose checksum failed")
    malformed: int = count("receiver messages with a valid checksum whose fields do not parse")
    no_fix: int = count("receiver epochs without a GNSS fix (GGA quality 0 or 6, RMC status V, RMC or VTG mode "
                        "E, N, M or S, NAV-PVT without a 3-D or GNSS + dead reckoning fix and gnssFixOK)")
    unpaired: int = count("NMEA GGA without an RMC or VTG of its output cycle, or RMC without GGA (dropped)")
    no_vertical: int = count("NMEA epochs without a GGA height 1 s or less before them: no vertical velocity "
                             "(the first of a stream and the first after a gap)")


class ReceiverDecoder(Protocol):
    """A GNSS receiver decoder: bytes and their arrival time (host clock, s) in, completed fixes out; its fixes'
    ``time_s`` wraps at ``time_period_s`` (a day of UTC, a GPS week)."""

    time_period_s: float

    def feed(self, data: bytes, arrival_s: float) -> list[GnssFix]: ...

    def counters(self) -> dict[str, int]: ...

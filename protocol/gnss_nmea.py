"""NMEA 0183 receiver output (GGA with RMC or VTG) as GNSS fixes, parsed with pynmeagps (docs/gnss-receivers.md).

- GGA gives the position: latitude, longitude and the altitude above the geoid plus the geoid separation, which
  is the height above the WGS-84 ellipsoid (an empty separation is taken as 0: the receiver then reports the
  ellipsoidal height as its altitude). A quality other than 1–5 (a GNSS fix: autonomous, differential, PPS, RTK
  fixed or float) is no fix, 0 (none) and 6 (dead reckoning: the receiver's extrapolation, not a measurement) among
  them: the epoch is dropped, counted (``no_fix``).
- RMC (or, in a stream without RMC, VTG) gives the speed over ground (knots) and the course over ground (degrees
  from true north): v_E = s sin c, v_N = s cos c. RMC status V is no fix (``no_fix``), and so is an RMC or VTG
  whose mode indicator (NMEA 2.3 and later) says estimated (dead reckoning), not valid, manual or simulated.
- NMEA has no vertical velocity. v_U is the change of the ellipsoidal height from the previous GGA with a fix over
  the time between their UTC times, if that is 1 s or less: the mean vertical velocity over that interval, half an
  interval late. Without such a height the epoch is dropped (``no_vertical``). A constant v_U = 0 would be wrong by
  the climb rate (±9 m/s in a pitched flight) at the σ of the horizontal axes, since one σ serves all three.
- A GGA and the RMC of the same UTC time are one epoch. VTG carries no time: it belongs to the GGA of its output
  cycle (before or after it), and is used only while the stream has no RMC. A GGA left without a velocity when the
  next time begins, or an RMC without a GGA, is dropped (``unpaired``).

Sentences are found by their shape (``$`` + talker and sentence id, printable text, ``*`` + two hex digits, CR LF)
so the binary frames of an IMU on the same line are skipped without being counted; a sentence of that shape whose
checksum fails is counted (``checksum_errors``), one whose fields do not parse too (``malformed``).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

from pynmeagps import VALCKSUM, NMEAReader
from pynmeagps.nmeahelpers import calc_checksum

from .gnss_fix import GnssFix, ReceiverCounters

GNSS_QUALITIES = frozenset((1, 2, 3, 4, 5))
"""GGA fix qualities of a GNSS fix: autonomous, differential, PPS, RTK fixed, RTK float."""
NO_FIX_MODES = frozenset("ENMS")
"""RMC and VTG mode indicators without a GNSS fix: estimated (dead reckoning), not valid, manual, simulator."""
NO_FIX = (math.nan, math.nan)
"""The ground velocity of an RMC or VTG without a GNSS fix: its cycle is dropped (``no_fix``)."""

KNOT_MPS = 1852.0 / 3600.0
MAX_SENTENCE_BYTES = 128
"""A sentence is at most 82 characters by the standard; high-precision output (7 decimals of minutes) and some
receivers exceed it."""
MAX_VERTICAL_BASE_S = 1.0
"""The longest interval between two GGA heights that still gives a vertical velocity (a gap is not one)."""
DAY_S = 86400.0
_RUN = re.compile(rb"[\x20-\x23\x25-\x7e]*")   # printable but '$': a '$' starts the next sentence
_SENTENCE = re.compile(rb"\$[A-Z]{5},[\x20-\x23\x25-\x7e]*\*[0-9A-F]{2}")
_USED = frozenset({"GGA", "RMC", "VTG"})


@dataclass(slots=True)
class _Cycle:
    """The epoch of one UTC time of day (s) being gathered: GGA's (lat_deg, lon_deg, h_m, v_U), RMC's or VTG's
    (v_E, v_N), and whether it is settled (given out, or dropped and counted)."""

    t_s: float
    position: tuple[float, float, float, float] | None = None
    velocity: tuple[float, float] | None = None
    settled: bool = False


def _seconds_of_day(message) -> float:
    t = message.time
    return t.hour * 3600.0 + t.minute * 60.0 + t.second + t.microsecond * 1e-6


def _ground_velocity(speed_kn: float | str, course_deg: float | str) -> tuple[float, float]:
    """(v_E, v_N) m/s of a speed over ground (kn) and a course over ground (° from true north); an empty course
    at zero speed is standing still."""
    if course_deg == "" and speed_kn == 0.0:
        return 0.0, 0.0
    speed, course = float(speed_kn) * KNOT_MPS, math.radians(float(course_deg))
    return speed * math.sin(course), speed * math.cos(course)


class NmeaDecoder:
    """GGA + RMC/VTG sentences in any pieces → :class:`~.gnss_fix.GnssFix` epochs (module docstring), timed by
    their UTC time of day."""

    time_period_s = DAY_S

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._counters = ReceiverCounters()
        self._cycle: _Cycle | None = None
        self._floating_vtg: tuple[float, float] | None = None   # a VTG before its cycle's GGA
        self._rmc_seen = False
        self._last_height: tuple[float, float] | None = None    # (UTC s of day, h_m) of the latest GGA with a fix

    def counters(self) -> dict[str, int]:
        return self._counters.as_dict()

    def feed(self, data: bytes, arrival_s: float) -> list[GnssFix]:
        """The epochs the sentences completed by ``data`` give, stamped ``arrival_s`` (host clock, s)."""
        self._buffer += data
        fixes = []
        for sentence in self._sentences():
            fix = self._take(sentence, arrival_s)
            if fix is not None:
                fixes.append(fix)
        return fixes

    def _sentences(self):
        """The complete candidates in the buffer (``$`` … ``*HH``, without CR LF); the rest waits for more bytes."""
        buf = self._buffer
        while True:
            start = buf.find(b"$")
            if start < 0:
                buf.clear()
                return
            del buf[:start]
            end = _RUN.match(buf, 1).end()
            if end > MAX_SENTENCE_BYTES:
                del buf[:1]
                continue
            if end == len(buf) or (buf[end:end + 1] == b"\r" and end + 1 == len(buf)):
                return   # incomplete: wait
            newline = 1 if buf[end:end + 1] == b"\n" else 2 if buf[end:end + 2] == b"\r\n" else 0
            line = bytes(buf[:end])
            del buf[:end + newline if newline else 1]
            if newline and _SENTENCE.fullmatch(line) and line[3:6].decode() in _USED:
                yield line

    def _take(self, line: bytes, arrival_s: float) -> GnssFix | None:
        if calc_checksum(line[1:-3].decode()) != line[-2:].decode():
            self._counters.checksum_errors += 1
            return None
        try:
            message = NMEAReader.parse(line + b"\r\n", validate=VALCKSUM)
            kind = message.msgID
            return {"GGA": self._gga, "RMC": self._rmc, "VTG": self._vtg}[kind](message, arrival_s)
        except Exception:   # pynmeagps raises several types for fields that do not parse; so does float("")
            self._counters.malformed += 1
            return None

    def _cycle_at(self, t_s: float) -> _Cycle:
        """The cycle of UTC time ``t_s``; a cycle of another time left unsettled is dropped, counted."""
        cycle = self._cycle
        if cycle is None or cycle.t_s != t_s:
            if cycle is not None and not cycle.settled:
                self._counters.unpaired += 1
            cycle = self._cycle = _Cycle(t_s)
        return cycle

    def _gga(self, message, arrival_s: float) -> GnssFix | None:
        t_s = _seconds_of_day(message)
        cycle = self._cycle_at(t_s)
        if cycle.settled:
            return None
        if message.quality not in GNSS_QUALITIES:
            return self._drop(cycle, "no_fix")
        h_m = float(message.alt) + (float(message.sep) if message.sep != "" else 0.0)
        lat, lon = float(message.lat), float(message.lon)   # signed degrees (N, E positive)
        last, self._last_height = self._last_height, (t_s, h_m)
        dt_s = None if last is None else (t_s - last[0]) % DAY_S
        if dt_s is None or not 0.0 < dt_s <= MAX_VERTICAL_BASE_S:
            return self._drop(cycle, "no_vertical")
        cycle.position = (lat, lon, h_m, (h_m - last[1]) / dt_s)
        floating, self._floating_vtg = self._floating_vtg, None
        if cycle.velocity is None and not self._rmc_seen and floating is not None:
            return self._velocity(cycle, floating, arrival_s)
        return self._complete(cycle, arrival_s)

    def _rmc(self, message, arrival_s: float) -> GnssFix | None:
        self._rmc_seen = True
        cycle = self._cycle_at(_seconds_of_day(message))
        if cycle.settled:
            return None
        fixed = message.status == "A" and getattr(message, "posMode", "") not in NO_FIX_MODES
        return self._velocity(cycle, _ground_velocity(message.spd, message.cog) if fixed else NO_FIX, arrival_s)

    def _vtg(self, message, arrival_s: float) -> GnssFix | None:
        if self._rmc_seen:
            return None
        velocity = NO_FIX if getattr(message, "posMode", "") in NO_FIX_MODES else _ground_velocity(message.sogn,
                                                                                                  message.cogt)
        cycle = self._cycle
        if cycle is None or cycle.settled or cycle.velocity is not None:
            self._floating_vtg = velocity   # its cycle's GGA comes next
            return None
        return self._velocity(cycle, velocity, arrival_s)

    def _velocity(self, cycle: _Cycle, velocity: tuple[float, float], arrival_s: float) -> GnssFix | None:
        """The cycle with its ground velocity (E, N; m/s), or dropped for :data:`NO_FIX`."""
        if velocity is NO_FIX:
            return self._drop(cycle, "no_fix")
        cycle.velocity = velocity
        return self._complete(cycle, arrival_s)

    def _drop(self, cycle: _Cycle, counter: str) -> None:
        cycle.settled = True
        setattr(self._counters, counter, getattr(self._counters, counter) + 1)

    @staticmethod
    def _complete(cycle: _Cycle, arrival_s: float) -> GnssFix | None:
        if cycle.position is None or cycle.velocity is None:
            return None
        cycle.settled = True
        lat, lon, h_m, v_up = cycle.position
        return GnssFix(arrival_s, cycle.t_s, lat, lon, h_m, (*cycle.velocity, v_up))

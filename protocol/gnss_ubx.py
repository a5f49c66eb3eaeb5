"""u-blox UBX NAV-PVT (class 0x01, id 0x07, 92-byte payload) as GNSS fixes, parsed with pyubx2
(docs/gnss-receivers.md).

A NAV-PVT gives the antenna's latitude and longitude (1e-7°), its height above the ellipsoid (mm), its velocity
north, east and down (mm/s; turned here into East, North, Up) and its accuracy estimates hAcc, vAcc (mm) and sAcc
(mm/s). An epoch counts as a fix with fixType 3 (3-D) or 4 (GNSS and dead reckoning combined, an automotive
receiver's usual output once its sensors are calibrated) and the gnssFixOK flag (a GNSS fix within the receiver's
accuracy masks is in the solution); any other, dead reckoning alone among them, is dropped, counted (``no_fix``).

Messages are found by their header (0xB5 0x62, class, id and the NAV-PVT length): everything else, the IMU's frames
on a shared line or the receiver's other UBX messages, is skipped without being counted; a NAV-PVT whose Fletcher
checksum fails is counted (``checksum_errors``).
"""
from __future__ import annotations

from pyubx2 import VALCKSUM, UBXReader

from .gnss_fix import GnssFix, ReceiverCounters

NAV_PVT_HEADER = b"\xb5\x62\x01\x07\x5c\x00"
"""Sync chars, class NAV, id PVT and the payload length (92, little-endian)."""
NAV_PVT_BYTES = len(NAV_PVT_HEADER) + 92 + 2
FIX_TYPES = (3, 4)
"""fixType 3-D, and GNSS + dead reckoning combined."""
WEEK_S = 7 * 86400.0


class UbxDecoder:
    """NAV-PVT messages in any pieces → :class:`~.gnss_fix.GnssFix` epochs with the receiver's accuracies, timed by
    their GPS time of week (iTOW)."""

    time_period_s = WEEK_S

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._counters = ReceiverCounters()

    def counters(self) -> dict[str, int]:
        """The counters that apply to NAV-PVT: checksum failures and epochs without a fix."""
        return {k: v for k, v in self._counters.as_dict().items() if k in ("checksum_errors", "no_fix")}

    def feed(self, data: bytes, arrival_s: float) -> list[GnssFix]:
        """The epochs of the NAV-PVT messages ``data`` completes, stamped ``arrival_s`` (host clock, s)."""
        buf = self._buffer
        buf += data
        fixes = []
        while True:
            start = buf.find(NAV_PVT_HEADER)
            if start < 0:   # keep what could be the start of a header
                del buf[:max(len(buf) - len(NAV_PVT_HEADER) + 1, 0)]
                return fixes
            if len(buf) - start < NAV_PVT_BYTES:
                del buf[:start]
                return fixes
            raw = bytes(buf[start:start + NAV_PVT_BYTES])
            try:
                message = UBXReader.parse(raw, validate=VALCKSUM)
            except Exception:   # pyubx2 raises UBXParseError for the checksum (the header and length are checked)
                self._counters.checksum_errors += 1
                del buf[:start + 1]   # a header inside other bytes: resynchronise after it
                continue
            del buf[:start + NAV_PVT_BYTES]
            fix = self._fix(message, arrival_s)
            if fix is not None:
                fixes.append(fix)

    def _fix(self, m, arrival_s: float) -> GnssFix | None:
        if m.fixType not in FIX_TYPES or not m.gnssFixOk:
            self._counters.no_fix += 1
            return None
        return GnssFix(arrival_s, m.iTOW * 1e-3, float(m.lat), float(m.lon), m.height * 1e-3,
                       (m.velE * 1e-3, m.velN * 1e-3, -m.velD * 1e-3), m.hAcc * 1e-3, m.vAcc * 1e-3, m.sAcc * 1e-3)

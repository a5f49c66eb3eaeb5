"""NMEA 0183 heading sentences from attitude records, without I/O (docs/outputs.md lists every field).

- ``$--THS,h.hh,M``: true heading (°, clockwise from true North), mode A while the record is converged, V otherwise.
- ``$--HDT,h.hh,T``: true heading for older receivers; it has no status, so its heading is empty until converged.
- ``$--ROT,r.r,A``: rate of turn (°/min, negative turning to port, so positive as the heading grows) from the
  heading's change between the last two records; A while both are converged, V otherwise.
- ``$PASHR,hhmmss.ss,h.hh,T,±r.rr,±p.pp,,r.rrr,p.ppp,h.hhh,q,s`` (the field order of Trimble's and NovAtel's
  definitions): UTC time, true heading, roll (positive starboard side down), pitch (positive bow up), heave (empty:
  not measured), roll, pitch and heading 1-σ (°), GNSS quality (0: no fix is used for the attitude), alignment
  status (1 coarse, 2 degraded: fine alignment not yet converged, or disturbed, 3 aligned: converged).

The record's roll (right wing down +) and pitch (nose up +) about body front and right (service/align/conventions.py)
are PASHR's roll and pitch as they are. The time is the record's ``t`` read as seconds since the Unix epoch (the host
clock that counter-stamped IMUs are anchored on), so its time of day is UTC. A number that is not finite, or beyond
its field's width, leaves the field empty: a receiver sees no value rather than a wrong one.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from .results import ResultRecord

SENTENCES = ("THS", "HDT", "ROT", "PASHR")
BITS_PER_CHAR = 10
"""Start bit, 8 data bits, stop bit."""
LINE_SHARE = 0.9
"""The share of a serial line's characters per second the sentences may take (the rest is slack for jitter)."""
ROT_LIMIT_DEG_MIN = 9999.9
"""The largest rate of turn written (°/min, 167 °/s): the field's width; a larger one is a jump, not a turn."""
SIGMA_LIMIT_DEG = 999.999
ALIGNMENT_STATUS = {"coarse": 1, "fine": 2, "disturbed": 2, "aligned": 2}
"""PASHR's alignment status of a record that is not converged, by phase; a converged record is 3."""
GNSS_QUALITY = 0
"""PASHR's GNSS quality: 0, fix not available. The sentence carries attitude only, and the attitude is valid by its
alignment status, whatever aiding (if any) it took."""
TIME_TOLERANCE_S = 1e-6
"""Records on the output grid (a multiple of ``output.period_s``) count as due at their nominal time."""


def checksum(body: str) -> str:
    """The XOR of the characters between ``$`` and ``*``, as two upper-case hex digits."""
    value = 0
    for char in body.encode("ascii"):
        value ^= char
    return f"{value:02X}"


def sentence(body: str) -> bytes:
    """``$body*cs`` and CRLF."""
    return f"${body}*{checksum(body)}\r\n".encode("ascii")


def _number(value: float, decimals: int, limit: float, sign: str = "") -> str:
    """``value`` with ``decimals`` decimals, or empty if it is not finite or its magnitude exceeds ``limit``."""
    if not math.isfinite(value) or abs(value) > limit:
        return ""
    return f"{value:{sign}.{decimals}f}"


def _sigma(value_deg: float) -> str:
    return "" if not value_deg >= 0.0 else _number(value_deg, 3, SIGMA_LIMIT_DEG)


def heading_text(heading_deg: float) -> str:
    """A heading (°) in [0, 360) with two decimals: 359.999 is 0.00, never 360.00; empty if not finite."""
    if not math.isfinite(heading_deg):
        return ""
    text = f"{heading_deg % 360.0:.2f}"
    return "0.00" if text == "360.00" else text


def utc_text(t_s: float) -> str:
    """hhmmss.ss of the time of day of ``t_s`` (s since the Unix epoch, UTC); empty if not finite."""
    if not math.isfinite(t_s):
        return ""
    centis = round(t_s * 100.0) % 8_640_000
    seconds, centi = divmod(centis, 100)
    return f"{seconds // 3600:02d}{seconds // 60 % 60:02d}{seconds % 60:02d}.{centi:02d}"


def ths(talker: str, record: ResultRecord) -> bytes:
    heading = heading_text(record.heading_deg)
    return sentence(f"{talker}THS,{heading},{'A' if record.converged and heading else 'V'}")


def hdt(talker: str, record: ResultRecord) -> bytes:
    return sentence(f"{talker}HDT,{heading_text(record.heading_deg) if record.converged else ''},T")


def rot(talker: str, rate_deg_min: float | None, valid: bool) -> bytes:
    """A rate of turn (°/min, negative to port); None: not known (no earlier record)."""
    text = "" if rate_deg_min is None else _number(rate_deg_min, 1, ROT_LIMIT_DEG_MIN)
    return sentence(f"{talker}ROT,{text},{'A' if valid and text else 'V'}")


def alignment_status(record: ResultRecord) -> int:
    return 3 if record.converged else ALIGNMENT_STATUS.get(record.phase, 2)


def pashr(record: ResultRecord) -> bytes:
    """The proprietary attitude sentence (no talker id); roll and pitch σ are both the level σ."""
    level = _sigma(record.level_sigma_deg)
    fields = (utc_text(record.t), heading_text(record.heading_deg), "T", _number(record.roll_deg, 2, 180.0, "+"),
              _number(record.pitch_deg, 2, 90.0, "+"), "", level, level, _sigma(record.heading_sigma_deg),
              str(GNSS_QUALITY), str(alignment_status(record)))
    return sentence("PASHR," + ",".join(fields))


def heading_rate_deg_min(earlier: ResultRecord, later: ResultRecord) -> float | None:
    """The heading's change from ``earlier`` to ``later`` (the short way round) per minute of data time."""
    dt_s = later.t - earlier.t
    if not dt_s > 0.0:
        return None
    change = (later.heading_deg - earlier.heading_deg + 180.0) % 360.0 - 180.0
    return change / dt_s * 60.0


_RECORD_SENTENCES: dict[str, Callable[[str, ResultRecord], bytes]] = {
    "THS": ths, "HDT": hdt, "PASHR": lambda talker, record: pashr(record)}
_LONGEST = ResultRecord(t=86399.99, phase="disturbed", q=(1.0, 0.0, 0.0, 0.0), pitch_deg=-89.99, roll_deg=-179.99,
                        heading_deg=359.99, heading_sigma_deg=SIGMA_LIMIT_DEG, level_sigma_deg=SIGMA_LIMIT_DEG,
                        converged=True, rho=0.0, trace_P=0.0, n_obs=0)
"""A record whose every field is as wide as its sentences write it."""


def max_length(name: str, talker: str) -> int:
    """The most characters (CRLF included) a ``name`` sentence takes."""
    if name == "ROT":
        return len(rot(talker, -ROT_LIMIT_DEG_MIN, True))
    return len(_RECORD_SENTENCES[name](talker, _LONGEST))


def line_bits_per_s(names: Sequence[str], talker: str, rate_hz: float) -> float:
    """The bits per second the sentences ``names`` at ``rate_hz`` each take at most on a serial line."""
    return sum(max_length(name, talker) for name in names) * BITS_PER_CHAR * rate_hz


class NmeaSentences:
    """The sentences due for each record, in the order of ``names``, at most ``rate_hz`` times a second of data
    time (and never more often than the records come)."""

    def __init__(self, names: Sequence[str], talker: str, rate_hz: float) -> None:
        self.names = tuple(names)
        self.talker = talker
        self.period_s = 1.0 / rate_hz
        self._next_t: float | None = None
        self._last: ResultRecord | None = None

    def feed(self, record: ResultRecord) -> list[bytes]:
        """The sentences for ``record``: none if it comes before the next is due."""
        earlier, self._last = self._last, record   # the rate of turn takes the closest pair, sent or not
        if self._next_t is not None and record.t < self._next_t - TIME_TOLERANCE_S:
            return []
        # stay on the grid of the first record unless the records fell a whole period behind it
        on_grid = self._next_t is not None and record.t - self._next_t < self.period_s
        self._next_t = (self._next_t if on_grid else record.t) + self.period_s
        return [self._sentence(name, earlier, record) for name in self.names]

    def _sentence(self, name: str, earlier: ResultRecord | None, record: ResultRecord) -> bytes:
        if name != "ROT":
            return _RECORD_SENTENCES[name](self.talker, record)
        rate = heading_rate_deg_min(earlier, record) if earlier is not None else None
        return rot(self.talker, rate, earlier is not None and earlier.converged and record.converged)

"""Time stamps from a sensor's sample counter, for IMUs whose frames carry no absolute time.

A STIM300 counts 2000 ticks per second in a u8, a KVH 1750/1775 one per sample in its sequence byte, an Xsens
10 000 per second in SampleTimeFine. :class:`CounterClock` unwraps the counter and stamps sample k as
``anchor + ticks(k) · tick_s``: the anchor is the host's arrival time of the first sample, taken once, so the
host's read jitter (whole bursts of frames arrive in one read) never enters the intervals. The counter's wraps
are told apart from lost frames by the arrival times, against the least lag seen lately (it follows the drift
between the sensor's and the host's clocks): a counter that wraps every 128 ms needs reads to come within some
tens of ms, which any serial reader does.

What the counter says is counted like a sequence counter (``seq_*``, protocol/sequence.py): frames missing
between two accepted ones, the same counter again (dropped), one from the past (dropped); three from the past in
a row are a sensor that restarted: the clock is anchored again at the arrival time, and the sample gate sees the
jump (a gap: a restart of the alignment).
"""
from __future__ import annotations

from dataclasses import dataclass

from .sequence import RESET_RUN

LAG_FOLLOW = 0.01
"""How fast (per sample) the least-lag estimate follows a lag that grows (the sensor's clock runs slow)."""


@dataclass(slots=True)
class CounterClock:
    """Stamps samples from a counter that wraps at ``modulus`` and steps ``step`` ticks of ``tick_s`` seconds per
    sample; times are on the host clock of the first arrival (s)."""

    modulus: int
    tick_s: float
    step: int = 1
    gaps: int = 0
    repeats: int = 0
    backwards: int = 0
    resets: int = 0
    _anchor_s: float | None = None
    _last_counter: int = 0
    _t_last: float = 0.0
    _lag_s: float = 0.0
    _ticks: int = 0
    _backwards_run: int = 0

    def stamp(self, counter: int, arrival_s: float) -> float | None:
        """The time (s) of the sample with ``counter`` that arrived at host time ``arrival_s``; None: dropped (a
        repeat or a counter from the past)."""
        if self._anchor_s is None:
            return self._anchor(counter, arrival_s)
        delta = (counter - self._last_counter) % self.modulus
        # the arrival times say how many whole wraps lie between (a lost burst longer than one wrap, or none)
        elapsed = (arrival_s - self._lag_s - self._t_last) / self.tick_s
        wraps = round((elapsed - delta) / self.modulus)
        ticks = delta + max(wraps, -1) * self.modulus
        if ticks == 0:
            self.repeats += 1
            return None
        if ticks < 0:
            self._backwards_run += 1
            if self._backwards_run < RESET_RUN:
                self.backwards += 1
                return None
            self.resets += 1
            return self._anchor(counter, arrival_s)
        self._backwards_run = 0
        self.gaps += max(round(ticks / self.step) - 1, 0)
        self._ticks += ticks
        self._last_counter = counter
        self._t_last = self._anchor_s + self._ticks * self.tick_s
        lag = arrival_s - self._t_last
        # the least lag, followed slowly upwards: a burst's first frame arrives with the read's whole delay
        self._lag_s = lag if lag < self._lag_s else self._lag_s + LAG_FOLLOW * (lag - self._lag_s)
        return self._t_last

    def _anchor(self, counter: int, arrival_s: float) -> float:
        self._anchor_s, self._ticks, self._backwards_run = arrival_s, 0, 0
        self._last_counter, self._t_last, self._lag_s = counter, arrival_s, 0.0
        return arrival_s

    def counters(self, prefix: str = "seq_") -> dict[str, int]:
        return {f"{prefix}gaps": self.gaps, f"{prefix}repeats": self.repeats, f"{prefix}backwards": self.backwards,
                f"{prefix}resets": self.resets}

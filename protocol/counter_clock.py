"""Time stamps from a sensor's sample counter, for IMUs whose frames carry no absolute time.

A STIM300 counts 2000 ticks per second in a u8, a KVH 1750/1775 one per sample in its sequence byte, an Xsens
10 000 per second in SampleTimeFine. :class:`CounterClock` unwraps the counter and stamps sample k as
``anchor + ticks(k) · tick_s``: the anchor is the host's arrival time of the first read's newest sample, taken
once, so the host's read jitter (whole bursts of frames arrive in one read) never enters the intervals.

Within one read the counter's steps are taken as they are (modulo its wrap). Between reads the arrival times say
whether whole wraps were lost: the newest samples of two reads are produced about as far apart as the reads
arrive, so the first sample of a read of n was produced some (n − 1) samples after the interval between the
reads began. A reader that paused gets a long read of frames that were queued, not lost; a line that went silent
gives a short read long after the last. A counter that wraps every 128 ms needs the reads to keep within some
tens of ms of the line, which any serial reader does in real time; a bench playing much faster than real time
does not (its pace follows its reader's): there ``counter_only`` takes the counter's steps alone, which tells
losses up to half a wrap.

What the counter says is counted like a sequence counter (``seq_*``, protocol/sequence.py): frames missing
between two accepted ones (``seq_gaps``), and the same counter again (``seq_repeats``, dropped). A sensor that
restarts its counter shows as a gap: the sample gate bridges it or restarts the alignment.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(slots=True)
class CounterClock:
    """Stamps samples from a counter that wraps at ``modulus`` and steps ``step`` ticks of ``tick_s`` seconds per
    sample; times are on the host clock of the first arrival (s). ``counter_only``: wraps lost between reads are
    not looked for."""

    modulus: int
    tick_s: float
    step: int = 1
    counter_only: bool = False
    gaps: int = 0
    repeats: int = 0
    _anchor_s: float | None = None
    _last_counter: int = 0
    _ticks: int = 0
    _last_arrival_s: float = 0.0

    def stamp(self, counters: np.ndarray, arrival_s: float) -> np.ndarray:
        """The times (s) of the samples of one read, ``counters`` (N,) in arrival order, that arrived at host time
        ``arrival_s``; NaN where dropped (the counter of the sample before again)."""
        counters = np.asarray(counters, dtype=np.int64)
        n = len(counters)
        if n == 0:
            return np.empty(0)
        previous = np.concatenate(([self._last_counter if self._anchor_s is not None else counters[0]],
                                   counters[:-1]))
        ticks = (counters - previous) % self.modulus
        if self._anchor_s is None:
            # the newest sample of the first read arrives as it is produced: the anchor puts it there
            self._anchor_s = arrival_s - float(ticks[1:].sum()) * self.tick_s
            first_dropped = False
        else:
            if not self.counter_only:
                # ticks from the last read's newest sample to this one's first: the reads' interval less n - 1
                produced = (arrival_s - self._last_arrival_s) / self.tick_s - (n - 1) * self.step
                ticks[0] += max(round((produced - ticks[0]) / self.modulus), 0) * self.modulus
            first_dropped = ticks[0] == 0
        dropped = ticks == 0
        dropped[0] = first_dropped
        self.repeats += int(dropped.sum())
        kept = ticks[~dropped]
        self.gaps += int(np.maximum(np.rint(kept / self.step) - 1, 0).sum())
        total = self._ticks + np.cumsum(ticks)
        self._ticks = int(total[-1])
        self._last_counter, self._last_arrival_s = int(counters[-1]), arrival_s
        t = self._anchor_s + total * self.tick_s
        t[dropped] = np.nan
        return t

    def counters(self, prefix: str = "seq_") -> dict[str, int]:
        return {f"{prefix}gaps": self.gaps, f"{prefix}repeats": self.repeats}

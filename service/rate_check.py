"""Whether the samples' time stamps step at the rate the alignment takes for theirs (``imu.rate_hz``, a log's
``rate_hz``), for the whole run.

The sample gate judges every window of :data:`RATE_CHECK_STEPS` steps of a time base: their median must lie within
:data:`RATE_TOLERANCE` of the stated period. At twice the data's rate every sample seems to follow a lost one and is
bridged (a swing log replayed 165° off); at half, the estimators' intervals hold half the time; an IMU whose rate
changes on a live line (200 → 400 Hz) was reported converged 2.3° off under σ 0.1° before anything restarted. The
median passes a clock a few per cent off its nominal rate, jittered stamps and a line that loses frames now and
then; a rate 25 % off (a STIM300 at 200 Hz configured as 250 Hz) does not.

A vendor IMU stamped from its counter (protocol/counter_clock.py) steps at whatever its ticks are stamped at: a KVH
counts one tick a sample, stamped 1/``imu.rate_hz`` apart, so its windows pass at any rate (a KVH at 200 Hz
configured as 250 Hz, or doubling its rate at 60 s, aligned at the wrong time scale: `coarse` for ever, health
`ok`). On a real-time line the host's arrival clock tells (:class:`HostPace`): its verdict fails the check too.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..protocol.imu_log import MAX_TIME_S

RATE_CHECK_STEPS = 100
"""Steps in one judgement: 0.5 s at 200 Hz, 20 ms at 5 kHz."""
RATE_TOLERANCE = (0.95, 1.05)
"""The median step over the stated period that passes: an IMU's oscillator within 5 % of its nominal rate."""
PACE_SPAN_S = 0.5
"""Host seconds of reads in one bucket of :class:`HostPace`: some 25 reads of a loop that waits up to 20 ms for
data, the least lag among them within a few ms of the line's own; two buckets apart that is ~1 % of pace, well
within :data:`RATE_TOLERANCE`. A pace beyond it counts once the next bucket's agrees (the first at 1.5 s): a reader
that fell 30 ms behind for a whole bucket, or caught up after one, moves one bucket's least lag, not two."""
AHEAD_LIMIT_S = 0.05
"""A read whose lead is this far (s) above the last closed bucket's least lag cannot be a late read (lag only takes
lead away): the counter runs ahead of the host's clock, and the pace beyond this lead is judged at once. An IMU that
doubled its rate was otherwise aligned at half its time scale until the next bucket closed, up to 1.5 s:
`converged` 3σ off; at twice the rate the counter is 50 ms ahead 50 ms after the change, and its pace beyond that
leaves the tolerance within another 0.1 s."""


@dataclass(slots=True)
class HostPace:
    """How fast counter time stamps run on the host's clock: the counter's seconds per host second, which is the
    IMU's true rate over the rate its ticks are stamped at (1.0 on a sound line).

    A read's lead is its newest sample's time ``t`` (the counter's time, anchored once on the host clock: s) less
    the read's arrival ``arrival_s`` (host monotonic clock, s): minus that sample's lag through the line, the driver
    and the reader's loop. Lag only adds (frames batched in one read, a loop that was busy), so the largest lead in
    a bucket of reads is its least lag, the same from bucket to bucket on a sound line; counter time that runs at
    ``ratio`` of host time moves it by (ratio − 1) s per host second. A bucket holds the reads of
    :data:`PACE_SPAN_S` from its first; the read that comes later (after a silence too) opens the next, and the
    pace is taken over the real distance between the two buckets' first reads."""

    span_s: float = PACE_SPAN_S
    _start_s: float | None = None   # the open bucket's first arrival (host s); None: no read yet
    _lead_s: float = 0.0            # the open bucket's largest lead (s)
    _lead_at_s: float = 0.0         # the arrival of that read (host s)
    _sound: bool = True             # the last verdict was within the tolerance: a read ahead may tell at once
    _beyond: int = 0                # the last bucket's pace beyond the tolerance: +1 above, −1 below, 0 within
    _closed: tuple[float, float, float] | None = None   # the last closed bucket's first arrival, largest lead, its
    # arrival (s)

    def observe(self, t: float, arrival_s: float) -> float | None:
        """A read whose newest sample has time ``t`` (s, the counter's) arrived at ``arrival_s`` (s, host) → the
        counter's seconds per host second from the last closed bucket to the one this read closes, or to this read
        if it is :data:`AHEAD_LIMIT_S` ahead of that bucket's least lag while the last verdict was sound (a rough
        figure at once, which the buckets' then refine); None while it does neither, or the first."""
        lead = t - arrival_s
        if self._start_s is not None and arrival_s - self._start_s < self.span_s:
            if lead > self._lead_s:
                self._lead_s, self._lead_at_s = lead, arrival_s
            if self._closed is not None and lead - self._closed[1] > AHEAD_LIMIT_S and self._sound:
                # ahead of any lag: the pace since that least lag, now, less the limit (a reader that fell behind
                # for a whole bucket and caught up is that far ahead once, and no faster)
                _, lead_s, lead_at_s = self._closed
                return self._verdict(1.0 + (lead - lead_s - AHEAD_LIMIT_S) / (arrival_s - lead_at_s))
            return None
        pace = None
        if self._start_s is not None:
            if self._closed is not None:
                start_s, lead_s, _ = self._closed
                pace = self._confirmed(1.0 + (self._lead_s - lead_s) / (self._start_s - start_s))
            self._closed = (self._start_s, self._lead_s, self._lead_at_s)
        self._start_s, self._lead_s, self._lead_at_s = arrival_s, lead, arrival_s
        return pace

    def _confirmed(self, pace: float) -> float | None:
        """A bucket's pace, if within the tolerance or beyond it on the same side as the bucket's before; None for
        the first beyond it."""
        beyond = 0 if RATE_TOLERANCE[0] <= pace <= RATE_TOLERANCE[1] else (1 if pace > 1.0 else -1)
        confirmed = beyond == 0 or beyond == self._beyond
        self._beyond = beyond
        return self._verdict(pace) if confirmed else None

    def _verdict(self, pace: float) -> float:
        self._sound = RATE_TOLERANCE[0] <= pace <= RATE_TOLERANCE[1]
        return pace


@dataclass(slots=True)
class RateCheck:
    """Windows of :data:`RATE_CHECK_STEPS` + 1 sample times, judged one after the other for the whole run: ``settled``
    once one steps at ``rate_hz`` and until one does not; ``failure`` says how the last judged window did not (None:
    none did not, or one since did). A verdict of the host's clock (:meth:`host_pace`) that the samples come at
    another rate fails the check too, and no window settles it while it stands."""

    rate_hz: float
    stated_as: str = "imu.rate_hz"
    settled: bool = False
    failure: str | None = None
    _times: np.ndarray = field(default_factory=lambda: np.empty(RATE_CHECK_STEPS + 1))
    _count: int = 0
    _host_failure: str | None = None   # the host clock's verdict, while it stands: the rate the samples come at
    _host_ratio: float = 1.0           # the pace that verdict names (counter s per host s)

    def take(self, t: np.ndarray) -> int:
        """How many of the next sample times ``t`` (s) are taken up to the end of the first window whose verdict
        changes the state (settled, refusing or neither yet; all of them if none does): windows are filled, judged
        once full, and the next one opens."""
        taken = 0
        while taken < len(t):
            was = self._state()
            width = len(self._times)
            n = min(len(t) - taken, width - self._count)
            self._times[self._count:self._count + n] = t[taken:taken + n]
            self._count += n
            taken += n
            if self._count < width:
                break
            self._count = 0
            self._judge(self._times)
            if self._state() != was:
                break
            if self.settled and len(t) - taken >= width:
                taken += self._whole_windows(t[taken:])
        return taken

    def _state(self) -> tuple[bool, bool]:
        return self.settled, self.failure is None

    def restart(self) -> None:
        """A new time base: judged afresh."""
        self.settled, self.failure, self._count, self._host_failure = False, None, 0, None

    def host_pace(self, ratio: float) -> None:
        """The host clock's verdict on counter time stamps: ``ratio``, their seconds per host second
        (:class:`HostPace`). Beyond :data:`RATE_TOLERANCE` the samples come at ``ratio`` · ``rate_hz``, which no
        window shows (each counter tick stamped at 1/``rate_hz``): the check fails until a verdict is back within it
        and a window then passes."""
        if RATE_TOLERANCE[0] <= ratio <= RATE_TOLERANCE[1]:
            self._host_failure = None
        elif self._host_failure is None or abs(ratio / self._host_ratio - 1.0) > RATE_TOLERANCE[1] - 1.0:
            # named again only once the pace moved beyond the tolerance (the first verdict may span a change of
            # rate): one event a rate, not one a bucket
            self._host_ratio = ratio
            self._host_failure = (f"samples come at {ratio * self.rate_hz:.4g} Hz by the host's clock (the IMU's "
                                  f"counter stamps them at {self.stated_as} = {self.rate_hz:g})")
            self.settled, self.failure = False, self._host_failure

    def _whole_windows(self, t: np.ndarray) -> int:
        """Judge the whole windows at the start of ``t`` at once while they keep the rate (a settled stream: one
        median per window, not one call): how many times they take, up to the end of the first that does not."""
        width = len(self._times)
        m = len(t) // width
        windows = t[:m * width].reshape(m, width)
        if not (np.abs(windows) <= MAX_TIME_S).all():
            return 0   # a time no clock reads: the windows one by one (_judge leaves such times out)
        ratios = np.median(np.diff(windows, axis=1), axis=1) * self.rate_hz
        off = np.flatnonzero((ratios < RATE_TOLERANCE[0]) | (ratios > RATE_TOLERANCE[1]))
        kept = m if len(off) == 0 else int(off[0])
        return kept * width   # the first window that does not keep the rate is judged by take, on its own

    def _judge(self, times: np.ndarray) -> None:
        steps = np.diff(times[np.abs(times) <= MAX_TIME_S])   # a time no clock reads says nothing of the rate
        if len(steps) < RATE_CHECK_STEPS // 2:
            return
        step_s = float(np.median(steps))
        if RATE_TOLERANCE[0] <= step_s * self.rate_hz <= RATE_TOLERANCE[1]:
            self.settled, self.failure = self._host_failure is None, self._host_failure
        else:
            self.settled = False
            self.failure = (f"samples come every {step_s * 1e3:.4g} ms ({1.0 / step_s:.4g} Hz, the median of "
                            f"{len(steps)} steps), where {self.stated_as} = {self.rate_hz:g} says "
                            f"{1e3 / self.rate_hz:.4g} ms")

"""Whether the samples' time stamps step at the rate the alignment takes for theirs (``imu.rate_hz``, a log's
``rate_hz``), for the whole run.

The sample gate judges every window of :data:`RATE_CHECK_STEPS` steps of a time base: their median must lie within
:data:`RATE_TOLERANCE` of the stated period. At twice the data's rate every sample seems to follow a lost one and is
bridged (a swing log replayed 165° off); at half, the estimators' intervals hold half the time; an IMU whose rate
changes on a live line (200 → 400 Hz) was reported converged 2.3° off under σ 0.1° before anything restarted. The
median passes a clock a few per cent off its nominal rate, jittered stamps and a line that loses frames now and
then; a rate 25 % off (a STIM300 at 200 Hz configured as 250 Hz) does not.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..protocol.imu_log import MAX_TIME_S

RATE_CHECK_STEPS = 100
"""Steps in one judgement: 0.5 s at 200 Hz, 20 ms at 5 kHz."""
RATE_TOLERANCE = (0.95, 1.05)
"""The median step over the stated period that passes: an IMU's oscillator within 5 % of its nominal rate."""


@dataclass(slots=True)
class RateCheck:
    """Windows of :data:`RATE_CHECK_STEPS` + 1 sample times, judged one after the other for the whole run: ``settled``
    once one steps at ``rate_hz`` and until one does not; ``failure`` says how the last judged window did not (None:
    none did not, or one since did)."""

    rate_hz: float
    stated_as: str = "imu.rate_hz"
    settled: bool = False
    failure: str | None = None
    _times: np.ndarray = field(default_factory=lambda: np.empty(RATE_CHECK_STEPS + 1))
    _count: int = 0

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
        self.settled, self.failure, self._count = False, None, 0

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
            self.settled, self.failure = True, None
        else:
            self.settled = False
            self.failure = (f"samples come every {step_s * 1e3:.4g} ms ({1.0 / step_s:.4g} Hz, the median of "
                            f"{len(steps)} steps), where {self.stated_as} = {self.rate_hz:g} says "
                            f"{1e3 / self.rate_hz:.4g} ms")

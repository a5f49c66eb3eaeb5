"""Whether the samples' time stamps step at the rate the alignment takes for theirs (``imu.rate_hz``, a log's
``rate_hz``).

The sample gate judges the first :data:`RATE_CHECK_STEPS` steps of a time base: their median must lie within
:data:`RATE_TOLERANCE` of the stated period. At twice the data's rate every sample seems to follow a lost one and is
bridged (a swing log replayed 165° off); at half, the estimators' intervals hold half the time. The median passes a
clock a few per cent off its nominal rate and a line that loses frames now and then.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..protocol.imu_log import MAX_TIME_S

RATE_CHECK_STEPS = 100
"""Steps in one judgement: 0.5 s at 200 Hz, 20 ms at 5 kHz."""
RATE_TOLERANCE = (0.8, 1.25)
"""The median step over the stated period that passes."""


@dataclass(slots=True)
class RateCheck:
    """Windows of :data:`RATE_CHECK_STEPS` + 1 sample times, judged one by one until one steps at ``rate_hz``
    (``settled``); ``failure`` says how the last judged window did not (None: none did not, or one since did)."""

    rate_hz: float
    stated_as: str = "imu.rate_hz"
    settled: bool = False
    failure: str | None = None
    _times: np.ndarray = field(default_factory=lambda: np.empty(RATE_CHECK_STEPS + 1))
    _count: int = 0

    def take(self, t: np.ndarray) -> int:
        """How many of the next sample times ``t`` (s) the open window takes: all until it is full, when it is
        judged and the next one opens."""
        n = min(len(t), len(self._times) - self._count)
        self._times[self._count:self._count + n] = t[:n]
        self._count += n
        if self._count == len(self._times):
            self._count = 0
            self._judge(self._times)
        return n

    def restart(self) -> None:
        """A new time base: judged afresh."""
        self.settled, self.failure, self._count = False, None, 0

    def _judge(self, times: np.ndarray) -> None:
        steps = np.diff(times[np.abs(times) <= MAX_TIME_S])   # a time no clock reads says nothing of the rate
        if len(steps) < RATE_CHECK_STEPS // 2:
            return
        step_s = float(np.median(steps))
        if RATE_TOLERANCE[0] <= step_s * self.rate_hz <= RATE_TOLERANCE[1]:
            self.settled, self.failure = True, None
        else:
            self.failure = (f"samples come every {step_s * 1e3:.4g} ms (the median of {len(steps)} steps), where "
                            f"{self.stated_as} = {self.rate_hz:g} says {1e3 / self.rate_hz:.4g} ms")

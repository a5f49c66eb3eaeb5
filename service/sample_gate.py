"""Checks between the decoders and the pipeline: what may be aligned, what must be bridged or restarted.

The strapdown integration needs every increment: a lost sample removes a slice of rotation and
velocity from the integrals, and a clipped one puts a wrong one in. So, per decoded sample:

- a time stamp beyond any clock (|t| above 1e10 s), or an increment beyond what the sensor can measure (|Δθ| or
  |Δv| above ``max_dtheta_rad`` / ``max_dv_mps``, its stated range over twice the sample interval) → dropped like a
  bad frame (``implausible``), and bridged as a missing sample; a finite 1e308 would otherwise reach the
  estimators;
- time not after the previous sample → dropped (``time_not_increasing``); but once ``max_bridge_samples`` + 1
  samples in a row are behind the last one and run on among themselves, the IMU's clock has gone back (a sensor
  restarted, or the last sample's time was wild): the alignment restarts from them (``clock_resets``);
- a gap of up to ``max_bridge_samples`` missing samples (from the time stamps) → the missing
  increments are interpolated linearly between the samples on either side (``samples_bridged``);
  the error is second order in the gap length on a smooth motion;
- a longer gap, or a saturated (full-scale) value → the alignment restarts from the next good
  sample (``restarts``, with the reason in ``last_error``), in the call that brings it if not this
  one: nothing converged survives on data the estimator never saw;
- time stamps that do not step at the stated rate (rate_check.py: the median of each window of 100 steps, for the
  whole run), or a vendor's counter stamps that the host's arrival clock says run at another pace (a real-time
  line) → the alignment restarts at once and every sample is dropped (``rate_mismatch``, the two periods or rates
  in ``last_error``) until 100 steps in a row do, the host's clock agreeing.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..protocol.counters import Counters, count
from ..protocol.imu_log import G0_MS2, MAX_TIME_S, RANGE_INTERVALS
from ..protocol.serial_frame import IMU_ROW_COLUMNS
from ._gate import plain_rows, screen
from .align.conventions import DEG
from .config import Config
from .rate_check import RATE_CHECK_STEPS, RATE_TOLERANCE, RateCheck

SAMPLE_COLUMNS = IMU_ROW_COLUMNS
"""The one row a decoded IMU sample travels in from every decoder to the pipeline: t (s), Δθ (3) rad, Δv (3) m/s,
the status word, saturated (1.0: a value at full scale). A u32 status word is exact in a float64."""


def sample_rows(samples: Iterable[tuple[float, Sequence[float], Sequence[float], int, bool]]) -> np.ndarray:
    """Decoded samples (t, Δθ, Δv, status, saturated), one tuple each, as rows (N, :data:`SAMPLE_COLUMNS`)."""
    rows = [(t, *dtheta, *dv, status, saturated) for t, dtheta, dv, status, saturated in samples]
    return np.array(rows, dtype=float).reshape(-1, SAMPLE_COLUMNS)


@dataclass(slots=True)
class GateCounters(Counters):
    time_not_increasing: int = count("samples dropped: their time did not follow the sample before")
    samples_bridged: int = count("missing samples interpolated between their neighbours")
    gaps_bridged: int = count("gaps of up to daemon.max_bridge_samples so bridged")
    restarts: int = count("alignment restarts the gate asked for (a longer gap, a saturated sample, a clock reset)")
    saturated: int = count("samples at full scale (not used: a restart)")
    status_flagged: int = count("samples with a non-zero IMU status word (used)")
    implausible: int = count("samples dropped for a time no clock reads or an increment beyond the IMU's range")
    clock_resets: int = count("the IMU's clock went back (samples in a row behind the last one): a restart")
    rate_mismatch: int = count("samples dropped: their time stamps do not step at the stated rate (imu.rate_hz)")


@dataclass(slots=True)
class Segment:
    """Rows (N, 7) of t, Δθ, Δv to align; ``restart`` says the alignment starts over before them."""

    rows: np.ndarray
    restart: bool
    reason: str | None = None


@dataclass(slots=True)
class SampleGate:
    """Admits decoded samples in calls of any size: the same samples give the same segments and counters
    however they are split into calls (a cut at the end of one call restarts the segment the next one begins).
    ``rate_stated_as`` names where ``rate_hz`` comes from, for the text of a rate the samples do not keep."""

    rate_hz: float
    max_bridge_samples: int = 5
    max_dtheta_rad: float = np.inf
    max_dv_mps: float = np.inf
    rate_stated_as: str = "imu.rate_hz"
    counters: GateCounters = field(default_factory=GateCounters)
    last_error: str | None = None
    rate: RateCheck = field(init=False)
    _last: np.ndarray | None = None     # the last row admitted: t (s), Δθ (rad), Δv (m/s)
    _restart_reason: str | None = None   # a cut no segment has carried yet: why the next segment restarts
    _behind: list[np.ndarray] = field(default_factory=list)   # samples in a row behind _last, in time order
    _held: np.ndarray = field(default_factory=lambda: np.empty((0, 7)))   # held by _release, in arrival order
    _refusing: bool = False   # stopped on the rate check's failure: every sample dropped until it passes

    def __post_init__(self) -> None:
        self.rate = RateCheck(self.rate_hz, self.rate_stated_as)

    def admit(self, samples: np.ndarray) -> list[Segment]:
        """Decoded samples (N, :data:`SAMPLE_COLUMNS`), or a log's rows (N, 7), in arrival order → segments to align;
        a segment carries the restart of every cut since the previous segment, whichever call made it. A segment
        without rows only restarts the alignment: the samples do not step at the stated rate (``rate.failure``).

        The samples of each window of the rate check are admitted or dropped by the verdict of the window before
        (the first one's admitted): a window that does not step at the stated rate restarts the alignment and drops
        every sample until one does, at any time in the run. So does a verdict of the host's clock that came since
        the last call, until a window passes after one that no longer says so."""
        segments: list[Segment] = []
        self._follow_rate(segments)   # a verdict of the host's clock since the last call (RateCheck.host_pace)
        while len(samples):
            taken = self.rate.take(samples[:, 0])
            if self._refusing:
                self.counters.rate_mismatch += taken
            else:
                segments += self._admit(self._release(samples[:taken]))
            samples = samples[taken:]
            self._follow_rate(segments)
        return segments

    def _follow_rate(self, segments: list[Segment]) -> None:
        """Stop the alignment when the rate check fails (the held samples dropped), refuse samples while it does."""
        if self.rate.failure is None:
            self._refusing = False
            return
        self.last_error = (f"{self.rate.failure}: no sample is aligned until they do (set {self.rate_stated_as} to "
                           "the IMU's rate)")
        if not self._refusing:
            self._refusing = True
            self.counters.rate_mismatch += len(self._held)
            self._held = self._held[:0]
            self._stop(segments)

    def _release(self, samples: np.ndarray) -> np.ndarray:
        """The samples (held ones first) that may go to the rules now: all but a trailing run whose every step is
        not one sample period (within the rate check's tolerance), held until a step that is one (a frame or two
        lost: a sample period late) or the rate check's verdict (a rate that changed: dropped with the window that
        shows it). Admitted at once, a 100-Hz stream read as 200 Hz had every sample doubled by bridging and the
        heading 3.4° off under σ 0.05° within the second its window takes."""
        if len(self._held):
            samples = np.concatenate((self._held, samples))
        t = samples[:, 0]
        clock = np.abs(t) <= MAX_TIME_S   # a time no clock reads is dropped by the rules: it holds nothing
        before = np.nan if self._last is None else self._last[0]
        t_clock = t[clock]
        steps = np.diff(t_clock, prepend=before) * self.rate_hz
        odd = np.zeros(len(t), dtype=bool)
        odd[clock] = ~((RATE_TOLERANCE[0] <= steps) & (steps <= RATE_TOLERANCE[1])) & ~np.isnan(steps)
        sound = np.flatnonzero(~odd)
        end = sound[-1] + 1 if len(sound) else 0
        if len(samples) - end > 2 * RATE_CHECK_STEPS:
            end = len(samples)   # the rate check has passed such a run: odd steps of a sound rate
        self._held = samples[end:].copy()
        return samples[:end]

    def _admit(self, samples: np.ndarray) -> list[Segment]:
        """:meth:`admit` once the samples step at the stated rate.

        Runs of plain samples (plausible, not saturated, each one sample period after the one before) are admitted
        as whole arrays; each other sample goes through the rules one at a time, with the same result."""
        dt = 1.0 / self.rate_hz
        segments: list[Segment] = []
        rows: list[np.ndarray] = []   # pieces (K, 7) of the current segment
        if len(samples) == 0:
            return segments
        block = samples[:, :7]
        # a log's rows (N, 7) carry no status word and no saturation flag
        flags = samples[:, 7:9].astype(np.int64) if samples.shape[1] > 7 else np.zeros((len(samples), 2), np.int64)
        # a time no clock reads; beyond the range, no sensor's value (a frame flagged saturated is the sensor at full
        # scale: a restart, below)
        dtheta_max, dv_max, clockless, out_of_range, refused = screen(block, flags[:, 1], self.max_dtheta_rad,
                                                                       self.max_dv_mps, MAX_TIME_S)
        breaks = np.flatnonzero(~self._plain(block[:, 0], refused))
        last_here = -1   # the index of the last row this call admitted (-1: none yet)
        k = 0
        while k < len(block):
            if (k == 0 or last_here == k - 1) and not self._behind:
                end = int(breaks[np.searchsorted(breaks, k)]) if len(breaks) and breaks[-1] >= k else len(block)
                if end > k:   # plain rows, each after the one before it, which is the last admitted
                    self.counters.status_flagged += int(np.count_nonzero(flags[k:end, 0]))
                    rows.append(block[k:end])
                    # a copy: a view would keep this whole read's array alive until the next one
                    self._last, last_here, k = block[end - 1].copy(), end - 1, end
                    continue
            row = block[k].copy()   # kept as the last admitted or held behind: not a view of the read
            t, (status, saturated) = float(row[0]), flags[k]
            k += 1
            if clockless[k - 1] or out_of_range[k - 1]:
                self.counters.implausible += 1
                self.last_error = (f"sample at t = {t:.6g} s: no IMU clock reads that (|t| > {MAX_TIME_S:g} s): "
                                   "dropped" if clockless[k - 1] else
                                   f"sample at t = {t:.6f} s beyond the IMU's range (|Δθ| {dtheta_max[k - 1]:.3g} "
                                   f"rad, |Δv| {dv_max[k - 1]:.3g} m/s): dropped")
                continue
            if self._last is not None and not t > self._last[0]:
                if not self._hold_behind(row):
                    continue
                rows = self._clock_reset(segments, rows)
                continue
            self._drop_behind()
            if status:
                self.counters.status_flagged += 1
            if saturated:
                self.counters.saturated += 1
                self._cut(segments, rows, f"saturated sample at t = {t:.6f} s")
                rows, self._last = [], None
                continue
            if self._last is not None:
                missing = round((t - self._last[0]) / dt) - 1
                if 0 < missing <= self.max_bridge_samples:
                    rows.append(self._bridge(self._last, row, missing))
                elif missing > self.max_bridge_samples:
                    self._cut(segments, rows, f"gap of {missing} samples before t = {t:.6f} s")
                    rows = []
            rows.append(row[None])
            self._last, last_here = row, k - 1
        self._close(segments, rows)
        return segments

    def new_time_base(self) -> None:
        """The samples from here on may start a new time base (a recording's restart marker: the alignment started
        over there, perhaps on a sensor's restarted clock): none before them is the last admitted, and their rate
        is judged afresh. Samples still held for their odd steps go with the old time base (``rate_mismatch``)."""
        self.counters.rate_mismatch += len(self._held)
        self._last, self._behind, self._restart_reason, self._held = None, [], None, self._held[:0]
        self.rate.restart()

    def _stop(self, segments: list[Segment]) -> None:
        """The samples do not step at the stated rate: the alignment restarts now (a segment without rows) and
        takes none until they do."""
        self.counters.restarts += 1
        segments.append(Segment(np.empty((0, 7)), True, self.last_error))
        self._last, self._behind, self._restart_reason = None, [], None

    def _plain(self, t: np.ndarray, refused: np.ndarray) -> np.ndarray:
        """Whether each sample, if the one before it (``_last`` for the first) is the last admitted, is admitted as
        it is: not ``refused`` (implausible, saturated), after that one, and not after a gap."""
        return plain_rows(t, refused.view(np.uint8), np.nan if self._last is None else self._last[0],
                          1.0 / self.rate_hz)

    def _hold_behind(self, row: np.ndarray) -> bool:
        """Hold a sample that does not follow the last admitted one; True once the held ones show a clock that went
        back (enough of them, running on)."""
        if self._behind and not row[0] > self._behind[-1][0]:
            self._drop_behind()
        self._behind.append(row)
        return len(self._behind) > self.max_bridge_samples

    def _drop_behind(self) -> None:
        """The held samples were strays (a repeat, one out of order): dropped, counted."""
        if self._behind:
            self.counters.time_not_increasing += len(self._behind)
            self.last_error = (f"{len(self._behind)} sample(s) from t = {self._behind[0][0]:.6f} s did not follow the "
                               "sample before: dropped")
            self._behind = []

    def _clock_reset(self, segments: list[Segment], rows: list[np.ndarray]) -> list[np.ndarray]:
        """The clock went back: cut, and the held samples begin the next segment (its rows, returned)."""
        self.counters.clock_resets += 1
        self._cut(segments, rows, f"the IMU's time went back from t = {self._last[0]:.6f} s to "
                                  f"t = {self._behind[0][0]:.6f} s")
        rows, self._behind = [np.array(self._behind)], []
        self._last = rows[0][-1]
        return rows

    def _close(self, segments: list[Segment], rows: list[np.ndarray]) -> None:
        """The rows since the last cut (pieces (K, 7)) as a segment, which takes the pending restart (none without
        rows)."""
        if rows:
            segments.append(Segment(rows[0] if len(rows) == 1 else np.concatenate(rows),
                                    self._restart_reason is not None, self._restart_reason))
            self._restart_reason = None

    def _cut(self, segments: list[Segment], rows: list[np.ndarray], why: str) -> None:
        """Close the current segment; the next one, in this call or a later one, restarts the alignment."""
        self._close(segments, rows)
        self.counters.restarts += 1
        self.last_error = self._restart_reason = f"{why}: alignment restarted"

    def _bridge(self, before: np.ndarray, after: np.ndarray, missing: int) -> np.ndarray:
        """The ``missing`` rows (missing, 7) between two samples, linearly interpolated."""
        self.counters.gaps_bridged += 1
        self.counters.samples_bridged += missing
        fractions = np.arange(1, missing + 1) / (missing + 1)
        return before + fractions[:, None] * (after - before)


def gate_for(config: Config, rate_hz: float | None = None) -> SampleGate:
    """The sample gate of the configured IMU: its rate (or ``rate_hz``: a log header's), the daemon's bridging, and
    the increments its ranges allow."""
    stated_as = "imu.rate_hz" if rate_hz is None else "the header's rate_hz"
    rate_hz = config.imu.rate_hz if rate_hz is None else rate_hz
    interval_s = RANGE_INTERVALS / rate_hz
    return SampleGate(rate_hz, config.daemon.max_bridge_samples,
                      max_dtheta_rad=config.imu.gyro_range_deg_s * DEG * interval_s,
                      max_dv_mps=config.imu.acc_range_g * G0_MS2 * interval_s, rate_stated_as=stated_as)

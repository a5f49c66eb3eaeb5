"""The white noise the IMU data show, against the datasheet's (fixed base).

The reported σ of the fixed-base stages is a model of the datasheet's noise figures: a datasheet that
claims far too little noise (a unit slip, a figure of another sensor) leaves σ far too small while
the errors are the data's. The data measure their own noise: white noise of density n gives
increments over a sample period dt with per-sample standard deviation n √dt, and the K-th
difference of a white sequence has C(2K, K) times its variance, while a smooth motion's K-th
difference shrinks as (ω dt)^K. At K = 4 a ship's swing or a turntable's sway at 200 Hz leaves
under 1e-12 rad against 2e-9 rad of a navigation-grade gyro's noise (measured on the seed-000 swing:
0.99 of the stated density for both sensors). Each control block gives one mean square per sensor;
the estimate is the median over the last :data:`BLOCKS_HELD` blocks, so a short burst of motion (a
turntable step, a knock) does not move it. Memory is O(1).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from math import comb

import numpy as np

from .conventions import DRH_TO_RRS, UG_TO_MS2
from .sensor_model import SensorGrade

DIFFERENCE_ORDER = 4
BLOCKS_HELD = 600
"""Blocks in the median (60 s of 0.1-s control steps)."""
MIN_BLOCKS = 100
"""Blocks before the meter gives a figure (10 s of 0.1-s control steps)."""
VERDICT_BLOCKS = 10
"""The pipeline asks for a verdict every this many blocks (one median per second of data)."""
ALARM_FACTOR = 2.0
"""A measured density above this many times the datasheet's is no estimation scatter: the datasheet is wrong
(or the base vibrates), and σ takes the measured figure."""
RESOLUTION = 1e-9
"""Densities (rad/√s, m/s/√s) below this are numerical residue of exact data, not noise: no real IMU is that
quiet (a strategic-grade gyro is 3e-8 rad/√s, 0.0001°/√h)."""


@dataclass(frozen=True, slots=True)
class NoiseVerdict:
    """The grade σ should use (the datasheet's, with a measured figure in place of a stated one it exceeds by more
    than :data:`ALARM_FACTOR`) and what to tell the operator (None: nothing)."""

    grade: SensorGrade
    notice: str | None


class NoiseMeter:
    """Measures the gyro and accelerometer white-noise densities from blocks of raw increments.

    sample_period_s : the IMU sample period dt (s).
    """

    def __init__(self, sample_period_s: float) -> None:
        self.sample_period_s = sample_period_s
        self._samples = np.empty((0, 6))   # the last K samples, then the block's: one buffer, no allocation per block
        self._difference = np.empty((0, 0))   # the K-th difference as a matrix (M, K + M): one product per block
        self._mean_squares = np.zeros((BLOCKS_HELD, 2))
        self.blocks = 0

    def feed(self, samples: np.ndarray) -> None:
        """One block of M consecutive samples (M, 6): Δθ (3) rad, Δv (3) m/s (the same M every block)."""
        K, M = DIFFERENCE_ORDER, len(samples)
        if len(self._samples) != K + M:   # the first block: its own differences only
            self._samples = np.empty((K + M, 6))
            self._samples[K:] = samples
            weights = [(-1.0) ** (K - i) * comb(K, i) for i in range(K + 1)]
            self._difference = np.array([np.r_[np.zeros(r), weights, np.zeros(M - 1 - r)] for r in range(M)])
            d = np.diff(samples, n=K, axis=0)
        else:
            self._samples[K:] = samples
            d = self._difference @ self._samples
        self._samples[:K] = self._samples[-K:]
        if len(d):
            squares = np.einsum("ij,ij->j", d, d)
            self._mean_squares[self.blocks % BLOCKS_HELD] = squares[:3].sum() / (3 * len(d)), squares[3:].sum() / (
                3 * len(d))
            self.blocks += 1

    def densities(self) -> tuple[float, float] | None:
        """(gyro ARW rad/√s, accelerometer VRW m/s/√s) the data show; None before :data:`MIN_BLOCKS` blocks."""
        if self.blocks < MIN_BLOCKS:
            return None
        held = self._mean_squares[:min(self.blocks, BLOCKS_HELD)]
        median = np.partition(held, len(held) // 2, axis=0)[len(held) // 2]
        variance = median / comb(2 * DIFFERENCE_ORDER, DIFFERENCE_ORDER)
        gyro, acc = np.sqrt(variance / self.sample_period_s)
        return float(gyro), float(acc)

    def verdict(self, stated: SensorGrade) -> NoiseVerdict | None:
        """The measured figures against the datasheet's ``stated``; None before the meter has a figure."""
        measured = self.densities()
        if measured is None:
            return None
        gyro, acc = measured
        louder = {name: value for name, value, claimed in (("gyro_arw_rad_rts", gyro, stated.gyro_arw_rad_rts),
                                                            ("acc_vrw_ms_rts", acc, stated.acc_vrw_ms_rts))
                  if value > max(ALARM_FACTOR * claimed, RESOLUTION)}
        if not louder:
            return NoiseVerdict(stated, None)
        parts = []
        if "gyro_arw_rad_rts" in louder:
            parts.append(f"gyro noise {gyro / DRH_TO_RRS:.3g}°/√h, {gyro / stated.gyro_arw_rad_rts:.3g}× the "
                         f"datasheet's {stated.gyro_arw_rad_rts / DRH_TO_RRS:.3g}°/√h (gyro_arw_deg_rth)")
        if "acc_vrw_ms_rts" in louder:
            parts.append(f"accelerometer noise {acc / UG_TO_MS2:.3g} µg/√Hz, {acc / stated.acc_vrw_ms_rts:.3g}× the "
                         f"datasheet's {stated.acc_vrw_ms_rts / UG_TO_MS2:.3g} µg/√Hz (acc_vrw_ug_rthz)")
        notice = (f"the data show {' and '.join(parts)}: σ uses the measured figure; check [sensor] or the log's "
                  "datasheet keys (or the base vibrates)")
        return NoiseVerdict(replace(stated, **louder), notice)

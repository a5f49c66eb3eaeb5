"""Time stamps from a wrapping sample counter (protocol/counter_clock.py).

GIVEN a STIM300-like counter (u8, 2000 ticks/s, 10 ticks per sample at 200 Hz: it wraps every 25.6 samples),
read by a host in bursts, THEN the samples are stamped at exact multiples of the sample period whatever the read
jitter, a reader that paused loses nothing, a line that went silent for several wraps is a gap of exactly the
frames lost, a repeated counter is dropped, and a sensor clock 1000 ppm off the host's for 10 minutes, or a bench
playing 40 times faster than real time, causes no false gap.
"""
from __future__ import annotations

import numpy as np
import pytest
from sinsalign.protocol.counter_clock import CounterClock

RATE_HZ, STEP, MODULUS, TICK_S = 200.0, 10, 256, 1 / 2000


def reads(k: np.ndarray, produced_s: np.ndarray, period_s: float, delay_s: float = 0.003):
    """The samples ``k`` produced at ``produced_s``, read every ``period_s`` (each read brings what was produced
    before it, ``delay_s`` late): (counters, arrival time) per read."""
    read_at = (np.floor(produced_s / period_s) + 1) * period_s + delay_s
    starts = np.flatnonzero(np.diff(read_at, prepend=-np.inf))
    for piece, at in zip(np.split((STEP * k) % MODULUS, starts[1:]), read_at[starts], strict=True):
        yield piece, float(at)


def stamped(clock: CounterClock, pieces) -> np.ndarray:
    return np.concatenate([clock.stamp(counters, at) for counters, at in pieces])


def test_steady_reads_give_exact_sample_intervals():
    clock = CounterClock(MODULUS, TICK_S, STEP)
    k = np.arange(20_000)
    rng = np.random.default_rng(1)
    t = stamped(clock, ((c, at + rng.uniform(0, 0.01)) for c, at in reads(k, 100.0 + k / RATE_HZ, 0.02)))
    assert np.allclose(np.diff(t), 1 / RATE_HZ, rtol=0, atol=1e-9)
    assert clock.counters() == {"seq_gaps": 0, "seq_repeats": 0}


def test_a_reader_that_paused_loses_nothing_and_a_silent_line_is_a_gap_of_the_frames_lost():
    clock = CounterClock(MODULUS, TICK_S, STEP)
    k = np.arange(4000)
    produced = 50.0 + k / RATE_HZ
    pieces = list(reads(k, produced, 0.02))
    # the reader stops for 0.4 s (a dozen wraps): the frames queue and come in one read
    late = [(c, at) for c, at in pieces if not 60.0 < at < 60.4]
    burst = np.concatenate([c for c, at in pieces if 60.0 < at < 60.4])
    late.insert(next(i for i, (_, at) in enumerate(late) if at >= 60.4), (burst, 60.4))
    t = stamped(clock, late)
    assert clock.gaps == 0 and np.allclose(np.diff(t), 1 / RATE_HZ, atol=1e-9)
    # the line goes silent for 0.73 s: 145 frames (5.7 wraps) never arrive
    lost = (produced > 60.0) & (produced <= 60.73)
    clock = CounterClock(MODULUS, TICK_S, STEP)
    t = stamped(clock, reads(k[~lost], produced[~lost], 0.02))
    assert clock.gaps == int(lost.sum()) == 145
    assert np.allclose(t - t[0], (k[~lost] - k[0]) / RATE_HZ, atol=1e-9)


def test_a_repeated_counter_is_dropped():
    clock = CounterClock(MODULUS, TICK_S, STEP)
    t = clock.stamp(np.array([0, 10, 10, 20]), 1.0)
    assert np.isnan(t[2]) and np.allclose(t[[0, 1, 3]], [1.0 - 0.01, 1.0 - 0.005, 1.0])
    assert np.isnan(clock.stamp(np.array([20]), 1.01)[0]) and clock.repeats == 2 and clock.gaps == 0


@pytest.mark.parametrize("clock_ratio", [1 + 1e-3, 1 - 1e-3])
def test_a_sensor_clock_1000_ppm_off_the_hosts_for_10_minutes_gives_no_false_gap(clock_ratio):
    """0.6 s of drift: what 170 ppm makes in an hour."""
    clock = CounterClock(MODULUS, TICK_S, STEP)
    k = np.arange(int(600 * RATE_HZ))
    stamped(clock, reads(k, 10.0 + k / RATE_HZ * clock_ratio, 0.02))
    assert clock.counters() == {"seq_gaps": 0, "seq_repeats": 0}


def test_a_bench_40_times_faster_than_real_time_gives_no_false_gap_and_counts_a_real_one():
    clock = CounterClock(MODULUS, TICK_S, STEP)
    k = np.delete(np.arange(16_000), [9000, 9001, 9002])
    stamped(clock, reads(k, 5.0 + k / RATE_HZ / 40, 0.02))
    assert clock.counters() == {"seq_gaps": 3, "seq_repeats": 0}

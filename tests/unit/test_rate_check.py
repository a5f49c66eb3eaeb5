"""The sample gate's rate check (service/rate_check.py): time stamps that do not step at the stated rate stop the
alignment.

GIVEN a 200-Hz IMU stream into a gate configured for 400 Hz (or 100 Hz), WHEN 101 samples have come, THEN the
alignment restarts at once (a segment without rows), every sample after the first (held for steps that are not
one period until the verdict) is dropped and counted (`rate_mismatch`),
and `last_error` names both periods; WHEN the stream then steps at the stated rate for a window, the samples after
it are admitted again. GIVEN a stream whose rate changes at any time in the run (200 → 400 or 100 Hz) or a rate
25 % off from the start, THEN the same within one window of the change. GIVEN a clock a few per cent off, a line
that loses frames now and then, or jittered time stamps, THEN nothing is dropped. The verdicts fall at the same
samples however the calls split the stream.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sinsalign.service.rate_check import RATE_CHECK_STEPS
from sinsalign.service.sample_gate import SampleGate, Segment
from support.sample_streams import stream

WINDOW = RATE_CHECK_STEPS + 1   # samples in one judgement


def admitted(gate: SampleGate, samples: np.ndarray, split: int | None = None) -> list[Segment]:
    calls = [samples] if split is None else [samples[k:k + split] for k in range(0, len(samples), split)]
    return [segment for call in calls for segment in gate.admit(call)]


@pytest.mark.parametrize("stated_hz", [400.0, 100.0])
def test_samples_that_do_not_step_at_the_stated_rate_restart_the_alignment_and_are_dropped(stated_hz):
    samples = stream(np.arange(1, 1001) / 200.0)
    gate = SampleGate(stated_hz)
    segments = admitted(gate, samples)
    stop = segments[-1]
    assert stop.restart and len(stop.rows) == 0
    # the first sample went in; the rest of the first window, every step not one period, was held and is dropped
    assert sum(len(s.rows) for s in segments[:-1]) == 1
    expected = (f"samples come every 5 ms (200 Hz, the median of {RATE_CHECK_STEPS} steps), where imu.rate_hz = "
                f"{stated_hz:g} says {1e3 / stated_hz:g} ms")
    assert stop.reason == gate.last_error == \
        f"{expected}: no sample is aligned until they do (set imu.rate_hz to the IMU's rate)"
    assert gate.counters.rate_mismatch == len(samples) - 1
    assert gate.counters.restarts == 1
    assert gate.admit(stream(np.arange(1001, 1101) / 200.0)) == []   # still dropped
    assert gate.counters.rate_mismatch == len(samples) - 1 + 100


def test_samples_admitted_again_after_a_window_that_steps_at_the_stated_rate():
    wrong = np.arange(1, 301) / 200.0            # 3 windows at 200 Hz, stated 400 Hz
    right = wrong[-1] + np.arange(1, 601) / 400.0
    gate = SampleGate(400.0)
    segments = admitted(gate, stream(np.concatenate((wrong, right))))
    after_stop = segments[[s.restart and len(s.rows) == 0 for s in segments].index(True) + 1:]
    rows = np.concatenate([s.rows for s in after_stop])
    # windows of 101: the 2nd is wrong, the 3rd takes the last 98 wrong samples and 3 right ones
    passing_window_end = 3 * WINDOW - len(wrong)
    np.testing.assert_array_equal(rows[:, 0], right[passing_window_end + WINDOW:])
    assert gate.counters.rate_mismatch == len(wrong) - 1 + passing_window_end + WINDOW
    assert gate.rate.settled


@pytest.mark.parametrize("case", ["clock 3 % fast", "clock 3 % slow", "30 % of frames lost", "jitter of 40 %"])
def test_a_stream_at_its_rate_with_a_real_clock_and_a_lossy_line_passes(case):
    rng = np.random.default_rng(7)
    k = np.arange(1, 2001)
    times = {"clock 3 % fast": k / 206.0, "clock 3 % slow": k / 194.0,
             "30 % of frames lost": k[rng.random(len(k)) > 0.3] / 200.0,
             "jitter of 40 %": (k + rng.uniform(-0.2, 0.2, len(k))) / 200.0}[case]
    gate = SampleGate(200.0, max_bridge_samples=20)
    segments = admitted(gate, stream(times))
    assert gate.counters.rate_mismatch == 0 and gate.rate.failure is None and gate.rate.settled
    assert not any(len(s.rows) == 0 for s in segments)


@pytest.mark.parametrize("new_hz", [400.0, 100.0])
@pytest.mark.parametrize("split", [None, 1, 37, 5000])
def test_a_rate_that_changes_late_in_the_run_stops_the_alignment_within_a_window(new_hz, split):
    before = np.arange(1, 12_001) / 200.0          # 60 s at the stated 200 Hz: a settled stream
    after = before[-1] + np.arange(1, 2001) / new_hz
    gate = SampleGate(200.0)
    segments = admitted(gate, stream(np.concatenate((before, after))), split)
    stops = [s for s in segments if s.restart and len(s.rows) == 0]
    assert len(stops) == 1 and gate.counters.restarts == 1 and not gate.rate.settled
    admitted_t = np.concatenate([s.rows[:, 0] for s in segments if len(s.rows)])
    late = np.isin(after, admitted_t).sum()         # the samples after the change admitted (bridged ones aside)
    assert late <= 2 * WINDOW                       # the window the change falls in and at most the next
    assert gate.counters.rate_mismatch == len(after) - late
    assert stops[0].reason.startswith(f"samples come every {1e3 / new_hz:g} ms ({new_hz:g} Hz, the median of")
    assert "where imu.rate_hz = 200 says 5 ms" in stops[0].reason


def test_a_rate_25_per_cent_off_from_the_start_is_told():
    gate = SampleGate(250.0)                        # a STIM300 at 200 Hz configured as 250 Hz
    segments = admitted(gate, stream(np.arange(1, 1001) / 200.0))
    assert segments[-1].restart and len(segments[-1].rows) == 0
    assert gate.counters.rate_mismatch == 1000 - 1
    assert gate.last_error.startswith("samples come every 5 ms (200 Hz, the median of 100 steps), where imu.rate_hz "
                                      "= 250 says 4 ms")


def test_a_time_no_clock_reads_says_nothing_of_the_rate():
    times = np.arange(1, 401) / 200.0
    times[::10] = 1e308                      # every tenth stamp wild: the rest step at 5 ms, some at 10 ms
    gate = SampleGate(200.0)
    admitted(gate, stream(times))
    assert gate.counters.rate_mismatch == 0 and gate.rate.settled


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 400), st.sampled_from([400.0, 100.0]))
def test_the_verdicts_fall_at_the_same_samples_however_the_calls_split_the_stream(split, stated_hz):
    wrong = np.arange(1, 351) / 200.0
    right = wrong[-1] + np.arange(1, 851) / stated_hz
    changed = right[-1] + np.arange(1, 351) / 200.0   # and the rate changes again, late
    samples = stream(np.concatenate((wrong, right, changed)))

    def runs(segments: list[Segment]) -> list[tuple[str | None, list[float]]]:
        out: list[tuple[str | None, list[float]]] = []
        for segment in segments:
            if segment.restart or not out:
                out.append((segment.reason, []))
            out[-1][1].extend(segment.rows[:, 0].tolist())
        return out

    whole, parts = SampleGate(stated_hz), SampleGate(stated_hz)
    assert runs(admitted(whole, samples)) == runs(admitted(parts, samples, split))
    assert whole.counters == parts.counters and whole.last_error == parts.last_error


def test_a_new_time_base_is_judged_afresh():
    gate = SampleGate(200.0)
    admitted(gate, stream(np.arange(1, 201) / 200.0))
    assert gate.rate.settled
    gate.new_time_base()
    segments = admitted(gate, stream(np.arange(1, 201) / 100.0))
    assert segments[-1].restart and len(segments[-1].rows) == 0 and gate.counters.rate_mismatch == 200 - 1

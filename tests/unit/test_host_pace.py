"""The host's clock on a vendor IMU's counter stamps (service/rate_check.py ``HostPace``, ``RateCheck.host_pace``):
a rate the counter's steps cannot show stops the alignment.

GIVEN reads of a real-time line (a few samples every 5–20 ms, each up to 30 ms late), stamped from a counter that
steps once a sample at 1/``imu.rate_hz`` (a KVH), WHEN the IMU runs at the configured rate, THEN every pace is
within 1 % of 1, across a silence of the line too; WHEN it runs at twice, half or 25 % off the configured rate
(from the start, or doubling late in the run), THEN the pace says so within 2 s of host time, the gate stops the
alignment (a segment without rows), drops every sample after (`rate_mismatch`, held ones too) and names both rates;
and a window that steps at the stated rate (they all do) does not resume it while the host's verdict stands, only
the first one after the verdict is back within tolerance. A vendor's format puts the pace out with its samples
unless ``counter_only``.
"""
from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from sinsalign.protocol.kvh import KvhDecoder, KvhEncoder
from sinsalign.service.rate_check import RATE_CHECK_STEPS, RATE_TOLERANCE, HostPace
from sinsalign.service.sample_gate import SampleGate, Segment
from sinsalign.service.serial_formats import VendorFrames
from support.sample_streams import stream

RATE_HZ = 200.0   # imu.rate_hz: the counter's ticks are stamped 5 ms apart
WINDOW = RATE_CHECK_STEPS + 1


def produced(true_hz: float, seconds: float, change: tuple[float, float] | None = None) -> np.ndarray:
    """The host times (s) an IMU at ``true_hz`` produces its samples at for ``seconds``; ``change``: (host time s,
    new rate Hz) from which it runs at another rate."""
    if change is None:
        return np.arange(1, int(seconds * true_hz) + 1) / true_hz
    at_s, new_hz = change
    before = np.arange(1, int(at_s * true_hz) + 1) / true_hz
    return np.concatenate((before, before[-1] + np.arange(1, int((seconds - at_s) * new_hz) + 1) / new_hz))


def reads(p: np.ndarray, seed: int = 3, silence: tuple[float, float] | None = None,
          behind: tuple[float, float, float] | None = None) -> Iterator[tuple[int, float]]:
    """A reader of a real-time line: every 5–20 ms, the samples produced (host times ``p``, s) up to 0–30 ms before
    the read; each read that brings samples as (one past its newest sample's index, arrival s). ``silence``: (from,
    to) host s in which nothing is read (the samples produced then come with the read after); ``behind``: (from, to,
    s) host s in which the reader lags that much more (a busy host), catching up after."""
    rng = np.random.default_rng(seed)
    arrival, taken = 0.0, 0
    while taken < len(p):
        arrival += rng.uniform(0.005, 0.020)
        if silence is not None and silence[0] <= arrival < silence[1]:
            continue
        lag = rng.uniform(0.0, 0.030) + (behind[2] if behind is not None and behind[0] <= arrival < behind[1] else 0)
        newest = int(np.searchsorted(p, arrival - lag, side="right"))
        if newest > taken:
            taken = newest
            yield newest, arrival


def paces(p: np.ndarray, **kwargs) -> list[tuple[float, float]]:
    """(arrival s, pace) of every verdict of :class:`HostPace` on the reads of ``p``, counter-stamped at RATE_HZ."""
    pace = HostPace()
    out = []
    for newest, arrival in reads(p, **kwargs):
        ratio = pace.observe((newest - 1) / RATE_HZ, arrival)
        if ratio is not None:
            out.append((arrival, ratio))
    return out


def through_gate(gate: SampleGate, p: np.ndarray) -> tuple[list[tuple[float, list[Segment]]], int]:
    """The gate's segments of each read (with its arrival s) of an IMU producing at host times ``p`` and stamped at
    RATE_HZ from its counter, the host's pace passed on as the daemon does; and the samples read."""
    pace = HostPace()
    out, taken = [], 0
    for newest, arrival in reads(p):
        ratio = pace.observe((newest - 1) / RATE_HZ, arrival)
        if ratio is not None:
            gate.rate.host_pace(ratio)
        out.append((arrival, gate.admit(stream(np.arange(taken, newest) / RATE_HZ))))
        taken = newest
    return out, taken


def test_a_sound_line_keeps_within_1_per_cent_of_the_counters_pace_across_a_silence():
    verdicts = paces(produced(RATE_HZ, 20.0), silence=(8.0, 11.0))
    assert 1.0 <= verdicts[0][0] < 1.1   # two buckets of 0.5 s
    ratios = np.array([ratio for _, ratio in verdicts])
    assert len(ratios) >= 20 and np.abs(ratios - 1.0).max() < 0.01


@pytest.mark.parametrize("behind_s", [(4.0, 5.0, 0.04), (4.0, 6.5, 0.04), (4.2, 4.9, 0.045)])
def test_a_reader_that_falls_behind_for_a_while_and_catches_up_is_no_rate(behind_s):
    """A busy host: every read 40-45 ms later than the line's own lag for 0.7-2.5 s, then on time again. The least
    lag of one bucket moves (a pace of 1 ± 0.08 between it and its neighbour), never two in a row, and a read that
    catches up is no further ahead than the limit."""
    verdicts = paces(produced(RATE_HZ, 12.0), behind=behind_s)
    assert all(RATE_TOLERANCE[0] <= ratio <= RATE_TOLERANCE[1] for _, ratio in verdicts)


@pytest.mark.parametrize("true_hz", [400.0, 100.0, 250.0, 160.0])
def test_a_rate_off_the_configured_one_is_out_of_tolerance_within_2_s(true_hz):
    verdicts = paces(produced(true_hz, 6.0))
    out = [arrival for arrival, ratio in verdicts if not RATE_TOLERANCE[0] <= ratio <= RATE_TOLERANCE[1]]
    assert out and out[0] < 2.0   # a bucket's confirmed by the next (1.5 s), or a read ahead at once
    ratios = np.array([ratio for arrival, ratio in verdicts if arrival >= out[0]])
    # from the first beyond it, every verdict on the true side of the tolerance; a bucket's within 2 % (a read ahead
    # of the least lag gives a rough one at once, which includes that read's own lag)
    assert np.all(ratios > RATE_TOLERANCE[1]) if true_hz > RATE_HZ else np.all(ratios < RATE_TOLERANCE[0])
    assert np.median(ratios) == pytest.approx(true_hz / RATE_HZ, rel=0.02)


def test_a_rate_that_doubles_late_is_told_within_2_s_of_the_change():
    verdicts = paces(produced(RATE_HZ, 14.0, change=(10.0, 2 * RATE_HZ)))
    out = [arrival for arrival, ratio in verdicts if not RATE_TOLERANCE[0] <= ratio <= RATE_TOLERANCE[1]]
    # a read ahead of the least lag by 50 ms tells at once (the buckets alone took up to 1.5 s)
    assert out and 10.0 < out[0] < 10.2
    assert all(abs(ratio - 1.0) < 0.01 for arrival, ratio in verdicts if arrival < 10.0)


@pytest.mark.parametrize(("true_hz", "change"), [(250.0, None), (RATE_HZ, (10.0, 2 * RATE_HZ))])
def test_the_gate_stops_and_drops_every_sample_after_the_hosts_verdict(true_hz, change):
    """Stated 200 Hz, a KVH at 250 Hz from the start, or at 200 Hz doubling its rate at 10 s: every window steps
    at 5 ms and passes; the host's clock alone stops the alignment."""
    p = produced(true_hz, 14.0, change)
    gate = SampleGate(RATE_HZ)
    calls, n = through_gate(gate, p)
    stops = [arrival for arrival, segments in calls for s in segments if s.restart and len(s.rows) == 0]
    changed_at = 0.0 if change is None else change[0]
    assert len(stops) == 1 and changed_at < stops[0] < changed_at + 2.0
    assert gate.counters.restarts == 1 and not gate.rate.settled
    assert not any(len(s.rows) for arrival, segments in calls if arrival >= stops[0] for s in segments)
    used = sum(len(s.rows) for _, segments in calls for s in segments)
    assert gate.counters.rate_mismatch == n - used
    true_after = true_hz if change is None else change[1]
    # the rate measured, in Hz (named again once it moves beyond the tolerance: a verdict may span the change)
    assert float(gate.last_error.split()[3]) == pytest.approx(true_after, rel=RATE_TOLERANCE[1] - 1.0)
    assert gate.last_error.startswith("samples come at ") and gate.last_error.endswith(
        " Hz by the host's clock (the IMU's counter stamps them at imu.rate_hz = 200): no sample is aligned until "
        "they do (set imu.rate_hz to the IMU's rate)")


def test_a_verdict_between_calls_stops_at_the_next_and_drops_the_held_samples():
    gate = SampleGate(RATE_HZ)
    t = np.arange(1, 3 * WINDOW) / RATE_HZ
    t = np.append(t, t[-1] + 2 / RATE_HZ)   # one frame lost: the last sample held for its step
    assert sum(len(s.rows) for s in gate.admit(stream(t))) == len(t) - 1 and gate.rate.settled
    gate.rate.host_pace(2.0)
    assert gate.rate.failure is not None and not gate.rate.settled
    more = stream(t[-1] + np.arange(1, 51) / RATE_HZ)
    (stop,) = gate.admit(more)
    assert stop.restart and len(stop.rows) == 0 and gate.counters.restarts == 1
    assert gate.counters.rate_mismatch == len(more) + 1
    assert stop.reason == gate.last_error == (
        "samples come at 400 Hz by the host's clock (the IMU's counter stamps them at imu.rate_hz = 200): no sample "
        "is aligned until they do (set imu.rate_hz to the IMU's rate)")


def test_passing_windows_do_not_resume_while_the_hosts_verdict_stands_the_next_one_after_it_does():
    gate = SampleGate(RATE_HZ)
    t = np.arange(1, 2 * WINDOW + 1) / RATE_HZ
    gate.admit(stream(t))
    gate.rate.host_pace(0.8)
    last = t[-1]

    def following(n: int) -> np.ndarray:
        nonlocal last
        times = last + np.arange(1, n + 1) / RATE_HZ
        last = times[-1]
        return stream(times)

    (stop,) = gate.admit(following(1))
    assert stop.restart and len(stop.rows) == 0
    for _ in range(5):                               # five windows, each at 5 ms: the failure stands
        gate.rate.host_pace(0.8)
        assert gate.admit(following(WINDOW)) == [] and not gate.rate.settled
    gate.rate.host_pace(1.003)                       # back within tolerance: the next passing window settles it
    assert gate.rate.failure is not None
    dropped = gate.counters.rate_mismatch
    rows = [s.rows for s in gate.admit(following(3 * WINDOW))]
    assert gate.rate.settled and gate.rate.failure is None and rows and gate.counters.restarts == 1
    assert WINDOW - 1 <= gate.counters.rate_mismatch - dropped <= 2 * WINDOW
    assert sum(map(len, rows)) == 3 * WINDOW - (gate.counters.rate_mismatch - dropped)


def test_a_verdict_within_tolerance_changes_nothing():
    gate = SampleGate(RATE_HZ)
    t = np.arange(1, 1001) / RATE_HZ
    gate.admit(stream(t[:500]))
    gate.rate.host_pace(0.97)
    segments = gate.admit(stream(t[500:]))
    assert gate.rate.settled and gate.counters.rate_mismatch == 0 and gate.counters.restarts == 0
    assert sum(len(s.rows) for s in segments) == 500


@pytest.mark.parametrize(("counter_only", "expected"), [(False, 0.8), (True, None)])
def test_a_vendors_format_puts_out_the_pace_of_its_stamps_on_the_host_clock(counter_only, expected):
    """A KVH 1775 at 200 Hz read with imu.rate_hz = 250: its counter stamps run at 0.8 of the host's clock."""
    encoder = KvhEncoder("1775", 250.0)
    now = [0.0]
    frames = VendorFrames(KvhDecoder("1775", 250.0), np.eye(3), clock=lambda: now[0], counter_only=counter_only)
    p = produced(200.0, 3.0)
    taken, out = 0, []
    for newest, arrival in reads(p):
        now[0] = arrival
        data = b"".join(encoder.encode(k % 128, np.zeros(3), np.array([0.0, 0.0, 0.05])) for k in range(taken, newest))
        decoded = frames.feed(data)
        assert len(decoded.samples) == newest - taken
        taken = newest
        out += [decoded.pace] if decoded.pace is not None else []
    if expected is None:
        assert out == []
    else:
        assert len(out) >= 2 and np.allclose(out, expected, rtol=0.02)   # 0.5-s buckets of jittered reads

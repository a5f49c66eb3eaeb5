"""The daemon's own read → published times: the status's ``loop`` figures against numpy's on the same reads."""
import numpy as np
from sinsalign.service.loop_timing import LoopTiming


def test_a_period_s_figures_are_its_reads_and_the_next_period_starts_afresh() -> None:
    rng = np.random.default_rng(3)
    seconds = rng.gamma(2.0, 2e-4, 500)
    timing = LoopTiming()
    for s in seconds:
        timing.add(float(s), float(s) / 2)
    first = timing.summary(advance=True)
    assert first["reads"] == 500
    assert first["p50_ms"] == np.percentile(seconds * 1e3, 50) and first["p99_ms"] == np.percentile(seconds * 1e3, 99)
    assert first["max_ms"] == first["max_ms_since_start"] == seconds.max() * 1e3
    assert first["max_cpu_ms"] == seconds.max() / 2 * 1e3
    timing.add(1e-4, 2.5e-5)
    second = timing.summary(advance=True)
    assert (second["reads"], second["p50_ms"], second["max_ms"], second["max_cpu_ms"]) == (1, 0.1, 0.1, 0.025)
    assert second["max_ms_since_start"] == first["max_ms"]
    empty = timing.summary()
    assert empty == {"reads": 0, "p50_ms": None, "p99_ms": None, "max_ms": None, "max_cpu_ms": None,
                     "max_ms_since_start": first["max_ms"]}


def test_a_query_between_two_statuses_leaves_the_period_whole() -> None:
    timing = LoopTiming()
    timing.add(2e-3, 1e-3)
    assert timing.summary() == timing.summary()
    timing.add(1e-3, 1e-3)
    assert timing.summary(advance=True)["reads"] == 2


def test_more_reads_than_kept_keep_the_latest_for_percentiles_and_the_exact_largest() -> None:
    timing = LoopTiming(capacity=8)
    times_ms = [20.0, *range(1, 16)]   # the largest is the first, overwritten in the ring
    for ms in times_ms:
        timing.add(ms / 1e3, 0.0)
    summary = timing.summary()
    assert summary["reads"] == 16 and summary["max_ms"] == summary["max_ms_since_start"] == 20.0
    assert summary["p50_ms"] == np.percentile(np.array(times_ms[-8:]) / 1e3 * 1e3, 50)

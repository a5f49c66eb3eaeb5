"""A land vehicle with an odometer and a GNSS receiver: the combined mode against each aid alone, on the same
seeds (docs/results.md, "Odometer and GNSS together"; ``sinsalign eval seed003-odo-gnss --seeds 20``).

Bounds: the combined heading MAE at 60 s and 120 s at most 0.8× the better single aid's, a 30-s GNSS outage
(60-90 s) costing at most 1.5× the clean run's MAE at its end, σ honest (≥ 90 % of epochs inside 2σ from 10 s, no
converged epoch beyond 3σ). Measured on 20 seeds: 0.15, 0.23, 1.36, 95.3 %, 0; the default run takes 4 of
them, the full set runs under -m slow.
"""
import pytest
from sinsalign.tools.evaluate_odo_gnss import combined_figures, run_variants


def assert_acceptance(seeds):
    figures = combined_figures(run_variants(seeds, progress=False))
    assert max(figures.ratio_to_better) <= 0.8, figures
    assert figures.outage_ratio <= 1.5, figures
    assert figures.inside_2sigma >= 0.9 and figures.converged_beyond_3sigma == 0, figures


def test_odometer_and_gnss_together_beat_either_alone_and_ride_through_an_outage_on_4_seeds():
    assert_acceptance(range(4))


@pytest.mark.slow
def test_odometer_and_gnss_together_on_20_seeds():
    assert_acceptance(range(20))

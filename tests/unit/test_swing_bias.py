"""The accelerometer bias seen through a swinging body (service/align/swing_bias.py) against simulated truth.

GIVEN a swinging or static base with a known accelerometer bias, WHEN the coarse stage fits the bias's
swing term and takes it out of α, THEN the bias and the Earth axis come out as simulated, the slow heading
transient of a swinging body is gone, the limit stays the limit, and a static base is left as it was.
"""
from dataclasses import replace

import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG, UG_TO_MS2, skew
from sinsalign.service.align.earth import C_n_n0_fixed, earth_turn_integrals
from sinsalign.service.align.swing_bias import SwingBias
from sinsalign.service.config import config_from_mapping
from sinsalign.service.pipeline import AlignmentPipeline
from sinsalign.tools.evaluate import COARSE_ONLY, run_once, window_stats
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import Scenario, get_scenario

SWING_BIAS = config_from_mapping(COARSE_ONLY)   # the fit is on by default (its figures: test_coarse_alignment)
PLAIN = config_from_mapping({"alignment": {"swing_bias": False}, **COARSE_ONLY})


def test_the_earth_turn_integrals_match_quadrature() -> None:
    lat, t = 32.0 * DEG, 300.0
    P1, P2, P3 = earth_turn_integrals(t)
    u = np.array([0.0, np.cos(lat), np.sin(lat)])
    tau = (np.arange(30000) + 0.5) * t / 30000
    quadrature = C_n_n0_fixed(lat, tau).sum(axis=0) * t / 30000
    closed = P1 * np.eye(3) + P2 * skew(u) + P3 * np.outer(u, u)
    assert np.abs(closed - quadrature).max() < 1e-9 * t


def _fitted(scenario: Scenario, seed: int):
    """The swing-bias fit after a whole run of the scenario, and the run's attitude at its start."""
    pipeline = AlignmentPipeline(SWING_BIAS, scenario.site, scenario.rate_hz, scenario.grade.datasheet())
    for chunk in simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, scenario.duration_s,
                          seed):
        pipeline.process(chunk.t, chunk.dtheta, chunk.dv)
    return pipeline.coarse.swing_bias, scenario.motion.attitude(np.array([0.0]))[0]


def test_on_a_swinging_base_the_bias_and_the_earth_axis_come_out_as_simulated() -> None:
    scenario = get_scenario("seed000-swing")
    fit, C_b_n0 = _fitted(scenario, 3)
    nabla_ug = fit.nabla / UG_TO_MS2
    assert np.abs(nabla_ug - np.asarray(scenario.errors.acc_bias_ms2) / UG_TO_MS2).max() < 5.0   # of 50 µg
    w_true = C_b_n0.T @ np.array([0.0, np.cos(scenario.site.lat), np.sin(scenario.site.lat)])
    assert np.degrees(np.arccos(np.clip(fit.earth_axis_b0() @ w_true, -1.0, 1.0))) < 0.5


def test_on_a_static_base_the_data_say_nothing_of_the_bias_and_nothing_changes() -> None:
    scenario = replace(get_scenario("static"), duration_s=200.0)
    fit, _ = _fitted(scenario, 1)
    assert np.abs(fit.nabla / UG_TO_MS2).max() < 5.0    # the prior's 0, not the simulated 50 µg
    with_fit, plain = run_once(scenario, 1, SWING_BIAS), run_once(scenario, 1, PLAIN)
    assert np.abs(with_fit.phi_deg - plain.phi_deg)[with_fit.t >= 30].max() < 2e-4


def test_the_slow_heading_transient_of_a_swinging_bias_is_gone_and_the_limit_stays() -> None:
    """Biases alone (no noise), seed-000 swing: without the fit the heading is still 0.0015° (STD) on the move
    between 101 and 200 s and 0.0033° above the limit; with it, it sits on the limit."""
    scenario = get_scenario("seed000-swing")
    scenario = replace(scenario, errors=scenario.errors.only("systematic"))
    plain, fitted = (window_stats([run_once(scenario, 0, c)], (101.0, 200.0)) for c in (PLAIN, SWING_BIAS))
    assert plain.heading_inwindow_std > 0.001 and plain.heading_mean > 0.002
    assert fitted.heading_inwindow_std < 2e-4 and abs(fitted.heading_mean) < 5e-4
    assert abs(fitted.level_east_mean) < 1e-4 and abs(fitted.level_north_mean) < 5e-4


@pytest.mark.parametrize("scale", [0.0, 1e-300])
def test_degenerate_data_leave_alpha_finite_and_unchanged_where_the_fit_says_nothing(scale: float) -> None:
    """No specific force at all (a log of zeros), or next to none (1e-300 m/s): the Earth axis is undefined,
    the fit takes nothing out of α, and nothing warns (a replay of such a log stopped in the eigen-solve)."""
    import warnings
    fit = SwingBias(0.55, 50 * UG_TO_MS2, 3.5e-5)
    elapsed = 0.1 * np.arange(1, 31)
    alpha = scale * np.ones((30, 3))
    q = np.tile([1.0, 0.0, 0.0, 0.0], (30, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        corrected = np.concatenate([fit.correct(elapsed[k:k + 10], alpha[k:k + 10], q[k:k + 10])
                                    for k in range(0, 30, 10)])
    assert np.isfinite(corrected).all()
    if scale == 0.0:
        assert (corrected == 0.0).all() and fit.earth_axis_b0() is None

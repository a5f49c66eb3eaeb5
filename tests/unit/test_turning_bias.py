"""What an accelerometer bias seen through a turning body does to the coarse fit (service/align/turning_bias.py),
and the swing-bias fit holding once the body has turned (service/align/swing_bias.py).

GIVEN a body at a fixed site, level, its attitude C_b^{b0} exact, WHEN it stays still, THEN the σ term is nil (the
bias limit already holds a still body's bias); WHEN it turns about the vertical at ω with ωT small, THEN the heading
term is ω b / (g Ω cos L), the Earth-rate signal the turning bias mimics; the sums do not depend on how the
observations come in calls. GIVEN a body turning at 0.2°/s, THEN the swing-bias fit takes no observation after
15° of turn, and its estimate stays what it was.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG, UG_TO_MS2, quat_from_dcm
from sinsalign.service.align.earth import OMEGA_IE, C_n_n0_fixed
from sinsalign.service.align.swing_bias import TURNED_DEG, SwingBias
from sinsalign.service.align.turning_bias import TurningBiasTerm

LAT, GRAVITY = 45.0 * DEG, 9.8
BIAS = 50.0 * UG_TO_MS2
OBS_S = 0.1


def turning(rate_deg_s: float, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Observation times (s) and C_b^{b0} (quaternions) of a level body, b0 = n0 (ENU), turning about Up."""
    t = OBS_S * np.arange(1, round(duration_s / OBS_S) + 1)
    angle = rate_deg_s * DEG * t
    c, s = np.cos(angle), np.sin(angle)
    zero, one = np.zeros_like(t), np.ones_like(t)
    about_up = np.stack((np.stack((c, -s, zero), -1), np.stack((s, c, zero), -1), np.stack((zero, zero, one), -1)),
                        axis=1)
    return t, np.array([quat_from_dcm(C) for C in C_n_n0_fixed(LAT, t) @ about_up])


def term_after(rate_deg_s: float, duration_s: float, split: int | None = None) -> TurningBiasTerm:
    t, q = turning(rate_deg_s, duration_s)
    term = TurningBiasTerm(LAT, GRAVITY)
    step = split or len(t)
    for k in range(0, len(t), step):
        term.observe(t[k:k + step], q[k:k + step])
    return term


def test_a_still_body_adds_nothing_to_sigma():
    heading2, level2 = term_after(0.0, 600.0).variances(600.0, np.eye(3), BIAS)
    bias_limit_heading = math.tan(LAT) * BIAS / GRAVITY
    assert math.sqrt(heading2) < 1e-3 * bias_limit_heading and math.sqrt(level2) < 1e-3 * BIAS / GRAVITY


def test_a_slow_turn_reads_as_the_earth_rate_signal():
    rate = 0.02   # °/s: 2.4° over the two minutes
    heading2, _ = term_after(rate, 120.0).variances(120.0, np.eye(3), BIAS)
    expected = rate * DEG * BIAS / (GRAVITY * OMEGA_IE * math.cos(LAT))
    assert math.sqrt(heading2) == pytest.approx(expected, rel=0.05)


def test_a_record_between_observations_takes_the_sums_of_its_time():
    whole = term_after(0.2, 200.0)
    at_100 = term_after(0.2, 100.0)
    assert whole.variances(100.04, np.eye(3), BIAS) == at_100.variances(100.04, np.eye(3), BIAS)


@pytest.mark.parametrize("split", [1, 7, 500])
def test_the_sums_do_not_depend_on_the_calls(split):
    whole, parts = term_after(0.2, 300.0), term_after(0.2, 300.0, split)
    assert whole.variances(300.0, np.eye(3), BIAS) == parts.variances(300.0, np.eye(3), BIAS)


def test_the_swing_bias_fit_holds_once_the_body_has_turned():
    """Data that the fit would read as a bias change nothing once the body has turned 15°, and do before."""
    rate = 0.2
    t, q = turning(rate, 300.0)
    alpha = GRAVITY * t[:, None] * np.array([0.0, 0.0, 1.0])   # the mean up: b0's third axis
    skewed = alpha + 0.01 * t[:, None] ** 2 * np.array([1.0, 0.0, 0.0])

    def fitted(from_deg: float) -> SwingBias:
        fit = SwingBias(LAT, BIAS, 3.5e-5)
        fit.correct(t, np.where((rate * t >= from_deg)[:, None], skewed, alpha), q)
        return fit

    plain, late, early = fitted(1e9), fitted(TURNED_DEG + 0.5), fitted(TURNED_DEG - 5.0)
    assert plain.held and late.held
    assert np.array_equal(late.params, plain.params) and np.array_equal(late.normal, plain.normal)
    assert not np.array_equal(early.params, plain.params)

"""Transfer alignment of a MEMS slave against a master whose attitude carries flexure and vibration.

GIVEN the ``transfer-mems`` scenario (a 100-300°/h, 1-10 mg slave stating its grade, a master at 0.15° and
0.1 m/s, a lever arm the slave does not know, straight driving then ±30° rolls), THEN phase 1 hands over inside
the filter's linear range, the Kalman stage estimates the biases and the lever arm, the heading is within 0.15°
from 40 s, every axis within 0.1° and the mounting within 0.12° after the rolls, and nothing is converged beyond
3σ. Two seeds by default, 20 under ``-m slow``.
"""
import numpy as np
import pytest
from sinsalign.service.modes.kalman import KalmanMode
from sinsalign.tools.evaluate import monte_carlo, nearest_epoch
from sinsalign.tools.evaluate_aided import fine_honesty
from sinsalign.tools.evaluate_transfer import (
    EARLY_S,
    LATE_FROM_S,
    SETTLED_FROM_S,
    converged_beyond_3sigma_any_axis,
    rms_at,
    straight_heading_limit_deg,
    worst_at,
)
from sinsalign.tools.sim.motion import AngleProfile, Sinusoid
from sinsalign.tools.sim.scenarios import MasterSpec, get_scenario
from sinsalign.tools.sim.transfer_field import TRANSFER_SITE
from sinsalign.tools.sim.vehicle import VehicleMotion


def assert_poor_slave(runs) -> None:
    for r in runs:
        assert r.phases == ("coarse", "fine", "aligned"), r.phases
        assert np.abs(r.phi_deg[r.t >= LATE_FROM_S, 2]).max() <= 0.15
        settled = r.t > SETTLED_FROM_S
        assert np.abs(r.phi_deg[settled]).max() <= 0.1
        assert np.abs(r.mount_phi_deg[settled]).max() <= 0.12
    assert converged_beyond_3sigma_any_axis(runs) == 0
    assert fine_honesty(runs, 10.0).inside_2sigma >= 0.9


@pytest.fixture(scope="module")
def two_seeds():
    return monte_carlo("transfer-mems", [0, 1], progress=False)


def test_a_mems_slave_hands_over_and_aligns_within_a_tenth_of_a_degree(two_seeds):
    assert_poor_slave(two_seeds)


@pytest.mark.parametrize("t_s", [20.0, 25.0])
def test_after_a_stalled_hand_over_the_heading_sigma_is_the_data_s_limit_while_driving_straight(two_seeds, t_s):
    """The Kalman stage runs over the data from the first master epoch: before the rolls its heading σ (without the
    reported margin) is within 1.5 times the Cramér-Rao bound of the lateral velocity, and the error within 3σ.
    Started from phase 1's answer instead, the filter's σ is 2.6° at 20 s on seed 1 where the bound is 0.3°."""
    scenario = get_scenario("transfer-mems")
    k = nearest_epoch(two_seeds, t_s)
    for r in two_seeds:
        limit = straight_heading_limit_deg(scenario.for_seed(r.seed).motion.vehicle, scenario.master, t_s)
        sigma = r.heading_sigma_deg[k] / KalmanMode.sigma_margin
        assert sigma <= 1.5 * limit, (r.seed, sigma, limit)
        assert abs(r.phi_deg[k, 2]) <= 3.0 * r.heading_sigma_deg[k]


def test_without_the_lever_arm_states_the_unknown_lever_arm_tilts_the_estimate():
    """The test above can fail: the same seeds with the lever arm taken as configured (zero) miss the level."""
    runs = monte_carlo("transfer-mems", [0, 1], {"aiding": {"master": {"lever_sigma_m": 0.0}}}, progress=False)
    assert max(np.abs(r.phi_deg[r.t > SETTLED_FROM_S]).max() for r in runs) > 0.1


@pytest.mark.slow
def test_a_mems_slave_on_20_seeds():
    assert_poor_slave(monte_carlo("transfer-mems", range(20), progress=False))


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="in the first seconds of straight driving the mount's yaw rests on the "
                   "speed's curvature alone, and phase 1 reports until it stalls (10-19 s): 5.1-17.5° at 5 s on 6 of "
                   "20 seeds (σ says so), within 5.9° from 7 s and 3.5° from 10 s; on seed 11 no estimator can have a "
                   "σ below 9° at 5 s (straight_heading_limit_deg)")
def test_a_mems_slave_keeps_the_heading_within_5_degrees_while_driving_straight():
    runs = monte_carlo("transfer-mems", range(20), progress=False)
    early = runs[0].t >= EARLY_S[0]
    early &= runs[0].t <= EARLY_S[1]
    assert max(np.abs(r.phi_deg[early, 2]).max() for r in runs) <= 5.0


@pytest.mark.slow
def test_the_good_slave_keeps_its_figures_with_the_early_hand_over_on_100_seeds():
    """Seed 002 (a 10°/h slave, a 0.001° master): every axis within 0.1° at 10 s on each of 100 seeds, RMS at 60 s
    within 0.005° per axis, the heading inside 2σ from 10 s 90 % of the time."""
    runs = monte_carlo("seed002", range(100), progress=False)
    assert worst_at(runs, 10.0) <= 0.1
    assert rms_at(runs, 60.0).max() <= 0.005
    assert fine_honesty(runs, 10.0).inside_2sigma >= 0.9


def test_the_heading_bound_while_driving_straight_rests_on_the_speed_curvature():
    """A steady speed tells nothing of the heading; doubling the speed's swing halves the bound; a longer run
    tightens it."""
    site, master = TRANSFER_SITE, MasterSpec(att_noise_deg=0.15, vel_noise_mps=0.1)

    def bound(speed: AngleProfile, t_s: float = 5.0) -> float:
        return straight_heading_limit_deg(VehicleMotion(site, 10.0, speed=speed), master, t_s)

    assert bound(AngleProfile(14.0)) > 1e3
    swing = AngleProfile(14.0, sinusoids=(Sinusoid(2.0, 0.1, 0.0),))
    wider = AngleProfile(14.0, sinusoids=(Sinusoid(4.0, 0.1, 0.0),))
    assert bound(wider) == pytest.approx(bound(swing) / 2.0, rel=1e-9)
    assert bound(swing, 10.0) < bound(swing, 5.0) / 1.5

"""Transfer alignment's hand-over from phase 1 to the Kalman stage, on a good slave with a large accelerometer bias.

GIVEN seed 002's slave (10°/h, 5 mg, mounted 20° off on every axis) whose first wing rock comes at 5 s instead of
1 s, against seed 002's master or a perfect one (no noise, stated at the configuration's smallest figures), WHEN
phase 1 hands over in the first roll, THEN no converged epoch is beyond 3σ on any axis and every axis is within
0.1° at 10 s, on seeds no other test runs.

Phase 1's velocity pairs take the accelerometer bias for a tilt (0.29° for 5 mg). Started from phase 1's answer,
the filter was 0.36° off in level at 10 s (within its σ); the Kalman stage now runs over the data from the first
master epoch with bias states from the start (0.035° worst of 20 seeds). With a perfect master its bias states
act through the attitude at the middle of each control step: through the step's end, one record per run in 13
was 3.4-3.8σ off in level as the body rolled.
"""
from dataclasses import replace

import numpy as np
import pytest
from sinsalign.tools.sim.scenarios import MasterSpec, get_scenario, seed002_flight
from support.aided_runs import errors_deg, run_transfer

MASTERS = {
    "seed002": (MasterSpec(), {}),
    "perfect": (MasterSpec(att_noise_deg=0.0, vel_noise_mps=0.0),
                {"aiding": {"master": {"att_std_deg": 1e-6, "vel_std_mps": 1e-4}}}),
}


def late_rock_errors(master: str, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, φ (N, 3) deg, heading σ, level σ, converged) of a 20-s run with the first rock at 5 s."""
    spec, overrides = MASTERS[master]
    scenario = replace(get_scenario("seed002"), motion=seed002_flight(first_rock_s=5.0), duration_s=20.0,
                       master=spec)
    records, _ = run_transfer(scenario, seed=seed, overrides=overrides)
    t, phi = errors_deg(scenario.for_seed(seed), records)
    sigma = np.array([(r.heading_sigma_deg, r.level_sigma_deg) for r in records])
    return t, phi, sigma[:, 0], sigma[:, 1], np.array([r.converged for r in records])


def check(master: str, seeds: range) -> None:
    for seed in seeds:
        t, phi, heading_sigma, level_sigma, converged = late_rock_errors(master, seed)
        beyond = converged & ((np.abs(phi[:, 2]) > 3.0 * heading_sigma)
                              | (np.abs(phi[:, :2]).max(axis=1) > 3.0 * level_sigma))
        assert not beyond.any(), f"seed {seed}: converged beyond 3σ at t = {t[beyond]}"
        k10 = int(np.argmin(np.abs(t - 10.0)))
        assert converged[k10] and np.abs(phi[k10]).max() <= 0.1, f"seed {seed}: {phi[k10]} at 10 s"


@pytest.mark.parametrize("master", MASTERS)
def test_a_hand_over_in_the_first_roll_is_honest_and_within_a_tenth_at_10_s(master):
    check(master, range(200, 206))


@pytest.mark.slow
@pytest.mark.parametrize("master", MASTERS)
def test_twenty_unseen_seeds(master):
    check(master, range(206, 226))

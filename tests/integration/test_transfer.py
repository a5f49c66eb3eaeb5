"""Transfer alignment against a master INS (seed 002, dual model) through the streaming pipeline.

GIVEN a slave IMU bolted 20°/20°/20° (or other mountings) off a master INS on a vehicle flying north
with wing rocks, WHEN the transfer pipeline runs its large-angle phase 1 and then the Kalman stage
with velocity and attitude matching, THEN with exact sensors the slave's attitude and the mounting
are exact whatever the mounting, the noisy run meets the issue's bounds and beats phase 1 alone, σ
is honest, a master stream with faults is counted and survived, a stream in pieces gives the bits
of one chunk, and a master log replays.
"""
import json
from dataclasses import replace

import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.service.config import config_from_mapping
from sinsalign.tools.replay import replay
from sinsalign.tools.sim.aiding import master_epochs, write_master_log
from sinsalign.tools.sim.files import write_simulation
from sinsalign.tools.sim.scenarios import get_scenario, seed002_flight
from support.aided_runs import errors_deg, run_transfer


def mounting_error_deg(scenario, pipeline):
    return misalignment(pipeline.mode.mounting()[0], scenario.motion.mounting) / DEG


@pytest.mark.parametrize("mount_deg", [(20.0, 20.0, 20.0), (-20.0, 20.0, -20.0), (10.0, 0.0, 33.0),
                                       (60.0, -45.0, 120.0)])
def test_exact_sensors_give_the_exact_attitude_and_mounting_whatever_the_mounting(mount_deg):
    scenario = replace(get_scenario("seed002-ideal"), motion=seed002_flight(mount_deg))
    records, pipeline = run_transfer(scenario)
    t, phi = errors_deg(scenario, records)
    assert np.abs(phi[t >= 10.0]).max() < 1e-4                 # the issue: < 1e-4° at 60 s
    assert np.abs(mounting_error_deg(scenario, pipeline)).max() < 1e-4
    assert records[-1].phase == "aligned"


def test_the_noisy_run_meets_the_issue_bounds_and_beats_phase_1_alone():
    scenario = get_scenario("seed002")
    records, pipeline = run_transfer(scenario, seed=3)
    t, phi = errors_deg(scenario.for_seed(3), records)
    at = {s: np.abs(phi[int(np.argmin(np.abs(t - s)))]) for s in (10.0, 60.0)}
    assert at[10.0].max() < 0.05 and at[60.0].max() < 0.01    # the RMS bound over 20 seeds is 0.005°
    assert np.abs(mounting_error_deg(scenario.for_seed(3), pipeline)).max() < 0.01
    single, _ = run_transfer(scenario, seed=3, overrides={"fine": {"enabled": False}})
    _, phi_single = errors_deg(scenario.for_seed(3), single)
    assert np.abs(phi_single[-1]).max() > 5 * at[60.0].max()   # one model alone: the biases stay in


def test_the_seed_switch_at_10_s_is_an_option():
    scenario = replace(get_scenario("seed002"), duration_s=20.0)
    records, _ = run_transfer(scenario, overrides={"aiding": {"master": {"handover_s": 10.0}}})
    assert {r.phase for r in records[:9]} == {"coarse"} and records[-1].phase in ("fine", "aligned")


def test_sigma_is_honest_over_seeds():
    scenario = replace(get_scenario("seed002"), duration_s=30.0)
    ratios = []
    for seed in range(1, 7):
        records, _ = run_transfer(scenario, seed=seed)
        t, phi = errors_deg(scenario.for_seed(seed), records)
        sigma = np.array([r.heading_sigma_deg for r in records])
        level_sigma = np.array([r.level_sigma_deg for r in records])
        converged = np.array([r.converged for r in records])
        assert not (converged & (np.abs(phi[:, 2]) > 3.0 * sigma)).any()
        assert not (converged & (np.abs(phi[:, :2]).max(axis=1) > 3.0 * level_sigma)).any()
        ratios.append(np.abs(phi[t >= 10.0, 2]) / sigma[t >= 10.0])
    ratios = np.concatenate(ratios)
    assert np.mean(ratios <= 2.0) >= 0.9 and np.median(ratios) > 0.3


def test_a_1_hz_master_gives_one_pair_set_and_one_update_per_epoch_and_an_honest_sigma():
    """A master INS at 1 Hz instead of 10 (``sinsalign eval seed002-rates``): its 1-s intervals are no gaps, the
    observations before its first epoch await it, phase 2 takes one velocity and one attitude update per epoch after
    the first (not one per 0.1-s step), σ stays honest, and slave and mounting are right (seeds 1-3 measured: slave
    at most 0.017° from 30 s (0.0094° at 10 Hz), mounting 0.015°, |error| at most 1.58 heading σ and 1.8 level σ
    from 10 s)."""
    scenario = get_scenario("seed002").with_aid_rate(1.0)
    for seed in (1, 2, 3):
        records, pipeline = run_transfer(scenario, seed=seed)
        counters = pipeline.aiding_counters()
        assert counters["master_observations_awaiting_aid"] == 9 and counters["master_unaided_observations"] == 0
        t, phi = errors_deg(scenario.for_seed(seed), records)
        # the Kalman stage starts at the first epoch (1 s: nine observations awaited it) and runs over every later one
        epochs_after_the_first = round(t[-1]) - 1
        for name in ("master_vel", "master_att"):
            assert counters[f"{name}_accepted"] + counters.get(f"{name}_rejected", 0) == epochs_after_the_first
        sigma = np.array([r.heading_sigma_deg for r in records])
        level_sigma = np.array([r.level_sigma_deg for r in records])
        assert (np.abs(phi[t >= 10.0, 2]) <= 3.0 * sigma[t >= 10.0]).all()
        assert (np.abs(phi[t >= 10.0, :2]).max(axis=1) <= 3.0 * level_sigma[t >= 10.0]).all()
        assert np.abs(phi[t >= 30.0]).max() < 0.05 and np.abs(mounting_error_deg(scenario, pipeline)).max() < 0.05


def test_the_rate_table_runs_on_a_short_seed():
    from sinsalign.tools.evaluate_transfer import rate_table
    text, runs = rate_table([1], progress=False, rates_hz=(1.0,), duration_s=12.0)
    assert "| 1 Hz |" in text and "| 0 | 9 / 0 |" in text and len(runs["1 Hz"]) == 1


def test_a_master_stream_that_stops_repeats_and_comes_late_is_counted_and_survived():
    scenario = get_scenario("seed002")
    faults = {"dropout_s": (30.0, 35.0), "repeated": 20, "late_s": 0.2}
    late = {"aiding": {"master": {"latency_s": 0.2}}}
    records, pipeline = run_transfer(scenario, seed=2, overrides=late, faults=faults)
    _, phi = errors_deg(scenario.for_seed(2), records)
    counters = pipeline.aiding_counters()
    assert counters["master_unaided_observations"] >= 50                 # 5 s of 10-Hz observations
    sigma = np.array([r.heading_sigma_deg for r in records])
    assert sigma[34] > sigma[29]                                         # σ grows without the master
    assert np.abs(phi[-1]).max() < 0.01 and records[-1].phase == "aligned"


def test_a_stream_one_sample_at_a_time_gives_the_same_bits_as_one_chunk():
    """Phase 1's pairs come from row-wise products (a BLAS product's last bits depend on how many rows it has,
    on some CPUs), so a sample at a time gives the bits of one chunk."""
    scenario = replace(get_scenario("seed002"), duration_s=4.0)
    whole, _ = run_transfer(scenario)
    pieces, _ = run_transfer(scenario, piece=1)
    assert len(whole) == 4 and whole[-1].phase in ("fine", "aligned")
    assert [r.to_json() for r in whole] == [r.to_json() for r in pieces]


def test_phase_1_records_inside_a_control_step_are_the_same_live_as_in_one_chunk():
    """GIVEN output epochs that fall inside a 0.5-s control step (fine stage off: phase 1 throughout), THEN a
    stream 7 samples at a time gives the same records as one chunk: the record computed on a scratch copy of the
    grouped solver folds into the copy's groups, not the pipeline's (before, it folded the pairs twice)."""
    scenario = replace(get_scenario("seed002"), duration_s=6.0)
    overrides = {"fine": {"enabled": False, "control_interval_s": 0.5}, "output": {"period_s": 0.2}}
    whole, _ = run_transfer(scenario, overrides=overrides)
    pieces, _ = run_transfer(scenario, overrides=overrides, piece=7)
    assert len(whole) == 30 and [r.to_json() for r in whole] == [r.to_json() for r in pieces]


def test_a_master_log_replays_with_the_noise_it_states(tmp_path):
    scenario = replace(get_scenario("seed002-ideal"), duration_s=12.0)
    files = write_simulation(scenario, 1, tmp_path)
    log = write_master_log(tmp_path / "master.csv", master_epochs(scenario, 1), 0.001, 0.005)
    replay(files.imu_csv, tmp_path / "out.jsonl", config_from_mapping({}), progress=False, aids={"master": str(log)})
    rows = [json.loads(line) for line in (tmp_path / "out.jsonl").read_text().splitlines()]
    t = np.array([r["t"] for r in rows])
    phi = misalignment(dcm_from_quat(np.array([r["q"] for r in rows])), scenario.motion.attitude(t)) / DEG
    assert len(rows) == 12 and np.abs(phi[t >= 2.0]).max() < 1e-3


def test_the_lever_arm_from_the_master_to_the_slave_is_compensated():
    """The slave 2.3 m from the master's point (master axes 1, 2, −0.5 m): the master reports the velocity of
    its own point, which differs by C_bm^n (ω × l) in the wing rocks (0.4 m/s). Configured, or left unconfigured
    for the filter's lever-arm states to find from the first epoch, it is compensated (0.028° from 10 s); taken as
    known and left at zero, it is not (0.22°)."""
    scenario = replace(get_scenario("seed002"), motion=seed002_flight(lever_m=(1.0, 2.0, -0.5)))
    worst = {}
    for name, master in (("configured", {"lever_m": [1.0, 2.0, -0.5]}), ("estimated", {}),
                         ("ignored", {"lever_sigma_m": 0.0})):
        records, _ = run_transfer(scenario, overrides={"aiding": {"master": master}})
        t, phi = errors_deg(scenario.for_seed(1), records)
        worst[name] = np.abs(phi[t >= 10.0]).max()
    assert max(worst["configured"], worst["estimated"]) < 0.05 < 0.15 < worst["ignored"]


def test_a_rough_nominal_mounting_gives_the_slave_an_attitude_until_phase_1_has_resolved_it():
    scenario = replace(get_scenario("seed002"), duration_s=4.0)
    config = {"output": {"period_s": 0.2}}
    nominal, _ = run_transfer(scenario, overrides={**config, "aiding": {"master": {"mount_deg": [21.0, 19.0, 20.5],
                                                                                   "mount_sigma_deg": 2.0}}})
    bare, _ = run_transfer(scenario, overrides=config)
    t, phi = errors_deg(scenario.for_seed(1), nominal)
    _, phi_bare = errors_deg(scenario.for_seed(1), bare)
    early = t <= 0.8                                            # before the first wing rock resolves the mounting
    assert np.abs(phi[early]).max() < 3.0 < np.abs(phi_bare[early]).max()
    assert all(r.heading_sigma_deg == pytest.approx(2.0, abs=0.01) for r, e in zip(nominal, early, strict=True) if e)
    late = t >= 3.0                                             # then the fit's, as without it
    assert np.abs(phi[late] - phi_bare[late]).max() < 1e-9

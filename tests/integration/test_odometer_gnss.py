"""A land vehicle with an odometer and a GNSS receiver (seed003-odo-gnss) through the streaming pipeline.

GIVEN the seed-003 drive with a 100-Hz odometer and a 10-Hz receiver whose antenna sits 1 m from the IMU,
WHEN the combined mode runs its GNSS coarse stage (with the odometer's velocity pairs) and then the Kalman
filter with both, THEN with exact sensors the heading is exact from the first seconds on only because both lever
arms are compensated, each fix gives two pairs, a stream in pieces gives the bits of one chunk, two logs replay
to the bits of the same run in memory, and either order of the aids selects the mode.
"""
import json
from dataclasses import replace

import numpy as np
from sinsalign.service.aiding import AidingFeed, AidingTrack, aid_rows
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.service.config import config_from_mapping
from sinsalign.service.modes.odometer_gnss import OdometerGnss
from sinsalign.service.pipeline import build_pipeline
from sinsalign.tools.evaluate import run_once
from sinsalign.tools.replay import replay
from sinsalign.tools.sim.aiding import scenario_aids, with_gnss_faults
from sinsalign.tools.sim.files import write_simulation
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import get_scenario
from support.aided_runs import errors_deg

ODO_LEVER_M = (0.4, -1.2, -0.5)
"""An odometer (a wheel) away from the IMU: the lever arm the velocity pairs and the filter must take off."""


def run_both(scenario, seed=1, piece=None, aiding=None, config=None, outage_s=None):
    """(records, pipeline) of the combined mode over a simulated seed, the sensors' lever arms configured unless
    ``aiding`` says otherwise; samples ``piece`` at a time (None: a chunk at once)."""
    scenario = scenario.for_seed(seed)
    aids = {aid.kind: aid for aid in scenario_aids(scenario, seed)}
    aiding = {"gnss": {"lever_m": list(scenario.gnss.lever_b), **(aiding or {}).get("gnss", {})},
              "odo": {"lever_m": list(scenario.odometer.lever_b), **(aiding or {}).get("odo", {})}}
    mapping = {**(config or {}), "aiding": aiding}
    pipeline = build_pipeline(config_from_mapping(mapping), scenario.site, scenario.rate_hz,
                              scenario.grade.datasheet(), ["odo", "gnss"])
    gnss = with_gnss_faults(aids["gnss"].epochs, outage_s=outage_s)
    feeds = {"odo": AidingFeed(AidingTrack.for_kind("odo"), iter([aids["odo"].epochs])),
             "gnss": AidingFeed(AidingTrack.for_kind("gnss"), iter([gnss]))}
    records = []
    for chunk in simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, scenario.duration_s, seed):
        step = piece or len(chunk.t)
        for k in range(0, len(chunk.t), step):
            s = slice(k, k + step)
            records += pipeline.process(chunk.t[s], chunk.dtheta[s], chunk.dv[s],
                                        aid_rows(feeds, pipeline.aid_kinds, chunk.t[s]))
    return records, pipeline


def ideal(duration_s: float):
    scenario = replace(get_scenario("seed003-odo-gnss-ideal"), duration_s=duration_s)
    return replace(scenario, odometer=replace(scenario.odometer, lever_b=ODO_LEVER_M))


def test_either_order_of_the_aids_selects_the_combined_mode_with_the_fix_first():
    config = config_from_mapping({})
    scenario = get_scenario("seed003-odo-gnss")
    for aids in (["odo", "gnss"], ["gnss", "odo"]):
        pipeline = build_pipeline(config, scenario.site, 100.0, None, aids)
        assert isinstance(pipeline.mode, OdometerGnss) and pipeline.aid_kinds == ("gnss", "odo")
        assert pipeline.aid_width == 9 and pipeline.stages_text() == "gnss+odo-aided alignment"


def test_exact_sensors_give_the_exact_heading_within_seconds_with_both_lever_arms_and_not_without():
    """The velocity pairs hold the heading from the first fixes (VIF alone needs the drive's accelerations: tens of
    degrees off before its first turn); both lever arms matter: the antenna's 1 m and the wheel's 1.4 m."""
    scenario = ideal(40.0)
    records, pipeline = run_both(scenario, aiding={"gnss": {"handover_s": 20.0}})
    t, phi = errors_deg(scenario, records)
    assert np.abs(phi[t >= 2.0]).max() < 0.001
    assert [r.phase for r in records][-1] == "aligned" and records[10].phase == "coarse"
    counters = pipeline.aiding_counters()
    assert counters["odo_accepted"] > 150 and counters["gnss_vel_accepted"] > 150   # 20 s of 10-Hz updates each
    _, wrong_wheel = errors_deg(scenario, run_both(scenario, aiding={"odo": {"lever_m": [0.0, 0.0, 0.0]}})[0])
    _, wrong_antenna = errors_deg(scenario, run_both(scenario, aiding={"gnss": {"lever_m": [0.0, 0.0, 0.0]}})[0])
    assert np.abs(wrong_wheel[t >= 2.0, 2]).max() > 0.004 and np.abs(wrong_antenna[t >= 2.0, 2]).max() > 0.004


def test_each_fix_gives_a_velocity_integration_pair_and_a_velocity_pair():
    records, pipeline = run_both(ideal(5.0), aiding={"gnss": {"handover_s": 100.0}})
    assert records[-1].n_obs == 2 * 50 and pipeline.coarse.solver.rejected == 0   # 50 fixes in 5 s, none screened


def test_a_stream_one_sample_at_a_time_gives_the_same_bits_as_one_chunk_through_both_stages():
    """Output epochs between observations (period 0.25 s) take the scratch path with both pairs due; the filter
    starts at 3 s and takes the odometer's and the receiver's epochs at their own rates."""
    scenario = replace(get_scenario("seed003-odo-gnss"), duration_s=6.0)
    config = {"output": {"period_s": 0.25}}
    whole, _ = run_both(scenario, aiding={"gnss": {"handover_s": 3.0}}, config=config)
    pieces, _ = run_both(scenario, piece=1, aiding={"gnss": {"handover_s": 3.0}}, config=config)
    odd, _ = run_both(scenario, piece=37, aiding={"gnss": {"handover_s": 3.0}}, config=config)
    assert len(whole) == 24 and whole[-1].phase in ("fine", "aligned")
    assert [r.to_json() for r in whole] == [r.to_json() for r in pieces] == [r.to_json() for r in odd]


def test_an_odometer_log_and_a_gnss_log_replay_to_the_bits_of_the_run_in_memory(tmp_path):
    scenario = replace(get_scenario("seed003-odo-gnss"), duration_s=40.0)
    files = write_simulation(scenario, 2, tmp_path)
    replay(files.imu_csv, tmp_path / "out.jsonl", config_from_mapping({}), progress=False,
           aids={"gnss": str(files.gnss_csv), "odo": str(files.odo_csv)})
    rows = [json.loads(line) for line in (tmp_path / "out.jsonl").read_text().splitlines()]
    offline = run_once(scenario, 2, config_from_mapping({}))
    t = np.array([r["t"] for r in rows])
    phi = misalignment(dcm_from_quat(np.array([r["q"] for r in rows])), scenario.motion.attitude(t)) / DEG
    assert len(rows) == 40 and rows[-1]["phase"] == "aligned"
    assert np.allclose(phi, offline.phi_deg, atol=1e-6)   # the logs hold the values to 12 significant digits


def test_a_gnss_outage_in_the_filter_is_carried_by_the_odometer_and_sigma_stops_shrinking():
    scenario = replace(get_scenario("seed003-odo-gnss"), duration_s=70.0)
    clean_records, clean = run_both(scenario, aiding={"gnss": {"handover_s": 20.0}})
    records, pipeline = run_both(scenario, aiding={"gnss": {"handover_s": 20.0}}, outage_s=(40.0, 60.0))
    t, phi = errors_deg(scenario, records)
    sigma = np.array([r.heading_sigma_deg for r in records])
    clean_sigma = np.array([r.heading_sigma_deg for r in clean_records])
    at = {s: int(np.flatnonzero(t == s)[0]) for s in (40.0, 59.0, 70.0)}
    # without the fixes the heading rests on the gyros and the odometer: σ holds where the clean run's shrinks
    assert 0.9 * sigma[at[40.0]] < sigma[at[59.0]] and clean_sigma[at[59.0]] < 0.9 * sigma[at[59.0]]
    assert all(r.phase == "aligned" for r in records[at[40.0]:])
    assert abs(phi[at[59.0], 2]) < 3 * sigma[at[59.0]] and abs(phi[at[70.0], 2]) < 0.05
    counters = pipeline.aiding_counters()
    assert counters["gnss_vel_rejected"] == 0 and counters["gnss_pos_rejected"] <= 1   # the fixes rejoin the filter
    assert counters["gnss_vel_accepted"] == clean.aiding_counters()["gnss_vel_accepted"] - 200   # 20 s of fixes

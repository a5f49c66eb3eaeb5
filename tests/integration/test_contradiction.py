"""Estimates that contradict their σ restart the alignment (service/align/consistency.py).

GIVEN a swinging base whose IMU lost 1 or 4 samples (5 or 20 ms) at 100 s without a trace in the time stamps the
pipeline sees (no gate: a sensor that drops a frame and stamps on), WHEN it is aligned, THEN the estimates after the
gap contradict the converged ones before it, the alignment restarts within 10 s of the gap and says why, no record
is converged while further off the truth than the check allows (2 K σ: 0.5° at σ 0.05°), and the alignment after
the restart converges within 3σ: without the check the missing rotation put the heading 14° off under a σ of
0.05°, reported converged; the replay of such a log says why it restarted. GIVEN the whole log, THEN nothing
restarts (the check can stay quiet).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from sinsalign.protocol.imu_log import IMU_COLUMNS, write_header, write_rows
from sinsalign.service.align.consistency import CONTRADICTION_SIGMAS, FLOOR_DEG
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.service.config import Config
from sinsalign.service.pipeline import build_pipeline
from sinsalign.tools.replay import replay
from sinsalign.tools.sim.files import log_keys
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import get_scenario

GAP_AT_S, SECONDS = 100.0, 240.0


@pytest.fixture(scope="module")
def swing():
    scenario = replace(get_scenario("seed000-swing"), duration_s=SECONDS).for_seed(3)
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, SECONDS, 3,
                        chunk_samples=10**7)
    return scenario, chunk


def aligned(swing, lost_samples: int):
    """The pipeline over the swing with ``lost_samples`` left out at :data:`GAP_AT_S`: (records, pipeline, the true
    attitudes at the records' times)."""
    scenario, chunk = swing
    keep = np.ones(len(chunk.t), bool)
    first = np.searchsorted(chunk.t, GAP_AT_S)
    keep[first:first + lost_samples] = False
    pipeline = build_pipeline(Config(), scenario.site, scenario.rate_hz, scenario.stated_datasheet())
    records = pipeline.process(chunk.t[keep], chunk.dtheta[keep], chunk.dv[keep])
    truth = chunk.C_b_n_true[np.searchsorted(chunk.t, [r.t for r in records])]
    return records, pipeline, truth


def heading_errors_deg(records, truth) -> np.ndarray:
    return np.array([abs(misalignment(dcm_from_quat(np.array(r.q)), C)[2]) / DEG
                     for r, C in zip(records, truth, strict=True)])


@pytest.mark.parametrize("lost_samples", [1, 4])
def test_samples_lost_without_a_trace_restart_the_alignment_instead_of_a_converged_heading_degrees_off(
        swing, lost_samples):
    records, pipeline, truth = aligned(swing, lost_samples)
    assert pipeline.disturbances == 1
    restart_s = float(pipeline.last_disturbance.split("t = ")[1].split(" s")[0])
    assert GAP_AT_S < restart_s <= GAP_AT_S + 10.0
    assert "the data contradict the fixed-base model" in pipeline.last_disturbance
    errors = heading_errors_deg(records, truth)
    sigma = np.array([r.heading_sigma_deg for r in records])
    converged = np.array([r.converged for r in records])
    # two estimates K σ each off the truth on either side of it: what the check lets a converged record reach
    assert (errors[converged] < FLOOR_DEG + 2.0 * CONTRADICTION_SIGMAS * sigma[converged]).all()
    assert converged[-1] and errors[-1] < 3.0 * sigma[-1]   # aligned again on the data after the gap


def test_the_whole_log_aligns_without_a_restart(swing):
    records, pipeline, truth = aligned(swing, 0)
    assert pipeline.disturbances == 0 and records[-1].converged
    assert heading_errors_deg(records[-1:], truth[-1:])[0] < 3.0 * records[-1].heading_sigma_deg


def test_replay_says_why_it_restarted(swing, tmp_path, capsys):
    """GIVEN a log whose IMU lost 4 samples at 100 s and stamped on (no gap in its time stamps for the gate to see),
    THEN the replay prints the contradiction and the restart."""
    scenario, chunk = swing
    first = np.searchsorted(chunk.t, GAP_AT_S)
    rows = np.column_stack((chunk.t, chunk.dtheta, chunk.dv))
    rows = np.concatenate((rows[:first], rows[first + 4:]))
    rows[first:, 0] -= 4 / scenario.rate_hz
    log = tmp_path / "stamped-on.csv"
    with open(log, "w", encoding="utf-8") as stream:
        write_header(stream, log_keys(scenario, 3), IMU_COLUMNS)
        write_rows(stream, rows)
    summary = replay(log, tmp_path / "out.jsonl", Config(), progress=False)
    err = capsys.readouterr().err
    assert "the data contradict the fixed-base model" in err and err.count("alignment restarted") == 1
    assert summary.gate == {} and summary.last.converged

"""The output period chooses when records are written, never what the estimators see.

GIVEN 120 s of the seed-000 swing base, WHEN the pipeline runs with output periods from one sample to two seconds
(one of them the control interval, where every epoch's sample ends a block), THEN the records at every epoch the
runs share are the same to the bit, the noise meter has seen every observation, and the compass loops have started.
"""
from __future__ import annotations

from dataclasses import replace

import pytest
from sinsalign.service.config import config_from_mapping
from sinsalign.service.pipeline import AlignmentPipeline
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import get_scenario

DURATION_S = 120.0
PERIODS_S = (0.005, 0.1, 0.25, 1.0, 2.0)


@pytest.fixture(scope="module")
def runs() -> dict[float, AlignmentPipeline]:
    scenario = replace(get_scenario("seed000-swing"), duration_s=DURATION_S)
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, DURATION_S, 1,
                        chunk_samples=round(DURATION_S * scenario.rate_hz))
    out = {}
    for period in PERIODS_S:
        pipeline = AlignmentPipeline(config_from_mapping({"output": {"period_s": period}}), scenario.site,
                                     scenario.rate_hz, scenario.grade.datasheet())
        pipeline.records = {r.t: r for r in pipeline.process(chunk.t, chunk.dtheta, chunk.dv)}
        out[period] = pipeline
    return out


@pytest.mark.parametrize("period", PERIODS_S[:-1])
def test_records_at_shared_epochs_are_the_same_whatever_the_output_period(runs, period):
    coarse = runs[PERIODS_S[-1]].records
    shared = [t for t in runs[period].records if t in coarse]
    assert len(shared) == DURATION_S / PERIODS_S[-1]
    assert [runs[period].records[t] for t in shared] == [coarse[t] for t in shared]


@pytest.mark.parametrize("period", PERIODS_S)
def test_the_noise_meter_sees_every_observation_and_the_loops_start(runs, period):
    pipeline = runs[period]
    assert pipeline.noise.steps == pipeline.coarse.solver.n_obs == round(DURATION_S / 0.1)
    assert pipeline.records[DURATION_S].phase in ("fine", "aligned")

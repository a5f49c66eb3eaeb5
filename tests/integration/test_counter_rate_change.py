"""An IMU stamped from its sample counter (a KVH: one tick a sample, stamped at ``imu.rate_hz``) that changes its
output rate mid-run, through the sample gate with the host's arrival clock (rate_check.HostPace) and the pipeline.

GIVEN the seed-000 swing aligned at the configured 200 Hz until 120.3 s, when the IMU doubles (or halves) its rate
(its counter still stamped 5 ms a sample, so every window of steps passes), and reads of 20 samples arriving 2 ms
after their newest, WHEN the host's clock shows the counter running ahead (behind), THEN the alignment stops within
0.2 s (2 s) of the change naming the new rate, and no record from 30 s on is beyond 3σ. Told only when a bucket of
reads closed (0.75 s then), the data at half their time scale were aligned for up to 1.5 s: a record `converged`
beyond 3σ.
"""
import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.service.config import config_from_mapping
from sinsalign.service.pipeline import AlignmentPipeline
from sinsalign.service.rate_check import HostPace
from sinsalign.service.sample_gate import SampleGate
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import get_scenario

CHANGE_S = 120.3
READ = 20


def outputs(chunk, start: int, stop: int, per: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The IMU's outputs from the 400-Hz simulation's samples start to stop: ``per`` increments summed each."""
    n = (stop - start) // per * per
    t = chunk.t[start + per - 1:start + n:per]
    return t, *(v[start:start + n].reshape(-1, per, 3).sum(axis=1) for v in (chunk.dtheta, chunk.dv))


@pytest.mark.parametrize(("new_hz", "within_s"), [(400.0, 0.2), (100.0, 2.0)])
def test_a_counter_stamped_imu_whose_rate_changes_stops_and_stays_honest(new_hz, within_s):
    scenario = get_scenario("seed000-swing").for_seed(1)
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, 400.0, CHANGE_S + 5.0, 1,
                        chunk_samples=10**7)
    n = int((chunk.t <= CHANGE_S + 1e-9).sum()) // 2 * 2
    before, after = outputs(chunk, 0, n, 2), outputs(chunk, n, len(chunk.t), round(400.0 / new_hz))
    t_true, dtheta, dv = (np.concatenate(pair) for pair in zip(before, after, strict=True))
    rows = np.zeros((len(t_true), 9))
    rows[:, 0] = np.arange(1, len(t_true) + 1) / 200.0   # the counter's time: 5 ms a sample whatever the rate
    rows[:, 1:4], rows[:, 4:7] = dtheta, dv
    config = config_from_mapping({})
    gate, pace = SampleGate(200.0), HostPace()
    pipeline = AlignmentPipeline(config, scenario.site, 200.0, scenario.grade.datasheet(), live=True)
    records, stop_s = [], None
    for k in range(0, len(rows), READ):
        read = rows[k:k + READ]
        ratio = pace.observe(float(read[-1, 0]), float(t_true[k + len(read) - 1]) + 0.002)
        if ratio is not None:
            gate.rate.host_pace(ratio)
        for segment in gate.admit(read):
            if segment.restart:
                stop_s = stop_s or float(t_true[k + len(read) - 1])
                pipeline = AlignmentPipeline(config, scenario.site, 200.0, scenario.grade.datasheet(), live=True)
            records += pipeline.process(segment.rows[:, 0], segment.rows[:, 1:4], segment.rows[:, 4:7])
    assert stop_s is not None and CHANGE_S < stop_s <= CHANGE_S + within_s
    assert gate.last_error.startswith(f"samples come at {new_hz:g} Hz by the host's clock")
    t_record = np.interp([r.t for r in records], rows[:, 0], t_true)   # the counter's time to the true one
    phi = misalignment(dcm_from_quat(np.array([r.q for r in records])), scenario.motion.attitude(t_record)) / DEG
    ratio = np.maximum(np.abs(phi[:, 2]) / [r.heading_sigma_deg for r in records],
                       np.abs(phi[:, :2]).max(axis=1) / [r.level_sigma_deg for r in records])
    assert not (ratio[t_record >= 30.0] > 3.0).any()

"""An IMU stamped from its sample counter (a KVH: one tick a sample, stamped at ``imu.rate_hz``) that changes its
output rate mid-run, through the sample gate with the host's arrival clock (rate_check.HostPace) and the pipeline.

GIVEN the seed-000 swing aligned at the configured 200 Hz until 120.3 s, when the IMU doubles its rate (its counter
still stamped 5 ms a sample, so every window of steps passes), and reads of 20 samples arriving 2 ms after their
newest, WHEN the host's clock shows the counter running ahead, THEN the alignment stops within 0.2 s of the change
(a read or two) naming 400 Hz, and no record from 30 s on is beyond 3σ. Told only when a 0.75-s bucket of reads
closed, the data at half their time scale were aligned for up to 1.5 s: a record `converged` beyond 3σ.
"""
import numpy as np
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.service.config import config_from_mapping
from sinsalign.service.pipeline import AlignmentPipeline
from sinsalign.service.rate_check import HostPace
from sinsalign.service.sample_gate import SampleGate
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import get_scenario

CHANGE_S = 120.3
READ = 20


def test_a_counter_stamped_imu_that_doubles_its_rate_stops_at_once_and_stays_honest():
    scenario = get_scenario("seed000-swing").for_seed(1)
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, 400.0, CHANGE_S + 5.0, 1,
                        chunk_samples=10**7)
    before = chunk.t <= CHANGE_S + 1e-9
    # the IMU's 200-Hz outputs are the 400-Hz simulation's increments summed in pairs, then its 400-Hz ones
    n = int(before.sum()) // 2 * 2
    t_true = np.concatenate((chunk.t[1:n:2], chunk.t[n:]))
    dtheta = np.concatenate((chunk.dtheta[:n].reshape(-1, 2, 3).sum(axis=1), chunk.dtheta[n:]))
    dv = np.concatenate((chunk.dv[:n].reshape(-1, 2, 3).sum(axis=1), chunk.dv[n:]))
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
    assert stop_s is not None and CHANGE_S < stop_s <= CHANGE_S + 0.2
    assert gate.last_error.startswith("samples come at 400 Hz by the host's clock")
    t_record = np.interp([r.t for r in records], rows[:, 0], t_true)   # the counter's time to the true one
    phi = misalignment(dcm_from_quat(np.array([r.q for r in records])), scenario.motion.attitude(t_record)) / DEG
    ratio = np.maximum(np.abs(phi[:, 2]) / [r.heading_sigma_deg for r in records],
                       np.abs(phi[:, :2]).max(axis=1) / [r.level_sigma_deg for r in records])
    assert not (ratio[t_record >= 30.0] > 3.0).any()

"""Shared by the aided-mode tests: a simulated seed through a pipeline with its aiding feed, and its errors."""
import numpy as np
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.tools.sim.imu import simulate


def process_simulation(pipeline, scenario, seed, feed, piece=None):
    """The records of ``pipeline`` over the simulated ``seed`` of ``scenario`` (as it runs that seed), the
    aiding values from ``feed``; the samples go in ``piece`` at a time (None: a chunk at once)."""
    records = []
    for chunk in simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, scenario.duration_s, seed):
        step = piece or len(chunk.t)
        for k in range(0, len(chunk.t), step):
            s = slice(k, k + step)
            records += pipeline.process(chunk.t[s], chunk.dtheta[s], chunk.dv[s], feed.aid_at(chunk.t[s]))
    return records


def errors_deg(scenario, records):
    """Output epochs t (N,) in s and the misalignment φ (N, 3: E, N, U) of ``records`` against the truth, degrees."""
    t = np.array([r.t for r in records])
    return t, misalignment(dcm_from_quat(np.array([r.q for r in records])), scenario.motion.attitude(t)) / DEG

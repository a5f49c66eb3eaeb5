"""Shared by the aided-mode tests: a simulated seed through a pipeline with its aiding feed, and its errors."""
import numpy as np
from sinsalign.service.aiding import AidingFeed, AidingTrack
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.service.config import config_from_mapping
from sinsalign.service.pipeline import build_pipeline
from sinsalign.tools.sim.aiding import master_epochs, with_master_faults
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


def run_transfer(scenario, seed=1, overrides=None, faults=None, piece=None):
    """(records, pipeline) of the transfer pipeline over a simulated seed (configuration ``overrides``, master
    ``faults`` of :func:`with_master_faults`, the stream fed ``piece`` samples at a time)."""
    scenario = scenario.for_seed(seed)
    config = config_from_mapping(overrides or {})
    pipeline = build_pipeline(config, scenario.site, scenario.rate_hz, scenario.grade.datasheet(), ["master"])
    epochs = with_master_faults(master_epochs(scenario, seed), **(faults or {}), seed=seed)
    feed = AidingFeed(AidingTrack(10, config.aiding.master.latency_s, config.aiding.max_gap_s), iter([epochs]))
    records = process_simulation(pipeline, scenario, seed, feed, piece)
    return records, pipeline

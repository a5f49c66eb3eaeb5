"""GNSS faults for the seed-004 evaluation, and its table's shape.

GIVEN the seed-004 GNSS fixes, WHEN an outage and glitches are applied, THEN exactly the outage's epochs
are gone and only the glitch epochs move, by the stated velocity (m/s east) and position (m north, via
the meridian radius); and the seed-004 table runs on one short seed with a row per variant.
"""
from dataclasses import replace

import numpy as np
from sinsalign.service.align.conventions import DEG
from sinsalign.service.align.earth import radii
from sinsalign.tools.evaluate_gnss import VARIANTS, seed004_table
from sinsalign.tools.sim.aiding import gnss_epochs, with_gnss_faults
from sinsalign.tools.sim.scenarios import get_scenario


def test_gnss_faults_remove_the_outage_and_shift_only_the_glitch_epochs():
    scenario = replace(get_scenario("seed004"), duration_s=20.0)
    clean = gnss_epochs(scenario, 1)
    faulty = with_gnss_faults(clean, outage_s=(10.0, 12.0), glitches=((3.0, 0.5, 20.0, 0.0), (5.0, 1.0, 0.0, 50.0)))
    t = clean[:, 0]
    kept = (t < 10.0) | (t >= 12.0)
    assert len(faulty) == kept.sum() == len(clean) - 100             # 2 s at 50 Hz
    assert not ((faulty[:, 0] >= 10.0) & (faulty[:, 0] < 12.0)).any()
    diff = faulty - clean[kept]
    t = faulty[:, 0]
    velocity_glitch, position_glitch = (t >= 3.0) & (t < 3.5), (t >= 5.0) & (t < 6.0)
    assert velocity_glitch.sum() == 25 and position_glitch.sum() == 50
    assert np.allclose(diff[velocity_glitch, 4], 20.0) and not diff[velocity_glitch][:, [1, 2, 3, 5, 6]].any()
    R_M, _ = radii(clean[kept][position_glitch, 1] * DEG)
    north_m = diff[position_glitch, 1] * DEG * (R_M + faulty[position_glitch, 3])
    assert np.allclose(north_m, 50.0, atol=1e-6) and not diff[position_glitch][:, 2:].any()
    assert not diff[~(velocity_glitch | position_glitch)].any()
    assert np.array_equal(with_gnss_faults(clean), clean)


def test_the_seed004_table_runs_on_a_short_seed():
    text, runs = seed004_table([1], progress=False, duration_s=12.0)
    lines = text.splitlines()
    for label, *_ in VARIANTS:
        assert sum(line.startswith(f"| {label} |") for line in lines) == 1
    assert set(runs) <= {label for label, *_ in VARIANTS} and runs
    assert all(len(r) == 1 and r[0].t[-1] == 12.0 for r in runs.values())
    assert "converged > 3σ" in text and "| – |" in text                 # 60 and 300 s lie beyond 12 s

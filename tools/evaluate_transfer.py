"""Seed-002 evaluation: transfer alignment against a master INS, Monte Carlo over seeds.

The table compares the dual model (the large-angle phase 1, then the Kalman stage with velocity and
attitude matching; switched by phase 1's σ, or at the seed's fixed 10 s) with phase 1 alone (a single
model for the whole run), and runs the dual model through a master stream that stops for 5 s,
repeats epochs and comes late. Errors are the slave's misalignment φ = (φ_E, φ_N, φ_U) against the
truth (φ_U ≈ heading error) and the mounting estimate's error, RMS over the seeds, in degrees.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .evaluate import RunResult, monte_carlo
from .evaluate_aided import fine_honesty
from .evaluate_gnss import plot_heading_runs, summed_counters

SCENARIO = "seed002"
AT_S = (10.0, 60.0)
HONEST_FROM_S = 10.0
DROPOUT_S = (30.0, 35.0)
LATE_S = 0.2
MASTER_FAULTS = {"dropout_s": DROPOUT_S, "repeated": 20, "late_s": LATE_S}
"""The master stops for 5 s, sends 20 epochs twice, and every time stamp is 0.2 s late (configured)."""
FAULTS_LABEL = "dual model + master faults"
VARIANTS: tuple[tuple[str, dict, dict | None], ...] = (
    ("dual model (switch by σ)", {}, None),
    ("dual model (switch at 10 s, the seed's)", {"aiding": {"master_handover_s": 10.0}}, None),
    ("phase 1 alone (one large-angle model)", {"fine": {"enabled": False}}, None),
    (FAULTS_LABEL, {"aiding": {"master_latency_s": LATE_S}}, MASTER_FAULTS),
)
"""(label, configuration overrides, master faults)."""


def rms_at(runs: Sequence[RunResult], t_s: float) -> np.ndarray:
    """RMS over the runs of φ (3,) deg at the epoch nearest ``t_s``."""
    k = int(np.argmin(np.abs(runs[0].t - t_s)))
    return np.sqrt(np.mean([r.phi_deg[k] ** 2 for r in runs], axis=0))


def _axes(v: np.ndarray) -> str:
    return " / ".join(f"{x:.4f}" for x in v)


def seed002_table(seeds: Sequence[int], progress: bool = True) -> tuple[str, dict[str, list[RunResult]]]:
    """The seed-002 table in Markdown and the runs of each variant."""
    lines = [f"seed 002 transfer alignment, {len(seeds)} seeds (RMS over seeds, deg, φ_E / φ_N / φ_U)", "",
             "| variant | slave @10 s | slave @60 s | mounting @60 s | in 2σ from 10 s (heading) | "
             "converged > 3σ |", "|---|---|---|---|---|---|"]
    all_runs: dict[str, list[RunResult]] = {}
    for label, overrides, faults in VARIANTS:
        runs = monte_carlo(SCENARIO, seeds, overrides, progress=progress, label=label, aid_faults=faults)
        all_runs[label] = runs
        honest = fine_honesty(runs, HONEST_FROM_S)
        mounting = np.sqrt(np.mean([r.mount_error_deg**2 for r in runs], axis=0))
        lines.append(f"| {label} | {_axes(rms_at(runs, AT_S[0]))} | {_axes(rms_at(runs, AT_S[1]))} | "
                     f"{_axes(mounting)} | {100 * honest.inside_2sigma:.1f} % | {honest.converged_beyond_3sigma} |")
    counters = summed_counters(all_runs[FAULTS_LABEL])
    lines += ["", f"{FAULTS_LABEL}: no master epochs {DROPOUT_S[0]:g}–{DROPOUT_S[1]:g} s, "
              f"{MASTER_FAULTS['repeated']} epochs sent twice, time stamps {LATE_S:g} s late "
              "(aiding.master_latency_s); counters summed over the seeds: " +
              ", ".join(f"{k} {v}" for k, v in sorted(counters.items()) if v)]
    return "\n".join(lines), all_runs


def plot_seed002(runs_by_variant: dict[str, list[RunResult]], path: str | Path) -> Path:
    """:func:`plot_heading_runs` of the seed-002 variants, the dropout shaded."""
    return plot_heading_runs(runs_by_variant, path, HONEST_FROM_S, {FAULTS_LABEL: (DROPOUT_S, ())},
                             "master dropout")

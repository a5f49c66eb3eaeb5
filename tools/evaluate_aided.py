"""Seed-003 evaluation: in-motion alignment with an odometer, Monte Carlo over speeds and seeds.

The table compares the traditional V^b model (one level) with the multistage method at 120 s
(heading MAE, mean, STD, max; level MAE), then follows the multistage runs through the Kalman
stage to 600 s (heading MAE and max, honesty of σ). Errors are the misalignment φ against the
truth (φ_U ≈ heading error), in degrees.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .evaluate import RunResult, monte_carlo, nearest_epoch

SPEEDS_MPS = (20, 60, 80)
COARSE_AT_S = 120.0
FINE_AT_S = 600.0
TRADITIONAL = {"aiding": {"odo": {"levels": 1}}, "fine": {"enabled": False}}
"""One level: the seed's traditional V^b model, no re-runs."""


@dataclass(frozen=True, slots=True)
class HeadingStats:
    """Heading error at one epoch over the seeds (deg), and the level MAE (deg, both axes)."""

    mae: float
    mean: float
    std: float
    max: float
    level_mae: float


def stats_at(runs: Sequence[RunResult], t_s: float) -> HeadingStats:
    """Heading and level error statistics over the runs at the output epoch nearest ``t_s`` (s)."""
    k = nearest_epoch(runs, t_s)
    phi = np.array([r.phi_deg[k] for r in runs])
    heading = phi[:, 2]
    return HeadingStats(float(np.abs(heading).mean()), float(heading.mean()), float(heading.std()),
                        float(np.abs(heading).max()), float(np.abs(phi[:, :2]).mean()))


@dataclass(frozen=True, slots=True)
class FineHonesty:
    inside_2sigma: float        # share of epochs from ``from_s`` on with |heading error| ≤ 2σ
    converged_beyond_3sigma: int


def fine_honesty(runs: Sequence[RunResult], from_s: float = COARSE_AT_S) -> FineHonesty:
    """How often |heading error| ≤ 2σ from ``from_s`` (s) on, and converged epochs there with |error| > 3σ."""
    inside, total, beyond = 0, 0, 0
    for r in runs:
        sel = r.t >= from_s - 1e-9
        err = np.abs(r.phi_deg[sel, 2])
        sigma = r.heading_sigma_deg[sel]
        inside += int((err <= 2.0 * sigma).sum())
        total += int(sel.sum())
        beyond += int((r.converged[sel] & (err > 3.0 * sigma)).sum())
    return FineHonesty(inside / max(total, 1), beyond)


def seed003_table(seeds: Sequence[int], speeds: Sequence[int] = SPEEDS_MPS, progress: bool = True,
                  aid_faults: dict | None = None) -> tuple[str, dict[int, list[RunResult]]]:
    """The seed-003 table in Markdown and the multistage runs per speed (``aid_faults``: odometer faults,
    keyword arguments of :func:`~.sim.aiding.with_odometer_faults`)."""
    lines = [f"seed 003 in-motion alignment with odometer, {len(seeds)} seeds per speed (heading φ_U, deg)", "",
             "| speed | method | MAE @120 s | mean | STD | max | level MAE | MAE @600 s | max @600 s | in 2σ | "
             "converged > 3σ |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    multistage_runs = {}
    for v in speeds:
        name = f"seed003-{v}"
        trad = stats_at(monte_carlo(name, seeds, TRADITIONAL, progress=progress, label="traditional",
                                    aid_faults=aid_faults and {"odo": aid_faults}, duration_s=COARSE_AT_S), COARSE_AT_S)
        runs = monte_carlo(name, seeds, {}, progress=progress, label="multistage + Kalman",
                           aid_faults=aid_faults and {"odo": aid_faults})
        multistage_runs[v] = runs
        coarse, fine, honest = stats_at(runs, COARSE_AT_S), stats_at(runs, FINE_AT_S), fine_honesty(runs)
        lines.append(f"| {v} m/s | traditional V^b | {trad.mae:.3f} | {trad.mean:+.3f} | {trad.std:.3f} | "
                     f"{trad.max:.3f} | {trad.level_mae:.4f} | | | | |")
        lines.append(f"| {v} m/s | multistage → Kalman | {coarse.mae:.3f} | {coarse.mean:+.3f} | {coarse.std:.3f} | "
                     f"{coarse.max:.3f} | {coarse.level_mae:.4f} | {fine.mae:.3f} | {fine.max:.3f} | "
                     f"{100 * honest.inside_2sigma:.1f} % | {honest.converged_beyond_3sigma} |")
    return "\n".join(lines), multistage_runs


def plot_seed003(runs_by_speed: dict[int, list[RunResult]], path: str | Path) -> Path:
    """Heading error of every run against time with the mean reported ±2σ, one panel per speed."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(runs_by_speed), 1, figsize=(10, 3.2 * len(runs_by_speed)), sharex=True,
                             squeeze=False)
    for ax, (v, runs) in zip(axes[:, 0], runs_by_speed.items(), strict=True):
        for r in runs:
            ax.plot(r.t, r.phi_deg[:, 2], lw=0.6, alpha=0.6)
        t = runs[0].t
        sigma = np.mean([r.heading_sigma_deg for r in runs], axis=0)
        ax.plot(t, 2 * sigma, "k--", lw=1, label="±2σ reported (mean)")
        ax.plot(t, -2 * sigma, "k--", lw=1)
        ax.axvline(COARSE_AT_S, color="grey", lw=0.8)
        ax.set_ylim(-1.5, 1.5)
        ax.set_ylabel("heading error (deg)")
        ax.set_title(f"{v} m/s: multistage coarse (0-120 s) → Kalman with odometer")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right")
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

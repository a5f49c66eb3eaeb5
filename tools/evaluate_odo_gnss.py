"""A land vehicle with an odometer and a GNSS receiver (seed003-odo-gnss): each aid alone, both together, and both
with a GNSS outage, on the same seeds (the same drive, IMU and sensor noise in every row).

The figures: heading MAE at the check epochs, the combined mode's MAE over the better single aid's at 60 s and
120 s, the outage's MAE at its end over the clean run's at that epoch, and σ's honesty from
:data:`HONEST_FROM_S` on (share of epochs with |error| ≤ 2σ, converged epochs beyond 3σ).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from .evaluate import RunResult, monte_carlo
from .evaluate_aided import fine_honesty, stats_at
from .evaluate_gnss import plot_heading_runs

SCENARIO = "seed003-odo-gnss"
CHECK_TIMES_S = (10.0, 30.0, 60.0, 90.0, 120.0, 150.0)
COMPARED_AT_S = (60.0, 120.0)
"""Where the combined mode is compared with the better single aid (s)."""
OUTAGE_S = (60.0, 90.0)
"""A 30-s GNSS outage (s), after the filter has started: the odometer carries the alignment through it."""
HONEST_FROM_S = 10.0
BOTH = "odometer + GNSS"
OUTAGE_LABEL = f"{BOTH}, GNSS out {OUTAGE_S[0]:g}–{OUTAGE_S[1]:g} s"
VARIANTS: tuple[tuple[str, tuple[str, ...], dict | None], ...] = (
    ("odometer alone", ("odo",), None),
    ("GNSS alone", ("gnss",), None),
    (BOTH, ("odo", "gnss"), None),
    (OUTAGE_LABEL, ("odo", "gnss"), {"gnss": {"outage_s": OUTAGE_S}}))
"""(label, the aiding kinds the run takes, aiding faults per kind)."""


@dataclass(frozen=True, slots=True)
class CombinedFigures:
    """The acceptance figures of the comparison: the combined mode's heading MAE over the better single aid's at
    each of :data:`COMPARED_AT_S`, the outage's MAE at its end over the clean run's, and σ's honesty of the
    combined runs with and without the outage (share inside 2σ, converged epochs beyond 3σ)."""

    ratio_to_better: tuple[float, ...]
    outage_ratio: float
    inside_2sigma: float
    converged_beyond_3sigma: int


def run_variants(seeds: Sequence[int], progress: bool = True) -> dict[str, list[RunResult]]:
    """The runs of every variant on the same seeds."""
    return {label: monte_carlo(SCENARIO, seeds, {}, progress=progress, label=label, kinds=kinds, aid_faults=faults)
            for label, kinds, faults in VARIANTS}


def combined_figures(runs: dict[str, list[RunResult]]) -> CombinedFigures:
    ratios = tuple(stats_at(runs[BOTH], t).mae / min(stats_at(runs[label], t).mae for label, _, _ in VARIANTS[:2])
                   for t in COMPARED_AT_S)
    end = OUTAGE_S[1]
    honest = [fine_honesty(runs[label], HONEST_FROM_S) for label in (BOTH, OUTAGE_LABEL)]
    return CombinedFigures(ratios, stats_at(runs[OUTAGE_LABEL], end).mae / stats_at(runs[BOTH], end).mae,
                           min(h.inside_2sigma for h in honest), sum(h.converged_beyond_3sigma for h in honest))


def odo_gnss_table(seeds: Sequence[int], progress: bool = True) -> tuple[str, dict[str, list[RunResult]]]:
    """The comparison in Markdown, and the runs per variant."""
    runs = run_variants(seeds, progress)
    lines = [f"{SCENARIO}: odometer and GNSS, each alone and together, {len(seeds)} seeds (heading φ_U, deg)", "",
             "| aids | " + " | ".join(f"MAE @{t:g} s" for t in CHECK_TIMES_S) + " | max @60 s | max @120 s | "
             f"in 2σ from {HONEST_FROM_S:g} s | converged > 3σ |",
             "|---|" + "---|" * (len(CHECK_TIMES_S) + 4)]
    for label, variant_runs in runs.items():
        at = [stats_at(variant_runs, t) for t in CHECK_TIMES_S]
        honest = fine_honesty(variant_runs, HONEST_FROM_S)
        lines.append(f"| {label} | " + " | ".join(f"{s.mae:.4f}" for s in at) +
                     f" | {stats_at(variant_runs, 60.0).max:.4f} | {stats_at(variant_runs, 120.0).max:.4f} | "
                     f"{100 * honest.inside_2sigma:.1f} % | {honest.converged_beyond_3sigma} |")
    figures = combined_figures(runs)
    lines += ["", "| figure | value | bound |", "|---|---|---|"]
    lines += [f"| heading MAE, {BOTH} / the better single aid, at {t:g} s | {ratio:.2f} | ≤ 0.8 |"
              for t, ratio in zip(COMPARED_AT_S, figures.ratio_to_better, strict=True)]
    lines += [f"| heading MAE at the outage's end ({OUTAGE_S[1]:g} s) / without the outage | "
              f"{figures.outage_ratio:.2f} | ≤ 1.5 |",
              f"| {BOTH}, with and without the outage: epochs inside 2σ from {HONEST_FROM_S:g} s (the fewer) | "
              f"{100 * figures.inside_2sigma:.1f} % | ≥ 90 % |",
              f"| {BOTH}, with and without the outage: converged epochs beyond 3σ | "
              f"{figures.converged_beyond_3sigma} | 0 |"]
    return "\n".join(lines), runs


def plot_odo_gnss(runs_by_variant: dict[str, list[RunResult]], path: str | Path) -> Path:
    """:func:`plot_heading_runs` of the variants, the outage shaded."""
    return plot_heading_runs(runs_by_variant, path, HONEST_FROM_S, {OUTAGE_LABEL: (OUTAGE_S, ())}, "GNSS outage")

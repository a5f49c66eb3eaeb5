"""Seed-004 evaluation: in-flight alignment from GNSS, Monte Carlo over seeds.

The table compares the velocity (VIF) and position (PIF) integration formulas, each with the antenna's
lever arm compensated (the log states it) and ignored (zero configured), at 10, 60 and 300 s (heading
MAE, mean, level MAE, honesty of σ), then follows VIF runs through GNSS glitches and an outage: what
the counters saw, and the heading error before the outage against 30 s after its end. A second table
(:func:`rate_table`) flies the same scenario with slower receivers. Errors are the misalignment φ against
the truth (φ_U ≈ heading error), in degrees.
"""
from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from sinsalign.service.config import ConfigError

from .evaluate import RunResult, monte_carlo, nearest_epoch
from .evaluate_aided import HeadingStats, fine_honesty, stats_at
from .sim.aiding import GnssGlitch

SCENARIO = "seed004"
CHECK_TIMES_S = (10.0, 60.0, 300.0)
"""The issue's epochs for the heading MAE (s)."""
MEAN_AT_S = 60.0
"""Epoch of the |mean heading error| and level MAE bounds (s)."""
HONEST_FROM_S = 10.0
"""σ is judged from this time on (s)."""
GLITCHES: tuple[GnssGlitch, ...] = ((45.0, 1.0, 20.0, 0.0), (150.0, 1.0, 0.0, 50.0))
"""A 20-m/s east velocity jump for 1 s at 45 s, a 50-m north position jump for 1 s at 150 s."""
OUTAGE_S = (200.0, 220.0)
"""A 20-s GNSS outage (s): no fixes from its start to its end."""
RECOVERY_S = 30.0
"""The heading should be back within 2× its error at the outage's start this long after its end (s)."""
GNSS_FAULTS = {"outage_s": OUTAGE_S, "glitches": GLITCHES}
"""Keyword arguments of :func:`~.sim.aiding.with_gnss_faults` for the faults row."""
FAULTS_LABEL = "VIF compensated + faults"
VARIANTS: tuple[tuple[str, str, bool, dict | None], ...] = (
    ("VIF, lever arm compensated", "vif", True, None),
    ("VIF, lever arm ignored", "vif", False, None),
    ("PIF, lever arm compensated", "pif", True, None),
    ("PIF, lever arm ignored", "pif", False, None),
    (FAULTS_LABEL, "vif", True, GNSS_FAULTS))
"""Seed 004's comparison: (label, aiding.gnss.formula, the log states the lever arm, GNSS faults)."""


def _stats(runs: Sequence[RunResult], t_s: float) -> HeadingStats | None:
    """:func:`stats_at` at ``t_s`` (s), or None when the runs end before it."""
    return stats_at(runs, t_s) if t_s <= runs[0].t[-1] + 1e-9 else None


def _cell(stats: HeadingStats | None, field: str, fmt: str) -> str:
    """One field of the stats formatted, – without stats."""
    return "–" if stats is None else format(getattr(stats, field), fmt)


def summed_counters(runs: Sequence[RunResult]) -> dict[str, int]:
    """Each counter of :attr:`RunResult.counters` summed over the runs."""
    total: Counter[str] = Counter()
    for r in runs:
        total.update(r.counters or {})
    return dict(total)


def _variant_row(label: str, runs: Sequence[RunResult]) -> str:
    at = [_stats(runs, t) for t in CHECK_TIMES_S]
    mid = _stats(runs, MEAN_AT_S)
    honest = fine_honesty(runs, HONEST_FROM_S)
    return (f"| {label} | " + " | ".join(_cell(s, "mae", ".4f") for s in at) +
            f" | {_cell(mid, 'mean', '+.4f')} | {_cell(mid, 'level_mae', '.4f')} | "
            f"{100 * honest.inside_2sigma:.1f} % | {honest.converged_beyond_3sigma} |")


def _mean_sigma(runs: Sequence[RunResult], t_s: float) -> str:
    """The reported heading σ (deg) at the epoch nearest ``t_s``, mean over the runs (– beyond them)."""
    if t_s > runs[0].t[-1] + 1e-9:
        return "–"
    k = nearest_epoch(runs, t_s)
    return f"{np.mean([r.heading_sigma_deg[k] for r in runs]):.5f}"


def _faults_lines(clean: Sequence[RunResult] | None, faulty: Sequence[RunResult]) -> list[str]:
    """The faults row's recovery (heading MAE at the outage's start and after it) and summed counters."""
    before, after = _stats(faulty, OUTAGE_S[0]), _stats(faulty, OUTAGE_S[1] + RECOVERY_S)
    ratio = f"{after.mae / before.mae:.2f}" if before is not None and after is not None and before.mae > 0 else "–"
    lines = ["", f"{FAULTS_LABEL}: {GLITCHES[0][2]:g} m/s east for {GLITCHES[0][1]:g} s at {GLITCHES[0][0]:g} s, "
             f"{GLITCHES[1][3]:g} m north for {GLITCHES[1][1]:g} s at {GLITCHES[1][0]:g} s, outage "
             f"{OUTAGE_S[0]:g}–{OUTAGE_S[1]:g} s", "",
             f"| heading MAE at {OUTAGE_S[0]:g} s (outage start) | MAE at {OUTAGE_S[1] + RECOVERY_S:g} s "
             f"({RECOVERY_S:g} s after its end) | ratio (≤ 2) | mean σ at {OUTAGE_S[0]:g} s | at "
             f"{OUTAGE_S[1] - 1:g} s (in the outage) |", "|---|---|---|---|---|",
             f"| {_cell(before, 'mae', '.4f')} | {_cell(after, 'mae', '.4f')} | {ratio} | "
             f"{_mean_sigma(faulty, OUTAGE_S[0])} | {_mean_sigma(faulty, OUTAGE_S[1] - 1.0)} |",
             "", "| counter (summed over seeds) | VIF compensated, clean | with faults |", "|---|---|---|"]
    clean_counts, faulty_counts = summed_counters(clean or []), summed_counters(faulty)
    for key in sorted(set(clean_counts) | set(faulty_counts)):
        lines.append(f"| {key} | {clean_counts.get(key, 0) if clean else '–'} | {faulty_counts.get(key, 0)} |")
    return lines


def seed004_table(seeds: Sequence[int], progress: bool = True,
                  duration_s: float | None = None) -> tuple[str, dict[str, list[RunResult]]]:
    """The seed-004 table in Markdown and the runs of each variant that ran (``duration_s`` cuts the flight
    short; epochs after it show –). A formula the pipeline refuses (ConfigError, NotImplementedError) gets
    a row saying so."""
    lines = [f"seed 004 in-flight alignment with GNSS, {len(seeds)} seeds (heading φ_U, deg)", "",
             "| variant | " + " | ".join(f"MAE @{t:g} s" for t in CHECK_TIMES_S) +
             f" | mean @{MEAN_AT_S:g} s | level MAE @{MEAN_AT_S:g} s | in 2σ from {HONEST_FROM_S:g} s | "
             "converged > 3σ |", "|---|" + "---|" * (len(CHECK_TIMES_S) + 4)]
    all_runs: dict[str, list[RunResult]] = {}
    for label, formula, lever_stated, faults in VARIANTS:
        try:
            runs = monte_carlo(SCENARIO, seeds, {"aiding": {"gnss": {"formula": formula}}}, progress=progress,
                               label=label, aid_faults=faults and {"gnss": faults}, duration_s=duration_s,
                               gnss_lever_stated=lever_stated)
        except (ConfigError, NotImplementedError) as e:
            lines.append(f"| {label} | not available: {e} |" + " |" * (len(CHECK_TIMES_S) + 3))
            continue
        all_runs[label] = runs
        lines.append(_variant_row(label, runs))
    if FAULTS_LABEL in all_runs:
        lines += _faults_lines(all_runs.get(VARIANTS[0][0]), all_runs[FAULTS_LABEL])
    return "\n".join(lines), all_runs


RATES_HZ = (50.0, 10.0, 5.0, 1.0)
"""GNSS fix rates of :func:`rate_table` (the scenario's own is 50 Hz)."""
RATES_DURATION_S = 120.0


def rate_table(seeds: Sequence[int], rates_hz: Sequence[float] = RATES_HZ, progress: bool = True,
               duration_s: float = RATES_DURATION_S) -> tuple[str, dict[str, list[RunResult]]]:
    """Seed 004 (VIF, lever arm compensated, default configuration) with the receiver at each of ``rates_hz``:
    heading accuracy, σ honesty and what the counters made of the fixes (summed over seeds), in Markdown, and the
    runs per rate."""
    lines = [f"seed 004 with slower GNSS receivers, {len(seeds)} seeds, {duration_s:g} s (heading φ_U, deg; "
             "counters summed over seeds)", "",
             f"| GNSS rate | MAE @{CHECK_TIMES_S[0]:g} s | MAE @{MEAN_AT_S:g} s | mean @{MEAN_AT_S:g} s | "
             f"in 2σ from {HONEST_FROM_S:g} s | converged > 3σ | gaps | "
             "observations before the first fix / unaided after | velocity updates |",
             "|---|" + "---|" * 8]

    def row(label: str, runs: list[RunResult]) -> str:
        honest, counts = fine_honesty(runs, HONEST_FROM_S), summed_counters(runs)
        early, mid = _stats(runs, CHECK_TIMES_S[0]), _stats(runs, MEAN_AT_S)
        return (f"| {label} | {_cell(early, 'mae', '.4f')} | {_cell(mid, 'mae', '.4f')} | "
                f"{_cell(mid, 'mean', '+.4f')} | {100 * honest.inside_2sigma:.1f} % | "
                f"{honest.converged_beyond_3sigma} | {stream_cells(counts, 'gnss')} | "
                f"{counts.get('gnss_vel_accepted', 0)} |")

    return rate_rows(SCENARIO, seeds, rates_hz, row, lines, progress, duration_s)


def stream_cells(counts: dict[str, int], kind: str) -> str:
    """The rate tables' cells of what an aiding stream's epochs came to (counters summed over seeds): its gaps, then
    the coarse observations awaiting its first epoch / unaided after it."""
    return (f"{counts.get('gaps', 0)} | {counts.get(f'{kind}_observations_awaiting_aid', 0)} / "
            f"{counts.get(f'{kind}_unaided_observations', 0)}")


def rate_rows(scenario: str, seeds: Sequence[int], rates_hz: Sequence[float],
              row: Callable[[str, list[RunResult]], str], lines: list[str], progress: bool = True,
              duration_s: float | None = None) -> tuple[str, dict[str, list[RunResult]]]:
    """The runs of ``scenario`` with its aiding sensor at each of ``rates_hz`` (labelled "N Hz"), and the Markdown
    table of ``lines`` (its heading) with ``row(label, runs)`` per rate."""
    all_runs: dict[str, list[RunResult]] = {}
    for rate in rates_hz:
        label = f"{rate:g} Hz"
        all_runs[label] = monte_carlo(scenario, seeds, progress=progress, label=label, duration_s=duration_s,
                                      aid_rate_hz=rate)
        lines.append(row(label, all_runs[label]))
    return "\n".join(lines), all_runs


def plot_rates(runs_by_rate: dict[str, list[RunResult]], path: str | Path, from_s: float = HONEST_FROM_S) -> Path:
    """:func:`plot_heading_runs` of a rate table's runs, σ honesty judged from ``from_s``."""
    return plot_heading_runs(runs_by_rate, path, from_s)


def plot_seed004(runs_by_variant: dict[str, list[RunResult]], path: str | Path) -> Path:
    """:func:`plot_heading_runs` of the seed-004 variants, the faults run with its outage shaded and its
    glitches marked."""
    return plot_heading_runs(runs_by_variant, path, HONEST_FROM_S,
                             {FAULTS_LABEL: (OUTAGE_S, tuple(g[0] for g in GLITCHES))}, "GNSS outage")


def plot_heading_runs(runs_by_variant: dict[str, list[RunResult]], path: str | Path, from_s: float,
                      marks: dict[str, tuple[tuple[float, float], tuple[float, ...]]] | None = None,
                      span_label: str = "outage") -> Path:
    """PNG: heading error of every run against time with the mean reported ±3σ, one row per variant: the error
    from ``from_s`` on (linear) and |error| over the whole run (log scale); ``marks`` per variant: a span
    (start, end) s to shade and times (s) to mark (faults)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(runs_by_variant)
    fig, axes = plt.subplots(n, 2, figsize=(13, 3.2 * n), squeeze=False)
    for (lin, log), (label, runs) in zip(axes, runs_by_variant.items(), strict=True):
        t = runs[0].t
        err = np.array([r.phi_deg[:, 2] for r in runs])
        three_sigma = 3 * np.mean([r.heading_sigma_deg for r in runs], axis=0)
        late = t >= from_s
        for e in err:
            lin.plot(t[late], e[late], lw=0.6, alpha=0.6)
            log.semilogy(t, np.abs(e), lw=0.6, alpha=0.6)
        lin.plot(t[late], three_sigma[late], "k--", lw=1, label="±3σ reported (mean over seeds)")
        lin.plot(t[late], -three_sigma[late], "k--", lw=1)
        log.semilogy(t, three_sigma, "k--", lw=1, label="3σ reported (mean over seeds)")
        if late.any():
            span = max(np.percentile(np.abs(err[:, late]), 99), np.median(three_sigma[late]))
            lin.set_ylim(-1.3 * span, 1.3 * span)
        log.set_ylim(1e-4, 10.0)
        for ax in (lin, log):
            if label in (marks or {}):
                span, times = marks[label]
                ax.axvspan(*span, color="grey", alpha=0.25, label=span_label)
                for k, start in enumerate(times):
                    ax.axvline(start, color="tab:red", lw=0.8, label="fault" if k == 0 else None)
            ax.grid(alpha=0.3, which="both")
            ax.set_ylabel("heading error (deg)")
        lin.set_title(f"{label}: heading error from {from_s:g} s ({len(runs)} seeds)", fontsize=9)
        log.set_title(f"{label}: |heading error|", fontsize=9)
        lin.legend(loc="upper right", fontsize=7)
        log.legend(loc="upper right", fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

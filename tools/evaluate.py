"""Monte Carlo evaluation against simulated truth: tables, settling times, honesty of σ, plots.

Errors are the misalignment φ = (φ_E, φ_N, φ_U) of the output attitude against the truth
(docs/algorithms/conventions.md, "Misalignment φ and the heading error"; φ_U ≈ heading error, estimate minus
truth, clockwise). Each run's physical limit (docs/algorithms/coarse.md, "Accuracy limits") comes from its
actual biases rotated into the n frame with the run's mean attitude.
"""
from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from rich.progress import Progress
from sinsalign.service.aiding import AidingFeed, AidingTrack, aid_rows
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment, quat_from_dcm, skew
from sinsalign.service.align.sensor_model import physical_limit
from sinsalign.service.config import Config, config_from_mapping
from sinsalign.service.pipeline import AlignmentPipeline, build_pipeline

from .sim.aiding import scenario_aids, with_faults
from .sim.imu import ERROR_SOURCES, simulate
from .sim.parked import DrivenMotion
from .sim.scenarios import Scenario, get_scenario

COARSE_ONLY = {"fine": {"enabled": False}}
"""Overrides that stop the pipeline after the coarse stage (seed 000's inertial-frame alignment alone)."""
SETTLE_BAND_DEG = 0.1
HONEST_FROM_S = 30.0


@dataclass(frozen=True, slots=True)
class RunResult:
    """One seed: per output epoch the time (s), φ (deg, E/N/U), σ (deg) and converged; the limit (deg)."""

    seed: int
    t: np.ndarray
    phi_deg: np.ndarray
    heading_sigma_deg: np.ndarray
    level_sigma_deg: np.ndarray
    converged: np.ndarray
    limit_deg: np.ndarray
    disturbances: int = 0
    counters: dict[str, int] | None = None
    mount_error_deg: np.ndarray | None = None
    """Transfer alignment: the final mounting estimate's error (3,) deg, in the master's axes."""
    mount_phi_deg: np.ndarray | None = None
    """Transfer alignment: per output epoch the reported mounting's error (N, 3) deg, in the master's axes."""
    phases: tuple[str, ...] = ()
    """The output phases in the order they appeared (a phase that comes back counts again)."""
    disturbed: np.ndarray | None = None
    """Per output epoch: the phase is ``disturbed``."""


def nearest_epoch(runs: Sequence[RunResult], t_s: float) -> int:
    """Index of the output epoch nearest ``t_s`` (s) in the runs (they share their epochs)."""
    return int(np.argmin(np.abs(runs[0].t - t_s)))


def run_limit_deg(scenario: Scenario, t: np.ndarray) -> np.ndarray:
    """φ limit (deg) of a run: its body-axis biases rotated into n with the mean attitude over t."""
    C_mean = scenario.motion.attitude(t).mean(axis=0)
    acc_n = C_mean @ np.asarray(scenario.errors.acc_bias_ms2)
    gyro_n = C_mean @ np.asarray(scenario.errors.gyro_bias_rad_s)
    return physical_limit(acc_n, gyro_n, scenario.site.lat, scenario.site.gravity) / DEG


def run_once(scenario: Scenario, seed: int, config: Config, initial_error_deg: Sequence[float] | None = None,
             live: bool = False, aid_faults: dict[str, dict] | None = None, gnss_lever_stated: bool = True,
             kinds: Sequence[str] | None = None) -> RunResult:
    """Simulate one seed in memory and run the pipeline over it (the scenario's datasheet grade, as its log states).

    ``initial_error_deg`` (φ_E, φ_N, φ_U) starts the compass loops alone from the truth at t = 0 turned by that
    misalignment, without the coarse stage (seed 001's compass-only runs). A scenario with an odometer or GNSS
    runs the aided pipeline, its readings going through the same aiding tracks as a log's; ``kinds`` keeps only those
    of its aiding sensors (None: all); ``aid_faults`` gives per kind the keyword arguments of
    :func:`with_odometer_faults`, :func:`with_gnss_faults` or :func:`with_master_faults`.
    ``gnss_lever_stated``: the GNSS log states the antenna's lever arm (it overrides ``aiding.gnss.lever_m``);
    False leaves the configuration's (zero by default: the lever arm ignored).
    """
    scenario = scenario.for_seed(seed)
    initial = None
    if initial_error_deg is not None:
        phi = np.asarray(initial_error_deg, dtype=float) * DEG
        initial = quat_from_dcm((np.eye(3) - skew(phi)) @ scenario.motion.attitude(np.array([0.0]))[0])
    aids = [aid for aid in scenario_aids(scenario, seed) if kinds is None or aid.kind in kinds]
    if not aids:
        pipeline = AlignmentPipeline(config, scenario.site, scenario.rate_hz, scenario.stated_datasheet(), live=live,
                                     initial_q_b_n=initial)
    for aid in aids:
        # the sensor as its log states it (its noise; a GNSS antenna's lever arm, unless that is left unstated)
        stated = {k: v for k, v in aid.stated().items()
                  if gnss_lever_stated or (aid.kind, k) != ("gnss", "lever_m")}
        config = config_from_mapping({"aiding": {aid.kind: stated}}, config)
    # the aided pipeline, its readings through the same aiding tracks as a log's
    faults = aid_faults or {}
    feeds = {aid.kind: AidingFeed(AidingTrack.configured(aid.kind, config.aiding),
                                  iter([with_faults(aid.kind, aid.epochs, seed, **faults.get(aid.kind, {}))]))
             for aid in aids}
    if aids:
        pipeline = build_pipeline(config, scenario.site, scenario.rate_hz, scenario.grade.datasheet(), feeds, live)
    records = []
    for chunk in simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, scenario.duration_s,
                          seed):
        records += pipeline.process(chunk.t, chunk.dtheta, chunk.dv, aid_rows(feeds, pipeline.aid_kinds, chunk.t))
    counters = None
    if feeds:
        counters = pipeline.aiding_counters()
        for kind, feed in feeds.items():
            counters |= feed.track.counters.as_dict(f"{kind}_")
    t = np.array([r.t for r in records])
    C_est = dcm_from_quat(np.array([r.q for r in records]))
    phi = misalignment(C_est, scenario.motion.attitude(t)) / DEG
    mount_error = mount_phi = None
    if scenario.master is not None:
        mount_error = misalignment(pipeline.mode.mounting()[0], scenario.motion.mounting) / DEG
        mount_phi = misalignment(dcm_from_quat(np.array([r.mount_q for r in records])), scenario.motion.mounting) / DEG
    phases = tuple(r.phase for i, r in enumerate(records) if i == 0 or records[i - 1].phase != r.phase)
    return RunResult(seed, t, phi, np.array([r.heading_sigma_deg for r in records]),
                     np.array([r.level_sigma_deg for r in records]), np.array([r.converged for r in records]),
                     run_limit_deg(scenario, t), pipeline.disturbances, counters, mount_error, mount_phi_deg=mount_phi,
                     phases=phases, disturbed=np.array([r.phase == "disturbed" for r in records]))


def _run_task(args: tuple[str, int, dict, float | None, float | None, str | None, dict]) -> RunResult:
    """One seed of :func:`monte_carlo`: scenario name, seed, overrides, duration (s), aiding rate (Hz), error
    source, run_once keywords."""
    name, seed, overrides, duration_s, aid_rate_hz, error_source, options = args
    scenario = get_scenario(name)
    if duration_s is not None:
        scenario = replace(scenario, duration_s=duration_s)
    if aid_rate_hz is not None:
        scenario = scenario.with_aid_rate(aid_rate_hz)
    if error_source is not None:
        scenario = replace(scenario, errors=scenario.errors.only(error_source))
    return run_once(scenario, seed, config_from_mapping(overrides), **options)


def monte_carlo(scenario_name: str, seeds: Sequence[int], overrides: dict | None = None, workers: int | None = None,
                progress: bool = True, label: str = "", initial_error_deg: Sequence[float] | None = None,
                aid_faults: dict[str, dict] | None = None, duration_s: float | None = None,
                gnss_lever_stated: bool = True, aid_rate_hz: float | None = None,
                error_source: str | None = None, kinds: Sequence[str] | None = None) -> list[RunResult]:
    """Run every seed (in parallel processes); results in seed order. See :func:`run_once`;
    ``duration_s`` cuts the scenario short, ``aid_rate_hz`` runs its aiding sensor at another rate,
    ``error_source`` (a key of ERROR_SOURCES) keeps that one IMU error and zeroes the others (the datasheet the
    log states stays the same, so the estimator weighs the data as before)."""
    options = {"initial_error_deg": initial_error_deg, "aid_faults": aid_faults, "gnss_lever_stated": gnss_lever_stated,
               "kinds": kinds}
    tasks = [(scenario_name, s, overrides or {}, duration_s, aid_rate_hz, error_source, options) for s in seeds]
    return run_parallel(_run_task, tasks, f"{scenario_name} {label}".strip(), progress, workers)


def run_parallel(function: Callable[[Any], RunResult], tasks: Sequence[Any], label: str, progress: bool = True,
                 workers: int | None = None) -> list[RunResult]:
    """``function`` over the tasks in parallel processes (a picklable module-level function), results in order,
    with a progress bar."""
    workers = workers or min(len(tasks), os.cpu_count() or 1)
    results = []
    with Progress(disable=not progress, transient=True) as bar:
        task = bar.add_task(label, total=len(tasks))
        if workers <= 1:
            for t in tasks:
                results.append(function(t))
                bar.advance(task)
        else:
            # forkserver, not fork: a fork of a process that runs Zenoh's threads (the daemon tests, a
            # live session) can inherit a lock held mid-call and deadlock in the child
            with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("forkserver")) as pool:
                for r in pool.map(function, tasks):
                    results.append(r)
                    bar.advance(task)
    return results


@dataclass(frozen=True, slots=True)
class WindowStats:
    """Statistics of heading (φ_U) and level (φ_E, φ_N) errors minus the limit in a time window, deg."""

    window_s: tuple[float, float]
    heading_mean: float          # average over seeds of each run's mean (error - limit)
    heading_seed_std: float      # STD over seeds of each run's mean (error - limit)
    heading_inwindow_std: float  # each run's STD inside the window, averaged over seeds
    level_east_mean: float
    level_north_mean: float
    limit_heading_mean: float


def window_stats(runs: Sequence[RunResult], window_s: tuple[float, float]) -> WindowStats:
    a, b = window_s
    sel = (runs[0].t >= a - 1e-9) & (runs[0].t <= b + 1e-9)
    rel = np.array([r.phi_deg[sel] - r.limit_deg for r in runs])   # (seeds, epochs, 3)
    run_means = rel[:, :, 2].mean(axis=1)
    return WindowStats(window_s, float(run_means.mean()), float(run_means.std()),
                       float(rel[:, :, 2].std(axis=1).mean()), float(rel[:, :, 0].mean()), float(rel[:, :, 1].mean()),
                       float(np.mean([r.limit_deg[2] for r in runs])))


def settling_time_s(run: RunResult, band_deg: float = SETTLE_BAND_DEG) -> float:
    """Time from which |heading error - limit| stays below ``band_deg`` (inf if never)."""
    outside = np.flatnonzero(np.abs(run.phi_deg[:, 2] - run.limit_deg[2]) >= band_deg)
    if len(outside) == 0:
        return float(run.t[0])
    return float(run.t[outside[-1] + 1]) if outside[-1] + 1 < len(run.t) else float("inf")


@dataclass(frozen=True, slots=True)
class Honesty:
    fraction_within_2sigma: float
    converged_beyond_3sigma: int
    first_converged_s: float


def honesty(runs: Sequence[RunResult], from_s: float = HONEST_FROM_S) -> Honesty:
    """How often |heading error| ≤ 2σ after ``from_s``; converged epochs with |error| > 3σ (all epochs)."""
    inside = np.concatenate([np.abs(r.phi_deg[r.t >= from_s, 2]) <= 2 * r.heading_sigma_deg[r.t >= from_s]
                             for r in runs])
    beyond = sum(int(np.sum(r.converged & (np.abs(r.phi_deg[:, 2]) > 3 * r.heading_sigma_deg))) for r in runs)
    first = [r.t[np.argmax(r.converged)] for r in runs if r.converged.any()]
    return Honesty(float(inside.mean()), beyond, float(np.median(first)) if first else float("inf"))


ALIGNMENT_PHASES = ("coarse", "fine", "aligned")


@dataclass(frozen=True, slots=True)
class FieldFigures:
    """A fixed-base scenario's acceptance figures from ``from_s`` on, over every seed and epoch: the largest
    |heading error − limit| (°); the reported σ's RMS over the actual error's RMS, and the smallest σ/|error|; the
    first time from which every run stays converged (s; inf if one ends unconverged); converged epochs beyond 3σ;
    restarts; runs whose phases did not go coarse → fine → aligned."""

    from_s: float
    max_rel_deg: float
    sigma_over_rms: float
    min_sigma_over_err: float
    converged_from_s: float
    beyond_3sigma: int
    disturbances: int
    phases_out_of_order: int


def field_figures(runs: Sequence[RunResult], from_s: float) -> FieldFigures:
    late = runs[0].t >= from_s
    err = np.array([r.phi_deg[late, 2] for r in runs])
    rel = np.array([r.phi_deg[late, 2] - r.limit_deg[2] for r in runs])
    sigma = np.array([r.heading_sigma_deg[late] for r in runs])
    converged_from = max(float(r.t[np.flatnonzero(~r.converged)[-1] + 1]) if r.converged[-1] else np.inf
                         for r in runs)
    return FieldFigures(from_s, float(np.abs(rel).max()), float(np.sqrt((sigma**2).mean() / (err**2).mean())),
                        float((sigma / np.maximum(np.abs(err), 1e-12)).min()), converged_from,
                        honesty(runs).converged_beyond_3sigma, sum(r.disturbances for r in runs),
                        sum(r.phases != ALIGNMENT_PHASES for r in runs))


def field_line(runs: Sequence[RunResult], from_s: float) -> str:
    """:func:`field_figures` as one line of text."""
    f = field_figures(runs, from_s)
    return (f"from {f.from_s:g} s: max |err−limit| {f.max_rel_deg:.4f}°; σ / RMS error {f.sigma_over_rms:.2f} "
            f"(smallest σ/|err| {f.min_sigma_over_err:.2f}); every run converged from {f.converged_from_s:.0f} s; "
            f"converged epochs beyond 3σ: {f.beyond_3sigma}; restarts: {f.disturbances}; runs not coarse → fine → "
            f"aligned: {f.phases_out_of_order}")


MOVING_MPS = 0.1
"""A base is moving once its speed passes this (m/s)."""


@dataclass(frozen=True, slots=True)
class DriveFigures:
    """A driven scenario's figures over its runs: when the base first passes ``MOVING_MPS`` (s), the longest delay
    from then to the first ``disturbed`` epoch (s; inf if a run never reports it), converged epochs while moving;
    once it is parked again (the last window, if the base is at rest there): the largest |heading error| (°) and
    the epochs not converged (None if it never stops)."""

    moving_from_s: float
    detect_delay_s: float
    converged_while_moving: int
    parked_max_heading_err_deg: float | None
    parked_unconverged: int | None


def drive_figures(scenario: Scenario, runs: Sequence[RunResult]) -> DriveFigures:
    t = runs[0].t
    speed = np.abs(scenario.motion.speed_and_accel(t)[0])
    grid = np.arange(0.0, scenario.duration_s, 0.01)
    moving_from = float(grid[np.argmax(np.abs(scenario.motion.speed_and_accel(grid)[0]) > MOVING_MPS)])
    delays = [float(t[np.argmax(r.disturbed & (t > moving_from))]) - moving_from
              if (r.disturbed & (t > moving_from)).any() else np.inf for r in runs]
    moving = sum(int(np.sum(r.converged & (speed > MOVING_MPS))) for r in runs)
    parked = t >= scenario.eval_windows_s[-1][0]
    if (speed[parked] > MOVING_MPS).any():
        return DriveFigures(moving_from, max(delays), moving, None, None)
    return DriveFigures(moving_from, max(delays), moving,
                        float(max(np.abs(r.phi_deg[parked, 2]).max() for r in runs)),
                        sum(int(np.sum(~r.converged[parked])) for r in runs))


def drive_line(scenario: Scenario, runs: Sequence[RunResult]) -> str:
    """:func:`drive_figures` as one line of text."""
    f = drive_figures(scenario, runs)
    line = (f"moving (> {MOVING_MPS:g} m/s) from {f.moving_from_s:.2f} s: `disturbed` within {f.detect_delay_s:.2f} s "
            f"(longest over the runs); converged epochs while moving: {f.converged_while_moving}")
    if f.parked_max_heading_err_deg is None:
        return line
    return (line + f"; parked again, from {scenario.eval_windows_s[-1][0]:g} s: largest |heading error| "
            f"{f.parked_max_heading_err_deg:.4f}°, epochs not converged: {f.parked_unconverged}")


def scenario_table(name: str, runs: Sequence[RunResult]) -> str:
    """Markdown table of one scenario: per window, heading and level errors relative to the limit."""
    scenario = get_scenario(name)
    lines = [f"**{name}** ({len(runs)} seeds) — {scenario.description}", "",
             "| window (s) | limit φ_U (°) | mean(err−limit) (°) | seed STD (°) | in-window STD (°) "
             "| level E err−limit (°) | level N err−limit (°) |", "|---|---|---|---|---|---|---|"]
    for w in scenario.eval_windows_s:
        s = window_stats(runs, w)
        lines.append(f"| {w[0]:g}–{w[1]:g} | {s.limit_heading_mean:+.4f} | {s.heading_mean:+.4f} | "
                     f"{s.heading_seed_std:.4f} | {s.heading_inwindow_std:.4f} | {s.level_east_mean:+.5f} | "
                     f"{s.level_north_mean:+.5f} |")
    settle = [settling_time_s(r) for r in runs]
    h = honesty(runs)
    lines += ["", f"median settling time (|err−limit| < {SETTLE_BAND_DEG}°): {np.median(settle):.1f} s; "
              f"|heading err| ≤ 2σ after {HONEST_FROM_S:g} s: {100 * h.fraction_within_2sigma:.1f} %; "
              f"converged epochs with |err| > 3σ: {h.converged_beyond_3sigma}; "
              f"median first converged: {h.first_converged_s:.0f} s"]
    if scenario.field_from_s is not None:
        lines += ["", field_line(runs, scenario.field_from_s)]
    if isinstance(scenario.motion, DrivenMotion):
        lines += ["", drive_line(scenario, runs)]
    return "\n".join(lines)


def seed_set_table(name: str, runs: Sequence[RunResult], set_size: int) -> str:
    """Markdown table of the scenario's last window per disjoint set of ``set_size`` seeds, then all seeds
    pooled: how much a figure over 20 seeds moves with the set of seeds."""
    window = get_scenario(name).eval_windows_s[-1]
    lines = [f"**{name}, per set of {set_size} seeds** (window {window[0]:g}–{window[1]:g} s; heading error − "
             "limit, °)", "", "| seeds | mean | seed STD | in-window STD | median settling (s) |",
             "|---|---|---|---|---|"]
    sets = [(f"{runs[k].seed}–{runs[min(k + set_size, len(runs)) - 1].seed}", runs[k:k + set_size])
            for k in range(0, len(runs), set_size)]
    for label, group in [*sets, (f"all {len(runs)}", runs)]:
        w = window_stats(group, window)
        lines.append(f"| {label} | {w.heading_mean:+.4f} | {w.heading_seed_std:.4f} | {w.heading_inwindow_std:.5f} | "
                     f"{np.median([settling_time_s(r) for r in group]):.1f} |")
    return "\n".join(lines)


def budget_table(name: str, runs: Sequence[RunResult], overrides: dict | None = None, progress: bool = True
                 ) -> tuple[str, dict[str, list[RunResult]]]:
    """Markdown error budget of one scenario's last window: ``runs`` (every error, the same seeds) and a re-run
    of those seeds with each IMU error source alone, the estimator configured by ``overrides`` as in ``runs``.
    The noise streams are the same in every row, so the rows split the figures of the first."""
    window = get_scenario(name).eval_windows_s[-1]
    seeds = [r.seed for r in runs]
    lines = [f"**error budget of {name}** ({len(seeds)} seeds, window {window[0]:g}–{window[1]:g} s; heading "
             "error − limit, °; level error − limit, °)", "",
             "| IMU errors | limit φ_U | mean | seed STD | in-window STD | level E | level N |",
             "|---|---|---|---|---|---|---|"]
    by_source = {"all": runs}
    for source, (label, _) in ERROR_SOURCES.items():
        by_source[source] = monte_carlo(name, seeds, overrides, progress=progress, label=label, error_source=source)
    for source, group in by_source.items():
        w = window_stats(group, window)
        label = "all (the scenario)" if source == "all" else f"{ERROR_SOURCES[source][0]} only"
        lines.append(f"| {label} | {w.limit_heading_mean:+.4f} | {w.heading_mean:+.4f} | {w.heading_seed_std:.4f} | "
                     f"{w.heading_inwindow_std:.5f} | {w.level_east_mean:+.5f} | {w.level_north_mean:+.5f} |")
    return "\n".join(lines), by_source


SOLVER_VARIANTS = (("OPREQ", {"solver": "opreq"}), ("q-method (OBA)", {"solver": "qmethod"}),
                   ("REQUEST ρ=0.1", {"solver": "request", "request_rho": 0.1}),
                   ("REQUEST ρ=0.01", {"solver": "request", "request_rho": 0.01}),
                   ("REQUEST ρ=0.001", {"solver": "request", "request_rho": 0.001}),
                   ("centred Wahba (free offset)", {"solver": "centred"}),
                   ("GLS (whitened increments)", {"solver": "gls"}))


def solver_table(name: str, seeds: Sequence[int], progress: bool = True) -> tuple[str, dict[str, list[RunResult]]]:
    """Markdown table comparing the solvers on one scenario (same seeds)."""
    scenario = get_scenario(name)
    early, late = scenario.eval_windows_s[0], scenario.eval_windows_s[-1]
    lines = [f"**solvers on {name}** ({len(seeds)} seeds; heading error − limit, °)", "",
             f"| solver | median settling (s) | mean {early[0]:g}–{early[1]:g} s | seed STD | "
             f"mean {late[0]:g}–{late[1]:g} s | seed STD | in-window STD |", "|---|---|---|---|---|---|---|"]
    all_runs = {}
    for label, overrides in SOLVER_VARIANTS:
        runs = monte_carlo(name, seeds, {"alignment": overrides, **COARSE_ONLY}, progress=progress, label=label)
        all_runs[label] = runs
        e, s = window_stats(runs, early), window_stats(runs, late)
        lines.append(f"| {label} | {np.median([settling_time_s(r) for r in runs]):.1f} | {e.heading_mean:+.4f} | "
                     f"{e.heading_seed_std:.4f} | {s.heading_mean:+.4f} | {s.heading_seed_std:.4f} | "
                     f"{s.heading_inwindow_std:.4f} |")
    return "\n".join(lines), all_runs


FINE_VARIANTS = (("OPREQ only", COARSE_ONLY, None),
                 ("compass alone from 1.5°", {"fine": {"compass": {"stored_pairs": 0}}}, (0.1, 0.1, 1.5)),
                 ("compass alone from 1.5°, stored data", {}, (0.1, 0.1, 1.5)),
                 ("OPREQ → compass", {"fine": {"compass": {"stored_pairs": 0}}}, None),
                 ("OPREQ → compass, stored data (default)", {}, None))
"""Seed 001's comparison: (label, configuration overrides, initial error of a compass-alone start)."""
FINE_BAND_DEG = 0.05


def fine_table(name: str, seeds: Sequence[int], progress: bool = True) -> tuple[str, dict[str, list[RunResult]]]:
    """Markdown table of seed 001's comparison on one scenario (same seeds for every variant)."""
    scenario = get_scenario(name)
    late = scenario.eval_windows_s[-1]
    lines = [f"**seed-001 comparison on {name}** ({len(seeds)} seeds; heading error − limit, °; stored data "
             f"= 80 s, 3 backward+forward pairs)", "",
             f"| variant | median settling < {FINE_BAND_DEG}° (s) | mean abs(err−limit) at 100 s "
             f"| mean {late[0]:g}–{late[1]:g} s | seed STD | level E | level N | within 2σ |",
             "|---|---|---|---|---|---|---|---|"]
    all_runs = {}
    for label, overrides, initial in FINE_VARIANTS:
        runs = monte_carlo(name, seeds, overrides, progress=progress, label=label, initial_error_deg=initial)
        all_runs[label] = runs
        s = window_stats(runs, late)
        at_100 = np.mean([abs(r.phi_deg[np.argmin(abs(r.t - 100.0)), 2] - r.limit_deg[2]) for r in runs])
        lines.append(f"| {label} | {np.median([settling_time_s(r, FINE_BAND_DEG) for r in runs]):.0f} | "
                     f"{at_100:.4f} | {s.heading_mean:+.4f} | {s.heading_seed_std:.4f} | {s.level_east_mean:+.5f} | "
                     f"{s.level_north_mean:+.5f} | {100 * honesty(runs).fraction_within_2sigma:.0f} % |")
    return "\n".join(lines), all_runs


def plot_fine(name: str, all_runs: dict[str, list[RunResult]], path: str | Path) -> Path:
    """PNG: seed-mean |heading error − limit| of each seed-001 variant vs time (log scale)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(10, 5))
    for label, runs in all_runs.items():
        rel = np.abs(np.array([r.phi_deg[:, 2] - r.limit_deg[2] for r in runs]))
        ax.semilogy(runs[0].t, np.sqrt((rel**2).mean(axis=0)), lw=1.2, label=label)
    ax.axhline(FINE_BAND_DEG, color="k", lw=0.8, ls="--", label=f"{FINE_BAND_DEG}° band")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("RMS over seeds of |heading error − limit| (°)")
    ax.set_title(f"{name}: OPREQ, compass, and stored-data repeated navigation")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_heading(name: str, runs: Sequence[RunResult], path: str | Path,
                 others: dict[str, list[RunResult]] | None = None) -> Path:
    """PNG: heading error of every seed vs time, the limit band and the ±2σ envelope."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    t = runs[0].t
    err = np.array([r.phi_deg[:, 2] for r in runs])
    sigma = np.array([r.heading_sigma_deg for r in runs]).mean(axis=0)
    limits = np.array([r.limit_deg[2] for r in runs])
    fig, axes = plt.subplots(2, 1, figsize=(10, 8))
    for ax, (lo, hi) in zip(axes, ((t[0], t[-1]), (t[-1] * 0.4, t[-1])), strict=True):
        sel = (t >= lo) & (t <= hi)
        for e in err:
            ax.plot(t[sel], e[sel], color="tab:blue", lw=0.6, alpha=0.5)
        ax.plot([], [], color="tab:blue", lw=0.6, label=f"heading error, {len(runs)} seeds")
        ax.fill_between(t[sel], -2 * sigma[sel], 2 * sigma[sel], color="tab:orange", alpha=0.15,
                        label="±2σ reported (mean over seeds)")
        ax.axhspan(limits.min(), limits.max(), color="tab:red", alpha=0.3, label="physical limit (range over seeds)")
        ax.axhline(limits.mean(), color="tab:red", lw=1)
        for label, other in (others or {}).items():
            ax.plot(t[sel], np.mean([r.phi_deg[sel, 2] for r in other], axis=0), lw=1.2, label=f"{label} (seed mean)")
        ax.set_xlim(lo, hi)
        span = np.percentile(np.abs(err[:, sel]), 98) if sel.any() else 1.0
        ax.set_ylim(-1.3 * span + limits.mean(), 1.3 * span + limits.mean())
        ax.set_xlabel("time (s)")
        ax.set_ylabel("heading error φ_U (°)")
        ax.grid(alpha=0.3)
    axes[0].set_title(f"{name}: heading error vs time")
    axes[0].legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path



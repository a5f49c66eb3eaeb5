"""Seed-002 evaluation: transfer alignment against a master INS, Monte Carlo over seeds.

The table compares the dual model (the large-angle phase 1, then the Kalman stage with velocity and
attitude matching; switched by phase 1's σ, or at the seed's fixed 10 s) with phase 1 alone (a single
model for the whole run), and runs the dual model through a master stream that stops for 5 s,
repeats epochs and comes late. Errors are the slave's misalignment φ = (φ_E, φ_N, φ_U) against the
truth (φ_U ≈ heading error) and the mounting estimate's error, RMS over the seeds, in degrees.

:func:`phase1_comparison` sets our closed-form phase 1 (the pipeline with the Kalman stage off) against the
seed's own phase 1, the additive-quaternion EKF (tools/transfer_ekf.py), on the seed's 20°/20°/20°
mounting and on 60°/−45°/120°.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.service.config import Config, config_from_mapping
from sinsalign.service.modes.kalman import KalmanMode

from .evaluate import (
    COARSE_ONLY,
    RunResult,
    monte_carlo,
    nearest_epoch,
    run_limit_deg,
    run_once,
    run_parallel,
)
from .evaluate_aided import fine_honesty
from .evaluate_gnss import plot_heading_runs, rate_rows, stream_cells, summed_counters
from .sim.aiding import master_epochs
from .sim.imu import simulate
from .sim.scenarios import SEED002_MOUNT_DEG, MasterSpec, Scenario, get_scenario, seed002_flight
from .sim.vehicle import VehicleMotion
from .transfer_ekf import EkfSettings, run_transfer_ekf

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
    ("dual model (switch at 10 s, the seed's)", {"aiding": {"master": {"handover_s": 10.0}}}, None),
    ("phase 1 alone (one large-angle model)", COARSE_ONLY, None),
    (FAULTS_LABEL, {"aiding": {"master": {"latency_s": LATE_S}}}, MASTER_FAULTS),
)
"""(label, configuration overrides, master faults)."""


def rms_at(runs: Sequence[RunResult], t_s: float) -> np.ndarray:
    """RMS over the runs of φ (3,) deg at the epoch nearest ``t_s``."""
    k = nearest_epoch(runs, t_s)
    return np.sqrt(np.mean([r.phi_deg[k] ** 2 for r in runs], axis=0))


def worst_at(runs: Sequence[RunResult], t_s: float) -> float:
    """The largest |φ| (deg) of any axis over the runs at the epoch nearest ``t_s``."""
    k = nearest_epoch(runs, t_s)
    return max(float(np.abs(r.phi_deg[k]).max()) for r in runs)


def converged_beyond_3sigma_any_axis(runs: Sequence[RunResult]) -> int:
    """Epochs, over all runs and the whole run, flagged converged with the heading error beyond 3 heading σ or a
    level error beyond 3 level σ."""
    return sum(int((r.converged & ((np.abs(r.phi_deg[:, 2]) > 3.0 * r.heading_sigma_deg)
                                   | (np.abs(r.phi_deg[:, :2]).max(axis=1) > 3.0 * r.level_sigma_deg))).sum())
               for r in runs)


def _axes(v: np.ndarray) -> str:
    return " / ".join(f"{x:.4f}" for x in v)


def seed002_table(seeds: Sequence[int], progress: bool = True) -> tuple[str, dict[str, list[RunResult]]]:
    """The seed-002 table in Markdown and the runs of each variant."""
    lines = [f"seed 002 transfer alignment, {len(seeds)} seeds (RMS over seeds, deg, φ_E / φ_N / φ_U)", "",
             "| variant | slave @10 s | worst seed @10 s (any axis) | slave @60 s | mounting @60 s | "
             "in 2σ from 10 s (heading) | converged > 3σ (any axis, any time) |", "|---|---|---|---|---|---|---|"]
    all_runs: dict[str, list[RunResult]] = {}
    for label, overrides, faults in VARIANTS:
        runs = monte_carlo(SCENARIO, seeds, overrides, progress=progress, label=label,
                           aid_faults=faults and {"master": faults})
        all_runs[label] = runs
        honest = fine_honesty(runs, HONEST_FROM_S)
        beyond = converged_beyond_3sigma_any_axis(runs)
        mounting = np.sqrt(np.mean([r.mount_error_deg**2 for r in runs], axis=0))
        worst = worst_at(runs, AT_S[0])
        lines.append(f"| {label} | {_axes(rms_at(runs, AT_S[0]))} | {worst:.4f} | {_axes(rms_at(runs, AT_S[1]))} | "
                     f"{_axes(mounting)} | {100 * honest.inside_2sigma:.1f} % | {beyond} |")
    counters = summed_counters(all_runs[FAULTS_LABEL])
    lines += ["", f"{FAULTS_LABEL}: no master epochs {DROPOUT_S[0]:g}–{DROPOUT_S[1]:g} s, "
              f"{MASTER_FAULTS['repeated']} epochs sent twice, time stamps {LATE_S:g} s late "
              "(aiding.master.latency_s); counters summed over the seeds: " +
              ", ".join(f"{k} {v}" for k, v in sorted(counters.items()) if v)]
    return "\n".join(lines), all_runs


def plot_seed002(runs_by_variant: dict[str, list[RunResult]], path: str | Path) -> Path:
    """:func:`plot_heading_runs` of the seed-002 variants, the dropout shaded."""
    return plot_heading_runs(runs_by_variant, path, HONEST_FROM_S, {FAULTS_LABEL: (DROPOUT_S, ())},
                             "master dropout")


RATES_HZ = (10.0, 5.0, 2.0, 1.0)
"""Master INS rates of :func:`rate_table` (the scenario's own is 10 Hz)."""


def rate_table(seeds: Sequence[int], progress: bool = True, rates_hz: Sequence[float] = RATES_HZ,
               duration_s: float | None = None) -> tuple[str, dict[str, list[RunResult]]]:
    """Seed 002 (dual model, default configuration) with the master INS at each of ``rates_hz``: accuracy of the
    slave and the mounting, σ honesty and the counters (summed over seeds), in Markdown, and the runs per rate."""
    lines = [f"seed 002 with slower master INS, {len(seeds)} seeds (RMS over seeds, deg, φ_E / φ_N / φ_U; counters "
             "summed over seeds)", "",
             f"| master rate | slave @{AT_S[0]:g} s | slave @{AT_S[1]:g} s | mounting at the end | "
             f"in 2σ from {HONEST_FROM_S:g} s (heading) | converged > 3σ (any axis) | gaps | "
             "awaiting / unaided observations | velocity / attitude updates |", "|---|" + "---|" * 8]

    def row(label: str, runs: list[RunResult]) -> str:
        mounting = np.sqrt(np.mean([r.mount_error_deg**2 for r in runs], axis=0))
        c = summed_counters(runs)
        return (f"| {label} | {_axes(rms_at(runs, AT_S[0]))} | {_axes(rms_at(runs, AT_S[1]))} | "
                f"{_axes(mounting)} | {100 * fine_honesty(runs, HONEST_FROM_S).inside_2sigma:.1f} % | "
                f"{converged_beyond_3sigma_any_axis(runs)} | {stream_cells(c, 'master')} | "
                f"{c.get('master_vel_accepted', 0)} / {c.get('master_att_accepted', 0)} |")

    return rate_rows(SCENARIO, seeds, rates_hz, row, lines, progress, duration_s)


COMPARISON_AT_S = (2.0, 5.0, 10.0, 60.0)
LARGE_MOUNT_DEG = (60.0, -45.0, 120.0)
CLOSED_FORM, EKF, EKF_QUATERNION = "closed", "ekf", "ekf-quaternion"
COMPARISON_ROWS: tuple[tuple[str, str, tuple[float, float, float]], ...] = (
    ("closed form, velocity + attitude pairs (ours)", CLOSED_FORM, SEED002_MOUNT_DEG),
    ("additive-quaternion EKF, quaternion + velocity matching (seed)", EKF, SEED002_MOUNT_DEG),
    ("additive-quaternion EKF, quaternion matching alone", EKF_QUATERNION, SEED002_MOUNT_DEG),
    ("closed form, velocity + attitude pairs (ours)", CLOSED_FORM, LARGE_MOUNT_DEG),
    ("additive-quaternion EKF, quaternion + velocity matching (seed)", EKF, LARGE_MOUNT_DEG),
)
"""(label, method, mounting (heading, pitch, roll) deg) of the phase-1 comparison."""


def mounted_scenario(mount_deg: Sequence[float] = SEED002_MOUNT_DEG, name: str = SCENARIO) -> Scenario:
    """The seed-002 scenario (or its ``-ideal`` twin), the slave mounted ``mount_deg`` (heading, pitch, roll) off."""
    mount = tuple(float(v) for v in mount_deg)
    scenario = get_scenario(name)
    if mount == SEED002_MOUNT_DEG:
        return scenario
    return replace(scenario, name=f"{name} mounted {'/'.join(f'{v:g}' for v in mount)}°",
                   motion=seed002_flight(mount))


def ekf_run_once(scenario: Scenario, seed: int, config: Config | None = None,
                 velocity_matching: bool = True) -> RunResult:
    """The seed's phase 1 (:func:`~sinsalign.tools.transfer_ekf.run_transfer_ekf`) over one simulated seed,
    as :func:`~.evaluate.run_once` gives the pipeline's: φ at the configured output epochs, σ from the filter's
    covariance (``converged`` all False: the filter has no such test), the final mounting's error. The filter
    takes the master's noise as the configuration states it."""
    config = config or config_from_mapping({})
    scenario = scenario.for_seed(seed)
    chunks = list(simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, scenario.duration_s,
                           seed))
    t = np.concatenate([c.t for c in chunks])
    settings = EkfSettings(config.aiding.master.att_std_deg * DEG, config.aiding.master.vel_std_mps,
                           velocity_matching=velocity_matching)
    period = config.output.period_s
    output_t = period * np.arange(1, int(np.floor(scenario.duration_s / period + 1e-9)) + 1)
    history = run_transfer_ekf(t, np.concatenate([c.dtheta for c in chunks]), np.concatenate([c.dv for c in chunks]),
                               master_epochs(scenario, seed), scenario.grade, settings, output_t)
    phi = misalignment(dcm_from_quat(history.q_bs_n), scenario.motion.attitude(output_t)) / DEG
    mount_error = misalignment(dcm_from_quat(history.q_bs_bm[-1]), scenario.motion.mounting) / DEG
    return RunResult(seed, output_t, phi, history.heading_sigma_rad / DEG, history.level_sigma_rad / DEG,
                     np.zeros(len(output_t), dtype=bool), run_limit_deg(scenario, output_t),
                     mount_error_deg=mount_error)


def _comparison_task(args: tuple[str, tuple[float, float, float], int]) -> RunResult:
    """One seed of one row: (method, mounting deg, seed)."""
    method, mount_deg, seed = args
    scenario = mounted_scenario(mount_deg)
    if method == CLOSED_FORM:
        return run_once(scenario, seed, config_from_mapping(COARSE_ONLY))
    return ekf_run_once(scenario, seed, velocity_matching=method == EKF)


def comparison_runs(method: str, mount_deg: Sequence[float], seeds: Sequence[int], progress: bool = True,
                    label: str = "", workers: int | None = None) -> list[RunResult]:
    """Every seed of one method on one mounting (in parallel processes), in seed order. The closed form on the
    seed's mounting is ``monte_carlo("seed002", seeds, COARSE_ONLY)``."""
    tasks = [(method, tuple(float(v) for v in mount_deg), s) for s in seeds]
    return run_parallel(_comparison_task, tasks, label or method, progress, workers)


def within_2sigma(runs: Sequence[RunResult], t_s: float) -> float:
    """Fraction of the runs' φ components at the epoch nearest ``t_s`` within twice their σ (level σ for φ_E,
    φ_N, heading σ for φ_U)."""
    k = nearest_epoch(runs, t_s)
    inside = [np.abs(r.phi_deg[k]) <= 2.0 * np.array([r.level_sigma_deg[k]] * 2 + [r.heading_sigma_deg[k]])
              for r in runs]
    return float(np.mean(inside))


def phase1_comparison(seeds: Sequence[int], progress: bool = True) -> str:
    """Markdown table: the slave's attitude error of our closed-form phase 1 and of the seed's additive-quaternion
    EKF at 2, 5, 10 (and 60) s, on the seed's mounting and on a large one."""
    heads = " | ".join(f"@{s:g} s" for s in COMPARISON_AT_S)
    lines = [f"seed 002 phase 1 alone, {len(seeds)} seeds: slave's attitude error, RMS over seeds, deg, "
             "φ_E / φ_N / φ_U", "",
             f"| phase 1 | mounting (°) | {heads} | worst seed @10 s | within 2σ @10 s |",
             "|---|---|" + "---|" * len(COMPARISON_AT_S) + "---|---|"]
    for label, method, mount in COMPARISON_ROWS:
        runs = comparison_runs(method, mount, seeds, progress, f"{label} {mount}")
        k = nearest_epoch(runs, 10.0)
        worst = max(float(np.abs(r.phi_deg[k]).max()) for r in runs)
        cells = " | ".join(_axes(rms_at(runs, s)) for s in COMPARISON_AT_S)
        lines.append(f"| {label} | {'/'.join(f'{v:g}' for v in mount)} | {cells} | {worst:.4f} | "
                     f"{100 * within_2sigma(runs, 10.0):.0f} % |")
    lines += ["", "The EKF starts at the first master epoch (0.1 s) from the master's attitude (the mounting taken "
              "as the identity), with the mounting quaternion's vector part at 1σ = 0.5 and the slave's biases at "
              "their datasheet σ; it predicts with the slave's increments in 0.1-s steps and updates at every "
              "10-Hz master epoch. Its states hold the biases, so it keeps learning after 10 s; the closed form "
              "has none (phase 2 takes them over). Quaternion matching alone (the seed's measurement, whose "
              "mounting is known) cannot see an unknown mounting's rotation about the wing rock's axis (φ_N here). "
              "At 60/−45/120° (a 153° rotation) the first velocity innovations, linearised that far from the "
              "truth, go into the accelerometer bias (metres per s² after one update): the filter settles on a "
              "wrong attitude with a σ of thousandths of a degree."]
    return "\n".join(lines)


MEMS_SCENARIO = "transfer-mems"
EARLY_S = (5.0, 30.0)
"""Straight driving: the mount's yaw only from the speed's changes."""
LATE_FROM_S = 40.0
"""Ten seconds into the rolls."""
EFFICIENT_AT_S = 20.0
"""Driving straight after the hand-over: where the filter's heading σ is set against the data's bound."""
SETTLED_FROM_S = 76.0
"""After the rolls."""
HANDOVER_VARIANTS: tuple[tuple[str, dict], ...] = (
    ("default: phase 1 to 0.2°, or stalled within its linear range (then run from the start); lever arm estimated", {}),
    ("phase 1 until 0.2° only", {"aiding": {"master": {"linear_sigma_deg": 0.2}}}),
    ("lever arm taken as configured (0)", {"aiding": {"master": {"lever_sigma_m": 0.0}}}),
)
"""(label, configuration overrides) of the hand-over table, each on the good and the poor slave."""


def _heading(r: RunResult) -> np.ndarray:
    return r.phi_deg[:, 2]


def _every_axis(r: RunResult) -> np.ndarray:
    return np.abs(r.phi_deg).max(axis=1)


def _mounting(r: RunResult) -> np.ndarray:
    return np.abs(r.mount_phi_deg).max(axis=1)


def _worst(runs: Sequence[RunResult], values: Callable[[RunResult], np.ndarray], mask: Callable[[RunResult], np.ndarray]
           ) -> float | None:
    """The largest |value| over the runs' epochs where ``mask``; None if no epoch is in it."""
    picked = [np.abs(values(r)[mask(r)]) for r in runs]
    picked = [p for p in picked if p.size]
    return float(max(p.max() for p in picked)) if picked else None


def _cell(value: float | None, digits: int = 3) -> str:
    return "—" if value is None else f"{value:.{digits}f}"


def straight_heading_limit_deg(vehicle: VehicleMotion, master: MasterSpec, t_s: float) -> float:
    """The smallest 1-σ (deg) any estimator can have on the slave's heading at ``t_s`` while the vehicle drives
    straight (the Cramér-Rao bound of the lateral velocity channel).

    Driving straight, the heading error ψ shows only in the lateral velocity: δv_lat(t) = ψ Δv_along(t) + c t + d,
    with c the tilt about the track times g plus the lateral accelerometer bias (one unknown: the mount's level is
    free) and d the start velocity's error (the master's stated velocity noise). So only the speed's curvature,
    what a line through the speed leaves, carries ψ, against the master's velocity noise at each of its epochs.
    """
    t = np.arange(0.0, t_s + 1e-9, 1.0 / master.rate_hz)
    C_b_n, _, V_n = vehicle.velocity_n(t)
    forward = C_b_n[0, :, 1]                     # the vehicle's forward axis in n at the start
    v_along = V_n @ forward
    H = np.column_stack((v_along - v_along[0], t, np.ones_like(t))) / master.vel_noise_mps
    information = H.T @ H
    information[2, 2] += 1.0 / master.vel_noise_mps**2
    # ψ's information once c and d are given their best values (the Schur complement): 0 for a steady speed
    heading_information = information[0, 0] - information[0, 1:] @ np.linalg.solve(information[1:, 1:],
                                                                                     information[1:, 0])
    return float(1.0 / np.sqrt(heading_information)) / DEG if heading_information > 0.0 else np.inf


def straight_limit_line(seeds: Sequence[int], runs: Sequence[RunResult]) -> str:
    """The poor slave's heading against :func:`straight_heading_limit_deg`, per seed: at the start of
    :data:`EARLY_S` the bound's range and the worst error in units of it; at :data:`EFFICIENT_AT_S` (driving
    straight, after the hand-over) the filter's σ without its reported margin in units of the bound."""
    scenario = get_scenario(MEMS_SCENARIO)
    vehicles = [scenario.for_seed(s).motion.vehicle for s in seeds]
    limits = np.array([straight_heading_limit_deg(v, scenario.master, EARLY_S[0]) for v in vehicles])
    k = nearest_epoch(runs, EARLY_S[0])
    ratio = np.array([abs(r.phi_deg[k, 2]) for r in runs]) / limits
    later = np.array([straight_heading_limit_deg(v, scenario.master, EFFICIENT_AT_S) for v in vehicles])
    k = nearest_epoch(runs, EFFICIENT_AT_S)
    efficiency = np.array([r.heading_sigma_deg[k] / KalmanMode.sigma_margin for r in runs]) / later
    return (f"`{MEMS_SCENARIO}`, heading at {EARLY_S[0]:g} s: the smallest σ any estimator can have while driving "
            f"straight (the Cramér-Rao bound of the lateral velocity) is {limits.min():.2f}° to {limits.max():.2f}° "
            f"by seed ({limits.max():.2f}° on seed {seeds[int(limits.argmax())]}); the default's error is at most "
            f"{ratio.max():.1f} times the seed's bound (seed {seeds[int(ratio.argmax())]}), "
            f"median {np.median(ratio):.1f}. At {EFFICIENT_AT_S:g} s the bound is {later.min():.2f}° to "
            f"{later.max():.2f}° and the filter's σ (without the reported margin) {efficiency.min():.2f} to "
            f"{efficiency.max():.2f} times it.")


def handover_row(label: str, runs: Sequence[RunResult]) -> str:
    """One row of :func:`handover_table`: worst heading while driving straight and from 10 s into the rolls, worst
    axis at 10 s and after the rolls, worst mounting after the rolls, RMS at the end, σ honesty."""
    end = runs[0].t[-1]
    at_10 = worst_at(runs, AT_S[0])
    honest = fine_honesty(runs, HONEST_FROM_S)
    return (f"| {label} | {_cell(_worst(runs, _heading, lambda r: (r.t >= EARLY_S[0]) & (r.t <= EARLY_S[1])), 2)} | "
            f"{_cell(_worst(runs, _heading, lambda r: r.t >= LATE_FROM_S))} | {at_10:.3f} | "
            f"{_cell(_worst(runs, _every_axis, lambda r: r.t > SETTLED_FROM_S))} | "
            f"{_cell(_worst(runs, _mounting, lambda r: r.t > SETTLED_FROM_S))} | {_axes(rms_at(runs, end))} | "
            f"{100 * honest.inside_2sigma:.1f} % | {converged_beyond_3sigma_any_axis(runs)} |")


def handover_table(seeds: Sequence[int], progress: bool = True) -> tuple[str, dict[str, list[RunResult]]]:
    """The hand-over table in Markdown: each variant on the poor slave (``transfer-mems``) and the good one
    (seed 002), worst over the seeds; and the runs by variant."""
    lines = [f"transfer alignment, good and poor slave, {len(seeds)} seeds (worst over the seeds and epochs, deg; "
             "RMS at the end per axis φ_E / φ_N / φ_U)", "",
             f"| scenario, variant | heading {EARLY_S[0]:g}–{EARLY_S[1]:g} s | heading from {LATE_FROM_S:g} s | "
             f"any axis at 10 s | any axis after {SETTLED_FROM_S:g} s | mounting after {SETTLED_FROM_S:g} s | "
             "RMS at the end | heading in 2σ from 10 s | converged > 3σ (any axis) |",
             "|---|---|---|---|---|---|---|---|---|"]
    all_runs: dict[str, list[RunResult]] = {}
    for name in (MEMS_SCENARIO, SCENARIO):
        for label, overrides in HANDOVER_VARIANTS:
            runs = monte_carlo(name, seeds, overrides, progress=progress, label=label)
            all_runs[f"{name}: {label}"] = runs
            lines.append(handover_row(f"`{name}`: {label}", runs))
    lines += ["", straight_limit_line(seeds, all_runs[f"{MEMS_SCENARIO}: {HANDOVER_VARIANTS[0][0]}"])]
    return "\n".join(lines), all_runs


def plot_handover(runs_by_variant: dict[str, list[RunResult]], path: str | Path) -> Path:
    """:func:`plot_heading_runs` of the poor slave's variants."""
    mems = {k: v for k, v in runs_by_variant.items() if k.startswith(MEMS_SCENARIO)}
    return plot_heading_runs(mems, path, HONEST_FROM_S)

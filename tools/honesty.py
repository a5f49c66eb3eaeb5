"""The honesty sweep (``sinsalign eval honesty``): every mode on the motion it is made for, with a navigation-grade,
a tactical and a MEMS IMU, each with a datasheet that states it and one that understates it tenfold, and the MEMS IMU
with a tactical datasheet.

A cell runs its seeds through the mode as a log would (:func:`~.evaluate.run_once`) and counts the records
reported ``converged`` with the heading or a level error beyond 3σ (asked: none) and the share of records from
:data:`HONEST_FROM_S` whose heading and level errors are both within 2σ (asked: at least 90 %).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from sinsalign.service.align.conventions import DH_TO_RS, DRH_TO_RRS, UG_TO_MS2
from sinsalign.service.align.sensor_model import SensorGrade
from sinsalign.service.config import config_from_mapping

from .evaluate import RunResult, run_once, run_parallel
from .sim.imu import ImuErrors
from .sim.scenarios import Scenario, get_scenario, grade_of, turntable_index

HONEST_FROM_S = 10.0
"""Records from this time (s) count for the share inside 2σ: the first seconds' σ is the coarse stage's guess."""
UNDERSTATED = 10.0
"""An understated datasheet states every figure (biases and noise densities) this many times better than the IMU."""
STATED = "stated"
UNDERSTATED_10 = "understated 10×"
AS_TACTICAL = "stated as tactical"
DATASHEETS = {"navigation": (STATED, UNDERSTATED_10), "tactical": (STATED, UNDERSTATED_10),
              "MEMS": (STATED, UNDERSTATED_10, AS_TACTICAL)}
"""Per grade, the datasheets its logs carry: its own figures, each :data:`UNDERSTATED` times better, or (a MEMS IMU)
the tactical grade's figures (its gyro bias 200 times better, its noise some times)."""


@dataclass(frozen=True, slots=True)
class Case:
    """A mode on its motion: the scenario that carries it and how long a run lasts (s)."""

    mode: str
    motion: str
    scenario: str
    duration_s: float


CASES = (Case("fixed base", "still", "static", 600.0),
         Case("fixed base", "swinging", "seed000-swing", 200.0),
         Case("fixed base", "turning (3 positions)", "turntable-index", 900.0),
         Case("odometer", "driving", "seed003-20", 150.0),
         Case("GNSS", "flying", "seed004", 120.0),
         Case("odometer + GNSS", "driving", "seed003-odo-gnss", 150.0),
         Case("transfer", "flying", "seed002", 60.0))

IMUS = {"navigation": (0.01, 0.002, 50.0, 50.0), "tactical": (1.0, 0.05, 300.0, 100.0),
        "MEMS": (200.0, 0.3, 2000.0, 100.0)}
"""Per grade: gyro bias (°/h), angle random walk (°/√h), accelerometer bias (µg), velocity random walk (µg/√Hz)."""


def imu_errors(grade: str) -> ImuErrors:
    """The ``grade``'s errors (:data:`IMUS`), each bias of the stated size (its sign drawn per seed)."""
    gyro_bias, arw, acc_bias, vrw = IMUS[grade]
    return ImuErrors(gyro_bias_rad_s=(gyro_bias * DH_TO_RS,) * 3, gyro_arw_rad_rts=arw * DRH_TO_RRS,
                     acc_bias_ms2=(acc_bias * UG_TO_MS2,) * 3, acc_vrw_ms_rts=vrw * UG_TO_MS2)


def cell_scenario(case: Case, grade: str, datasheet: str) -> Scenario:
    """The case's scenario with the grade's IMU (bias signs drawn per seed), its log stating the truth, every
    figure :data:`UNDERSTATED` times better, or the tactical grade's figures (``datasheet``)."""
    base = get_scenario(case.scenario)
    if case.scenario == "turntable-index":
        base = replace(base, motion=turntable_index(3))
    errors = imu_errors(grade)
    truth = grade_of(errors, base.rate_hz)
    stated = {STATED: truth, AS_TACTICAL: grade_of(imu_errors("tactical"), base.rate_hz),
              UNDERSTATED_10: SensorGrade(*(figure / UNDERSTATED for figure in (
                  truth.gyro_bias_rad_s, truth.gyro_arw_rad_rts, truth.acc_bias_ms2, truth.acc_vrw_ms_rts)))}[datasheet]
    return replace(base, errors=errors, errors_for_seed=None, random_bias_signs=True, grade=stated,
                   duration_s=case.duration_s)


def _run_cell(task: tuple[int, str, str, int]) -> RunResult:
    """One seed of one cell: (case index, grade, datasheet, seed)."""
    case, grade, datasheet, seed = task
    return run_once(cell_scenario(CASES[case], grade, datasheet), seed, config_from_mapping({}))


@dataclass(frozen=True, slots=True)
class CellFigures:
    converged_beyond_3sigma: int
    inside_2sigma: float
    records: int


def cell_figures(runs: Sequence[RunResult], from_s: float = HONEST_FROM_S) -> CellFigures:
    """Converged records beyond 3σ (heading or level) and the share within 2σ (heading and level) from ``from_s``."""
    beyond, inside, total = 0, 0, 0
    for r in runs:
        heading = np.abs(r.phi_deg[:, 2]) / r.heading_sigma_deg
        level = np.abs(r.phi_deg[:, :2]).max(axis=1) / r.level_sigma_deg
        ratio = np.maximum(heading, level)
        beyond += int((r.converged & (ratio > 3.0)).sum())
        late = r.t >= from_s - 1e-9
        inside += int((ratio[late] <= 2.0).sum())
        total += int(late.sum())
    return CellFigures(beyond, inside / max(total, 1), total)


COLUMNS = tuple((grade, datasheet) for grade in IMUS for datasheet in DATASHEETS[grade])
"""The table's columns: (grade, datasheet)."""
CELLS = tuple((i, grade, datasheet) for i in range(len(CASES)) for grade, datasheet in COLUMNS)
"""Every cell of the sweep: (case index, grade, datasheet)."""


def sweep(seeds: Sequence[int], cells: Sequence[tuple[int, str, str]] = CELLS, progress: bool = True
          ) -> dict[tuple[int, str, str], list[RunResult]]:
    """The runs of every cell over ``seeds`` (in parallel processes)."""
    tasks = [(*cell, seed) for cell in cells for seed in seeds]
    results = run_parallel(_run_cell, tasks, "honesty sweep", progress)
    return {cell: results[k * len(seeds):(k + 1) * len(seeds)] for k, cell in enumerate(cells)}


def honesty_table(seeds: Sequence[int], progress: bool = True
                  ) -> tuple[str, dict[tuple[int, str, str], list[RunResult]]]:
    """The sweep's table in Markdown (each cell: converged records beyond 3σ / share within 2σ), and its runs."""
    runs = sweep(seeds, progress=progress)
    columns = COLUMNS
    lines = [f"honesty sweep, {len(seeds)} seeds per cell (seeds {seeds[0]}–{seeds[-1]}): converged records beyond "
             f"3σ / records within 2σ from {HONEST_FROM_S:g} s (heading and level); asked: 0 / ≥ 90 %", "",
             "| mode | motion | " + " | ".join(f"{grade}, {datasheet}" for grade, datasheet in columns) + " |",
             "|---|---|" + "---|" * len(columns)]
    failing = 0
    for i, case in enumerate(CASES):
        cells = []
        for grade, datasheet in columns:
            figures = cell_figures(runs[(i, grade, datasheet)])
            ok = figures.converged_beyond_3sigma == 0 and figures.inside_2sigma >= 0.9
            failing += not ok
            cells.append(f"{'' if ok else '**'}{figures.converged_beyond_3sigma} / "
                         f"{100 * figures.inside_2sigma:.0f} %{'' if ok else '**'}")
        lines.append(f"| {case.mode} | {case.motion} | " + " | ".join(cells) + " |")
    imus = "; ".join(f"{grade} {g:g}°/h, {a:g}°/√h, {b:g} µg, {v:g} µg/√Hz" for grade, (g, a, b, v) in IMUS.items())
    lines += ["", f"Cells that miss either figure (bold): {failing} of {len(CASES) * len(columns)}. IMUs: {imus}; an "
              f"understated datasheet states every figure {UNDERSTATED:g}× better; a MEMS IMU stated as tactical has "
              "the tactical IMU's figures in its log."]
    return "\n".join(lines), runs


def plot_honesty(runs: dict[tuple[int, str, str], list[RunResult]], path: str | Path) -> Path:
    """PNG: per cell, the worst |error|/σ of each seed from :data:`HONEST_FROM_S` (heading or level), one panel per
    case, 3 and 2 marked."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(len(CASES), 1, figsize=(10, 2.0 * len(CASES)), sharex=True)
    labels = [f"{grade}{'' if datasheet == STATED else ' ÷10' if datasheet == UNDERSTATED_10 else ' as tact.'}"
              for grade, datasheet in COLUMNS]
    for i, (case, ax) in enumerate(zip(CASES, axes, strict=True)):
        for j, (grade, datasheet) in enumerate(COLUMNS):
            worst = []
            for r in runs[(i, grade, datasheet)]:
                late = r.t >= HONEST_FROM_S
                ratio = np.maximum(np.abs(r.phi_deg[late, 2]) / r.heading_sigma_deg[late],
                                   np.abs(r.phi_deg[late, :2]).max(axis=1) / r.level_sigma_deg[late])
                worst.append(float(ratio.max()) if len(ratio) else 0.0)
            ax.scatter(np.full(len(worst), j), worst, s=10)
        ax.axhline(3.0, color="r", lw=0.8)
        ax.axhline(2.0, color="orange", lw=0.8, ls="--")
        ax.set_yscale("log")
        ax.set_ylabel("max |err|/σ")
        ax.set_title(f"{case.mode}, {case.motion}", fontsize=9)
    axes[-1].set_xticks(range(len(labels)), labels)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path

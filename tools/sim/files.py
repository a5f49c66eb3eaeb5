"""Write a simulated run as the pinned IMU log plus a truth log.

The IMU log's comments carry the site, the rate, the datasheet grade (unless the scenario states none)
and the actual simulated biases (``sim_gyro_bias_deg_h``, ``sim_acc_bias_ug``, body axes), so any tool
can compute the physical limit of that run. The truth log has ``t,heading_deg,pitch_deg,roll_deg,qw,qx,qy,qz``.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sinsalign.protocol.imu_binary import SUFFIX, BinaryLogWriter
from sinsalign.protocol.imu_log import TRUTH_COLUMNS, CsvLogWriter, LogHeader, write_header, write_rows
from sinsalign.service.align.conventions import DEG, DH_TO_RS, UG_TO_MS2, euler_from_dcm, quat_from_dcm

from .aiding import scenario_aids, write_aiding_log
from .imu import simulate
from .scenarios import Scenario


@dataclass(frozen=True, slots=True)
class SimulatedFiles:
    imu_csv: Path
    truth_csv: Path
    odo_csv: Path | None = None
    gnss_csv: Path | None = None
    master_csv: Path | None = None


def _vector(values: tuple[float, ...] | np.ndarray, scale: float) -> str:
    return " ".join(f"{v / scale:.12g}" for v in values)


def log_keys(scenario: Scenario, seed: int) -> dict[str, object]:
    e = scenario.errors
    return {
        "lat_deg": f"{scenario.site.lat / DEG:.12g}", "lon_deg": f"{scenario.site.lon / DEG:.12g}",
        "height_m": f"{scenario.site.height_m:.12g}", "rate_hz": f"{scenario.rate_hz:.12g}",
        **{key: f"{value:.12g}" for key, value in (scenario.stated_datasheet() or {}).items()},
        "sim_gyro_bias_deg_h": _vector(e.gyro_bias_rad_s, DH_TO_RS),
        "sim_acc_bias_ug": _vector(e.acc_bias_ms2, UG_TO_MS2),
        "scenario": scenario.name, "seed": seed, "source": "sinsalign sim",
    }


def simulated_biases(header: LogHeader) -> tuple[np.ndarray, np.ndarray] | None:
    """(gyro bias rad/s, acc bias m/s²) in body axes from a simulated log's comments, if present."""
    try:
        gyro = np.array(str(header.values["sim_gyro_bias_deg_h"]).split(), dtype=float) * DH_TO_RS
        acc = np.array(str(header.values["sim_acc_bias_ug"]).split(), dtype=float) * UG_TO_MS2
    except (KeyError, ValueError):
        return None
    return (gyro, acc) if gyro.shape == (3,) and acc.shape == (3,) else None


def write_simulation(scenario: Scenario, seed: int, out_dir: str | Path, stem: str = "imu",
                     binary: bool = False) -> SimulatedFiles:
    """Simulate ``scenario`` with ``seed`` into OUT_DIR/STEM.csv (``binary``: the log's binary form, STEM.sbin)
    and OUT_DIR/STEM_truth.csv."""
    scenario = scenario.for_seed(seed)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    aids = {aid.kind: aid for aid in scenario_aids(scenario, seed)}
    files = SimulatedFiles(out / f"{stem}{SUFFIX if binary else '.csv'}", out / f"{stem}_truth.csv",
                           *(out / f"{stem}_{kind}.csv" if kind in aids else None
                             for kind in ("odo", "gnss", "master")))
    for kind, aid in aids.items():
        write_aiding_log(getattr(files, f"{kind}_csv"), kind, aid.epochs, aid.log_keys)
    keys = log_keys(scenario, seed)
    imu = (BinaryLogWriter(open(files.imu_csv, "wb"), keys) if binary   # noqa: SIM115 (closed below)
           else CsvLogWriter(open(files.imu_csv, "w", encoding="utf-8"), keys))   # noqa: SIM115
    try:
        with open(files.truth_csv, "w", encoding="utf-8") as truth:
            write_header(truth, {"scenario": scenario.name, "seed": seed}, TRUTH_COLUMNS)
            for chunk in simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz,
                                  scenario.duration_s, seed):
                imu.rows(np.column_stack((chunk.t, chunk.dtheta, chunk.dv)))
                heading, pitch, roll = euler_from_dcm(chunk.C_b_n_true)
                write_rows(truth, np.column_stack((chunk.t, heading / DEG, pitch / DEG, roll / DEG,
                                                   quat_from_dcm(chunk.C_b_n_true))))
    finally:
        imu.close()
    return files

"""Configuration: defaults < TOML file < command-line overrides, validated at start-up.

Every key lives in one table; an unknown key or a value of the wrong type or range stops the
start with a message that names the key. Units are in the key names.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from ..protocol.keys import UnitKeys
from ..protocol.messages import AIDING_FIELDS as AIDING_KINDS
from .align.compass import GainSchedule
from .align.solvers import ALIGNMENT_SOLVERS, SOLVERS


class ConfigError(ValueError):
    """A configuration problem; the message names the key."""


@dataclass(frozen=True, slots=True)
class SensorConfig:
    """Datasheet 1-sigma figures of the IMU; a log's own comment keys override them."""

    gyro_bias_deg_h: float = 0.01
    gyro_arw_deg_rth: float = 0.001
    acc_bias_ug: float = 50.0
    acc_vrw_ug_rthz: float = 5.0


@dataclass(frozen=True, slots=True)
class AlignmentConfig:
    """Coarse alignment (inertial frame, seed 000)."""

    solver: str = "auto"
    """One of :data:`~.align.solvers.ALIGNMENT_SOLVERS`; "auto": OPREQ, or GLS where the gyro's walk dominates."""
    request_rho: float = 0.01
    obs_interval_s: float = 0.1
    disturbance_velocity_mps: float = 1e-3
    converged_heading_sigma_deg: float = 0.1
    swing_bias: bool = True
    """Estimate the accelerometer bias seen through a swinging body and take its term out of α (fixed base)."""


@dataclass(frozen=True, slots=True)
class FineConfig:
    """Compass fine alignment (seed 001): hand-over, gain schedule, stored-data passes.

    The schedule gives loop bandwidths σ (rad/s) at loop times (s since the hand-over), geometric
    in between; azimuth σ 0 = levelling only. Defaults suit navigation-grade sensors. A "sigma"
    hand-over waits at least ``handover_min_s`` of coarse alignment whatever the σ.
    """

    enabled: bool = True
    handover: str = "sigma"
    handover_sigma_deg: float = 0.05
    handover_min_s: float = 10.0
    handover_time_s: float = 60.0
    handover_schedule_s: float = 31.0
    control_interval_s: float = 0.1
    schedule_time_s: tuple[float, ...] = (0.0, 30.0, 31.0, 100.0, 200.0, 300.0)
    level_sigma: tuple[float, ...] = (0.5, 0.5, 0.05, 0.04, 0.03, 0.02)
    azimuth_sigma: tuple[float, ...] = (0.0, 0.0, 0.05, 0.03, 0.015, 0.01)
    stored_data_s: float = 80.0
    stored_pairs: int = 3
    live_pass_steps: int = 40


@dataclass(frozen=True, slots=True)
class AidingConfig:
    """Aided modes (selected by the aids given, e.g. ``--aid odo=FILE``): streams, coarse levels, Kalman.

    Odometer / DVL: latency of its time stamps, noise (a log's ``vel_std_mps`` overrides), lever arm
    from the IMU (body axes, m), and the Kalman stage's priors of its scale factor and lever arm
    (0: not estimated). GNSS: latency of its time stamps, antenna lever arm from the IMU (body axes,
    m; a GNSS log's ``# lever_*_m`` keys override it), the coarse stage's formula (``vif`` velocity
    integration, ``pif`` position integration: positions only), the fixes' noise per ENU axis (a log's
    ``vel_std_mps`` / ``pos_std_m`` override), and when the Kalman stage takes over (s of alignment).
    Master INS (transfer alignment): latency, the lever arm from the master's point to the slave IMU
    (master body axes, m; a master log's ``# lever_*_m`` keys override), its attitude and velocity
    noise (a log's ``att_std_deg`` / ``vel_std_mps`` override), and the switch from the large-angle
    phase to the Kalman stage: at ``master_handover_s`` if set (the seed's fixed 10 s), else once
    phase 1's σ is at most ``master_handover_sigma_deg``, or at most ``master_linear_sigma_deg`` (the
    filter's linear range: phase 1 hands its errors over with their correlations) and no longer improving,
    as with a MEMS slave that never reaches the first. The Kalman stage estimates the lever arm as
    well, from the configured one with the 1-sigma ``master_lever_sigma_m`` per axis (0: taken as known).
    A rough nominal
    mounting ``master_mount_deg`` (heading, pitch, roll of C_bs^bm; empty: none) with its 1-sigma
    ``master_mount_sigma_deg`` gives the slave an attitude until phase 1 has resolved the mounting.
    Coarse: the multistage window (s, bounded store of window / obs interval rows), its levels, how
    often they are re-run, the solver of each level. ``max_gap_s``: epochs further apart are not
    interpolated across. ``gate_chi2``: innovation gate of the Kalman stage.
    ``handover_heading_sigma_deg``: the Kalman stage starts only from a window whose heading σ is at
    most this (a linear filter started several degrees off grows overconfident); a full window above it
    keeps the coarse stage, and says so.
    Daemon: ``inputs`` lists the aiding kinds it subscribes to (``…/aid/<kind>`` on Zenoh, serial
    aiding frames) and selects the aided mode; an IMU sample waits (data time) for the aiding epoch after
    it up to the stream's usual interval plus ``max_wait_s`` (its latency and transport delay).
    """

    odo_latency_s: float = 0.0
    odo_std_mps: float = 0.03
    odo_lever_m: tuple[float, ...] = (0.0, 0.0, 0.0)
    odo_scale_sigma: float = 0.0
    odo_lever_sigma_m: float = 0.0
    gnss_latency_s: float = 0.0
    gnss_lever_m: tuple[float, ...] = (0.0, 0.0, 0.0)
    gnss_formula: str = "vif"
    gnss_vel_std_mps: float = 0.1
    gnss_pos_std_m: float = 2.0
    gnss_handover_s: float = 30.0
    master_latency_s: float = 0.0
    master_lever_m: tuple[float, ...] = (0.0, 0.0, 0.0)
    master_mount_deg: tuple[float, ...] = ()
    master_mount_sigma_deg: float = 5.0
    master_att_std_deg: float = 0.001
    master_vel_std_mps: float = 0.005
    master_handover_s: float = 0.0
    master_handover_sigma_deg: float = 0.2
    master_linear_sigma_deg: float = 5.0
    master_lever_sigma_m: float = 1.0
    window_s: float = 120.0
    levels: int = 10
    relevel_interval_s: float = 1.0
    solver: str = "centred"
    max_gap_s: float = 0.5
    gate_chi2: float = 16.3
    handover_heading_sigma_deg: float = 1.0
    inputs: tuple[str, ...] = ()
    max_wait_s: float = 0.5


HANDOVERS = ("sigma", "time")
GNSS_FORMULAS = ("vif", "pif")
ZENOH_MODES = ("", "peer", "client", "router")


@dataclass(frozen=True, slots=True)
class DisturbanceConfig:
    """A base that moves although the alignment assumes it fixed in position (service/align/disturbance.py).

    Every ``check_interval_s`` the horizontal velocity gained over the last ``window_s`` is checked; above
    ``velocity_threshold_mps`` the base is moving: ``disturbed``, never converged, until it has been at rest for
    ``hold_s``. Then ``action = "restart"`` starts the alignment over if the base really went somewhere (and the
    restarted alignment stays disturbed for ``hold_s`` more); ``"report"`` only flags.
    """

    enabled: bool = True
    velocity_threshold_mps: float = 0.1
    window_s: float = 2.0
    check_interval_s: float = 0.1
    hold_s: float = 10.0
    action: str = "restart"


DISTURBANCE_ACTIONS = ("restart", "report")


@dataclass(frozen=True, slots=True)
class SiteConfig:
    """Where the live IMU sits (a log states its own site in its comment keys)."""

    lat_deg: float = 32.0
    lon_deg: float = 118.0
    height_m: float = 0.0


@dataclass(frozen=True, slots=True)
class ImuConfig:
    """The live IMU: nominal sample rate (a log states its own) and its measurement ranges: an increment beyond
    range × interval (twice, for the interval's jitter) cannot come from the sensor and is dropped as a bad sample.
    The defaults cover MEMS and tactical units (2000°/s, 100 g); set the datasheet's."""

    rate_hz: float = 200.0
    gyro_range_deg_s: float = 2000.0
    acc_range_g: float = 100.0


@dataclass(frozen=True, slots=True)
class SerialConfig:
    """The serial input (RS-422 IMU, or a pty on a bench); an empty path means no serial input."""

    path: str = ""
    baud: int = 921600
    reconnect_max_s: float = 2.0


@dataclass(frozen=True, slots=True)
class ZenohConfig:
    """The Zenoh session and keys. Default: peer listening on tcp/127.0.0.1:7447 (loopback only),
    multicast scouting off. An empty mode, listen or connect leaves it to ``config_file`` (if any)."""

    mode: str = ""
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    config_file: str = ""
    prefix: str = "sinsalign"
    unit: str = "unit1"
    imu_input: bool = False


@dataclass(frozen=True, slots=True)
class DaemonConfig:
    status_period_s: float = 1.0
    record_path: str = ""
    max_bridge_samples: int = 5


@dataclass(frozen=True, slots=True)
class OutputConfig:
    period_s: float = 1.0


@dataclass(frozen=True, slots=True)
class Config:
    sensor: SensorConfig = field(default_factory=SensorConfig)
    alignment: AlignmentConfig = field(default_factory=AlignmentConfig)
    fine: FineConfig = field(default_factory=FineConfig)
    disturbance: DisturbanceConfig = field(default_factory=DisturbanceConfig)
    aiding: AidingConfig = field(default_factory=AidingConfig)
    site: SiteConfig = field(default_factory=SiteConfig)
    imu: ImuConfig = field(default_factory=ImuConfig)
    serial: SerialConfig = field(default_factory=SerialConfig)
    zenoh: ZenohConfig = field(default_factory=ZenohConfig)
    daemon: DaemonConfig = field(default_factory=DaemonConfig)
    output: OutputConfig = field(default_factory=OutputConfig)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _check(config: Config) -> Config:
    a, s, o, f = config.alignment, config.sensor, config.output, config.fine
    if a.solver not in ALIGNMENT_SOLVERS:
        raise ConfigError(f"alignment.solver: {a.solver!r} is not one of {', '.join(ALIGNMENT_SOLVERS)}")
    z = config.zenoh
    if z.mode not in ZENOH_MODES:
        raise ConfigError(f"zenoh.mode: {z.mode!r} is not one of {', '.join(ZENOH_MODES[1:])}")
    for key, text in (("zenoh.prefix", z.prefix), ("zenoh.unit", z.unit)):
        try:
            UnitKeys(z.prefix if key == "zenoh.prefix" else "p", text if key == "zenoh.unit" else "u")
        except ValueError as exc:
            raise ConfigError(f"{key}: {exc}") from None
    ad = config.aiding
    if ad.solver not in SOLVERS or ad.solver == "gls":
        raise ConfigError(f"aiding.solver: {ad.solver!r} is not one of {', '.join(s for s in SOLVERS if s != 'gls')} "
                          "(gls models a fixed base)")
    unknown = [k for k in ad.inputs if k not in AIDING_KINDS]
    if unknown or len(set(ad.inputs)) != len(ad.inputs):
        raise ConfigError(f"aiding.inputs: {list(ad.inputs)} must name distinct kinds among {', '.join(AIDING_KINDS)}")
    if len(ad.gnss_lever_m) != 3:
        raise ConfigError(f"aiding.gnss_lever_m: expected 3 numbers (body x, y, z in m), got {list(ad.gnss_lever_m)}")
    if ad.gnss_formula not in GNSS_FORMULAS:
        raise ConfigError(f"aiding.gnss_formula: {ad.gnss_formula!r} is not one of {', '.join(GNSS_FORMULAS)}")
    if len(ad.master_mount_deg) not in (0, 3):
        raise ConfigError(f"aiding.master_mount_deg: expected 3 numbers (heading, pitch, roll in deg) or none, got "
                          f"{list(ad.master_mount_deg)}")
    if len(ad.master_lever_m) != 3:
        raise ConfigError(f"aiding.master_lever_m: expected 3 numbers (master body x, y, z in m), got "
                          f"{list(ad.master_lever_m)}")
    if len(ad.odo_lever_m) != 3:
        raise ConfigError(f"aiding.odo_lever_m: expected 3 numbers (body x, y, z in m), got {list(ad.odo_lever_m)}")
    if config.disturbance.action not in DISTURBANCE_ACTIONS:
        raise ConfigError(f"disturbance.action: {config.disturbance.action!r} is not one of "
                          f"{', '.join(DISTURBANCE_ACTIONS)}")
    if f.handover not in HANDOVERS:
        raise ConfigError(f"fine.handover: {f.handover!r} is not one of {', '.join(HANDOVERS)}")
    try:
        GainSchedule(f.schedule_time_s, f.level_sigma, f.azimuth_sigma)
    except ValueError as exc:
        raise ConfigError(f"fine.{exc}") from None
    checks = [
        ("alignment.request_rho", 0.0 < a.request_rho <= 1.0, "must be in (0, 1]"),
        ("alignment.obs_interval_s", a.obs_interval_s > 0.0, "must be > 0"),
        ("alignment.disturbance_velocity_mps", a.disturbance_velocity_mps >= 0.0, "must be ≥ 0"),
        ("alignment.converged_heading_sigma_deg", a.converged_heading_sigma_deg > 0.0, "must be > 0"),
        ("output.period_s", o.period_s > 0.0, "must be > 0"),
        ("fine.handover_sigma_deg", f.handover_sigma_deg > 0.0, "must be > 0"),
        ("fine.handover_time_s", f.handover_time_s >= 0.0, "must be ≥ 0"),
        ("fine.handover_min_s", f.handover_min_s >= 0.0, "must be ≥ 0"),
        ("fine.handover_schedule_s", f.handover_schedule_s >= 0.0, "must be ≥ 0"),
        ("fine.control_interval_s", f.control_interval_s > 0.0, "must be > 0"),
        ("fine.stored_data_s", f.stored_data_s >= 0.0, "must be ≥ 0 (0 turns the stored-data passes off)"),
        ("fine.stored_pairs", 0 <= f.stored_pairs <= 100, "must be in 0..100"),
        ("fine.live_pass_steps", f.live_pass_steps >= 1, "must be ≥ 1"),
        ("site.lat_deg", -90.0 < config.site.lat_deg < 90.0, "must be in (-90, 90) (gyrocompassing needs Ω cos L)"),
        ("imu.rate_hz", 0.0 < config.imu.rate_hz <= 10000.0, "must be in (0, 10000]"),
        ("imu.gyro_range_deg_s", 0.0 < config.imu.gyro_range_deg_s <= 1e5, "must be in (0, 100000]"),
        ("imu.acc_range_g", 0.0 < config.imu.acc_range_g <= 1e4, "must be in (0, 10000]"),
        ("serial.baud", 0 < config.serial.baud <= 16_000_000, "must be in 1..16000000"),
        ("serial.reconnect_max_s", config.serial.reconnect_max_s > 0.0, "must be > 0"),
        ("daemon.status_period_s", config.daemon.status_period_s > 0.0, "must be > 0"),
        ("disturbance.velocity_threshold_mps", config.disturbance.velocity_threshold_mps > 0.0, "must be > 0"),
        ("disturbance.window_s", config.disturbance.window_s > 0.0, "must be > 0"),
        ("disturbance.check_interval_s", config.disturbance.check_interval_s > 0.0, "must be > 0"),
        ("disturbance.hold_s", config.disturbance.hold_s >= 0.0, "must be ≥ 0"),
        ("aiding.odo_latency_s", 0.0 <= ad.odo_latency_s <= 10.0, "must be in [0, 10]"),
        ("aiding.odo_std_mps", ad.odo_std_mps > 0.0, "must be > 0"),
        ("aiding.gnss_latency_s", 0.0 <= ad.gnss_latency_s <= 10.0, "must be in [0, 10]"),
        ("aiding.gnss_vel_std_mps", ad.gnss_vel_std_mps > 0.0, "must be > 0"),
        ("aiding.gnss_pos_std_m", ad.gnss_pos_std_m > 0.0, "must be > 0"),
        ("aiding.gnss_handover_s", 0.0 <= ad.gnss_handover_s <= 3600.0, "must be in [0, 3600]"),
        ("aiding.master_latency_s", 0.0 <= ad.master_latency_s <= 10.0, "must be in [0, 10]"),
        ("aiding.master_att_std_deg", ad.master_att_std_deg > 0.0, "must be > 0"),
        ("aiding.master_vel_std_mps", ad.master_vel_std_mps > 0.0, "must be > 0"),
        ("aiding.master_handover_s", 0.0 <= ad.master_handover_s <= 3600.0, "must be in [0, 3600] (0: by σ)"),
        ("aiding.master_mount_sigma_deg", 0.0 < ad.master_mount_sigma_deg <= 180.0, "must be in (0, 180]"),
        ("aiding.master_lever_sigma_m", 0.0 <= ad.master_lever_sigma_m <= 1000.0, "must be in [0, 1000]"),
        ("aiding.master_linear_sigma_deg", 0.0 < ad.master_linear_sigma_deg <= 30.0, "must be in (0, 30]"),
        ("aiding.master_handover_sigma_deg", ad.master_handover_sigma_deg > 0.0, "must be > 0"),
        ("aiding.odo_scale_sigma", 0.0 <= ad.odo_scale_sigma < 1.0, "must be in [0, 1)"),
        ("aiding.odo_lever_sigma_m", 0.0 <= ad.odo_lever_sigma_m <= 100.0, "must be in [0, 100]"),
        ("aiding.window_s", 1.0 <= ad.window_s <= 3600.0, "must be in [1, 3600]"),
        ("aiding.levels", 1 <= ad.levels <= 50, "must be in 1..50"),
        ("aiding.relevel_interval_s", ad.relevel_interval_s > 0.0, "must be > 0"),
        ("aiding.max_gap_s", ad.max_gap_s > 0.0, "must be > 0"),
        ("aiding.gate_chi2", ad.gate_chi2 > 0.0, "must be > 0"),
        ("aiding.handover_heading_sigma_deg", 0.0 < ad.handover_heading_sigma_deg <= 10.0, "must be in (0, 10]"),
        ("aiding.max_wait_s", 0.0 <= ad.max_wait_s <= 10.0, "must be in [0, 10]"),
        ("daemon.max_bridge_samples", 0 <= config.daemon.max_bridge_samples <= 1000, "must be in 0..1000"),
    ] + [(f"sensor.{f.name}", getattr(s, f.name) >= 0.0, "must be ≥ 0") for f in fields(s)]
    for key, ok, rule in checks:
        if not ok:
            raise ConfigError(f"{key}: {rule}")
    return config


def _merge(section_obj: Any, section: str, table: dict[str, Any]) -> Any:
    known = {f.name: f for f in fields(section_obj)}
    updates = {}
    for key, value in table.items():
        if key not in known:
            raise ConfigError(f"{section}.{key}: unknown key (known: {', '.join(known)})")
        default = getattr(section_obj, key)
        if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
            try:
                value = float(value)
            except OverflowError:
                raise ConfigError(f"{section}.{key}: {value} is out of range") from None
        if isinstance(default, tuple):
            value = (_string_list if "str" in str(known[key].type) else _number_list)(f"{section}.{key}", value)
        if type(value) is not type(default):
            raise ConfigError(f"{section}.{key}: expected {type(default).__name__}, got {value!r}")
        if isinstance(value, float) and not math.isfinite(value):
            raise ConfigError(f"{section}.{key}: must be a finite number, got {value!r}")
        updates[key] = value
    return replace(section_obj, **updates)


def _number_list(key: str, value: Any) -> tuple[float, ...]:
    if not isinstance(value, list | tuple) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        raise ConfigError(f"{key}: expected a list of numbers, got {value!r}")
    try:
        numbers = tuple(float(v) for v in value)
    except OverflowError:
        raise ConfigError(f"{key}: a number is out of range") from None
    if not all(math.isfinite(v) for v in numbers):
        raise ConfigError(f"{key}: must hold finite numbers, got {value!r}")
    return numbers


def _string_list(key: str, value: Any) -> tuple[str, ...]:
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
        raise ConfigError(f"{key}: expected a list of strings, got {value!r}")
    return tuple(value)


def config_from_mapping(data: dict[str, Any], base: Config | None = None) -> Config:
    """Apply a nested mapping (parsed TOML, or overrides) onto ``base`` and validate."""
    config = base or Config()
    sections = {f.name for f in fields(config)}
    updates = {}
    for section, table in data.items():
        if section not in sections:
            raise ConfigError(f"{section}: unknown section (known: {', '.join(sorted(sections))})")
        if not isinstance(table, dict):
            raise ConfigError(f"{section}: must be a table")
        updates[section] = _merge(getattr(config, section), section, table)
    return _check(replace(config, **updates))


def load_config(path: str | Path | None = None, overrides: dict[str, Any] | None = None) -> Config:
    """Defaults, then the TOML file (if any), then ``overrides`` like {"output": {"period_s": 0.5}}."""
    config = Config()
    if path is not None:
        try:
            with open(path, "rb") as stream:
                data = tomllib.load(stream)
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise ConfigError(f"{path}: not valid TOML: {exc}") from exc
        except OSError as exc:
            raise ConfigError(f"{path}: cannot read: {exc.strerror}") from exc
        config = config_from_mapping(data, config)
    return config_from_mapping(overrides or {}, config)

"""Configuration: defaults < TOML file < command-line overrides, validated at start-up.

Every key lives in one table; an unknown key or a value of the wrong type or range stops the
start with a message that names the key. Units are in the key names. Every number has the range a physical system
needs next to its field (:func:`_number`), every list its lengths, every text its length: a value that parses but
no sensor, site or computer can hold (a control step of 1e12 s sizes a store of petabytes) is refused at the start
like a wrong type. A key a log states of itself (site, rate, datasheet, aiding noise and lever arm) has the range
the log's reader holds it to (protocol/imu_log.py, protocol/aiding_log.py).
"""
from __future__ import annotations

import difflib
import math
import tomllib
from collections.abc import Collection, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from ..protocol.aiding_log import (
    LEVER_RANGE,
    MASTER_ATTITUDE_STD_RANGE,
    MASTER_VELOCITY_STD_RANGE,
    POSITION_STD_RANGE,
    VELOCITY_STD_RANGE,
)
from ..protocol.imu_log import (
    DATASHEET_RANGES,
    MAX_ACC_RANGE_G,
    MAX_GYRO_RANGE_DEG_S,
    RATE_RANGE,
    SITE_RANGES,
    Range,
    shown,
)
from ..protocol.keys import UnitKeys
from ..protocol.messages import AIDING_FIELDS as AIDING_KINDS
from .align.compass import GainSchedule
from .align.solvers import ALIGNMENT_SOLVERS, SOLVERS

DAY_S = 86400.0
MAX_TEXT_CHARS = 4096
"""The longest text a key may hold (a path's limit on Linux)."""
MAX_FILE_BYTES = 1 << 20
"""The largest configuration file read: a configuration takes a few kilobytes."""
MAX_STORED_ROWS = 100_000
"""The most rows a store sized by two keys may take (window / interval): tens of megabytes at most."""


class ConfigError(ValueError):
    """A configuration problem; the message names the key."""


def _number(default: float, limit: Range) -> Any:
    """A numeric key: its ``default`` and the range ``limit`` its value must lie in."""
    return field(default=default, metadata={"range": limit})


def _numbers(default: tuple[float, ...], limit: Range, lengths: Collection[int], what: str) -> Any:
    """A list of numbers: each in ``limit``, as many as ``lengths`` allows (``what`` says so in the message)."""
    return field(default=default, metadata={"range": limit, "lengths": lengths, "what": what})


def _texts(default: tuple[str, ...], lengths: Collection[int], what: str) -> Any:
    """A list of texts, as many as ``lengths`` allows."""
    return field(default=default, metadata={"lengths": lengths, "what": what})


def _text(default: str, chars: int) -> Any:
    """A text of at most ``chars`` characters (those that go into keys and messages are short)."""
    return field(default=default, metadata={"chars": chars})


def _seconds(default: float, low: float, high: float, why: str = "s") -> Any:
    """A duration or interval in seconds from ``low`` to ``high``."""
    return _number(default, Range(low, high, why=why))


def _positive(default: float, high: float, why: str) -> Any:
    """A number above 0 (a 0 would divide or gate everything away) up to ``high``."""
    return _number(default, Range(0.0, high, open_low=True, why=why))


@dataclass(frozen=True, slots=True)
class SensorConfig:
    """Datasheet 1-sigma figures of the IMU; a log's own comment keys override them."""

    gyro_bias_deg_h: float = _number(0.01, DATASHEET_RANGES["gyro_bias_deg_h"])
    gyro_arw_deg_rth: float = _number(0.001, DATASHEET_RANGES["gyro_arw_deg_rth"])
    acc_bias_ug: float = _number(50.0, DATASHEET_RANGES["acc_bias_ug"])
    acc_vrw_ug_rthz: float = _number(5.0, DATASHEET_RANGES["acc_vrw_ug_rthz"])


@dataclass(frozen=True, slots=True)
class AlignmentConfig:
    """Coarse alignment (inertial frame, seed 000)."""

    solver: str = _text("auto", 32)
    """One of :data:`~.align.solvers.ALIGNMENT_SOLVERS`; "auto": OPREQ, or GLS where the gyro's walk dominates."""
    request_rho: float = _number(0.01, Range(0.0, 1.0, open_low=True))
    obs_interval_s: float = _positive(0.1, 60.0, "s; the pipeline refuses one shorter than the IMU's sample period")
    disturbance_velocity_mps: float = _number(1e-3, Range(0.0, 10.0, why="m/s"))
    converged_heading_sigma_deg: float = _positive(0.1, 180.0, "°")
    swing_bias: bool = True
    """Estimate the accelerometer bias seen through a swinging body and take its term out of α (fixed base)."""


@dataclass(frozen=True, slots=True)
class FineConfig:
    """Compass fine alignment (seed 001): hand-over, gain schedule, stored-data passes.

    The schedule gives loop bandwidths σ (rad/s) at loop times (s since the hand-over), geometric
    in between; azimuth σ 0 = levelling only. Defaults suit navigation-grade sensors. A "sigma"
    hand-over waits at least ``handover_min_s`` of coarse alignment whatever the σ. The passes' store holds
    ``stored_data_s / control_interval_s`` steps, at most :data:`MAX_STORED_ROWS`.
    """

    enabled: bool = True
    handover: str = _text("sigma", 32)
    handover_sigma_deg: float = _positive(0.05, 180.0, "°")
    handover_min_s: float = _seconds(10.0, 0.0, DAY_S)
    handover_time_s: float = _seconds(60.0, 0.0, DAY_S)
    handover_schedule_s: float = _seconds(31.0, 0.0, DAY_S)
    control_interval_s: float = _seconds(0.1, 1e-3, 10.0)
    schedule_time_s: tuple[float, ...] = _numbers((0.0, 30.0, 31.0, 100.0, 200.0, 300.0), Range(0.0, DAY_S, why="s"),
                                                  range(1, 101), "1 to 100 knots")
    level_sigma: tuple[float, ...] = _numbers((0.5, 0.5, 0.05, 0.04, 0.03, 0.02), Range(0.0, 10.0, why="rad/s"),
                                              range(1, 101), "1 to 100 knots")
    azimuth_sigma: tuple[float, ...] = _numbers((0.0, 0.0, 0.05, 0.03, 0.015, 0.01), Range(0.0, 10.0, why="rad/s"),
                                                range(1, 101), "1 to 100 knots")
    stored_data_s: float = _seconds(80.0, 0.0, 3600.0, "s; 0 turns the stored-data passes off")
    stored_pairs: int = _number(3, Range(0, 100))
    live_pass_steps: int = _number(40, Range(1, 100_000))


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

    odo_latency_s: float = _seconds(0.0, 0.0, 10.0)
    odo_std_mps: float = _number(0.03, VELOCITY_STD_RANGE)
    odo_lever_m: tuple[float, ...] = _numbers((0.0, 0.0, 0.0), LEVER_RANGE, (3,), "3 numbers (body x, y, z in m)")
    odo_scale_sigma: float = _number(0.0, Range(0.0, 1.0, open_high=True))
    odo_lever_sigma_m: float = _number(0.0, Range(0.0, 100.0, why="m"))
    gnss_latency_s: float = _seconds(0.0, 0.0, 10.0)
    gnss_lever_m: tuple[float, ...] = _numbers((0.0, 0.0, 0.0), LEVER_RANGE, (3,), "3 numbers (body x, y, z in m)")
    gnss_formula: str = _text("vif", 32)
    gnss_vel_std_mps: float = _number(0.1, VELOCITY_STD_RANGE)
    gnss_pos_std_m: float = _number(2.0, POSITION_STD_RANGE)
    gnss_handover_s: float = _seconds(30.0, 0.0, 3600.0)
    master_latency_s: float = _seconds(0.0, 0.0, 10.0)
    master_lever_m: tuple[float, ...] = _numbers((0.0, 0.0, 0.0), LEVER_RANGE, (3,),
                                                 "3 numbers (master body x, y, z in m)")
    master_mount_deg: tuple[float, ...] = _numbers((), Range(-360.0, 360.0, why="°"), (0, 3),
                                                   "3 numbers (heading, pitch, roll in deg) or none")
    master_mount_sigma_deg: float = _positive(5.0, 180.0, "°")
    master_att_std_deg: float = _number(0.001, MASTER_ATTITUDE_STD_RANGE)
    master_vel_std_mps: float = _number(0.005, MASTER_VELOCITY_STD_RANGE)
    master_handover_s: float = _seconds(0.0, 0.0, 3600.0, "s; 0: by σ")
    master_handover_sigma_deg: float = _positive(0.2, 30.0, "°")
    master_linear_sigma_deg: float = _positive(5.0, 30.0, "°")
    master_lever_sigma_m: float = _number(1.0, Range(0.0, 100.0, why="m; 0: taken as known"))
    window_s: float = _seconds(120.0, 1.0, 3600.0)
    levels: int = _number(10, Range(1, 50))
    relevel_interval_s: float = _seconds(1.0, 0.01, 3600.0)
    solver: str = _text("centred", 32)
    max_gap_s: float = _seconds(0.5, 1e-3, 60.0)
    gate_chi2: float = _number(16.3, Range(1.0, 1e4, why="χ², 3 dof; below 1 most good inputs fail"))
    handover_heading_sigma_deg: float = _positive(1.0, 10.0, "°")
    inputs: tuple[str, ...] = _texts((), range(len(AIDING_KINDS) + 1), "distinct aiding kinds")
    max_wait_s: float = _seconds(0.5, 0.0, 10.0)


HANDOVERS = ("sigma", "time")
GNSS_FORMULAS = ("vif", "pif")
ZENOH_MODES = ("", "peer", "client", "router")


@dataclass(frozen=True, slots=True)
class DisturbanceConfig:
    """A base that moves although the alignment assumes it fixed in position (service/align/disturbance.py).

    Every ``check_interval_s`` the horizontal velocity gained over the last ``window_s`` is checked; above
    ``velocity_threshold_mps`` the base is moving: ``disturbed``, never converged, until it has been at rest for
    ``hold_s``. Then ``action = "restart"`` starts the alignment over if the base really went somewhere (and the
    restarted alignment stays disturbed for ``hold_s`` more); ``"report"`` only flags. The window's store holds
    ``window_s / check_interval_s`` checks, at most :data:`MAX_STORED_ROWS`.
    """

    enabled: bool = True
    velocity_threshold_mps: float = _positive(0.1, 100.0, "m/s")
    window_s: float = _seconds(2.0, 0.01, 600.0)
    check_interval_s: float = _seconds(0.1, 1e-3, 60.0)
    hold_s: float = _seconds(10.0, 0.0, DAY_S)
    action: str = _text("restart", 32)


DISTURBANCE_ACTIONS = ("restart", "report")


@dataclass(frozen=True, slots=True)
class SiteConfig:
    """Where the live IMU sits (a log states its own site in its comment keys)."""

    lat_deg: float = _number(32.0, SITE_RANGES["lat_deg"])
    lon_deg: float = _number(118.0, SITE_RANGES["lon_deg"])
    height_m: float = _number(0.0, SITE_RANGES["height_m"])


@dataclass(frozen=True, slots=True)
class ImuConfig:
    """The live IMU: nominal sample rate (a log states its own) and its measurement ranges: an increment beyond
    range × interval (twice, for the interval's jitter) cannot come from the sensor and is dropped as a bad sample.
    The defaults cover MEMS and tactical units (2000°/s, 100 g); set the datasheet's. A range below 1 g could not
    measure gravity."""

    rate_hz: float = _number(200.0, RATE_RANGE)
    gyro_range_deg_s: float = _number(2000.0, Range(1.0, MAX_GYRO_RANGE_DEG_S, why="°/s"))
    acc_range_g: float = _number(100.0, Range(1.0, MAX_ACC_RANGE_G, why="g"))


@dataclass(frozen=True, slots=True)
class SerialConfig:
    """The serial input (RS-422 IMU, or a pty on a bench); an empty path means no serial input."""

    path: str = ""
    baud: int = _number(921600, Range(1, 16_000_000))
    reconnect_max_s: float = _seconds(2.0, 0.01, 3600.0)


@dataclass(frozen=True, slots=True)
class ZenohConfig:
    """The Zenoh session and keys. Default: peer listening on tcp/127.0.0.1:7447 (loopback only),
    multicast scouting off. An empty mode, listen or connect leaves it to ``config_file`` (if any)."""

    mode: str = _text("", 32)
    listen: tuple[str, ...] = _texts((), range(33), "at most 32 endpoints")
    connect: tuple[str, ...] = _texts((), range(33), "at most 32 endpoints")
    config_file: str = ""
    prefix: str = _text("sinsalign", 100)
    unit: str = _text("unit1", 64)
    imu_input: bool = False


@dataclass(frozen=True, slots=True)
class DaemonConfig:
    status_period_s: float = _seconds(1.0, 0.01, 3600.0)
    record_path: str = ""
    max_bridge_samples: int = _number(5, Range(0, 1000))


@dataclass(frozen=True, slots=True)
class OutputConfig:
    period_s: float = _seconds(1.0, 1e-4, 3600.0)


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


def _check_field(key: str, value: Any, metadata: Any) -> None:
    """One key against its field's bounds: the list's length, each number's range, each text's length."""
    if "lengths" in metadata and len(value) not in metadata["lengths"]:
        raise ConfigError(f"{key}: expected {metadata['what']}, got {len(value)}: {shown(list(value))}")
    items = value if isinstance(value, tuple) else (value,)
    limit = metadata.get("range")
    for item in items:
        if limit is not None and not limit.holds(item):
            raise ConfigError(f"{key}: {'each value ' if isinstance(value, tuple) else ''}must be in {limit}, "
                              f"got {shown(item)}")
        if isinstance(item, str) and len(item) > metadata.get("chars", MAX_TEXT_CHARS):
            raise ConfigError(f"{key}: at most {metadata.get('chars', MAX_TEXT_CHARS)} characters, got {shown(item)}")


def _check_one_of(key: str, value: str, allowed: Sequence[str], note: str = "") -> None:
    if value not in allowed:
        raise ConfigError(f"{key}: {shown(value)} is not one of {', '.join(a for a in allowed if a)}{note}")


def _check_store(key: str, window_s: float, per: str, interval_s: float, what: str) -> None:
    """A store of ``window_s / interval_s`` rows stays within :data:`MAX_STORED_ROWS` (its memory is allocated at
    the start)."""
    rows = window_s / interval_s
    if rows > MAX_STORED_ROWS:
        raise ConfigError(f"{key}: {window_s:g} s at {per} = {interval_s:g} s is {rows:.3g} {what}; at most "
                          f"{MAX_STORED_ROWS} (lengthen the interval or shorten the window)")


def _check(config: Config) -> Config:
    for section in fields(config):
        table = getattr(config, section.name)
        for f in fields(table):
            _check_field(f"{section.name}.{f.name}", getattr(table, f.name), f.metadata)
    a, f, ad, z = config.alignment, config.fine, config.aiding, config.zenoh
    _check_one_of("alignment.solver", a.solver, ALIGNMENT_SOLVERS)
    _check_one_of("zenoh.mode", z.mode, ZENOH_MODES)
    for key, text in (("zenoh.prefix", z.prefix), ("zenoh.unit", z.unit)):
        try:
            UnitKeys(z.prefix if key == "zenoh.prefix" else "p", text if key == "zenoh.unit" else "u")
        except ValueError as exc:
            raise ConfigError(f"{key}: {exc}") from None
    _check_one_of("aiding.solver", ad.solver, [s for s in SOLVERS if s != "gls"], " (gls models a fixed base)")
    unknown = [k for k in ad.inputs if k not in AIDING_KINDS]
    if unknown or len(set(ad.inputs)) != len(ad.inputs):
        raise ConfigError(f"aiding.inputs: {shown(list(ad.inputs))} must name distinct kinds among "
                          f"{', '.join(AIDING_KINDS)}")
    _check_one_of("aiding.gnss_formula", ad.gnss_formula, GNSS_FORMULAS)
    _check_one_of("disturbance.action", config.disturbance.action, DISTURBANCE_ACTIONS)
    _check_one_of("fine.handover", f.handover, HANDOVERS)
    try:
        GainSchedule(f.schedule_time_s, f.level_sigma, f.azimuth_sigma)
    except ValueError as exc:
        raise ConfigError(f"fine.{exc}") from None
    if f.stored_pairs > 0:
        _check_store("fine.stored_data_s", f.stored_data_s, "fine.control_interval_s", f.control_interval_s,
                     "stored steps")
    if a.obs_interval_s >= 1.0 / RATE_RANGE.high:   # a shorter one is shorter than any IMU's period: refused unsized
        _check_store("aiding.window_s", ad.window_s, "alignment.obs_interval_s", a.obs_interval_s,
                     "stored observations")
    d = config.disturbance
    _check_store("disturbance.window_s", d.window_s, "disturbance.check_interval_s", d.check_interval_s,
                 "stored checks")
    return config


def _unknown(name: object, where: str, known: Sequence[str]) -> ConfigError:
    """An unknown section or key, named (cut short, quoted unless a plain name) with the names it may have meant: all
    of them if they are few."""
    text = str(name)
    text = (text if len(text) <= 40 else text[:40] + "…") if text.isidentifier() else shown(name)
    listing = ", ".join(known)
    close = difflib.get_close_matches(str(name)[:100], known, n=3)
    hint = (f"known: {listing}" if len(listing) <= 120 else f"did you mean {' or '.join(close)}?" if close
            else "docs/reference.md, 'Configuration', lists them")
    return ConfigError(f"{where}{text}: unknown {'key' if where else 'section'} ({hint})")


def _merge(section_obj: Any, section: str, table: dict[str, Any]) -> Any:
    known = {f.name: f for f in fields(section_obj)}
    updates = {}
    for key, value in table.items():
        if key not in known:
            raise _unknown(key, f"{section}.", list(known))
        default = getattr(section_obj, key)
        if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
            try:
                value = float(value)
            except OverflowError:
                raise ConfigError(f"{section}.{key}: {shown(value)} is out of range") from None
        if isinstance(default, tuple):
            value = (_string_list if "str" in str(known[key].type) else _number_list)(f"{section}.{key}", value)
        if type(value) is not type(default):
            raise ConfigError(f"{section}.{key}: expected {type(default).__name__}, got {shown(value)}")
        if isinstance(value, float) and not math.isfinite(value):
            raise ConfigError(f"{section}.{key}: must be a finite number, got {value!r}")
        updates[key] = value
    return replace(section_obj, **updates)


def _number_list(key: str, value: Any) -> tuple[float, ...]:
    if not isinstance(value, list | tuple) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        raise ConfigError(f"{key}: expected a list of numbers, got {shown(value)}")
    try:
        numbers = tuple(float(v) for v in value)
    except OverflowError:
        raise ConfigError(f"{key}: a number is out of range") from None
    if not all(math.isfinite(v) for v in numbers):
        raise ConfigError(f"{key}: must hold finite numbers, got {shown(value)}")
    return numbers


def _string_list(key: str, value: Any) -> tuple[str, ...]:
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
        raise ConfigError(f"{key}: expected a list of strings, got {shown(value)}")
    return tuple(value)


def config_from_mapping(data: dict[str, Any], base: Config | None = None) -> Config:
    """Apply a nested mapping (parsed TOML, or overrides) onto ``base`` and validate."""
    config = base or Config()
    sections = sorted(f.name for f in fields(config))
    updates = {}
    for section, table in data.items():
        if section not in sections:
            raise _unknown(section, "", sections)
        if not isinstance(table, dict):
            raise ConfigError(f"{section}: must be a table")
        updates[section] = _merge(getattr(config, section), section, table)
    return _check(replace(config, **updates))


def _read_toml(path: str | Path) -> dict[str, Any]:
    """The TOML file at ``path``, read no further than :data:`MAX_FILE_BYTES`; every way it can fail (unreadable,
    not UTF-8, not TOML, nested beyond the parser's recursion, an integer too long to convert) as one line."""
    try:
        with open(path, "rb") as stream:
            raw = stream.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read: {exc.strerror}") from exc
    if len(raw) > MAX_FILE_BYTES:
        raise ConfigError(f"{path}: larger than {MAX_FILE_BYTES} bytes: not a configuration file")
    try:
        return tomllib.loads(raw.decode("utf-8"))
    except RecursionError:
        raise ConfigError(f"{path}: not valid TOML: nested too deeply") from None
    except ValueError as exc:   # TOMLDecodeError, UnicodeDecodeError, an integer of more than 4300 digits
        problem = str(exc)
        raise ConfigError(f"{path}: not valid TOML: {problem if len(problem) <= 120 else problem[:120] + '…'}") from exc


def load_config(path: str | Path | None = None, overrides: dict[str, Any] | None = None) -> Config:
    """Defaults, then the TOML file (if any), then ``overrides`` like {"output": {"period_s": 0.5}}."""
    config = Config()
    if path is not None:
        config = config_from_mapping(_read_toml(path), config)
    return config_from_mapping(overrides or {}, config)

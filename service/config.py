"""Configuration: defaults < TOML file < command-line overrides, validated at start-up.

Every key lives in one table: the common ones in their section, each mode's in its own (``[aiding.odo]``,
``[aiding.gnss]``, ``[aiding.master]``, ``[fine.compass]``, ``[fine.kalman]``). An unknown key or a value of
the wrong type or range stops the start with a message that names the key (a mode's key written in its
section, ``aiding.gnss_lever_m``: the key that holds it). Each field declares its range, its choices and what it
means beside it, and the reference (:func:`reference_markdown`) is generated from that. Units are in the key
names. Every number has the range a physical system needs, every list its lengths, every text its length: a
value that parses but no sensor, site or computer can hold (a control step of 1e12 s sizes a store of petabytes)
is refused at the start like a wrong type. A key a log states of itself (site, rate, datasheet, aiding noise and
lever arm) has the range the log's reader holds it to (protocol/imu_log.py, protocol/aiding_log.py).
"""
from __future__ import annotations

import math
from collections.abc import Collection, Iterator, Sequence
from dataclasses import asdict, dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any

from ..protocol.aiding_log import (
    LEVER_RANGE,
    MASTER_ATTITUDE_STD_RANGE,
    MASTER_VELOCITY_STD_RANGE,
    POSITION_STD_RANGE,
    VELOCITY_STD_RANGE,
)
from ..protocol.axes import axis_map
from ..protocol.formats import GNSS_INPUTS, IMU_FORMATS
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
from ..protocol.nmea_out import LINE_SHARE, line_bits_per_s
from ..protocol.nmea_out import SENTENCES as NMEA_SENTENCES
from ..protocol.stim300 import STIM300_CONTENT, STIM300_DATAGRAMS, STIM300_DV_LSB
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


def _number(default: float, limit: Range, doc: str = "") -> Any:
    """A numeric key: its ``default``, the range ``limit`` its value must lie in, and what it means (``doc``, for the
    generated reference)."""
    return field(default=default, metadata={"range": limit, "doc": doc})


def _numbers(default: tuple[float, ...], limit: Range, lengths: Collection[int], what: str, doc: str = "") -> Any:
    """A list of numbers: each in ``limit``, as many as ``lengths`` allows (``what`` says so in the message)."""
    return field(default=default, metadata={"range": limit, "lengths": lengths, "what": what, "doc": doc})


def _texts(default: tuple[str, ...], lengths: Collection[int], what: str, doc: str = "") -> Any:
    """A list of texts, as many as ``lengths`` allows."""
    return field(default=default, metadata={"lengths": lengths, "what": what, "doc": doc})


def _text(default: str, chars: int = MAX_TEXT_CHARS, doc: str = "", choices: Sequence[str] = ()) -> Any:
    """A text of at most ``chars`` characters (those that go into keys and messages are short); one of ``choices``
    if given."""
    return field(default=default, metadata={"chars": chars, "doc": doc, "choices": tuple(choices)})


def _flag(default: bool, doc: str) -> Any:
    return field(default=default, metadata={"doc": doc})


def _seconds(default: float, low: float, high: float, why: str = "s", doc: str = "") -> Any:
    """A duration or interval in seconds from ``low`` to ``high``."""
    return _number(default, Range(low, high, why=why), doc)


def _positive(default: float, high: float, why: str, doc: str = "") -> Any:
    """A number above 0 (a 0 would divide or gate everything away) up to ``high``."""
    return _number(default, Range(0.0, high, open_low=True, why=why), doc)


HANDOVERS = ("sigma", "time")
GNSS_FORMULAS = ("vif", "pif")
ZENOH_MODES = ("", "peer", "client", "router")
DISTURBANCE_ACTIONS = ("restart", "report")
LEVER = "3 numbers (body x, y, z in m)"


@dataclass(frozen=True, slots=True)
class SensorConfig:
    """Datasheet 1-sigma figures of the IMU; an IMU log's own comment keys take precedence."""

    gyro_bias_deg_h: float = _number(0.01, DATASHEET_RANGES["gyro_bias_deg_h"],
                                     "gyro bias 1-σ as the alignment meets it: the warmed-up turn-on "
                                     "(run-to-run) figure, not the Allan minimum")
    gyro_arw_deg_rth: float = _number(0.001, DATASHEET_RANGES["gyro_arw_deg_rth"], "gyro angle random walk")
    acc_bias_ug: float = _number(50.0, DATASHEET_RANGES["acc_bias_ug"], "accelerometer bias 1-σ")
    acc_vrw_ug_rthz: float = _number(5.0, DATASHEET_RANGES["acc_vrw_ug_rthz"], "accelerometer noise density")


@dataclass(frozen=True, slots=True)
class AlignmentConfig:
    """The coarse stage (inertial frame, seed 000) and the output's convergence rule."""

    solver: str = _text("auto", 32, "fixed-base solver; auto: OPREQ, or GLS where the datasheet's gyro walk "
                        "dominates (docs/algorithms/coarse.md, \"Which solver\")", ALIGNMENT_SOLVERS)
    request_rho: float = _number(0.01, Range(0.0, 1.0, open_low=True), "fixed gain of the \"request\" solver")
    obs_interval_s: float = _positive(0.1, 60.0, "s; the pipeline refuses one shorter than the IMU's sample period",
                                      "vector observation interval (1 s gives the same accuracy)")
    disturbance_velocity_mps: float = _number(1e-3, Range(0.0, 10.0, why="m/s"),
                                              "base velocity disturbance the observation noise allows for")
    converged_heading_sigma_deg: float = _positive(0.1, 180.0, "°", "`converged` once the heading σ is at or "
                                                   "below this")
    swing_bias: bool = _flag(True, "fit the accelerometer bias seen through a swinging body and take its term out "
                             "of α (fixed base)")


@dataclass(frozen=True, slots=True)
class CompassConfig:
    """The compass loops of the fixed base (seed 001): hand-over, gain schedule, stored-data passes.

    The schedule gives loop bandwidths σ (rad/s) at loop times (s since the hand-over), geometric in between;
    azimuth σ 0 = levelling only. Defaults suit navigation-grade sensors. The passes' store holds
    ``stored_data_s / fine.control_interval_s`` steps, at most :data:`MAX_STORED_ROWS`.
    """

    handover: str = _text("sigma", 32, "\"sigma\": once the coarse heading noise σ (bias floor excluded) is "
                          "within handover_sigma_deg; \"time\": at handover_time_s", HANDOVERS)
    handover_sigma_deg: float = _positive(0.05, 180.0, "°", "the \"sigma\" hand-over's heading noise σ")
    handover_min_s: float = _seconds(10.0, 0.0, DAY_S, doc="a \"sigma\" hand-over waits at least this long (a "
                                     "datasheet claiming far too little noise would hand over at once)")
    handover_time_s: float = _seconds(60.0, 0.0, DAY_S, doc="the \"time\" hand-over's time")
    handover_schedule_s: float = _seconds(31.0, 0.0, DAY_S, doc="loop time at which a hand-over from the coarse "
                                          "stage enters the schedule (skips levelling)")
    schedule_time_s: tuple[float, ...] = _numbers((0.0, 30.0, 31.0, 100.0, 200.0, 300.0), Range(0.0, DAY_S, why="s"),
                                                  range(1, 101), "1 to 100 knots", "loop time of each knot")
    level_sigma: tuple[float, ...] = _numbers((0.5, 0.5, 0.05, 0.04, 0.03, 0.02), Range(0.0, 10.0, why="rad/s"),
                                              range(1, 101), "1 to 100 knots", "level-loop bandwidth σ per knot")
    azimuth_sigma: tuple[float, ...] = _numbers((0.0, 0.0, 0.05, 0.03, 0.015, 0.01), Range(0.0, 10.0, why="rad/s"),
                                                range(1, 101), "1 to 100 knots",
                                                "azimuth-loop σ per knot; 0 = levelling only")
    stored_data_s: float = _seconds(80.0, 0.0, 3600.0, "s; 0 turns the stored-data passes off",
                                    "seconds kept for the repeated passes")
    stored_pairs: int = _number(3, Range(0, 100), "backward + forward pass pairs (CLI --stored-pairs)")
    live_pass_steps: int = _number(40, Range(1, 100_000), "pass steps per control step in the daemon (offline: "
                                   "all at once)")


@dataclass(frozen=True, slots=True)
class KalmanConfig:
    """The error-state Kalman filter of the aided modes."""

    gate_chi2: float = _number(16.3, Range(1.0, 1e4, why="χ², 3 dof; below 1 most good inputs fail"),
                               "innovation gate of each measurement")
    handover_heading_sigma_deg: float = _positive(1.0, 10.0, "°", "the filter starts only from a coarse heading σ "
                                                  "this small (odometer, GNSS; a linear filter started several "
                                                  "degrees off grows overconfident)")


@dataclass(frozen=True, slots=True)
class FineConfig:
    """The fine stage: the compass loops on a fixed base (``[fine.compass]``), the Kalman filter in the aided modes
    (``[fine.kalman]``)."""

    enabled: bool = _flag(True, "false: the coarse stage alone (CLI --no-fine)")
    control_interval_s: float = _seconds(0.1, 1e-3, 10.0, doc="control step of either fine stage; also the block "
                                         "of samples processed together")
    compass: CompassConfig = field(default_factory=CompassConfig)
    kalman: KalmanConfig = field(default_factory=KalmanConfig)


@dataclass(frozen=True, slots=True)
class OdometerConfig:
    """An odometer or DVL (``--aid odo``): body velocity at its point, and the multistage coarse window."""

    latency_s: float = _seconds(0.0, 0.0, 10.0, doc="its time stamps are this late")
    vel_std_mps: float = _number(0.03, VELOCITY_STD_RANGE, "noise 1-σ per axis (an odometer log's vel_std_mps "
                                 "overrides)")
    lever_m: tuple[float, ...] = _numbers((0.0, 0.0, 0.0), LEVER_RANGE, (3,), LEVER, "its point from the IMU, body "
                                          "axes")
    scale_sigma: float = _number(0.0, Range(0.0, 1.0, open_high=True), "Kalman prior σ of its scale factor (0: not "
                                 "estimated)")
    lever_sigma_m: float = _number(0.0, Range(0.0, 100.0, why="m"), "Kalman prior σ of each lever-arm axis (0: not "
                                   "estimated)")
    window_s: float = _seconds(120.0, 1.0, 3600.0, doc="multistage stored window (rows = window / "
                               "alignment.obs_interval_s, at most 100000)")
    levels: int = _number(10, Range(1, 50), "multistage levels (1 = the traditional V^b model alone)")
    relevel_interval_s: float = _seconds(1.0, 0.01, 3600.0, doc="a window re-run starts this often (its levels: "
                                         "one per control step)")
    solver: str = _text("centred", 32, "solver of each level (not gls: it models a fixed base)",
                        [s for s in SOLVERS if s != "gls"])


@dataclass(frozen=True, slots=True)
class GnssConfig:
    """A GNSS receiver (``--aid gnss``): the antenna's position and velocity."""

    latency_s: float = _seconds(0.0, 0.0, 10.0, doc="its time stamps are this late")
    lever_m: tuple[float, ...] = _numbers((0.0, 0.0, 0.0), LEVER_RANGE, (3,), LEVER, "the antenna from the IMU, "
                                          "body axes (a GNSS log's lever_*_m keys override)")
    formula: str = _text("vif", 32, "coarse stage: velocity integration, or positions only", GNSS_FORMULAS)
    vel_std_mps: float = _number(0.1, VELOCITY_STD_RANGE, "velocity noise 1-σ per ENU axis (a log's vel_std_mps "
                                 "overrides)")
    pos_std_m: float = _number(2.0, POSITION_STD_RANGE, "position noise 1-σ per ENU axis (a log's pos_std_m "
                               "overrides)")
    handover_s: float = _seconds(0.0, 0.0, 3600.0, doc="the Kalman filter starts no earlier (and once the coarse "
                                 "heading σ is within fine.kalman.handover_heading_sigma_deg); 0: as soon as it is")
    input: str = _text("sinsalign", 32, "the receiver's output: the project's aiding frames and messages, NMEA "
                       "0183 (GGA with RMC or VTG) or u-blox UBX NAV-PVT", GNSS_INPUTS)
    serial: str = _text("", doc="the receiver's own serial port; empty: on the IMU's line")
    baud: int = _number(115200, Range(1, 16_000_000), "its baud rate")


@dataclass(frozen=True, slots=True)
class MasterConfig:
    """A master INS (``--aid master``, transfer alignment): its attitude, velocity and position.

    Phase 2 (the Kalman filter) starts at ``handover_s`` if set (the seed's fixed 10 s), else once phase 1's σ is
    at most ``handover_sigma_deg``, or within the filter's linear range (``linear_sigma_deg``, at most
    √(2 att_std)) and no longer improving, as with a MEMS slave that never reaches the first. Either way the
    filter then runs over the data from the first master epoch, about phase 1's mounting.
    """

    latency_s: float = _seconds(0.0, 0.0, 10.0, doc="its time stamps are this late")
    lever_m: tuple[float, ...] = _numbers((0.0, 0.0, 0.0), LEVER_RANGE, (3,), "3 numbers (master body x, y, z in m)",
                                          "from the master's point to the slave IMU, master body axes (a master "
                                          "log's lever_*_m keys override)")
    mount_deg: tuple[float, ...] = _numbers((), Range(-360.0, 360.0, why="°"), (0, 3), "3 numbers (heading, pitch, "
                                            "roll in deg) or none", "a rough mounting C_bs^bm: the slave's "
                                            "attitude until phase 1 has resolved the mounting")
    mount_sigma_deg: float = _positive(5.0, 180.0, "°", "its 1-σ")
    att_std_deg: float = _number(0.001, MASTER_ATTITUDE_STD_RANGE, "attitude noise 1-σ per axis (a master log's "
                                 "att_std_deg overrides)")
    vel_std_mps: float = _number(0.005, MASTER_VELOCITY_STD_RANGE, "velocity noise 1-σ per ENU axis (a master "
                                 "log's vel_std_mps overrides)")
    handover_s: float = _seconds(0.0, 0.0, 3600.0, "s; 0: by σ", "> 0: phase 2 starts at this time")
    handover_sigma_deg: float = _positive(0.2, 30.0, "°", "phase 2 starts once phase 1's noise σ is this small,")
    linear_sigma_deg: float = _positive(5.0, 30.0, "°", "or within this (at most √(2 att_std), in rad) and no "
                                     "longer improving (a MEMS slave): the filter then runs from the start")
    lever_sigma_m: float = _number(1.0, Range(0.0, 100.0, why="m; 0: taken as known"), "1-σ of the lever arm the "
                                   "filter estimates")


@dataclass(frozen=True, slots=True)
class AidingConfig:
    """The aided modes: the aids given (``replay --aid KIND=FILE``, the daemon's ``inputs``) select the mode; each
    aid's own table (``[aiding.odo]``, ``[aiding.gnss]``, ``[aiding.master]``) holds its sensor."""

    inputs: tuple[str, ...] = _texts((), range(len(AIDING_KINDS) + 1), "distinct aiding kinds",
                                     "daemon: the aiding kinds it takes (…/aid/KIND on Zenoh, serial aiding frames; "
                                     "CLI serve --aid)")
    max_wait_s: float = _seconds(0.5, 0.0, 10.0, doc="daemon: how long (data time) beyond a stream's usual interval "
                                 "(up to 2 s) an IMU sample waits for the epoch after it: latency and transport")
    max_gap_s: float = _seconds(0.5, 1e-3, 60.0, doc="epochs further apart than this and than 2.5 of the stream's "
                                "usual interval are a gap: not interpolated across, counted")
    odo: OdometerConfig = field(default_factory=OdometerConfig)
    gnss: GnssConfig = field(default_factory=GnssConfig)
    master: MasterConfig = field(default_factory=MasterConfig)


@dataclass(frozen=True, slots=True)
class DisturbanceConfig:
    """A base that moves although the alignment assumes it fixed in position (service/align/disturbance.py).

    Every ``check_interval_s`` the horizontal velocity gained over the last ``window_s`` is checked; above
    ``velocity_threshold_mps`` the base is moving: ``disturbed``, never converged, until it has been at rest for
    ``hold_s``. The window's store holds ``window_s / check_interval_s`` checks, at most :data:`MAX_STORED_ROWS`.
    """

    enabled: bool = _flag(True, "watch a fixed base for translation and for estimates that contradict their σ")
    velocity_threshold_mps: float = _positive(0.1, 100.0, "m/s", "horizontal velocity gained within window_s that "
                                              "counts as moving")
    window_s: float = _seconds(2.0, 0.01, 600.0, doc="the window the velocity gained is judged over")
    check_interval_s: float = _seconds(0.1, 1e-3, 60.0, doc="how often it is judged")
    hold_s: float = _seconds(10.0, 0.0, DAY_S, doc="at rest this long ends a motion; a restarted alignment is "
                             "disturbed this long")
    action: str = _text("restart", 32, "restart (once at rest, if the base went somewhere) or report only",
                        DISTURBANCE_ACTIONS)


@dataclass(frozen=True, slots=True)
class SiteConfig:
    """Where the live IMU sits (a log states its own site in its comment keys)."""

    lat_deg: float = _number(32.0, SITE_RANGES["lat_deg"], "geodetic latitude (WGS-84)")
    lon_deg: float = _number(118.0, SITE_RANGES["lon_deg"], "longitude")
    height_m: float = _number(0.0, SITE_RANGES["height_m"], "height above the ellipsoid")


@dataclass(frozen=True, slots=True)
class Stim300Config:
    """A Sensonor STIM300 in normal mode, set to incremental angle and incremental velocity output."""

    datagram: int = _number(0x93, Range(0, 255), "the datagram identifier the sensor is set to (0x90–0x93, "
                            "0xA4–0xA7; TOML takes 0x93)")
    acc_range_g: int = _number(10, Range(1, 100, why="g"), "the accelerometer variant (5, 10, 30 or 80 g): it sets "
                               "the incremental velocity's scale")


@dataclass(frozen=True, slots=True)
class FrameConfig:
    """A fixed-length vendor frame declared field by field (``[imu] format = "frame"``; docs/imu-formats.md)."""

    sync: str = _text("", 64, "the sync bytes at the frame's start, in hex (\"FA FF 36\")")
    length: int = _number(0, Range(0, 1024), "the whole frame in bytes, sync and checksum included")
    endian: str = _text("little", 16, "byte order of every field", ("little", "big"))
    fields: tuple[str, ...] = _texts((), range(65), "at most 64 fields", "after the sync bytes, in order: \"NAME "
                                     "TYPE [SCALE]\" (NAME dtheta_x…z rad, dv_x…z m/s, gyro_x…z rad/s, acc_x…z "
                                     "m/s², counter, status, pad, checksum; TYPE i8…i64, u8…u64, f32, f64)")
    checksum: str = _text("none", 32, "what the checksum field holds", ("none", "crc32", "crc32-mpeg2", "crc16-ccitt",
                                                                        "sum8", "xor8"))
    checksum_from: int = _number(0, Range(0, 1024), "the first byte (from the frame's start) the checksum covers; it "
                                 "covers up to the checksum field")


@dataclass(frozen=True, slots=True)
class ImuConfig:
    """The live IMU: its serial format, axes, nominal sample rate (a log states its own) and its measurement ranges:
    an increment beyond range × interval (twice, for the interval's jitter) cannot come from the sensor and is
    dropped as a bad sample. The defaults cover MEMS and tactical units (2000°/s, 100 g); set the datasheet's. A
    range below 1 g could not measure gravity."""

    format: str = _text("sinsalign", 32, "the serial frame (CLI serve --imu-format; docs/imu-formats.md)",
                        IMU_FORMATS)
    axes: tuple[str, ...] = _texts(("x", "y", "z"), (3,), "3 sensor axes", "the sensor axes that are body Right, "
                                   "Front, Up; a \"-\" prefix flips one (a right-handed set)")
    rate_hz: float = _number(200.0, RATE_RANGE, "nominal sample rate of the live input (a counter's time stamps "
                             "step by its period)")
    gyro_range_deg_s: float = _number(2000.0, Range(1.0, MAX_GYRO_RANGE_DEG_S, why="°/s"), "gyro measurement range")
    acc_range_g: float = _number(100.0, Range(1.0, MAX_ACC_RANGE_G, why="g"), "accelerometer measurement range")
    counter_only: bool = _flag(False, "stamp a vendor's samples from its counter's steps alone, never from "
                               "arrival times (a bench playing faster than real time: a loss longer than half the "
                               "counter's wrap is then undercounted, and the rate is not checked against the "
                               "host's clock)")
    stim300: Stim300Config = field(default_factory=Stim300Config)
    frame: FrameConfig = field(default_factory=FrameConfig)


@dataclass(frozen=True, slots=True)
class SerialConfig:
    """The serial input (RS-422 IMU, or a pty on a bench); an empty path means no serial input."""

    path: str = _text("", doc="e.g. \"/dev/ttyUSB0\" (CLI --serial)")
    baud: int = _number(921600, Range(1, 16_000_000), "CLI --baud")
    reconnect_max_s: float = _seconds(2.0, 0.01, 3600.0, doc="back-off ceiling when the port vanishes")


@dataclass(frozen=True, slots=True)
class ZenohConfig:
    """The Zenoh connection and keys. Default: peer listening on tcp/127.0.0.1:7447 (loopback only),
    multicast scouting off. An empty mode, listen or connect leaves it to ``config_file`` (if any)."""

    mode: str = _text("", 32, "peer, client or router (CLI -m); empty: the file's, else peer", ZENOH_MODES)
    listen: tuple[str, ...] = _texts((), range(33), "at most 32 endpoints", "CLI -l; empty: the file's, else "
                                     "tcp/127.0.0.1:7447")
    connect: tuple[str, ...] = _texts((), range(33), "at most 32 endpoints", "CLI -e")
    config_file: str = _text("", doc="a standard Zenoh JSON5 file as the base: TLS, access control, routers (CLI "
                             "--zenoh-config)")
    prefix: str = _text("sinsalign", 100, "keys <prefix>/<unit>/… (CLI --prefix)")
    unit: str = _text("unit1", 64, "CLI --unit")
    imu_input: bool = _flag(False, "also read IMU samples from <prefix>/<unit>/imu (CLI --zenoh-imu)")


@dataclass(frozen=True, slots=True)
class DaemonConfig:
    """The daemon's status, recording and scheduling."""

    status_period_s: float = _seconds(1.0, 0.01, 3600.0, doc="status publication period (wall time)")
    record_path: str = _text("", doc="record the decoded input as an IMU log (CLI --record; a name ending in .sbin: "
                             "the binary form)")
    max_bridge_samples: int = _number(5, Range(0, 1000), "longest sequence gap bridged by interpolation; longer "
                                      "restarts")
    realtime_priority: int = _number(0, Range(0, 99), "SCHED_FIFO priority of the loop and Zenoh's threads (1-99, "
                                     "CAP_SYS_NICE or `ulimit -r`; a refusal is logged and the daemon runs on); 0: "
                                     "the normal scheduler")


@dataclass(frozen=True, slots=True)
class NmeaConfig:
    """NMEA 0183 heading output for bridge systems, chart plotters and DP systems (docs/outputs.md); no
    destination: none."""

    udp: tuple[str, ...] = _texts((), range(17), "at most 16 destinations", "\"HOST:PORT\" destinations of UDP "
                                  "datagrams, one sentence each (CLI serve --nmea-udp)")
    serial: str = _text("", doc="a serial port to write the sentences to")
    baud: int = _number(4800, Range(300, 4_000_000), "its baud rate (gyrocompass lines: 4800 or 38400)")
    sentences: tuple[str, ...] = _texts(("THS", "ROT", "PASHR"), range(1, 5), "1 to 4 sentences", "THS, HDT (older "
                                        "receivers), ROT, PASHR")
    rate_hz: float = _number(1.0, Range(0.01, 50.0, why="Hz"), "sentences per second, each")
    talker: str = _text("HE", 2, "the talker id (HE: gyrocompass, IN: integrated navigation)")


@dataclass(frozen=True, slots=True)
class Ros2Config:
    """ROS 2 output through zenoh-bridge-ros2dds (docs/outputs.md)."""

    enabled: bool = _flag(False, "publish sensor_msgs/msg/Imu (CDR) on <prefix>/<unit>/ros/imu (CLI serve --ros2; "
                          "the ros2 extra)")
    frame_id: str = _text("imu_link", 64, "the message header's frame_id")


@dataclass(frozen=True, slots=True)
class OutputConfig:
    """The records."""

    period_s: float = _seconds(1.0, 1e-4, 3600.0, doc="attitude output period (CLI --period)")


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
    nmea: NmeaConfig = field(default_factory=NmeaConfig)
    ros2: Ros2Config = field(default_factory=Ros2Config)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


MOVED = {
    **{f"aiding.{kind}_{'std_mps' if key == 'vel_std_mps' and kind == 'odo' else key}": f"aiding.{kind}.{key}"
       for kind, table in (("odo", OdometerConfig), ("gnss", GnssConfig), ("master", MasterConfig))
       for key in (f.name for f in fields(table))},
    **{f"aiding.{key}": f"aiding.odo.{key}" for key in ("window_s", "levels", "relevel_interval_s", "solver")},
    **{f"aiding.{key}": f"fine.kalman.{key}" for key in ("gate_chi2", "handover_heading_sigma_deg")},
    **{f"fine.{f.name}": f"fine.compass.{f.name}" for f in fields(CompassConfig)}}
"""A mode's keys as written in their section (``aiding.gnss_lever_m``) → the key that holds each
(``aiding.gnss.lever_m``): refused, with that key named."""


def tables(obj: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(dotted name, table) of every table and sub-table of a configuration object, parents first."""
    for f in fields(obj):
        value = getattr(obj, f.name)
        if is_dataclass(value):
            name = f"{prefix}{f.name}"
            yield name, value
            yield from tables(value, f"{name}.")


def value_fields(table: Any) -> list[Any]:
    """The fields of a table that hold values (not sub-tables)."""
    return [f for f in fields(table) if not is_dataclass(getattr(table, f.name))]


def _check_field(key: str, value: Any, metadata: Any) -> None:
    """One key against its field's bounds: the list's length, each number's range, each text's length and
    choices."""
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
    choices = metadata.get("choices")
    if choices and value not in choices:
        raise ConfigError(f"{key}: {shown(value)} is not one of {', '.join(c for c in choices if c)}")


def _check_store(key: str, window_s: float, per: str, interval_s: float, what: str) -> None:
    """A store of ``window_s / interval_s`` rows stays within :data:`MAX_STORED_ROWS` (its memory is allocated at
    the start)."""
    rows = window_s / interval_s
    if rows > MAX_STORED_ROWS:
        raise ConfigError(f"{key}: {window_s:g} s at {per} = {interval_s:g} s is {rows:.3g} {what}; at most "
                          f"{MAX_STORED_ROWS} (lengthen the interval or shorten the window)")


def _check(config: Config) -> Config:
    for name, table in tables(config):
        for f in value_fields(table):
            _check_field(f"{name}.{f.name}", getattr(table, f.name), f.metadata)
    a, f, ad, z = config.alignment, config.fine, config.aiding, config.zenoh
    for key, text in (("zenoh.prefix", z.prefix), ("zenoh.unit", z.unit)):
        try:
            UnitKeys(z.prefix if key == "zenoh.prefix" else "p", text if key == "zenoh.unit" else "u")
        except ValueError as exc:
            raise ConfigError(f"{key}: {exc}") from None
    unknown = [k for k in ad.inputs if k not in AIDING_KINDS]
    if unknown or len(set(ad.inputs)) != len(ad.inputs):
        raise ConfigError(f"aiding.inputs: {shown(list(ad.inputs))} must name distinct kinds among "
                          f"{', '.join(AIDING_KINDS)}")
    _check_imu(config.imu)
    _check_nmea(config.nmea)
    c = f.compass
    try:
        GainSchedule(c.schedule_time_s, c.level_sigma, c.azimuth_sigma)
    except ValueError as exc:
        raise ConfigError(f"fine.compass.schedule_time_s, level_sigma, azimuth_sigma: "
                          f"{str(exc).removeprefix('schedule: ')}") from None
    if c.stored_pairs > 0:
        _check_store("fine.compass.stored_data_s", c.stored_data_s, "fine.control_interval_s", f.control_interval_s,
                     "stored steps")
    if a.obs_interval_s >= 1.0 / RATE_RANGE.high:   # a shorter one is shorter than any IMU's period: refused unsized
        _check_store("aiding.odo.window_s", ad.odo.window_s, "alignment.obs_interval_s", a.obs_interval_s,
                     "stored observations")
    d = config.disturbance
    _check_store("disturbance.window_s", d.window_s, "disturbance.check_interval_s", d.check_interval_s,
                 "stored checks")
    return config


def _check_imu(imu: ImuConfig) -> None:
    """The axes form a right-handed set; the STIM300's datagram and variant are ones its datasheet has; a declared
    frame (``format = "frame"``) adds up (:meth:`~sinsalign.protocol.declared_frame.FrameSpec.parse`)."""
    try:
        axis_map(imu.axes)
    except ValueError as exc:
        raise ConfigError(f"imu.axes: {exc}") from None
    st = imu.stim300
    if st.datagram not in STIM300_DATAGRAMS:
        raise ConfigError(f"imu.stim300.datagram: {st.datagram:#04x} is not a normal-mode datagram (one of "
                          f"{', '.join(f'{d:#04x}' for d in STIM300_DATAGRAMS)})")
    if imu.format == "stim300" and "acc" not in STIM300_CONTENT[st.datagram]:
        raise ConfigError(f"imu.stim300.datagram: {st.datagram:#04x} carries no accelerometers, and an alignment "
                          f"needs them: set the sensor to 0x91, 0x93, 0xA5 or 0xA7")
    if st.acc_range_g not in STIM300_DV_LSB:
        raise ConfigError(f"imu.stim300.acc_range_g: {st.acc_range_g} g is not a STIM300 variant (one of "
                          f"{', '.join(str(g) for g in STIM300_DV_LSB)})")
    if imu.format == "frame":
        from ..protocol.declared_frame import FrameSpec, FrameSpecError  # here: only a declared frame needs it

        try:
            FrameSpec.parse(imu.frame, imu.rate_hz)
        except FrameSpecError as exc:
            raise ConfigError(f"imu.frame.{exc.key}: {exc}") from None


def nmea_destination(text: str) -> tuple[str, int]:
    """(host, port) of an ``[nmea] udp`` destination ``HOST:PORT`` (``[::1]:10110`` for an IPv6 address)."""
    host, _, port = text.rpartition(":")
    host = host.removeprefix("[").removesuffix("]")
    if not host or not (port.isascii() and port.isdigit()) or not 0 < int(port) < 65536:
        raise ConfigError(f"nmea.udp: {shown(text)} is not HOST:PORT (a port from 1 to 65535)")
    return host, int(port)


def _check_nmea(n: NmeaConfig) -> None:
    """Known, distinct sentences; a talker id of two capitals; HOST:PORT destinations; and, to a serial port, the
    sentences at their rate within :data:`~sinsalign.protocol.nmea_out.LINE_SHARE` of the line (a line that cannot
    keep up would drop sentences all the time)."""
    if not set(n.sentences) <= set(NMEA_SENTENCES) or len(set(n.sentences)) != len(n.sentences):
        raise ConfigError(f"nmea.sentences: {shown(list(n.sentences))} must name distinct sentences among "
                          f"{', '.join(NMEA_SENTENCES)}")
    if not (n.talker.isascii() and n.talker.isalpha() and n.talker.isupper() and len(n.talker) == 2):
        raise ConfigError(f"nmea.talker: {shown(n.talker)} must be two capital letters (HE, IN, GP, …)")
    for text in n.udp:
        nmea_destination(text)
    need = line_bits_per_s(n.sentences, n.talker, n.rate_hz)
    if n.serial and need > LINE_SHARE * n.baud:
        raise ConfigError(f"nmea.baud, nmea.rate_hz: {', '.join(n.sentences)} at {n.rate_hz:g} Hz take up to "
                          f"{need:.0f} bit/s (10 bits a character), more than {LINE_SHARE:.0%} of {n.baud} Bd: raise "
                          "nmea.baud, lower nmea.rate_hz or send fewer sentences")


def _unknown(name: object, where: str, known: Sequence[str]) -> ConfigError:
    """An unknown section or key, named (cut short, quoted unless a plain name) with the names it may have meant: all
    of them if they are few; a mode's key written in its section with the key that holds it (:data:`MOVED`)."""
    text = str(name)
    text = (text if len(text) <= 40 else text[:40] + "…") if text.isidentifier() else shown(name)
    moved = MOVED.get(f"{where}{name}")
    if moved is not None:
        return ConfigError(f"{where}{text}: unknown key; it is {moved} (each mode's keys live in its own table: "
                           f"[{moved.rsplit('.', 1)[0]}] {moved.rsplit('.', 1)[1]} = …)")
    import difflib  # here: only a mistyped key needs it (the replay path imports no more than it runs)

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
        if is_dataclass(default):
            if not isinstance(value, dict):
                raise ConfigError(f"{section}.{key}: must be a table ([{section}.{key}])")
            updates[key] = _merge(default, f"{section}.{key}", value)
            continue
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
    import tomllib  # here: a run without a configuration file does not import the parser

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


def _toml(value: Any) -> str:
    """A default as it is written in a TOML file."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return repr(value)


def _bounds(f: Any) -> str:
    """What a field's values may be, from its metadata."""
    m = f.metadata
    if m.get("choices"):
        return "one of " + ", ".join(f"`{c}`" if c else "empty" for c in m["choices"])
    parts = [m["what"]] if "what" in m else []
    if "range" in m:
        parts.append(("each in " if "lengths" in m else "") + str(m["range"]))
    if f.type in ("str", "tuple[str, ...]") and "what" not in m:
        parts.append(f"text of at most {m.get('chars', MAX_TEXT_CHARS)} characters")
    return ", ".join(parts) or ("true or false" if f.type == "bool" else "")


def reference_markdown() -> str:
    """The configuration reference (docs/reference.md, "Configuration"): per table its purpose, then each key with its
    default, its bounds and what it means, all from the fields."""
    out = []
    for name, table in tables(Config()):
        doc = " ".join((type(table).__doc__ or "").split("\n\n")[0].split()).replace("``", "`")
        out += [f"**`[{name}]`** {doc}", "", "| key | default | values | meaning |", "|---|---|---|---|"]
        out += [f"| `{f.name}` | `{_toml(getattr(table, f.name))}` | {_bounds(f)} | {f.metadata.get('doc', '')} |"
                for f in value_fields(table)]
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def config_toml(config: Config) -> str:
    """``config`` as a TOML file (every table and key, sub-tables after their table's keys): what ``--config`` takes
    back unchanged."""
    out = []
    for name, table in tables(config):
        out += [f"[{name}]", *(f"{f.name} = {_toml(getattr(table, f.name))}" for f in value_fields(table)), ""]
    return "\n".join(out)

"""The pinned aiding logs (docs/reference.md, "Aiding log formats"): body velocity, GNSS, master INS.

Same style as the IMU log: comment lines ``# key=value``, the header row, one row per epoch in
time order, each value the instantaneous one at ``t`` (same time base as the IMU log). The
reader is the IMU log's (streamed in chunks, malformed input named by file, line and column);
only the columns, the optional comment keys and what a row may physically hold differ: noise figures a filter can
weigh and lever arms within a vehicle (always checked), and, for a consumer that asks (the replay), the speeds,
positions and quaternion norms a source can report (the limits the live decoders hold epochs to,
protocol/plausibility.py).
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .imu_log import (
    CHUNK_ROWS,
    TIME_RANGE,
    LogFormatError,
    LogHeader,
    Range,
    RowLimits,
    read_header,
    shown,
    stream_rows,
)
from .plausibility import (
    HEIGHT_RANGE_M,
    LATITUDE_RANGE_DEG,
    LONGITUDE_RANGE_DEG,
    QUATERNION_NORM_TOLERANCE,
    SPEED_LIMITS_MPS,
)

LEVER_KEYS = ("lever_x_m", "lever_y_m", "lever_z_m")
LEVER_RANGE = Range(-100.0, 100.0, why="m: a lever arm within a vehicle")
"""Each axis of a lever arm (a log's keys and the configuration's): a lever of 1e300 m turns every product with a
rate into NaN."""
VELOCITY_STD_RANGE = Range(1e-4, 10.0, why="m/s: 0.1 mm/s to a poor sensor's 10 m/s")
"""A velocity noise figure: a filter that weighs a figure below any sensor's becomes numerically singular."""
POSITION_STD_RANGE = Range(1e-3, 100.0, why="m: RTK to a fix too poor to align with")
MASTER_VELOCITY_STD_RANGE = Range(1e-4, 1.0, why="m/s: an INS's velocity is better than 1 m/s")
"""A master INS whose velocity noise is stated in metres per second is no master: transfer alignment's
heading grows overconfident beyond it."""
MASTER_ATTITUDE_STD_RANGE = Range(1e-6, 1.0, why="°: an INS's attitude is better than 1°")
LATITUDE = Range(*LATITUDE_RANGE_DEG, why="°")
LONGITUDE = Range(*LONGITUDE_RANGE_DEG, why="°")
HEIGHT = Range(*HEIGHT_RANGE_M, why="m")
QUATERNION_NORM = Range(1.0 - QUATERNION_NORM_TOLERANCE, 1.0 + QUATERNION_NORM_TOLERANCE, why="a rotation")


def _speed(columns: tuple[str, str, str], kind: str) -> tuple[tuple[str, ...], str, Range]:
    return columns, f"speed ‖{', '.join(columns)}‖", Range(0.0, SPEED_LIMITS_MPS[kind],
                                                           why=f"m/s: above it no {kind} source reports")


def _position(prefix: str = "") -> dict[str, Range]:
    return {f"{prefix}lat_deg": LATITUDE, f"{prefix}lon_deg": LONGITUDE, f"{prefix}h_m": HEIGHT}


@dataclass(frozen=True, slots=True)
class AidingKind:
    name: str
    columns: tuple[str, ...]
    std_ranges: Mapping[str, Range]  # optional 1-sigma figures: 0 (the configuration's stays) or in their range
    has_lever: bool                  # optional lever arm keys (m, body axes), default 0
    limits: RowLimits                # what a row may physically hold

    @property
    def std_keys(self) -> tuple[str, ...]:
        return tuple(self.std_ranges)

    @property
    def key_ranges(self) -> dict[str, Range]:
        """The ranges of the comment keys the header reader checks (the lever arm's; a noise figure may be 0)."""
        return dict.fromkeys(LEVER_KEYS, LEVER_RANGE) if self.has_lever else {}


def stated_aiding(kind: str, keys: Mapping[str, object]) -> dict[str, object]:
    """The ``[aiding.<kind>]`` configuration that an aiding log's comment ``keys`` state of its sensor (they override
    the configuration's, under the same names): each noise figure above 0 (a 0 states an ideal sensor, which no
    filter can weigh: the configuration's stays) and, for a kind with a lever arm, ``lever_m`` once any of its keys
    is given."""
    spec = KINDS[kind]
    out: dict[str, object] = {key: float(keys[key]) for key in spec.std_keys if keys.get(key)}
    if spec.has_lever and any(key in keys for key in LEVER_KEYS):
        out["lever_m"] = tuple(float(keys.get(key, 0.0)) for key in LEVER_KEYS)
    return out


KINDS = {k.name: k for k in (
    AidingKind("odo", ("t", "vx", "vy", "vz"), {"vel_std_mps": VELOCITY_STD_RANGE}, False,
               RowLimits({"t": TIME_RANGE}, (_speed(("vx", "vy", "vz"), "odo"),))),
    AidingKind("gnss", ("t", "lat_deg", "lon_deg", "h_m", "vE", "vN", "vU"),
               {"vel_std_mps": VELOCITY_STD_RANGE, "pos_std_m": POSITION_STD_RANGE}, True,
               RowLimits({"t": TIME_RANGE, **_position()}, (_speed(("vE", "vN", "vU"), "gnss"),))),
    AidingKind("master", ("t", "qw", "qx", "qy", "qz", "vE", "vN", "vU", "lat_deg", "lon_deg", "h_m"),
               {"att_std_deg": MASTER_ATTITUDE_STD_RANGE, "vel_std_mps": MASTER_VELOCITY_STD_RANGE}, True,
               RowLimits({"t": TIME_RANGE, **_position()}, (
                   (("qw", "qx", "qy", "qz"), "quaternion norm", QUATERNION_NORM),
                   _speed(("vE", "vN", "vU"), "master")))),
)}


@dataclass(frozen=True, slots=True)
class AidingLog:
    """An aiding log opened for streaming: kind, header keys, and (N, columns) blocks of epochs."""

    kind: AidingKind
    path: str
    header: LogHeader

    def stated(self) -> dict[str, object]:
        """The ``[aiding]`` configuration this log states of its sensor (:func:`stated_aiding`)."""
        return stated_aiding(self.kind.name, self.header.values)

    def blocks(self, chunk_rows: int = CHUNK_ROWS, limits: RowLimits | None = None) -> Iterator[np.ndarray]:
        """(N, columns) blocks of epochs; with ``limits`` (the kind's, for an alignment) an epoch outside them stops
        the reading, named by line (and column)."""
        # epochs out of order or repeated are the consumer's to count (service/aiding.py), not fatal
        yield from stream_rows(self.path, self.kind.columns, (), chunk_rows, increasing=False,
                               ranges=self.kind.key_ranges, limits=limits)


def open_aiding_log(kind: str, path: str | Path) -> AidingLog:
    """Open an aiding log of ``kind`` (odo, gnss, master) and check its header keys."""
    if kind not in KINDS:
        raise ValueError(f"unknown aiding kind {kind!r}; known: {', '.join(KINDS)}")
    spec, path = KINDS[kind], str(path)
    with open(path, encoding="utf-8", errors="replace") as stream:
        header, line_no = read_header(stream, path, spec.columns, (), spec.key_ranges)
    for key, limit in spec.std_ranges.items():
        value = header.values.get(key, 0.0)
        if not isinstance(value, float) or not (value == 0.0 or limit.holds(value)):
            raise LogFormatError(path, line_no, None, f"comment key {key} must be a finite number ≥ 0: 0 (the "
                                 f"configuration's figure stays) or in {limit}, found {shown(value)}")
    return AidingLog(spec, path, header)

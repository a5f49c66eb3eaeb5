"""The pinned aiding logs (service.md, "Pinned interfaces" 1): body velocity, GNSS, master INS.

Same style as the IMU log: comment lines ``# key=value``, the header row, one row per epoch in
time order, each value the instantaneous one at ``t`` (same time base as the IMU log). The
reader is the IMU log's (streamed in chunks, malformed input named by file, line and column);
only the columns and the optional comment keys differ.
"""
from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .imu_log import CHUNK_ROWS, LogFormatError, LogHeader, read_header, stream_rows

LEVER_KEYS = ("lever_x_m", "lever_y_m", "lever_z_m")


@dataclass(frozen=True, slots=True)
class AidingKind:
    name: str
    columns: tuple[str, ...]
    std_keys: tuple[str, ...]        # optional 1-sigma figures, ≥ 0
    has_lever: bool                  # optional lever arm keys (m, body axes), default 0


def stated_aiding(kind: str, keys: Mapping[str, object]) -> dict[str, object]:
    """The ``[aiding]`` configuration that an aiding log's comment ``keys`` state of its sensor (they override the
    configuration's): each noise figure above 0 (a 0 states an ideal sensor, which no filter can weigh: the
    configuration's stays) and, for a kind with a lever arm, the lever arm once any of its keys is given."""
    spec = KINDS[kind]
    out: dict[str, object] = {_CONFIG_KEYS.get((kind, key), f"{kind}_{key}"): float(keys[key])
                              for key in spec.std_keys if keys.get(key)}
    if spec.has_lever and any(key in keys for key in LEVER_KEYS):
        out[f"{kind}_lever_m"] = tuple(float(keys.get(key, 0.0)) for key in LEVER_KEYS)
    return out


KINDS = {k.name: k for k in (
    AidingKind("odo", ("t", "vx", "vy", "vz"), ("vel_std_mps",), False),
    AidingKind("gnss", ("t", "lat_deg", "lon_deg", "h_m", "vE", "vN", "vU"), ("vel_std_mps", "pos_std_m"), True),
    AidingKind("master", ("t", "qw", "qx", "qy", "qz", "vE", "vN", "vU", "lat_deg", "lon_deg", "h_m"),
               ("att_std_deg", "vel_std_mps"), True),
)}
_CONFIG_KEYS = {("odo", "vel_std_mps"): "odo_std_mps"}
"""Where a log key's configuration key is not ``<kind>_<key>``."""


@dataclass(frozen=True, slots=True)
class AidingLog:
    """An aiding log opened for streaming: kind, header keys, and (N, columns) blocks of epochs."""

    kind: AidingKind
    path: str
    header: LogHeader

    def stated(self) -> dict[str, object]:
        """The ``[aiding]`` configuration this log states of its sensor (:func:`stated_aiding`)."""
        return stated_aiding(self.kind.name, self.header.values)

    def blocks(self, chunk_rows: int = CHUNK_ROWS) -> Iterator[np.ndarray]:
        # epochs out of order or repeated are the consumer's to count (service/aiding.py), not fatal
        yield from stream_rows(self.path, self.kind.columns, (), chunk_rows, increasing=False)


def open_aiding_log(kind: str, path: str | Path) -> AidingLog:
    """Open an aiding log of ``kind`` (odo, gnss, master) and check its header keys."""
    if kind not in KINDS:
        raise ValueError(f"unknown aiding kind {kind!r}; known: {', '.join(KINDS)}")
    spec, path = KINDS[kind], str(path)
    with open(path, encoding="utf-8", errors="replace") as stream:
        header, line_no = read_header(stream, path, spec.columns, ())
    for key in spec.std_keys + (LEVER_KEYS if spec.has_lever else ()):
        if key in header.values:
            value = header.values[key]
            if not isinstance(value, float) or (key in spec.std_keys and value < 0) or not math.isfinite(value):
                raise LogFormatError(path, line_no, None, f"comment key {key} must be a finite number"
                                     + (" ≥ 0" if key in spec.std_keys else "") + f", found {value!r}")
    return AidingLog(spec, path, header)

"""The pinned IMU log (CSV): reader and writer (service.md, "Pinned interfaces" 1).

Layout: comment lines ``# key=value`` first (at least lat_deg, lon_deg, height_m, rate_hz;
optionally the datasheet figures gyro_bias_deg_h, gyro_arw_deg_rth, acc_bias_ug,
acc_vrw_ug_rthz), then the header ``t,dthx,dthy,dthz,dvx,dvy,dvz``, then one row per sample:
t in s at the end of the sample interval, gyro angle increments in rad, velocity increments in
m/s, body axes Right-Front-Up.

The reader streams the file in chunks (bounded memory) with numpy's C parser; when a chunk does
not parse it re-reads that chunk line by line to name the file, line and column at fault.
"""
from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path
from typing import TextIO

import numpy as np

IMU_COLUMNS = ("t", "dthx", "dthy", "dthz", "dvx", "dvy", "dvz")
IMU_WIDTH = len(IMU_COLUMNS)
"""Floats per IMU sample wherever samples travel as rows: t (s), Δθ (3) rad, Δv (3) m/s."""
REQUIRED_KEYS = ("lat_deg", "lon_deg", "height_m", "rate_hz")
DATASHEET_KEYS = ("gyro_bias_deg_h", "gyro_arw_deg_rth", "acc_bias_ug", "acc_vrw_ug_rthz")
TRUTH_COLUMNS = ("t", "heading_deg", "pitch_deg", "roll_deg", "qw", "qx", "qy", "qz")
CHUNK_ROWS = 20000


class LogFormatError(ValueError):
    """A malformed log; the message names the file, line and column."""

    def __init__(self, path: str, line: int, column: str | None, problem: str) -> None:
        where = f"{path}:{line}" + (f", column {column!r}" if column else "")
        super().__init__(f"{where}: {problem}")
        self.path, self.line, self.column, self.problem = path, line, column, problem


@dataclass(frozen=True, slots=True)
class LogHeader:
    """The comment keys of a log. Numbers are kept as float; anything else stays text."""

    values: dict[str, float | str] = field(default_factory=dict)

    def number(self, key: str) -> float:
        value = self.values[key]
        if not isinstance(value, float):
            raise TypeError(f"{key} is not a number: {value!r}")
        return value

    @property
    def lat_deg(self) -> float:
        return self.number("lat_deg")

    @property
    def lon_deg(self) -> float:
        return self.number("lon_deg")

    @property
    def height_m(self) -> float:
        return self.number("height_m")

    @property
    def rate_hz(self) -> float:
        return self.number("rate_hz")

    def datasheet(self) -> dict[str, float]:
        """The datasheet keys present in the log (they override the configured sensor grade)."""
        return {k: self.number(k) for k in DATASHEET_KEYS if k in self.values}


def _parse_value(text: str) -> float | str:
    try:
        value = float(text)
    except ValueError:
        return text
    return value if math.isfinite(value) else text


def read_header(stream: TextIO, path: str, columns: tuple[str, ...] = IMU_COLUMNS,
                required: tuple[str, ...] = REQUIRED_KEYS) -> tuple[LogHeader, int]:
    """Read the comment lines and the column header; return the header and lines consumed."""
    values: dict[str, float | str] = {}
    line_no = 0
    for raw in stream:
        line_no += 1
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            body = line[1:].strip()
            if "=" in body:
                key, _, value = body.partition("=")
                values[key.strip()] = _parse_value(value.strip())
            continue
        names = tuple(name.strip() for name in line.split(","))
        if names != columns:
            raise LogFormatError(path, line_no, None, f"header must be {','.join(columns)!r}, found {line!r}")
        for key in required:
            if key not in values:
                raise LogFormatError(path, line_no, None, f"comment key '# {key}=…' is missing before the header")
            if not isinstance(values[key], float):
                raise LogFormatError(path, line_no, None, f"comment key {key} is not a finite number: {values[key]!r}")
        if "rate_hz" in required and not values["rate_hz"] > 0:
            raise LogFormatError(path, line_no, None, f"rate_hz must be positive, found {values['rate_hz']}")
        for key in DATASHEET_KEYS:
            if key in values and not (isinstance(values[key], float) and values[key] >= 0):
                raise LogFormatError(path, line_no, None, f"datasheet key {key} must be a number ≥ 0")
        return LogHeader(values), line_no
    raise LogFormatError(path, max(line_no, 1), None, f"no header line {','.join(columns)!r} found")


NUMBER = re.compile(r"\s*[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\s*")
"""A plain decimal number, the only cell numpy's parser and this diagnosis both accept."""
NON_FINITE = re.compile(r"\s*[+-]?(?:nan|inf|infinity)\s*", re.IGNORECASE)


def _is_row(raw: str) -> bool:
    """Data rows are the non-blank lines that are not comments ('#' lines may annotate a log anywhere)."""
    text = raw.strip()
    return bool(text) and not text.startswith("#")


def _diagnose(lines: list[str], first_line: int, path: str, columns: tuple[str, ...]) -> LogFormatError:
    """Find the first bad cell of a chunk that numpy refused."""
    for offset, raw in enumerate(lines):
        if not _is_row(raw):
            continue
        cells = raw.strip().split(",")
        line_no = first_line + offset
        if len(cells) < len(columns):
            return LogFormatError(path, line_no, columns[len(cells)],
                                  f"missing: expected {len(columns)} values, found {len(cells)}")
        if len(cells) > len(columns):
            return LogFormatError(path, line_no, None, f"expected {len(columns)} values, found {len(cells)}")
        for name, cell in zip(columns, cells, strict=True):
            if not NUMBER.fullmatch(cell) and not NON_FINITE.fullmatch(cell):
                return LogFormatError(path, line_no, name, f"not a number: {cell.strip()!r}")
            if not math.isfinite(float(cell)):
                return LogFormatError(path, line_no, name, f"not finite: {cell.strip()!r}")
    return LogFormatError(path, first_line, None, "unreadable rows")


def read_rows(stream: TextIO, path: str, first_line: int, columns: tuple[str, ...] = IMU_COLUMNS,
              chunk_rows: int = CHUNK_ROWS, increasing: bool = True) -> Iterator[np.ndarray]:
    """Yield (N, len(columns)) float64 blocks of the data rows.

    ``increasing``: time must increase strictly (IMU logs); aiding logs leave ordering to the
    consumer, which counts repeats and out-of-order epochs instead of stopping.
    """
    line_no = first_line
    t_last = -math.inf
    while True:
        lines = [raw for raw in islice(stream, chunk_rows)]
        if not lines:
            return
        kept = [raw for raw in lines if _is_row(raw)]
        try:
            with np.errstate(all="ignore"):
                block = (np.loadtxt(kept, delimiter=",", ndmin=2, comments=None) if kept
                         else np.empty((0, len(columns))))
            ok = block.shape[1] == len(columns) and bool(np.isfinite(block).all())
        except ValueError:
            ok = False
        if not ok:
            raise _diagnose(lines, line_no, path, columns)
        times = block[:, 0]
        steps = np.diff(times, prepend=t_last)
        if increasing and len(times) and not (steps > 0).all():
            bad = int(np.flatnonzero(steps <= 0)[0])
            bad_line = line_no + [i for i, raw in enumerate(lines) if _is_row(raw)][bad]
            raise LogFormatError(path, bad_line, "t", f"time does not increase ({float(times[bad])!r} after "
                                 f"{float(times[bad - 1] if bad else t_last)!r})")
        if len(times):
            t_last = float(times[-1])
        line_no += len(lines)
        yield block


@dataclass(frozen=True, slots=True)
class ImuLog:
    """An IMU log opened for streaming: its header and an iterator of (t, dtheta, dv) blocks."""

    path: str
    header: LogHeader

    def blocks(self, chunk_rows: int = CHUNK_ROWS) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        for block in stream_rows(self.path, IMU_COLUMNS, REQUIRED_KEYS, chunk_rows):
            yield block[:, 0], block[:, 1:4], block[:, 4:7]


def stream_rows(path: str, columns: tuple[str, ...], required: tuple[str, ...], chunk_rows: int = CHUNK_ROWS,
                increasing: bool = True) -> Iterator[np.ndarray]:
    """The data rows of a log with these columns, in (N, len(columns)) blocks after its header."""
    with open(path, encoding="utf-8", errors="replace") as stream:
        _, consumed = read_header(stream, path, columns, required)
        yield from read_rows(stream, path, consumed + 1, columns, chunk_rows, increasing)


def open_imu_log(path: str | Path) -> ImuLog:
    """Open and check an IMU log's header; raises LogFormatError (or OSError) with the file named."""
    path = str(path)
    with open(path, encoding="utf-8", errors="replace") as stream:
        header, _ = read_header(stream, path)
    return ImuLog(path, header)


def write_header(stream: TextIO, values: dict[str, object], columns: tuple[str, ...]) -> None:
    for key, value in values.items():
        stream.write(f"# {key}={value}\n")
    stream.write(",".join(columns) + "\n")


def write_rows(stream: TextIO, rows: np.ndarray) -> None:
    """Rows with round-trip precision (17 significant digits), so replays are exact."""
    np.savetxt(stream, rows, fmt="%.17g", delimiter=",")

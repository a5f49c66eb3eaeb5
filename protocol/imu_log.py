"""The pinned IMU log (CSV): reader and writer (docs/reference.md, "IMU log format").

Layout: comment lines ``# key=value`` first (at least lat_deg, lon_deg, height_m, rate_hz;
optionally the datasheet figures gyro_bias_deg_h, gyro_arw_deg_rth, acc_bias_ug,
acc_vrw_ug_rthz), then the header ``t,dthx,dthy,dthz,dvx,dvy,dvz``, then one row per sample:
t in s at the end of the sample interval, gyro angle increments in rad, velocity increments in
m/s, body axes Right-Front-Up.

The reader streams the file in chunks (bounded memory, lines of at most :data:`MAX_LINE_CHARS`) through a compiled
parser (``_rows.parse_rows``), a plain file's bytes where the read put them; when a chunk does not parse it re-reads
that chunk line by line to name the file, line and column at fault.
A value that parses but no sensor or place can have (a rate of 1e308 Hz, a latitude of 95°, an increment of 1e300)
is refused like a malformed one: every comment key is held to a :class:`Range`, and so is every cell when the
consumer asks (:class:`RowLimits`; the replay does, a round trip of the format need not); every value an error
message quotes is cut short (:func:`shown`), so the message stays one short line whatever the file holds.
"""
from __future__ import annotations

import io
import math
import re
import reprlib
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from functools import partial
from itertools import islice
from pathlib import Path
from typing import BinaryIO, TextIO

import numpy as np

from ._rows import newlines, parse_rows, plain_text, rows_within
from .plausibility import HEIGHT_RANGE_M, LATITUDE_RANGE_DEG, LONGITUDE_RANGE_DEG

IMU_COLUMNS = ("t", "dthx", "dthy", "dthz", "dvx", "dvy", "dvz")
IMU_WIDTH = len(IMU_COLUMNS)
"""Floats per IMU sample wherever samples travel as rows: t (s), Δθ (3) rad, Δv (3) m/s."""
REQUIRED_KEYS = ("lat_deg", "lon_deg", "height_m", "rate_hz")
TRUTH_COLUMNS = ("t", "heading_deg", "pitch_deg", "roll_deg", "qw", "qx", "qy", "qz")
CHUNK_ROWS = 20000
MAX_LINE_CHARS = 4096
"""The longest line a log may hold (a data row takes under 200 characters): a file without line ends is no log,
and reading it as one line would take its whole size in memory."""
BATCH_LINES = 256
"""Lines read before their ends are checked: a line without an end is read in pieces of :data:`MAX_LINE_CHARS`."""
MAX_COMMENT_KEYS = 1000
"""Comment keys a log may state: a log states a dozen; a file of millions would fill the memory with them."""
SHOWN_CHARS = 40
"""The most characters of a value an error message quotes."""


class LogFormatError(ValueError):
    """A malformed log; the message names the file, line (or ``unit`` and its number: a binary log's sample) and
    column."""

    def __init__(self, path: str, line: int, column: str | None, problem: str, unit: str = "") -> None:
        where = f"{path}:{unit}{line}" + (f", column {column!r}" if column else "")
        super().__init__(f"{where}: {problem}")
        self.path, self.line, self.column, self.problem = path, line, column, problem


_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxstring, _REPR.maxother, _REPR.maxlong = 3, SHOWN_CHARS, SHOWN_CHARS, SHOWN_CHARS


def shown(value: object) -> str:
    """``value`` quoted for a one-line error message, cut to :data:`SHOWN_CHARS` characters then "…": a log's
    line or a configured value may be megabytes long or nested thousands deep, and an integer of more than 4300
    digits has no decimal form at all."""
    if isinstance(value, str):
        return repr(value[:SHOWN_CHARS]) + ("…" if len(value) > SHOWN_CHARS else "")
    try:
        text = _REPR.repr(value)
    except ValueError:   # Python refuses to print an integer that long
        return f"<{type(value).__name__} too large to print>"
    return text if len(text) <= SHOWN_CHARS else text[:SHOWN_CHARS] + "…"


@dataclass(frozen=True, slots=True)
class Range:
    """The values a physical quantity may take: ``low`` to ``high``, an end excluded where ``open_low`` or
    ``open_high`` says; ``why`` (its unit, or why the bound) goes into the error message."""

    low: float
    high: float
    open_low: bool = False
    open_high: bool = False
    why: str = ""

    def holds(self, values: float | np.ndarray) -> bool | np.ndarray:
        """Whether each value lies in the range (NaN never does); a Python number may be an integer of any size."""
        above = values > self.low if self.open_low else values >= self.low
        below = values < self.high if self.open_high else values <= self.high
        return above & below

    def __str__(self) -> str:
        text = f"{'(' if self.open_low else '['}{self.low:g}, {self.high:g}{')' if self.open_high else ']'}"
        return f"{text} ({self.why})" if self.why else text


ANY_NUMBER = Range(-math.inf, math.inf)
"""A column without limits: any finite number."""

SITE_RANGES = {
    "lat_deg": Range(*LATITUDE_RANGE_DEG, open_low=True, open_high=True, why="°; gyrocompassing needs Ω cos L"),
    "lon_deg": Range(*LONGITUDE_RANGE_DEG, why="°"),
    "height_m": Range(*HEIGHT_RANGE_M, why="m: the deepest ocean floor to the edge of space"),
}
RATE_RANGE = Range(1.0, 10000.0, why="Hz, positive: no IMU outputs slower than 1 Hz or faster than 10 kHz")
DATASHEET_RANGES = {
    "gyro_bias_deg_h": Range(0.0, 1e5, why="°/h, 28 °/s: above any MEMS gyro's offset"),
    "gyro_arw_deg_rth": Range(0.0, 100.0, why="°/√h: far above a consumer MEMS gyro's, about 1"),
    "acc_bias_ug": Range(0.0, 1e5, why="µg, 0.1 g: above any MEMS accelerometer's offset"),
    "acc_vrw_ug_rthz": Range(0.0, 1e4, why="µg/√Hz: far above a consumer MEMS accelerometer's, about 300"),
}
"""The datasheet's 1-sigma figures; 0 states an ideal sensor (a simulation's)."""
DATASHEET_KEYS = tuple(DATASHEET_RANGES)
IMU_KEY_RANGES = {**SITE_RANGES, "rate_hz": RATE_RANGE, **DATASHEET_RANGES}
MAX_GYRO_RANGE_DEG_S = 1e5
"""The widest measurement range a gyro may be stated to have (°/s; the widest MEMS ones: ±4000)."""
MAX_ACC_RANGE_G = 1e4
"""The widest measurement range an accelerometer may be stated to have (g; shock-rated ones: ±2000)."""
MAX_TIME_S = 1e10
"""The largest time stamp of any clock (s): Unix time stays below it until the year 2286."""
TIME_RANGE = Range(-MAX_TIME_S, MAX_TIME_S, why="s")
G0_MS2 = 9.80665
"""Standard gravity (m/s² per g): the datasheet unit of an accelerometer's range."""
RANGE_INTERVALS = 2.0
"""An increment may span this many sample intervals at full range (a sensor clock's jitter)."""


@dataclass(frozen=True, slots=True)
class RowLimits:
    """What a log's rows may physically hold: a :class:`Range` per column (by name), and Ranges for the length of
    vectors spanning several columns (a speed, a quaternion's norm), each named for the message."""

    cells: Mapping[str, Range]
    norms: tuple[tuple[tuple[str, ...], str, Range], ...] = ()

    def problem(self, block: np.ndarray, columns: tuple[str, ...]) -> tuple[int, str | None, str] | None:
        """The first row of ``block`` (finite values, columns named ``columns``) outside the limits: (row index,
        the column at fault or None for a vector, the problem), or None."""
        checks = [(block[:, columns.index(name)], name, name, limit) for name, limit in self.cells.items()]
        with np.errstate(over="ignore", under="ignore"):   # a vector of 1e200s has an infinite length: refused below
            checks += [(np.linalg.norm(block[:, [columns.index(c) for c in names]], axis=1), None, what, limit)
                       for names, what, limit in self.norms]
        failures = []
        for order, (values, column, what, limit) in enumerate(checks):
            bad = ~limit.holds(values)
            if bad.any():
                row = int(np.argmax(bad))
                failures.append((row, order, column, f"{what} {float(values[row])!r} is outside {limit}"))
        if not failures:
            return None
        row, _, column, text = min(failures)
        return row, column, text


def imu_limits(rate_hz: float) -> RowLimits:
    """What an IMU log's rows may hold at ``rate_hz``: time stamps of any clock, and increments within the widest
    ranges a sensor may be stated to have over twice the sample interval (its clock's jitter)."""
    interval_s = RANGE_INTERVALS / rate_hz
    dtheta = math.radians(MAX_GYRO_RANGE_DEG_S) * interval_s
    dv = MAX_ACC_RANGE_G * G0_MS2 * interval_s
    angle = Range(-dtheta, dtheta, why=f"rad: {MAX_GYRO_RANGE_DEG_S:g} °/s over {RANGE_INTERVALS:g} sample intervals")
    speed = Range(-dv, dv, why=f"m/s: {MAX_ACC_RANGE_G:g} g over {RANGE_INTERVALS:g} sample intervals")
    return RowLimits({"t": TIME_RANGE, **dict.fromkeys(IMU_COLUMNS[1:4], angle),
                      **dict.fromkeys(IMU_COLUMNS[4:], speed)})


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


def _lines(stream: TextIO, path: str, first_line: int, count: int) -> list[str]:
    """Up to ``count`` lines of ``stream``, the first being line ``first_line``, each read no further than
    :data:`MAX_LINE_CHARS`; LogFormatError on a longer line, or on a last line without its line end (a file cut
    short: its last number may be cut too). Read in batches of :data:`BATCH_LINES`, so a line of gigabytes costs
    one batch of pieces before it is found."""
    read = iter(partial(stream.readline, MAX_LINE_CHARS + 1), "")
    lines: list[str] = []
    while len(lines) < count:
        wanted = min(BATCH_LINES, count - len(lines))
        batch = list(islice(read, wanted))
        if "".join(batch).count("\n") != len(batch):
            k = next(k for k, raw in enumerate(batch) if not raw.endswith("\n"))
            raise LogFormatError(path, first_line + len(lines) + k, None,
                                 f"line longer than {MAX_LINE_CHARS} characters" if len(batch[k]) > MAX_LINE_CHARS
                                 else "no end of line: the file ends inside this line (cut short?)")
        lines += batch
        if len(batch) < wanted:
            break
    return lines


def _check_keys(values: Mapping[str, float | str], path: str, line_no: int, required: tuple[str, ...],
                ranges: Mapping[str, Range]) -> None:
    """The required comment keys are there and numbers; each key with a range (present) lies in it."""
    for key in required:
        if key not in values:
            raise LogFormatError(path, line_no, None, f"comment key '# {key}=…' is missing before the header")
    for key in (*required, *(k for k in ranges if k in values and k not in required)):
        value = values[key]
        if not isinstance(value, float):
            raise LogFormatError(path, line_no, None, f"comment key {key} is not a finite number: {shown(value)}")
        if key in ranges and not ranges[key].holds(value):
            raise LogFormatError(path, line_no, None, f"comment key {key} must be a number in {ranges[key]}, "
                                 f"found {value!r}")


def read_header(stream: TextIO, path: str, columns: tuple[str, ...] = IMU_COLUMNS,
                required: tuple[str, ...] = REQUIRED_KEYS,
                ranges: Mapping[str, Range] = IMU_KEY_RANGES) -> tuple[LogHeader, int]:
    """Read the comment lines and the column header; return the header and lines consumed. The ``required`` keys
    must be numbers, and every key of ``ranges`` that is given must lie in its range."""
    values: dict[str, float | str] = {}
    line_no = 0
    while lines := _lines(stream, path, line_no + 1, 1):
        line_no += 1
        line = lines[0].strip()
        if not line:
            continue
        if line.startswith("#"):
            body = line[1:].strip()
            if "=" in body:
                key, _, value = body.partition("=")
                values[key.strip()] = _parse_value(value.strip())
                if len(values) > MAX_COMMENT_KEYS:
                    raise LogFormatError(path, line_no, None, f"more than {MAX_COMMENT_KEYS} comment keys")
            continue
        names = tuple(name.strip() for name in line.split(","))
        if names != columns:
            raise LogFormatError(path, line_no, None, f"header must be {','.join(columns)!r}, found {shown(line)}")
        _check_keys(values, path, line_no, required, ranges)
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
                return LogFormatError(path, line_no, name, f"not a number: {shown(cell.strip())}")
            if not math.isfinite(float(cell)):
                return LogFormatError(path, line_no, name, f"not finite: {shown(cell.strip())}")
    return LogFormatError(path, first_line, None, "unreadable rows")


def _line_of(lines: list[str], first_line: int, row: int) -> int:
    """The line number of data row ``row`` of a chunk of ``lines`` starting at line ``first_line``."""
    return first_line + [i for i, raw in enumerate(lines) if _is_row(raw)][row]


RESTART_MARKER = "# restart:"
"""A comment line of a daemon's recording: the alignment started over here (the reason follows), so a replay must
too; the samples after it may begin a new time base (a sensor restarted its clock)."""
MARKER_BYTES = RESTART_MARKER.encode()


def _pieces(lines: list[str], first_line: int) -> list[tuple[str | None, list[str], int]]:
    """A chunk's lines cut at :data:`RESTART_MARKER` lines: (the marker's reason before the piece or None, its
    lines, the line number of its first)."""
    if RESTART_MARKER not in "".join(lines):   # one substring search: most chunks have no marker
        return [(None, lines, first_line)]
    pieces, start, reason = [], 0, None
    for k, raw in enumerate(lines):
        if raw.startswith(RESTART_MARKER):
            pieces.append((reason, lines[start:k], first_line + start))
            reason, start = raw[len(RESTART_MARKER):].strip(), k + 1
    pieces.append((reason, lines[start:], first_line + start))
    return pieces


def _loadtxt_block(lines: list[str], first_line: int, path: str, columns: tuple[str, ...]) -> np.ndarray:
    """The data rows of ``lines`` by numpy's reader (what it takes beyond plain decimals: nan, inf, which the check
    of finite values then refuses); LogFormatError naming the first bad cell."""
    kept = [raw for raw in lines if _is_row(raw)]
    try:
        with np.errstate(all="ignore"):
            block = np.loadtxt(kept, delimiter=",", ndmin=2, comments=None) if kept else np.empty((0, len(columns)))
        ok = block.shape[1] == len(columns) and bool(np.isfinite(block).all())
    except ValueError:
        ok = False
    if not ok:
        raise _diagnose(lines, first_line, path, columns)
    return block


def _block(lines: list[str], first_line: int, path: str, columns: tuple[str, ...],
           limits: RowLimits | None) -> np.ndarray:
    """The data rows of ``lines`` (line ``first_line`` on) as an (N, len(columns)) float64 block, every value finite
    and within ``limits`` (if given); LogFormatError naming the first bad cell."""
    block = parse_rows("".join(lines), len(columns), MAX_LINE_CHARS)
    if block is None:   # beyond the plain rows the compiled pass takes: numpy's reader, then the diagnosis
        block = _loadtxt_block(lines, first_line, path, columns)
    problem = None if limits is None else limits.problem(block, columns)
    if problem is not None:
        row, column, text = problem
        raise LogFormatError(path, _line_of(lines, first_line, row), column, text)
    return block


def first_not_increasing(times: np.ndarray, t_last: float) -> tuple[int, str] | None:
    """The index of the first time stamp not after the one before it (``t_last`` before the first) and the problem
    to report, or None."""
    steps = np.diff(times, prepend=t_last)
    if not len(times) or (steps > 0).all():
        return None
    bad = int(np.flatnonzero(steps <= 0)[0])
    return bad, f"time does not increase ({float(times[bad])!r} after {float(times[bad - 1] if bad else t_last)!r})"


def read_segments(pieces: Iterable[str | memoryview], path: str, first_line: int,
                  columns: tuple[str, ...] = IMU_COLUMNS, chunk_rows: int = CHUNK_ROWS, increasing: bool = True,
                  limits: RowLimits | None = None) -> Iterator[tuple[str | None, np.ndarray]]:
    """Yield (restart, block): (N, len(columns)) float64 blocks of at most ``chunk_rows`` data rows, every value
    within ``limits`` (if given), each after a :data:`RESTART_MARKER` line with that marker's reason (None for the
    others; a marker's block may be empty).

    ``pieces``: the log's text after its header, line ``first_line`` on, in pieces of whole lines (the last may end
    inside a line) as :func:`_plain_pieces` or :func:`_text_pieces` cut it. ``increasing``: time must increase
    strictly (IMU logs), within the rows between two markers; aiding logs leave ordering to the consumer, which
    counts repeats and out-of-order epochs instead of stopping.

    A piece of plain rows within their limits is one compiled pass; any other (a marker, a bad or long line, a file
    cut inside its last line) is read line by line by :func:`_line_segments`, which names the line.
    """
    line_no, t_last = first_line, -math.inf
    ranges = _column_ranges(limits, columns)
    for piece in pieces:
        block = parse_rows(piece, len(columns), MAX_LINE_CHARS, MARKER_BYTES)
        if block is None or not _acceptable(block, columns, limits, ranges, increasing, t_last):
            text = piece if isinstance(piece, str) else str(piece, "ascii")
            found = _line_segments(io.StringIO(text), path, line_no, columns, chunk_rows, increasing, limits, t_last)
        else:
            found = ((None, block[start:start + chunk_rows]) for start in range(0, len(block), chunk_rows))
        for reason, rows in found:
            if reason is not None:
                t_last = -math.inf
            if len(rows):
                t_last = float(rows[-1, 0])
            yield reason, rows
        line_no += newlines(piece)


CHUNK_CHARS = 1 << 19
"""Characters read at a time: whole lines of them are parsed in one pass."""


def _plain_pieces(raw: BinaryIO) -> Iterator[str | memoryview]:
    """The text of ``raw`` (binary, from the start of a line) in pieces of whole lines of about :data:`CHUNK_CHARS`
    as :func:`_text_pieces` cuts a text-mode read, without decoding it: while the bytes are their text (ASCII, no
    carriage return: ``_rows.plain_text``) a piece is a view of one buffer, valid until the next piece is asked for;
    from the first read that is not, the rest of the file is read in text mode (UTF-8, bad bytes replaced,
    universal newlines) by :func:`_text_pieces`, from that read's offset with the plain text before it carried:
    the pieces, and so the blocks and which error of a piece is named first, are a text-mode read's."""
    buffer = bytearray(CHUNK_CHARS + MAX_LINE_CHARS + 1)
    view = memoryview(buffer)
    kept, start = 0, raw.tell()   # bytes carried over (the start of a line), the file offset of buffer[0]
    while read := raw.readinto(view[kept:kept + CHUNK_CHARS]):
        end = kept + read
        cut = buffer.rfind(b"\n", 0, end) + 1
        if not plain_text(view[kept:end]):   # text mode from this read on, with the plain text carried over
            raw.seek(start + kept)
            yield from _text_pieces(io.TextIOWrapper(raw, encoding="utf-8", errors="replace"),
                                    str(view[:kept], "ascii"))
            return
        if cut:
            yield view[:cut]
        kept, start = end - cut, start + cut
        buffer[:kept] = bytes(view[cut:end])   # a copy: the two ranges may overlap
        if kept > MAX_LINE_CHARS:
            yield str(view[:MAX_LINE_CHARS + 1], "ascii")
            return
    if kept:
        yield str(view[:kept], "ascii")


def _text_pieces(stream: TextIO, carry: str = "") -> Iterator[str]:
    """The stream's text, after the start of a line ``carry``, in pieces of whole lines of about
    :data:`CHUNK_CHARS`; the last piece may end without a line end: a file cut short, or a line longer than
    :data:`MAX_LINE_CHARS` (its first characters only, read no further: the line reader refuses it, so a line of
    gigabytes costs one piece of memory)."""
    while data := stream.read(CHUNK_CHARS):
        text = carry + data
        cut = text.rfind("\n") + 1
        if cut:
            yield text[:cut]
        carry = text[cut:]
        if len(carry) > MAX_LINE_CHARS:
            yield carry[:MAX_LINE_CHARS + 1]
            return
    if carry:
        yield carry


def _acceptable(block: np.ndarray, columns: tuple[str, ...], limits: RowLimits | None,
                ranges: tuple[np.ndarray, ...] | None, increasing: bool, t_last: float) -> bool:
    """No value of ``block`` beyond ``limits`` and, with ``increasing``, its times increasing after ``t_last``: one
    compiled pass (``_rows.rows_within``) over the ``ranges`` of :func:`_column_ranges` where it gave them."""
    if ranges is not None:
        return rows_within(block, *ranges, increasing, t_last)
    if limits is not None and limits.problem(block, columns) is not None:
        return False
    return not increasing or first_not_increasing(block[:, 0], t_last) is None


def _column_ranges(limits: RowLimits | None, columns: tuple[str, ...]) -> tuple[np.ndarray, ...] | None:
    """Per column (low, high, open low, open high) of ``limits`` (no limit: any number); None where the limits
    bound vectors too (RowLimits.norms)."""
    if limits is not None and limits.norms:
        return None
    ranges = [ANY_NUMBER if limits is None else limits.cells.get(name, ANY_NUMBER) for name in columns]
    return (np.array([r.low for r in ranges], dtype=float), np.array([r.high for r in ranges], dtype=float),
            np.array([r.open_low for r in ranges], dtype=np.uint8),
            np.array([r.open_high for r in ranges], dtype=np.uint8))


def _line_segments(stream: TextIO, path: str, first_line: int, columns: tuple[str, ...], chunk_rows: int,
                   increasing: bool, limits: RowLimits | None,
                   t_last: float) -> Iterator[tuple[str | None, np.ndarray]]:
    """:func:`read_segments` line by line, the rows before the first after ``t_last``: cut at markers, each bad
    cell, out-of-order time or overlong line raised as LogFormatError with its line."""
    line_no = first_line
    while lines := _lines(stream, path, line_no, chunk_rows):
        for reason, piece, piece_line in _pieces(lines, line_no):
            if reason is not None:
                t_last = -math.inf
            block = _block(piece, piece_line, path, columns, limits)
            times = block[:, 0]
            found = first_not_increasing(times, t_last) if increasing else None
            if found is not None:
                raise LogFormatError(path, _line_of(piece, piece_line, found[0]), "t", found[1])
            if len(times):
                t_last = float(times[-1])
            if len(times) or reason is not None:
                yield reason, block
        line_no += len(lines)


@dataclass(frozen=True, slots=True)
class ImuLog:
    """An IMU log opened for streaming, CSV or its binary form (``binary``): its header and an iterator of
    (t, dtheta, dv) blocks."""

    path: str
    header: LogHeader
    binary: bool = False
    first_line: int = 1   # the line of the first sample (CSV), or its number (binary)

    @property
    def limits(self) -> RowLimits:
        """What this log's rows may physically hold at its rate (:func:`imu_limits`)."""
        return imu_limits(self.header.rate_hz)

    def blocks(self, chunk_rows: int = CHUNK_ROWS,
               limits: RowLimits | None = None) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """(t, Δθ, Δv) blocks of at most ``chunk_rows`` samples; with ``limits`` (:attr:`limits` for an alignment)
        a sample outside them stops the reading, named by line and column. Without, any finite value reads back
        exactly as written, the float64 extremes too."""
        for _, t, dtheta, dv in self.segments(chunk_rows, limits):
            if len(t):
                yield t, dtheta, dv

    def segments(self, chunk_rows: int = CHUNK_ROWS, limits: RowLimits | None = None
                 ) -> Iterator[tuple[str | None, np.ndarray, np.ndarray, np.ndarray]]:
        """(restart, t, Δθ, Δv) blocks as :meth:`blocks`, ``restart`` the reason of the :data:`RESTART_MARKER` line
        before the block (a daemon's recording: the alignment started over there), else None."""
        for reason, block in self.row_segments(chunk_rows, limits):
            yield reason, block[:, 0], block[:, 1:4], block[:, 4:7]

    def row_segments(self, chunk_rows: int = CHUNK_ROWS,
                     limits: RowLimits | None = None) -> Iterator[tuple[str | None, np.ndarray]]:
        """(restart, rows) as :meth:`segments`, the rows (N, 7: t, Δθ, Δv) as the reader parsed them."""
        if self.binary:
            from .imu_binary import read_binary_segments  # here: it builds on this module
            return read_binary_segments(self.path, chunk_rows, limits)
        return stream_segments(self.path, IMU_COLUMNS, REQUIRED_KEYS, chunk_rows, limits=limits)


def stream_segments(path: str, columns: tuple[str, ...], required: tuple[str, ...], chunk_rows: int = CHUNK_ROWS,
                    increasing: bool = True, ranges: Mapping[str, Range] = IMU_KEY_RANGES,
                    limits: RowLimits | None = None) -> Iterator[tuple[str | None, np.ndarray]]:
    """The (restart, block) pieces of :func:`read_segments` of a log with these columns, after its header (its keys
    checked against ``ranges``), each value within ``limits``."""
    with open(path, encoding="utf-8", errors="replace") as stream, open(path, "rb") as raw:
        _, consumed = read_header(stream, path, columns, required, ranges)
        pieces = _plain_pieces(raw) if _skip_plain_lines(raw, consumed) else _text_pieces(stream)
        yield from read_segments(pieces, path, consumed + 1, columns, chunk_rows, increasing, limits)


def _skip_plain_lines(raw: BinaryIO, count: int) -> bool:
    """Read ``count`` lines of ``raw`` (the header a text-mode read took): True if their bytes are their text (each
    ended by a newline, ASCII, no carriage return), so ``raw`` now stands where the text stream does."""
    for _ in range(count):
        line = raw.readline(MAX_LINE_CHARS + 1)
        if not line.endswith(b"\n") or not plain_text(line):
            return False
    return True


def stream_rows(path: str, columns: tuple[str, ...], required: tuple[str, ...], chunk_rows: int = CHUNK_ROWS,
                increasing: bool = True, ranges: Mapping[str, Range] = IMU_KEY_RANGES,
                limits: RowLimits | None = None) -> Iterator[np.ndarray]:
    """The blocks of :func:`stream_segments` without their restart marks."""
    for _, block in stream_segments(path, columns, required, chunk_rows, increasing, ranges, limits):
        yield block


def open_imu_log(path: str | Path) -> ImuLog:
    """Open and check an IMU log's header, CSV or binary (by its first line); raises LogFormatError (or OSError)
    with the file named."""
    from .imu_binary import is_binary, read_binary_header  # here: it builds on this module
    path = str(path)
    if is_binary(path):
        return ImuLog(path, read_binary_header(path), binary=True)
    with open(path, encoding="utf-8", errors="replace") as stream:
        header, consumed = read_header(stream, path)
    return ImuLog(path, header, first_line=consumed + 1)


def write_header(stream: TextIO, values: dict[str, object], columns: tuple[str, ...]) -> None:
    """Comment keys and the header row, each line ended (a reader takes a last line without its end as a file cut
    short)."""
    for key, value in values.items():
        stream.write(f"# {key}={value}\n")
    stream.write(",".join(columns) + "\n")


def write_rows(stream: TextIO, rows: np.ndarray) -> None:
    """Rows with round-trip precision (17 significant digits), so replays are exact; each line ended."""
    np.savetxt(stream, rows, fmt="%.17g", delimiter=",")


class CsvLogWriter:
    """Writes the pinned CSV IMU log to ``stream`` (text): the header of ``values`` now, then rows and restarts."""

    def __init__(self, stream: TextIO, values: Mapping[str, object]) -> None:
        self._stream = stream
        write_header(stream, dict(values), IMU_COLUMNS)

    def rows(self, rows: np.ndarray) -> None:
        write_rows(self._stream, rows)

    def restart(self, reason: str) -> None:
        """One line, whatever the reason's white space."""
        self._stream.write(f"{RESTART_MARKER} {' '.join(reason.split())}\n")

    def flush(self) -> None:
        self._stream.flush()

    def close(self) -> None:
        self._stream.close()

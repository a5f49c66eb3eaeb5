"""The IMU log's binary form (docs/reference.md, "Binary IMU log"): the pinned CSV log's header and samples, the
samples as raw little-endian float64, for long recordings (no text to format or parse: a 1-h 200-Hz log is 40 MB
and reads at memory speed).

Layout: first the CSV log's text header, UTF-8, every line ended: the line ``# format=sinsalign-imu-binary-1``,
then the comment keys (``# key=value``), then the column line ``t,dthx,dthy,dthz,dvx,dvy,dvz``. Then blocks to
the end of the file, each:

    b"SIB1" | rows: u32 | reason bytes: u32 (0xFFFFFFFF: none) | reason (UTF-8) | rows × 7 float64

all little-endian, the rows row-major in the columns' order. A block with a reason follows a restart of the
alignment (the CSV's ``# restart: why`` line; it may hold no rows). The reader holds the same promises as the
CSV's: every key within its range, every value finite and, when asked, within the rows' limits, time increasing
between restarts; a file cut short, a block of more than :data:`MAX_BLOCK_ROWS` rows or a reason longer than
:data:`MAX_REASON_BYTES` is refused naming the file and the sample (its number from 1), never read into memory
whole.
"""
from __future__ import annotations

import io
import math
import struct
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import BinaryIO

import numpy as np

from .imu_log import (
    CHUNK_ROWS,
    IMU_COLUMNS,
    IMU_KEY_RANGES,
    MAX_COMMENT_KEYS,
    MAX_LINE_CHARS,
    REQUIRED_KEYS,
    LogFormatError,
    LogHeader,
    Range,
    RowLimits,
    first_not_increasing,
    read_header,
    write_header,
)

FORMAT_LINE = "# format=sinsalign-imu-binary-1\n"
MAGIC = b"SIB1"
NO_REASON = 0xFFFFFFFF
MAX_BLOCK_ROWS = 1 << 20
"""Rows a block may hold (56 MiB): a count beyond is a corrupt file, not a block to allocate."""
MAX_REASON_BYTES = 4096
SUFFIX = ".sbin"
"""The file name ending that selects the binary form where a log is written (``--record``, ``convert``)."""
_HEAD = struct.Struct("<4sII")
_ROW_BYTES = 8 * len(IMU_COLUMNS)


def is_binary(path: str | Path) -> bool:
    """Whether the file at ``path`` begins as a binary IMU log."""
    with open(path, "rb") as stream:
        return stream.read(len(FORMAT_LINE)) == FORMAT_LINE.encode()


class BinaryLogWriter:
    """Writes a binary IMU log to ``stream`` (opened for binary writing): the header of ``values`` now, then
    :meth:`rows` and :meth:`restart` in the order they come."""

    def __init__(self, stream: BinaryIO, values: Mapping[str, object]) -> None:
        self._stream = stream
        text = io.StringIO()
        text.write(FORMAT_LINE)
        write_header(text, dict(values), IMU_COLUMNS)
        stream.write(text.getvalue().encode())

    def rows(self, rows: np.ndarray) -> None:
        """Samples (N, 7: t in s, Δθ in rad, Δv in m/s), in blocks of at most :data:`MAX_BLOCK_ROWS`."""
        rows = np.ascontiguousarray(rows, dtype="<f8").reshape(-1, len(IMU_COLUMNS))
        for start in range(0, len(rows), MAX_BLOCK_ROWS):
            self._block(rows[start:start + MAX_BLOCK_ROWS], None)

    def restart(self, reason: str) -> None:
        """The alignment started over here (whatever the reason's white space, one line of it)."""
        self._block(np.empty((0, len(IMU_COLUMNS)), dtype="<f8"), " ".join(reason.split()))

    def _block(self, rows: np.ndarray, reason: str | None) -> None:
        encoded = b"" if reason is None else reason.encode()[:MAX_REASON_BYTES]
        self._stream.write(_HEAD.pack(MAGIC, len(rows), NO_REASON if reason is None else len(encoded)))
        self._stream.write(encoded)
        self._stream.write(rows.tobytes())

    def flush(self) -> None:
        self._stream.flush()

    def close(self) -> None:
        self._stream.close()


def _read_text_header(stream: BinaryIO, path: str, ranges: Mapping[str, Range]) -> LogHeader:
    """The text header up to and with the column line, read a bounded line at a time and parsed as the CSV's."""
    lines = []
    while len(lines) <= MAX_COMMENT_KEYS + 1:
        raw = stream.readline(MAX_LINE_CHARS + 1)
        if not raw.endswith(b"\n"):
            raise LogFormatError(path, len(lines) + 1, None, "the header is cut short or has a line over "
                                 f"{MAX_LINE_CHARS} characters")
        lines.append(raw.decode("utf-8", errors="replace"))
        if not raw.startswith(b"#"):
            break
    else:
        raise LogFormatError(path, len(lines), None, f"more than {MAX_COMMENT_KEYS} comment keys")
    try:
        header, _ = read_header(io.StringIO("".join(lines[1:])), path, IMU_COLUMNS, REQUIRED_KEYS, ranges)
    except LogFormatError as exc:   # its lines counted from the one after the format line
        raise LogFormatError(path, exc.line + 1, exc.column, exc.problem) from None
    return header


def read_binary_header(path: str | Path, ranges: Mapping[str, Range] = IMU_KEY_RANGES) -> LogHeader:
    """The header of the binary IMU log at ``path`` (LogFormatError if it is none or malformed)."""
    path = str(path)
    with open(path, "rb") as stream:
        if stream.read(len(FORMAT_LINE)) != FORMAT_LINE.encode():
            raise LogFormatError(path, 1, None, f"not a binary IMU log (its first line is not {FORMAT_LINE.strip()})")
        stream.seek(0)
        return _read_text_header(stream, path, ranges)


def read_binary_segments(path: str | Path, chunk_rows: int = CHUNK_ROWS, limits: RowLimits | None = None
                         ) -> Iterator[tuple[str | None, np.ndarray]]:
    """(restart, block) as the CSV's :func:`~.imu_log.read_segments`: (N, 7) float64 blocks of at most
    ``chunk_rows`` samples, each value finite and within ``limits`` (if given), time increasing between restarts;
    ``restart`` the reason of a block that follows one, else None."""
    path = str(path)
    with open(path, "rb") as stream:
        _read_text_header(stream, path, IMU_KEY_RANGES)
        sample, t_last = 0, -math.inf
        while head := stream.read(_HEAD.size):
            magic, rows, reason_bytes = _HEAD.unpack(head) if len(head) == _HEAD.size else (b"", 0, 0)
            if magic != MAGIC:
                raise LogFormatError(path, sample + 1, None, "cut short or corrupt: no block starts here", "sample ")
            if rows > MAX_BLOCK_ROWS or (reason_bytes != NO_REASON and reason_bytes > MAX_REASON_BYTES):
                raise LogFormatError(path, sample + 1, None, f"corrupt block: {rows} rows, a reason of "
                                     f"{reason_bytes} bytes (at most {MAX_BLOCK_ROWS} and {MAX_REASON_BYTES})",
                                     "sample ")
            reason = None
            if reason_bytes != NO_REASON:
                reason, t_last = stream.read(reason_bytes).decode("utf-8", errors="replace"), -math.inf
                if not rows:
                    yield reason, np.empty((0, len(IMU_COLUMNS)))
            for start in range(0, rows, chunk_rows):
                n = min(chunk_rows, rows - start)
                data = stream.read(n * _ROW_BYTES)
                if len(data) < n * _ROW_BYTES:
                    raise LogFormatError(path, sample + len(data) // _ROW_BYTES + 1, None,
                                         "cut short: the file ends inside a block", "sample ")
                block = np.frombuffer(data, dtype="<f8").reshape(n, len(IMU_COLUMNS)).astype(np.float64)
                t_last = _checked(block, path, sample, t_last, limits)
                sample += n
                yield (reason if start == 0 else None), block


def _checked(block: np.ndarray, path: str, sample: int, t_last: float, limits: RowLimits | None) -> float:
    """``block``'s last time stamp, once every value is finite and within ``limits`` and time increases from
    ``t_last``; LogFormatError naming the first sample at fault (``sample`` samples came before the block)."""
    finite = np.isfinite(block)
    if not finite.all():
        row, column = np.argwhere(~finite)[0]
        raise LogFormatError(path, sample + int(row) + 1, IMU_COLUMNS[column],
                             f"{float(block[row, column])!r} is not a finite number", "sample ")
    problem = None if limits is None else limits.problem(block, IMU_COLUMNS)
    if problem is not None:
        row, column, text = problem
        raise LogFormatError(path, sample + row + 1, column, text, "sample ")
    found = first_not_increasing(block[:, 0], t_last)
    if found is not None:
        raise LogFormatError(path, sample + found[0] + 1, "t", found[1], "sample ")
    return float(block[-1, 0]) if len(block) else t_last

"""The CSV reader's two ways through a log's text (protocol/imu_log.py): the bytes of a plain file parsed where they
lie, and a text-mode read (UTF-8 with bad bytes replaced, universal newlines) from the first piece that is not plain.

GIVEN any log (plain rows, comments in any language, restart markers, Windows and old Mac line ends, bytes that are
no UTF-8, lines of thousands of characters, a last line cut short), read in pieces of any size, WHEN the reader takes
it, THEN it gives what a text-mode read of the whole file gives: the same blocks of samples bit for bit, the same
restart marks, or the same error naming the same line and column.
"""
from __future__ import annotations

import io
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sinsalign.protocol import imu_log
from sinsalign.protocol.imu_log import (
    IMU_COLUMNS,
    IMU_KEY_RANGES,
    REQUIRED_KEYS,
    LogFormatError,
    imu_limits,
    read_header,
    read_segments,
    stream_segments,
    write_header,
)

HEADER = {"lat_deg": 45.5, "lon_deg": -73.25, "height_m": 12.0, "rate_hz": 100.0}
FUZZ = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
LINE_ENDS = st.sampled_from([b"\n"] * 12 + [b"\r\n", b"\r"])


@st.composite
def log_bytes(draw) -> bytes:
    """A log's bytes: its header (sometimes with Windows line ends or a comment beyond ASCII) and lines of every
    kind a recording or a hostile file holds."""
    head = io.StringIO()
    write_header(head, HEADER, IMU_COLUMNS)
    header = head.getvalue().encode()
    if draw(st.integers(0, 9)) == 0:
        header = header.replace(b"\n", b"\r\n")
    if draw(st.integers(0, 9)) == 0:
        header = "# opérateur: Zoë\n".encode() + header
    lines, t = [], 0.0
    for _ in range(draw(st.integers(0, 120))):
        kind = draw(st.sampled_from(["row"] * 10 + ["comment", "marker", "blank", "bad", "wide", "long", "back"]))
        t += 0.01
        if kind == "row":
            line = f"{t!r},1e-05,-2.5e-06,0,0.001,-0.002,0.0980665".encode()
        elif kind == "back":   # time steps back: a marker before it makes it a new time base
            t -= 1.0
            line = f"{t!r},0,0,0,0,0,0.0980665".encode()
        elif kind == "comment":
            line = draw(st.sampled_from([b"# note", " # déjà vu".encode(), b"# \xff\xfe not UTF-8", b"#"]))
        elif kind == "marker":
            line = b"# restart: " + draw(st.sampled_from([b"outage 2.0 s", b"clock reset", "réinit".encode()]))
        elif kind == "blank":
            line = draw(st.sampled_from([b"", b"  ", b"\t"]))
        elif kind == "bad":
            line = draw(st.sampled_from([b"0.5,0,0,0,0,0", b"x,0,0,0,0,0,0", b"1,nan,0,0,0,0,0", b"1,2,3,4,5,6,7,8",
                                         "0.5,０,0,0,0,0,0".encode()]))
        elif kind == "wide":   # a row an IMU cannot measure: refused under the replay's limits only
            line = f"{t!r},1e300,0,0,0,0,0.0980665".encode()
        else:
            line = b"#" + b"x" * draw(st.sampled_from([4094, 4095, 4096, 5000]))
        lines.append(line + draw(LINE_ENDS))
    body = b"".join(lines)
    if body and draw(st.booleans()):
        body = body[:draw(st.integers(0, len(body) - 1))]   # cut anywhere: inside a line, a number, a line end
    return header + body


def outcome(pieces) -> list[tuple[str | None, bytes]] | str:
    """What a reader yields, block by block, or its error's message."""
    try:
        return [(reason, rows.tobytes()) for reason, rows in pieces]
    except LogFormatError as exc:
        return str(exc)


def text_mode_outcome(path: Path, limits) -> list[tuple[str | None, bytes]] | str:
    """The whole file read in text mode: the reference."""
    try:
        with open(path, encoding="utf-8", errors="replace") as stream:
            _, consumed = read_header(stream, str(path), IMU_COLUMNS, REQUIRED_KEYS, IMU_KEY_RANGES)
            return outcome(read_segments(imu_log._text_pieces(stream), str(path), consumed + 1, IMU_COLUMNS,
                                         chunk_rows=7, limits=limits))
    except LogFormatError as exc:
        return str(exc)


@FUZZ
@given(data=log_bytes(), chunk_chars=st.sampled_from([64, 333, 4097, 1 << 19]), limited=st.booleans())
def test_the_reader_gives_what_a_text_mode_read_gives(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, data: bytes,
                                                     chunk_chars: int, limited: bool) -> None:
    monkeypatch.setattr(imu_log, "CHUNK_CHARS", chunk_chars)
    path = tmp_path / "imu.csv"
    path.write_bytes(data)
    limits = imu_limits(HEADER["rate_hz"]) if limited else None
    got = outcome(stream_segments(str(path), IMU_COLUMNS, REQUIRED_KEYS, chunk_rows=7, limits=limits))
    assert got == text_mode_outcome(path, limits)


def test_a_plain_log_is_read_from_its_bytes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The fast way is the one taken on a plain file, and a piece that is not plain turns the rest to text mode."""
    monkeypatch.setattr(imu_log, "CHUNK_CHARS", 1000)
    head = io.StringIO()
    write_header(head, HEADER, IMU_COLUMNS)
    rows = "".join(f"{k / 100!r},0,0,0,0,0,0.0980665\n" for k in range(1, 200))
    path = tmp_path / "imu.csv"
    for tail, kinds in (("", [memoryview]), ("# fin de l'essai à 2 s\n" + rows, [memoryview, str])):
        path.write_text(head.getvalue() + rows + tail, encoding="utf-8")
        with open(path, "rb") as raw:
            assert imu_log._skip_plain_lines(raw, 5)
            pieces = [type(piece) for piece in imu_log._plain_pieces(raw)]
        assert sorted(set(pieces), key=pieces.index) == kinds

"""The pinned IMU log (CSV): exact round trip, precise errors (file, line, column), CLI errors, fuzzing."""
from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sinsalign.protocol.imu_log import (
    DATASHEET_KEYS,
    IMU_COLUMNS,
    LogFormatError,
    open_imu_log,
    write_header,
    write_rows,
)

from sinsalign.cli import main

HEADER = {"lat_deg": 45.5, "lon_deg": -73.25, "height_m": 12.0, "rate_hz": 100.0}
# 4 comment lines, the column header on line 5, so data row k (0-based) is on line FIRST_DATA_LINE + k.
FIRST_DATA_LINE = 6
CHUNK_SIZES = (1, 2, 3, 4, 7, 20000)
FUZZ = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def sample_rows(n: int, rate_hz: float = 100.0) -> np.ndarray:
    """n plausible samples: t strictly increasing, small increments, awkward (non-short) decimals."""
    rng = np.random.default_rng(1234)
    rows = np.empty((n, 7))
    rows[:, 0] = np.arange(1, n + 1) / rate_hz + 1e-7 * rng.random()
    rows[:, 1:4] = 1e-5 * rng.standard_normal((n, 3))
    rows[:, 4:7] = 1e-3 * rng.standard_normal((n, 3)) + np.array([0.0, 0.0, 9.80665 / rate_hz])
    return rows


def row_text(t: float, cells: tuple[str, ...] | None = None) -> str:
    return ",".join([repr(t), *(cells or ("0", "0", "0", "0", "0", "0.0980665"))])


def good_lines(n: int) -> list[str]:
    return [row_text((k + 1) / 100) for k in range(n)]


def write_text_log(path: Path, lines: list[str], header: dict[str, object] | None = None,
                   columns: tuple[str, ...] = IMU_COLUMNS) -> Path:
    buf = io.StringIO()
    write_header(buf, HEADER if header is None else header, columns)
    path.write_text(buf.getvalue() + "".join(line + "\n" for line in lines), encoding="utf-8")
    return path


def write_array_log(path: Path, rows: np.ndarray, header: dict[str, object] | None = None) -> Path:
    with open(path, "w", encoding="utf-8") as stream:
        write_header(stream, HEADER if header is None else header, IMU_COLUMNS)
        write_rows(stream, rows)
    return path


def read_all(path: Path, chunk_rows: int = 20000) -> np.ndarray:
    blocks = [np.column_stack([t, dth, dv]) for t, dth, dv in open_imu_log(path).blocks(chunk_rows=chunk_rows)]
    return np.concatenate(blocks) if blocks else np.empty((0, 7))


def assert_bits_equal(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype == np.float64 and b.dtype == np.float64
    assert a.shape == b.shape
    np.testing.assert_array_equal(a.view(np.uint64), b.view(np.uint64))


def read_error(path: Path, chunk_rows: int = 20000) -> LogFormatError:
    with pytest.raises(LogFormatError) as info:
        read_all(path, chunk_rows)
    return info.value


def check_error(exc: LogFormatError, path: Path, line: int, column: str | None) -> None:
    assert (exc.line, exc.column) == (line, column), str(exc)
    assert exc.path == str(path)
    message = str(exc)
    assert message.startswith(f"{path}:{line}"), message
    if column is not None:
        assert f"column {column!r}" in message, message
    else:
        assert "column" not in message, message


# --- round trip ------------------------------------------------------------------------------------------------


def test_round_trip_exact_across_chunk_sizes(tmp_path: Path) -> None:
    rows = sample_rows(23)
    # values that need all 17 significant digits or sit at the edges of float64
    rows[0, 1:7] = [0.1, 1 / 3, -2 / 3, 5e-324, -1.7976931348623157e308, -0.0]
    rows[1, 1:7] = [2.2250738585072014e-308, np.nextafter(1.0, 2.0), np.pi, -np.e, 1e22, 123456789.12345678]
    path = write_array_log(tmp_path / "imu.csv", rows)
    reference = read_all(path)
    assert_bits_equal(reference, rows)
    for chunk_rows in CHUNK_SIZES:
        blocks = list(open_imu_log(path).blocks(chunk_rows=chunk_rows))
        assert all(0 < len(t) <= chunk_rows for t, _, _ in blocks)
        assert len(blocks) == math.ceil(len(rows) / chunk_rows)
        for t, dth, dv in blocks:
            assert t.shape == (len(t),) and dth.shape == (len(t), 3) and dv.shape == (len(t), 3)
        assert_bits_equal(read_all(path, chunk_rows), rows)


def test_header_values_and_datasheet_round_trip(tmp_path: Path) -> None:
    header = {**HEADER, "gyro_bias_deg_h": 0.01, "gyro_arw_deg_rth": 0.001, "acc_bias_ug": 50.0,
              "acc_vrw_ug_rthz": 5.0, "note": "bench run 7"}
    log = open_imu_log(write_array_log(tmp_path / "imu.csv", sample_rows(3), header))
    assert (log.header.lat_deg, log.header.lon_deg, log.header.height_m, log.header.rate_hz) == (45.5, -73.25, 12.0,
                                                                                                  100.0)
    assert log.header.datasheet() == {k: header[k] for k in DATASHEET_KEYS}
    assert log.header.values["note"] == "bench run 7"


def test_datasheet_is_empty_when_absent(tmp_path: Path) -> None:
    assert open_imu_log(write_array_log(tmp_path / "imu.csv", sample_rows(2))).header.datasheet() == {}


def test_header_only_log_has_no_rows(tmp_path: Path) -> None:
    path = write_text_log(tmp_path / "imu.csv", [])
    assert read_all(path).shape == (0, 7)


# --- malformed rows ----------------------------------------------------------------------------------------------

# (cells after t, expected column)
BAD_CELLS = [
    (("0", "0", "0", "0", "abc", "0.098"), "dvy"),
    (("x1", "0", "0", "0", "0", "0.098"), "dthx"),
    (("0", "0", "0", "0", "0", ""), "dvz"),
    (("nan", "0", "0", "0", "0", "0.098"), "dthx"),
    (("0", "NaN", "0", "0", "0", "0.098"), "dthy"),
    (("0", "0", "inf", "0", "0", "0.098"), "dthz"),
    (("0", "0", "0", "-inf", "0", "0.098"), "dvx"),
    (("0", "0", "0", "0", "0", "1e400"), "dvz"),
]
# bad line in the first chunk (line 8) and in a later chunk (line 15: chunks of 4 are lines 6-9, 10-13, 14-17)
POSITIONS = [(8, 4), (15, 4), (15, 1), (15, 20000), (FIRST_DATA_LINE, 4), (FIRST_DATA_LINE + 19, 4)]


@pytest.mark.parametrize(("line", "chunk_rows"), POSITIONS)
@pytest.mark.parametrize(("cells", "column"), BAD_CELLS)
def test_bad_cell_names_line_and_column(tmp_path: Path, cells: tuple[str, ...], column: str, line: int,
                                        chunk_rows: int) -> None:
    lines = good_lines(20)
    k = line - FIRST_DATA_LINE
    lines[k] = row_text((k + 1) / 100, cells)
    path = write_text_log(tmp_path / "bad.csv", lines)
    check_error(read_error(path, chunk_rows), path, line, column)


def test_bad_t_cell_names_column_t(tmp_path: Path) -> None:
    lines = good_lines(20)
    lines[9] = "oops,0,0,0,0,0,0.098"
    path = write_text_log(tmp_path / "bad.csv", lines)
    check_error(read_error(path, 4), path, FIRST_DATA_LINE + 9, "t")


@pytest.mark.parametrize(("line", "chunk_rows"), POSITIONS)
@pytest.mark.parametrize(("text", "found"), [("0.5,0,0,0,0,0", 6), ("0.5,0,0,0,0,0,0,0", 8),
                                             ("0.5,0,0,0,0,0,0,", 8), ("0.5;0;0;0;0;0;0", 1)])
def test_wrong_cell_count_names_line(tmp_path: Path, text: str, found: int, line: int, chunk_rows: int) -> None:
    lines = good_lines(20)
    lines[line - FIRST_DATA_LINE] = text
    path = write_text_log(tmp_path / "bad.csv", lines)
    exc = read_error(path, chunk_rows)
    check_error(exc, path, line, IMU_COLUMNS[found] if found < len(IMU_COLUMNS) else None)   # a short row names
    assert f"expected 7 values, found {found}" in str(exc)                                  # its first missing cell


def test_missing_cell_names_first_missing_column(tmp_path: Path) -> None:
    lines = good_lines(10)
    lines[3] = "0.04,0,0,0,0,0"
    path = write_text_log(tmp_path / "bad.csv", lines)
    exc = read_error(path)
    assert (exc.line, exc.column) == (FIRST_DATA_LINE + 3, "dvz")


@pytest.mark.parametrize(("line", "chunk_rows"), [*POSITIONS, (10, 4), (14, 4)])  # 10, 14: first row of a chunk
@pytest.mark.parametrize("step", [0.0, -0.005, -1.0])
def test_time_not_increasing_names_line_and_t(tmp_path: Path, step: float, line: int, chunk_rows: int) -> None:
    lines = good_lines(20)
    k = line - FIRST_DATA_LINE
    if k == 0:  # the first row may hold any time: make the second one fail instead
        k, line = 1, line + 1
    lines[k] = row_text(k / 100 + step)  # previous row holds t = k / 100
    path = write_text_log(tmp_path / "bad.csv", lines)
    exc = read_error(path, chunk_rows)
    check_error(exc, path, line, "t")
    assert "time does not increase" in str(exc)


def test_first_row_may_hold_any_finite_time(tmp_path: Path) -> None:
    path = write_text_log(tmp_path / "imu.csv", [row_text(-5.0), row_text(-4.99), row_text(0.0)])
    np.testing.assert_array_equal(read_all(path, 1)[:, 0], [-5.0, -4.99, 0.0])


def test_time_error_message_shows_plain_numbers(tmp_path: Path) -> None:
    lines = good_lines(10)
    lines[4] = row_text(0.03)
    path = write_text_log(tmp_path / "bad.csv", lines)
    message = str(read_error(path))
    assert "np.float64" not in message
    assert "0.03 after 0.04" in message


# --- blank lines ----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("chunk_rows", CHUNK_SIZES)
def test_blank_lines_in_data_are_skipped(tmp_path: Path, chunk_rows: int) -> None:
    rows = sample_rows(12)
    buf = io.StringIO()
    write_rows(buf, rows)
    lines = buf.getvalue().splitlines()
    for k in (9, 5, 5, 2, 0):  # runs of blank lines, one right after the header; whitespace-only too
        lines.insert(k, "   \t" if k == 5 else "")
    lines += ["", ""]
    path = write_text_log(tmp_path / "imu.csv", lines)
    assert_bits_equal(read_all(path, chunk_rows), rows)


@pytest.mark.parametrize("chunk_rows", [1, 2, 3, 4, 20000])
def test_blank_lines_keep_time_error_line_numbers(tmp_path: Path, chunk_rows: int) -> None:
    lines = good_lines(12)
    lines[8] = row_text(0.08)  # line 14 repeats the time of line 13
    for k in (7, 3, 1):
        lines.insert(k, "")
    # blank lines on 7, 10 and 15 now; the bad row moved from line 14 to 17
    path = write_text_log(tmp_path / "bad.csv", lines)
    check_error(read_error(path, chunk_rows), path, 17, "t")


@pytest.mark.parametrize("chunk_rows", [1, 2, 4])
def test_blank_line_in_earlier_chunk_keeps_bad_cell_line(tmp_path: Path, chunk_rows: int) -> None:
    lines = good_lines(12)
    lines.insert(1, "")  # line 7
    lines[9] = row_text(0.09, ("0", "0", "0", "0", "abc", "0"))  # line 15
    path = write_text_log(tmp_path / "bad.csv", lines)
    check_error(read_error(path, chunk_rows), path, 15, "dvy")


@pytest.mark.parametrize("chunk_rows", [4, 20000])
def test_blank_line_before_bad_cell_in_same_chunk(tmp_path: Path, chunk_rows: int) -> None:
    lines = good_lines(12)
    lines.insert(1, "")  # line 7
    lines[2] = row_text(0.02, ("0", "0", "0", "0", "abc", "0"))  # line 8, same chunk as line 7
    path = write_text_log(tmp_path / "bad.csv", lines)
    check_error(read_error(path, chunk_rows), path, 8, "dvy")


# --- faults numpy and float() disagree on, comment lines among the data ----------------------------------------------


@pytest.mark.parametrize("cell", ["1_0", "\uff11"])
def test_cell_numpy_refuses_but_float_accepts(tmp_path: Path, cell: str) -> None:
    lines = good_lines(12)
    lines[5] = row_text(0.06, ("0", "0", "0", "0", cell, "0"))  # line 11, chunk of 4 starts on line 10
    path = write_text_log(tmp_path / "bad.csv", lines)
    check_error(read_error(path, 4), path, 11, "dvy")


def test_comment_line_among_rows_keeps_time_error_line(tmp_path: Path) -> None:
    lines = good_lines(12)
    lines.insert(2, "# note")  # line 8
    lines[5] = row_text(0.03)  # line 11: t = 0.03 after t = 0.04 on line 10
    path = write_text_log(tmp_path / "bad.csv", lines)
    exc = read_error(path)
    # either the stray comment (comment lines belong before the header) or the row whose time goes back
    assert (exc.line, exc.column) in {(8, None), (11, "t")}, str(exc)


def outcome(path: Path, chunk_rows: int) -> object:
    try:
        return read_all(path, chunk_rows).tobytes()
    except LogFormatError as exc:
        return (exc.line, exc.column)


@pytest.mark.filterwarnings("ignore:loadtxt:UserWarning")
def test_comment_line_among_rows_same_outcome_for_every_chunk_size(tmp_path: Path) -> None:
    lines = good_lines(12)
    lines.insert(3, "# note")  # line 9
    path = write_text_log(tmp_path / "imu.csv", lines)
    outcomes = {chunk_rows: outcome(path, chunk_rows) for chunk_rows in CHUNK_SIZES}
    assert len(set(outcomes.values())) == 1, outcomes


# --- malformed header -----------------------------------------------------------------------------------------------


def header_error(path: Path) -> LogFormatError:
    with pytest.raises(LogFormatError) as info:
        open_imu_log(path)
    return info.value


@pytest.mark.parametrize("header_row", ["t,dthx,dthy,dthz,dvx,dvy", "t,dthx,dthy,dthz,dvx,dvy,dvz,extra",
                                        "t,dthy,dthx,dthz,dvx,dvy,dvz", "0.01,0,0,0,0,0,0.098", "time,a,b,c,d,e,f"])
def test_wrong_header_row(tmp_path: Path, header_row: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text("".join(f"# {k}={v}\n" for k, v in HEADER.items()) + header_row + "\n0.01,0,0,0,0,0,0\n")
    exc = header_error(path)
    check_error(exc, path, 5, None)
    assert "header must be" in str(exc)


def test_header_row_tolerates_spaces(tmp_path: Path) -> None:
    path = tmp_path / "imu.csv"
    path.write_text("".join(f"# {k} = {v}\n" for k, v in HEADER.items()) + " t, dthx ,dthy,dthz,dvx,dvy,dvz \n"
                    + row_text(0.01) + "\n")
    assert read_all(path).shape == (1, 7)


@pytest.mark.parametrize("missing", ["lat_deg", "lon_deg", "height_m", "rate_hz"])
def test_missing_required_key(tmp_path: Path, missing: str) -> None:
    header = {k: v for k, v in HEADER.items() if k != missing}
    path = write_text_log(tmp_path / "bad.csv", good_lines(3), header)
    exc = header_error(path)
    check_error(exc, path, 4, None)
    assert missing in str(exc) and "missing" in str(exc)


@pytest.mark.parametrize("rate", ["0", "0.0", "-100", "-0.0"])
def test_rate_not_positive(tmp_path: Path, rate: str) -> None:
    path = write_text_log(tmp_path / "bad.csv", good_lines(3), {**HEADER, "rate_hz": rate})
    exc = header_error(path)
    check_error(exc, path, 5, None)
    assert "rate_hz" in str(exc) and "positive" in str(exc)


@pytest.mark.parametrize(("key", "value"), [("lat_deg", "abc"), ("lat_deg", "nan"), ("lon_deg", "inf"),
                                            ("height_m", ""), ("rate_hz", "fast"), ("rate_hz", "inf")])
def test_required_key_not_a_finite_number(tmp_path: Path, key: str, value: str) -> None:
    path = write_text_log(tmp_path / "bad.csv", good_lines(3), {**HEADER, key: value})
    exc = header_error(path)
    check_error(exc, path, 5, None)
    assert key in str(exc) and "not a finite number" in str(exc)


@pytest.mark.parametrize("key", DATASHEET_KEYS)
@pytest.mark.parametrize("value", ["-1", "-1e-9", "abc", "nan", "inf"])
def test_bad_datasheet_key(tmp_path: Path, key: str, value: str) -> None:
    path = write_text_log(tmp_path / "bad.csv", good_lines(3), {**HEADER, key: value})
    exc = header_error(path)
    check_error(exc, path, 6, None)
    assert key in str(exc)


def test_zero_datasheet_key_is_accepted(tmp_path: Path) -> None:
    path = write_text_log(tmp_path / "imu.csv", good_lines(3), {**HEADER, "acc_bias_ug": 0})
    assert open_imu_log(path).header.datasheet() == {"acc_bias_ug": 0.0}


def test_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "empty.csv"
    path.write_bytes(b"")
    exc = header_error(path)
    check_error(exc, path, 1, None)
    assert "no header" in str(exc)


def test_comments_but_no_header(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    path.write_text("".join(f"# {k}={v}\n" for k, v in HEADER.items()) + "\n")
    exc = header_error(path)
    assert exc.path == str(path) and exc.column is None and exc.line in (4, 5)
    assert str(exc).startswith(f"{path}:{exc.line}")
    assert "no header" in str(exc)


def test_missing_file_is_oserror(tmp_path: Path) -> None:
    with pytest.raises(OSError):
        open_imu_log(tmp_path / "nope.csv")


# --- the CLI ----------------------------------------------------------------------------------------------------------


def run_replay(capsys: pytest.CaptureFixture[str], tmp_path: Path, log: Path) -> tuple[int, str]:
    code = main(["replay", str(log), "--out", str(tmp_path / "r.jsonl"), "--no-progress"])
    return code, capsys.readouterr().err


@pytest.mark.parametrize(("k", "text", "column"), [
    (14, "0.15,0,0,0,0,abc,0.098", "dvy"),
    (3, "0.04,0,0,nan,0,0,0.098", "dthz"),
    (25, "0.26,0,0,0,0,0,inf", "dvz"),
    (160, "1.6,0,0,0,0,0,0.098", "t"),  # repeats the previous row's time
])
def test_cli_replay_names_file_line_column(capsys: pytest.CaptureFixture[str], tmp_path: Path, k: int, text: str,
                                           column: str) -> None:
    lines = good_lines(300)
    lines[k] = text
    log = write_text_log(tmp_path / "bad_imu.csv", lines)
    code, err = run_replay(capsys, tmp_path, log)
    assert code == 2
    line = FIRST_DATA_LINE + k
    assert f"{log}:{line}" in err
    assert f"column {column!r}" in err
    assert "Traceback" not in err


def test_failed_replay_leaves_the_previous_results_file_untouched(capsys: pytest.CaptureFixture[str],
                                                                 tmp_path: Path) -> None:
    (tmp_path / "r.jsonl").write_text("previous results\n")
    lines = good_lines(30000)   # the fault sits past the first chunk: results were already being written
    lines[25000] = "oops"
    code, _ = run_replay(capsys, tmp_path, write_text_log(tmp_path / "late_fault.csv", lines))
    assert code == 2
    assert (tmp_path / "r.jsonl").read_text() == "previous results\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["late_fault.csv", "r.jsonl"]


def test_cli_replay_header_error(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    log = write_text_log(tmp_path / "no_rate.csv", good_lines(10), {k: v for k, v in HEADER.items() if k != "rate_hz"})
    code, err = run_replay(capsys, tmp_path, log)
    assert code == 2
    assert f"{log}:4" in err and "rate_hz" in err


def test_cli_replay_missing_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, err = run_replay(capsys, tmp_path, tmp_path / "absent.csv")
    assert code == 2 and "error" in err


def test_cli_replay_good_log_exits_zero(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    log = write_array_log(tmp_path / "imu.csv", sample_rows(250))
    code, _ = run_replay(capsys, tmp_path, log)
    assert code == 0
    assert (tmp_path / "r.jsonl").read_text().count("\n") >= 2


# --- fuzzing ---------------------------------------------------------------------------------------------------------


def parse_or_format_error(path: Path, chunk_rows: int) -> None:
    """Reading must either succeed or raise LogFormatError; anything else escapes and fails the test."""
    try:
        for t, dth, dv in open_imu_log(path).blocks(chunk_rows=chunk_rows):
            assert np.isfinite(t).all() and np.isfinite(dth).all() and np.isfinite(dv).all()
            assert (np.diff(t) > 0).all()
    except LogFormatError as exc:
        assert exc.path == str(path) and exc.line >= 1
        assert str(exc).startswith(f"{path}:{exc.line}")


NUMBERISH = st.text(alphabet="0123456789.,-+eE naifNI\t#_", max_size=60)
FLOAT_TEXT = st.floats().map(repr) | st.integers(-10**6, 10**6).map(str) | st.sampled_from(["", "nan", "1e999", "x"])
ROWISH = st.lists(FLOAT_TEXT, min_size=5, max_size=9).map(",".join)
DATA_LINE = st.one_of(st.text(max_size=40), NUMBERISH, ROWISH, st.just(""))


@pytest.mark.filterwarnings("ignore:loadtxt:UserWarning")
@FUZZ
@given(lines=st.lists(DATA_LINE, max_size=25), chunk_rows=st.sampled_from([1, 3, 20000]))
def test_fuzz_text_after_valid_header(tmp_path: Path, lines: list[str], chunk_rows: int) -> None:
    path = tmp_path / "fuzz.csv"
    buf = io.StringIO()
    write_header(buf, HEADER, IMU_COLUMNS)
    path.write_text(buf.getvalue() + "\n".join(lines), encoding="utf-8", errors="surrogatepass")
    parse_or_format_error(path, chunk_rows)


@pytest.mark.filterwarnings("ignore:loadtxt:UserWarning")
@FUZZ
@given(data=st.binary(max_size=400), with_header=st.booleans(), chunk_rows=st.sampled_from([1, 3, 20000]))
def test_fuzz_arbitrary_bytes(tmp_path: Path, data: bytes, with_header: bool, chunk_rows: int) -> None:
    path = tmp_path / "fuzz.csv"
    buf = io.StringIO()
    write_header(buf, HEADER, IMU_COLUMNS)
    path.write_bytes((buf.getvalue().encode() if with_header else b"") + data)
    parse_or_format_error(path, chunk_rows)


FINITE = st.floats(allow_nan=False, allow_infinity=False)


@FUZZ
@given(times=st.lists(FINITE, min_size=1, max_size=30, unique=True), data=st.data(),
       chunk_rows=st.sampled_from([1, 2, 3, 5, 20000]))
def test_fuzz_round_trip(tmp_path: Path, times: list[float], data: st.DataObject, chunk_rows: int) -> None:
    cells = data.draw(st.lists(st.lists(FINITE, min_size=6, max_size=6), min_size=len(times), max_size=len(times)))
    rows = np.column_stack([np.sort(np.array(times)), np.array(cells, dtype=np.float64).reshape(len(times), 6)])
    path = write_array_log(tmp_path / "fuzz.csv", rows)
    assert_bits_equal(read_all(path, chunk_rows), rows)

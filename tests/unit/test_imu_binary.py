"""The IMU log's binary form: exact round trips with the CSV (samples and restart marks, any chunking), the same
checks as the CSV's, and hostile files refused by a one-line error naming the sample, never a crash."""
from __future__ import annotations

import io
import struct
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sinsalign.protocol.imu_binary import FORMAT_LINE, MAGIC, MAX_BLOCK_ROWS, NO_REASON, BinaryLogWriter
from sinsalign.protocol.imu_log import LogFormatError, open_imu_log
from sinsalign.service.recording import open_log_writer
from sinsalign.tools.convert import convert
from sinsalign.tools.sim.files import write_simulation
from sinsalign.tools.sim.scenarios import get_scenario

from sinsalign.cli import main

HEADER = {"lat_deg": 45.5, "lon_deg": -73.25, "height_m": 12.0, "rate_hz": 100.0, "gyro_bias_deg_h": 0.01}
CHUNK_SIZES = (1, 3, 7, 20000)
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def sample_rows(n: int, t0: float = 0.0) -> np.ndarray:
    rng = np.random.default_rng(n)
    rows = np.empty((n, 7))
    rows[:, 0] = t0 + np.arange(1, n + 1) / 100.0 + 1e-7 * rng.random()
    rows[:, 1:4] = 1e-5 * rng.standard_normal((n, 3))
    rows[:, 4:7] = 1e-3 * rng.standard_normal((n, 3)) + np.array([0.0, 0.0, 0.0980665])
    return rows


def write_log(path: Path, pieces: list[tuple[str | None, np.ndarray]]) -> Path:
    writer = open_log_writer(path, HEADER)
    for reason, rows in pieces:
        if reason is not None:
            writer.restart(reason)
        writer.rows(rows)
    writer.close()
    return path


def segments(path: Path, chunk_rows: int = 20000, limits: bool = False) -> list[tuple[str | None, np.ndarray]]:
    """The (restart, rows) pieces of a log, empty marker pieces merged into the rows after them (the two forms cut
    their pieces differently; what a reader gets is the same samples and the same marks before the same rows)."""
    log = open_imu_log(path)
    out: list[tuple[str | None, np.ndarray]] = []
    pending = None
    for reason, t, dtheta, dv in log.segments(chunk_rows, log.limits if limits else None):
        pending = reason if reason is not None else pending
        if len(t):
            rows = np.column_stack((t, dtheta, dv))
            if pending is None and out:
                out[-1] = (out[-1][0], np.vstack((out[-1][1], rows)))
            else:
                out.append((pending, rows))
            pending = None
    return out


PIECES = [(None, sample_rows(50)), ("outage 2.0 s", sample_rows(30, 10.0)), ("clock reset", sample_rows(25, -5.0))]
IN_ORDER = PIECES[:2]
"""Time increasing across the marker: only the marker itself cuts the rows."""


@pytest.mark.parametrize("chunk_rows", CHUNK_SIZES)
@pytest.mark.parametrize("pieces", [PIECES, IN_ORDER])
def test_csv_and_binary_hold_the_same_samples_and_restart_marks_bit_for_bit(tmp_path, chunk_rows, pieces):
    csv = write_log(tmp_path / "imu.csv", pieces)
    binary, back = tmp_path / "imu.sbin", tmp_path / "back.csv"
    assert convert(csv, binary) == convert(binary, back) == sum(len(rows) for _, rows in pieces)
    for path in (csv, binary, back):
        got = segments(path, chunk_rows)
        assert [r for r, _ in got] == [r for r, _ in pieces]
        for (_, rows), (_, want) in zip(got, pieces, strict=True):
            assert rows.tobytes() == want.tobytes()
    assert open_imu_log(binary).header.values == open_imu_log(csv).header.values
    assert open_imu_log(binary).binary and not open_imu_log(csv).binary


def test_the_simulator_writes_the_same_samples_in_either_form(tmp_path):
    scenario = replace(get_scenario("seed000-swing"), duration_s=3.0)
    csv = write_simulation(scenario, 4, tmp_path / "csv").imu_csv
    binary = write_simulation(scenario, 4, tmp_path / "bin", binary=True).imu_csv
    assert binary.suffix == ".sbin" and open_imu_log(binary).binary
    assert segments(binary)[0][1].tobytes() == segments(csv)[0][1].tobytes()
    assert open_imu_log(binary).header.values == open_imu_log(csv).header.values


def test_extreme_finite_values_read_back_exactly(tmp_path):
    rows = sample_rows(4)
    rows[1, 1:] = [1e308, -1e308, 5e-324, -0.0, 2.2250738585072014e-308, 1.0 + 2**-52]
    path = write_log(tmp_path / "imu.sbin", [(None, rows)])
    assert segments(path)[0][1].tobytes() == rows.tobytes()


def corrupt(path: Path, offset_from_end: int, data: bytes) -> Path:
    raw = bytearray(path.read_bytes())
    raw[len(raw) - offset_from_end:len(raw) - offset_from_end + len(data)] = data
    path.write_bytes(bytes(raw))
    return path


def refusal(path: Path, limits: bool = True) -> str:
    with pytest.raises(LogFormatError) as info:
        segments(path, limits=limits)
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(path))
    return message


def test_a_value_that_is_not_finite_or_not_physical_is_refused_by_sample_and_column(tmp_path):
    rows = sample_rows(10)
    rows[6, 2] = np.nan
    assert "nan.sbin:sample 7, column 'dthy': nan is not a finite number" in refusal(
        write_log(tmp_path / "nan.sbin", [(None, rows)]))
    rows = sample_rows(10)
    rows[3, 5] = 1e300
    assert ":sample 4, column 'dvy'" in refusal(write_log(tmp_path / "huge.sbin", [(None, rows)]))
    rows = sample_rows(10)
    rows[8, 0] = rows[7, 0]
    assert ":sample 9, column 't': time does not increase" in refusal(write_log(tmp_path / "t.sbin", [(None, rows)]))


def test_a_header_key_out_of_range_is_refused_as_in_the_csv(tmp_path):
    with open(tmp_path / "lat.sbin", "wb") as stream:
        BinaryLogWriter(stream, {**HEADER, "lat_deg": 95.0}).rows(sample_rows(3))
    with pytest.raises(LogFormatError, match=r"lat\.sbin:7: comment key lat_deg must be a number in \(-90, 90\)"):
        open_imu_log(tmp_path / "lat.sbin")   # line 7: the column line after the format line and 5 keys


def test_a_file_cut_anywhere_is_refused_naming_the_sample(tmp_path):
    whole = write_log(tmp_path / "whole.sbin", PIECES).read_bytes()
    header_end = whole.index(b"dvz\n") + 4
    for cut in range(header_end + 1, len(whole), 97):
        path = tmp_path / "cut.sbin"
        path.write_bytes(whole[:cut])
        assert "sample" in refusal(path, limits=False)


def test_a_block_that_claims_more_rows_than_a_block_may_hold_is_refused_before_any_allocation(tmp_path):
    path = write_log(tmp_path / "big.sbin", [(None, sample_rows(5))])
    raw = path.read_bytes()
    start = raw.index(MAGIC)
    path.write_bytes(raw[:start] + struct.pack("<4sII", MAGIC, MAX_BLOCK_ROWS + 1, NO_REASON) + raw[start + 12:])
    assert "corrupt block" in refusal(path)


@FUZZ
@given(garbage=st.binary(max_size=400))
def test_garbage_after_a_good_header_gives_samples_or_a_one_line_error(tmp_path, garbage):
    text = io.StringIO()
    text.write(FORMAT_LINE + "".join(f"# {k}={v}\n" for k, v in HEADER.items()) + "t,dthx,dthy,dthz,dvx,dvy,dvz\n")
    path = tmp_path / "fuzz.sbin"
    path.write_bytes(text.getvalue().encode() + MAGIC + garbage)
    try:
        segments(path, chunk_rows=3, limits=True)
    except LogFormatError as exc:
        assert "\n" not in str(exc)


def test_convert_on_the_command_line_and_a_malformed_source_exits_2_with_one_line(tmp_path, capsys):
    csv = write_log(tmp_path / "imu.csv", PIECES)
    assert main(["convert", str(csv), str(tmp_path / "imu.sbin")]) == 0
    assert "105 samples" in capsys.readouterr().err
    bad = corrupt(write_log(tmp_path / "bad.sbin", [(None, sample_rows(5))]), 8, struct.pack("<d", np.inf))
    assert main(["convert", str(bad), str(tmp_path / "out.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad.sbin:sample 5" in err

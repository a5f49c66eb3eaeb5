"""Files that parse but are absurd: logs, aiding logs and configurations with values at the float limits.

GIVEN an IMU log, an aiding log or a configuration that is well-formed but holds a value no physical system has (a
cell of 1e300, a rate of 1e308 Hz, a latitude of 95°, a lever arm of 1e300 m, a control step of 1e12 s, an output
period of 1e-300 s, an array nested 5000 deep), a line of megabytes or a file cut in the middle of its last number,
WHEN it is read or replayed, THEN the reader or the loader stops with one line naming the file and line (or the key),
the command exits 2 without a traceback, and nothing invalid is written: no NaN in the results, nothing through a
planted symbolic link.
"""
from __future__ import annotations

import io
import json
import math
import os
import subprocess
import sys
import tracemalloc
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sinsalign.protocol.aiding_log import KINDS, open_aiding_log
from sinsalign.protocol.imu_log import (
    DATASHEET_KEYS,
    IMU_COLUMNS,
    LogFormatError,
    open_imu_log,
    write_header,
    write_rows,
)
from sinsalign.protocol.results import ResultRecord
from sinsalign.service.config import Config, ConfigError, config_from_mapping, load_config, tables, value_fields
from support.config_keys import in_table, one_key

from sinsalign.cli import main

RATE_HZ = 100.0
HEADER = {"lat_deg": 32.0, "lon_deg": 118.0, "height_m": 10.0, "rate_hz": RATE_HZ}
FIRST_DATA_LINE = len(HEADER) + 2
MAX_MESSAGE = 300
PROPERTY = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
PROPERTY_LONG = settings(max_examples=5000, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def static_rows(n: int = 300) -> np.ndarray:
    """n samples of a level IMU at rest: gravity on the up axis, the Earth's rate on the north one (rad, m/s)."""
    rows = np.zeros((n, 7))
    rows[:, 0] = np.arange(1, n + 1) / RATE_HZ
    rows[:, 2] = 7.292115e-5 * math.cos(math.radians(32.0)) / RATE_HZ
    rows[:, 6] = 9.7949 / RATE_HZ
    return rows


def log_text(header: dict[str, object] | None = None, rows: np.ndarray | None = None,
             columns: tuple[str, ...] = IMU_COLUMNS) -> str:
    buf = io.StringIO()
    write_header(buf, HEADER if header is None else header, columns)
    write_rows(buf, static_rows() if rows is None else rows)
    return buf.getvalue()


def write_log(tmp_path: Path, text: str, name: str = "imu.csv") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def read_log(path: Path) -> None:
    """Read as the replay does: the header, then the rows held to the log's physical limits."""
    log = open_imu_log(path)
    for _ in log.blocks(chunk_rows=64, limits=log.limits):
        pass


def assert_one_line(message: str) -> None:
    assert "\n" not in message.rstrip("\n") and len(message) <= MAX_MESSAGE, message


def log_error(path: Path) -> LogFormatError:
    with pytest.raises(LogFormatError) as info:
        read_log(path)
    assert str(info.value).startswith(f"{path}:")
    assert_one_line(str(info.value))
    return info.value


def replay_error(capsys: pytest.CaptureFixture[str], tmp_path: Path, imu: Path, *options: str) -> str:
    """The one line ``sinsalign replay`` prints on stderr when it refuses; it must exit 2, no results written."""
    out = tmp_path / "r.jsonl"
    code = main(["replay", str(imu), "--out", str(out), "--no-progress", *options])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("sinsalign replay: error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    assert len(err) <= MAX_MESSAGE + len("sinsalign replay: error: "), err
    assert not out.exists()
    return err


# --- the IMU log ------------------------------------------------------------------------------------------------------


def test_a_huge_cell_names_line_and_column(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    rows = static_rows()
    rows[20, 1] = 1e300
    path = write_log(tmp_path, log_text(rows=rows))
    exc = log_error(path)
    assert (exc.line, exc.column) == (FIRST_DATA_LINE + 20, "dthx")
    assert f"{path}:{FIRST_DATA_LINE + 20}, column 'dthx'" in replay_error(capsys, tmp_path, path)


@pytest.mark.parametrize(("column", "value", "refused"), [
    ("dthz", 30.0, False), ("dthz", -40.0, True), ("dvx", 1900.0, False), ("dvx", -2000.0, True), ("t", 1e11, True),
])
def test_an_increment_no_imu_measures_is_refused(tmp_path: Path, column: str, value: float, refused: bool) -> None:
    """The bounds at 100 Hz: the widest ranges a sensor may be stated to have (1e5 °/s, 1e4 g) over twice the sample
    interval (34.9 rad, 1961 m/s), and a time stamp of any clock (|t| ≤ 1e10 s)."""
    rows = static_rows()
    rows[5, IMU_COLUMNS.index(column)] = value
    path = write_log(tmp_path, log_text(rows=rows))
    if not refused:
        read_log(path)
        return
    exc = log_error(path)
    assert (exc.line, exc.column) == (FIRST_DATA_LINE + 5, column)


@pytest.mark.parametrize(("key", "value"), [
    ("rate_hz", "1e308"), ("rate_hz", "0.5"), ("rate_hz", "20000"),
    ("acc_bias_ug", "1e308"), ("gyro_bias_deg_h", "1e300"), ("gyro_arw_deg_rth", "1e6"), ("acc_vrw_ug_rthz", "1e9"),
    ("height_m", "-1e308"), ("height_m", "2e5"),
    ("lat_deg", "95"), ("lat_deg", "-90"), ("lon_deg", "1000"), ("lon_deg", "-180.5"),
])
def test_an_absurd_comment_key_names_the_key(capsys: pytest.CaptureFixture[str], tmp_path: Path, key: str,
                                            value: str) -> None:
    path = write_log(tmp_path, log_text({**HEADER, key: value}))
    with pytest.raises(LogFormatError) as info:
        open_imu_log(path)
    assert key in str(info.value) and str(info.value).startswith(f"{path}:")
    assert_one_line(str(info.value))
    assert key in replay_error(capsys, tmp_path, path)


@pytest.mark.parametrize("key", DATASHEET_KEYS)
def test_datasheet_figures_at_their_bounds_are_accepted(tmp_path: Path, key: str) -> None:
    """0 states an ideal sensor (the simulator's ideal runs write figures of 1e-7)."""
    for value in ("0", "1e-7"):
        header = open_imu_log(write_log(tmp_path, log_text({**HEADER, key: value}))).header
        assert header.datasheet()[key] == float(value)


def test_a_file_cut_in_its_last_number_names_the_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    text = log_text()
    path = write_log(tmp_path, text[:-5])
    exc = log_error(path)
    assert exc.line == FIRST_DATA_LINE + 299 and "end of line" in str(exc)
    assert f"{path}:{FIRST_DATA_LINE + 299}" in replay_error(capsys, tmp_path, path)


def test_a_header_cut_short_names_the_line(tmp_path: Path) -> None:
    path = write_log(tmp_path, "".join(f"# {k}={v}\n" for k, v in HEADER.items()) + "t,dthx,dthy,dthz,dvx,dv")
    with pytest.raises(LogFormatError) as info:
        open_imu_log(path)
    assert info.value.line == len(HEADER) + 1


def test_the_writer_ends_every_line(tmp_path: Path) -> None:
    """Our own logs end with a line end, so a file without one is one cut short, never one of ours."""
    assert log_text().endswith("\n") and log_text(rows=np.empty((0, 7))).endswith("\n")
    read_log(write_log(tmp_path, log_text()))


def test_a_line_of_megabytes_is_refused_in_bounded_memory(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_log(tmp_path, log_text() + "1" * 16_000_000)
    tracemalloc.start()
    try:
        exc = log_error(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert exc.line == FIRST_DATA_LINE + 300 and "longer than" in str(exc)
    assert peak < 4_000_000
    replay_error(capsys, tmp_path, path)


def test_a_long_header_row_is_quoted_short(tmp_path: Path) -> None:
    path = write_log(tmp_path, "".join(f"# {k}={v}\n" for k, v in HEADER.items()) + "t," + "x" * 4000 + "\n")
    with pytest.raises(LogFormatError) as info:
        open_imu_log(path)
    assert_one_line(str(info.value))
    assert "…" in str(info.value)


def test_a_flood_of_comment_keys_is_refused(tmp_path: Path) -> None:
    path = write_log(tmp_path, "".join(f"# key{k}=1\n" for k in range(5000)) + log_text())
    with pytest.raises(LogFormatError, match="comment keys"):
        open_imu_log(path)


# --- aiding logs ------------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def master_run(tmp_path_factory: pytest.TempPathFactory):
    """A 3-s transfer alignment (seed 002): the slave's IMU log and the master's log."""
    from sinsalign.tools.sim.files import write_simulation
    from sinsalign.tools.sim.scenarios import seed_run
    files = write_simulation(seed_run("seed002", 1, 3.0), 1, tmp_path_factory.mktemp("seed002"))
    return files.imu_csv, Path(files.master_csv).read_text()


def master_with(master_text: str, keys: str = "", row: int | None = None, cells: dict[str, str] | None = None) -> str:
    """The master log with comment ``keys`` added after its own (a key given twice: the later counts) and data row
    ``row`` given these ``cells``."""
    lines = master_text.splitlines(keepends=True)
    header_at = next(k for k, line in enumerate(lines) if line.startswith("t,"))
    if row is not None:
        values = lines[header_at + 1 + row].rstrip("\n").split(",")
        for name, cell in (cells or {}).items():
            values[KINDS["master"].columns.index(name)] = cell
        lines[header_at + 1 + row] = ",".join(values) + "\n"
    return "".join(lines[:header_at]) + keys + "".join(lines[header_at:])


def test_a_master_lever_arm_of_1e300_is_refused(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                               master_run) -> None:
    """A lever arm is within a vehicle (|lever| ≤ 100 m): a huge one would put NaN into every record."""
    imu, master = master_run
    aid = write_log(tmp_path, master_with(master, "# lever_x_m=1e300\n"), "master.csv")
    with pytest.raises(LogFormatError, match="lever_x_m"):
        open_aiding_log("master", aid)
    assert "lever_x_m" in replay_error(capsys, tmp_path, imu, "--aid", f"master={aid}")


def test_a_master_lever_arm_within_a_vehicle_gives_finite_records(tmp_path: Path, master_run) -> None:
    imu, master = master_run
    aid = write_log(tmp_path, master_with(master, "# lever_x_m=50\n"), "master.csv")
    out = tmp_path / "r.jsonl"
    assert main(["replay", str(imu), "--out", str(out), "--no-progress", "--aid", f"master={aid}"]) == 0
    assert out.read_text().count("\n") == 3 and "NaN" not in out.read_text()


@pytest.mark.parametrize(("keys", "name"), [
    ("# att_std_deg=1e-300\n", "att_std_deg"), ("# att_std_deg=1e300\n", "att_std_deg"),
    ("# vel_std_mps=-1\n", "vel_std_mps"), ("# vel_std_mps=5e-324\n", "vel_std_mps"),
    ("# vel_std_mps=50\n", "vel_std_mps"), ("# lever_z_m=-101\n", "lever_z_m"),
])
def test_absurd_noise_figures_and_levers_of_a_master_log(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                         master_run, keys: str, name: str) -> None:
    imu, master = master_run
    aid = write_log(tmp_path, master_with(master, keys), "master.csv")
    assert name in replay_error(capsys, tmp_path, imu, "--aid", f"master={aid}")


@pytest.mark.parametrize(("cells", "column"), [
    ({"vN": "1e300"}, None), ({"qw": "0", "qx": "0", "qy": "0", "qz": "0"}, None), ({"qx": "1e200"}, None),
    ({"qw": "2"}, None),
    ({"lat_deg": "95"}, "lat_deg"), ({"h_m": "-1e308"}, "h_m"), ({"t": "-1e300"}, "t"),
])
def test_absurd_values_of_a_master_log_name_the_line(capsys: pytest.CaptureFixture[str], tmp_path: Path, master_run,
                                                     cells: dict[str, str], column: str | None) -> None:
    imu, master = master_run
    aid = write_log(tmp_path, master_with(master, row=7, cells=cells), "master.csv")
    with pytest.raises(LogFormatError) as info:
        for _ in open_aiding_log("master", aid).blocks(limits=KINDS["master"].limits):
            pass
    assert (info.value.line, info.value.column) == (2 + 1 + 1 + 7, column)   # two comment keys, the header
    assert_one_line(str(info.value))
    assert f"{aid}:{info.value.line}" in replay_error(capsys, tmp_path, imu, "--aid", f"master={aid}")


@pytest.mark.parametrize(("kind", "keys", "row"), [
    ("odo", "# vel_std_mps=1e-300\n", (0.1, 0.0, 20.0, 0.0)),
    ("odo", "", (0.1, 0.0, 1e300, 0.0)),
    ("odo", "", (0.1, 400.0, 0.0, 0.0)),
    ("gnss", "# pos_std_m=1e9\n", (0.1, 30.0, 114.0, 20.0, 0.0, 50.0, 0.0)),
    ("gnss", "# lever_y_m=1e300\n", (0.1, 30.0, 114.0, 20.0, 0.0, 50.0, 0.0)),
    ("gnss", "", (0.1, 30.0, 214.0, 20.0, 0.0, 50.0, 0.0)),
    ("gnss", "", (0.1, 30.0, 114.0, 20.0, 0.0, 1e300, 0.0)),
])
def test_absurd_odometer_and_gnss_logs(tmp_path: Path, kind: str, keys: str, row: tuple[float, ...]) -> None:
    buf = io.StringIO()
    write_header(buf, {}, KINDS[kind].columns)
    write_rows(buf, np.array([row]))
    path = write_log(tmp_path, keys + buf.getvalue(), f"{kind}.csv")
    with pytest.raises(LogFormatError) as info:
        for _ in open_aiding_log(kind, path).blocks(limits=KINDS[kind].limits):
            pass
    assert str(info.value).startswith(f"{path}:")
    assert_one_line(str(info.value))


# --- the configuration ------------------------------------------------------------------------------------------------


def config_error(data: dict[str, Any]) -> str:
    with pytest.raises(ConfigError) as info:
        config_from_mapping(data)
    assert_one_line(str(info.value))
    return str(info.value)


@pytest.mark.parametrize(("section", "key", "value"), [
    ("fine", "control_interval_s", 1e12), ("fine.compass", "stored_data_s", 1e15), ("output", "period_s", 1e-300),
    ("fine.compass", "live_pass_steps", 10**30), ("aiding.odo", "window_s", 1e300), ("disturbance", "window_s", 1e300),
    ("aiding.master", "lever_m", [1e300, 0.0, 0.0]), ("site", "lon_deg", 400.0), ("site", "height_m", -1e308),
])
def test_absurd_configuration_values_are_refused(capsys: pytest.CaptureFixture[str], tmp_path: Path, section: str,
                                                 key: str, value: Any) -> None:
    assert config_error(one_key(section, key, value)).startswith(f"{section}.{key}:")
    toml = tmp_path / "absurd.toml"
    literal = json.dumps(value) if isinstance(value, list) else repr(value)
    toml.write_text(f"[{section}]\n{key} = {literal}\n")
    assert f"{section}.{key}" in replay_error(capsys, tmp_path, write_log(tmp_path, log_text()), "--config", str(toml))


@pytest.mark.parametrize(("data", "key"), [
    ({"fine": {"compass": {"stored_data_s": 3600.0}, "control_interval_s": 0.001}}, "fine.compass.stored_data_s"),
    ({"aiding": {"odo": {"window_s": 3600.0}}, "alignment": {"obs_interval_s": 0.001}}, "aiding.odo.window_s"),
    ({"disturbance": {"window_s": 600.0, "check_interval_s": 0.001}}, "disturbance.window_s"),
])
def test_stores_sized_by_two_keys_are_bounded(data: dict[str, Any], key: str) -> None:
    assert config_error(data).startswith(f"{key}:")


def numeric_fields() -> list[tuple[str, str, object]]:
    """Every numeric key of the configuration (numbers and lists of numbers) with its table and default."""
    return [(name, f.name, getattr(table, f.name)) for name, table in tables(Config()) for f in value_fields(table)
            if isinstance(getattr(table, f.name), int | float | tuple) and not isinstance(getattr(table, f.name), bool)
            and "str" not in str(f.type)]


@pytest.mark.parametrize(("section", "key", "default"), numeric_fields())
def test_every_numeric_key_has_both_bounds(section: str, key: str, default: object) -> None:
    for extreme in (1e300, -1e300):
        value: object = extreme if isinstance(default, float) else int(extreme) if isinstance(default, int) else (
            [extreme] * max(len(default), 3))
        assert config_error(one_key(section, key, value)).startswith(f"{section}.{key}:")


@pytest.mark.parametrize(("section", "key"), [("fine.compass", "schedule_time_s"), ("zenoh", "listen")])
def test_lists_have_a_bounded_length(section: str, key: str) -> None:
    value = list(range(10_000)) if key == "schedule_time_s" else ["tcp/127.0.0.1:7447"] * 10_000
    assert config_error(one_key(section, key, value)).startswith(f"{section}.{key}:")


def test_a_deeply_nested_toml_array_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    toml = tmp_path / "deep.toml"
    toml.write_text("[fine.compass]\nlevel_sigma = " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(ConfigError) as info:
        load_config(toml)
    assert str(info.value).startswith(f"{toml}:")
    assert_one_line(str(info.value))
    replay_error(capsys, tmp_path, write_log(tmp_path, log_text()), "--config", str(toml))


@pytest.mark.parametrize("text", ["[fine.compass]\nstored_pairs = " + "9" * 5000 + "\n",
                                  "[zenoh]\nunit = '" + "u" * 10**6 + "'\n",
                                  "[fine.compass]\nlevel_sigma = [" + "[" * 3000 + "]" * 3000 + ", 1]\n"])
def test_toml_at_python_limits_is_one_line(tmp_path: Path, text: str) -> None:
    toml = tmp_path / "limits.toml"
    toml.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_config(toml)
    assert_one_line(str(info.value))


def test_a_huge_configuration_file_is_refused_unread(tmp_path: Path) -> None:
    toml = tmp_path / "huge.toml"
    toml.write_text("# padding\n" * 200_000)
    with pytest.raises(ConfigError, match="larger than"):
        load_config(toml)


def test_a_nested_deep_mapping_value_is_one_line() -> None:
    deep: list[Any] = []
    for _ in range(5000):
        deep = [deep]
    assert config_error({"fine": {"compass": {"level_sigma": deep}}}).startswith("fine.compass.level_sigma:")
    assert config_error({"fine": {"compass": {"stored_pairs": 10**5000}}}).startswith("fine.compass.stored_pairs:")
    assert config_error({"fine": {"x" * 10**6: 1}}).startswith("fine.xxx")


# --- results ----------------------------------------------------------------------------------------------------------


def record(**changes: object) -> ResultRecord:
    good = ResultRecord(t=1.0, phase="coarse", q=(1.0, 0.0, 0.0, 0.0), pitch_deg=0.0, roll_deg=0.0, heading_deg=0.0,
                        heading_sigma_deg=1.0, level_sigma_deg=0.1, converged=False, rho=0.1, trace_P=math.inf,
                        n_obs=1)
    return replace(good, **changes)


def test_the_writer_writes_strict_json_only() -> None:
    assert json.loads(record().to_json())["trace_P"] is None   # no observation yet: null, as before
    for name, bad in (("heading_sigma_deg", {"heading_sigma_deg": math.nan}), ("q", {"q": (math.nan, 0.0, 0.0, 0.0)}),
                      ("rho", {"rho": math.inf}),
                      ("mount_sigma_deg", {"mount_q": (1.0, 0.0, 0.0, 0.0), "mount_sigma_deg": math.nan})):
        with pytest.raises(ValueError, match="not finite") as info:
            record(**bad).to_json()
        assert name in str(info.value)


# --- the results file and the command ---------------------------------------------------------------------------------


def test_a_planted_partial_link_is_not_followed(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    (tmp_path / ".r.jsonl.partial").symlink_to(victim)
    err = replay_error(capsys, tmp_path, write_log(tmp_path, log_text()))
    assert ".r.jsonl.partial" in err
    assert victim.read_text() == "precious\n"
    assert (tmp_path / ".r.jsonl.partial").is_symlink()   # not ours to remove


def test_results_are_owner_only(tmp_path: Path) -> None:
    out = tmp_path / "r.jsonl"
    assert main(["replay", str(write_log(tmp_path, log_text())), "--out", str(out), "--no-progress"]) == 0
    assert out.stat().st_mode & 0o777 == 0o600
    assert not (tmp_path / ".r.jsonl.partial").exists()


def test_a_bug_is_not_reported_as_a_user_error(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    import sinsalign.tools.replay as replay_tool

    def broken(*args: object, **kwargs: object) -> None:
        raise KeyError("a bug")
    monkeypatch.setattr(replay_tool, "replay", broken)
    with pytest.raises(KeyError):
        main(["replay", str(write_log(tmp_path, log_text())), "--out", str(tmp_path / "r.jsonl"), "--no-progress"])


@pytest.mark.parametrize("command", [["sim", "nosuch", "--out-dir"], ["eval", "nosuch", "--seeds", "1", "--out-dir"],
                                     ["bench", "--scenario", "nosuch", "--start-delay", "0", "--port"],
                                     ["demo", "--scenario", "nosuch", "--out-dir"]])
def test_an_unknown_scenario_is_a_user_error(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                             command: list[str]) -> None:
    """Said before anything runs: no folder made, no port opened."""
    assert main([*command, str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "unknown scenario 'nosuch'" in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("case", ["cell", "rate", "cut", "config", "deep"])
def test_the_command_exits_2_with_one_line(tmp_path: Path, case: str) -> None:
    rows = static_rows()
    rows[3, 4] = 1e300
    imu = write_log(tmp_path, {"cell": log_text(rows=rows), "rate": log_text({**HEADER, "rate_hz": "1e308"}),
                               "cut": log_text()[:-3]}.get(case, log_text()))
    options = []
    if case in ("config", "deep"):
        toml = tmp_path / "c.toml"
        toml.write_text("[fine]\ncontrol_interval_s = 1e12\n" if case == "config"
                        else "[fine]\nlevel_sigma = " + "[" * 5000 + "]" * 5000 + "\n")
        options = ["--config", str(toml)]
    script = Path(sys.executable).with_name("sinsalign")
    done = subprocess.run([str(script), "replay", str(imu), "--out", str(tmp_path / "r.jsonl"), *options],
                          capture_output=True, text=True, timeout=60, env={**os.environ, "COLUMNS": "80"})
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr, done.stderr
    assert len(done.stderr) <= MAX_MESSAGE + 30


# --- properties -------------------------------------------------------------------------------------------------------


def nested(depth: int) -> list[Any]:
    value: list[Any] = []
    for _ in range(depth):
        value = [value]
    return value


LIMITS = st.sampled_from([1e308, -1e308, 5e-324, -5e-324, 0.0, -0.0, math.nan, math.inf, -math.inf, 2**63, -2**63,
                          10**400, -10**400, True, False, "", "x" * 5000, "\n", None])
TOO_LONG_TO_PRINT = st.integers(4301, 6000).map(lambda digits: 10**digits)   # hypothesis cannot show it as a sample
SCALAR = LIMITS | TOO_LONG_TO_PRINT | st.floats() | st.integers() | st.text(max_size=30)
VALUE = st.recursive(SCALAR, lambda inner: st.lists(inner, max_size=6) | st.dictionaries(st.text(max_size=8), inner,
                                                                                          max_size=3), max_leaves=12)
VALUE = VALUE | st.integers(1, 5000).map(nested) | st.lists(SCALAR, min_size=3, max_size=3)
SECTION_KEYS = {name: [f.name for f in fields(table)] for name, table in tables(Config())}
TABLE = st.sampled_from(sorted(SECTION_KEYS)).flatmap(
    lambda section: st.dictionaries(st.sampled_from(SECTION_KEYS[section]) | st.text(max_size=12), VALUE,
                                    max_size=4).map(lambda table: in_table(section, table)))
MAPPING = TABLE | st.dictionaries(st.text(max_size=12), VALUE | st.dictionaries(st.text(max_size=8), VALUE, max_size=2),
                                  max_size=3)


def loads_or_refuses(data: dict[str, Any]) -> None:
    try:
        config_from_mapping(data)
    except ConfigError as exc:
        assert_one_line(str(exc))


@PROPERTY
@given(data=MAPPING)
def test_configuration_at_the_limits_loads_or_says_why(data: dict[str, Any]) -> None:
    loads_or_refuses(data)


@pytest.mark.slow
@PROPERTY_LONG
@given(data=MAPPING)
def test_configuration_at_the_limits_loads_or_says_why_long(data: dict[str, Any]) -> None:
    loads_or_refuses(data)


NUMBER_TEXT = (st.floats().map(repr) | st.integers().map(str)
               | st.sampled_from(["1e308", "-1e308", "5e-324", "1e999", "nan", "-inf", "0", "-0", "95", "1e-300", ""]))
COMMENT_KEY = st.sampled_from([*HEADER, *DATASHEET_KEYS, "lever_x_m", "vel_std_mps", "att_std_deg", "pos_std_m"])
CELL = NUMBER_TEXT | st.text(alphabet="0123456789.,-+eE naifNI#", max_size=20)


def reads_or_refuses(tmp_path: Path, keys: dict[str, str], cells: list[list[str]], kind: str | None,
                     ending: str) -> None:
    """A log of these comment ``keys`` and rows of ``cells`` (time increasing), then ``ending``: it reads, or it is
    refused with one short line naming the file."""
    columns = IMU_COLUMNS if kind is None else KINDS[kind].columns
    text = "".join(f"# {k}={v}\n" for k, v in keys.items()) + ",".join(columns) + "\n"
    text += "".join(",".join((str(k + 1), *row[:len(columns) - 1])) + "\n" for k, row in enumerate(cells))
    path = write_log(tmp_path, text + ending, "fuzz.csv")
    try:
        if kind is None:
            read_log(path)
        else:
            for _ in open_aiding_log(kind, path).blocks(chunk_rows=3, limits=KINDS[kind].limits):
                pass
    except LogFormatError as exc:
        assert str(exc).startswith(f"{path}:")
        assert_one_line(str(exc))


ENDINGS = st.sampled_from(["", "1", "#", "1" * 5000])
"""What follows the last row: nothing, a line cut short, a comment cut short, a line too long."""


LOG_CASES = {"keys": st.dictionaries(COMMENT_KEY, NUMBER_TEXT, max_size=8),
             "cells": st.lists(st.lists(CELL, min_size=10, max_size=10), max_size=6),
             "kind": st.sampled_from([None, *KINDS]), "ending": ENDINGS}
"""A log's comment keys, rows of cells, kind (None: an IMU log) and ending."""


@PROPERTY
@given(**LOG_CASES)
def test_logs_at_the_limits_read_or_say_why(tmp_path: Path, keys: dict[str, str], cells: list[list[str]],
                                            kind: str | None, ending: str) -> None:
    reads_or_refuses(tmp_path, {**HEADER, **keys} if kind is None else keys, cells, kind, ending)


@pytest.mark.slow
@PROPERTY_LONG
@given(**LOG_CASES)
def test_logs_at_the_limits_read_or_say_why_long(tmp_path: Path, keys: dict[str, str], cells: list[list[str]],
                                                 kind: str | None, ending: str) -> None:
    reads_or_refuses(tmp_path, {**HEADER, **keys} if kind is None else keys, cells, kind, ending)

"""Configuration: defaults < TOML file < overrides; every bad key stops the start with the key named."""
from __future__ import annotations

import math
from dataclasses import fields
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sinsalign.service.align.solvers import ALIGNMENT_SOLVERS
from sinsalign.service.config import (
    MOVED,
    AlignmentConfig,
    Config,
    ConfigError,
    OutputConfig,
    SensorConfig,
    config_from_mapping,
    config_toml,
    load_config,
)
from support.config_keys import one_key

from sinsalign.cli import build_parser, main

GOOD_TOML = """\
# a comment
[sensor]
acc_bias_ug = 100.0
gyro_arw_deg_rth = 0.002

[alignment]
solver = "request"
request_rho = 0.05
obs_interval_s = 0.2

[output]
period_s = 0.5
"""


def write(tmp_path: Path, text: str, name: str = "sinsalign.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def config_error(data: dict[str, Any]) -> str:
    with pytest.raises(ConfigError) as info:
        config_from_mapping(data)
    return str(info.value)


# --- loading and layering ---------------------------------------------------------------------------------------------


def test_defaults() -> None:
    config = load_config()
    assert config == Config()
    assert config == config_from_mapping({})
    assert config.alignment == AlignmentConfig()
    assert (config.alignment.solver, config.alignment.request_rho, config.alignment.obs_interval_s,
            config.alignment.swing_bias) == ("auto", 0.01, 0.1, True)
    assert config.output.period_s == 1.0
    assert config.sensor == SensorConfig(0.01, 0.001, 50.0, 5.0)
    assert config.as_dict()["alignment"]["solver"] == "auto"


def test_empty_file_gives_defaults(tmp_path: Path) -> None:
    assert load_config(write(tmp_path, "")) == Config()


def test_file_overrides_defaults(tmp_path: Path) -> None:
    config = load_config(write(tmp_path, GOOD_TOML))
    assert config.sensor == SensorConfig(gyro_bias_deg_h=0.01, gyro_arw_deg_rth=0.002, acc_bias_ug=100.0,
                                         acc_vrw_ug_rthz=5.0)
    assert config.alignment == AlignmentConfig(solver="request", request_rho=0.05, obs_interval_s=0.2)
    assert config.output == OutputConfig(period_s=0.5)


def test_file_path_may_be_str(tmp_path: Path) -> None:
    assert load_config(str(write(tmp_path, GOOD_TOML))).output.period_s == 0.5


def test_overrides_override_file(tmp_path: Path) -> None:
    overrides = {"alignment": {"request_rho": 0.5}, "output": {"period_s": 2.0}}
    config = load_config(write(tmp_path, GOOD_TOML), overrides)
    assert config.alignment.request_rho == 0.5
    assert config.output.period_s == 2.0
    # keys the overrides leave alone keep the file's values, not the defaults
    assert config.alignment.solver == "request" and config.alignment.obs_interval_s == 0.2
    assert config.sensor.acc_bias_ug == 100.0


def test_overrides_without_file() -> None:
    config = load_config(None, {"alignment": {"solver": "qmethod"}})
    assert config.alignment == AlignmentConfig(solver="qmethod")


def test_config_from_mapping_applies_onto_base() -> None:
    base = config_from_mapping({"output": {"period_s": 0.25}})
    config = config_from_mapping({"alignment": {"obs_interval_s": 0.5}}, base)
    assert config.output.period_s == 0.25 and config.alignment.obs_interval_s == 0.5


@pytest.mark.parametrize(("section", "key", "value"), [("alignment", "request_rho", 1), ("output", "period_s", 3),
                                                        ("sensor", "acc_bias_ug", 0)])
def test_int_for_float_key(tmp_path: Path, section: str, key: str, value: int) -> None:
    for config in (load_config(write(tmp_path, f"[{section}]\n{key} = {value}\n")),
                   config_from_mapping({section: {key: value}})):
        got = getattr(getattr(config, section), key)
        assert type(got) is float and got == value


@pytest.mark.parametrize(("section", "key", "value"), [
    ("alignment", "request_rho", 1.0), ("alignment", "disturbance_velocity_mps", 0.0),
    ("sensor", "gyro_bias_deg_h", 0.0), ("alignment", "obs_interval_s", 1e-9), ("alignment", "solver", "request"),
])
def test_boundary_values_accepted(section: str, key: str, value: object) -> None:
    assert getattr(getattr(config_from_mapping({section: {key: value}}), section), key) == value


# --- bad keys, types and ranges -----------------------------------------------------------------------------------


@pytest.mark.parametrize(("data", "key"), [
    ({"sensors": {}}, "sensors"),
    ({"alignment": {"rho": 0.1}}, "alignment.rho"),
    ({"output": {"period": 1.0}}, "output.period"),
    ({"sensor": {"acc_bias_ug": 50.0, "gyro_bias": 1.0}}, "sensor.gyro_bias"),
    ({"alignment": 0.1}, "alignment"),
    ({"alignment": "opreq"}, "alignment"),
])
def test_unknown_section_or_key(data: dict[str, Any], key: str) -> None:
    message = config_error(data)
    assert message.startswith(f"{key}:")


@pytest.mark.parametrize(("section", "key", "value"), [
    ("alignment", "obs_interval_s", "0.1"),
    ("alignment", "request_rho", True),
    ("alignment", "request_rho", False),
    ("output", "period_s", [1.0]),
    ("output", "period_s", {"value": 1.0}),
    ("sensor", "acc_bias_ug", None),
    ("alignment", "solver", 1),
    ("alignment", "solver", ["opreq"]),
])
def test_wrong_type(section: str, key: str, value: object) -> None:
    message = config_error({section: {key: value}})
    assert f"{section}.{key}" in message
    assert "expected" in message


@pytest.mark.parametrize(("section", "key", "value"), [
    ("alignment", "obs_interval_s", 0.0),
    ("alignment", "obs_interval_s", -0.1),
    ("alignment", "obs_interval_s", -1),
    ("alignment", "obs_interval_s", math.nan),
    ("alignment", "request_rho", 1.0000001),
    ("alignment", "request_rho", 2),
    ("alignment", "request_rho", 0.0),
    ("alignment", "request_rho", -0.5),
    ("alignment", "disturbance_velocity_mps", -1e-6),
    ("alignment", "converged_heading_sigma_deg", 0.0),
    ("output", "period_s", 0.0),
    ("output", "period_s", -1.0),
    ("alignment", "solver", "OPREQ"),
    ("alignment", "solver", "kalman"),
    ("alignment", "solver", ""),
    ("aiding.odo", "solver", "gls"),      # the whitened fit models a fixed base, not the aided sources
    *[("sensor", f.name, -1.0) for f in fields(SensorConfig)],
    *[("sensor", f.name, math.nan) for f in fields(SensorConfig)],
])
def test_out_of_range(tmp_path: Path, section: str, key: str, value: object) -> None:
    assert config_error(one_key(section, key, value)).startswith(f"{section}.{key}:")
    # the same from a file and from overrides on top of a good file
    literal = {str: f'"{value}"', float: "nan" if isinstance(value, float) and math.isnan(value) else repr(value),
               int: repr(value)}[type(value)]
    with pytest.raises(ConfigError, match=rf"^{section}\.{key}:"):
        load_config(write(tmp_path, f"[{section}]\n{key} = {literal}\n"))
    with pytest.raises(ConfigError, match=rf"^{section}\.{key}:"):
        load_config(write(tmp_path, GOOD_TOML, "good.toml"), one_key(section, key, value))


def test_bad_key_in_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"^alignment\.obs_interval:"):
        load_config(write(tmp_path, "[alignment]\nobs_interval = 0.1\n"))
    with pytest.raises(ConfigError, match=r"^alignment\.obs_interval_s: expected float"):
        load_config(write(tmp_path, '[alignment]\nobs_interval_s = "fast"\n'))


def test_top_level_key_outside_a_table(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"^period_s:"):
        load_config(write(tmp_path, "period_s = 1.0\n"))


@pytest.mark.parametrize(("section", "key"), [("alignment", "obs_interval_s"), ("output", "period_s")])
def test_infinite_value_rejected(tmp_path: Path, section: str, key: str) -> None:
    with pytest.raises(ConfigError, match=rf"^{section}\.{key}:"):
        load_config(write(tmp_path, f"[{section}]\n{key} = inf\n"))


def test_huge_int_for_float_key() -> None:
    with pytest.raises(ConfigError, match=r"alignment\.request_rho"):
        config_from_mapping({"alignment": {"request_rho": 10**400}})


# --- file problems ----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("text", ["[alignment\nsolver = 'opreq'\n", "[alignment]\nsolver = opreq\n",
                                  "[output]\nperiod_s = 1.0\nperiod_s = 2.0\n", "= 1\n"])
def test_invalid_toml_names_file(tmp_path: Path, text: str) -> None:
    path = write(tmp_path, text, "broken.toml")
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert str(info.value).startswith(f"{path}:")
    assert "not valid TOML" in str(info.value)


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "absent.toml"
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert str(path) in str(info.value) and "cannot read" in str(info.value)


def test_directory_instead_of_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path)


def test_non_utf8_file_names_file(tmp_path: Path) -> None:
    path = tmp_path / "latin1.toml"
    path.write_bytes(b'[alignment]\nsolver = "r\xe9quest"\n')
    with pytest.raises(ConfigError, match=r"latin1\.toml"):
        load_config(path)


def test_cli_reports_config_error(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    config = write(tmp_path, "[alignment]\nobs_interval_s = -1.0\n")
    code = main(["replay", str(tmp_path / "imu.csv"), "--out", str(tmp_path / "r.jsonl"), "--no-progress",
                 "--config", str(config)])
    assert code == 2
    assert "alignment.obs_interval_s" in capsys.readouterr().err


def test_eval_applies_the_configuration_file(tmp_path: Path) -> None:
    """``eval --config`` runs the scenario with the file's configuration (not only read and checked): a file choosing
    the q-method gives the table ``--solver qmethod`` gives, not the default OPREQ's."""
    config = write(tmp_path, '[alignment]\nsolver = "qmethod"\n')

    def table(*options: str) -> str:
        out = tmp_path / "_".join(options).replace("/", "") if options else tmp_path / "default"
        assert main(["eval", "seed000-swing", "--seeds", "1", "--no-fine", "--out-dir", str(out), *options]) == 0
        return (out / "seed000-swing.md").read_text().split("\n", 1)[1]   # the tables, after the stamp line

    from_file = table("--config", str(config))
    assert from_file == table("--solver", "qmethod") and from_file != table()


def test_eval_refuses_a_configuration_for_an_aided_table(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    config = write(tmp_path, '[alignment]\nsolver = "qmethod"\n')
    assert main(["eval", "seed004", "--config", str(config), "--out-dir", str(tmp_path)]) == 2
    assert "eval seed004 runs its table's own configurations" in capsys.readouterr().err


def test_every_aided_eval_table_resolves_to_its_table_and_plot() -> None:
    from sinsalign.tools.eval_command import AIDED_TABLES, _tool
    for table, plot in AIDED_TABLES.values():
        assert callable(_tool(table)) and callable(_tool(plot))


@pytest.mark.parametrize("options", [["--solvers"], ["--seed-sets", "2"], ["--fine"], ["--budget"]])
def test_eval_refuses_comparisons_for_an_aided_table(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                     options: list[str]) -> None:
    assert main(["eval", "seed002-rates", "--out-dir", str(tmp_path), *options]) == 2
    assert "runs its table's own configurations" in capsys.readouterr().err


@pytest.mark.parametrize(("option", "named"), [(["--solver", "gls"], "--solver"), (["--rho", "0.01"], "--rho"),
                                               (["--stored-pairs", "0"], "--stored-pairs"),
                                               (["--swing-bias"], "--[no-]swing-bias"),
                                               (["--no-swing-bias"], "--[no-]swing-bias")])
def test_replay_refuses_a_fixed_base_option_in_an_aided_mode(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                             option: list[str], named: str) -> None:
    """--solver, --rho, --stored-pairs and --[no-]swing-bias set the fixed-base stages: an aided replay ignored them
    silently."""
    code = main(["replay", str(tmp_path / "imu.csv"), "--aid", f"gnss={tmp_path / 'gnss.csv'}", "--out",
                 str(tmp_path / "r.jsonl"), "--no-progress", *option])
    assert code == 2 and f"{named} set the fixed-base alignment" in capsys.readouterr().err


@pytest.mark.parametrize(("scenario", "options", "stages"), [
    ("seed000-turntable", [], "coarse solver gls (auto: gyro walk dominates), swing-bias fit on, compass stage on"),
    ("static", ["--no-fine", "--no-swing-bias"],
     "coarse solver opreq (auto: accelerometer noise dominates), swing-bias fit off, compass stage off"),
    ("static", ["--solver", "qmethod"], "coarse solver qmethod, swing-bias fit on, compass stage on")])
def test_replay_says_which_stages_ran(capsys: pytest.CaptureFixture[str], tmp_path: Path, scenario: str,
                                      options: list[str], stages: str) -> None:
    """The log's datasheet decides what auto runs (the turntable's gyro walk: GLS), and the replay says so."""
    from dataclasses import replace as _replace

    from sinsalign.tools.sim.files import write_simulation
    from sinsalign.tools.sim.scenarios import get_scenario
    files = write_simulation(_replace(get_scenario(scenario), duration_s=2.0), 0, tmp_path)
    assert main(["replay", str(files.imu_csv), "--out", str(tmp_path / "r.jsonl"), "--no-progress", *options]) == 0
    assert f"; {stages})" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["benchmark", "--stream-hours", "0.001"], ["soak", "--hours", "0.1"],
                                  ["soak", "--window", "600", "--report-every", "600"]])
def test_benchmark_and_soak_refuse_a_run_too_short_to_report(capsys: pytest.CaptureFixture[str],
                                                             argv: list[str]) -> None:
    """Too short a stream or soak (or a soak's window as long as its report) is a clear error before the run."""
    assert main(argv) == 2
    assert argv[1] in capsys.readouterr().err


# --- fuzzing ----------------------------------------------------------------------------------------------------------

SECTION_NAMES = [f.name for f in fields(Config)]
KEY_NAMES = [f.name for cls in (SensorConfig, AlignmentConfig, OutputConfig) for f in fields(cls)]
SCALARS = st.one_of(st.integers(), st.integers(-2**63, 2**63 - 1), st.floats(), st.floats(0.0, 2.0),
                    st.text(max_size=10), st.booleans(), st.sampled_from(["opreq", "request", "qmethod"]))
VALUES = st.recursive(SCALARS, lambda inner: st.dictionaries(st.text(max_size=8) | st.sampled_from(KEY_NAMES), inner,
                                                               max_size=4), max_leaves=12)
TABLES = st.dictionaries(st.sampled_from(KEY_NAMES) | st.text(max_size=8), VALUES, max_size=5)
MAPPINGS = st.dictionaries(st.sampled_from(SECTION_NAMES) | st.text(max_size=8), TABLES | VALUES, max_size=4)


@settings(max_examples=200, deadline=None)
@given(data=MAPPINGS)
def test_fuzz_config_from_mapping(data: dict[str, Any]) -> None:
    try:
        config = config_from_mapping(data)
    except ConfigError as exc:
        assert str(exc)
    else:
        assert isinstance(config, Config)
        assert set(data) <= set(SECTION_NAMES)


def test_observation_interval_shorter_than_a_sample_is_a_config_error(capsys: pytest.CaptureFixture[str],
                                                                       tmp_path: Path) -> None:
    from dataclasses import replace as _replace

    from sinsalign.tools.sim.files import write_simulation
    from sinsalign.tools.sim.scenarios import get_scenario

    from sinsalign.cli import main
    files = write_simulation(_replace(get_scenario("static"), duration_s=2.0), 0, tmp_path)
    code = main(["replay", str(files.imu_csv), "--out", str(tmp_path / "r.jsonl"), "--obs-interval", "0.001",
                 "--no-progress"])
    assert code == 2
    assert "alignment.obs_interval_s" in capsys.readouterr().err


def test_the_cli_offers_every_solver_the_configuration_takes() -> None:
    """The CLI spells the solver names out (its --help must not import numpy); they must be the solvers module's."""
    replay = build_parser()._subparsers._group_actions[0].choices["replay"]
    (option,) = [a for a in replay._actions if "--solver" in a.option_strings]
    assert tuple(option.choices) == ALIGNMENT_SOLVERS


def test_a_key_outside_its_modes_table_is_refused_with_the_key_that_holds_it() -> None:
    for old, new in MOVED.items():
        section, key = old.split(".", 1)
        with pytest.raises(ConfigError, match=rf"^{old}: unknown key; it is {new} \("):
            config_from_mapping({section: {key: 1.0}})
        table, name = new.rsplit(".", 1)
        config = Config()
        for part in table.split("."):
            config = getattr(config, part)
        assert hasattr(config, name)   # where it points is a key


def test_the_configuration_printed_as_toml_loads_back_unchanged(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "car.toml"
    path.write_text('[aiding]\ninputs = ["odo", "gnss"]\n[aiding.gnss]\nlever_m = [0.0, 0.6, 0.8]\n'
                    '[fine.kalman]\ngate_chi2 = 20.0\n[fine.compass]\nstored_pairs = 2\n')
    config = load_config(path)
    assert config.aiding.gnss.lever_m == (0.0, 0.6, 0.8) and config.fine.kalman.gate_chi2 == 20.0
    assert main(["config", "--config", str(path)]) == 0
    printed = tmp_path / "printed.toml"
    printed.write_text(capsys.readouterr().out)
    assert load_config(printed) == config and config_toml(config) == printed.read_text()
    with pytest.raises(ConfigError, match=r"^aiding.odo: must be a table"):
        config_from_mapping({"aiding": {"odo": 1.0}})

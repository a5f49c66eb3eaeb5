"""A log with lost samples replays as the daemon would have aligned the same samples live.

GIVEN a swinging base's log that lost 4 samples (20 ms) at 100 s, WHEN it is replayed, THEN the gap is bridged as
the daemon's sample gate bridges it and every record from then on is within 0.01° of the whole log's (without the
gate the missing rotation put the heading 10° off under a σ of 0.05°). GIVEN the same log with 1 s lost, THEN the
alignment starts over after the gap (coarse again, its σ wide) and ends on the whole log's heading within its σ.
GIVEN a header whose rate_hz is not the data's (every sample would seem to follow a lost one), THEN the replay
refuses the log at its first sample, naming both periods.
"""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from sinsalign.protocol.imu_log import IMU_COLUMNS, LogFormatError, open_imu_log, write_header, write_rows
from sinsalign.service.config import Config
from sinsalign.tools.replay import replay
from sinsalign.tools.sim.files import write_simulation
from sinsalign.tools.sim.scenarios import get_scenario

GAP_AT_S = 100.0


@pytest.fixture(scope="module")
def swing_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    scenario = replace(get_scenario("seed000-swing"), duration_s=240.0)
    return write_simulation(scenario, 3, tmp_path_factory.mktemp("swing")).imu_csv


def without(log: Path, seconds: float, out: Path, rate_hz: float | None = None) -> Path:
    """The log with the samples of ``seconds`` from :data:`GAP_AT_S` on left out (and ``rate_hz`` in its header)."""
    opened = open_imu_log(log)
    rows = np.concatenate([rows for _, rows in opened.row_segments()])
    kept = rows[(rows[:, 0] < GAP_AT_S) | (rows[:, 0] >= GAP_AT_S + seconds - 1e-9)]
    header = opened.header.values | ({} if rate_hz is None else {"rate_hz": rate_hz})
    with open(out, "w", encoding="utf-8") as stream:
        write_header(stream, header, IMU_COLUMNS)
        write_rows(stream, kept)
    return out


def records(log: Path, tmp_path: Path) -> tuple[dict[float, dict], dict[str, int]]:
    out = tmp_path / f"{log.stem}.jsonl"
    summary = replay(log, out, Config(), progress=False)
    return {r["t"]: r for r in map(json.loads, out.read_text().splitlines())}, summary.gate


def heading_difference_deg(a: dict, b: dict) -> float:
    return abs((a["heading_deg"] - b["heading_deg"] + 180.0) % 360.0 - 180.0)


def test_a_gap_of_four_samples_is_bridged(swing_log: Path, tmp_path: Path) -> None:
    whole, whole_gate = records(swing_log, tmp_path)
    gapped, gate = records(without(swing_log, 0.02, tmp_path / "gap.csv"), tmp_path)
    assert whole_gate == {} and gate == {"samples_bridged": 4, "gaps_bridged": 1}
    after = [t for t in whole if t > GAP_AT_S]
    assert after == [t for t in gapped if t > GAP_AT_S]
    assert max(heading_difference_deg(whole[t], gapped[t]) for t in after) < 0.01
    assert gapped[after[-1]]["converged"] == whole[after[-1]]["converged"]


def test_a_gap_of_one_second_starts_the_alignment_over(swing_log: Path, tmp_path: Path, capsys) -> None:
    whole, _ = records(swing_log, tmp_path)
    gapped, gate = records(without(swing_log, 1.0, tmp_path / "gap.csv"), tmp_path)
    assert gate == {"restarts": 1}
    assert "gap of 200 samples before t = 101.0" in capsys.readouterr().err
    first_after = gapped[min(t for t in gapped if t > GAP_AT_S)]
    assert first_after["phase"] == "coarse" and first_after["heading_sigma_deg"] > 1.0
    end = max(gapped)
    assert heading_difference_deg(gapped[end], whole[end]) < 3.0 * gapped[end]["heading_sigma_deg"]


@pytest.mark.parametrize(("rate_hz", "refused"), [(400.0, True), (100.0, True), (206.0, False), (194.0, False)])
def test_a_header_rate_that_is_not_the_data_s_is_refused(swing_log: Path, tmp_path: Path, rate_hz: float,
                                                         refused: bool) -> None:
    log = without(swing_log, 0.0, tmp_path / "rate.csv", rate_hz)
    if not refused:   # a clock a few per cent off its nominal rate
        assert records(log, tmp_path)[0]
        return
    with pytest.raises(LogFormatError) as info:
        replay(log, tmp_path / "out.jsonl", Config(), progress=False)
    first_sample_line = 1 + sum(1 for line in log.read_text().splitlines() if not line[0].isdigit())
    assert (info.value.line, info.value.column) == (first_sample_line, "t")
    assert f"samples come every 5 ms (200 Hz, the median of 100 steps), where the header's rate_hz = {rate_hz:g} " \
           f"says {1e3 / rate_hz:g} ms" in str(info.value)
    assert not (tmp_path / "out.jsonl").exists()

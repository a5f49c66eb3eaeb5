"""The compiled loop over a fixed-base chunk's control steps (service/align/_blocks.pyx) against the pipeline's Python
steps, block by block: the same records, bit for bit, in every configuration it takes part in (offline and live,
chunks of any size, with the loops or without, motion episodes and restarts, noise verdicts that change σ's grade,
another solver, no stored-data passes), and it takes most blocks (else the comparison would prove nothing)."""
from __future__ import annotations

import numpy as np
import pytest
import sinsalign.service.pipeline as pipeline_module
from sinsalign.service.config import config_from_mapping
from sinsalign.service.pipeline import AlignmentPipeline, _imu_rows
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import get_scenario


class _Counting:
    """The compiled loop, counting the blocks it completes."""

    def __init__(self, blocks: object) -> None:
        self.blocks, self.completed = blocks, 0

    def chunk(self, *arrays: object) -> None:
        self.blocks.chunk(*arrays)

    def run(self, b: int, limit: int, *state: object) -> tuple:
        stopped = self.blocks.run(b, limit, *state)
        self.completed += stopped[0] - b
        return stopped


def _records(monkeypatch: pytest.MonkeyPatch, name: str, seconds: float, overrides: dict, live: bool,
             call_samples: int | None, compiled: bool) -> tuple[list, int]:
    loops: list[_Counting] = []
    make = pipeline_module.fixed_base_blocks

    def counted(pipeline: AlignmentPipeline) -> _Counting | None:
        blocks = make(pipeline) if compiled else None
        if blocks is not None:
            loops.append(_Counting(blocks))
            return loops[-1]
        return None

    monkeypatch.setattr(pipeline_module, "fixed_base_blocks", counted)
    scenario = get_scenario(name)
    p = AlignmentPipeline(config_from_mapping(overrides), scenario.site, scenario.rate_hz,
                          scenario.grade.datasheet(), live=live)
    records = []
    for chunk in simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, seconds, 1):
        step = call_samples or len(chunk.t)
        for k in range(0, len(chunk.t), step):
            records += p.process(chunk.t[k:k + step], chunk.dtheta[k:k + step], chunk.dv[k:k + step],
                                 defer_control=live)
    p.settle()
    return records, sum(loop.completed for loop in loops)


@pytest.mark.parametrize(("name", "seconds", "overrides", "live", "call_samples", "share"), [
    ("seed001-swing", 300.0, {}, False, None, 0.8),
    ("seed001-swing", 200.0, {}, True, 7, 0.3),                 # live passes: Python's steps until they end
    ("swing-drive-stop", 300.0, {}, False, None, 0.3),          # a motion episode, a restart
    ("parked-nodatasheet", 400.0, {}, False, 1000, 0.7),        # the data's noise replaces the datasheet's
    ("seed000-swing", 200.0, {"fine": {"enabled": False}}, False, 333, 0.8),
    ("seed000-swing", 150.0, {"fine": {"compass": {"handover": "time", "handover_time_s": 20.0}}}, False, 1000, 0.8),
    ("seed001-swing", 200.0, {"alignment": {"solver": "request"}, "fine": {"compass": {"stored_pairs": 0}}},
     True, 70, 0.4),
])
def test_the_compiled_loop_gives_the_python_steps_records(monkeypatch: pytest.MonkeyPatch, name: str, seconds: float,
                                                          overrides: dict, live: bool, call_samples: int | None,
                                                          share: float) -> None:
    compiled, completed = _records(monkeypatch, name, seconds, overrides, live, call_samples, True)
    python, none = _records(monkeypatch, name, seconds, overrides, live, call_samples, False)
    assert none == 0
    assert len(compiled) == len(python) > 0
    for a, b in zip(compiled, python, strict=True):
        assert a == b
    blocks = seconds / 0.1
    assert completed >= share * blocks, f"the compiled loop took {completed} of {blocks:g} blocks"


def test_a_reader_s_rows_are_read_in_place_with_the_same_records():
    """t, Δθ and Δv as the columns of one (N, 7) block (a log reader's) are read in place, never written: the same
    records as from arrays of their own."""
    scenario = get_scenario("seed001-swing")
    chunks = list(simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, 60.0, 1))
    blocks = [np.column_stack((c.t, c.dtheta, c.dv)) for c in chunks]
    kept = [block.copy() for block in blocks]
    records = []
    for columns in (lambda b: (b[:, 0], b[:, 1:4], b[:, 4:7]), lambda b: (b[:, 0].copy(), b[:, 1:4].copy(),
                                                                           b[:, 4:7].copy())):
        p = AlignmentPipeline(config_from_mapping({}), scenario.site, scenario.rate_hz, scenario.grade.datasheet())
        records.append([r for block in blocks for k in range(0, len(block), 777)
                        for r in p.process(*columns(block[k:k + 777]))])
    assert records[0] == records[1] and len(records[0]) == 60
    assert all(np.array_equal(a, b) for a, b in zip(blocks, kept, strict=True))


def test_rows_are_taken_in_place_only_where_they_lie_as_a_reader_s_rows():
    """The in-place view is exactly the rows, read-only, wherever in its owner they begin (a row slice, a 1-D
    buffer of the owner's); any other layout (another owner, other columns, other row length, a step over rows,
    another dtype) is None, and the pipeline copies."""
    block = np.arange(12 * 7, dtype=float).reshape(12, 7)
    rows = block[3:9]
    view = _imu_rows(rows[:, 0], rows[:, 1:4], rows[:, 4:7])
    assert view is not None and np.shares_memory(view, block) and not view.flags.writeable
    assert np.array_equal(view, rows)
    flat = np.frombuffer(block.tobytes(), dtype=float).reshape(12, 7)
    assert np.array_equal(_imu_rows(flat[:, 0], flat[:, 1:4], flat[:, 4:7]), block)
    wide = np.zeros((12, 8))
    other = block.copy()
    for columns in ((rows[:, 0], rows[:, 1:4], other[3:9, 4:7]), (rows[:, 0], rows[:, 4:7], rows[:, 1:4]),
                    (wide[:, 0], wide[:, 1:4], wide[:, 4:7]), (block[::2, 0], block[::2, 1:4], block[::2, 4:7]),
                    (rows[:, 0].copy(), rows[:, 1:4], rows[:, 4:7])):
        assert _imu_rows(*columns) is None
    as32 = block.astype(np.float32)
    assert _imu_rows(as32[:, 0], as32[:, 1:4], as32[:, 4:7]) is None

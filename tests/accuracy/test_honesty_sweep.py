"""The honesty sweep (tools/honesty.py, ``sinsalign eval honesty``): every mode on its motion, with navigation-grade,
tactical and MEMS IMUs whose logs state them.

GIVEN a mode (fixed base still, swinging and turning; odometer driving; GNSS flying; odometer + GNSS driving;
transfer flying) and an IMU of each grade whose datasheet states its errors, WHEN it aligns on seeds no other test
runs, THEN no record reported ``converged`` is beyond 3σ in heading or level, and at least 90 % of the records from
10 s are within 2σ in both, but for a MEMS transfer slave against a 0.001° master (below). The default run takes
one seed of a representative cell per mode; the slow one every such cell on five seeds. The cells whose datasheet
understates the IMU tenfold are in the documented table (docs/results.md): most of them miss, and on a still base
they must (no data tell an accelerometer bias from a tilt, nor the east gyro bias from a heading).
"""
import pytest
from sinsalign.tools.honesty import CASES, IMUS, cell_figures, sweep

# a MEMS slave against seed 002's 0.001° master is not yet honest: its filter's σ is 2-3 times small in the rolls
# (0.01-0.02° off under 0.008°; 44-51 converged records beyond 3σ in 30 runs, seeds 410-439)
TRANSFER_MEMS = (6, "MEMS", False)
STATED = [(i, grade, False) for i in range(len(CASES)) for grade in IMUS if (i, grade, False) != TRANSFER_MEMS]
REPRESENTATIVE = [(0, "MEMS", False), (1, "tactical", False), (2, "navigation", False), (3, "tactical", False),
                  (4, "MEMS", False), (5, "navigation", False), (6, "tactical", False)]


def assert_honest(runs) -> None:
    for (case, grade, _), cell_runs in runs.items():
        figures = cell_figures(cell_runs)
        where = f"{CASES[case].mode}, {CASES[case].motion}, {grade}"
        assert figures.converged_beyond_3sigma == 0, f"{where}: {figures.converged_beyond_3sigma} converged > 3σ"
        assert figures.inside_2sigma >= 0.9, f"{where}: {100 * figures.inside_2sigma:.1f} % within 2σ"


def test_a_representative_cell_of_each_mode_is_honest():
    assert_honest(sweep([300], REPRESENTATIVE, progress=False))


@pytest.mark.slow
def test_every_cell_whose_datasheet_states_its_imu_is_honest():
    assert_honest(sweep(range(301, 306), STATED, progress=False))

"""The sample gate's compiled screens (service/_gate.pyx) against the numpy expressions they replace, on hostile
rows: NaN, infinities, 1e308, times beyond any clock, repeats and gaps."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from sinsalign.protocol.imu_log import MAX_TIME_S
from sinsalign.service._gate import plain_rows, screen

VALUES = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, 1e-3, 0.02, 1e308, 2e10]))
ROWS = st.integers(0, 12).flatmap(lambda n: arrays(float, (n, 7), elements=VALUES))


@settings(max_examples=300, deadline=None)
@given(ROWS, st.data())
def test_the_screens_are_the_numpy_expressions(rows, data):
    saturated = np.array(data.draw(st.lists(st.integers(0, 1), min_size=len(rows), max_size=len(rows))), np.int64)
    dtheta_max, dv_max, clockless, out_of_range, refused = screen(rows, saturated, 0.05, 10.0, MAX_TIME_S)
    with np.errstate(invalid="ignore"):
        expected_dtheta, expected_dv = np.abs(rows[:, 1:4]).max(axis=1), np.abs(rows[:, 4:7]).max(axis=1)
        expected_clockless = ~(np.abs(rows[:, 0]) <= MAX_TIME_S)
        expected_range = ((expected_dtheta > 0.05) | (expected_dv > 10.0)) & (saturated == 0)
    assert np.array_equal(dtheta_max, expected_dtheta, equal_nan=True)
    assert np.array_equal(dv_max, expected_dv, equal_nan=True)
    assert np.array_equal(clockless, expected_clockless) and np.array_equal(out_of_range, expected_range)
    assert np.array_equal(refused, expected_clockless | expected_range | (saturated != 0))


TIMES = st.one_of(st.floats(-1e12, 1e12, allow_nan=False), st.sampled_from([np.nan, np.inf, 0.005, 0.0125, 0.01]))


@settings(max_examples=300, deadline=None)
@given(st.lists(TIMES, max_size=12), st.one_of(st.none(), st.floats(-1e3, 1e3)), st.data())
def test_the_plain_rows_are_the_numpy_expression(times, last_t, data):
    t = np.cumsum(times) if data.draw(st.booleans()) else np.array(times, float)   # runs on, or anywhere
    refused = np.array(data.draw(st.lists(st.booleans(), min_size=len(t), max_size=len(t))), bool)
    plain = plain_rows(t, refused.view(np.uint8), np.nan if last_t is None else last_t, 0.005)
    previous = np.concatenate(([-np.inf if last_t is None else last_t], t[:-1]))
    with np.errstate(invalid="ignore", over="ignore"):
        missing = np.round((t - previous) / 0.005) - 1.0
    expected = ~refused & (t > previous) & ~(missing > 0.0)
    if last_t is None and len(t):
        expected[0] = not refused[0]
    assert np.array_equal(plain, expected)

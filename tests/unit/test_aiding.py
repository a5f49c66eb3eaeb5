"""Aiding input (foundation of the aided modes): the pinned aiding logs and the epoch track.

GIVEN odometer, GNSS and master-INS logs in the pinned format, THEN they stream like the IMU log
and a malformed one names file, line and column; GIVEN epochs late, repeated, out of order or
missing, THEN the track shifts, drops and counts them and interpolates exactly between good ones.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sinsalign.protocol.aiding_log import KINDS, open_aiding_log
from sinsalign.protocol.imu_log import LogFormatError, write_header, write_rows
from sinsalign.service.aiding import AidingTrack


def write_log(path: Path, kind: str, rows: np.ndarray, keys: dict | None = None) -> Path:
    with open(path, "w", encoding="utf-8") as f:
        write_header(f, keys or {}, KINDS[kind].columns)
        write_rows(f, rows)
    return path


@pytest.mark.parametrize("kind", list(KINDS))
def test_each_kind_streams_its_columns(tmp_path, kind):
    n = len(KINDS[kind].columns)
    rows = np.column_stack((np.arange(1, 301) * 0.01, np.random.default_rng(1).normal(size=(300, n - 1))))
    log = open_aiding_log(kind, write_log(tmp_path / f"{kind}.csv", kind, rows))
    assert np.array_equal(np.concatenate(list(log.blocks(chunk_rows=64))), rows)


def test_lever_arm_and_std_keys(tmp_path):
    rows = np.array([[0.1, 30.0, 114.0, 20.0, 0.0, 50.0, 0.0]])
    keys = {"lever_x_m": 1.0, "lever_y_m": -1.0, "lever_z_m": 0.5, "vel_std_mps": 0.1, "pos_std_m": 2.0}
    log = open_aiding_log("gnss", write_log(tmp_path / "g.csv", "gnss", rows, keys))
    assert log.stated() == {"lever_m": (1.0, -1.0, 0.5), "vel_std_mps": 0.1, "pos_std_m": 2.0}
    assert open_aiding_log("odo", write_log(tmp_path / "o.csv", "odo", rows[:, :4])).stated() == {}
    lever_y = open_aiding_log("gnss", write_log(tmp_path / "y.csv", "gnss", rows, {"lever_y_m": 2.0, "vel_std_mps": 0}))
    assert lever_y.stated() == {"lever_m": (0.0, 2.0, 0.0)}   # a 0 std states an ideal receiver: none taken
    with pytest.raises(LogFormatError, match="vel_std_mps must be a finite number ≥ 0"):
        open_aiding_log("odo", write_log(tmp_path / "bad.csv", "odo", rows[:, :4], {"vel_std_mps": -1}))
    with pytest.raises(ValueError, match="unknown aiding kind"):
        open_aiding_log("lidar", tmp_path / "o.csv")


def test_a_bad_cell_names_file_line_and_column_and_disorder_is_not_fatal(tmp_path):
    path = tmp_path / "odo.csv"
    path.write_text("# vel_std_mps=0.03\nt,vx,vy,vz\n0.1,0,20,0\n0.05,0,20,0\n0.2,0,abc,0\n")
    log = open_aiding_log("odo", path)
    with pytest.raises(LogFormatError) as info:
        list(log.blocks())
    assert (info.value.line, info.value.column) == (5, "vy")      # line 4 goes back in time: not an error here


def test_track_shifts_by_latency_and_interpolates_exactly():
    track = AidingTrack(2, latency_s=0.05)
    track.push(np.array([[1.05, 10.0, 0.0], [2.05, 20.0, 4.0]]))
    assert track.latest_time == pytest.approx(2.0)
    assert track.at(1.25) == pytest.approx([12.5, 1.0])
    assert track.at(2.5) is None and track.counters.unaided_queries == 1


def test_track_counts_repeats_disorder_non_finite_and_gaps():
    track = AidingTrack(1, max_gap_s=1.0)
    track.push(np.array([[1.0, 1.0], [1.0, 1.0], [0.5, 1.0], [1.5, np.nan], [1.2, 1.0], [4.0, 2.0]]))
    c = track.counters
    assert (c.epochs, c.repeats, c.out_of_order, c.non_finite, c.gaps) == (3, 1, 1, 1, 1)
    assert track.at(2.0) is None     # across a 2.8-s gap: nothing, not a made-up value


def test_a_gap_is_judged_against_the_streams_own_rate():
    """GIVEN a 1-Hz stream and max_gap_s 0.5, THEN its 1-s intervals are no gaps and are interpolated across, one
    missing epoch (2 s) is no gap either, two (3 s) are; a 50-Hz stream has gaps from max_gap_s on, as before."""
    slow = AidingTrack(1, max_gap_s=0.5)
    t = np.r_[np.arange(10.0), 11.0, 12.0, 15.0, 16.0]          # 10 s missing one epoch, then two
    slow.push(np.column_stack((t, t)))
    assert slow.counters.gaps == 1
    assert slow.values_at(np.array([3.25, 10.5, 13.0]))[:, 0] == pytest.approx([3.25, 10.5, np.nan], nan_ok=True)
    fast = AidingTrack(1, max_gap_s=0.5)
    t = np.r_[np.arange(50) * 0.02, 1.4, 2.0, 2.02]              # 0.42 s: no gap; 0.6 s: a gap
    fast.push(np.column_stack((t, t)))
    assert fast.counters.gaps == 1 and np.isnan(fast.values_at(np.array([1.7]))[0, 0])


@given(st.lists(st.floats(1e-4, 10.0), min_size=1, max_size=40))
def test_the_usual_interval_is_the_median_of_the_last_16(intervals: list[float]) -> None:
    """Odd and even counts, fewer and more than 16 intervals: numpy's median of the latest ones, to the bit."""
    track = AidingTrack(1, max_gap_s=1e9)
    t = np.cumsum([0.0, *intervals])
    track.push(np.column_stack((t, t)))
    steps = np.diff(t)
    assert track.usual_interval_s == float(np.median(steps[-16:]))


def test_each_value_carries_the_number_of_the_newest_epoch_at_or_before_it():
    """The number tells an estimator whether a sample brings a new epoch: samples between the same two epochs
    carry the earlier one's, a sample at an epoch carries that one's, a sample with no values NaN."""
    track = AidingTrack(1, latency_s=0.5)
    track.push(np.array([[0.5, 0.0], [1.5, 10.0], [1.5, 99.0], [2.5, 20.0]]))   # a repeat: not an epoch, no number
    rows = track.aid_at(np.array([-0.5, 0.0, 0.3, 0.9999999, 1.0, 1.7, 2.0, 2.5]))
    np.testing.assert_allclose(rows[1:, 0], [0, 0, 1, 1, 1, 2, np.nan])
    np.testing.assert_allclose(rows[1:-1, 1], [0.0, 3.0, 10.0, 10.0, 17.0, 20.0])
    assert np.isnan(rows[0]).all() and np.isnan(rows[-1]).all()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.text(max_size=400))
def test_fuzz_aiding_reader_gives_only_format_errors(tmp_path, text):
    path = tmp_path / "fuzz.csv"
    path.write_text("t,vx,vy,vz\n" + text, encoding="utf-8", errors="replace")
    try:
        for _ in open_aiding_log("odo", path).blocks(chunk_rows=7):
            pass
    except LogFormatError:
        pass


def test_track_interpolates_many_times_at_once_and_forgets_what_is_passed():
    track = AidingTrack(1, max_gap_s=0.5)
    track.push(np.column_stack((np.arange(10) * 0.1, np.arange(10.0))))
    values = track.values_at(np.array([-0.05, 0.05, 0.45, 0.9, 0.95]))
    assert np.isnan(values[0, 0]) and np.isnan(values[-1, 0]) and track.counters.unaided_queries == 2
    assert values[1:4, 0] == pytest.approx([0.5, 4.5, 9.0])
    track.release(0.45)
    assert track.values_at(np.array([0.45]))[0, 0] == pytest.approx(4.5)
    assert np.isnan(track.values_at(np.array([0.35]))[0, 0])       # forgotten: before the epochs it keeps


def test_feed_reads_ahead_only_as_far_as_the_imu_needs():
    from sinsalign.service.aiding import AidingFeed
    blocks = [np.column_stack((np.arange(k, k + 10) * 0.1, np.arange(k, k + 10.0))) for k in range(0, 100, 10)]
    pulled = []

    def source():
        for b in blocks:
            pulled.append(b)
            yield b

    feed = AidingFeed(AidingTrack(1), source())
    assert feed.aid_at(np.array([0.15, 0.25]))[:, 1] == pytest.approx([1.5, 2.5])
    assert len(pulled) == 1
    assert feed.aid_at(np.array([2.55]))[0, 1] == pytest.approx(25.5) and len(pulled) == 3
    assert np.isnan(feed.aid_at(np.array([20.0]))[0, 1])         # past the end: nothing, no error


def test_a_track_far_ahead_of_the_imu_stays_bounded_and_counts_what_it_drops():
    """GIVEN aiding that keeps coming while the IMU does not (link down, clock mismatch), THEN the track holds
    at most ``capacity`` epochs, counts the rest as overflow (a fault in the status), and takes new epochs
    again once the IMU has passed some."""
    track = AidingTrack(3, capacity=100)
    t = np.arange(150) * 0.01
    track.push(np.column_stack((t, np.ones((150, 3)))))
    assert track.counters.overflow == 50 and track.counters.epochs == 100
    assert track._epochs.shape[0] <= 100
    assert track.latest_time == pytest.approx(t[99])
    track.release(t[60])                          # keeps epochs 60…99: room for 60 more
    later = 2.0 + np.arange(70) * 0.01
    track.push(np.column_stack((later, np.ones((70, 3)))))
    assert track.counters.epochs == 160 and track.counters.overflow == 60
    assert track._epochs.shape[0] <= 100
    np.testing.assert_allclose(track.at(t[80]), [1.0, 1.0, 1.0])


def test_a_track_interpolates_longitude_the_short_way_round_the_antimeridian():
    """GIVEN fixes at 179.99° and -179.99° E, THEN a sample half-way lies at ±180°, not on the Greenwich meridian
    (a plain interpolation puts it 20 000 km away); the other columns interpolate as before."""
    track = AidingTrack.for_kind("gnss")
    assert track.width == 6 and track.longitude_column == 1
    track.push(np.array([[0.0, 30.0, 179.99, 100.0, 1.0, 2.0, 3.0], [1.0, 30.0, -179.99, 200.0, 3.0, 2.0, 1.0]]))
    middle, quarter = track.values_at(np.array([0.5, 0.75]))
    assert abs(abs(middle[1]) - 180.0) < 1e-9 and quarter[1] == pytest.approx(-179.995)
    np.testing.assert_allclose(middle[[0, 2, 3, 4, 5]], [30.0, 150.0, 2.0, 2.0, 2.0])
    assert AidingTrack.for_kind("master").longitude_column == 8 and AidingTrack.for_kind("odo").longitude_column is None


def test_a_master_track_interpolates_its_attitude_as_a_rotation_whatever_the_quaternions_sign():
    """GIVEN master epochs off the IMU grid whose quaternions alternate in sign (q and -q are one attitude), THEN
    values between them are unit quaternions of the attitude in between, not the component mean of q and -q."""
    from sinsalign.service.align.conventions import dcm_from_quat, misalignment, quat_from_rotvec
    track = AidingTrack.for_kind("master")
    assert track.quaternion_column == 0
    t = np.arange(6) * 0.1 + 0.003
    angles = 0.2 * t                                                    # a 0.2-rad/s turn about up
    q = quat_from_rotvec(np.column_stack((np.zeros((6, 2)), angles)))
    q[1::2] *= -1.0
    track.push(np.column_stack((t, q, np.ones((6, 3)), np.full((6, 3), 30.0))))
    at = np.arange(1, 50) * 0.01
    values = track.values_at(at)
    assert np.allclose(np.linalg.norm(values[:, :4], axis=1), 1.0)
    truth = dcm_from_quat(quat_from_rotvec(np.column_stack((np.zeros((49, 2)), 0.2 * at))))
    assert np.abs(misalignment(dcm_from_quat(values[:, :4]), truth)).max() < 1e-6


@pytest.mark.parametrize("name", ["seed003-20", "seed003-20-ideal", "seed004", "seed004-ideal", "seed002",
                                  "seed002-ideal", "seed003-odo-gnss", "seed003-odo-gnss-ideal"])
def test_sim_replay_eval_and_the_live_bench_configure_an_aiding_sensor_alike(tmp_path: Path, name: str) -> None:
    """What a simulated aiding log states of its sensor is read back by the replay as the evaluation and the live
    bench configure it, and the bench's [aiding] table (every sensor of the scenario) is a valid configuration. An
    ideal sensor states no noise, and the demo must not configure that 0 (it would stop with
    "aiding.gnss.vel_std_mps: must be > 0")."""
    from sinsalign.service.config import config_from_mapping
    from sinsalign.tools.sim.aiding import daemon_aiding, scenario_aids
    from sinsalign.tools.sim.files import write_simulation
    from sinsalign.tools.sim.scenarios import seed_run
    scenario = seed_run(name, 1, 2.0)
    aids = scenario_aids(scenario, 1)
    files = write_simulation(scenario, 1, tmp_path)
    config = config_from_mapping({"aiding": daemon_aiding(aids)})
    assert config.aiding.inputs == tuple(aid.kind for aid in aids) and len(aids) == 1 + ("odo-gnss" in name)
    for aid in aids:
        log = open_aiding_log(aid.kind, getattr(files, f"{aid.kind}_csv"))
        assert log.stated() == aid.stated()
        assert bool(aid.stated()) == (not name.endswith("-ideal") or aid.kind == "gnss")   # an antenna's lever arm
        for key, value in aid.stated().items():
            assert getattr(getattr(config.aiding, aid.kind), key) == value

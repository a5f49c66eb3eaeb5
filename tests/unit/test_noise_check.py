"""The noise the data show, from the fixed-base residual (service/align/noise_check.py).

GIVEN α sequences made of the reference turning with the Earth plus one known error process (white accelerometer
noise: a random walk; a gyro's angle random walk: an integrated random walk; a bounded disturbance such as
quantisation or rocking), THEN the meter finds that process's figure and no other; a knock is left out; the
verdict keeps a datasheet the data cannot tell apart, and replaces one they can (up or down), saying so when
the data are far louder. Through the pipeline, a datasheet ten times too quiet is told and σ stays honest.
"""
import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG, dcm_from_euler, dcm_from_quat, misalignment
from sinsalign.service.align.earth import Site, beta_fixed
from sinsalign.service.align.noise_check import NoiseMeter
from sinsalign.service.align.sensor_model import SensorGrade
from sinsalign.service.config import config_from_mapping
from sinsalign.service.pipeline import AlignmentPipeline
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import get_scenario

STEP = 0.1
SITE = Site(34.0 * DEG, 118.0 * DEG)
C_N0_B0 = dcm_from_euler(0.7, 0.02, -0.01).T
Q = (50e-6 * 9.8) ** 2            # 50 µg/√Hz
N = 0.01 * DEG / 60.0             # 0.01°/√h
S = 1.4e-3                        # m/s: a 4.9-mm/s quantiser's remainder, uniform


def alpha_of(duration_s: float, rng: np.random.Generator, q: float = 0.0, n: float = 0.0, s: float = 0.0):
    """α (K, 3) at the control steps: C β(t) plus a random walk of density q, the tilt of an angle random walk n seen
    by gravity, and a uniform bounded disturbance of std s, per axis."""
    t = np.arange(1, round(duration_s / STEP) + 1) * STEP
    walk = np.cumsum(rng.standard_normal((len(t), 3)) * np.sqrt(q * STEP), axis=0)
    tilt = np.cumsum(rng.standard_normal((len(t), 3)) * np.sqrt(n**2 * STEP), axis=0)
    tilt_walk = np.cumsum(SITE.gravity * tilt * STEP, axis=0)
    bounded = (rng.random((len(t), 3)) - 0.5) * np.sqrt(12.0) * s
    return t, beta_fixed(SITE.lat, SITE.gravity, t) @ C_N0_B0.T + walk + tilt_walk + bounded


def metered(t: np.ndarray, alpha: np.ndarray) -> NoiseMeter:
    meter = NoiseMeter(STEP, SITE.lat, SITE.gravity)
    meter.C_n0_b0 = C_N0_B0 @ dcm_from_euler(0.02, 0.0, 0.0)   # a rough estimate is enough
    meter.feed(t, alpha)
    return meter


@pytest.mark.parametrize(("kind", "q", "n", "s"), [("white", Q, 0.0, 0.0), ("walk", 0.0, N, 0.0),
                                                     ("bounded", 0.0, 0.0, S)])
def test_the_meter_finds_each_error_process_alone(kind, q, n, s):
    f = metered(*alpha_of(600.0, np.random.default_rng(7), q, n, s)).figures()
    found = {"white": f.q / Q if q else None, "walk": f.n2 / N**2 if n else None,
             "bounded": f.s / (S**2 * STEP) if s else None}
    assert 0.7 < found[kind] < 1.3, f
    # the other figures are not told apart from zero
    for value, se, true in ((f.q, f.q_se, q), (f.n2, f.n2_se, n**2), (f.s, f.s_se, s**2)):
        if not true:
            assert value <= 2.5 * se + 1e-30, f


def test_a_knock_is_left_out():
    t, alpha = alpha_of(600.0, np.random.default_rng(8), Q, 0.0, S)
    clean = metered(t, alpha).figures()
    knocked = alpha.copy()
    knock = (t > 300.0) & (t < 301.5)
    knocked[knock, :2] += 0.05 * np.sin(np.pi * (t[knock] - 300.0) / 1.5)[:, None]   # 5 cm/s and back
    meter = metered(t, knocked)
    f = meter.figures()
    assert meter.outliers > 0
    assert abs(f.q / clean.q - 1.0) < 0.1 and abs(f.s / clean.s - 1.0) < 0.1


def test_the_verdict_bounds_what_the_data_cannot_tell_and_replaces_what_they_can():
    """σ takes the upper bound of the white noise the residual shows. Under a quantiser's floor that bound is a few
    times the true figure and no notice (the data do not show a louder sensor); a datasheet ten times too quiet is
    told; one ten times too loud gives way to the data."""
    meter = metered(*alpha_of(600.0, np.random.default_rng(9), (5e-6 * 9.8) ** 2, 0.0, S))
    honest = SensorGrade(5e-8, 3e-7, 5e-4, 5e-6 * 9.8)
    verdict = meter.verdict(honest)
    assert 1.0 <= verdict.grade.acc_vrw_ms_rts / honest.acc_vrw_ms_rts < 4.0 and verdict.notice is None
    assert verdict.grade.gyro_arw_rad_rts == honest.gyro_arw_rad_rts
    assert 1.0 <= verdict.grade.base_motion_m_rts / (S * np.sqrt(STEP)) < 1.3
    meter = metered(*alpha_of(600.0, np.random.default_rng(10), Q))
    quiet = meter.verdict(SensorGrade(5e-8, 3e-7, 5e-4, np.sqrt(Q) / 10))
    assert 1.0 <= quiet.grade.acc_vrw_ms_rts / np.sqrt(Q) < 1.3 and "acc_vrw_ug_rthz" in quiet.notice
    loud = meter.verdict(SensorGrade(5e-8, 3e-7, 5e-4, np.sqrt(Q) * 10))
    assert 1.0 <= loud.grade.acc_vrw_ms_rts / np.sqrt(Q) < 1.3 and loud.notice is None


def test_exact_data_are_no_noise():
    t, alpha = alpha_of(200.0, np.random.default_rng(11))
    verdict = metered(t, alpha).verdict(SensorGrade(1e-12, 1e-12, 1e-12, 1e-12))
    assert verdict.notice is None and verdict.grade.base_motion_m_rts < 1e-8


def aligned_errors(datasheet_scale: float, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, str | None]:
    """Seed-000 swing, OPREQ then compass, with the datasheet's noise figures times ``datasheet_scale``: t (s),
    |heading error| / σ, converged, and the pipeline's notice."""
    scenario = get_scenario("seed000-swing")
    stated = scenario.grade.datasheet()
    datasheet = {**stated, "acc_vrw_ug_rthz": stated["acc_vrw_ug_rthz"] * datasheet_scale,
                 "gyro_arw_deg_rth": stated["gyro_arw_deg_rth"] * datasheet_scale}
    pipeline = AlignmentPipeline(config_from_mapping({}), scenario.site, scenario.rate_hz, datasheet)
    records = []
    for chunk in simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, scenario.duration_s, seed):
        records += pipeline.process(chunk.t, chunk.dtheta, chunk.dv)
    t = np.array([r.t for r in records])
    phi = misalignment(dcm_from_quat(np.array([r.q for r in records])), scenario.motion.attitude(t)) / DEG
    ratio = np.abs(phi[:, 2]) / np.array([r.heading_sigma_deg for r in records])
    return t, ratio, np.array([r.converged for r in records]), pipeline.last_notice


def test_a_datasheet_ten_times_too_quiet_is_told_and_sigma_stays_honest():
    """The accelerometer's white noise is what the swing's heading rests on: the residual shows it and σ takes it.
    The gyro's per-sample noise is far under anything the residual can see, and its figure stays the datasheet's."""
    for seed in (0, 1):
        t, ratio, converged, notice = aligned_errors(0.1, seed)
        late = t >= 30.0
        assert "acc_vrw_ug_rthz" in notice
        assert (ratio[late] <= 2.0).mean() >= 0.9 and (ratio[late & converged] <= 3.0).all()
    _, _, _, notice = aligned_errors(1.0, 0)
    assert notice is None

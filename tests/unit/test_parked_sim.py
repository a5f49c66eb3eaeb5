"""The parked-vehicle simulator (tools/sim/parked.py), quantised increments and the scenarios built on them.

GIVEN a parked car (rocking, engine vibration, knocks, people getting in and out) or a swinging base driven off,
WHEN its exact increments are simulated, THEN the strapdown integral of them follows the analytic attitude and
displacement, the events settle as drawn, the quantised sensor stays within a count of the truth, and the
scenarios that existed before give the same bits.
"""
import pickle
from dataclasses import replace
from itertools import pairwise

import numpy as np
import pytest
from sinsalign.protocol.imu_log import DATASHEET_KEYS, open_imu_log
from sinsalign.service.align.conventions import DEG, dcm_from_quat, euler_from_dcm, misalignment
from sinsalign.service.align.earth import C_n_n0_fixed
from sinsalign.service.align.strapdown import InertialIntegrator
from sinsalign.tools.sim.files import write_simulation
from sinsalign.tools.sim.imu import Accumulator, ImuErrors, simulate, true_increments
from sinsalign.tools.sim.parked import DampedOscillation, ParkedMotion, Signal, SmoothStep, parked_motion
from sinsalign.tools.sim.scenarios import PARKED_ERRORS, PARKED_SITE, daemon_sections, get_scenario

SITE = PARKED_SITE


def busy_car(seed: int = 1) -> ParkedMotion:
    """Seed ``seed``'s car with a knock at 20 s (0.3° pitch, -0.2° roll) and someone getting in at 40 s (0.5° pitch,
    3 cm down, with a bounce) added, so a minute sees every kind of term."""
    car = parked_motion(seed)
    pitch = (*car.pitch.terms, DampedOscillation(20.0, 0.3 * DEG, 2.5, 1.0), SmoothStep(40.0, 2.0, 0.5 * DEG),
             DampedOscillation(42.0, 0.05 * DEG, 1.5, 0.5, 0.33))
    up = (*car.up.terms, SmoothStep(40.0, 2.0, -0.03), DampedOscillation(42.0, -0.003, 1.5, 0.5, 0.33))
    return replace(car, pitch=replace(car.pitch, terms=pitch),
                   roll=replace(car.roll, terms=(*car.roll.terms, DampedOscillation(20.0, -0.2 * DEG, 2.5, 1.0))),
                   up=replace(car.up, terms=up))


def car_velocity_n(car: ParkedMotion, t: np.ndarray) -> np.ndarray:
    """ṙ^n (…, 3) m/s: the rate of the displacement."""
    return np.stack([s.jet(t)[1] for s in (car.right, car.front, car.up)], axis=-1) @ car.car_axes.T


def test_error_free_increments_integrate_to_the_parked_attitude_and_displacement():
    car, rate = busy_car(), 400.0
    dt = 1.0 / rate
    chunks = list(simulate(car, SITE, ImuErrors(), rate, 60.0, 0))
    t = np.concatenate([c.t for c in chunks])
    dtheta, dv = np.concatenate([c.dtheta for c in chunks]), np.concatenate([c.dv for c in chunks])
    q_b_b0, alpha = InertialIntegrator().integrate(dtheta, dv)
    C0 = car.attitude(np.zeros(1))[0]
    C_n_n0 = C_n_n0_fixed(SITE.lat, t)
    C_b_n = np.swapaxes(C_n_n0, -1, -2) @ C0 @ dcm_from_quat(q_b_b0)
    # at 400 Hz the strapdown's own coning error under the 20-40 Hz engine is 5e-10 rad (7e-8 rad at 100 Hz)
    assert np.abs(misalignment(C_b_n, np.concatenate([c.C_b_n_true for c in chunks]))).max() < 2e-9
    # C_b^n(0) α − ∫ C_n^{n0} [0, 0, g] dt = ∫ C_n^{n0} r̈ dt ≈ C_n^{n0} ṙ − ṙ(0), up to Ω × r (2e-6 m/s)
    x, w = np.polynomial.legendre.leggauss(5)
    tau = (t - dt)[:, None] + 0.5 * dt * (x + 1.0)[None, :]
    up_g = np.array([0.0, 0.0, SITE.gravity])
    beta = np.cumsum(((C_n_n0_fixed(SITE.lat, tau) @ up_g) * (0.5 * dt * w)[None, :, None]).sum(axis=1), axis=0)
    expected = (C_n_n0 @ car_velocity_n(car, t)[..., None])[..., 0] - car_velocity_n(car, np.zeros(1))
    assert np.abs(car_velocity_n(car, t)).max() > 0.02               # the sink moves at centimetres per second
    assert np.abs((C0 @ alpha.T).T - beta - expected).max() < 1e-5


def test_rates_and_accelerations_are_the_derivatives_of_the_analytic_attitude_and_displacement():
    car, h = busy_car(), 1e-5
    t = np.linspace(0.0, 60.0, 20001)
    C, omega_nb_b = car.attitude_and_rate(t)
    dC = (car.attitude(t + h) - car.attitude(t - h)) / (2.0 * h)
    W = np.swapaxes(C, -1, -2) @ dC                                   # [ω_nb^b ×]
    assert np.abs(np.stack((W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]), -1) - omega_nb_b).max() < 1e-8
    r = car.displacement_n
    assert np.abs((r(t + 1e-4) - 2 * r(t) + r(t - 1e-4)) / 1e-8 - car.accel_n(t)).max() < 2e-5   # of 0.37 m/s²


def test_specific_force_is_gravity_with_bounded_deviations_and_the_car_stays_put():
    scenario = get_scenario("parked")
    t = np.arange(0.0, 1800.0, 0.01)
    for seed in (0, 1):
        car = scenario.for_seed(seed).motion
        _, _, f_b = car.body_rate_and_force(SITE, t)
        deviation = np.linalg.norm(f_b, axis=-1) - SITE.gravity
        assert np.abs(deviation).max() < 1.0                         # engine ≤ 0.17, bounces ≤ 1 m/s²
        assert 0.005 < np.sqrt(np.mean(deviation**2)) < 0.1           # m/s²: the engine's vibration
        assert abs(deviation.mean()) < 1e-3
        assert np.abs(car.displacement_n(t)).max() < 0.1              # m: centimetres, no drift


def test_a_knock_rings_and_settles_back_to_the_tilt_before():
    knock = DampedOscillation(100.0, 0.3 * DEG, 2.0, 1.0)
    car = ParkedMotion(heading=Signal(1.0), pitch=Signal(1.0 * DEG, (knock,)), roll=Signal(-0.5 * DEG))
    t = np.arange(90.0, 120.0, 0.001)
    _, pitch, roll = euler_from_dcm(car.attitude(t))
    swing = (pitch - 1.0 * DEG) / DEG
    assert np.abs(swing[t <= 100.0]).max() < 1e-12
    assert 0.25 < np.abs(swing[(t > 100.0) & (t < 101.0)]).max() <= 0.3   # the peak, within a second
    assert np.abs(swing[t > 105.0]).max() < 0.02 * 0.3                    # 2 % left after 5 s (decay 1 s)
    assert np.abs(swing[t > 110.0]).max() < 2e-4 * 0.3                    # and nothing after 10 s
    assert np.abs(roll / DEG + 0.5).max() < 1e-12


def test_a_load_sinks_the_car_until_it_gets_out():
    car = ParkedMotion(up=Signal(0.0, (SmoothStep(10.0, 2.0, -0.02), SmoothStep(50.0, 1.5, 0.02))))
    z = car.displacement_n(np.array([9.0, 11.0, 12.0, 40.0, 51.5, 60.0]))[:, 2]
    assert z == pytest.approx([0.0, -0.01, -0.02, -0.02, 0.0, 0.0], abs=1e-15)
    # the drawn people: each sinks the car 1-3 cm over 1-3 s; who gets out lifts it by as much again
    sinks = [s for seed in range(4) for s in parked_motion(seed).up.terms if isinstance(s, SmoothStep)]
    assert sinks and all(0.01 <= abs(s.delta) <= 0.03 and 1.0 <= s.duration_s <= 3.0 for s in sinks)
    assert sum(s.delta < 0 for s in sinks) >= sum(s.delta > 0 for s in sinks)    # out only after in


def test_the_accumulator_stays_within_one_count_and_carries_over_chunks():
    rng = np.random.default_rng(7)
    increments = 9.80665e-2 + 1e-3 * rng.standard_normal((200_000, 3))   # 2000 s of Δv at 100 Hz, m/s
    quantum = 500.0 * 9.80665e-6
    whole = Accumulator(quantum).quantise(increments)
    counts = whole / quantum
    assert np.array_equal(counts, np.rint(counts))
    # integrated: the counts emitted so far against the input's sum (1e-9: rounding of a 2e4-m/s sum)
    assert np.abs(np.cumsum(counts, axis=0) * quantum - np.cumsum(increments, axis=0)).max() <= 0.5 * quantum + 1e-9
    chunked = Accumulator(quantum)
    cuts = [0, 1, 2, 5, 1000, 77_777, 200_000]
    pieces = [chunked.quantise(increments[a:b]) for a, b in pairwise(cuts)]
    assert np.array_equal(np.concatenate(pieces), whole)


def test_simulated_parked_increments_are_whole_counts_and_the_same_whatever_the_chunks():
    scenario = replace(get_scenario("parked"), duration_s=60.0).for_seed(4)
    # without the white noise: simulate() draws the gyro's and the accelerometer's noise chunk by chunk, in turn
    noiseless = replace(scenario.errors, gyro_arw_rad_rts=0.0, acc_vrw_ms_rts=0.0)
    small, large = (list(simulate(scenario.motion, SITE, noiseless, 100.0, 60.0, 4, chunk_samples=n))
                    for n in (7, 20000))
    for field in ("t", "dtheta", "dv", "C_b_n_true"):
        assert np.array_equal(np.concatenate([getattr(c, field) for c in small]),
                              np.concatenate([getattr(c, field) for c in large])), field
    dtheta, dv = np.concatenate([c.dtheta for c in large]), np.concatenate([c.dv for c in large])
    for increments, quantum in ((dtheta, PARKED_ERRORS.gyro_quantum_rad), (dv, PARKED_ERRORS.acc_quantum_mps)):
        assert np.abs(increments / quantum - np.rint(increments / quantum)).max() < 1e-6
    # against the same sensor unquantised: within half a count, integrated
    raw = replace(noiseless, gyro_quantum_rad=0.0, acc_quantum_mps=0.0)
    raw_chunks = list(simulate(scenario.motion, SITE, raw, 100.0, 60.0, 4))
    for quantised, unquantised, quantum in ((dtheta, [c.dtheta for c in raw_chunks], PARKED_ERRORS.gyro_quantum_rad),
                                            (dv, [c.dv for c in raw_chunks], PARKED_ERRORS.acc_quantum_mps)):
        error = np.cumsum(quantised, axis=0) - np.cumsum(np.concatenate(unquantised), axis=0)
        assert 0.4 * quantum < np.abs(error).max() <= 0.5 * quantum + 1e-12
    assert PARKED_ERRORS.only("gyro-noise").gyro_quantum_rad == PARKED_ERRORS.gyro_quantum_rad
    assert PARKED_ERRORS.only("systematic").acc_quantum_mps == 0.0


def test_each_seed_draws_its_own_car_the_same_every_time():
    scenario = get_scenario("parked")
    one, again, other = scenario.for_seed(3), scenario.for_seed(3), scenario.for_seed(4)
    assert one.motion == again.motion == parked_motion(3) and one.motion != other.motion
    assert one.motion.heading.centre != other.motion.heading.centre
    assert one.for_seed(3) == one and one.motion_for_seed is None and not one.random_bias_signs   # drawn once
    signs = {tuple(np.sign(scenario.for_seed(seed).errors.acc_bias_ms2)) for seed in range(6)}
    assert len(signs) > 1                                                        # bias signs drawn per seed
    assert np.abs(one.errors.acc_bias_ms2) == pytest.approx(np.abs(scenario.errors.acc_bias_ms2))   # sizes not
    assert pickle.loads(pickle.dumps(scenario)) == scenario and pickle.loads(pickle.dumps(one)) == one
    assert get_scenario("parked-nodatasheet").for_seed(3).motion == one.motion      # the same data


@pytest.mark.parametrize("name, stated", [("parked", (0.01, 0.0005, 50.0, 5.0)),
                                          ("parked-tactical", (1.0, 0.05, 300.0, 50.0)),
                                          ("parked-nodatasheet", None)])
def test_the_parked_logs_state_their_datasheet_or_none(tmp_path, name, stated):
    files = write_simulation(replace(get_scenario(name), duration_s=2.0), 0, tmp_path)
    header = open_imu_log(files.imu_csv).header
    assert header.lat_deg == pytest.approx(34.0) and header.rate_hz == 100.0
    if stated is None:
        assert not any(key in header.values for key in DATASHEET_KEYS) and header.datasheet() == {}
        assert get_scenario(name).stated_datasheet() is None and "sensor" not in daemon_sections(get_scenario(name))
    else:
        assert [header.datasheet()[key] for key in DATASHEET_KEYS] == pytest.approx(stated, rel=1e-9)
    # the actual sensor is the same RLG in every variant
    assert max(abs(float(v)) for v in str(header.values["sim_gyro_bias_deg_h"]).split()) == pytest.approx(0.01)


def test_drive_away_reaches_30_mps_at_90_s_and_keeps_it():
    scenario = get_scenario("swing-drive-away")
    motion, swing = scenario.motion, get_scenario("seed000-swing").motion
    t = np.array([0.0, 59.0, 60.0, 75.0, 90.0, 150.0, 200.0])
    speed, accel = motion.speed_and_accel(t)
    assert speed == pytest.approx([0.0, 0.0, 0.0, 15.0, 30.0, 30.0, 30.0], abs=1e-12)
    assert accel == pytest.approx([0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0], abs=1e-12)
    C_b_n, _, f_b = motion.body_rate_and_force(scenario.site, t)
    f_n = (C_b_n @ f_b[..., None])[..., 0] - [0.0, 0.0, scenario.site.gravity]
    assert f_n == pytest.approx(accel[:, None] * [0.0, 1.0, 0.0], abs=1e-12)   # north
    assert np.array_equal(motion.attitude(t), swing.attitude(t)) and scenario.duration_s == 200.0


def test_drive_stop_moves_the_base_50_m_and_parks_it():
    scenario = get_scenario("swing-drive-stop")
    t = np.linspace(0.0, 300.0, 300_001)
    speed = scenario.motion.speed_and_accel(t)[0]
    distance = np.concatenate(([0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))))
    assert distance[t >= 80.0] == pytest.approx(50.0, abs=1e-6) and distance[t <= 60.0].max() == 0.0
    assert speed.max() == pytest.approx(5.0) and np.abs(speed[t >= 80.0]).max() < 1e-12
    assert scenario.duration_s == 300.0


def _legacy_simulate(scenario, seed, chunk_samples):
    """simulate() as it was before quantisation: the reference the scenarios that existed must still give."""
    e, dt = scenario.errors, 1.0 / scenario.rate_hz
    rng = np.random.default_rng(seed)
    gyro_std, acc_std = e.increment_noise_std(dt)
    n_total = round(scenario.duration_s * scenario.rate_hz)
    for first in range(0, n_total, chunk_samples):
        k = np.arange(first, min(first + chunk_samples, n_total), dtype=float)
        dtheta, dv = true_increments(scenario.motion, scenario.site, k * dt, dt)
        n = len(k)
        yield (dtheta @ (np.eye(3) + np.diag(e.gyro_scale) + np.asarray(e.gyro_misalignment)).T
               + np.asarray(e.gyro_bias_rad_s) * dt + gyro_std * rng.standard_normal((n, 3)),
               dv @ (np.eye(3) + np.diag(e.acc_scale) + np.asarray(e.acc_misalignment)).T
               + np.asarray(e.acc_bias_ms2) * dt + acc_std * rng.standard_normal((n, 3)))


@pytest.mark.parametrize("name", ["seed000-swing", "seed000-turntable"])
def test_the_existing_scenarios_give_the_same_bits(name):
    scenario = replace(get_scenario(name), duration_s=5.0)
    assert scenario.for_seed(2) is scenario                     # nothing drawn per seed
    new = list(simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, 5.0, 2, chunk_samples=300))
    for chunk, (dtheta, dv) in zip(new, _legacy_simulate(scenario, 2, 300), strict=True):
        assert np.array_equal(chunk.dtheta, dtheta) and np.array_equal(chunk.dv, dv)

"""The vehicle simulator (aided modes) against the exact inertial-frame identity (docs/algorithms/odometer.md,
"The identity").

GIVEN a drive with turns and speed changes over the WGS-84 Earth, WHEN its exact increments go
through the strapdown integrator, THEN C_b^n(0) α(t) = β(t) holds, with
α = ∫ C_b^{b0} f^b dt − C_b^{b0} V^b(t) + V^b(0) and β = ∫ C_n^{n0} (−g^n + ω_ie^n × V^n) dt,
where C_{n(t)}^{n0} = C_e^n(0) R_z(Ω t) C_n^e(t) comes from the positions alone. Any error in
the body rates, specific force, transport rate, Coriolis or gravity of the simulator breaks it.
"""
import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG, cross, dcm_from_quat
from sinsalign.service.align.earth import OMEGA_IE, Site, normal_gravity
from sinsalign.service.align.strapdown import InertialIntegrator
from sinsalign.tools.sim.imu import true_increments
from sinsalign.tools.sim.motion import AngleProfile, AngularMotion, Sinusoid
from sinsalign.tools.sim.vehicle import VehicleMotion

RATE = 100.0


def drive(speed_mps: float) -> VehicleMotion:
    return VehicleMotion(
        Site(45.68 * DEG, 126.6 * DEG, 100.0), 120.0,
        AngularMotion(AngleProfile(30 * DEG, steps=((30.0, 120 * DEG), (70.0, 60 * DEG))),
                      AngleProfile(0.0, (Sinusoid(0.5 * DEG, 0.1),)),
                      AngleProfile(0.0, (Sinusoid(1.0 * DEG, 0.2),))),
        AngleProfile(speed_mps, steps=((40.0, 1.5 * speed_mps),), transition_s=10.0))


def C_n_e(lat, lon):
    """Columns E, N, U of the local frame in ECEF axes."""
    sL, cL, sl, cl = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    return np.stack((np.stack((-sl, cl, np.zeros_like(sl)), -1),
                     np.stack((-sL * cl, -sL * sl, cL), -1),
                     np.stack((cL * cl, cL * sl, sL), -1)), axis=-1)


def C_n_n0(motion: VehicleMotion, t: np.ndarray) -> np.ndarray:
    lat, lon, _ = np.moveaxis(motion.position(t), -1, 0)
    a = OMEGA_IE * t
    Rz = np.zeros((*t.shape, 3, 3))
    Rz[..., 0, 0], Rz[..., 0, 1], Rz[..., 1, 0], Rz[..., 1, 1], Rz[..., 2, 2] = \
        np.cos(a), -np.sin(a), np.sin(a), np.cos(a), 1.0
    start = motion.position(np.zeros(1))[0]
    return C_n_e(start[0], start[1]).T @ Rz @ C_n_e(lat, lon)


@pytest.mark.parametrize("speed", [20.0, 80.0])
def test_vehicle_increments_satisfy_the_inertial_frame_identity(speed):
    motion = drive(speed)
    dt = 1.0 / RATE
    t_end = np.arange(1, int(120 * RATE) + 1) * dt
    dtheta, dv = true_increments(motion, motion.start, t_end - dt, dt)
    q_b_b0, alpha_f = InertialIntegrator().integrate(dtheta, dv)
    # β by Gauss-Legendre quadrature over each sample interval
    x, w = np.polynomial.legendre.leggauss(5)
    tau = (t_end - dt)[:, None] + 0.5 * dt * (x + 1.0)[None, :]
    lat, _, h = np.moveaxis(motion.position(tau), -1, 0)
    V_n = motion.velocity_n(tau)[2]
    g_n = np.stack((np.zeros_like(lat), np.zeros_like(lat), -normal_gravity(lat, h)), -1)
    omega_ie_n = OMEGA_IE * np.stack((np.zeros_like(lat), np.cos(lat), np.sin(lat)), -1)
    integrand = (C_n_n0(motion, tau) @ (-g_n + cross(omega_ie_n, V_n))[..., None])[..., 0]
    beta = np.cumsum((integrand * (0.5 * dt * w)[None, :, None]).sum(axis=1), axis=0)
    V_b = motion.velocity_n(t_end)[1]
    V_b0 = motion.velocity_n(np.zeros(1))[1][0]
    alpha = alpha_f - (dcm_from_quat(q_b_b0) @ V_b[..., None])[..., 0] + V_b0
    residual = (motion.attitude(np.zeros(1))[0] @ alpha.T).T - beta
    assert np.abs(residual).max() < 1e-4    # m/s, against |β| ≈ 1200 m/s at 120 s
    assert abs(motion.position(np.array([120.0]))[0, 0] - motion.start.lat) > 1e-5   # it did drive


def test_odometer_measures_the_lever_arm_point_and_writes_the_pinned_log(tmp_path):
    from sinsalign.protocol.aiding_log import open_aiding_log
    from sinsalign.tools.sim.aiding import body_velocity, write_body_velocity_log
    motion = drive(20.0)
    t = np.arange(1, 12001) * 0.01
    ideal = body_velocity(motion, t)
    assert np.abs(ideal - motion.velocity_n(t)[1]).max() < 1e-12
    lever = np.array([0.0, 2.0, -1.0])
    with_lever = body_velocity(motion, t, lever, scale=np.array([0.0, 0.01, 0.0]))
    # the first turn (90° in 10 s) swings the 2-m forward lever sideways at up to 0.5 m/s; before it only
    # the 1° roll at 0.2 Hz moves the 1-m vertical lever (0.022 m/s)
    turning = (t > 30.0) & (t < 40.0)
    assert np.abs(with_lever[turning, 0]).max() > 0.3 and np.abs(with_lever[t < 25.0, 0]).max() < 0.03
    assert with_lever[t < 25.0, 1] == pytest.approx(20.0 * 1.01, abs=0.01)   # pitch rate × lever: 6 mm/s
    noisy = body_velocity(motion, t, noise_std_mps=0.03, rng=np.random.default_rng(0))
    assert np.std(noisy - ideal) == pytest.approx(0.03, rel=0.05)
    log = open_aiding_log("odo", write_body_velocity_log(tmp_path / "odo.csv", t, noisy, 0.03))
    assert log.stated() == {"vel_std_mps": 0.03}
    assert np.array_equal(np.concatenate(list(log.blocks()))[:, 1:], noisy)


def window_of(motion: VehicleMotion, noise_mps: float = 0.0, seed: int = 0):
    from sinsalign.service.align.velocity_aided import VelocityWindow
    from sinsalign.tools.sim.aiding import body_velocity
    dt = 1.0 / RATE
    t = np.arange(1, int(120 * RATE) + 1) * dt
    q_b_b0, alpha_f = InertialIntegrator().integrate(*true_increments(motion, motion.start, t - dt, dt))
    epochs = np.arange(9, len(t), 10)            # 10 Hz
    rng = np.random.default_rng(seed)
    V_b = body_velocity(motion, t[epochs], noise_std_mps=noise_mps, rng=rng)
    V_b0 = body_velocity(motion, np.zeros(1), noise_std_mps=noise_mps, rng=rng)[0]
    return VelocityWindow(t[epochs], alpha_f[epochs], dcm_from_quat(q_b_b0[epochs]), V_b, V_b0)


@pytest.mark.parametrize("speed", [20.0, 80.0])
def test_multistage_velocity_aided_alignment_is_exact_where_the_traditional_model_is_not(speed):
    from sinsalign.service.align.conventions import misalignment
    from sinsalign.service.align.velocity_aided import multistage_alignment
    motion = drive(speed)
    levels = multistage_alignment(window_of(motion), motion.start, levels=10)
    truth = motion.attitude(np.zeros(1))[0]
    heading = [abs(misalignment(C, truth)[2]) / DEG for C in levels]
    assert heading[-1] < 0.01                      # the issue asks < 0.01° noise-free at 80 m/s
    assert heading[0] > 0.1                        # level 1 (traditional V^b model) is off by tenths
    assert heading[3] < heading[1] < heading[0]    # each level improves on the last


def test_the_centred_solver_survives_a_noisy_first_aiding_sample():
    from sinsalign.service.align.conventions import misalignment
    from sinsalign.service.align.velocity_aided import multistage_alignment
    motion = drive(80.0)
    window = window_of(motion, noise_mps=0.03, seed=1)
    truth = motion.attitude(np.zeros(1))[0]
    centred = abs(misalignment(multistage_alignment(window, motion.start, 10, "centred")[-1], truth)[2]) / DEG
    plain = abs(misalignment(multistage_alignment(window, motion.start, 10, "qmethod")[-1], truth)[2]) / DEG
    assert centred < 0.2 < 1.0 < plain

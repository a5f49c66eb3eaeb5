"""The compass loops' compiled control step against the numpy arithmetic it replaces (service/align/_compass.pyx).

GIVEN a fixed base's step increments (gravity in the b0 axes, a small tilt and heading error, sensor noise) over
the default gain schedule (levelling, the azimuth loop taking the north channel over at 30 s, the gains
interpolated to their final values) and stored-data passes in reverse time, WHEN the compiled step and the numpy
step it stands for run them side by side, THEN the platform attitude agrees to 1e-10 rad, the velocity to 1e-11
m/s, the integrators and the azimuth command to 1e-13 rad/s and the covariance to 1e-12 relative at every step,
and the compiled covariance is exactly symmetric. The bound: the two add the 3×3 and 8×8 products' terms in
different orders (index order against numpy's BLAS), a few units of the last place per step (1e-16 of a 1-m/s
increment in the velocity); the level loops' damping holds those apart, but the azimuth loop reads the heading
through the Earth's rate, so a difference of rounding in the east rate is one of heading divided by Ω cos L
(measured 9e-13 rad after 400 s).
"""
from __future__ import annotations

import numpy as np
from sinsalign.service.align._compass import transition
from sinsalign.service.align.compass import CompassLoops, CompassState, rotation_matrix
from sinsalign.service.align.conventions import dcm_from_euler
from sinsalign.service.config import CompassConfig
from support.compass_loops import SITE, default_loops

DT_S = 0.1
ATTITUDE_BOUND_RAD = 1e-10
VELOCITY_BOUND_MPS = 1e-11
RATE_BOUND_RAD_S = 1e-13
RELATIVE_BOUND = 1e-12
"""Module docstring: the rounding of one step is 1e-16 of a 1-m/s increment; gyrocompassing turns an east rate ε
into a heading ε / (Ω cos L), 2e4 s at this latitude, so 1e-16 rad per 0.1-s step apart holds the headings up to
2e-11 rad apart (1e-9°)."""


def numpy_platform_rate(loops: CompassLoops, state: CompassState) -> np.ndarray:
    """ω_p = s ω_ie^n + ω_c (rad/s) at the state's gains (the azimuth loop switched on first where they say so)."""
    level, azimuth = loops.gains_at(state.t_loop_s)
    if azimuth is not None and not state.azimuth_on:
        state.azimuth_on, state.I_N, state.y = True, 0.0, 0.0
    K2L = level[1]
    V_E, V_N = state.V
    if state.azimuth_on:
        omega_E = -(1.0 + azimuth[1]) * V_N / loops.radius_m
    else:
        omega_E = -(1.0 + K2L) * V_N / loops.radius_m - state.I_N
    omega_c = np.array([omega_E, (1.0 + K2L) * V_E / loops.radius_m + state.I_E, state.y])
    return state.earth_sign * loops.omega_ie_n + omega_c


def numpy_step(loops: CompassLoops, state: CompassState, dalpha_b0: np.ndarray, dt_s: float,
               advance_schedule: bool = True) -> None:
    """The control step in numpy (compass.py's module docstring), the form the kernel must match, its transition
    matrix the numpy exponential of the error model."""
    half_turn = rotation_matrix(-0.5 * dt_s * numpy_platform_rate(loops, state))
    level, azimuth = loops.gains_at(state.t_loop_s)
    K1L, _, K3L = level
    north = azimuth if state.azimuth_on else level
    V_E, V_N = state.V
    dv = half_turn @ (state.C_b0_p @ dalpha_b0)
    w_up = state.earth_sign * loops.omega_sin
    state.V = np.array([V_E + dv[0] + (2.0 * w_up * V_N - K1L * V_E) * dt_s,
                        V_N + dv[1] + (-2.0 * w_up * V_E - north[0] * V_N) * dt_s])
    state.I_E += K3L * V_E * dt_s
    if state.azimuth_on:
        state.y += (-azimuth[2] * state.y + azimuth[3] / (state.earth_sign * loops.omega_cos) * V_N) * dt_s
    else:
        state.I_N += K3L * V_N * dt_s
    C = half_turn @ (half_turn @ state.C_b0_p)
    state.C_b0_p = 1.5 * C - 0.5 * C @ C.T @ C
    F = numpy_expm(loops.error_dynamics(level, azimuth if state.azimuth_on else None, state.earth_sign) * dt_s)
    state.P = F @ state.P @ F.T + loops._process_noise(dt_s)
    if advance_schedule:
        state.t_loop_s += dt_s


def assert_close(compiled: CompassState, reference: CompassState) -> None:
    turn = compiled.C_b0_p @ reference.C_b0_p.T
    assert np.max(np.abs(turn - turn.T)) / 2.0 <= ATTITUDE_BOUND_RAD
    assert np.max(np.abs(compiled.V - reference.V)) <= VELOCITY_BOUND_MPS
    rates = np.array([compiled.I_E - reference.I_E, compiled.I_N - reference.I_N, compiled.y - reference.y])
    assert np.max(np.abs(rates)) <= RATE_BOUND_RAD_S
    assert np.max(np.abs(compiled.P - reference.P)) <= RELATIVE_BOUND * np.max(np.abs(reference.P))
    assert compiled.azimuth_on == reference.azimuth_on
    assert np.array_equal(compiled.P, compiled.P.T)


def test_the_compiled_step_is_the_numpy_step_over_a_schedule_and_reverse_passes():
    rng = np.random.default_rng(2027)
    loops, site, c = default_loops(), SITE, CompassConfig()
    C_b_n = dcm_from_euler(0.3, -0.2, 1.1)
    error = dcm_from_euler(2e-3, -1e-3, 0.02)   # tilt and heading errors the loops pull in
    compiled = loops.start(error @ C_b_n, np.eye(3), 1e-3, 0.03)
    reference = compiled.copy()
    gravity_b = C_b_n.T @ np.array([0.0, 0.0, site.gravity])
    for k in range(4000):   # 400 s: every knot of the schedule, the azimuth loop from 30 s
        dalpha = gravity_b * DT_S + rng.normal(0.0, 1e-4, 3)
        if k in (1500, 1600):   # a backward then a forward stored pass, at the gains of then
            loops.reverse(compiled)
            loops.reverse(reference)
        advance = not 1500 <= k < 1700
        loops.step(compiled, dalpha, DT_S, advance)
        numpy_step(loops, reference, dalpha, DT_S, advance)
        assert_close(compiled, reference)
        # a record's attitude between two steps: the platform turned on at the state's rate
        C_b_b0, since_s = dcm_from_euler(*rng.uniform(-3.0, 3.0, 3)), rng.uniform(0.0, DT_S)
        turned = rotation_matrix(-since_s * numpy_platform_rate(loops, compiled)) @ compiled.C_b0_p @ C_b_b0
        assert np.abs(loops.attitude(compiled, C_b_b0, since_s) - turned).max() < 8 * np.finfo(float).eps
    assert compiled.azimuth_on and compiled.t_loop_s > c.schedule_time_s[-1]


def numpy_expm(A: np.ndarray) -> np.ndarray:
    """The matrix exponential in numpy, the form the compiled one must match: scaling to a row-sum norm of at
    most 0.25, nine Taylor terms, squarings."""
    norm = float(np.abs(A).sum(axis=1).max())
    squarings = max(0, int(np.ceil(np.log2(norm / 0.25))) if norm > 0.25 else 0)
    X = A / 2.0**squarings
    E = term = np.eye(len(A))
    for k in range(1, 10):
        term = term @ X / k
        E = E + term
    for _ in range(squarings):
        E = E @ E
    return E


def test_the_compiled_transition_is_the_numpy_matrix_exponential_over_the_schedule():
    """Every step length the configuration allows (1 ms to 10 s), both time directions, levelling and the azimuth
    loop at every knot's gains: exp(A Δ) of the error model within 1e-13 of the largest entry of the numpy form
    (the products' terms summed in another order, each squaring doubling the difference: 2e-14 measured at 10 s, 3e-16
    at the default 0.1 s); a step of no length is the identity."""
    loops, c = default_loops(), CompassConfig()
    for t_loop_s in (0.0, *c.schedule_time_s, 1e4):
        level, azimuth = loops.gains_at(t_loop_s)
        for sign in (1.0, -1.0):
            for dt_s in (0.0, 1e-3, 0.1, 1.0, 10.0):
                compiled = transition(*level, azimuth is not None, *(azimuth or (0.0,) * 4), sign, loops.gravity,
                                      loops.radius_m, loops.omega_cos, loops.omega_sin, dt_s)
                reference = numpy_expm(loops.error_dynamics(level, azimuth, sign) * dt_s)
                assert np.max(np.abs(compiled - reference)) <= 1e-13 * np.max(np.abs(reference))
                assert dt_s > 0.0 or np.array_equal(compiled, np.eye(8))

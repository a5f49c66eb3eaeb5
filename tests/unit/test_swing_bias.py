"""The accelerometer bias seen through a swinging body (service/align/swing_bias.py) against simulated truth.

GIVEN a swinging or static base with a known accelerometer bias, WHEN the coarse stage fits the bias's
swing term and takes it out of α, THEN the bias and the Earth axis come out as simulated, the slow heading
transient of a swinging body is gone, the limit stays the limit, and a static base is left as it was.
"""
from dataclasses import replace

import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG, EYE3, UG_TO_MS2, cross, dcm_from_quat, skew
from sinsalign.service.align.earth import C_n_n0_fixed, earth_turn_integrals
from sinsalign.service.align.strapdown import InertialIntegrator
from sinsalign.service.align.swing_bias import N_PARAMS, RIDGE, SwingBias
from sinsalign.service.config import config_from_mapping
from sinsalign.service.pipeline import AlignmentPipeline
from sinsalign.tools.evaluate import COARSE_ONLY, run_once, window_stats
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import Scenario, get_scenario

SWING_BIAS = config_from_mapping(COARSE_ONLY)   # the fit is on by default (its figures: test_coarse_alignment)
PLAIN = config_from_mapping({"alignment": {"swing_bias": False}, **COARSE_ONLY})


def test_the_earth_turn_integrals_match_quadrature() -> None:
    lat, t = 32.0 * DEG, 300.0
    P1, P2, P3 = earth_turn_integrals(t)
    u = np.array([0.0, np.cos(lat), np.sin(lat)])
    tau = (np.arange(30000) + 0.5) * t / 30000
    quadrature = C_n_n0_fixed(lat, tau).sum(axis=0) * t / 30000
    closed = P1 * np.eye(3) + P2 * skew(u) + P3 * np.outer(u, u)
    assert np.abs(closed - quadrature).max() < 1e-9 * t


def _fitted(scenario: Scenario, seed: int):
    """The swing-bias fit after a whole run of the scenario, and the run's attitude at its start."""
    pipeline = AlignmentPipeline(SWING_BIAS, scenario.site, scenario.rate_hz, scenario.grade.datasheet())
    for chunk in simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, scenario.duration_s,
                          seed):
        pipeline.process(chunk.t, chunk.dtheta, chunk.dv)
    return pipeline.coarse.swing_bias, scenario.motion.attitude(np.array([0.0]))[0]


def test_on_a_swinging_base_the_bias_and_the_earth_axis_come_out_as_simulated() -> None:
    scenario = get_scenario("seed000-swing")
    fit, C_b_n0 = _fitted(scenario, 3)
    nabla_ug = fit.nabla / UG_TO_MS2
    assert np.abs(nabla_ug - np.asarray(scenario.errors.acc_bias_ms2) / UG_TO_MS2).max() < 5.0   # of 50 µg
    w_true = C_b_n0.T @ np.array([0.0, np.cos(scenario.site.lat), np.sin(scenario.site.lat)])
    assert np.degrees(np.arccos(np.clip(fit.earth_axis_b0() @ w_true, -1.0, 1.0))) < 0.5


def test_on_a_static_base_the_data_say_nothing_of_the_bias_and_nothing_changes() -> None:
    scenario = replace(get_scenario("static"), duration_s=200.0)
    fit, _ = _fitted(scenario, 1)
    assert np.abs(fit.nabla / UG_TO_MS2).max() < 5.0    # the prior's 0, not the simulated 50 µg
    with_fit, plain = run_once(scenario, 1, SWING_BIAS), run_once(scenario, 1, PLAIN)
    assert np.abs(with_fit.phi_deg - plain.phi_deg)[with_fit.t >= 30].max() < 2e-4


def test_the_slow_heading_transient_of_a_swinging_bias_is_gone_and_the_limit_stays() -> None:
    """Biases alone (no noise), seed-000 swing: without the fit the heading is still 0.0015° (STD) on the move
    between 101 and 200 s and 0.0033° above the limit; with it, it sits on the limit."""
    scenario = get_scenario("seed000-swing")
    scenario = replace(scenario, errors=scenario.errors.only("systematic"))
    plain, fitted = (window_stats([run_once(scenario, 0, c)], (101.0, 200.0)) for c in (PLAIN, SWING_BIAS))
    assert plain.heading_inwindow_std > 0.001 and plain.heading_mean > 0.002
    assert fitted.heading_inwindow_std < 2e-4 and abs(fitted.heading_mean) < 5e-4
    assert abs(fitted.level_east_mean) < 1e-4 and abs(fitted.level_north_mean) < 5e-4


@pytest.mark.parametrize("scale", [0.0, 1e-300])
def test_degenerate_data_leave_alpha_finite_and_unchanged_where_the_fit_says_nothing(scale: float) -> None:
    """No specific force at all (a log of zeros), or next to none (1e-300 m/s): the Earth axis is undefined,
    the fit takes nothing out of α, and nothing warns (a replay of such a log stopped in the eigen-solve)."""
    import warnings
    fit = SwingBias(0.55, 50 * UG_TO_MS2, 3.5e-5)
    elapsed = 0.1 * np.arange(1, 31)
    alpha = scale * np.ones((30, 3))
    q = np.tile([1.0, 0.0, 0.0, 0.0], (30, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        corrected = np.concatenate([fit.correct(elapsed[k:k + 10], alpha[k:k + 10], q[k:k + 10])
                                    for k in range(0, 30, 10)])
    assert np.isfinite(corrected).all()
    if scale == 0.0:
        assert (corrected == 0.0).all() and fit.earth_axis_b0() is None


class _NumpySwingBias(SwingBias):
    """SwingBias.correct in its numpy form (the module docstring's algorithm, vectorised over the observations):
    the oracle of the compiled sums and correction."""

    def correct(self, elapsed_s, alpha, q_b_b0):
        if len(elapsed_s) == 0:
            return alpha.copy()
        C = dcm_from_quat(q_b_b0)
        basis = earth_turn_integrals(elapsed_s)
        t_last, basis_last, alpha_last, C_last, M_last = self._last
        dt = np.diff(elapsed_s, prepend=t_last)
        dM = 0.5 * dt[:, None, None] * (np.concatenate((C_last[None], C[:-1])) + C)
        M = np.cumsum(np.concatenate((M_last[None], dM)), axis=0)[1:]
        step = np.diff(basis, axis=0, prepend=basis_last[None])
        X = np.concatenate((step[:, None, :, None] * EYE3[None, :, None, :], dM[:, :, None, :]),
                           axis=2).reshape(-1, 3, N_PARAMS)
        dalpha = np.diff(alpha, axis=0, prepend=alpha_last[None])
        weight = 1.0 / np.maximum(self._vrw2 * dt, 1e-300)
        XtX = sum(X[:, r, :, None] * X[:, r, None, :] for r in range(3))
        Xtz = sum(X[:, r, :] * dalpha[:, r, None] for r in range(3))
        normal = np.cumsum(np.concatenate((self.normal[None], weight[:, None, None] * XtX)), axis=0)[1:]
        rhs = np.cumsum(np.concatenate((self.rhs[None], weight[:, None] * Xtz)), axis=0)[1:]
        self.normal, self.rhs = normal[-1], rhs[-1]
        self._last = (float(elapsed_s[-1]), basis[-1], alpha[-1].copy(), C[-1], M[-1])
        scale = 1.0 / np.sqrt(np.maximum(np.diagonal(normal, axis1=1, axis2=2), 1e-300))
        scaled = normal * scale[:, :, None] * scale[:, None, :] + RIDGE * np.eye(N_PARAMS)
        params = scale * np.linalg.solve(scaled, (scale * rhs)[:, :, None])[:, :, 0]
        self.params = params[-1]
        b, c, nabla = params[:, 0:3], params[:, 3:6], params[:, 9:]
        b2 = np.sum(b * b, axis=-1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            along = self._lat_sign * np.sqrt(np.maximum(0.0, 1.0 - np.sum(c * c, axis=-1, keepdims=True) / b2))
            w = cross(b, c) / b2 + along * b / np.sqrt(b2)
            w = w / np.sqrt(np.sum(w * w, axis=-1, keepdims=True))
        w = np.where(np.isfinite(w).all(axis=-1, keepdims=True), w, 0.0)
        n0, n1, n2 = nabla[:, 0, None], nabla[:, 1, None], nabla[:, 2, None]
        along = w[:, 0, None] * n0 + w[:, 1, None] * n1 + w[:, 2, None] * n2
        static = basis[:, 0, None] * nabla + basis[:, 1, None] * cross(w, nabla) + basis[:, 2, None] * (along * w)
        return alpha - (M[:, :, 0] * n0 + M[:, :, 1] * n1 + M[:, :, 2] * n2 - static)


@pytest.mark.parametrize("group", [1, 3, 10])
def test_the_compiled_fit_is_the_numpy_form_to_the_bit(group: int) -> None:
    """The swinging run's observations (and a start from nothing, zeros included), fed in groups: the compiled sums
    and correction give every α, the fit's state and the Earth axis to the bit of the numpy form."""
    scenario = get_scenario("seed000-swing")
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, 200.0, 60.0, 2, chunk_samples=12000)
    integrator = InertialIntegrator()
    q, alpha = integrator.integrate(chunk.dtheta, chunk.dv)
    due = np.arange(19, 12000, 20)
    elapsed = chunk.t[due] - (chunk.t[0] - 1 / 200.0)
    compiled, oracle = (cls(scenario.site.lat, 50 * UG_TO_MS2, 3.5e-5) for cls in (SwingBias, _NumpySwingBias))
    for k in range(0, len(due), group):
        pick = due[k:k + group]
        alpha_k = alpha[pick] if k else np.zeros((len(pick), 3))
        assert np.array_equal(compiled.correct(elapsed[k:k + group], alpha_k, q[pick]),
                              oracle.correct(elapsed[k:k + group], alpha_k, q[pick]))
    assert np.array_equal(compiled.normal, oracle.normal) and np.array_equal(compiled.rhs, oracle.rhs)
    assert np.array_equal(compiled.params, oracle.params)
    assert all(np.array_equal(a, b) for a, b in zip(compiled._last, oracle._last, strict=True))
    assert np.array_equal(compiled.earth_axis_b0(), oracle.earth_axis_b0())

"""WGS-84 model and the closed-form n0-frame gravity integral β(t)."""
import itertools

import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG
from sinsalign.service.align.earth import OMEGA_IE, C_n_n0_fixed, beta_fixed, earth_rate_n, normal_gravity, radii


def test_normal_gravity_reference_values():
    assert normal_gravity(0.0) == pytest.approx(9.7803253359, abs=1e-9)
    assert normal_gravity(90 * DEG) == pytest.approx(9.8321849379, abs=1e-9)
    assert normal_gravity(45 * DEG, 1000.0) == pytest.approx(normal_gravity(45 * DEG) - 3.086e-3, abs=2e-5)


def test_radii_at_equator_and_pole():
    R_M, R_N = radii(0.0)
    assert pytest.approx(6378137.0) == R_N
    assert pytest.approx(6335439.327, abs=1e-3) == R_M
    R_M, R_N = radii(90 * DEG)
    assert pytest.approx(R_N) == R_M


def test_navigation_frame_turns_about_the_earth_axis():
    lat = 32 * DEG
    C = C_n_n0_fixed(lat, np.array(3600.0))
    np.testing.assert_allclose(C @ earth_rate_n(lat), earth_rate_n(lat), atol=1e-18)   # the axis stays put
    up_now = C @ [0, 0, 1]
    assert up_now[0] > 0   # local up has moved east in inertial space
    assert np.arccos(up_now[2]) == pytest.approx(np.cos(lat) * OMEGA_IE * 3600, rel=1e-3)


@pytest.mark.parametrize("t", [0.01, 1.0, 200.0, 5000.0, 86400.0])
def test_beta_matches_quadrature(t):
    lat, g = 32 * DEG, 9.7949
    x, w = np.polynomial.legendre.leggauss(40)
    edges = np.linspace(0.0, t, 65)
    total = np.zeros(3)
    for a, b in itertools.pairwise(edges):
        tau = 0.5 * (b - a) * (x + 1) + a
        total += ((C_n_n0_fixed(lat, tau) @ [0, 0, g]) * (0.5 * (b - a) * w)[:, None]).sum(axis=0)
    np.testing.assert_allclose(beta_fixed(lat, g, np.array(t)), total, rtol=1e-12, atol=1e-12 * g * t)

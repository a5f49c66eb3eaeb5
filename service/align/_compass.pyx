# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The compass loops compiled (built at install; docs/performance.md): the control step, a stretch of steps at
held gains, and the transition matrix of the loops' error model.

One step does what :meth:`service.align.compass.CompassLoops.step` describes for one step of Δ seconds: the commanded
rate from the state at the step's start, the platform turned by half the step either side of the velocity update,
the level integrators or the azimuth command, the first-order re-orthonormalisation, and the covariance
P ← F P Fᵀ + Q. :func:`compass_steps` loops that step over a stored-data pass's stretch; :func:`transition` builds
the error model A and gives exp(A Δ). Elementwise formulas are numpy's (the same libm sin, cos and pow, no fused
multiply-adds: compiled with -ffp-contract=off); the 3×3 and 8×8 products add their terms in index order where numpy's
BLAS may add them in another, so the state agrees with the numpy arithmetic to the last few bits
(tests/unit/test_compass_kernel.py, tests/unit/test_stored_passes.py). P is made exactly symmetric: its upper
triangle is computed and mirrored.

Frames and units as in compass.py: C_{b0}^{p} (3, 3), V^p (E, N) m/s, rates rad/s, Δα m/s in b0 axes.
"""
from libc.math cimport M_PI, ceil, cos, fabs, log2, pow, sin, sqrt

import numpy as np


include "_platform.pxi"
include "_compass_core.pxi"
include "_policy.pxi"


def compass_step(double[:, ::1] C_b0_p, double[::1] V, double I_E, double I_N, double y,
                 const double[::1] dalpha_b0, double dt_s, double K1L, double K2L, double K3L, bint azimuth_on,
                 double K1A, double K2A, double K3A, double K4A, double earth_sign, const double[::1] omega_ie_n,
                 double omega_cos, double omega_sin, double radius_m, const double[:, ::1] F,
                 const double[:, ::1] Q, double[:, ::1] P):
    """One control step (module docstring): ``C_b0_p``, ``V`` and ``P`` updated in place; returns the new
    (I_E, I_N, y). The azimuth gains K1A..K4A are read only with ``azimuth_on``."""
    _step(&C_b0_p[0, 0], &V[0], &I_E, &I_N, &y, &dalpha_b0[0], dt_s, K1L, K2L, K3L, azimuth_on, K1A, K2A, K3A, K4A,
          earth_sign, &omega_ie_n[0], omega_cos, omega_sin, radius_m, &F[0, 0], &Q[0, 0], &P[0, 0])
    return I_E, I_N, y


def platform_attitude(const double[:, ::1] C_b0_p, const double[::1] V, double I_E, double I_N, double y,
                      bint azimuth_on, double K2L, double K2A, double earth_sign, const double[::1] omega_ie_n,
                      double radius_m, double since_step_s, const double[:, ::1] C_b_b0):
    """C_b^n (3, 3) = exp(−[ω_p t ×]) C_{b0}^{p} C_{b}^{b0}: the loops' attitude ``since_step_s`` (t) after their last
    step, the platform turned on at the rate the state commands, ω_p = s ω_ie^n + ω_c (CompassLoops.attitude; the
    azimuth gain K2A read only with ``azimuth_on``). The products add their terms in index order where numpy's BLAS
    may not, and sin and cos are the C library's: within a few units of the last place of the numpy form."""
    out = np.empty((3, 3))
    cdef double[:, ::1] o = out
    _platform_attitude(&C_b0_p[0, 0], &V[0], I_E, I_N, y, azimuth_on, K2L, K2A, earth_sign, &omega_ie_n[0],
                       radius_m, since_step_s, &C_b_b0[0, 0], &o[0, 0])
    return out


def compass_steps(double[:, ::1] C_b0_p, double[::1] V, double I_E, double I_N, double y,
                  const double[:, ::1] dalpha_b0, const double[::1] dt_s, double K1L, double K2L, double K3L,
                  bint azimuth_on, double K1A, double K2A, double K3A, double K4A, double earth_sign,
                  const double[::1] omega_ie_n, double omega_cos, double omega_sin, double radius_m,
                  const double[:, :, ::1] F, const double[:, :, ::1] Q, const Py_ssize_t[::1] which,
                  double[:, ::1] P):
    """:func:`compass_step` over N steps at fixed gains (Δα (N, 3), Δ (N,)), step k with ``F[which[k]]`` and
    ``Q[which[k]]``: the same arithmetic in the same order as N calls; returns the new (I_E, I_N, y)."""
    cdef Py_ssize_t k, n = dt_s.shape[0], m
    if dalpha_b0.shape[0] != n or dalpha_b0.shape[1] != 3 or which.shape[0] != n:
        raise ValueError("compass_steps: dalpha_b0 (N, 3), dt_s (N,) and which (N,): one row per step")
    if F.shape[0] != Q.shape[0] or F.shape[1] != 8 or F.shape[2] != 8 or Q.shape[1] != 8 or Q.shape[2] != 8 \
            or P.shape[0] != 8 or P.shape[1] != 8 or C_b0_p.shape[0] != 3 or C_b0_p.shape[1] != 3 or V.shape[0] != 2:
        raise ValueError("compass_steps: F and Q (K, 8, 8), P (8, 8), C_b0_p (3, 3), V (2,)")
    for k in range(n):   # every index checked before the state moves
        if which[k] < 0 or which[k] >= F.shape[0]:
            raise IndexError("compass_steps: which names no transition")
    for k in range(n):
        m = which[k]
        _step(&C_b0_p[0, 0], &V[0], &I_E, &I_N, &y, &dalpha_b0[k, 0], dt_s[k], K1L, K2L, K3L, azimuth_on, K1A, K2A,
              K3A, K4A, earth_sign, &omega_ie_n[0], omega_cos, omega_sin, radius_m, &F[m, 0, 0], &Q[m, 0, 0],
              &P[0, 0])
    return I_E, I_N, y


def transition(double K1L, double K2L, double K3L, bint azimuth_on, double K1A, double K2A, double K3A, double K4A,
               double earth_sign, double gravity, double radius_m, double omega_cos, double omega_sin, double dt_s):
    """F = exp(A Δ) (8, 8) of the loops' linear error model over a step of Δ seconds (:func:`_transition`)."""
    F_out = np.empty((8, 8))
    cdef double[:, ::1] F = F_out
    _transition(K1L, K2L, K3L, azimuth_on, K1A, K2A, K3A, K4A, earth_sign, gravity, radius_m, omega_cos, omega_sin,
                dt_s, &F[0, 0])
    return F_out


def schedule_sigma(const double[::1] knots, const double[::1] values, double t) -> float:
    """The gain schedule's σ at loop time ``t`` s (_policy.pxi ``_geometric``: the rule the compiled block loop
    applies), of ``values`` at ``knots`` (same length, increasing from 0)."""
    return _geometric(&knots[0], &values[0], knots.shape[0], t)


def level_gains(double sigma, double gravity, double radius_m) -> tuple:
    """(K1, K2, K3) of the third-order level loop with poles −σ, −σ ± jσ (_policy.pxi: the compiled loop's rule)."""
    cdef double K[3]
    _level_gains(sigma, gravity, radius_m, K)
    return K[0], K[1], K[2]


def azimuth_gains(double sigma, double gravity, double radius_m) -> tuple:
    """(K1, K2, K3, K4) of the fourth-order azimuth loop with double poles −σ ± jσ (_policy.pxi)."""
    cdef double K[4]
    _azimuth_gains(sigma, gravity, radius_m, K)
    return K[0], K[1], K[2], K[3]


def process_noise(double vrw2, double arw2, double dt_s):
    """Q (8, 8) of one step of the compass loops (_policy.pxi ``_process_noise``: the compiled loop's rule)."""
    out = np.zeros((8, 8))
    cdef double[:, ::1] Q = out
    _process_noise(vrw2, arw2, dt_s, &Q[0, 0])
    return out

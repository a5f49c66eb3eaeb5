"""Exact IMU increments of a simulated motion, with seeded sensor errors.

Δθ_k = ∫ ω_ib^b dt and Δv_k = ∫ f^b dt over (t_{k-1}, t_k] are integrated by Gauss-Legendre
quadrature of the analytic body rate and specific force: the integrands are smooth and slow
against the sample interval, so a few nodes reach double precision.
The motion supplies ω_ib^b and f^b (motion.py for a base fixed in position, vehicle.py for a
vehicle that drives).
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np
from sinsalign.service.align.earth import Site

from .motion import AngularMotion
from .vehicle import VehicleMotion

GAUSS_NODES = 5
ERROR_SOURCES: dict[str, tuple[str, tuple[str, ...]]] = {
    "systematic": ("biases, scale factors, axis misalignments",
                   ("gyro_bias_rad_s", "acc_bias_ms2", "gyro_scale", "acc_scale", "gyro_misalignment",
                    "acc_misalignment")),
    "acc-noise": ("accelerometer noise", ("acc_noise_ms2", "acc_vrw_ms_rts", "acc_quantum_mps")),
    "gyro-noise": ("gyro noise", ("gyro_noise_rad_s", "gyro_arw_rad_rts", "gyro_quantum_rad"))}
"""The IMU's error sources for an error budget: name → (label, the :class:`ImuErrors` fields it holds); the
quantisation of the increments counts with each sensor's noise."""


@dataclass(frozen=True, slots=True)
class ImuErrors:
    """Sensor errors in SI units, body axes. Noise is white: per-sample std and/or density.

    gyro_bias_rad_s, acc_bias_ms2 : (3,) constant biases.
    gyro_noise_rad_s : std of the rate noise of each sample (the paper's "°/h per sample").
    gyro_arw_rad_rts : angle random walk density (rad/√s). Both noise forms add.
    acc_noise_ms2, acc_vrw_ms_rts : the accelerometer's equivalents (m/s², m/s/√s).
    gyro_scale, acc_scale : (3,) scale-factor errors (dimensionless, 1e-6 = 1 ppm).
    gyro_misalignment, acc_misalignment : (3, 3) small-angle axis misalignment (rad), zero diagonal.
    gyro_quantum_rad, acc_quantum_mps : one count of the output increments (rad, m/s), 0: not quantised
        (see :class:`Accumulator`).
    """

    gyro_bias_rad_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_noise_rad_s: float = 0.0
    gyro_arw_rad_rts: float = 0.0
    acc_bias_ms2: tuple[float, float, float] = (0.0, 0.0, 0.0)
    acc_noise_ms2: float = 0.0
    acc_vrw_ms_rts: float = 0.0
    gyro_scale: tuple[float, float, float] = (0.0, 0.0, 0.0)
    acc_scale: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_misalignment: tuple[tuple[float, ...], ...] = ((0.0,) * 3,) * 3
    acc_misalignment: tuple[tuple[float, ...], ...] = ((0.0,) * 3,) * 3
    gyro_quantum_rad: float = 0.0
    acc_quantum_mps: float = 0.0

    def only(self, source: str) -> ImuErrors:
        """These errors with one source of :data:`ERROR_SOURCES` kept and the others zero. The simulator draws
        the same noise stream whatever is kept, so a seed's noise is the same with and without the biases."""
        if source not in ERROR_SOURCES:
            raise ValueError(f"error source {source!r} is not one of {', '.join(ERROR_SOURCES)}")
        return replace(ImuErrors(), **{name: getattr(self, name) for name in ERROR_SOURCES[source][1]})

    def increment_noise_std(self, dt_s: float) -> tuple[float, float]:
        """(Δθ std in rad, Δv std in m/s) of one sample of length dt_s."""
        gyro = np.hypot(self.gyro_noise_rad_s * dt_s, self.gyro_arw_rad_rts * np.sqrt(dt_s))
        acc = np.hypot(self.acc_noise_ms2 * dt_s, self.acc_vrw_ms_rts * np.sqrt(dt_s))
        return float(gyro), float(acc)


@dataclass(frozen=True, slots=True)
class ImuChunk:
    """A run of consecutive samples: times at the end of each interval and the increments."""

    t: np.ndarray            # (N,) s
    dtheta: np.ndarray       # (N, 3) rad, body axes
    dv: np.ndarray           # (N, 3) m/s, body axes
    C_b_n_true: np.ndarray   # (N, 3, 3) true attitude at t


class Accumulator:
    """A sensor's output counter: it integrates its input and emits whole counts of ``quantum`` (rad or m/s),
    carrying the remainder to the next sample, also from one chunk to the next. The integrated output differs
    from the integrated input by at most half a count (counts are rounded)."""

    def __init__(self, quantum: float) -> None:
        self.quantum = quantum
        self._sum = np.zeros(3)      # the input integrated since the start
        self._counts = np.zeros(3)   # the counts emitted since the start (the remainder: sum − counts · quantum)

    def quantise(self, increments: np.ndarray) -> np.ndarray:
        """The output increments (N, 3), whole counts times the quantum, of the next input increments (N, 3)."""
        sums = np.cumsum(np.vstack((self._sum, increments)), axis=0)[1:]   # the same sums whatever the chunks
        counts = np.rint(sums / self.quantum)
        output = (np.diff(counts, axis=0, prepend=self._counts[None, :]) + 0.0) * self.quantum   # + 0.0: no −0
        self._sum, self._counts = sums[-1], counts[-1]
        return output


def true_increments(motion: AngularMotion | VehicleMotion, site: Site, t_start: np.ndarray,
                    dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Error-free Δθ (N, 3) rad and Δv (N, 3) m/s over [t_start, t_start + dt_s]."""
    x, w = np.polynomial.legendre.leggauss(GAUSS_NODES)
    tau = t_start[:, None] + 0.5 * dt_s * (x + 1.0)[None, :]
    _, omega_ib_b, f_b = motion.body_rate_and_force(site, tau)
    weights = (0.5 * dt_s * w)[None, :, None]
    return (omega_ib_b * weights).sum(axis=1), (f_b * weights).sum(axis=1)


def simulate(motion: AngularMotion, site: Site, errors: ImuErrors, rate_hz: float, duration_s: float,
             seed: int, chunk_samples: int = 20000) -> Iterator[ImuChunk]:
    """Yield the IMU samples of ``duration_s`` seconds in chunks (bounded memory for long runs).

    Sample k (k = 1 … N) covers ((k-1)/rate, k/rate]; the noise stream depends on the seed only. With a
    quantum set, the increments (the true ones with every error) leave the sensor as whole counts.
    """
    dt = 1.0 / rate_hz
    n_total = round(duration_s * rate_hz)
    rng = np.random.default_rng(seed)
    gyro_std, acc_std = errors.increment_noise_std(dt)
    gyro_matrix = np.eye(3) + np.diag(errors.gyro_scale) + np.asarray(errors.gyro_misalignment)
    acc_matrix = np.eye(3) + np.diag(errors.acc_scale) + np.asarray(errors.acc_misalignment)
    gyro_bias_step = np.asarray(errors.gyro_bias_rad_s) * dt
    acc_bias_step = np.asarray(errors.acc_bias_ms2) * dt
    gyro_counter = Accumulator(errors.gyro_quantum_rad) if errors.gyro_quantum_rad else None
    acc_counter = Accumulator(errors.acc_quantum_mps) if errors.acc_quantum_mps else None
    for first in range(0, n_total, chunk_samples):
        k = np.arange(first, min(first + chunk_samples, n_total), dtype=float)
        t_start = k * dt
        dtheta, dv = true_increments(motion, site, t_start, dt)
        n = len(k)
        dtheta = dtheta @ gyro_matrix.T + gyro_bias_step + gyro_std * rng.standard_normal((n, 3))
        dv = dv @ acc_matrix.T + acc_bias_step + acc_std * rng.standard_normal((n, 3))
        if gyro_counter is not None:
            dtheta = gyro_counter.quantise(dtheta)
        if acc_counter is not None:
            dv = acc_counter.quantise(dv)
        t_end = (k + 1.0) * dt
        yield ImuChunk(t_end, dtheta, dv, motion.attitude(t_end))

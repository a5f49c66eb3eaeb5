"""A parked vehicle and a swinging base that is driven off: base motion that is not white and not a clean swing.

Frames and angles as motion.py: n = ENU, body = Right-Front-Up, Euler angles (heading clockwise from North,
pitch, roll; rad). Every term is analytic together with its first two time derivatives (a :data:`Jet`) and
continuous through the second derivative (a damped oscillation through every derivative), so the 5-node Gauss
quadrature of imu.py integrates it to far below any sensor's noise.

:class:`ParkedMotion`, a car parked on a site (the IMU's position fixed up to a few centimetres):

- Euler angles = base attitude + engine vibration + suspension rocking (slowly amplitude-modulated
  sinusoids) + knocks (damped oscillations) + people getting in and out (smooth tilt steps with a bounce);
- the IMU's displacement r(t) from its rest point, along the car's axes (the body axes at the base attitude,
  C_0 = C_b^n of the centres, constant): engine vibration A sin(2π f t), the sink and shift of a load with its
  bounce; bounded, and its second derivative is the acceleration, a^n = C_0 r̈;
- ω_ib^b = ω_nb^b + C_n^b ω_ie^n and f^b = C_n^b (a^n + [0, 0, g]) (AngularMotion's kinematics). The Coriolis
  term of the centimetre-per-second displacement rates (2Ω × ṙ < 1e-5 m/s²) is left out.

:func:`parked_motion` draws one seed's car: its heading, tilt, modes and events.
:class:`DrivenMotion` adds to a swinging base (AngularMotion) a drive along a fixed ENU direction.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from sinsalign.service.align.conventions import DEG, dcm_from_euler
from sinsalign.service.align.earth import Site

from .motion import AngularMotion

Jet = tuple[np.ndarray, np.ndarray, np.ndarray]
"""A signal and its first and second time derivatives at the same times."""
ONSET_S = 0.1
"""Rise time constant of a knock's envelope (s): it peaks within a few tenths of a second."""
PARKED_HORIZON_S = 1800.0
"""Span over which :func:`parked_motion` draws events (s); a longer run sees no knock nor person after it."""
KNOCKS_PER_S = 3.0 / 600.0
"""Mean rate of knocks (door slams, bumps): 3 per 10 minutes."""
PEOPLE_PER_S = 2.0 / 1800.0
"""Mean rate of people getting in (each later gets out, or stays): 2 per 30 minutes."""
PARKED_STREAM = 11
"""Seed stream of the parked car's draws, apart from the IMU noise (the seed alone), the aiding sensors' (3, 4, 6, 7)
and the bias signs (5)."""


def _product(a: Jet, b: Jet) -> Jet:
    """The jet of a·b (Leibniz rule)."""
    return a[0] * b[0], a[1] * b[0] + a[0] * b[1], a[2] * b[0] + 2.0 * a[1] * b[1] + a[0] * b[2]


def _sine(t: np.ndarray, amplitude: float, freq_hz: float, phase: float) -> Jet:
    """The jet of amplitude · sin(2π f t + phase)."""
    w = 2.0 * np.pi * freq_hz
    s, c = np.sin(w * t + phase), np.cos(w * t + phase)
    return amplitude * s, amplitude * w * c, -amplitude * w**2 * s


@dataclass(frozen=True, slots=True)
class Wave:
    """A (1 + depth sin(2π f_m t + φ_m)) sin(2π f t + φ): a sinusoid (depth 0: engine vibration) or a slowly
    amplitude-modulated one (suspension rocking). Amplitude in rad (an angle) or m (a displacement), frequencies
    in Hz, phases in rad; bounded by |A| (1 + depth)."""

    amplitude: float
    freq_hz: float
    phase: float = 0.0
    depth: float = 0.0
    mod_freq_hz: float = 0.0
    mod_phase: float = 0.0

    def jet(self, t: np.ndarray) -> Jet:
        carrier = _sine(t, self.amplitude, self.freq_hz, self.phase)
        if not self.depth:
            return carrier
        m, m_dot, m_ddot = _sine(t, self.depth, self.mod_freq_hz, self.mod_phase)
        return _product(carrier, (1.0 + m, m_dot, m_ddot))


@dataclass(frozen=True, slots=True)
class SmoothStep:
    """A change by ``delta`` (rad, m or m/s) over [t_s, t_s + duration_s] with a raised-cosine rate:
    x = (t − t_s)/T, value = delta (x − sin(2πx)/2π), rate = (delta/T)(1 − cos 2πx), peak rate 2·delta/T at
    mid-step; value, rate and second derivative are continuous."""

    t_s: float
    duration_s: float
    delta: float

    def jet(self, t: np.ndarray) -> Jet:
        x = np.clip((t - self.t_s) / self.duration_s, 0.0, 1.0)
        inside = (x > 0.0) & (x < 1.0)
        arg = 2.0 * np.pi * x
        rate = self.delta / self.duration_s
        return (self.delta * (x - np.sin(arg) / (2.0 * np.pi)), np.where(inside, rate * (1.0 - np.cos(arg)), 0.0),
                np.where(inside, rate * 2.0 * np.pi / self.duration_s * np.sin(arg), 0.0))


@dataclass(frozen=True, slots=True)
class DampedOscillation:
    """A knock or a bounce: amplitude · E(s) sin(2π f s), s = t − t_s, with the envelope
    E(s) = exp(2√(τ_on/τ) − τ_on/s − s/τ) for s > 0 and 0 before (τ_on = onset_s, τ = decay_s). E rises within a
    few τ_on to its peak 1 at s = √(τ_on τ), then decays as e^(−s/τ); every derivative is continuous at t_s, and
    the signal returns to the level before within a few τ. Amplitude in rad or m; the faster the rise, the more
    the second derivative exceeds amplitude · (2π f)² (up to ≈ 1.7× with τ_on half a period, 3-5× at 0.1 s)."""

    t_s: float
    amplitude: float
    freq_hz: float
    decay_s: float
    onset_s: float = ONSET_S

    def jet(self, t: np.ndarray) -> Jet:
        after = t > self.t_s
        s = np.where(after, t - self.t_s, 1.0)
        a, tau = self.onset_s, self.decay_s
        envelope = np.where(after, np.exp(2.0 * np.sqrt(a / tau) - a / s - s / tau), 0.0)
        log_slope = a / s**2 - 1.0 / tau
        return _product((envelope, envelope * log_slope, envelope * (log_slope**2 - 2.0 * a / s**3)),
                        _sine(s, self.amplitude, self.freq_hz, 0.0))


Term = Wave | SmoothStep | DampedOscillation


@dataclass(frozen=True, slots=True)
class Signal:
    """One coordinate of a base: an Euler angle (rad), a displacement (m) or a speed (m/s), centre + terms."""

    centre: float = 0.0
    terms: tuple[Term, ...] = ()

    def jet(self, t: np.ndarray) -> Jet:
        """Value and its first two time derivatives at times t (s)."""
        t = np.asarray(t, dtype=float)
        total = [np.full_like(t, self.centre), np.zeros_like(t), np.zeros_like(t)]
        for term in self.terms:
            for k, part in enumerate(term.jet(t)):
                total[k] += part
        return total[0], total[1], total[2]

    def value_and_rate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Value and rate at times t: the interface of motion.AngleProfile, through which AngularMotion reads it."""
        value, rate, _ = self.jet(t)
        return value, rate


def _add_accel(C_b_n: np.ndarray, f_b: np.ndarray, accel_n: np.ndarray) -> np.ndarray:
    """f^b plus a linear acceleration a^n (…, 3) of the base, m/s², turned into body axes."""
    return f_b + (np.swapaxes(C_b_n, -1, -2) @ accel_n[..., None])[..., 0]


@dataclass(frozen=True, slots=True)
class ParkedMotion:
    """A parked car: Euler angles (rad) heading, pitch, roll and the IMU's displacement (m) from its rest point
    along the car's axes right, front, up (the body axes at the centres' attitude)."""

    heading: Signal = field(default_factory=Signal)
    pitch: Signal = field(default_factory=Signal)
    roll: Signal = field(default_factory=Signal)
    right: Signal = field(default_factory=Signal)
    front: Signal = field(default_factory=Signal)
    up: Signal = field(default_factory=Signal)

    @property
    def angles(self) -> AngularMotion:
        """The attitude as an AngularMotion of the three angle signals (no drive)."""
        return AngularMotion(self.heading, self.pitch, self.roll)

    @property
    def car_axes(self) -> np.ndarray:
        """C_0 (3, 3): the car's axes (right, front, up) in ENU, C_b^n at the centres of the angles."""
        return dcm_from_euler(self.heading.centre, self.pitch.centre, self.roll.centre)

    def displacement_n(self, t: np.ndarray) -> np.ndarray:
        """The IMU's displacement from its rest point (…, 3), m ENU."""
        return self._car_to_n(t, 0)

    def accel_n(self, t: np.ndarray) -> np.ndarray:
        """The IMU's linear acceleration (…, 3), m/s² ENU: the second derivative of :meth:`displacement_n`."""
        return self._car_to_n(t, 2)

    def _car_to_n(self, t: np.ndarray, order: int) -> np.ndarray:
        car = np.stack([s.jet(t)[order] for s in (self.right, self.front, self.up)], axis=-1)
        return car @ self.car_axes.T

    def attitude(self, t: np.ndarray) -> np.ndarray:
        """C_b^n at times t, shape (…, 3, 3)."""
        return self.angles.attitude(t)

    def attitude_and_rate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """C_b^n (…, 3, 3) and ω_nb^b (…, 3, rad/s) at times t."""
        return self.angles.attitude_and_rate(t)

    def body_rate_and_force(self, site: Site, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """C_b^n (…, 3, 3), ω_ib^b (…, 3) rad/s and f^b = C_n^b (a^n + [0, 0, g]) (…, 3) m/s² at times t."""
        C_b_n, omega_ib_b, f_b = self.angles.body_rate_and_force(site, t)
        return C_b_n, omega_ib_b, _add_accel(C_b_n, f_b, self.accel_n(t))


@dataclass(frozen=True, slots=True)
class DrivenMotion:
    """A base swinging as ``base`` and driven along ``direction_n`` (ENU unit vector) at ``speed`` (m/s, a signal
    of smooth steps: each a raised-cosine acceleration pulse). f^b = C_n^b (v̇ direction_n + [0, 0, g]). As
    AngularMotion's own drive, the Coriolis and transport terms of the velocity (2Ω × V ≈ 4e-3 m/s² at 30 m/s,
    ω_en ≈ 5e-6 rad/s) and the change of position are left out: the scenarios test the detection of the drive,
    not navigation."""

    base: AngularMotion
    speed: Signal
    direction_n: tuple[float, float, float] = (0.0, 1.0, 0.0)

    def speed_and_accel(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Speed (m/s) and its rate (m/s²) along ``direction_n`` at times t."""
        speed, accel, _ = self.speed.jet(t)
        return speed, accel

    def accel_n(self, t: np.ndarray) -> np.ndarray:
        """Linear acceleration of the drive (…, 3), m/s² ENU."""
        return self.speed_and_accel(t)[1][..., None] * np.asarray(self.direction_n)

    def attitude(self, t: np.ndarray) -> np.ndarray:
        """C_b^n at times t, shape (…, 3, 3): the base's."""
        return self.base.attitude(t)

    def body_rate_and_force(self, site: Site, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """C_b^n (…, 3, 3), ω_ib^b (…, 3) rad/s and f^b (…, 3) m/s² at times t: the base's, plus the drive."""
        C_b_n, omega_ib_b, f_b = self.base.body_rate_and_force(site, t)
        return C_b_n, omega_ib_b, _add_accel(C_b_n, f_b, self.accel_n(t))


def _uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(rng.uniform(low, high))


def _engine(rng: np.random.Generator, terms: dict[str, list[Term]]) -> None:
    """Engine idling at 20–40 Hz: 1e-4–5e-4° on each angle, 0.02–0.1 m/s² along each car axis (as a displacement
    a/ω² sin ωt)."""
    freq_hz = _uniform(rng, 20.0, 40.0)
    for name in ("heading", "pitch", "roll"):
        terms[name].append(Wave(_uniform(rng, 1e-4, 5e-4) * DEG, freq_hz, _uniform(rng, 0.0, 2.0 * np.pi)))
    for name in ("right", "front", "up"):
        accel_mps2 = _uniform(rng, 0.02, 0.1)
        terms[name].append(Wave(accel_mps2 / (2.0 * np.pi * freq_hz) ** 2, freq_hz, _uniform(rng, 0.0, 2.0 * np.pi)))


def _rocking(rng: np.random.Generator, terms: dict[str, list[Term]]) -> None:
    """Two suspension modes on pitch and on roll: 0.002–0.01° at 1–3 Hz, amplitude modulated by 20–80 % over
    20–200 s."""
    for name in ("pitch", "roll"):
        for _ in range(2):
            terms[name].append(Wave(_uniform(rng, 0.002, 0.01) * DEG, _uniform(rng, 1.0, 3.0),
                                    _uniform(rng, 0.0, 2.0 * np.pi), _uniform(rng, 0.2, 0.8),
                                    _uniform(rng, 1 / 200, 1 / 20), _uniform(rng, 0.0, 2.0 * np.pi)))


def _knocks(rng: np.random.Generator, terms: dict[str, list[Term]], horizon_s: float) -> None:
    """Knocks at Poisson times: a tilt of 0.01–0.3° (log-uniform, any direction) ringing at 1.5–3 Hz, decay
    0.5–2 s."""
    for _ in range(rng.poisson(KNOCKS_PER_S * horizon_s)):
        t_s = _uniform(rng, 0.0, horizon_s)
        tilt = float(np.exp(rng.uniform(np.log(0.01), np.log(0.3)))) * DEG
        direction = _uniform(rng, 0.0, 2.0 * np.pi)
        freq_hz, decay_s = _uniform(rng, 1.5, 3.0), _uniform(rng, 0.5, 2.0)
        terms["pitch"].append(DampedOscillation(t_s, tilt * np.cos(direction), freq_hz, decay_s))
        terms["roll"].append(DampedOscillation(t_s, tilt * np.sin(direction), freq_hz, decay_s))


def _load_change(rng: np.random.Generator, terms: dict[str, list[Term]], t_s: float,
                 load: dict[str, float]) -> None:
    """One change of load at t_s: each coordinate steps by ``load[name]`` (rad or m) over 1–3 s, then the
    tilts and the height bounce by 5–15 % of their step at 1.2–1.8 Hz (decay 0.3–1 s, rising over half a period:
    at most ≈ 1 m/s² vertically)."""
    duration_s = _uniform(rng, 1.0, 3.0)
    bounce, freq_hz, decay_s = _uniform(rng, 0.05, 0.15), _uniform(rng, 1.2, 1.8), _uniform(rng, 0.3, 1.0)
    for name, delta in load.items():
        terms[name].append(SmoothStep(t_s, duration_s, delta))
        if name in ("pitch", "roll", "up"):
            terms[name].append(DampedOscillation(t_s + duration_s, bounce * delta, freq_hz, decay_s,
                                                 0.5 / freq_hz))


def _people(rng: np.random.Generator, terms: dict[str, list[Term]], horizon_s: float) -> None:
    """People getting in at Poisson times and out 1–20 min later (if within the horizon; else they stay):
    the car tilts by 0.1–0.5° (any direction), sinks 1–3 cm and shifts up to 2 cm sideways, and back."""
    for _ in range(rng.poisson(PEOPLE_PER_S * horizon_s)):
        t_in = _uniform(rng, 0.0, horizon_s)
        t_out = t_in + _uniform(rng, 60.0, 1200.0)
        tilt, direction = _uniform(rng, 0.1, 0.5) * DEG, _uniform(rng, 0.0, 2.0 * np.pi)
        shift, shift_direction = _uniform(rng, 0.0, 0.02), _uniform(rng, 0.0, 2.0 * np.pi)
        load = {"pitch": tilt * np.cos(direction), "roll": tilt * np.sin(direction), "up": -_uniform(rng, 0.01, 0.03),
                "right": shift * np.cos(shift_direction), "front": shift * np.sin(shift_direction)}
        _load_change(rng, terms, t_in, load)
        if t_out < horizon_s:
            _load_change(rng, terms, t_out, {name: -delta for name, delta in load.items()})


def parked_motion(seed: int, horizon_s: float = PARKED_HORIZON_S) -> ParkedMotion:
    """Seed ``seed``'s parked car (the same for the same seed): heading uniform over 0–360°, pitch and roll within
    ±2°, engine vibration, suspension rocking, knocks and people getting in and out over ``horizon_s``."""
    rng = np.random.default_rng([seed, PARKED_STREAM])
    centres = {"heading": _uniform(rng, 0.0, 2.0 * np.pi), "pitch": _uniform(rng, -2.0, 2.0) * DEG,
               "roll": _uniform(rng, -2.0, 2.0) * DEG}
    terms: dict[str, list[Term]] = {name: [] for name in ("heading", "pitch", "roll", "right", "front", "up")}
    _engine(rng, terms)
    _rocking(rng, terms)
    _knocks(rng, terms, horizon_s)
    _people(rng, terms, horizon_s)
    return ParkedMotion(**{name: Signal(centres.get(name, 0.0), tuple(parts)) for name, parts in terms.items()})

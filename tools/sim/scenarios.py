"""Named simulation scenarios: the set-ups of the seed papers and a few bench classics.

Each scenario fixes the site, the motion, the sensor errors (actual values) and the datasheet
grade that the IMU log states (if it states one); only the seed changes between Monte Carlo runs
(with it the bias signs and the parked car's motion, where the scenario draws them).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from sinsalign.service.align.conventions import DEG, DH_TO_RS, DRH_TO_RRS, UG_TO_MS2, dcm_from_euler
from sinsalign.service.align.earth import Site
from sinsalign.service.align.sensor_model import SensorGrade

from .imu import ImuErrors
from .motion import AngleProfile, AngularMotion, Sinusoid
from .parked import DrivenMotion, ParkedMotion, Signal, SmoothStep, parked_motion
from .transfer_field import TRANSFER_SITE, poor_slave_errors, poor_slave_motion
from .vehicle import MountedMotion, VehicleMotion


@dataclass(frozen=True, slots=True)
class OdometerSpec:
    """A simulated odometer / DVL: its rate, white noise per axis, lever arm (body axes, m) and
    scale-factor error (the same on every axis: 0.01 reads 1 % fast)."""

    rate_hz: float = 100.0
    noise_mps: float = 0.03
    lever_b: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: float = 0.0


@dataclass(frozen=True, slots=True)
class GnssSpec:
    """A simulated GNSS receiver: fix rate, white noise of velocity (m/s per ENU axis) and position
    (m per ENU axis), antenna lever arm from the IMU (body axes, m)."""

    rate_hz: float = 50.0
    vel_noise_mps: float = 0.1
    pos_noise_m: float = 2.0
    lever_b: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True, slots=True)
class MasterSpec:
    """A simulated master INS (transfer alignment): its output rate and the white noise of its attitude
    (deg per axis) and ENU velocity (m/s per axis)."""

    rate_hz: float = 10.0
    att_noise_deg: float = 0.001
    vel_noise_mps: float = 0.005


@dataclass(frozen=True, slots=True)
class Scenario:
    """Everything needed to simulate one run, except the seed."""

    name: str
    description: str
    site: Site
    motion: AngularMotion | VehicleMotion | ParkedMotion | DrivenMotion
    errors: ImuErrors
    grade: SensorGrade
    """The datasheet grade the IMU log states (which may differ from the actual errors)."""
    rate_hz: float
    duration_s: float
    eval_windows_s: tuple[tuple[float, float], ...]
    odometer: OdometerSpec | None = None
    random_bias_signs: bool = False
    """Each seed draws the sign of every axis's bias (a population of IMUs with biases of the stated size)."""
    gnss: GnssSpec | None = None
    master: MasterSpec | None = None
    motion_for_seed: Callable[[int], ParkedMotion | MountedMotion] | None = None
    """Draws each seed's motion (its own heading and events; a module-level function, so the scenario pickles);
    None: ``motion`` for every seed."""
    errors_for_seed: Callable[[int], ImuErrors] | None = None
    """Draws each seed's sensor errors (their magnitudes; the signs as ``random_bias_signs``); None: ``errors``."""
    states_datasheet: bool = True
    """The IMU log states ``grade`` as its datasheet; False: the log states none (the configured one serves)."""
    field_from_s: float | None = None
    """The field acceptance figures (``eval``'s last line: error, σ honesty, convergence, restarts, phases) count
    from this time (s); None: the scenario has none."""

    def for_seed(self, seed: int) -> Scenario:
        """The scenario as seed ``seed`` runs it (its own motion and bias signs, if drawn)."""
        scenario = self
        if self.motion_for_seed is not None:
            scenario = replace(scenario, motion=self.motion_for_seed(seed), motion_for_seed=None)
        if self.errors_for_seed is not None:
            scenario = replace(scenario, errors=self.errors_for_seed(seed), errors_for_seed=None)
        if not scenario.random_bias_signs:
            return scenario
        signs = np.random.default_rng([seed, 5]).choice([-1.0, 1.0], size=(2, 3))
        e = scenario.errors
        return replace(scenario, random_bias_signs=False, errors=replace(
            e, gyro_bias_rad_s=tuple(float(v) for v in signs[0] * e.gyro_bias_rad_s),
            acc_bias_ms2=tuple(float(v) for v in signs[1] * e.acc_bias_ms2)))

    def stated_datasheet(self) -> dict[str, float] | None:
        """The datasheet keys the IMU log states (°/h, °/√h, µg, µg/√Hz), or None if it states none."""
        return self.grade.datasheet() if self.states_datasheet else None

    def with_aid_rate(self, rate_hz: float) -> Scenario:
        """The scenario with its aiding sensor (GNSS, master or odometer) at ``rate_hz`` instead of its own."""
        for kind in ("gnss", "master", "odometer"):
            spec = getattr(self, kind)
            if spec is not None:
                return replace(self, **{kind: replace(spec, rate_hz=rate_hz)})
        raise ValueError(f"scenario {self.name} has no aiding sensor")

    def without_errors(self) -> Scenario:
        odometer = None if self.odometer is None else replace(self.odometer, noise_mps=0.0)
        gnss = None if self.gnss is None else replace(self.gnss, vel_noise_mps=0.0, pos_noise_m=0.0)
        master = None if self.master is None else replace(self.master, att_noise_deg=0.0, vel_noise_mps=0.0)
        return replace(self, name=self.name + "-ideal", errors=ImuErrors(),
                       grade=SensorGrade(1e-12, 1e-12, 1e-12, 1e-12), odometer=odometer, gnss=gnss, master=master)


def _swing(centre_deg: tuple[float, float, float], amp_deg: tuple[float, float, float],
           freq_hz: tuple[float, float, float]) -> AngularMotion:
    """Swing about (heading, pitch, roll) centres; amplitudes in degrees, zero initial phase."""
    profiles = [AngleProfile(c * DEG, (Sinusoid(a * DEG, f),) if a else ())
                for c, a, f in zip(centre_deg, amp_deg, freq_hz, strict=True)]
    return AngularMotion(*profiles)


def _errors(gyro_bias_deg_h: float, acc_bias_ug: float, gyro_noise_deg_h: float = 0.0,
            gyro_arw_deg_rth: float = 0.0, acc_noise_ug: float = 0.0) -> ImuErrors:
    return ImuErrors(gyro_bias_rad_s=(gyro_bias_deg_h * DH_TO_RS,) * 3,
                     gyro_noise_rad_s=gyro_noise_deg_h * DH_TO_RS, gyro_arw_rad_rts=gyro_arw_deg_rth * DRH_TO_RRS,
                     acc_bias_ms2=(acc_bias_ug * UG_TO_MS2,) * 3, acc_noise_ms2=acc_noise_ug * UG_TO_MS2)


def grade_of(errors: ImuErrors, rate_hz: float) -> SensorGrade:
    """The datasheet grade matching the simulated errors: bias magnitude per axis, noise as density."""
    dt = 1.0 / rate_hz
    gyro_std, acc_std = errors.increment_noise_std(dt)
    return SensorGrade(max(abs(b) for b in errors.gyro_bias_rad_s), gyro_std / dt**0.5,
                       max(abs(b) for b in errors.acc_bias_ms2), acc_std / dt**0.5)


def _scenario(name: str, description: str, site: Site, motion: AngularMotion | VehicleMotion, errors: ImuErrors,
              rate_hz: float, duration_s: float, windows: tuple[tuple[float, float], ...],
              odometer: OdometerSpec | None = None, random_bias_signs: bool = False,
              gnss: GnssSpec | None = None, master: MasterSpec | None = None) -> Scenario:
    return Scenario(name, description, site, motion, errors, grade_of(errors, rate_hz), rate_hz, duration_s,
                    windows, odometer, random_bias_signs, gnss, master)


SEED003_SITE = Site(45.68 * DEG, 126.63 * DEG, 150.0)
SEED003_DURATION_S = 600.0


def seed003_drive(speed_mps: float) -> VehicleMotion:
    """Seed 003's land vehicle: heading 30° then turns every two minutes or so, speed changes of ±25 %,
    road pitch and roll of a degree; 600 s so the Kalman stage can follow the 120-s coarse window."""
    heading = AngleProfile(30 * DEG, steps=((30.0, 120 * DEG), (70.0, 60 * DEG), (200.0, 150 * DEG),
                                            (330.0, 30 * DEG), (460.0, -60 * DEG)))
    speed = AngleProfile(speed_mps, steps=((40.0, 1.25 * speed_mps), (150.0, speed_mps), (260.0, 0.75 * speed_mps),
                                           (400.0, speed_mps)))
    return VehicleMotion(SEED003_SITE, SEED003_DURATION_S,
                         AngularMotion(heading, AngleProfile(0.0, (Sinusoid(0.5 * DEG, 0.1),)),
                                       AngleProfile(0.0, (Sinusoid(1.0 * DEG, 0.2),))), speed)


def _seed003(speed_mps: int) -> Scenario:
    return _scenario(f"seed003-{speed_mps}", f"seed 003 in-motion with odometer: L=45.68°, 100 Hz, {speed_mps} m/s "
                     "(±25 %), heading 30° with turns, 600 s; gyro 0.01°/h bias + 0.001°/h per sample, acc 100 µg + "
                     "10 µg per sample (bias signs drawn per seed and axis); V^b noise 0.03 m/s at 100 Hz",
                     SEED003_SITE, seed003_drive(float(speed_mps)),
                     _errors(0.01, 100.0, gyro_noise_deg_h=0.001, acc_noise_ug=10.0), 100.0, SEED003_DURATION_S,
                     ((120.0, 120.0), (600.0, 600.0)), OdometerSpec(100.0, 0.03), random_bias_signs=True)


SEED004_SITE = Site(30.0 * DEG, 114.0 * DEG, 3000.0)


def seed004_flight() -> VehicleMotion:
    """Seed 004's manoeuvring flight: 100 m/s (±15 m/s), heading 45° swinging ±30° (a 60-s period),
    banked ±20° and pitched ±5° with it; the attitude and translation oscillate as in the paper's
    Figures 1-2, so the horizontal acceleration keeps turning."""
    heading = AngleProfile(45 * DEG, (Sinusoid(30 * DEG, 1 / 60), Sinusoid(5 * DEG, 0.11, 1.0)))
    pitch = AngleProfile(0.0, (Sinusoid(5 * DEG, 1 / 40, 0.5), Sinusoid(1 * DEG, 0.23)))
    roll = AngleProfile(0.0, (Sinusoid(20 * DEG, 1 / 60, np.pi / 2), Sinusoid(2 * DEG, 0.3, 2.0)))
    speed = AngleProfile(100.0, (Sinusoid(15.0, 1 / 50, 0.3),))
    return VehicleMotion(SEED004_SITE, 300.0, AngularMotion(heading, pitch, roll), speed)


SCENARIOS: dict[str, Scenario] = {s.name: s for s in (
    _scenario("seed000-swing", "seed 000 §5.2 ship swing: L=32°, 200 Hz, 200 s, pitch/roll/yaw 8°/10°/6° "
              "at 0.15/0.125/0.2 Hz; gyro 0.01°/h bias + 0.01°/h per sample, acc 50 µg + 50 µg per sample",
              Site(32.0 * DEG, 118.0 * DEG), _swing((0.0, 0.0, 0.0), (6.0, 8.0, 10.0), (0.2, 0.15, 0.125)),
              _errors(0.01, 50.0, gyro_noise_deg_h=0.01, acc_noise_ug=50.0), 200.0, 200.0,
              ((1.0, 100.0), (101.0, 200.0))),
    _scenario("seed000-turntable", "seed 000 §5.3 turntable: L=32.057°, 200 Hz, 300 s, heading 225° pitch 2° "
              "roll -2°, swing 3°/3°/2° at 0.15/0.2/0.125 Hz; gyro 0.02°/h + ARW 0.005°/√h, acc 50 µg + 50 µg",
              Site(32.057 * DEG, 118.786 * DEG), _swing((225.0, 2.0, -2.0), (2.0, 3.0, 3.0), (0.125, 0.15, 0.2)),
              _errors(0.02, 50.0, gyro_arw_deg_rth=0.005, acc_noise_ug=50.0), 200.0, 300.0,
              ((101.0, 200.0), (201.0, 300.0))),
    _scenario("static", "static base 600 s: L=32.057°, heading 300°, pitch 1°, roll -1.5°; gyro 0.02°/h + "
              "0.006°/h per sample, acc 50 µg + 50 µg per sample",
              Site(32.057 * DEG, 118.786 * DEG), _swing((300.0, 1.0, -1.5), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
              _errors(0.02, 50.0, gyro_noise_deg_h=0.006, acc_noise_ug=50.0), 200.0, 600.0,
              ((1.0, 300.0), (550.0, 600.0))),
    _scenario("turntable-positions", "turntable stepping heading 0° → 90° → 180° → 270° every 60 s "
              "(10-s moves) with pitch 5°: L=45°, navigation-grade IMU",
              Site(45.0 * DEG, 10.0 * DEG),
              AngularMotion(AngleProfile(0.0, steps=((60.0, 90 * DEG), (120.0, 180 * DEG), (180.0, 270 * DEG))),
                            AngleProfile(5.0 * DEG), AngleProfile()),
              _errors(0.01, 50.0, gyro_arw_deg_rth=0.002, acc_noise_ug=50.0), 200.0, 240.0,
              ((1.0, 120.0), (121.0, 240.0))),
    _scenario("seed001-static", "seed 001 static base: L=32.057°, 200 Hz, 600 s, heading 30° pitch 1° roll 1°; "
              "gyro 0.02°/h + 0.006°/h per sample, acc 50 µg + 50 µg per sample",
              Site(32.057 * DEG, 118.786 * DEG), _swing((30.0, 1.0, 1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
              _errors(0.02, 50.0, gyro_noise_deg_h=0.006, acc_noise_ug=50.0), 200.0, 600.0,
              ((101.0, 200.0), (550.0, 600.0))),
    _scenario("seed001-swing", "seed 001 swing base: L=32.057°, 200 Hz, 600 s, heading 30° ± 5° at 0.125 Hz, "
              "pitch 8° at 0.15 Hz, roll 6° at 0.2 Hz; gyro 0.02°/h + 0.006°/h per sample, acc 50 µg + 50 µg "
              "per sample",
              Site(32.057 * DEG, 118.786 * DEG), _swing((30.0, 0.0, 0.0), (5.0, 8.0, 6.0), (0.125, 0.15, 0.2)),
              _errors(0.02, 50.0, gyro_noise_deg_h=0.006, acc_noise_ug=50.0), 200.0, 600.0,
              ((101.0, 200.0), (550.0, 600.0))),
)}


def _driven(base: Scenario) -> Scenario:
    motion = replace(base.motion, drive_from_s=60.0, drive_accel_n=(0.0, 1.0, 0.0))
    return replace(base, name=base.name + "-driven", motion=motion,
                   description=base.description + "; from 60 s the base is driven north at 1 m/s²")


SCENARIOS["seed000-swing-driven"] = _driven(SCENARIOS["seed000-swing"])


def turntable_index(positions: int, dwell_s: float = 300.0, turn_s: float = 20.0) -> AngularMotion:
    """A table indexed 90° about the vertical between ``positions`` positions, ``dwell_s`` at each (the turn at the
    end of each dwell takes ``turn_s``), the IMU pitched 5° on it."""
    steps = tuple((dwell_s * k, 90.0 * DEG * k) for k in range(1, positions))
    return AngularMotion(AngleProfile(0.0, steps=steps, transition_s=turn_s), AngleProfile(5.0 * DEG), AngleProfile())


SCENARIOS["turntable-index"] = replace(
    SCENARIOS["turntable-positions"], name="turntable-index", motion=turntable_index(4), duration_s=1200.0,
    description="turntable indexed 90° at a time, 300 s at each of 4 positions (20-s turns), pitch 5°: L=45°, "
                "navigation-grade IMU (turntable-positions' IMU, bias signs drawn per seed and axis)",
    eval_windows_s=((1.0, 300.0), (900.0, 1200.0)), random_bias_signs=True)
SCENARIOS.update({s.name: s for s in (_seed003(20), _seed003(60), _seed003(80))})
ODO_GNSS_DURATION_S = 150.0
SCENARIOS["seed003-odo-gnss"] = replace(
    SCENARIOS["seed003-20"], name="seed003-odo-gnss", duration_s=ODO_GNSS_DURATION_S, eval_windows_s=((60.0, 60.0),
                                                                                                     (120.0, 120.0)),
    description=SCENARIOS["seed003-20"].description.replace(", 600 s", f", {ODO_GNSS_DURATION_S:g} s") +
    "; GNSS 10 Hz, 0.1 m/s and 2 m white noise, antenna 0.6 m forward and 0.8 m up (1 m)",
    gnss=GnssSpec(10.0, 0.1, 2.0, (0.0, 0.6, 0.8)))
SCENARIOS["seed004"] = _scenario(
    "seed004", "seed 004 in-flight with GNSS: L=30°, 100 Hz, 300 s of manoeuvres at 100 m/s; gyro 0.01°/h bias + "
    "0.1°/h/√Hz, acc 50 µg bias + 500 µg/√Hz (bias signs drawn per seed and axis); GNSS 50 Hz, 0.1 m/s and 2 m "
    "white noise, lever arm 1 m on every axis",
    SEED004_SITE, seed004_flight(), replace(_errors(0.01, 50.0), gyro_arw_rad_rts=0.1 / 60.0 * DRH_TO_RRS,
                                            acc_vrw_ms_rts=500.0 * UG_TO_MS2),
    100.0, 300.0, ((10.0, 10.0), (60.0, 60.0), (300.0, 300.0)), random_bias_signs=True, gnss=GnssSpec())


SEED002_SITE = Site(32.5 * DEG, 135.0 * DEG, 500.0)
SEED002_MOUNT_DEG = (20.0, 20.0, 20.0)


def seed002_flight(mount_deg: tuple[float, float, float] = SEED002_MOUNT_DEG,
                   lever_m: tuple[float, float, float] = (0.0, 0.0, 0.0), first_rock_s: float = 1.0) -> MountedMotion:
    """Seed 002's transfer-alignment run: 50 m/s north, level, with three 30° wing rocks (roll up in 2.5 s,
    back in 2.5 s 4 s later, from ``first_rock_s``, 20 s and 40 s after it: 1, 21 and 41 s), 60 s; the slave IMU
    mounted (heading, pitch, roll) ``mount_deg`` off the master (C_bs^bm from those Euler angles), at ``lever_m``
    from the master's point (master body axes)."""
    roll = AngleProfile(0.0, steps=tuple((first_rock_s + start + up, angle) for start in (0.0, 20.0, 40.0)
                                         for up, angle in ((0.0, 30 * DEG), (4.0, 0.0))), transition_s=2.5)
    vehicle = VehicleMotion(SEED002_SITE, 60.0, AngularMotion(roll=roll), AngleProfile(50.0))
    M = dcm_from_euler(*(np.array(mount_deg) * DEG))
    return MountedMotion(vehicle, tuple(tuple(float(v) for v in row) for row in M), lever_m)


SCENARIOS["seed002"] = _scenario(
    "seed002", "seed 002 transfer alignment: L=32.5°, 500 m, 50 m/s north, three 30° wing rocks, 60 s, 100 Hz; "
    "slave mounted 20°/20°/20° off the master; slave gyro 10°/h bias + 0.1°/√h, acc 5 mg bias + 50 µg/√Hz (bias "
    "signs drawn per seed and axis); master at 10 Hz, attitude 0.001° and velocity 0.005 m/s white noise",
    SEED002_SITE, seed002_flight(), replace(_errors(10.0, 5000.0, gyro_arw_deg_rth=0.1),
                                            acc_vrw_ms_rts=50.0 * UG_TO_MS2),
    100.0, 60.0, ((10.0, 10.0), (60.0, 60.0)), random_bias_signs=True, master=MasterSpec())


MEMS_GRADE = SensorGrade.from_datasheet(300.0, 0.5, 10000.0, 50.0)
"""The poor slave's datasheet: the population's upper figures (300°/h, 0.5°/√h, 10 mg, 50 µg/√Hz)."""
SCENARIOS["transfer-mems"] = replace(_scenario(
    "transfer-mems", "transfer alignment of a MEMS slave in a road vehicle: L=31°, 100 Hz, 100 s; straight north "
    "at 14 ± 2 m/s (a swing of 8–15 s period), rolled ±30° at 5–10°/s (per seed) over 30–75 s; slave mounted "
    "12°/−4°/7° off the master at a lever arm of (0.4, 1.2, −0.3) m it does not know; slave gyro 100–300°/h bias "
    "per axis + 0.1–0.5°/√h, acc 1–10 mg + 50 µg/√Hz (magnitudes and signs per seed), stating 300°/h, 0.5°/√h, "
    "10 mg, 50 µg/√Hz; master at 10 Hz, attitude 0.15° (flexure, vibration) and velocity 0.1 m/s white noise",
    TRANSFER_SITE, poor_slave_motion(0), poor_slave_errors(0), 100.0, 100.0, ((10.0, 30.0), (40.0, 100.0)),
    random_bias_signs=True, master=MasterSpec(att_noise_deg=0.15, vel_noise_mps=0.1)),
    grade=MEMS_GRADE, motion_for_seed=poor_slave_motion, errors_for_seed=poor_slave_errors)


PARKED_SITE = Site(34.0 * DEG, 118.0 * DEG)
PARKED_FIGURES_FROM_S = 300.0
"""The parked car's figures count from 5 minutes: the heading within 0.03° of its limit, σ honest from then on."""
ARCSEC = DEG / 3600.0
PARKED_ERRORS = ImuErrors(gyro_bias_rad_s=(0.01 * DH_TO_RS, 0.007 * DH_TO_RS, 0.005 * DH_TO_RS),
                          gyro_arw_rad_rts=0.0005 * DRH_TO_RRS,
                          acc_bias_ms2=(50.0 * UG_TO_MS2, 30.0 * UG_TO_MS2, 20.0 * UG_TO_MS2),
                          acc_vrw_ms_rts=5.0 * UG_TO_MS2, gyro_quantum_rad=0.93 * ARCSEC,
                          acc_quantum_mps=500.0 * UG_TO_MS2)
"""A navigation-grade ring-laser-gyro IMU within the default datasheet (0.01°/h, 0.001°/√h, 50 µg, 5 µg/√Hz):
biases per axis (x, y, z), signs drawn per seed; counts of 0.93″ and 500 µg·s. Its angle random walk, 0.0005°/√h,
is what a recording whose heading sits within 0.02° of the truth from 120 s implies (the noise floor
N/(Ω cos L √T) is then 0.009° at 120 s); the default datasheet overstates it twice."""
PARKED_DESCRIPTION = (
    "parked car: L=34°, 100 Hz, 1800 s; per seed heading 0–360°, pitch/roll ±2°, engine at 20–40 Hz "
    "(1e-4–5e-4°, 0.02–0.1 m/s²), rocking 0.002–0.01° at 1–3 Hz (slowly modulated), knocks 0.01–0.3° ringing at "
    "1.5–3 Hz (3 per 10 min), people in/out (2 per 30 min: tilt 0.1–0.5°, sink 1–3 cm, bounce); RLG gyro "
    "0.01/0.007/0.005°/h bias + 0.0005°/√h, acc 50/30/20 µg + 5 µg/√Hz (bias signs drawn per seed and axis), "
    "counts of 0.93″ and 500 µg·s")


def _parked() -> Scenario:
    scenario = _scenario("parked", PARKED_DESCRIPTION + "; the log states the matching datasheet", PARKED_SITE,
                         parked_motion(0), PARKED_ERRORS, 100.0, 1800.0, ((300.0, 600.0), (1500.0, 1800.0)),
                         random_bias_signs=True)
    return replace(scenario, motion_for_seed=parked_motion, field_from_s=PARKED_FIGURES_FROM_S)


TACTICAL_GRADE = SensorGrade.from_datasheet(1.0, 0.05, 300.0, 50.0)
"""A tactical-grade datasheet (1°/h, 0.05°/√h, 300 µg, 50 µg/√Hz): far louder than the parked RLG."""
SCENARIOS["parked"] = _parked()
SCENARIOS["parked-nodatasheet"] = replace(
    SCENARIOS["parked"], name="parked-nodatasheet", states_datasheet=False,
    description=PARKED_DESCRIPTION + "; the log states no datasheet (the configured one serves)")
SCENARIOS["parked-tactical"] = replace(
    SCENARIOS["parked"], name="parked-tactical", grade=TACTICAL_GRADE,
    description=PARKED_DESCRIPTION + "; the log states a tactical datasheet (1°/h, 0.05°/√h, 300 µg, 50 µg/√Hz) "
    "that overstates the sensor")


def _swing_driven(name: str, drive: str, speed: Signal, duration_s: float,
                  windows: tuple[tuple[float, float], ...]) -> Scenario:
    """Seed 000's swing (its site, swing and IMU) driven north at ``speed`` (m/s), ``duration_s`` long."""
    base = SCENARIOS["seed000-swing"]
    return replace(base, name=name, motion=DrivenMotion(base.motion, speed), duration_s=duration_s,
                   eval_windows_s=windows,
                   description=f"seed 000 §5.2 ship swing (L=32°, 200 Hz, pitch/roll/yaw 8°/10°/6° at "
                               f"0.15/0.125/0.2 Hz, seed000-swing's IMU); {drive}")


SCENARIOS["swing-drive-away"] = _swing_driven(
    "swing-drive-away", "from 60 s the base is driven north, reaching 30 m/s at 90 s (raised-cosine acceleration, "
    "peak 2 m/s²), then on at 30 m/s to 200 s", Signal(terms=(SmoothStep(60.0, 30.0, 30.0),)), 200.0,
    ((1.0, 60.0), (101.0, 200.0)))
SCENARIOS["swing-drive-stop"] = _swing_driven(
    "swing-drive-stop", "the base is driven 50 m north over 60–80 s (raised-cosine acceleration and braking, "
    "peak 5 m/s and 1 m/s²), then parked again to 300 s",
    Signal(terms=(SmoothStep(60.0, 10.0, 5.0), SmoothStep(70.0, 10.0, -5.0))), 300.0,
    ((1.0, 60.0), (201.0, 300.0)))


def daemon_sections(scenario: Scenario) -> dict[str, dict]:
    """The daemon's [site] (degrees, metres), [imu] (Hz) and [sensor] (datasheet, if the log states one) tables
    for ``scenario``."""
    datasheet = scenario.stated_datasheet()
    return {"site": {"lat_deg": scenario.site.lat / DEG, "lon_deg": scenario.site.lon / DEG,
                     "height_m": scenario.site.height_m},
            "imu": {"rate_hz": scenario.rate_hz}, **({"sensor": datasheet} if datasheet is not None else {})}


def get_scenario(name: str) -> Scenario:
    """A scenario by name; a name ending in ``-ideal`` gives the same run without sensor errors."""
    base = name.removesuffix("-ideal")
    if base not in SCENARIOS:
        raise KeyError(f"unknown scenario {name!r}; known: {', '.join(sorted(SCENARIOS))} (each also as NAME-ideal)")
    return SCENARIOS[base].without_errors() if name.endswith("-ideal") else SCENARIOS[base]


def seed_run(name: str, seed: int, duration_s: float | None = None) -> Scenario:
    """The named scenario as seed ``seed`` runs it (its own bias signs, if drawn), ``duration_s`` long if given:
    what ``sim``, ``bench`` and ``demo`` play for the same name and seed, so they play the same data."""
    scenario = get_scenario(name).for_seed(seed)
    return replace(scenario, duration_s=duration_s) if duration_s else scenario

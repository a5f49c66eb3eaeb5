"""Named simulation scenarios: the set-ups of the seed papers and a few bench classics.

Each scenario fixes the site, the motion, the sensor errors (actual values) and the datasheet
grade that the IMU log states; only the seed changes between Monte Carlo runs.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from sinsalign.service.align.conventions import DEG, DH_TO_RS, DRH_TO_RRS, UG_TO_MS2
from sinsalign.service.align.earth import Site
from sinsalign.service.align.sensor_model import SensorGrade

from .imu import ImuErrors
from .motion import AngleProfile, AngularMotion, Sinusoid


@dataclass(frozen=True, slots=True)
class Scenario:
    """Everything needed to simulate one run, except the seed."""

    name: str
    description: str
    site: Site
    motion: AngularMotion
    errors: ImuErrors
    grade: SensorGrade
    rate_hz: float
    duration_s: float
    eval_windows_s: tuple[tuple[float, float], ...]

    def without_errors(self) -> Scenario:
        return replace(self, name=self.name + "-ideal", errors=ImuErrors(),
                       grade=SensorGrade(1e-12, 1e-12, 1e-12, 1e-12))


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


def _scenario(name: str, description: str, site: Site, motion: AngularMotion, errors: ImuErrors, rate_hz: float,
              duration_s: float, windows: tuple[tuple[float, float], ...]) -> Scenario:
    return Scenario(name, description, site, motion, errors, grade_of(errors, rate_hz), rate_hz, duration_s,
                    windows)


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


def get_scenario(name: str) -> Scenario:
    """A scenario by name; a name ending in ``-ideal`` gives the same run without sensor errors."""
    base = name.removesuffix("-ideal")
    if base not in SCENARIOS:
        raise KeyError(f"unknown scenario {name!r}; known: {', '.join(sorted(SCENARIOS))} (each also as NAME-ideal)")
    return SCENARIOS[base].without_errors() if name.endswith("-ideal") else SCENARIOS[base]

"""Simulated aiding sensors on a moving vehicle: odometer / DVL body velocity (seed 003), GNSS (seed 004),
a master INS (seed 002).

A sensor sits at lever arm l^b from the IMU (body axes, m) and measures that point P:
odometer: its velocity over ground in body axes, V_P^b = V^b + ω_eb^b × l^b with
ω_eb^b = ω_nb^b + C_n^b ω_en^n, times (1 + scale factor) per axis, plus white noise;
GNSS: its position (P = IMU + C_b^n l^b) and ENU velocity V_P^n = V^n + C_b^n (ω_eb^b × l^b), plus
white noise; each written as its pinned log.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sinsalign.protocol.aiding_log import KINDS, LEVER_KEYS, stated_aiding
from sinsalign.protocol.imu_log import write_header, write_rows
from sinsalign.service.align.conventions import DEG, cross, dcm_from_quat, quat_from_dcm, quat_from_rotvec, wrap_pi
from sinsalign.service.align.earth import radii, transport_rate_n

from .scenarios import Scenario
from .vehicle import VehicleMotion


def _omega_eb_b(motion: VehicleMotion, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(C_b^n, V^b, V^n, ω_eb^b) at times t."""
    C_b_n, omega_nb_b = motion.attitude_profiles.attitude_and_rate(t)
    _, V_b, V_n = motion.velocity_n(t)
    lat, _, h = np.moveaxis(motion.position(t), -1, 0)
    omega_en_n = transport_rate_n(V_n, lat, h)
    return C_b_n, V_b, V_n, omega_nb_b + (np.swapaxes(C_b_n, -1, -2) @ omega_en_n[..., None])[..., 0]


def body_velocity(motion: VehicleMotion, t: np.ndarray, lever_b: np.ndarray | None = None,
                  scale: np.ndarray | None = None, noise_std_mps: float = 0.0,
                  rng: np.random.Generator | None = None) -> np.ndarray:
    """Measured V_P^b (N, 3) in m/s at times t (N,); lever arm and scale factors default to zero."""
    lever_b = np.zeros(3) if lever_b is None else np.asarray(lever_b, dtype=float)
    scale = np.zeros(3) if scale is None else np.asarray(scale, dtype=float)
    _, V_b, _, omega_eb_b = _omega_eb_b(motion, t)
    measured = (V_b + cross(omega_eb_b, np.broadcast_to(lever_b, V_b.shape))) * (1.0 + scale)
    if noise_std_mps:
        measured = measured + noise_std_mps * (rng or np.random.default_rng()).standard_normal(measured.shape)
    return measured


def write_aiding_log(path: str | Path, kind: str, epochs: np.ndarray, keys: Mapping[str, float]) -> Path:
    """The pinned aiding log of ``kind``: the comment ``keys``, the kind's header row, the epochs (N, columns)."""
    path = Path(path)
    with open(path, "w", encoding="utf-8") as f:
        write_header(f, keys, KINDS[kind].columns)
        write_rows(f, epochs)
    return path


def _given(**keys: float | None) -> dict[str, float]:
    return {k: v for k, v in keys.items() if v is not None}


def write_body_velocity_log(path: str | Path, t: np.ndarray, v_b: np.ndarray, vel_std_mps: float | None = None) -> Path:
    """The pinned body-velocity log: ``t,vx,vy,vz`` with an optional ``# vel_std_mps=`` key."""
    return write_aiding_log(path, "odo", np.column_stack((t, v_b)), _given(vel_std_mps=vel_std_mps))


def epoch_times(duration_s: float, rate_hz: float) -> np.ndarray:
    """A sensor's epochs (s): every 1/rate from the first period to the end of the run."""
    return np.arange(1, round(duration_s * rate_hz) + 1) / rate_hz


def odometer_epochs(scenario: Scenario, seed: int) -> np.ndarray:
    """The scenario's odometer readings (N, 4): t, V_P^b (seeded; a noise stream apart from the IMU's)."""
    odo = scenario.odometer
    t = epoch_times(scenario.duration_s, odo.rate_hz)
    v = body_velocity(scenario.motion, t, np.asarray(odo.lever_b), np.full(3, odo.scale), odo.noise_mps,
                      np.random.default_rng([seed, 3]))
    return np.column_stack((t, v))


def without_span(epochs: np.ndarray, span_s: tuple[float, float] | None) -> np.ndarray:
    """The epochs (N, 1 + k) without those whose time lies in [start, end) of ``span_s`` (a dropout, an outage)."""
    if span_s is None:
        return epochs
    return epochs[(epochs[:, 0] < span_s[0]) | (epochs[:, 0] >= span_s[1])]


def with_master_faults(epochs: np.ndarray, dropout_s: tuple[float, float] | None = None, repeated: int = 0,
                       late_s: float = 0.0, seed: int = 0) -> np.ndarray:
    """Master-INS epochs (N, 11) with faults: none inside ``dropout_s``, ``repeated`` epochs sent twice, and every
    time stamp ``late_s`` late (what ``aiding.master.latency_s`` takes back)."""
    out = without_span(epochs, dropout_s)
    if repeated:
        twice = np.sort(np.random.default_rng([seed, 7]).choice(len(out), repeated, replace=False))
        out = np.insert(out, twice + 1, out[twice], axis=0)
    out = out.copy()
    out[:, 0] += late_s
    return out


def with_odometer_faults(epochs: np.ndarray, dropout_s: tuple[float, float] | None = None,
                         slip: tuple[float, float, float] | None = None, swapped: int = 0,
                         seed: int = 0) -> np.ndarray:
    """Odometer epochs (N, 4) with faults: no epochs inside ``dropout_s`` (start, end); a wheel slip
    ``(start_s, length_s, extra_mps)`` reading the forward axis fast; ``swapped`` pairs of
    neighbouring epochs sent out of order."""
    out = epochs.copy()
    if slip is not None:
        start, length, extra = slip
        out[(out[:, 0] >= start) & (out[:, 0] < start + length), 2] += extra
    out = without_span(out, dropout_s)
    if swapped:
        for k in np.random.default_rng([seed, 4]).choice(len(out) - 1, swapped, replace=False):
            out[[k, k + 1]] = out[[k + 1, k]]
    return out


def gnss_fixes(motion: VehicleMotion, t: np.ndarray, lever_b: np.ndarray | None = None, vel_noise_mps: float = 0.0,
               pos_noise_m: float = 0.0, rng: np.random.Generator | None = None) -> np.ndarray:
    """Antenna fixes (N, 6) at times t (N,): lat_deg, lon_deg, h_m, vE, vN, vU (m/s)."""
    lever_b = np.zeros(3) if lever_b is None else np.asarray(lever_b, dtype=float)
    C_b_n, _, V_n, omega_eb_b = _omega_eb_b(motion, t)
    lat, lon, h = np.moveaxis(motion.position(t), -1, 0)
    offset_n = (C_b_n @ lever_b)
    V_P = V_n + (C_b_n @ cross(omega_eb_b, np.broadcast_to(lever_b, V_n.shape))[..., None])[..., 0]
    rng = rng or np.random.default_rng()
    if pos_noise_m:
        offset_n = offset_n + pos_noise_m * rng.standard_normal(offset_n.shape)
    if vel_noise_mps:
        V_P = V_P + vel_noise_mps * rng.standard_normal(V_P.shape)
    R_M, R_N = radii(lat)
    lat_P = lat + offset_n[:, 1] / (R_M + h)
    lon_P = lon + offset_n[:, 0] / ((R_N + h) * np.cos(lat))
    return np.column_stack((lat_P / DEG, wrap_pi(lon_P) / DEG, h + offset_n[:, 2], V_P))   # as a receiver gives it


def gnss_epochs(scenario: Scenario, seed: int) -> np.ndarray:
    """The scenario's GNSS fixes (N, 7): t, lat_deg, lon_deg, h_m, vE, vN, vU (seeded apart from the IMU)."""
    g = scenario.gnss
    t = epoch_times(scenario.duration_s, g.rate_hz)
    return np.column_stack((t, gnss_fixes(scenario.motion, t, np.asarray(g.lever_b), g.vel_noise_mps, g.pos_noise_m,
                                          np.random.default_rng([seed, 4]))))


GnssGlitch = tuple[float, float, float, float]
"""A GNSS glitch: (start_s, length_s, east velocity jump m/s, north position jump m)."""


def with_gnss_faults(epochs: np.ndarray, outage_s: tuple[float, float] | None = None,
                     glitches: Sequence[GnssGlitch] = ()) -> np.ndarray:
    """GNSS epochs (N, 7: t, lat_deg, lon_deg, h_m, vE, vN, vU) with faults: no epochs inside ``outage_s``
    (start, end in s); each glitch ``(start_s, length_s, dvel_mps, dpos_m)`` adds ``dvel_mps`` (m/s) to the
    east velocity and moves the position ``dpos_m`` (m) north (in degrees of latitude with the meridian
    radius at the fix) in the fixes within [start_s, start_s + length_s)."""
    out = epochs.copy()
    for start, length, dvel, dpos in glitches:
        sel = (out[:, 0] >= start) & (out[:, 0] < start + length)
        R_M, _ = radii(out[sel, 1] * DEG)
        out[sel, 1] += dpos / (R_M + out[sel, 3]) / DEG
        out[sel, 4] += dvel
    return without_span(out, outage_s)


def write_gnss_log(path: str | Path, epochs: np.ndarray, lever_b: np.ndarray | None = None,
                   vel_std_mps: float | None = None, pos_std_m: float | None = None) -> Path:
    """The pinned GNSS log: ``t,lat_deg,lon_deg,h_m,vE,vN,vU`` with lever-arm and noise keys."""
    keys = {} if lever_b is None else dict(zip(LEVER_KEYS, (float(v) for v in lever_b), strict=True))
    return write_aiding_log(path, "gnss", epochs, keys | _given(vel_std_mps=vel_std_mps, pos_std_m=pos_std_m))


def master_epochs(scenario: Scenario, seed: int) -> np.ndarray:
    """The master INS's output (N, 11): t, q (4, [w, x, y, z] of its C_bm^n), vE, vN, vU, lat_deg, lon_deg, h_m,
    with the scenario's white attitude noise (a random small rotation per epoch) and velocity noise."""
    m, vehicle = scenario.master, scenario.motion.vehicle
    t = epoch_times(scenario.duration_s, m.rate_hz)
    rng = np.random.default_rng([seed, 6])
    C_bm_n = vehicle.attitude(t)
    if m.att_noise_deg:
        C_bm_n = dcm_from_quat(quat_from_rotvec(m.att_noise_deg * DEG * rng.standard_normal((len(t), 3)))) @ C_bm_n
    V_n = vehicle.velocity_n(t)[2] + m.vel_noise_mps * rng.standard_normal((len(t), 3))
    lat, lon, h = np.moveaxis(vehicle.position(t), -1, 0)
    return np.column_stack((t, quat_from_dcm(C_bm_n), V_n, lat / DEG, wrap_pi(lon) / DEG, h))


def write_master_log(path: str | Path, epochs: np.ndarray, att_std_deg: float | None = None,
                     vel_std_mps: float | None = None) -> Path:
    """The pinned master-INS log: ``t,qw,qx,qy,qz,vE,vN,vU,lat_deg,lon_deg,h_m`` with its noise keys."""
    return write_aiding_log(path, "master", epochs, _given(att_std_deg=att_std_deg, vel_std_mps=vel_std_mps))


@dataclass(frozen=True, slots=True)
class ScenarioAid:
    """A scenario's aiding sensor for one seed: its kind (odo, gnss, master), its epochs (N, 1 + values: t in s, then
    the kind's pinned log columns) and the comment keys its log states (noise figures above 0, a GNSS antenna's
    lever arm): what ``sim`` writes, the replay reads, and the evaluation and the live bench configure alike."""

    kind: str
    epochs: np.ndarray
    log_keys: dict[str, float]
    odo_lever_b: tuple[float, float, float] | None = None

    def stated(self) -> dict[str, object]:
        """The ``[aiding.<kind>]`` configuration its log states (:func:`stated_aiding`), as a replay of it takes."""
        return stated_aiding(self.kind, self.log_keys)

    def daemon_config(self) -> dict[str, object]:
        """The daemon's ``[aiding]`` keys: this kind as the input, and in its table what its log would state and an
        odometer's lever arm (its log has no key for it: the integrator configures it)."""
        lever = {} if self.odo_lever_b is None else {"lever_m": list(self.odo_lever_b)}
        table = {k: list(v) if isinstance(v, tuple) else v for k, v in self.stated().items()}
        return {"inputs": [self.kind], self.kind: {**table, **lever}}


def scenario_aids(scenario: Scenario, seed: int) -> list[ScenarioAid]:
    """The scenario's aiding sensors for ``seed`` (none, one, or an odometer and a GNSS receiver), in the order
    odo, gnss, master."""
    aids = []
    if scenario.odometer is not None:
        o = scenario.odometer
        aids.append(ScenarioAid("odo", odometer_epochs(scenario, seed), _given(vel_std_mps=o.noise_mps or None),
                                o.lever_b))
    if scenario.gnss is not None:
        g = scenario.gnss
        aids.append(ScenarioAid("gnss", gnss_epochs(scenario, seed), dict(zip(LEVER_KEYS, g.lever_b, strict=True))
                                | _given(vel_std_mps=g.vel_noise_mps or None, pos_std_m=g.pos_noise_m or None)))
    if scenario.master is not None:
        m = scenario.master
        aids.append(ScenarioAid("master", master_epochs(scenario, seed),
                                _given(att_std_deg=m.att_noise_deg or None, vel_std_mps=m.vel_noise_mps or None)))
    return aids


def daemon_aiding(aids: Sequence[ScenarioAid]) -> dict[str, object]:
    """The daemon's ``[aiding]`` table for these sensors: their kinds as the inputs, and each one's
    :meth:`ScenarioAid.daemon_config`."""
    table: dict[str, object] = {}
    for aid in aids:
        table |= aid.daemon_config()
    return {**table, "inputs": [aid.kind for aid in aids]} if aids else {}


def with_faults(kind: str, epochs: np.ndarray, seed: int, **faults: object) -> np.ndarray:
    """Epochs of an aiding ``kind`` with the faults of :func:`with_gnss_faults`, :func:`with_master_faults` or
    :func:`with_odometer_faults`, whichever is that kind's (keyword arguments; none: the epochs as they are)."""
    if kind == "gnss":
        return with_gnss_faults(epochs, **faults)
    return (with_master_faults if kind == "master" else with_odometer_faults)(epochs, **faults, seed=seed)

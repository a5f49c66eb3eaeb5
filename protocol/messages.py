"""msgpack messages on the Zenoh keys (protocol/README.md lists every field).

Every message is a map with ``"v"`` (schema version, 1) first. Decoders check the shape and the
types and raise :class:`MessageError` with a reason; they never execute or evaluate anything.

- IMU in (``…/imu``): v, seq (int), t (s), dtheta [3] (rad), dv [3] (m/s), status (int).
- aiding in (``…/aid/<kind>``): v, seq, t (s) and the fields of the kind's pinned aiding log:
  ``odo`` v_b [3] (m/s, body axes); ``gnss`` lat_deg, lon_deg, h_m, v_enu [3]; ``master`` q [4]
  (the master's C_b^n), v_enu [3], lat_deg, lon_deg, h_m.
- attitude out (``…/attitude``): v, unit and the pinned result fields (t, phase, q, pitch_deg,
  roll_deg, heading_deg, heading_sigma_deg, level_sigma_deg, converged, rho, trace_P, n_obs); in
  transfer alignment also mount_q [4] (C_bs^bm, scalar first) and mount_sigma_deg.
- status out (``…/status``, 1 Hz): v, unit, uptime_s, health, phase, t_last, last_error, counters {name: int},
  loop {reads, p50_ms, p99_ms, max_ms, max_cpu_ms, max_ms_since_start} (the daemon's own read → published time:
  service/loop_timing.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import msgpack

from .plausibility import aiding_problem
from .results import ResultRecord

VERSION = 1
HEALTH = ("starting", "ok", "degraded", "no_input")
NOT_FAULTS = frozenset({"frames", "samples_in", "samples_used", "records_published", "serial_reconnects",
                        "unknown_type", "other_messages", "samples_bridged", "samples_in_serial", "samples_in_zenoh",
                        "aiding_frames",
                        "odo_epochs", "odo_unaided_queries", "odo_accepted", "gnss_epochs", "gnss_unaided_queries",
                        "gnss_vel_accepted", "gnss_pos_accepted", "master_epochs", "master_unaided_queries",
                        "master_vel_accepted", "master_att_accepted", "odo_observations_awaiting_aid",
                        "gnss_observations_awaiting_aid", "master_observations_awaiting_aid", "gnss_rx_no_fix",
                        "gnss_rx_no_vertical", "gnss_rx_before_imu", "gnss_serial_reconnects"})
"""Status counters that count work, not faults; every other counter counts a drop or a fault, but for SCREENED. A
receiver's epochs without a fix, the first NMEA epoch without a height before it and the epochs before the IMU's
first sample come with every start: no fault."""
SCREENED = frozenset({"odo_rejected", "odo_outlier_pairs", "gnss_coarse_rejected", "gnss_vel_rejected",
                      "gnss_pos_rejected", "master_vel_rejected", "master_att_rejected"})
"""Inputs an estimator's gate or screen turned away. A gate at χ² 16.3 also turns away about 0.1 % of good
inputs, so one rejection is not a fault: :func:`screening_alarm` says when their rate is."""
SCREENING_ALARM_COUNT = 3
SCREENING_ALARM_SHARE = 0.05
"""A status period whose rejections of one kind reach both this count and this share of that kind's updates
(a glitch, a bad lever arm or latency, a failing sensor) is degraded."""


def faults(counters: dict[str, int]) -> dict[str, int]:
    """The counters that count drops or faults (not work, not screening) and are not zero."""
    return {k: v for k, v in counters.items() if v and k not in NOT_FAULTS and k not in SCREENED}


def screening_alarm(before: dict[str, int], now: dict[str, int]) -> list[str]:
    """The screening counters whose rise from ``before`` to ``now`` is an alarm: at least
    :data:`SCREENING_ALARM_COUNT` and :data:`SCREENING_ALARM_SHARE` of the kind's updates (its ``…_accepted``
    counter's rise plus the rejections; a screen without one counts the rejections alone)."""
    alarms = []
    for key in SCREENED & now.keys():
        rejected = now[key] - before.get(key, 0)
        accepted_key = key.removesuffix("_rejected") + "_accepted"
        accepted = now.get(accepted_key, 0) - before.get(accepted_key, 0)
        if rejected >= SCREENING_ALARM_COUNT and rejected >= SCREENING_ALARM_SHARE * (accepted + rejected):
            alarms.append(key)
    return sorted(alarms)


def fault_count(counters: dict[str, int]) -> int:
    return sum(faults(counters).values())


class MessageError(ValueError):
    """A message that does not follow its schema; the text says what is wrong."""


@dataclass(frozen=True, slots=True)
class ImuSample:
    seq: int
    t: float
    dtheta: tuple[float, float, float]
    dv: tuple[float, float, float]
    status: int


def pack(message: dict[str, Any]) -> bytes:
    return msgpack.packb(message, use_bin_type=True)


def unpack_map(data: bytes) -> dict[str, Any]:
    """A msgpack map with a supported version, else MessageError."""
    try:
        message = msgpack.unpackb(data, raw=False, strict_map_key=True)
    except Exception as exc:   # msgpack raises several types for corrupt input
        raise MessageError(f"not msgpack: {type(exc).__name__}") from None
    if not isinstance(message, dict):
        raise MessageError(f"expected a map, got {type(message).__name__}")
    if message.get("v") != VERSION:
        raise MessageError(f"unsupported schema version {message.get('v')!r} (this build reads {VERSION})")
    return message


def _number(message: dict[str, Any], key: str) -> float:
    value = message.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise MessageError(f"{key}: expected a number, got {value!r:.40}")
    if not math.isfinite(value):
        raise MessageError(f"{key}: not finite")
    return float(value)


def _integer(message: dict[str, Any], key: str, low: int, high: int) -> int:
    value = message.get(key)
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise MessageError(f"{key}: expected an integer in {low}..{high}, got {value!r:.40}")
    return value


def _vector(message: dict[str, Any], key: str) -> tuple[float, float, float]:
    value = message.get(key)
    if not isinstance(value, list) or len(value) != 3:
        raise MessageError(f"{key}: expected a list of 3 numbers")
    return tuple(_number({key: v}, key) for v in value)


def imu_message(sample: ImuSample) -> dict[str, Any]:
    return {"v": VERSION, "seq": sample.seq, "t": sample.t, "dtheta": list(sample.dtheta), "dv": list(sample.dv),
            "status": sample.status}


def decode_imu(data: bytes) -> ImuSample:
    m = unpack_map(data)
    return ImuSample(_integer(m, "seq", 0, 2**32 - 1), _number(m, "t"), _vector(m, "dtheta"), _vector(m, "dv"),
                     _integer(m, "status", 0, 2**32 - 1))


AIDING_FIELDS = {"odo": {"v_b": 3}, "gnss": {"lat_deg": 1, "lon_deg": 1, "h_m": 1, "v_enu": 3},
                 "master": {"q": 4, "v_enu": 3, "lat_deg": 1, "lon_deg": 1, "h_m": 1}}
"""Fields of each aiding kind and how many numbers each holds (1 = a scalar)."""
AIDING_FIELDS_FLAT = {kind: [f"{name}{i}" if n > 1 else name for name, n in fields.items() for i in range(n)]
                      for kind, fields in AIDING_FIELDS.items()}
"""The numbers of each kind one by one, in the pinned log's column order (after t)."""


@dataclass(frozen=True, slots=True)
class AidingSample:
    kind: str
    seq: int
    t: float
    values: dict[str, tuple[float, ...]]


def aiding_row(sample: AidingSample) -> list[float]:
    """[t, values…] in the kind's pinned log column order (what an aiding track takes)."""
    return [sample.t, *(v for name in AIDING_FIELDS[sample.kind] for v in sample.values[name])]


def aiding_sample(kind: str, seq: int, row: list[float] | tuple[float, ...]) -> AidingSample:
    """The epoch of ``row`` = [t (s), values…] in the kind's pinned log column order (inverse of :func:`aiding_row`)."""
    values, at = {}, 1
    for name, count in AIDING_FIELDS[kind].items():
        values[name] = tuple(float(v) for v in row[at:at + count])
        at += count
    if at != len(row):
        raise MessageError(f"aiding {kind}: expected t and {at - 1} values, got {len(row)} numbers")
    return AidingSample(kind, seq, float(row[0]), values)


def aiding_message(sample: AidingSample) -> dict[str, Any]:
    fields = {k: (v[0] if AIDING_FIELDS[sample.kind][k] == 1 else list(v)) for k, v in sample.values.items()}
    return {"v": VERSION, "seq": sample.seq, "t": sample.t, **fields}


def decode_aiding(kind: str, data: bytes) -> AidingSample:
    """An aiding message of ``kind`` (the last chunk of its key), checked against the kind's fields and what such a
    source can physically report (:func:`~.plausibility.aiding_problem`)."""
    if kind not in AIDING_FIELDS:
        raise MessageError(f"unknown aiding kind {kind!r} (known: {', '.join(AIDING_FIELDS)})")
    m = unpack_map(data)
    values = {}
    for name, count in AIDING_FIELDS[kind].items():
        if count == 1:
            values[name] = (_number(m, name),)
            continue
        value = m.get(name)
        if not isinstance(value, list) or len(value) != count:
            raise MessageError(f"{name}: expected a list of {count} numbers")
        values[name] = tuple(_number({name: v}, name) for v in value)
    problem = aiding_problem(kind, values)
    if problem is not None:
        raise MessageError(f"aiding {kind}: {problem}")
    return AidingSample(kind, _integer(m, "seq", 0, 2**32 - 1), _number(m, "t"), values)


def attitude_message(unit: str, record: ResultRecord) -> dict[str, Any]:
    return {"v": VERSION, "unit": unit, **record.wire_dict()}


def decode_attitude(data: bytes) -> dict[str, Any]:
    m = unpack_map(data)
    for key in ("t", "heading_deg", "pitch_deg", "roll_deg", "heading_sigma_deg", "level_sigma_deg"):
        _number(m, key)
    if not isinstance(m.get("q"), list) or len(m["q"]) != 4 or not isinstance(m.get("phase"), str):
        raise MessageError("attitude: q must be 4 numbers and phase a string")
    if "mount_q" in m or "mount_sigma_deg" in m:   # transfer alignment's mounting: both, or neither
        mount_q = m.get("mount_q")
        if not isinstance(mount_q, list) or len(mount_q) != 4:
            raise MessageError("attitude: mount_q must be 4 numbers")
        for c in mount_q:
            _number({"mount_q": c}, "mount_q")
        _number(m, "mount_sigma_deg")
    return m


def status_message(unit: str, uptime_s: float, health: str, phase: str, t_last: float | None,
                   last_error: str | None, counters: dict[str, int],
                   loop: dict[str, float | int | None] | None = None) -> dict[str, Any]:
    return {"v": VERSION, "unit": unit, "uptime_s": uptime_s, "health": health, "phase": phase, "t_last": t_last,
            "last_error": last_error, "counters": counters, "loop": loop}


def decode_status(data: bytes) -> dict[str, Any]:
    m = unpack_map(data)
    if m.get("health") not in HEALTH or not isinstance(m.get("counters"), dict) or \
            not isinstance(m.get("loop", {}), dict | None):
        raise MessageError("status: health must be one of " + ", ".join(HEALTH) + ", counters a map and loop a map "
                           "or null")
    return m

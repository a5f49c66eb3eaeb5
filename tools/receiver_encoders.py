"""The bench's emulated GNSS receiver: a scenario's gnss epochs as NMEA 0183 sentences or u-blox UBX NAV-PVT
messages, made with pynmeagps and pyubx2 and quantised as those formats are.

An epoch is (t in s, lat_deg, lon_deg, h_m above the ellipsoid, v_E, v_N, v_U in m/s); its UTC time is
:data:`UTC_START` + t. NMEA (the high-precision output some receivers offer): latitude and longitude in degrees and
minutes with 7 decimals of minutes (2e-4 m), the ellipsoidal height as the altitude with 3 decimals (m) and a
geoid separation of 0, speed over ground in knots and course over ground in degrees with 3 decimals each, the time
with 2 decimals of seconds; the cycle is RMC, VTG, GGA (a u-blox receiver's order). NAV-PVT: 1e-7° of latitude and
longitude, mm of height, mm/s of velocity, the accuracies stated in mm and mm/s.
"""
from __future__ import annotations

import datetime
import math

import numpy as np
from pynmeagps import NMEAMessage
from pyubx2 import GET, UBXMessage

UTC_START = datetime.datetime(2026, 1, 1, tzinfo=datetime.UTC)
"""The UTC time of the scenario's t = 0."""
GPS_EPOCH = datetime.datetime(1980, 1, 6, tzinfo=datetime.UTC)
GPS_LEAP_S = 18
"""GPS time runs ahead of UTC by the leap seconds since 1980 (18 since 2017)."""
KNOT_MPS = 1852.0 / 3600.0
KMH_MPS = 1.0 / 3.6


def _utc(t_s: float) -> datetime.datetime:
    # to the hundredth of a second, as NMEA's time field carries it
    return UTC_START + datetime.timedelta(seconds=round(t_s, 2))


def _ground_track(v_e: float, v_n: float) -> tuple[float, float]:
    """(speed over ground in m/s, course over ground in degrees from true north, 0 to 360)."""
    return math.hypot(v_e, v_n), math.degrees(math.atan2(v_e, v_n)) % 360.0


def nmea_epoch(epoch: np.ndarray, talker: str = "GN") -> bytes:
    """The RMC, VTG and GGA sentences of one epoch (module docstring)."""
    t, lat, lon, h, v_e, v_n, _ = (float(v) for v in epoch)
    utc = _utc(t)
    speed, course = _ground_track(v_e, v_n)
    place = {"lat": lat, "lon": lon}   # pynmeagps writes N/S and E/W from the signs
    knots, course = round(speed / KNOT_MPS, 3), round(course, 3) % 360.0
    sentences = [
        NMEAMessage(talker, "RMC", GET, hpnmeamode=True, time=utc.time(), date=utc.date(), status="A", **place,
                    spd=knots, cog=course, mv="", mvEW="", posMode="A", navStatus="V"),
        NMEAMessage(talker, "VTG", GET, cogt=course, cogtUnit="T", cogm="", cogmUnit="M", sogn=knots, sognUnit="N",
                    sogk=round(speed / KMH_MPS, 3), sogkUnit="K", posMode="A"),
        NMEAMessage(talker, "GGA", GET, hpnmeamode=True, time=utc.time(), **place, quality=1, numSV=12, HDOP=0.8,
                    alt=round(h, 3), altUnit="M", sep=0.0, sepUnit="M", diffAge="", diffStation=""),
    ]
    return b"".join(s.serialize() for s in sentences)


def _scaled(value: float, resolution: float) -> float:
    """``value`` for a field pyubx2 scales by ``resolution``: it truncates value / resolution toward zero, so the
    nearest step is given half a step outward (its truncation is that step whatever the float rounding)."""
    k = round(value / resolution)
    return 0.0 if k == 0 else (k + math.copysign(0.5, k)) * resolution


def ubx_epoch(epoch: np.ndarray, pos_acc_m: float, vel_acc_mps: float) -> bytes:
    """The NAV-PVT message of one epoch with a 3-D fix, stating hAcc = vAcc = ``pos_acc_m`` and sAcc =
    ``vel_acc_mps`` (module docstring)."""
    t, lat, lon, h, v_e, v_n, v_u = (float(v) for v in epoch)
    utc = _utc(t)
    speed, course = _ground_track(v_e, v_n)
    gps_ms = round(((utc - GPS_EPOCH).total_seconds() + GPS_LEAP_S) * 1000.0)
    mm = round(h * 1000.0)
    return UBXMessage(
        "NAV", "NAV-PVT", GET, iTOW=gps_ms % (7 * 86400 * 1000), year=utc.year, month=utc.month, day=utc.day,
        hour=utc.hour, min=utc.minute, second=utc.second, validDate=1, validTime=1, fullyResolved=1,
        nano=utc.microsecond * 1000, fixType=3, gnssFixOk=1, numSV=12, lon=_scaled(lon, 1e-7), lat=_scaled(lat, 1e-7),
        height=mm, hMSL=mm, hAcc=round(pos_acc_m * 1000.0), vAcc=round(pos_acc_m * 1000.0),
        velN=round(v_n * 1000.0), velE=round(v_e * 1000.0), velD=-round(v_u * 1000.0), gSpeed=round(speed * 1000.0),
        headMot=_scaled(course, 1e-5), sAcc=round(vel_acc_mps * 1000.0), headAcc=_scaled(1.0, 1e-5),
        pDOP=_scaled(1.2, 0.01)).serialize()

"""GNSS receiver decoders (NMEA 0183 GGA + RMC/VTG, UBX NAV-PVT), their time mapping and their place on the IMU's
line.

The NMEA sentences are the GGA, RMC and VTG examples of u-blox's receiver description (the 092725.00 GGA at
47°17.11399' N, 8°33.91590' E, 499.6 m + 48.0 m; the 0.004-kn, 77.52° RMC and VTG), some with their time or a field
changed and the checksum made anew. The NAV-PVT vector is packed here field by field from the u-blox layout
(class 0x01, id 0x07, 92 bytes; lat/lon in 1e-7°, height in mm, NED velocity in mm/s) with its own Fletcher-8
checksum, apart from pyubx2's encoder.
"""
from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pynmeagps.nmeahelpers import calc_checksum
from sinsalign.protocol.gnss_nmea import KNOT_MPS, NmeaDecoder
from sinsalign.protocol.gnss_ubx import UbxDecoder
from sinsalign.protocol.serial_frame import encode_imu
from sinsalign.service.arrival_clock import ArrivalClock
from sinsalign.service.config import config_from_mapping
from sinsalign.service.gnss_receiver import GnssReceiver
from sinsalign.service.ingest import Ingest
from sinsalign.tools.receiver_encoders import nmea_epoch, ubx_epoch

GGA = b"$GPGGA,092725.00,4717.11399,N,00833.91590,E,1,08,1.01,499.6,M,48.0,M,,*5B\r\n"
RMC = b"$GPRMC,083559.00,A,4717.11437,N,00833.91522,E,0.004,77.52,091202,,,A*57\r\n"
VTG = b"$GPVTG,77.52,T,,M,0.004,N,0.008,K,A*06\r\n"


def sentence(body: str) -> bytes:
    """``$body*HH`` CR LF with its checksum."""
    return f"${body}*{calc_checksum(body)}\r\n".encode()


def changed(line: bytes, old: str, new: str) -> bytes:
    """A published sentence with ``old`` replaced by ``new`` and its checksum made anew."""
    return sentence(line.decode()[1:-5].replace(old, new, 1))


GGA_BEFORE = changed(changed(GGA, "092725.00", "092724.00"), "499.6", "499.1")   # 1 s earlier, 0.5 m lower
RMC_SAME = changed(RMC, "083559.00", "092725.00")


def vel(speed_kn: float, course_deg: float) -> tuple[float, float]:
    s, c = speed_kn * KNOT_MPS, math.radians(course_deg)
    return s * math.sin(c), s * math.cos(c)


def nav_pvt(lat_deg=47.2852332, lon_deg=8.565265, height_mm=547600, vel_ned_mm_s=(1000, -2000, 300), fix_type=3,
            flags=0x01, acc_mm=(1500, 2500, 80), itow_ms=123_456_000) -> bytes:
    """A NAV-PVT message packed from the u-blox layout (module docstring)."""
    h_acc, v_acc, s_acc = acc_mm
    payload = struct.pack("<IHBBBBBBIiBBBBiiiiIIiiiiiIIHHIiHH", itow_ms, 2026, 1, 1, 12, 0, 0, 0x07, 30, 0, fix_type,
                          flags, 0, 12, round(lon_deg * 1e7), round(lat_deg * 1e7), height_mm, height_mm - 48000,
                          h_acc, v_acc, *vel_ned_mm_s, 2236, 0, s_acc, 100000, 120, 0, 0, 0, 0, 0)
    body = b"\x01\x07" + struct.pack("<H", len(payload)) + payload
    a = b = 0
    for byte in body:
        a = (a + byte) & 0xFF
        b = (b + a) & 0xFF
    return b"\xb5\x62" + body + bytes((a, b))


# ---- NMEA ---------------------------------------------------------------------------------------------------------

def test_gga_with_the_rmc_of_its_time_is_one_epoch_at_the_ellipsoidal_height():
    decoder = NmeaDecoder()
    fixes = decoder.feed(GGA_BEFORE + RMC_SAME + GGA, 7.0)
    assert len(fixes) == 1
    fix = fixes[0]
    assert fix.lat_deg == pytest.approx(47 + 17.11399 / 60, abs=1e-9)
    assert fix.lon_deg == pytest.approx(8 + 33.91590 / 60, abs=1e-9)
    assert fix.h_m == pytest.approx(499.6 + 48.0)                                   # altitude + geoid separation
    assert fix.v_enu == pytest.approx((*vel(0.004, 77.52), 0.5), abs=1e-9)          # v_U: 0.5 m over 1 s
    assert fix.arrival_s == 7.0 and fix.time_s == 9 * 3600 + 27 * 60 + 25
    assert decoder.counters()["no_vertical"] == 1 and decoder.counters()["unpaired"] == 0


@pytest.mark.parametrize("order", ["gga-vtg", "vtg-gga"])
def test_a_stream_without_rmc_takes_the_vtg_of_the_ggas_output_cycle(order):
    decoder = NmeaDecoder()
    cycle = GGA + VTG if order == "gga-vtg" else VTG + GGA
    fixes = decoder.feed((GGA_BEFORE + VTG if order == "gga-vtg" else VTG + GGA_BEFORE) + cycle, 0.0)
    assert len(fixes) == 1 and fixes[0].v_enu[:2] == pytest.approx(vel(0.004, 77.52), abs=1e-12)


def test_with_rmc_in_the_stream_vtg_is_left_aside_and_a_lonely_gga_is_dropped_counted():
    decoder = NmeaDecoder()
    later = changed(GGA, "092725.00", "092726.00")
    assert decoder.feed(GGA_BEFORE + RMC_SAME + VTG + GGA + VTG + later + changed(RMC, "083559.00", "092727.00"),
                        0.0)
    assert decoder.counters()["unpaired"] == 1   # the 092726 GGA had no RMC when 092727 began


def test_no_fix_and_bad_checksums_are_dropped_and_counted():
    decoder = NmeaDecoder()
    no_fix = changed(GGA, ",1,08,", ",0,00,")
    void = changed(changed(RMC, ",A,4717", ",V,4717"), "083559.00", "092726.00")
    bad = GGA.replace(b"*5B", b"*5C")
    assert decoder.feed(GGA_BEFORE + no_fix + RMC_SAME + bad + void + GGA, 0.0) == []
    counts = decoder.counters()
    assert counts["no_fix"] == 2 and counts["checksum_errors"] == 1


def test_dead_reckoning_is_no_fix():
    """GGA quality 6 and an RMC or VTG whose mode indicator says estimated (E) are the receiver's extrapolation, not a
    measurement: dropped as no fix, whichever of the cycle's sentences says so and in either order."""
    dead_gga = changed(GGA, ",1,08,", ",6,08,")
    dead_rmc = changed(RMC_SAME, "091202,,,A", "091202,,,E")
    dead_vtg = changed(VTG, ",K,A", ",K,E")
    for stream in (GGA_BEFORE + dead_gga + RMC_SAME, GGA_BEFORE + GGA + dead_rmc, GGA_BEFORE + GGA + dead_vtg,
                   GGA_BEFORE + dead_vtg + GGA):
        decoder = NmeaDecoder()
        assert decoder.feed(stream, 0.0) == []
        assert decoder.counters()["no_fix"] == 1 and decoder.counters()["unpaired"] == 0
    decoder = NmeaDecoder()
    assert len(decoder.feed(GGA_BEFORE + GGA + VTG, 0.0)) == 1   # the same cycle with a fix


def test_every_chunking_gives_the_same_epochs():
    stream = b"".join(nmea_epoch(np.array([0.02 * k, 30.0 + 1e-6 * k, 114.0, 3000.0 + 0.01 * k, 70.0, 70.0, 0.5]))
                      for k in range(1, 6))
    whole = NmeaDecoder().feed(stream, 1.0)
    assert len(whole) == 4
    for step in (1, 2, 7, 61):
        decoder = NmeaDecoder()
        pieces = [decoder.feed(stream[i:i + step], 1.0) for i in range(0, len(stream), step)]
        assert [f for p in pieces for f in p] == whole


def test_the_bench_encoder_quantises_as_nmea_does():
    epochs = [np.array([0.02, -30.123456789, -114.98765432, 3000.1234, 70.1234567, -70.654321, 0.0]),
              np.array([0.04, -30.1234571, -114.98765, 3000.1480, 70.1234567, -70.654321, 0.0])]
    (fix,) = NmeaDecoder().feed(nmea_epoch(epochs[0]) + nmea_epoch(epochs[1]), 0.0)
    assert abs(fix.lat_deg - epochs[1][1]) * 60 <= 0.5e-7 + 1e-12          # 7 decimals of minutes
    assert math.hypot(*(np.array(fix.v_enu[:2]) - epochs[1][4:6])) < 0.0005 * KNOT_MPS + 0.0005 * math.pi / 180 * 100
    assert fix.v_enu[2] == pytest.approx((3000.148 - 3000.123) / 0.02)     # from the mm heights


# ---- UBX ----------------------------------------------------------------------------------------------------------

def test_nav_pvt_gives_position_enu_velocity_and_the_receivers_accuracies():
    (fix,) = UbxDecoder().feed(nav_pvt(), 3.0)
    assert (fix.lat_deg, fix.lon_deg, fix.h_m) == pytest.approx((47.2852332, 8.565265, 547.6))
    assert fix.v_enu == pytest.approx((-2.0, 1.0, -0.3))   # velN 1, velE -2, velD 0.3 m/s
    assert (fix.h_acc_m, fix.v_acc_m, fix.s_acc_mps) == pytest.approx((1.5, 2.5, 0.08))
    assert fix.time_s == 123_456.0


def test_nav_pvt_without_a_gnss_fix_and_bad_checksums_are_counted():
    """A 2-D fix, dead reckoning alone (fixType 1) and any fix without gnssFixOK are no fix; a 3-D fix and GNSS with
    dead reckoning combined (fixType 4, an automotive receiver's output) with gnssFixOK are."""
    bad = bytearray(nav_pvt())
    bad[-1] ^= 0xFF
    decoder = UbxDecoder()
    stream = (nav_pvt(fix_type=2) + nav_pvt(fix_type=1) + nav_pvt(fix_type=4, flags=0) + nav_pvt(flags=0) + bytes(bad)
              + nav_pvt() + nav_pvt(fix_type=4, height_mm=548600))
    assert [fix.h_m for fix in decoder.feed(stream, 0.0)] == [547.6, 548.6]
    assert decoder.counters() == {"checksum_errors": 1, "no_fix": 4}


def test_nav_pvt_in_any_pieces_among_other_bytes():
    stream = b"\xb5\x62\x01\x07" + nav_pvt() + b"\x00\xb5" + ubx_epoch(np.array([1.0, 30, 114, 3000, 1, 2, 3]), 2, .1)
    whole = UbxDecoder().feed(stream, 0.0)
    assert len(whole) == 2 and whole[1].v_enu == pytest.approx((1.0, 2.0, 3.0))
    for step in (1, 3, 50):
        decoder = UbxDecoder()
        assert [f for i in range(0, len(stream), step) for f in decoder.feed(stream[i:i + step], 0.0)] == whole


# ---- time mapping, refusal, the IMU's line ------------------------------------------------------------------------

def test_the_arrival_clock_keeps_the_least_lag_and_follows_a_slower_clock_slowly():
    clock = ArrivalClock(drift_rate=1e-3)
    clock.observe(np.array([10.0, 10.01]), 100.05)   # 40 ms late
    clock.observe(np.array([10.02]), 100.03)         # 10 ms late: the least so far
    clock.observe(np.array([11.0]), 101.5)           # a late batch: the offset falls by 1e-3 s/s only
    assert clock.offset_s == pytest.approx(10.02 - 100.03 - 1e-3 * (101.5 - 100.03))
    assert clock.source_time(100.03) == pytest.approx(100.03 + clock.offset_s)
    assert clock.arrival_time(clock.source_time(5.0)) == pytest.approx(5.0)


def receiver(decoder, **gnss) -> GnssReceiver:
    clock = ArrivalClock()
    clock.observe(np.array([50.0]), 1000.0)   # IMU time = host time − 950 s
    return GnssReceiver(decoder, clock, config_from_mapping({"aiding": {"gnss": gnss}}).aiding.gnss)


def test_receiver_epochs_go_on_the_imu_clock_by_their_least_lag_and_keep_their_spacing():
    rx = receiver(UbxDecoder())
    out = rx.feed(nav_pvt(itow_ms=1000) + nav_pvt(itow_ms=1020) + nav_pvt(itow_ms=1040), 1000.5)
    assert [e.t for e in out.aiding] == pytest.approx([50.46, 50.48, 50.5])
    late = rx.feed(nav_pvt(itow_ms=1060), 1000.9)     # a late read: the least lag stays
    assert late.aiding[0].t == pytest.approx(50.52)


def test_a_ubx_epoch_stating_worse_than_3_times_the_configured_noise_is_dropped_counted():
    rx = receiver(UbxDecoder(), pos_std_m=0.5)
    assert rx.feed(nav_pvt(acc_mm=(1600, 1000, 50)), 1000.0).aiding == []
    assert rx.feed(nav_pvt(acc_mm=(1400, 1400, 50), itow_ms=1), 1000.0).aiding
    assert rx.counters()["gnss_rx_inaccurate"] == 1


@pytest.mark.parametrize("stream, reason", [
    (changed(GGA_BEFORE, "4717", "9517") + changed(GGA, "4717", "9517") + changed(RMC_SAME, "4717", "9517"),
     "latitude 95.28"),
    (GGA_BEFORE + GGA + changed(RMC_SAME, "0.004", "1000000.0"), "speed 514444 m/s")])
def test_well_formed_but_absurd_epochs_are_refused_with_their_reason_as_bad_aiding(stream, reason):
    config = config_from_mapping({"aiding": {"inputs": ["gnss"], "gnss": {"input": "nmea"}}})
    reports = []
    ingest = Ingest(config, reports.append)
    ingest.decode_serial(encode_imu(0, 1.0, np.zeros(3), np.zeros(3)), 0.0)
    ingest.decode_serial(stream, 0.1)
    assert ingest.counters.bad_aiding == 1 and ingest.aiding_inbox == []
    assert reason in reports[-1]


def test_nmea_on_the_imus_line_among_its_frames():
    config = config_from_mapping({"aiding": {"inputs": ["gnss"], "gnss": {"input": "nmea"}}})
    ingest = Ingest(config, lambda _text: None)
    epochs = [np.array([0.02 * k, 30.0, 114.0, 3000.0, 10.0, 0.0, 0.0]) for k in range(1, 5)]
    line = b"".join(encode_imu(k, 0.02 * k, np.zeros(3), np.zeros(3)) + nmea_epoch(epochs[k - 1]) for k in range(1, 5))
    samples = np.concatenate([ingest.decode_serial(line[i:i + 50], 10.0) for i in range(0, len(line), 50)])
    assert len(samples) == 4
    assert [kind for kind, _ in ingest.aiding_inbox] == ["gnss"] * 3   # the first: no height before it
    assert ingest.aiding_inbox[0][1].values["v_enu"] == pytest.approx((10.0, 0.0, 0.0), abs=1e-3)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=400), st.integers(1, 64))
def test_garbage_never_raises_in_either_decoder(data, step):
    for decoder in (NmeaDecoder(), UbxDecoder()):
        for i in range(0, len(data), step):
            decoder.feed(data[i:i + step], 0.0)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from(["", "0", "-1", "9999.9", "1e308", "nan", "inf", "x", ",", "*"]), min_size=14,
                max_size=14))
def test_well_formed_sentences_of_absurd_fields_are_counted_or_refused_never_raised(fields):
    rx = receiver(NmeaDecoder())
    body = ",".join(["GPGGA", "092725.00", *fields[:12]])
    rmc = ",".join(["GPRMC", "092725.00", "A", *fields[2:4], "N", *fields[4:6], "E", *fields[12:14], "091202"])
    out = rx.feed(sentence(changed(GGA, "092725.00", "092724.00").decode()[1:-5]) + sentence(body) + sentence(rmc),
                  1000.0)
    for epoch in out.aiding:
        assert all(math.isfinite(v) for values in epoch.values.values() for v in values)

"""NMEA 0183 sentences (protocol/nmea_out.py) read back by independent parsers: pynmeagps for every sentence,
pynmea2 for HDT, ROT and PASHR (it has no THS)."""
from __future__ import annotations

import math

import pynmea2
import pynmeagps
import pytest
from hypothesis import given
from hypothesis import strategies as st
from sinsalign.protocol import nmea_out
from sinsalign.protocol.results import PHASES, ResultRecord
from sinsalign.service.config import ConfigError, config_from_mapping


def record(heading_deg: float = 123.456, converged: bool = True, phase: str = "aligned", t: float = 1_764_680_400.25,
           **fields) -> ResultRecord:
    values = {"pitch_deg": 1.234, "roll_deg": -2.345, "heading_sigma_deg": 0.0567, "level_sigma_deg": 0.0089, **fields}
    return ResultRecord(t=t, phase=phase, q=(1.0, 0.0, 0.0, 0.0), heading_deg=heading_deg, converged=converged,
                        rho=0.0, trace_P=0.0, n_obs=0, **values)


def parse(sentence: bytes) -> pynmeagps.NMEAMessage:
    """pynmeagps's reading, its checksum checked (it raises on a wrong one)."""
    assert sentence.endswith(b"\r\n") and sentence.count(b"*") == 1
    return pynmeagps.NMEAReader.parse(sentence, validate=pynmeagps.VALCKSUM)


def angle_error(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@pytest.mark.parametrize("heading_deg", [0.0, 0.004, 123.456, 359.994, 359.999])
def test_heading_sentences_give_the_records_heading_within_a_hundredth_of_a_degree(heading_deg: float) -> None:
    r = record(heading_deg)
    ths, hdt, pashr = parse(nmea_out.ths("HE", r)), parse(nmea_out.hdt("HE", r)), parse(nmea_out.pashr(r))
    assert (ths.talker, ths.msgID, hdt.talker, hdt.msgID) == ("HE", "THS", "HE", "HDT")
    for value in (ths.headt, hdt.headingT, pashr.trueHdg, pynmea2.parse(nmea_out.pashr(r).decode()).true_heading,
                  float(pynmea2.parse(nmea_out.hdt("HE", r).decode()).heading)):
        assert 0.0 <= value < 360.0 and angle_error(value, heading_deg) <= 0.005 + 1e-9


def test_ths_mode_is_a_only_while_converged_and_hdt_holds_no_heading_before() -> None:
    assert parse(nmea_out.ths("IN", record(converged=True))).mi == "A"
    for phase in PHASES:
        assert parse(nmea_out.ths("IN", record(converged=False, phase=phase))).mi == "V"
    assert parse(nmea_out.hdt("IN", record(converged=False))).headingT == ""


def test_pashr_carries_the_records_attitude_its_sigmas_and_status() -> None:
    r = record()
    m = parse(nmea_out.pashr(r))
    assert (m.roll, m.pitch, m.trueHdgInd) == (pytest.approx(-2.35, abs=0.005), pytest.approx(1.23, abs=0.005), "T")
    assert m.rollAcc == m.pitchAcc == pytest.approx(r.level_sigma_deg, abs=5e-4)
    assert m.hdgAcc == pytest.approx(r.heading_sigma_deg, abs=5e-4)
    assert (m.gnssQual, m.imuAlign, m.reserved) == (nmea_out.GNSS_QUALITY, 3, "")
    assert m.utctime.strftime("%H%M%S.%f") == "130000.250000"   # 2025-12-02 13:00:00.25 UTC
    other = pynmea2.parse(nmea_out.pashr(r).decode())
    assert (other.roll_accuracy, other.heading_accuracy, int(other.imu_status)) == (0.009, 0.057, 3)
    statuses = {phase: parse(nmea_out.pashr(record(converged=False, phase=phase))).imuAlign for phase in PHASES}
    assert statuses == {"coarse": 1, "fine": 2, "aligned": 2, "disturbed": 2}


def test_rate_of_turn_is_the_headings_change_per_minute_negative_to_port() -> None:
    sentences = nmea_out.NmeaSentences(["ROT"], "HE", 10.0)
    first = parse(sentences.feed(record(359.9, t=100.0))[0])
    assert (first.rot, first.valid) == ("", "V")                # no earlier record
    across_north = parse(sentences.feed(record(0.1, t=100.5))[0])
    assert (across_north.rot, across_north.valid) == (pytest.approx(24.0), "A")   # +0.2° in 0.5 s, to starboard
    to_port = pynmea2.parse(sentences.feed(record(0.05, t=101.0, converged=False))[0].decode())
    assert (float(to_port.rate_of_turn), to_port.status) == (pytest.approx(-6.0), "V")


def test_sentences_come_at_the_rate_on_the_records_grid() -> None:
    sentences = nmea_out.NmeaSentences(["THS", "PASHR"], "HE", 2.0)
    sent = [t for t in [k * 0.1 for k in range(31)] if sentences.feed(record(t=t))]
    assert sent == pytest.approx([0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0])
    assert len(sentences.feed(record(t=10.0))) == 2            # after a gap: at once, and on from there


def test_a_serial_line_too_slow_for_the_sentences_is_refused_at_the_start() -> None:
    table = {"serial": "/dev/ttyS0", "sentences": ["THS", "ROT", "PASHR"], "baud": 4800}
    config_from_mapping({"nmea": {**table, "rate_hz": 3.0}})
    with pytest.raises(ConfigError, match=r"nmea\.baud, nmea\.rate_hz"):
        config_from_mapping({"nmea": {**table, "rate_hz": 4.0}})
    config_from_mapping({"nmea": {**table, "rate_hz": 4.0, "baud": 38400}})
    config_from_mapping({"nmea": {"udp": ["127.0.0.1:10110"], "rate_hz": 50.0}})   # UDP alone has no baud rate
    assert nmea_out.max_length("PASHR", "HE") == len(b"$PASHR,235959.99,359.99,T,-179.99,-89.99,,999.999,999.999,"
                                                     b"999.999,0,3*00\r\n")


@pytest.mark.parametrize("udp", ["10110", "host:", "host:0", "host:65536", ":10110", "host:1x"])
def test_a_destination_that_is_not_host_port_is_refused(udp: str) -> None:
    with pytest.raises(ConfigError, match=r"nmea\.udp"):
        config_from_mapping({"nmea": {"udp": [udp]}})


numbers = st.floats(allow_nan=True, allow_infinity=True) | st.floats(-1e6, 1e6) | st.sampled_from(
    [359.999, 359.995, -0.0, -1e-12, 360.0, 720.004])


@given(heading=numbers, roll=numbers, pitch=numbers, heading_sigma=numbers, level_sigma=numbers,
       t=st.floats(0.0, 4e9) | st.sampled_from([86399.999, 86399.994]), converged=st.booleans(),
       phase=st.sampled_from(PHASES))
def test_any_record_gives_valid_sentences_with_values_or_empty_fields(heading, roll, pitch, heading_sigma,
                                                                      level_sigma, t, converged, phase) -> None:
    r = record(heading, converged, phase, t, roll_deg=roll, pitch_deg=pitch, heading_sigma_deg=heading_sigma,
               level_sigma_deg=level_sigma)
    sentences = nmea_out.NmeaSentences(nmea_out.SENTENCES, "HE", 1.0)
    sentences.feed(record(t=t - 1.0))
    for sentence in sentences.feed(r):
        assert len(sentence) <= nmea_out.max_length(sentence[3:6].decode() if sentence[1:2] != b"P" else "PASHR",
                                                    "HE")
        parse(sentence)
    m = parse(nmea_out.pashr(r))
    if math.isfinite(heading):
        assert 0.0 <= m.trueHdg < 360.0 and angle_error(m.trueHdg, heading) <= 0.005 + 1e-6 * abs(heading)
    else:
        assert m.trueHdg == "" and parse(nmea_out.ths("HE", r)).mi == "V"
    for field, value in ((m.hdgAcc, heading_sigma), (m.rollAcc, level_sigma)):
        assert field == "" if not 0.0 <= value <= nmea_out.SIGMA_LIMIT_DEG else field == pytest.approx(value, abs=5e-4)

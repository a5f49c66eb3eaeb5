"""The NMEA 0183 and ROS 2 outputs through real parts: a daemon fed over Zenoh on loopback, its sentences sent to
a UDP socket on 127.0.0.1 and written to a pty, its Imu messages on Zenoh.

GIVEN 20 s of simulated IMU data played as fast as the daemon takes it, WHEN it aligns with ``[nmea] udp``,
``[nmea] serial`` and ``[ros2] enabled``, THEN every sentence set, over UDP and on the line, gives the heading of
the attitude message of its epoch within 0.01°, and each Imu message decodes (rosbags) to that attitude.
"""
from __future__ import annotations

import os
import socket
import time

import numpy as np
import pynmeagps
import zenoh
from rosbags.typesys import Stores, get_typestore
from sinsalign.protocol import messages
from sinsalign.protocol.ros_imu import IMU_TYPE, ros_quaternion
from support.daemon_harness import RunningDaemon, free_port, samples, wait_until

SECONDS = 20.0


def test_nmea_over_udp_and_serial_and_ros_imu_on_zenoh_follow_the_attitude(tmp_path, pty_pair) -> None:
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", free_port()))
    receiver.setblocking(False)
    nmea_line = pty_pair   # the daemon writes its port_name; the test reads master_fd
    try:
        run = RunningDaemon(tmp_path, zenoh={"imu_input": True},
                            nmea={"udp": [f"127.0.0.1:{receiver.getsockname()[1]}"], "serial": nmea_line.port_name,
                                  "baud": 38400, "rate_hz": 2.0, "sentences": ["THS", "HDT", "ROT", "PASHR"]},
                            ros2={"enabled": True, "frame_id": "bench_imu"})
        session, keys = run.subscriber.session, run.daemon.keys
        ros: list[bytes] = []
        subscriber = session.declare_subscriber(keys.ros_imu, lambda s: ros.append(s.payload.to_bytes()))
        publisher = session.declare_publisher(keys.imu, congestion_control=zenoh.CongestionControl.BLOCK)
        time.sleep(0.3)   # the subscriber's declaration reaches the daemon
        n_records = int(SECONDS / run.config.output.period_s)
        seq, udp, serial = 0, [], b""
        for chunk in samples(SECONDS):
            for k in range(len(chunk.t)):
                sample = messages.ImuSample(seq, float(chunk.t[k]), tuple(chunk.dtheta[k]), tuple(chunk.dv[k]), 0)
                publisher.put(messages.pack(messages.imu_message(sample)))
                seq += 1
            udp, serial = udp + datagrams(receiver), serial + pty_bytes(nmea_line.master_fd)
        assert wait_until(lambda: len(run.subscriber.attitude) >= n_records and len(ros) >= n_records)
        time.sleep(0.2)
        udp, serial = udp + datagrams(receiver), serial + pty_bytes(nmea_line.master_fd)
        counters = run.daemon.all_counters()
        subscriber.undeclare()
        run.stop()
    finally:
        receiver.close()
    attitude = {round(m["t"], 2): m for m in run.subscriber.attitude}
    assert len(attitude) == n_records and counters["nmea_send_errors"] == counters["nmea_serial_dropped"] == 0
    for sentences in (udp, [line + b"\r\n" for line in serial.split(b"\r\n") if line]):
        assert len(sentences) == 4 * n_records   # one set per record: 2 Hz on records every 0.5 s
        check_sets(sentences, attitude)
    check_ros(ros, attitude)


def datagrams(sock: socket.socket) -> list[bytes]:
    received = []
    while True:
        try:
            received.append(sock.recv(256))
        except BlockingIOError:
            return received


def pty_bytes(fd: int) -> bytes:
    data = b""
    while True:
        try:
            data += os.read(fd, 65536)
        except BlockingIOError:
            return data


def check_sets(sentences: list[bytes], attitude: dict[float, dict]) -> None:
    """Each THS, HDT, ROT, PASHR set against the attitude message of the PASHR's time (the data start at t = 0 s,
    so the time of day is t)."""
    for k in range(0, len(sentences), 4):
        ths, hdt, rot, pashr = (pynmeagps.NMEAReader.parse(s, validate=pynmeagps.VALCKSUM) for s in sentences[k:k + 4])
        assert (ths.msgID, hdt.msgID, rot.msgID, pashr.msgID) == ("THS", "HDT", "ROT", "ASHR")
        clock = pashr.utctime
        t = clock.hour * 3600 + clock.minute * 60 + clock.second + clock.microsecond / 1e6
        m = attitude[round(t, 2)]
        for heading in (ths.headt, pashr.trueHdg, *([hdt.headingT] if m["converged"] else [])):
            assert abs((heading - m["heading_deg"] + 180.0) % 360.0 - 180.0) <= 0.01
        assert ths.mi == ("A" if m["converged"] else "V") and pashr.hdgAcc == round(m["heading_sigma_deg"], 3)


def check_ros(received: list[bytes], attitude: dict[float, dict]) -> None:
    store = get_typestore(Stores.ROS2_HUMBLE)
    for data in received:
        message = store.deserialize_cdr(data, IMU_TYPE)
        m = attitude[round(message.header.stamp.sec + message.header.stamp.nanosec * 1e-9, 2)]
        o = message.orientation
        assert message.header.frame_id == "bench_imu"
        assert np.allclose([o.x, o.y, o.z, o.w], ros_quaternion(tuple(m["q"])), atol=1e-12)

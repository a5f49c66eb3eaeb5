"""Security on loopback: Zenoh TLS set through a standard Zenoh configuration file.

GIVEN a daemon listening on TLS with a certificate signed by a throw-away CA, WHEN one client
trusts that CA and another does not, THEN the first receives attitude and the second cannot
even open its session (nothing is received without the certificate chain).
"""
from __future__ import annotations

import datetime
import ipaddress
import json
import time
from pathlib import Path

import pytest
import zenoh
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID
from daemon_harness import RunningDaemon, daemon_config, free_port, run_daemon
from sinsalign.protocol import messages
from sinsalign.service.daemon import Daemon
from sinsalign.service.serial_port import SerialPort
from sinsalign.service.zenoh_session import open_session
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import get_scenario
from sinsalign.tools.virtual_imu import FramePlayer, PtyPair


def _pem(key) -> bytes:
    return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())


def make_certificates(folder: Path) -> dict[str, Path]:
    """A CA and a server certificate for localhost / 127.0.0.1, as PEM files."""
    now = datetime.datetime.now(datetime.UTC)
    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "sinsalign test CA")])
    ca = (x509.CertificateBuilder().subject_name(ca_name).issuer_name(ca_name).public_key(ca_key.public_key())
          .serial_number(x509.random_serial_number()).not_valid_before(now - datetime.timedelta(minutes=5))
          .not_valid_after(now + datetime.timedelta(days=1))
          .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
          .sign(ca_key, hashes.SHA256()))
    key = ec.generate_private_key(ec.SECP256R1())
    cert = (x509.CertificateBuilder().subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "localhost")]))
            .issuer_name(ca_name).public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5)).not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.SubjectAlternativeName([x509.DNSName("localhost"),
                                                        x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]),
                           critical=False)
            .sign(ca_key, hashes.SHA256()))
    files = {"ca": folder / "ca.pem", "cert": folder / "server.pem", "key": folder / "server.key"}
    files["ca"].write_bytes(ca.public_bytes(serialization.Encoding.PEM))
    files["cert"].write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    files["key"].write_bytes(_pem(key))
    return files


def client_config(port: int, ca: Path | None) -> zenoh.Config:
    conf = zenoh.Config()
    for key, value in (("mode", '"peer"'), ("scouting/multicast/enabled", "false"), ("scouting/delay", "0"),
                       ("listen/endpoints", "[]"), ("connect/endpoints", f'["tls/localhost:{port}"]'),
                       ("connect/timeout_ms", "2000"), ("connect/exit_on_failure", "true")):
        conf.insert_json5(key, value)
    if ca is not None:
        conf.insert_json5("transport/link/tls/root_ca_certificate", json.dumps(str(ca)))
    return conf


def test_tls_client_without_the_certificate_gets_nothing(tmp_path):
    files = make_certificates(tmp_path)
    port = free_port()
    server_file = tmp_path / "zenoh-server.json5"
    server_file.write_text(json.dumps({
        "mode": "peer", "scouting": {"multicast": {"enabled": False}},
        "listen": {"endpoints": [f"tls/localhost:{port}"]},
        "transport": {"link": {"tls": {"listen_private_key": str(files["key"]),
                                       "listen_certificate": str(files["cert"])}}}}))
    pty = PtyPair()
    config = daemon_config(tmp_path, port, serial={"path": pty.port_name},
                           zenoh={"config_file": str(server_file), "listen": []})
    daemon = Daemon(config, open_session(config.zenoh), SerialPort(pty.port_name, config.serial.baud))
    trusted = zenoh.open(client_config(port, files["ca"]))
    received = []
    sub = trusted.declare_subscriber(daemon.keys.attitude, lambda s: received.append(
        messages.decode_attitude(s.payload.to_bytes())))
    with pytest.raises(zenoh.ZError):
        zenoh.open(client_config(port, None))     # no CA: the TLS handshake fails, no session at all
    thread = run_daemon(daemon)
    scenario = get_scenario("seed000-swing")
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, 10.0, 1)
    FramePlayer(pty.master_fd, 20.0).play(chunk.t, chunk.dtheta, chunk.dv)
    deadline = time.monotonic() + 10
    while len(received) < 20 and time.monotonic() < deadline:
        time.sleep(0.02)
    daemon.stop()
    thread.join(timeout=5)
    sub.undeclare()
    trusted.close()
    pty.close()
    assert len(received) == 20 and received[-1]["t"] == 10.0


def test_nothing_on_the_wire_changes_the_configuration_and_the_state_query_is_read_only(tmp_path):
    run = RunningDaemon(tmp_path)
    config, daemon, client = run.config, run.daemon, run.subscriber
    hostile = messages.pack({"v": 1, "config": {"zenoh": {"unit": "pwned"}, "daemon": {"record_path": "/tmp/x"}}})
    for key in (daemon.keys.state, f"{daemon.keys.prefix}/{daemon.keys.unit}/config", daemon.keys.status):
        client.session.put(key, hostile)
        client.session.delete(key)
    replies = []
    deadline = time.monotonic() + 5
    while not replies and time.monotonic() < deadline:
        replies = [r.ok for r in client.session.get(daemon.keys.state, payload=hostile, timeout=1.0)
                   if r.ok is not None]
    run.stop()
    state = messages.unpack_map(replies[0].payload.to_bytes())
    assert state["config"]["zenoh"]["unit"] == "bench" and state["config"]["daemon"]["record_path"].endswith(
        "recorded.csv")
    assert daemon.config == config

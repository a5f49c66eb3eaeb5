"""Security on loopback: Zenoh TLS, mutual TLS and access control set through standard Zenoh files.

GIVEN a daemon listening on TLS with a certificate signed by a throw-away CA, WHEN one client
trusts that CA and another does not, THEN the first receives attitude and the second cannot
even open its session (nothing is received without the certificate chain).

GIVEN the daemon started with docs/zenoh-mtls.json5 (mutual TLS, access control denying by default;
only the certificate folder and the port replaced), THEN a client without a certificate of that CA
cannot open a session, a CA-signed client whose common name has no rights receives nothing and
feeds nothing into the pipeline, the "imu-source" feeds the alignment and the "bridge" receives
attitude, status, the liveliness token and the state; with access control switched off the same
unauthorised client would get through (the control that the other tests can fail).
"""
from __future__ import annotations

import datetime
import ipaddress
import json
import threading
import time
from pathlib import Path, PurePosixPath

import pytest
import zenoh
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID
from sinsalign.protocol import messages
from sinsalign.service.daemon import Daemon
from sinsalign.service.serial_port import SerialPort
from sinsalign.service.zenoh_session import open_session
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import get_scenario
from sinsalign.tools.virtual_imu import FramePlayer, PtyPair
from support.daemon_harness import RunningDaemon, daemon_config, free_port, run_daemon, wait_until

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "zenoh-mtls.json5"
EXAMPLE_FOLDER = "/etc/sinsalign/tls"
EXAMPLE_ENDPOINT = "tls/localhost:7447"
IMU_SOURCE, BRIDGE, INTRUDER = "imu-source", "bridge", "intruder"


def _pem(key) -> bytes:
    return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())


def make_certificates(folder: Path, clients: tuple[str, ...] = (), ca_name: str = "sinsalign test CA"
                      ) -> dict[str, Path]:
    """A CA, the daemon's certificate for localhost / 127.0.0.1 and one client certificate per common name
    in ``clients``, as PEM files in ``folder``: keys "ca", "cert", "key" (the daemon's) and "<cn>.cert",
    "<cn>.key"; the file names are the ones docs/zenoh-mtls.json5 uses (ca.pem, daemon.pem, daemon.key)."""
    folder.mkdir(parents=True, exist_ok=True)
    now = datetime.datetime.now(datetime.UTC)
    ca_key = ec.generate_private_key(ec.SECP256R1())
    issuer = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, ca_name)])
    ca = (x509.CertificateBuilder().subject_name(issuer).issuer_name(issuer).public_key(ca_key.public_key())
          .serial_number(x509.random_serial_number()).not_valid_before(now - datetime.timedelta(minutes=5))
          .not_valid_after(now + datetime.timedelta(days=1))
          .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
          .sign(ca_key, hashes.SHA256()))
    files = {"ca": folder / "ca.pem"}
    files["ca"].write_bytes(ca.public_bytes(serialization.Encoding.PEM))

    def leaf(stem: str, common_name: str, usage, names=()) -> tuple[Path, Path]:
        key = ec.generate_private_key(ec.SECP256R1())
        builder = (x509.CertificateBuilder()
                   .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)]))
                   .issuer_name(issuer).public_key(key.public_key()).serial_number(x509.random_serial_number())
                   .not_valid_before(now - datetime.timedelta(minutes=5))
                   .not_valid_after(now + datetime.timedelta(days=1))
                   .add_extension(x509.ExtendedKeyUsage([usage]), critical=False))
        if names:
            builder = builder.add_extension(x509.SubjectAlternativeName(list(names)), critical=False)
        cert_file, key_file = folder / f"{stem}.pem", folder / f"{stem}.key"
        cert_file.write_bytes(builder.sign(ca_key, hashes.SHA256()).public_bytes(serialization.Encoding.PEM))
        key_file.write_bytes(_pem(key))
        return cert_file, key_file

    files["cert"], files["key"] = leaf("daemon", "localhost", ExtendedKeyUsageOID.SERVER_AUTH,
                                       (x509.DNSName("localhost"), x509.IPAddress(ipaddress.ip_address("127.0.0.1"))))
    for name in clients:
        files[f"{name}.cert"], files[f"{name}.key"] = leaf(name, name, ExtendedKeyUsageOID.CLIENT_AUTH)
    return files


def client_config(port: int, ca: Path | None, cert: Path | None = None, key: Path | None = None,
                  mode: str = "peer", timeout_ms: int = 2000) -> zenoh.Config:
    """A client connecting to tls/localhost:``port``; with ``cert`` and ``key`` it presents them (mutual TLS)."""
    conf = zenoh.Config()
    for name, value in (("mode", json.dumps(mode)), ("scouting/multicast/enabled", "false"), ("scouting/delay", "0"),
                        ("listen/endpoints", "[]"), ("connect/endpoints", f'["tls/localhost:{port}"]'),
                        ("connect/timeout_ms", str(timeout_ms)), ("connect/exit_on_failure", "true")):
        conf.insert_json5(name, value)
    if ca is not None:
        conf.insert_json5("transport/link/tls/root_ca_certificate", json.dumps(str(ca)))
    if cert is not None:
        conf.insert_json5("transport/link/tls/enable_mtls", "true")
        conf.insert_json5("transport/link/tls/connect_certificate", json.dumps(str(cert)))
        conf.insert_json5("transport/link/tls/connect_private_key", json.dumps(str(key)))
    return conf


def load_example() -> dict:
    """docs/zenoh-mtls.json5 as a mapping (the file is JSON with whole-line // comments)."""
    return json.loads("\n".join(line for line in EXAMPLE.read_text().splitlines()
                                 if not line.lstrip().startswith("//")))


def secure_config_file(folder: Path, port: int, access_control: bool = True) -> Path:
    """docs/zenoh-mtls.json5 with its certificate folder replaced by ``folder`` (files from
    :func:`make_certificates`) and its port by ``port``; ``access_control=False`` only for the control test."""
    conf = load_example()
    tls = conf["transport"]["link"]["tls"]
    for name in ("root_ca_certificate", "listen_certificate", "listen_private_key"):
        path = PurePosixPath(tls[name])
        assert str(path.parent) == EXAMPLE_FOLDER and (folder / path.name).is_file(), tls[name]
        tls[name] = str(folder / path.name)
    assert conf["listen"]["endpoints"] == [EXAMPLE_ENDPOINT]
    conf["listen"]["endpoints"] = [f"tls/localhost:{port}"]
    conf["access_control"]["enabled"] = access_control
    target = folder / "zenoh-mtls.json5"
    target.write_text(json.dumps(conf, indent=1))
    return target


class SecureDaemon:
    """The real daemon (Zenoh IMU input on, no serial port) on the example file; clients by common name."""

    def __init__(self, tmp_path: Path, access_control: bool = True) -> None:
        self.files = make_certificates(tmp_path / "tls", (IMU_SOURCE, BRIDGE, INTRUDER))
        self.port = free_port()
        zenoh_file = secure_config_file(tmp_path / "tls", self.port, access_control)
        self.config = daemon_config(tmp_path, self.port,
                                    zenoh={"config_file": str(zenoh_file), "listen": [], "imu_input": True,
                                           "unit": "unit1"})   # the example's rules are unit1's
        self.daemon = Daemon(self.config, open_session(self.config.zenoh))
        self.keys = self.daemon.keys
        self.sessions: list[zenoh.Session] = []
        self.thread = threading.Thread(target=self.daemon.run, daemon=True)
        self.thread.start()

    def client(self, common_name: str, mode: str = "peer") -> zenoh.Session:
        session = zenoh.open(client_config(self.port, self.files["ca"], self.files[f"{common_name}.cert"],
                                           self.files[f"{common_name}.key"], mode))
        self.sessions.append(session)
        return session

    def stop(self) -> None:
        self.daemon.stop()
        self.thread.join(timeout=5)
        while self.sessions:
            self.sessions.pop().close()
        assert not self.thread.is_alive()


class Listener:
    """What one client session receives of the daemon's attitude, status and liveliness token."""

    def __init__(self, session: zenoh.Session, keys) -> None:
        self.attitude: list[dict] = []
        self.status: list[dict] = []
        self.alive: list[zenoh.SampleKind] = []
        self.entities = [
            session.declare_subscriber(keys.attitude, lambda s: self.attitude.append(
                messages.decode_attitude(s.payload.to_bytes()))),
            session.declare_subscriber(keys.status, lambda s: self.status.append(
                messages.decode_status(s.payload.to_bytes()))),
            session.liveliness().declare_subscriber(keys.alive, lambda s: self.alive.append(s.kind), history=True)]


@pytest.fixture
def secure(tmp_path):
    """Starts :class:`SecureDaemon` (``secure(access_control=False)`` for the control); stopped after the test."""
    started = []

    def start(access_control: bool = True) -> SecureDaemon:
        started.append(SecureDaemon(tmp_path, access_control))
        return started[-1]
    yield start
    for run in started:
        run.stop()


def imu_messages(seconds: float = 10.0) -> list[bytes]:
    scenario = get_scenario("seed000-swing")
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, seconds, 1)
    return [messages.pack(messages.imu_message(messages.ImuSample(k, float(chunk.t[k]), tuple(chunk.dtheta[k]),
                                                                  tuple(chunk.dv[k]), 0)))
            for k in range(len(chunk.t))]


def put_all(session: zenoh.Session, key: str, payloads: list[bytes]) -> None:
    publisher = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
    for payload in payloads:
        publisher.put(payload)
    publisher.undeclare()


FAKE_ATTITUDE = messages.pack({"v": messages.VERSION, "unit": "unit1", "t": -1.0, "heading_deg": 123.0,
                               "pitch_deg": 0.0, "roll_deg": 0.0, "heading_sigma_deg": 0.01,
                               "level_sigma_deg": 0.01, "q": [1.0, 0.0, 0.0, 0.0], "phase": "fine"})
"""A well-formed attitude message nobody computed (t = -1 s)."""


def state_replies(session: zenoh.Session, key: str) -> list[dict]:
    return [messages.unpack_map(r.ok.payload.to_bytes()) for r in session.get(key, timeout=1.0) if r.ok is not None]


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


def test_the_example_file_is_read_by_zenoh_as_the_tests_read_it():
    """The tests parse docs/zenoh-mtls.json5 by dropping its comment lines: Zenoh's own reader sees the same."""
    example, conf = load_example(), zenoh.Config.from_file(str(EXAMPLE))
    seen = json.loads(conf.get_json("access_control"))
    seen["subjects"] = [{k: v for k, v in subject.items() if v is not None} for subject in seen["subjects"]]
    assert seen == example["access_control"]
    tls = json.loads(conf.get_json("transport/link/tls"))
    assert {k: v for k, v in tls.items() if v is not None} == example["transport"]["link"]["tls"]
    assert json.loads(conf.get_json("listen/endpoints")) == [EXAMPLE_ENDPOINT]
    assert tls["enable_mtls"] is True and seen["enabled"] is True and seen["default_permission"] == "deny"


def test_mtls_a_client_without_a_certificate_of_the_ca_cannot_open_a_session(tmp_path, secure):
    run = secure()
    foreign = make_certificates(tmp_path / "foreign", (IMU_SOURCE,), ca_name="another CA")
    with pytest.raises(zenoh.ZError):   # the CA alone (server-side TLS only): the daemon asks for a certificate
        zenoh.open(client_config(run.port, run.files["ca"], timeout_ms=1000))
    with pytest.raises(zenoh.ZError):   # the right common name, signed by another CA
        zenoh.open(client_config(run.port, run.files["ca"], foreign[f"{IMU_SOURCE}.cert"],
                                 foreign[f"{IMU_SOURCE}.key"], timeout_ms=1000))
    bridge = Listener(run.client(BRIDGE), run.keys)   # the listener is there: the refusals were the handshake's
    assert wait_until(lambda: len(bridge.status) >= 2)


def test_mtls_a_certified_client_without_rights_gets_nothing_and_feeds_nothing(secure):
    run = secure()
    daemon, keys = run.daemon, run.keys
    payloads = imu_messages()
    intruders = {mode: run.client(INTRUDER, mode) for mode in ("client", "peer")}   # both handshakes succeed
    seen = {mode: Listener(session, keys) for mode, session in intruders.items()}
    bridge_session = run.client(BRIDGE)
    bridge = Listener(bridge_session, keys)
    for session in (*intruders.values(), bridge_session):   # a reader may not write either
        put_all(session, keys.imu, payloads)
    run.client(INTRUDER, "client").put(keys.attitude, FAKE_ATTITUDE)   # the daemon routes for client sessions
    assert wait_until(lambda: len(bridge.status) >= 5)   # about 1 s of status: the daemon is serving
    assert daemon.counters.samples_in_zenoh == 0 and daemon.counters.bad_messages == 0
    assert all(state_replies(session, keys.state) == [] for session in intruders.values())
    put_all(run.client(IMU_SOURCE), keys.imu, payloads)   # now the real source: there is attitude to steal
    assert wait_until(lambda: len(bridge.attitude) >= 20, timeout_s=8.0)
    assert daemon.counters.samples_in_zenoh == len(payloads)
    assert len(bridge.attitude) == 20 and min(a["t"] for a in bridge.attitude) > 0   # the fake did not pass
    for listener in seen.values():
        assert (listener.attitude, listener.status, listener.alive) == ([], [], [])
    assert bridge.alive == [zenoh.SampleKind.PUT]


def test_mtls_the_imu_source_feeds_the_alignment_and_the_bridge_reads_the_results(secure):
    run = secure()
    daemon, keys = run.daemon, run.keys
    bridge_session = run.client(BRIDGE)
    bridge = Listener(bridge_session, keys)
    assert wait_until(lambda: daemon.attitude_subscribed)
    payloads = imu_messages()
    source_client = run.client(IMU_SOURCE, "client")
    put_all(source_client, keys.imu, payloads[:1000])   # either session mode
    assert wait_until(lambda: daemon.counters.samples_in_zenoh == 1000)    # (two links: not interleaved)
    source_client.put(keys.attitude, FAKE_ATTITUDE)      # the source may put the inputs, nothing else
    source_peer = run.client(IMU_SOURCE)
    source = Listener(source_peer, keys)                   # ... and reads nothing
    put_all(source_peer, keys.imu, payloads[1000:])
    assert wait_until(lambda: len(bridge.attitude) >= 20, timeout_s=8.0)
    assert daemon.counters.samples_in_zenoh == len(payloads) and bridge.attitude[-1]["t"] == 10.0
    assert len(bridge.attitude) == 20 and min(a["t"] for a in bridge.attitude) > 0
    (state,) = state_replies(bridge_session, keys.state)
    assert state["attitude"]["t"] == 10.0 and state["config"]["zenoh"]["imu_input"] is True
    assert bridge.status and bridge.alive == [zenoh.SampleKind.PUT]
    assert (source.attitude, source.status, source.alive, state_replies(source_peer, keys.state)) == ([], [], [], [])


def test_control_without_access_control_the_certified_intruder_would_feed_the_alignment(secure):
    """The same file with access control off: the unauthorised client's puts arrive, its fake attitude reaches
    the bridge and it reads everything, so the assertions of the tests above can fail."""
    run = secure(access_control=False)
    bridge = Listener(run.client(BRIDGE), run.keys)
    intruder_session = run.client(INTRUDER, "client")
    intruder = Listener(intruder_session, run.keys)
    payloads = imu_messages(2.0)
    put_all(intruder_session, run.keys.imu, payloads)
    assert wait_until(lambda: run.daemon.counters.samples_in_zenoh == len(payloads))
    intruder_session.put(run.keys.attitude, FAKE_ATTITUDE)
    assert wait_until(lambda: any(a["t"] == -1.0 for a in bridge.attitude))
    assert wait_until(lambda: len(intruder.status) >= 2) and intruder.alive == [zenoh.SampleKind.PUT]
    assert len(state_replies(intruder_session, run.keys.state)) == 1

"""The Zenoh session's configuration keeps the daemon on loopback unless told otherwise.

GIVEN no file, or a standard Zenoh file that sets only some keys (TLS, access control), THEN every key the file
leaves at Zenoh's own default (listen on all interfaces, multicast scouting) gets sinsalign's loopback default, and
what the file or the command line sets explicitly is kept.
"""
from __future__ import annotations

import json

import zenoh
from sinsalign.service.config import ZenohConfig
from sinsalign.service.zenoh_session import DEFAULT_LISTEN, open_session, session_config
from support.daemon_harness import free_port


def value(conf: zenoh.Config, key: str):
    return json.loads(conf.get_json(key))


def write(tmp_path, content: dict) -> str:
    path = tmp_path / "zenoh.json5"
    path.write_text(json.dumps(content))
    return str(path)


def test_a_file_that_sets_only_tls_keeps_the_loopback_defaults(tmp_path):
    file = write(tmp_path, {"transport": {"link": {"tls": {"root_ca_certificate": "ca.pem"}}}})
    conf = session_config(ZenohConfig(config_file=file))
    assert value(conf, "listen/endpoints") == list(DEFAULT_LISTEN)
    assert value(conf, "scouting/multicast/enabled") is False
    assert value(conf, "scouting/gossip/enabled") is False
    assert value(conf, "mode") == "peer"
    assert value(conf, "transport/link/tls/root_ca_certificate") == "ca.pem"


def test_what_the_file_sets_is_kept_and_the_command_line_goes_on_top(tmp_path):
    port = free_port()
    file = write(tmp_path, {"mode": "peer", "listen": {"endpoints": [f"tcp/127.0.0.1:{port}"]},
                            "scouting": {"multicast": {"enabled": True}}})
    conf = session_config(ZenohConfig(config_file=file))
    assert value(conf, "listen/endpoints") == [f"tcp/127.0.0.1:{port}"]
    assert value(conf, "scouting/multicast/enabled") is True
    other = f"tcp/127.0.0.1:{free_port()}"
    assert value(session_config(ZenohConfig(config_file=file, listen=(other,))), "listen/endpoints") == [other]


def test_a_client_file_listens_nowhere_and_connecting_needs_no_listener(tmp_path):
    client = session_config(ZenohConfig(config_file=write(tmp_path, {"mode": "client"})))
    assert value(client, "listen/endpoints") == []
    connecting = session_config(ZenohConfig(connect=("tcp/127.0.0.1:1",)))
    assert value(connecting, "listen/endpoints") == []


def test_a_session_from_a_partial_file_opens_on_loopback(tmp_path):
    port = free_port()
    file = write(tmp_path, {"transport": {"link": {"tx": {"lease": 10000}}}})
    session = open_session(ZenohConfig(config_file=file, listen=(f"tcp/127.0.0.1:{port}",)))
    try:
        assert value(session_config(ZenohConfig(config_file=file)), "scouting/multicast/enabled") is False
    finally:
        session.close()

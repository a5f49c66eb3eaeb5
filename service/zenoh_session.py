"""Opening the Zenoh session from the configuration (transport-notes.md §1).

The embedded default is a peer on loopback with multicast scouting off and explicit endpoints:
nothing leaves the machine unless the configuration says so. A standard Zenoh JSON5 file
(``zenoh.config_file``) is the base when given; mode, listen and connect from sinsalign's
configuration or the command line go on top.
"""
from __future__ import annotations

import json

import zenoh

from .config import ZenohConfig

DEFAULT_LISTEN = ("tcp/127.0.0.1:7447",)
"""Where the embedded default listens: loopback only."""


def session_config(z: ZenohConfig) -> zenoh.Config:
    """A zenoh.Config for ``z``; raises ZError with Zenoh's own message on a bad file or key.

    Without a file: the embedded default (peer, multicast scouting off, listen on
    ``DEFAULT_LISTEN`` unless told otherwise). With a file (TLS, access control, a router
    deployment …): the file as written, with only what the configuration or the command line
    states explicitly (mode, listen, connect) put on top.
    """
    if z.config_file:
        conf = zenoh.Config.from_file(z.config_file)
    else:
        conf = zenoh.Config()
        conf.insert_json5("scouting/multicast/enabled", "false")
        conf.insert_json5("scouting/gossip/enabled", "false")
        conf.insert_json5("scouting/delay", "0")
        # sub-second reconnects instead of the default 1 s → 4 s back-off (transport-notes pitfall 4)
        conf.insert_json5("connect/retry", "{period_init_ms: 100, period_max_ms: 500, period_increase_factor: 1.5}")
        conf.insert_json5("listen/endpoints", json.dumps(list(z.listen or (() if z.connect else DEFAULT_LISTEN))))
        conf.insert_json5("connect/endpoints", json.dumps(list(z.connect)))
    if z.mode or not z.config_file:
        conf.insert_json5("mode", json.dumps(z.mode or "peer"))
    if z.config_file and z.listen:
        conf.insert_json5("listen/endpoints", json.dumps(list(z.listen)))
    if z.config_file and z.connect:
        conf.insert_json5("connect/endpoints", json.dumps(list(z.connect)))
    return conf


def open_session(z: ZenohConfig) -> zenoh.Session:
    return zenoh.open(session_config(z))

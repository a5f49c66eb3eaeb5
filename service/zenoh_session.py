"""Opening the Zenoh session from the configuration.

The embedded default is a peer on loopback with multicast scouting off and explicit endpoints:
nothing leaves the machine unless the configuration says so (a plain ``zenoh.Config()`` scouts by UDP multicast
and listens on every interface), with or without a standard Zenoh JSON5 file
(``zenoh.config_file``) as the base; mode, listen and connect from sinsalign's configuration or the command
line go on top.
"""
from __future__ import annotations

import json

import zenoh

from .config import ZenohConfig

DEFAULT_LISTEN = ("tcp/127.0.0.1:7447",)
"""Where the embedded default listens: loopback only."""


LOOPBACK_DEFAULTS = (
    ("scouting/multicast/enabled", "false"),
    ("scouting/gossip/enabled", "false"),
    ("scouting/delay", "0"),
    # sub-second reconnects: Zenoh's default back-off (1 s, 2 s, 4 s) leaves up to 4 s without data after a peer is back
    ("connect/retry", "{period_init_ms: 100, period_max_ms: 500, period_increase_factor: 1.5}"),
)
"""What sinsalign sets where a configuration leaves Zenoh's own default: no multicast scouting (Zenoh's default
announces the session on the LAN), no waiting for scouting at open, quick reconnects."""


def session_config(z: ZenohConfig) -> zenoh.Config:
    """A zenoh.Config for ``z``; raises ZError with Zenoh's own message on a bad file or key.

    The base is a standard Zenoh JSON5 file (``z.config_file``: TLS, access control, a router deployment …) or
    nothing. Every key of :data:`LOOPBACK_DEFAULTS`, and the listen endpoints (:data:`DEFAULT_LISTEN`, none when
    connecting), that the base leaves at Zenoh's default gets sinsalign's: Zenoh's defaults listen on every
    interface and scout by multicast, so a file that sets only TLS must not open the daemon to the network. What
    the configuration or the command line states (mode, listen, connect) goes on top.
    """
    conf = zenoh.Config.from_file(z.config_file) if z.config_file else zenoh.Config()
    pristine = zenoh.Config()
    if z.mode or conf.get_json("mode") == pristine.get_json("mode"):
        conf.insert_json5("mode", json.dumps(z.mode or "peer"))
    client = json.loads(conf.get_json("mode")) == "client"     # a client listens nowhere
    listen = json.dumps(list(() if z.connect or client else DEFAULT_LISTEN))
    for key, value in (*LOOPBACK_DEFAULTS, ("listen/endpoints", listen)):
        if conf.get_json(key) == pristine.get_json(key):
            conf.insert_json5(key, value)
    if z.listen:
        conf.insert_json5("listen/endpoints", json.dumps(list(z.listen)))
    if z.connect:
        conf.insert_json5("connect/endpoints", json.dumps(list(z.connect)))
    return conf


def open_session(z: ZenohConfig) -> zenoh.Session:
    return zenoh.open(session_config(z))

"""The daemon's Zenoh outputs: each attitude record and the periodic status as msgpack, a liveliness token, and
a read-only state query (``messages`` documents the payloads, ``protocol/keys.py`` the key expressions).

Another output format (NMEA sentences, ROS 2 messages) is another class with :meth:`ZenohOutputs.records` and
``close``: the loop hands every output the same records.
"""
from __future__ import annotations

from collections.abc import Callable

import zenoh

from ..protocol import messages
from ..protocol.keys import UnitKeys
from ..protocol.results import ResultRecord

MSGPACK = zenoh.Encoding("application/msgpack")


class ZenohOutputs:
    """Publishers of ``keys``' attitude and status topics on ``session``, its liveliness token, and the state
    queryable, which answers with ``state()``."""

    def __init__(self, session: zenoh.Session, keys: UnitKeys, state: Callable[[], dict]) -> None:
        self.keys = keys
        self._state = state
        self._attitude = session.declare_publisher(keys.attitude, encoding=MSGPACK)
        self._status = session.declare_publisher(keys.status, encoding=MSGPACK)
        self._token = session.liveliness().declare_token(keys.alive)
        self._queryable = session.declare_queryable(keys.state, self._on_query)

    def records(self, records: list[ResultRecord]) -> None:
        """Publish each record as an attitude message, in order."""
        for record in records:
            self._attitude.put(messages.pack(messages.attitude_message(self.keys.unit, record)))

    def status(self, status: dict) -> None:
        self._status.put(messages.pack(status))

    @property
    def attitude_subscribed(self) -> bool:
        """Some subscriber matches the attitude key."""
        return self._attitude.matching_status.matching

    def _on_query(self, query: zenoh.Query) -> None:
        query.reply(self.keys.state, messages.pack(self._state()), encoding=MSGPACK)

    def close(self) -> None:
        for entity in (self._queryable, self._token, self._status, self._attitude):
            entity.undeclare()

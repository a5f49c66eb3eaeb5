"""The daemon's Zenoh inputs: the IMU topic (if configured) and each aiding kind's topic, decoded in the loop.

Zenoh delivers on its own threads; the callbacks only hand the payload (not even copied) to a bounded
:class:`~.inbox.Inbox`, and the loop decodes what has arrived. A message that does not decode is counted
(``bad_messages``, ``bad_aiding``) and dropped; the IMU messages' sequence counters are checked
(``zenoh_seq_*``), the inboxes' overflow and oversized payloads counted.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import zenoh

from ..protocol import messages
from ..protocol.keys import UnitKeys
from ..protocol.sequence import SequenceTracker
from .inbox import Inbox
from .ingest import SampleCounters
from .sample_gate import sample_rows

INBOX_LIMIT = 100_000
"""Messages each Zenoh inbox holds for the loop (8 minutes of a 200-Hz IMU)."""
INBOX_BYTES = 32 << 20
"""Bytes each Zenoh inbox holds: the messages' limit at their usual size, three times over."""


class ZenohInputs:
    """Subscribers of ``keys``' IMU topic (``imu``) and aiding topics (``aid_kinds``) on ``session``; ``counters``
    (the ingest's) take the decoding drops, ``report`` a line for the operator."""

    def __init__(self, session: zenoh.Session, keys: UnitKeys, imu: bool, aid_kinds: tuple[str, ...],
                 counters: SampleCounters, report: Callable[[str], None]) -> None:
        self.keys = keys
        self.aid_kinds = aid_kinds
        self.sequence = SequenceTracker(modulus=1 << 32)
        self._counters = counters
        self._report = report
        self._imu_inbox: Inbox[zenoh.ZBytes] = Inbox(INBOX_LIMIT, INBOX_BYTES)
        self._aid_inbox: Inbox[tuple[str, zenoh.ZBytes]] = Inbox(INBOX_LIMIT, INBOX_BYTES)
        self._imu_sub = session.declare_subscriber(keys.imu, self._on_imu) if imu else None
        self._aid_subs = [session.declare_subscriber(keys.aid(kind), self._aid_callback(kind)) for kind in aid_kinds]

    @property
    def takes_imu(self) -> bool:
        return self._imu_sub is not None

    def _on_imu(self, sample: zenoh.Sample) -> None:
        # a Zenoh thread: only hand the payload over (not even copied); decoding happens in the loop
        self._imu_inbox.put(sample.payload, len(sample.payload))

    def _aid_callback(self, kind: str) -> Callable[[zenoh.Sample], None]:
        def on_aid(sample: zenoh.Sample) -> None:   # a Zenoh thread: hand the payload over
            self._aid_inbox.put((kind, sample.payload), len(sample.payload))
        return on_aid

    def imu_samples(self, wait_s: float) -> np.ndarray:
        """The IMU samples that arrived (waiting up to ``wait_s`` for the first), decoded, in arrival order (N,
        :data:`~.sample_gate.SAMPLE_COLUMNS`); a message that does not decode, or comes again or from the past, is
        dropped and counted."""
        if self._imu_sub is None:
            return sample_rows([])
        out = []
        for payload in self._imu_inbox.drain(wait_s):
            try:
                m = messages.decode_imu(payload.to_bytes())
            except messages.MessageError as exc:
                self._counters.bad_messages += 1
                self._report(f"IMU message dropped: {exc}")
                continue
            if self.sequence.accept(m.seq):
                out.append((m.t, m.dtheta, m.dv, m.status, False))
        self._counters.samples_in_zenoh += len(out)
        return sample_rows(out)

    def aiding_epochs(self) -> list[tuple[str, messages.AidingSample]]:
        """Every aiding epoch that arrived, decoded, in arrival order; a bad one counted and dropped."""
        epochs = []
        for kind, payload in self._aid_inbox.drain():
            try:
                epochs.append((kind, messages.decode_aiding(kind, payload.to_bytes())))
            except messages.MessageError as exc:
                self._counters.bad_aiding += 1
                self._report(f"aiding message on {self.keys.aid(kind)} dropped: {exc}")
        return epochs

    def counters(self) -> dict[str, int]:
        """The IMU topic's sequence counters, and what the inboxes dropped (``inbox_overflow`` to add to the
        ingest's, ``oversized_messages``)."""
        inboxes = (self._imu_inbox, self._aid_inbox)
        return {**self.sequence.counters("zenoh_seq_"), "inbox_overflow": sum(i.overflow for i in inboxes),
                "oversized_messages": sum(i.oversized for i in inboxes)}

    def texts(self) -> list[str]:
        """What they take, for the operator's log."""
        imu = [f"Zenoh {self.keys.imu}"] if self._imu_sub is not None else []
        return imu + [f"{kind} aiding (Zenoh {self.keys.aid(kind)}, serial aiding frames)" for kind in self.aid_kinds]

    def close(self) -> None:
        for sub in (self._imu_sub, *self._aid_subs):
            if sub is not None:
                sub.undeclare()

"""What arrives on the serial line, decoded: a format turns the bytes of any read into IMU sample rows and aiding
epochs, and keeps its own counters.

The ingest core (ingest.py) takes a format and never looks inside it, so a vendor's frame (a STIM300 datagram, a
KVH or Xsens message) is another class with the same three members, and nothing else changes. The project's own
frame (protocol/serial_frame.py) is :class:`SinsalignFrames`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..protocol import messages
from ..protocol.serial_frame import MSG_AIDING, MSG_IMU, FrameDecoder, decode_aiding, decode_imu
from .sample_gate import sample_rows


@dataclass(slots=True)
class Decoded:
    """What one read gave: IMU samples (N, :data:`~.sample_gate.SAMPLE_COLUMNS`), aiding epochs in arrival order,
    and a line per unit that was dropped for what it held (its frame was whole: counted as ``bad_aiding``)."""

    samples: np.ndarray
    aiding: list[messages.AidingSample] = field(default_factory=list)
    refused: list[str] = field(default_factory=list)


class SerialFormat(Protocol):
    """A serial input format: bytes in any pieces in, :class:`Decoded` out, the same whatever the pieces."""

    def feed(self, data: bytes) -> Decoded: ...

    def counters(self) -> dict[str, int]: ...


class SinsalignFrames:
    """The project's own frame: IMU increments (type 1) and aiding epochs (type 2) on one line, each checked by its
    CRC and sequence counter (:class:`~sinsalign.protocol.serial_frame.FrameDecoder`)."""

    def __init__(self) -> None:
        self.decoder = FrameDecoder()

    def feed(self, data: bytes) -> Decoded:
        samples, out = [], Decoded(np.empty(0))
        for frame in self.decoder.feed(data):
            if frame.msg_type == MSG_IMU:
                m = decode_imu(frame)
                samples.append((m.t, m.dtheta, m.dv, m.status, m.saturated))
            elif frame.msg_type == MSG_AIDING:
                try:
                    out.aiding.append(decode_aiding(frame))
                except messages.MessageError as exc:
                    out.refused.append(f"serial aiding frame dropped: {exc}")
        out.samples = sample_rows(samples)
        return out

    def counters(self) -> dict[str, int]:
        """The decoder's and its sequence counters (protocol/README.md, "Decoder rules and counters")."""
        return self.decoder.all_counters()

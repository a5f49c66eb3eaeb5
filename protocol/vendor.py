"""What every vendor IMU decoder (stim300.py, kvh.py, xsens.py, declared_frame.py) gives: the samples of the frames
a read completed, in the sensor's own axes and on the sensor's own counter, and lines for the operator.

A decoder is sans-I/O: bytes in any pieces in, the same samples out whatever the pieces; it keeps its counters
(status names, documented with :func:`~.counters.count`). The service's VendorFrames (service/serial_formats.py)
stamps the counter into time (:class:`~.counter_clock.CounterClock`), turns the axes into the body's and hands
the rows to the sample gate.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


@dataclass(slots=True)
class SensorSamples:
    """N decoded samples: ``counter`` (N,) the frame's counter (raw, wrapping at the decoder's ``counter_modulus``),
    ``dtheta`` (N, 3) rad and ``dv`` (N, 3) m/s over each sample interval in sensor axes, ``status`` (N,) the
    sensor's status bits (0: healthy; any other value is counted as ``status_flagged`` and the sample used), and
    ``notices``: lines for the operator (a configuration the stream contradicts), each said once by the caller."""

    counter: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    status: np.ndarray
    notices: list[str] = field(default_factory=list)

    @classmethod
    def of(cls, rows: list[tuple[int, tuple[float, float, float], tuple[float, float, float], int]],
           notices: list[str] | None = None) -> SensorSamples:
        """From one (counter, Δθ, Δv, status) tuple per sample."""
        n = len(rows)
        return cls(np.array([r[0] for r in rows], dtype=np.int64),
                   np.array([r[1] for r in rows], dtype=float).reshape(n, 3),
                   np.array([r[2] for r in rows], dtype=float).reshape(n, 3),
                   np.array([r[3] for r in rows], dtype=np.int64), notices or [])


class VendorDecoder(Protocol):
    """A vendor frame decoder. ``counter_modulus`` the counter wraps at, ``tick_s`` one counter unit (s) and
    ``counter_step`` counter units per sample at the configured rate."""

    counter_modulus: int
    tick_s: float
    counter_step: int

    def feed(self, data: bytes) -> SensorSamples: ...

    def counters(self) -> dict[str, int]: ...


class VendorEncoder(Protocol):
    """A vendor frame encoder (the bench's emulated IMU): sample ``index`` (0, 1, …; the frame's counter follows from
    it), Δθ (3,) rad and Δv (3,) m/s in sensor axes, the status bits → the frame's bytes, quantised as the sensor
    quantises."""

    def encode(self, index: int, dtheta: np.ndarray, dv: np.ndarray, status: int = 0) -> bytes: ...

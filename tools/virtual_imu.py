"""A virtual IMU for the bench: plays samples as serial frames into a pty (or a real port).

``PtyPair`` makes the RS-422 link out of a pseudo-terminal: the daemon opens ``port_name`` with
pyserial, the player writes into the master end. Both ends are put in raw mode at once
(until made raw a pty slave is cooked: it echoes bytes back to the master and translates some, CR to CRLF
among them). Playing paces frames by
their own timestamps at ``speed`` × real time, writing every frame that is due in one burst, and
never blocks for long: a reader that stops reading makes :meth:`FramePlayer.play` stop with a
timeout error instead of hanging.

A vendor's IMU (``[imu] format``) is played in its own frames (:func:`imu_encoder`).

An :class:`AidingPlayback` adds an aiding sensor on the same line (serial aiding frames, type 2):
each epoch goes out ``late_s`` of data after its time stamp, just before the first IMU frame at or
after that time, as a real aiding sensor's output reaches the IMU's line late. A GNSS receiver's own output (NMEA,
UBX: tools/receiver_encoders.py) is played on a port of its own, on the same clock.
"""
from __future__ import annotations

import contextlib
import os
import select
import time
import tty
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from sinsalign.protocol.axes import axis_map
from sinsalign.protocol.declared_frame import DeclaredFrameEncoder
from sinsalign.protocol.kvh import KvhEncoder
from sinsalign.protocol.serial_frame import encode_aiding, encode_imu
from sinsalign.protocol.stim300 import Stim300Encoder
from sinsalign.protocol.vendor import VendorEncoder
from sinsalign.protocol.xsens import XsensEncoder
from sinsalign.service.config import ImuConfig

WRITE_TIMEOUT_S = 2.0


class PtyPair:
    """A raw pseudo-terminal pair: write frames to ``master_fd``, open ``port_name`` as the serial port."""

    def __init__(self) -> None:
        self.master_fd, self._slave_fd = os.openpty()
        tty.setraw(self.master_fd)
        tty.setraw(self._slave_fd)
        self.port_name = os.ttyname(self._slave_fd)
        os.set_blocking(self.master_fd, False)

    def close(self) -> None:
        """Close both ends, once: a second close of an fd number closes whatever file has it by then (another pty's,
        a serial port's), the fault of another reader far away."""
        for fd in (self.master_fd, self._slave_fd):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self.master_fd = self._slave_fd = -1


def write_all(fd: int, data: bytes, timeout_s: float = WRITE_TIMEOUT_S) -> None:
    """Write every byte to a non-blocking fd, waiting for room; TimeoutError if the reader stalls."""
    view = memoryview(data)
    deadline = time.monotonic() + timeout_s
    while view:
        try:
            view = view[os.write(fd, view):]
        except BlockingIOError:
            if time.monotonic() > deadline:
                raise TimeoutError(f"the serial reader stopped reading ({len(view)} bytes pending)") from None
            select.select([], [fd], [], 0.05)


EpochEncoder = Callable[[int, np.ndarray], bytes]
"""One aiding epoch: (its index, its row: t in s, then the kind's pinned log columns) → its bytes."""


@dataclass(slots=True)
class AidingPlayback:
    """Epochs (N, 1 + values: t in s, then the kind's pinned log columns) of one aiding ``kind`` (odo, gnss,
    master) to interleave with the IMU frames, each ``late_s`` seconds of data after its time stamp, as serial
    aiding frames or in the bytes ``encode`` makes of them (a GNSS receiver's own output)."""

    kind: str
    epochs: np.ndarray
    late_s: float = 0.0
    encode: EpochEncoder | None = None
    sent: int = 0
    _due_s: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self._due_s = self.epochs[:, 0] + self.late_s   # once: due() runs before every IMU frame
        if self.encode is None:
            kind = self.kind
            self.encode = lambda j, row: encode_aiding(j, float(row[0]), kind, row[1:])

    def due(self, t: float) -> bytes:
        """The frames of the epochs not sent yet that are due before an IMU frame at time t (s)."""
        return self._frames(int(np.searchsorted(self._due_s, t, side="right")))

    def rest(self) -> bytes:
        """The frames of every epoch not sent yet (after the last IMU frame)."""
        return self._frames(len(self.epochs))

    def _frames(self, end: int) -> bytes:
        out = b"".join(self.encode(j, self.epochs[j]) for j in range(self.sent, end))
        self.sent = max(self.sent, end)
        return out


ImuEncoder = Callable[[int, float, np.ndarray, np.ndarray], bytes]
"""One IMU frame: (sequence number, t in s, Δθ (3,) rad, Δv (3,) m/s in body axes) → its bytes."""

VENDOR_ENCODERS: dict[str, Callable[[ImuConfig], VendorEncoder]] = {
    "stim300": lambda imu: Stim300Encoder(imu.rate_hz, imu.stim300.datagram, imu.stim300.acc_range_g),
    "kvh1750": lambda imu: KvhEncoder("1750", imu.rate_hz),
    "kvh1775": lambda imu: KvhEncoder("1775", imu.rate_hz),
    "xsens": XsensEncoder.from_imu,
    "frame": DeclaredFrameEncoder.from_imu,
}
"""The bench encoder of each vendor ``[imu] format``, built from the ``[imu]`` table."""


def imu_encoder(imu: ImuConfig) -> ImuEncoder:
    """The frames of the IMU ``[imu] format`` names: the project's frame, or a vendor's in its sensor axes (the
    inverse of ``[imu] axes``), numbered by the sample and without a time stamp of its own."""
    if imu.format == "sinsalign":
        return encode_imu
    vendor = VENDOR_ENCODERS[imu.format](imu)
    C_b_s = axis_map(imu.axes).T
    return lambda seq, _t, dtheta, dv: vendor.encode(seq, C_b_s @ dtheta, C_b_s @ dv)


def encode_samples(t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, seq: int,
                   aiding: Sequence[AidingPlayback] = (), encode: ImuEncoder = encode_imu) -> bytes:
    """IMU frames (sequence numbers from ``seq``, by ``encode``) of samples t (N,) s, Δθ (N, 3) rad, Δv (N, 3) m/s,
    each preceded by the aiding frames due before it (of every stream in ``aiding``)."""
    frames = []
    for i in range(len(t)):
        frames += [stream.due(float(t[i])) for stream in aiding]
        frames.append(encode(seq + i, float(t[i]), dtheta[i], dv[i]))
    return b"".join(frames)


@dataclass(slots=True)
class FramePlayer:
    """Encodes samples as IMU frames and writes them to a file descriptor, paced by their time stamps; a
    ``receiver`` (a GNSS receiver's own output) goes to its own ``receiver_fd`` on the same clock, each epoch's
    bytes just after the IMU frames written with its due time."""

    fd: int
    speed: float = 1.0
    aiding: Sequence[AidingPlayback] = ()
    encode: ImuEncoder = encode_imu
    receiver: AidingPlayback | None = None
    receiver_fd: int = -1
    seq: int = 0
    frames_written: int = 0
    write_started: float = float("nan")   # monotonic time (s) at which the last write began
    _origin: tuple[float, float] | None = None   # (data time, wall time) of the first frame

    def play(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, stop: object = None) -> None:
        """Write samples (t (N,) s, Δθ (N, 3) rad, Δv (N, 3) m/s); ``stop`` is an optional threading.Event."""
        if self._origin is None:
            self._origin = (float(t[0]), time.monotonic())
        t0_data, t0_wall = self._origin
        k = 0
        while k < len(t):
            if stop is not None and stop.is_set():
                return
            ahead_s = (float(t[k]) - t0_data) / self.speed - (time.monotonic() - t0_wall)
            if ahead_s > 0:   # frame k is not due yet
                time.sleep(min(ahead_s, 0.05))
                continue
            due_data = t0_data + (time.monotonic() - t0_wall) * self.speed
            end = max(k + 1, int(np.searchsorted(t, due_data, side="right")))
            self.write_started = time.monotonic()
            write_all(self.fd, encode_samples(t[k:end], dtheta[k:end], dv[k:end], self.seq, self.aiding, self.encode))
            if self.receiver is not None:   # after the IMU frames: a reader that lags the IMU never sees it lead
                write_all(self.receiver_fd, self.receiver.due(float(t[end - 1])))
            self.seq += end - k
            self.frames_written += end - k
            k = end

    def play_chunks(self, chunks: Iterable, stop: object = None) -> None:
        """Play chunks of (t, Δθ, Δv) arrays (simulator chunks or log blocks) back to back, one clock; then the
        aiding epochs still due (those less than ``late_s`` before the end)."""
        for t, dtheta, dv in chunks:
            self.play(t, dtheta, dv, stop)
        for stream in self.aiding:
            write_all(self.fd, stream.rest())
        if self.receiver is not None:
            write_all(self.receiver_fd, self.receiver.rest())

"""A virtual IMU for the bench: plays samples as serial frames into a pty (or a real port).

``PtyPair`` makes the RS-422 link out of a pseudo-terminal: the daemon opens ``port_name`` with
pyserial, the player writes into the master end. Both ends are put in raw mode at once
(transport-notes.md §3: a cooked slave would echo and translate bytes). Playing paces frames by
their own timestamps at ``speed`` × real time, writing every frame that is due in one burst, and
never blocks for long: a reader that stops reading makes :meth:`FramePlayer.play` stop with a
timeout error instead of hanging.
"""
from __future__ import annotations

import contextlib
import os
import select
import time
import tty
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from sinsalign.protocol.serial_frame import encode_imu

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
        for fd in (self.master_fd, self._slave_fd):
            with contextlib.suppress(OSError):
                os.close(fd)


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


@dataclass(slots=True)
class FramePlayer:
    """Encodes samples as IMU frames and writes them to a file descriptor, paced by their time stamps."""

    fd: int
    speed: float = 1.0
    seq: int = 0
    frames_written: int = 0
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
            write_all(self.fd, b"".join(encode_imu(self.seq + i, float(t[k + i]), dtheta[k + i], dv[k + i])
                                        for i in range(end - k)))
            self.seq += end - k
            self.frames_written += end - k
            k = end

    def play_chunks(self, chunks: Iterable, stop: object = None) -> None:
        """Play chunks of (t, Δθ, Δv) arrays (simulator chunks or log blocks) back to back, one clock."""
        for t, dtheta, dv in chunks:
            self.play(t, dtheta, dv, stop)

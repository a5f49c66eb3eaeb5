"""The serial input: pyserial on any device path (an RS-422 adapter, or a pty on a bench).

A vanished port (unplugged adapter, closed pty) is not fatal: the read returns nothing, the
disconnect is counted, and the port is reopened with a growing back-off (0.1 s doubling up to
``reconnect_max_s``) until it is back (transport-notes.md §3: a closed pty raises on every read).
"""
from __future__ import annotations

import contextlib
import logging
import time

import serial

from ..protocol.serial_frame import CRC, HEADER, IMU_PAYLOAD

FRAME_BYTES = HEADER.size + IMU_PAYLOAD.size + CRC.size
READ_TIMEOUT_S = 0.02
log = logging.getLogger("sinsalign.serial")


class SerialPort:
    def __init__(self, path: str, baud: int, reconnect_max_s: float = 2.0) -> None:
        self.path = path
        self.baud = baud
        self.reconnect_max_s = reconnect_max_s
        self.disconnects = 0
        self.reconnects = 0
        self.last_error: str | None = None
        self._port: serial.Serial | None = None
        self._backoff_s = 0.1
        self._next_attempt = 0.0
        self._opened_once = False
        self._open()

    @property
    def connected(self) -> bool:
        return self._port is not None

    def _open(self) -> None:
        try:
            self._port = serial.Serial(self.path, self.baud, timeout=READ_TIMEOUT_S)
        except (serial.SerialException, OSError, ValueError) as exc:
            text = f"serial {self.path}: {exc}"
            if text != self.last_error:
                log.warning("%s (retrying, back-off up to %g s)", text, self.reconnect_max_s)
            self.last_error = text
            self._next_attempt = time.monotonic() + self._backoff_s
            self._backoff_s = min(2.0 * self._backoff_s, self.reconnect_max_s)
            return
        if self._opened_once:
            self.reconnects += 1
            log.info("serial %s reopened", self.path)
        self._opened_once = True
        self._backoff_s = 0.1

    def read(self) -> bytes:
        """Whatever arrived (waits up to 20 ms for a frame's worth); b'' while the port is down."""
        if self._port is None:
            if time.monotonic() >= self._next_attempt:
                self._open()
            if self._port is None:
                time.sleep(READ_TIMEOUT_S)
                return b""
        try:
            return self._port.read(max(FRAME_BYTES, self._port.in_waiting))
        except (serial.SerialException, OSError) as exc:
            self.disconnects += 1
            self.last_error = f"serial {self.path} lost: {exc}"
            log.warning(self.last_error)
            self.close()
            self._next_attempt = time.monotonic() + self._backoff_s
            return b""

    def close(self) -> None:
        if self._port is not None:
            with contextlib.suppress(serial.SerialException, OSError):
                self._port.close()
            self._port = None

"""The serial input: pyserial on any device path (an RS-422 adapter, or a pty on a bench).

The port is held exclusively (pyserial's ``exclusive=True``: a non-blocking ``flock`` on the open device), so two
daemons never read the same IMU: a :class:`SerialPort` that finds the port locked when it is made raises
:class:`PortInUseError` (``sinsalign serve`` exits 2 with its one line); found locked later (the port was absent
at start, or on a reopen), it keeps waiting. A program that opens the device without locking it is not seen.

A vanished port (unplugged adapter, closed pty) is not fatal: the read returns nothing, the disconnect is counted,
and the port is reopened with a growing back-off (0.1 s doubling up to ``reconnect_max_s``) until it is back
(a pty whose master end has closed makes every read raise SerialException at once, and its /dev/pts name
vanishes with it), but only if what is back is the same device:

- a plain device path (``/dev/ttyUSB0``, ``/dev/pts/3``) is reopened only while its node's identity
  (st_rdev, st_ino, st_ctime_ns) is the one it had at the last open. A node removed and made again has a new
  ctime even where its device number and inode number repeat (a pty's number reused by another program, another
  adapter enumerated under the same name, and also the same adapter plugged in again: name it by its by-id link
  to have it followed). The ctime has the kernel tick's resolution (a few ms), so only a node that lived less
  than a tick could pass for its successor;
- a symbolic link (``/dev/serial/by-id/…``, socat's ``link=``) names the device: made anew (its own inode, ctime
  or target differ from the last open's), it is followed to whatever node it points at, since udev and socat
  remove the link when the device goes and make it again when it is back. An unchanged link whose node changed
  is stale (a socat killed before it could remove it, and its pty's number reused) and is judged by its node,
  as a plain path is.

Anything else under the port's name is never opened, not even to set its line settings: it is counted once for
each node found in its place (``foreign_devices``), said in ``last_error``, and the port keeps waiting.
"""
from __future__ import annotations

import contextlib
import errno
import logging
import os
import select
import stat
import time
from dataclasses import dataclass

import serial

from ..protocol.serial_frame import IMU_FRAME_BYTES

READ_TIMEOUT_S = 0.02
MAX_READ_BYTES = 1 << 16
"""What one :meth:`SerialPort.read` gathers at most from a port that keeps having data (about 1300 IMU frames)."""
LINE_BUFFER_BYTES = 4095
"""The most a Linux tty (a pty too) holds ready to read: a read that took this much found the line behind."""
CATCH_UP_WAIT_S = 0.001
"""How long a read that found the line behind waits for the kernel to move the next bytes into its buffer."""
log = logging.getLogger("sinsalign.serial")


class PortInUseError(OSError):
    """Another program holds the port's lock (a second daemon on the same IMU)."""


@dataclass(frozen=True, slots=True)
class DeviceIdentity:
    """What a port's path leads to: the device node (st_rdev, st_ino, st_ctime_ns) and, when the path is a
    symbolic link, the link itself (st_ino, st_ctime_ns, target)."""

    node: tuple[int, int, int]
    link: tuple[int, int, str] | None

    @classmethod
    def of(cls, path: str) -> DeviceIdentity:
        """The identity of ``path`` now (OSError when nothing is there)."""
        node, entry = os.stat(path), os.lstat(path)
        link = (entry.st_ino, entry.st_ctime_ns, os.readlink(path)) if stat.S_ISLNK(entry.st_mode) else None
        return cls((node.st_rdev, node.st_ino, node.st_ctime_ns), link)

    def admits(self, now: DeviceIdentity) -> bool:
        """Whether ``now`` (found at the path of this identity) is the same device: the same node, or a link
        made anew for it (module docstring)."""
        return now.node == self.node or (self.link is not None and now.link not in (None, self.link))


class SerialPort:
    """One serial input by its path; ``disconnects``, ``reconnects`` and ``foreign_devices`` count what happened to
    it (module docstring) and ``last_error`` says the latest, in one line."""

    def __init__(self, path: str, baud: int, reconnect_max_s: float = 2.0) -> None:
        self.path = path
        self.baud = baud
        self.reconnect_max_s = reconnect_max_s
        self.disconnects = 0
        self.reconnects = 0
        self.foreign_devices = 0
        self.last_error: str | None = None
        self._port: serial.Serial | None = None
        self._identity: DeviceIdentity | None = None
        self._refused: tuple[int, int, int] | None = None
        self._backoff_s = 0.1
        self._next_attempt = 0.0
        self._open(first=True)

    @property
    def connected(self) -> bool:
        return self._port is not None

    def _open(self, first: bool = False) -> None:
        """Open the port if its path leads to the device it had; ``first``: raise PortInUseError if locked."""
        try:
            now = DeviceIdentity.of(self.path)
            if self._identity is not None and not self._identity.admits(now):
                self._refuse(now)
                return
            self._port = serial.Serial(self.path, self.baud, timeout=READ_TIMEOUT_S, exclusive=True)
        except (serial.SerialException, OSError, ValueError) as exc:
            if isinstance(exc, serial.SerialException) and exc.errno == errno.EWOULDBLOCK:   # exclusive's flock
                text = f"serial {self.path} is in use by another program (it holds the port's lock)"
                if first:
                    raise PortInUseError(text) from None
            else:
                text = f"serial {self.path}: {exc}"
            self._wait(text)
            return
        if self._identity is not None:
            self.reconnects += 1
            log.info("serial %s reopened", self.path)
        self._identity = now
        self._backoff_s = 0.1

    def _refuse(self, now: DeviceIdentity) -> None:
        if now.node != self._refused:
            self.foreign_devices += 1
            self._refused = now.node
        self._wait(f"serial {self.path}: another device now has this name, not opened "
                   "(a /dev/serial/by-id/ link follows an adapter plugged in again)")

    def _wait(self, text: str) -> None:
        """Say why the port is down and schedule the next attempt, backing off."""
        if text != self.last_error:
            log.warning("%s (retrying, back-off up to %g s)", text, self.reconnect_max_s)
        self.last_error = text
        self._next_attempt = time.monotonic() + self._backoff_s
        self._backoff_s = min(2.0 * self._backoff_s, self.reconnect_max_s)

    def read(self, wait: bool = True) -> bytes:
        """Whatever arrived (waits up to 20 ms for a frame's worth; without ``wait``, what is there: a second port
        read in the same loop must not hold it); b'' while the port is down.

        A line that is behind is read on, up to :data:`MAX_READ_BYTES`: a tty (a pty too) hands at most its 4-KiB
        line buffer per read (about 80 frames) and refills it from the kernel's queue a moment later, so a read that
        took a full buffer waits up to :data:`CATCH_UP_WAIT_S` for more. An IMU that ran ahead of the loop is then
        caught up in one pass, with one decoder and one pipeline call, not one per 4 KiB. A frame arriving alone
        (200 Hz, a loop that keeps up) finds nothing behind it and goes on at once."""
        if self._port is None:
            if time.monotonic() >= self._next_attempt:
                self._open()
            if self._port is None:
                if wait:
                    time.sleep(READ_TIMEOUT_S)
                return b""
        try:
            data = chunk = self._port.read(max(IMU_FRAME_BYTES, self._port.in_waiting) if wait
                                           else self._port.in_waiting)
            while len(data) < MAX_READ_BYTES:
                waiting = self._port.in_waiting
                if not waiting and len(chunk) >= LINE_BUFFER_BYTES and select.select([self._port.fileno()], [], [],
                                                                                     CATCH_UP_WAIT_S)[0]:
                    waiting = self._port.in_waiting
                if not waiting:
                    break
                chunk = self._port.read(min(waiting, MAX_READ_BYTES - len(data)))
                data += chunk
            return data
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

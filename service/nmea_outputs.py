"""The NMEA 0183 outputs: each due sentence (protocol/nmea_out.py) as one UDP datagram to every ``[nmea] udp``
destination and on the ``[nmea] serial`` line. Neither ever waits: a datagram the socket refuses is counted
(``nmea_send_errors``), and a sentence the serial line has no room for, or cannot take, is dropped whole and
counted (``nmea_serial_dropped``), so a receiver that stops reading never stalls the loop.
"""
from __future__ import annotations

import os
import socket
from dataclasses import dataclass

import serial

from ..protocol.counters import Counters, count
from ..protocol.nmea_out import NmeaSentences
from ..protocol.results import ResultRecord
from .config import ConfigError, NmeaConfig, nmea_destination


@dataclass(slots=True)
class NmeaCounters(Counters):
    """What the NMEA outputs could not send."""

    nmea_send_errors: int = count("NMEA datagrams a UDP send refused (no route, a full buffer, a port refused)")
    nmea_serial_dropped: int = count("NMEA sentences left out on the serial line: no room (the line is slower than "
                                     "the sentences, or stuck) or a write error")


class SerialLine:
    """A serial port opened and set by pyserial, written without blocking: a sentence goes out whole or not at all
    (the part of one the line had no room for goes first next time, and until it has, new ones are dropped)."""

    def __init__(self, path: str, baud: int) -> None:
        try:
            self._port = serial.Serial(path, baud, write_timeout=0)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise ConfigError(f"nmea.serial: cannot open {path!r}: {exc}") from None
        self._fd = self._port.fileno()
        os.set_blocking(self._fd, False)
        self._pending = b""

    def write(self, data: bytes) -> bool:
        """Whether ``data`` was taken (wholly written, or its rest held until the line has room)."""
        self._pending = self._pending[self._write(self._pending):] if self._pending else b""
        if self._pending:
            return False
        written = self._write(data)
        if written == 0:
            return False
        self._pending = data[written:]
        return True

    def _write(self, data: bytes) -> int:
        try:
            return os.write(self._fd, data)
        except OSError:   # EAGAIN: no room; EIO and others: the port is gone. Either way the sentence is dropped
            return 0

    def close(self) -> None:
        self._port.close()


class NmeaOutputs:
    """The sentences of ``config`` for every record, to its UDP destinations and serial line."""

    def __init__(self, config: NmeaConfig) -> None:
        self.counters = NmeaCounters()
        self._sentences = NmeaSentences(config.sentences, config.talker, config.rate_hz)
        self._destinations = [_resolve(text) for text in config.udp]
        self._sockets = {family: _udp_socket(family) for family, _ in self._destinations}
        self._serial = SerialLine(config.serial, config.baud) if config.serial else None

    def records(self, records: list[ResultRecord]) -> None:
        for record in records:
            for sentence in self._sentences.feed(record):
                self._send(sentence)

    def _send(self, sentence: bytes) -> None:
        for family, address in self._destinations:
            try:
                self._sockets[family].sendto(sentence, address)
            except OSError:
                self.counters.nmea_send_errors += 1
        if self._serial is not None and not self._serial.write(sentence):
            self.counters.nmea_serial_dropped += 1

    def close(self) -> None:
        for sock in self._sockets.values():
            sock.close()
        if self._serial is not None:
            self._serial.close()


def _resolve(text: str) -> tuple[int, tuple]:
    """(address family, socket address) of a ``HOST:PORT`` destination, resolved once at the start."""
    host, port = nmea_destination(text)
    try:
        family, _, _, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0]
    except OSError as exc:
        raise ConfigError(f"nmea.udp: {text!r}: {exc}") from None
    return family, address


def _udp_socket(family: int) -> socket.socket:
    sock = socket.socket(family, socket.SOCK_DGRAM)
    sock.setblocking(False)
    return sock

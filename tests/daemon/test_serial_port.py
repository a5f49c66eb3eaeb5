"""The serial port on real ptys: held exclusively, and reopened only when the device under its name is the same.

GIVEN a port held by one SerialPort, WHEN a second one (a second daemon) opens it, THEN it fails at once with one
line naming the port, and ``sinsalign serve`` exits 2 with it. GIVEN a port that vanished, WHEN another pty comes
back under the same plain name or behind the same unchanged link, THEN it is not opened (its line settings stay
as they were), the refusal is counted and said; WHEN the same device is there again, or the link was made anew
for the device (udev's by-id links, socat's link=), THEN the port is reopened.
"""
from __future__ import annotations

import os
import re
import termios
import time
from pathlib import Path

import pytest
from sinsalign.protocol import messages
from sinsalign.service.daemon import Daemon
from sinsalign.service.serial_port import SerialPort
from sinsalign.service.zenoh_session import open_session
from sinsalign.tools.virtual_imu import PtyPair, write_all
from support.daemon_harness import daemon_config, free_port

from sinsalign.cli import main

BAUD = 115200


@pytest.fixture
def ptys():
    """Every pty a test makes, closed after it."""
    made: list[PtyPair] = []
    yield made
    for pair in made:
        pair.close()


def new_pty(made: list[PtyPair]) -> PtyPair:
    made.append(PtyPair())
    return made[-1]


def reuse_name(name: str, made: list[PtyPair]) -> None:
    """Make ``name`` (a /dev/pts node that vanished) exist again as another pty: the kernel hands out the lowest
    free number, so the ptys made on the way to it are kept; if another program took the number, it exists too."""
    time.sleep(0.02)   # a node's ctime has the kernel's tick as resolution: the new node's comes later
    for _ in range(64):
        if os.path.exists(name):
            return
        new_pty(made)
    pytest.fail(f"{name} did not come back")


def read_until(port: SerialPort, condition, timeout_s: float = 1.5) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:
        port.read()


def received(port: SerialPort, expected: bytes, timeout_s: float = 1.5) -> bytes:
    data = b""
    deadline = time.monotonic() + timeout_s
    while not data.endswith(expected) and time.monotonic() < deadline:
        data += port.read()
    return data


def lose(port: SerialPort) -> None:
    """Read until the port notices its device went away."""
    read_until(port, lambda: not port.connected)
    assert port.disconnects == 1


def test_a_second_port_on_the_same_device_fails_naming_the_port(ptys, capsys):
    pty = new_pty(ptys)
    first = SerialPort(pty.port_name, BAUD)
    message = rf"^serial {re.escape(pty.port_name)} is in use by another program"
    with pytest.raises(OSError, match=message):
        SerialPort(pty.port_name, BAUD)
    assert main(["serve", "--serial", pty.port_name]) == 2
    err = capsys.readouterr().err.strip()
    assert re.match(rf"sinsalign serve: error: {message[1:]}", err) and "\n" not in err
    write_all(pty.master_fd, b"still mine")   # the first holder is unharmed
    assert received(first, b"still mine") == b"still mine"
    first.close()
    SerialPort(pty.port_name, BAUD).close()   # released on close


def test_another_pty_under_the_vanished_plain_name_is_not_opened(ptys, tmp_path: Path):
    first = new_pty(ptys)
    name = first.port_name
    port = SerialPort(name, BAUD, reconnect_max_s=0.1)
    first.close()
    lose(port)
    reuse_name(name, ptys)
    before = termios.tcgetattr(fd := os.open(name, os.O_RDWR | os.O_NOCTTY))
    read_until(port, lambda: port.foreign_devices > 0)
    time.sleep(0.25)
    read_until(port, lambda: False, 0.3)         # retries go on, the device stays untouched
    assert not port.connected and port.reconnects == 0 and port.foreign_devices == 1
    assert port.last_error.startswith(f"serial {name}: another device now has this name") and \
        "\n" not in port.last_error
    assert termios.tcgetattr(fd) == before       # never opened: pyserial's open would have set raw mode
    os.close(fd)
    config = daemon_config(tmp_path, free_port())
    daemon = Daemon(config, open_session(config.zenoh), port)
    assert messages.faults(daemon.all_counters()) == {"serial_disconnects": 1, "serial_foreign_devices": 1}
    daemon.close()
    daemon.session.close()


def test_a_link_is_followed_when_made_anew_and_not_when_its_old_target_name_is_reused(ptys, tmp_path: Path):
    first = new_pty(ptys)
    link = tmp_path / "imu"
    link.symlink_to(first.port_name)
    port = SerialPort(str(link), BAUD, reconnect_max_s=0.1)
    first.close()
    lose(port)
    reuse_name(first.port_name, ptys)            # the link is stale: its old target's number went to another pty
    read_until(port, lambda: port.foreign_devices > 0)
    assert not port.connected and port.foreign_devices == 1
    second = new_pty(ptys)                        # the device is back and its link is made again for it
    link.unlink()
    link.symlink_to(second.port_name)
    read_until(port, lambda: port.connected)
    assert port.reconnects == 1 and port.foreign_devices == 1
    write_all(second.master_fd, b"frames")
    assert received(port, b"frames") == b"frames"
    port.close()


def test_the_same_device_after_a_read_error_is_reopened(ptys):
    pty = new_pty(ptys)
    port = SerialPort(pty.port_name, BAUD, reconnect_max_s=0.1)
    other = os.open(pty.port_name, os.O_RDWR | os.O_NOCTTY)   # a program that puts the line in canonical mode:
    attrs = termios.tcgetattr(other)                          # an end-of-file character then ends the read
    attrs[3] |= termios.ICANON
    termios.tcsetattr(other, termios.TCSANOW, attrs)
    os.close(other)
    write_all(pty.master_fd, b"\x04")
    lose(port)
    read_until(port, lambda: port.connected)
    assert port.reconnects == 1 and port.foreign_devices == 0
    port.close()

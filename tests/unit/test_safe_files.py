"""Output files with the customer's data: owner-only, never written through a symbolic link.

GIVEN an existing world-readable file, THEN it is truncated and ends 0600. GIVEN a symbolic link at the path,
THEN the open is refused with one line naming the path and the link's target is untouched; ``sinsalign serve
--record`` exits 2 with that line. GIVEN nothing at the path, THEN the new file is 0600 whatever the umask;
``exclusive`` makes only a new file. GIVEN a FIFO, THEN it is refused at once (no wait for a reader).
"""
from __future__ import annotations

import contextlib
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from sinsalign.service.daemon import Daemon
from sinsalign.service.safe_files import open_private
from sinsalign.service.zenoh_session import open_session
from support.daemon_harness import daemon_config, free_port


def mode_of(path: Path) -> int:
    return stat.S_IMODE(path.lstat().st_mode)


@contextlib.contextmanager
def umask(mask: int):
    old = os.umask(mask)
    try:
        yield
    finally:
        os.umask(old)


def test_an_existing_world_readable_file_is_truncated_and_ends_owner_only(tmp_path: Path) -> None:
    path = tmp_path / "results.jsonl"
    path.write_text("an earlier run's data\n")
    path.chmod(0o644)
    with open_private(path) as stream:
        stream.write("new\n")
    assert mode_of(path) == 0o600 and path.read_text() == "new\n"


@pytest.mark.parametrize("exclusive", [False, True])
def test_a_symbolic_link_is_refused_and_its_target_untouched(tmp_path: Path, exclusive: bool) -> None:
    target = tmp_path / "victim"
    target.write_text("precious\n")
    target.chmod(0o644)
    link = tmp_path / "out.csv"
    link.symlink_to(target)
    with pytest.raises(OSError, match=r"(is a symbolic link, not written through|File exists)") as refused:
        open_private(link, exclusive=exclusive)
    assert "\n" not in str(refused.value) and str(link) in str(refused.value)
    assert target.read_text() == "precious\n" and mode_of(target) == 0o644 and link.is_symlink()


@pytest.mark.parametrize("mode", ["w", "wb"])
def test_a_new_file_is_owner_only_whatever_the_umask(tmp_path: Path, mode: str) -> None:
    path = tmp_path / "new.csv"
    with umask(0), open_private(path, mode) as stream:
        stream.write("x" if mode == "w" else b"x")
    assert mode_of(path) == 0o600 and path.read_bytes() == b"x"


def test_exclusive_makes_a_new_file_only(tmp_path: Path) -> None:
    partial = tmp_path / "results.jsonl.partial"
    with open_private(partial, exclusive=True) as stream:
        stream.write("part")
    assert mode_of(partial) == 0o600
    with pytest.raises(FileExistsError):
        open_private(partial, exclusive=True)
    assert partial.read_text() == "part"


def test_a_fifo_is_refused_at_once(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(OSError, match="is not a regular file, not written"):
        open_private(fifo)


def test_the_daemon_recording_is_owner_only_and_a_link_there_is_refused(tmp_path: Path) -> None:
    recording = tmp_path / "recorded.csv"
    recording.write_text("")
    recording.chmod(0o644)
    config = daemon_config(tmp_path, free_port(), daemon={"record_path": str(recording)})
    session = open_session(config.zenoh)
    try:
        Daemon(config, session).close()
        assert mode_of(recording) == 0o600 and recording.read_text().startswith("#")
        recording.unlink()
        recording.symlink_to(tmp_path / "victim")
        with pytest.raises(OSError, match="is a symbolic link"):
            Daemon(config, session)
    finally:
        session.close()
    assert not (tmp_path / "victim").exists()


def test_serve_exits_2_with_one_line_when_the_recording_path_is_a_link(tmp_path: Path) -> None:
    link = tmp_path / "recorded.csv"
    link.symlink_to(tmp_path / "victim")
    done = subprocess.run([sys.executable, "-m", "sinsalign", "serve", "--zenoh-imu", "--record", str(link),
                           "-l", f"tcp/127.0.0.1:{free_port()}"], capture_output=True, text=True, timeout=30)
    assert done.returncode == 2
    assert done.stderr.splitlines()[-1] == f"sinsalign serve: error: {link} is a symbolic link, not written through"
    assert not (tmp_path / "victim").exists()

"""Output files that hold the customer's data (recordings of the raw input, results): owner-only, never written
through a symbolic link.

A symbolic link planted at an output path (in a shared directory, by another user) would have the daemon
overwrite whatever it points at with the daemon's rights; a file left readable by a previous run or a loose
umask would give the data to everyone. :func:`open_private` refuses the one and closes the other.
"""
from __future__ import annotations

import errno
import os
import stat
from pathlib import Path
from typing import IO

PRIVATE = 0o600


def open_private(path: str | os.PathLike[str], mode: str = "w", *, exclusive: bool = False) -> IO:
    """``path`` opened for writing (``mode`` "w": UTF-8 text, "wb": bytes), owner-only (0600).

    The file is truncated if it exists, and made owner-only even when it was not (an existing 0644 file ends
    0600, but a program that had opened it before keeps its access: permissions are checked at open);
    ``exclusive`` makes a new file and fails with FileExistsError if anything is at ``path`` (a temporary
    ``.partial`` that is renamed when complete). OSError with one line naming the path when ``path`` is a
    symbolic link or not a regular file (a FIFO would block the writer, a device would take the data)."""
    if mode not in ("w", "wb"):
        raise ValueError(f"open_private: mode must be 'w' or 'wb', not {mode!r}")
    # O_NONBLOCK: opening a FIFO nobody reads fails at once instead of waiting for a reader; O_NOCTTY: a terminal
    # at the path is refused below and must not become the process's controlling terminal meanwhile
    flags = os.O_WRONLY | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC | os.O_NONBLOCK | os.O_NOCTTY
    flags |= os.O_EXCL if exclusive else os.O_TRUNC
    try:
        fd = os.open(path, flags, PRIVATE)
    except OSError as exc:
        # O_NOFOLLOW at a link gives ELOOP; a FIFO nobody reads, or a socket, gives ENXIO
        if exc.errno == errno.ENXIO or (exc.errno == errno.ELOOP and Path(path).is_symlink()):
            raise _refusal(path) from None
        raise
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise _refusal(path)
        os.fchmod(fd, PRIVATE)
        os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return os.fdopen(fd, mode, encoding="utf-8" if mode == "w" else None)


def _refusal(path: str | os.PathLike[str]) -> OSError:
    what = "a symbolic link, not written through" if Path(path).is_symlink() else "not a regular file, not written"
    return OSError(f"{path} is {what}")

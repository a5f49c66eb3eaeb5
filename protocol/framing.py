"""What every stream decoder does between frames."""
from __future__ import annotations


def sync_tail(buf: bytes | bytearray, pos: int, sync: bytes) -> int:
    """How many bytes at the end of ``buf[pos:]`` may be the start of ``sync``, split by the read: the decoder keeps
    them for the next read instead of skipping them."""
    return next(n for n in range(len(sync) - 1, -1, -1) if n <= len(buf) - pos and buf.endswith(sync[:n]))

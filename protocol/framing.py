"""What every stream decoder does between frames."""
from __future__ import annotations


def next_sync(buf: bytes | bytearray, pos: int, sync: bytes) -> tuple[int, int, bool]:
    """(where to go on, how many bytes before it to count as skipped, whether it is a ``sync``) for a decoder at
    ``pos`` in ``buf``: the next ``sync``; without one, the end of ``buf`` less the bytes that may be the start of a
    ``sync`` split by the read, which the decoder keeps for the next read instead of skipping them."""
    start = buf.find(sync, pos)
    if start >= 0:
        return start, start - pos, True
    keep = next(n for n in range(len(sync) - 1, -1, -1) if n <= len(buf) - pos and buf.endswith(sync[:n]))
    return len(buf) - keep, len(buf) - pos - keep, False

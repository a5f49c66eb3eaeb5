"""Sequence-counter bookkeeping shared by every input (serial frames, Zenoh IMU messages)."""
from __future__ import annotations

from dataclasses import dataclass

SEQUENCE_DOCS = {"gaps": "frames or messages missing between accepted ones (from the sequence counter)",
                 "repeats": "the previous sequence counter again (dropped)",
                 "backwards": "a sequence counter from the past (dropped)",
                 "resets": "the sender restarted its counter (three from the past in a row: followed)"}
"""What each sequence counter counts (status names ``seq_*`` for serial IMU frames, ``aiding_seq_*`` for serial
aiding frames, ``zenoh_seq_*`` for Zenoh IMU messages)."""
RESET_RUN = 3
"""Consecutive counters from the "past" after which the sender is taken to have restarted."""


@dataclass(slots=True)
class SequenceTracker:
    """Accepts counters that move forward (mod ``modulus``), counts gaps, drops repeats and stale ones.

    gaps : frames missing between accepted ones. repeats : the previous counter again (dropped).
    backwards : a counter from the past (dropped). resets : the sender restarted its counter
    (``RESET_RUN`` such in a row); followed from then on.
    """

    modulus: int = 1 << 16
    gaps: int = 0
    repeats: int = 0
    backwards: int = 0
    resets: int = 0
    _last: int | None = None
    _backwards_run: int = 0

    def accept(self, seq: int) -> bool:
        if self._last is None:
            self._last = seq
            return True
        step = (seq - self._last) % self.modulus
        if step == 0:
            self.repeats += 1
            return False
        if step >= self.modulus // 2:
            self._backwards_run += 1
            if self._backwards_run < RESET_RUN:
                self.backwards += 1
                return False
            self.resets += 1
        else:
            self.gaps += step - 1
        self._backwards_run = 0
        self._last = seq
        return True

    @property
    def last(self) -> int | None:
        """The last accepted counter (None before the first)."""
        return self._last

    def follow(self, seq: int) -> None:
        """``seq`` accepted as the end of a run of counters each one after the other (what :meth:`accept` does for
        each of them: no gap, no repeat)."""
        self._last = seq
        self._backwards_run = 0

    def counters(self, prefix: str = "seq_") -> dict[str, int]:
        return {f"{prefix}gaps": self.gaps, f"{prefix}repeats": self.repeats, f"{prefix}backwards": self.backwards,
                f"{prefix}resets": self.resets}

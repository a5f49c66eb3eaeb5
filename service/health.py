"""The daemon's health in its status: one rule from what came in, when, and what the counters did."""
from __future__ import annotations

from ..protocol import messages

NO_INPUT_S = 1.0
"""Wall time (s) without a sample after which the input is taken to be gone."""
AID_START_GRACE_S = 30.0
"""IMU data (s) an aided mode may run without a usable aiding value before health degrades: a GNSS receiver's
warm start; a stream that never comes, comes for another kind, or is stamped off the IMU's clock shows after it."""


def health(since_start_s: float, since_input_s: float | None, awaiting_aid_for_s: float | None,
           before: dict[str, int], now: dict[str, int]) -> str:
    """``starting``, ``ok``, ``degraded`` or ``no_input``.

    since_start_s : wall time since the daemon started. since_input_s : since the last sample (None: none yet).
    awaiting_aid_for_s : IMU data time (s) an aided mode has run without a usable aiding value yet (None: not
    waiting). before, now : the counters at the last periodic status and now; a fault counter that rose, or a
    screening alarm (:func:`~.messages.screening_alarm`), degrades.
    """
    if since_input_s is None:
        return "starting" if since_start_s < NO_INPUT_S else "no_input"
    if since_input_s > NO_INPUT_S:
        return "no_input"
    # a receiver before its first fix is no fault, for a while: the aided alignment has not begun
    rose = messages.fault_count(now) > messages.fault_count(before)
    overdue = awaiting_aid_for_s is not None and awaiting_aid_for_s > AID_START_GRACE_S
    if rose or overdue or messages.screening_alarm(before, now):
        return "degraded"
    return "starting" if awaiting_aid_for_s is not None else "ok"

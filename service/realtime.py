"""Real-time scheduling for the daemon (``daemon.realtime_priority``): its threads (the loop, and Zenoh's, started
after) under SCHED_FIFO, so a frame's arrival wakes the loop at once instead of after another task's time slice
(docs/performance.md, "A day of data through the daemon")."""
from __future__ import annotations

import logging
import os

log = logging.getLogger("sinsalign.daemon")


def request_realtime(priority: int) -> str | None:
    """Put every thread of the process under SCHED_FIFO at ``priority`` (1–99; 0: leave the normal scheduler), as
    ``chrt`` would have started it; threads started afterwards inherit the policy. The outcome goes to the log;
    returns why the system refused it, or None."""
    if priority == 0:
        return None
    try:
        for thread_id in map(int, os.listdir("/proc/self/task")):
            try:
                os.sched_setscheduler(thread_id, os.SCHED_FIFO, os.sched_param(priority))
            except ProcessLookupError:   # a thread that ended meanwhile
                continue
    except OSError as exc:   # no CAP_SYS_NICE and an RLIMIT_RTPRIO below the priority: EPERM
        refused = (f"daemon.realtime_priority = {priority} refused ({exc.strerror}): running under the normal "
                   f"scheduler; grant it with CAP_SYS_NICE, `ulimit -r {priority}` or systemd's "
                   "CPUSchedulingPolicy=fifo")
        log.warning(refused)
        return refused
    log.info("real-time scheduling: SCHED_FIFO priority %d", priority)
    return None

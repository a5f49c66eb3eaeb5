"""Real-time scheduling of the daemon (service/realtime.py, ``daemon.realtime_priority``).

GIVEN a priority, WHEN the daemon's start asks for it, THEN every thread of the process and every thread started
after (Zenoh's runtime) run under SCHED_FIFO at that priority; GIVEN a process the system refuses it (no
CAP_SYS_NICE, RLIMIT_RTPRIO 0), THEN it gets one line saying why and how to grant it, and runs on under the normal
scheduler. Each case runs in a child process: the test process keeps its own scheduling.
"""
from __future__ import annotations

import ctypes
import json
import os
import resource
import subprocess
import sys

import pytest
from sinsalign.tools.demo import free_loopback_port

CHILD = """
import json, os, sys
from sinsalign.service.config import ZenohConfig
from sinsalign.service.realtime import request_realtime
from sinsalign.service.zenoh_session import open_session
refused = request_realtime(int(sys.argv[1]))
with open_session(ZenohConfig(listen=(f"tcp/127.0.0.1:{sys.argv[2]}",))) as session:   # its threads start now
    threads = {tid: (os.sched_getscheduler(int(tid)), os.sched_getparam(int(tid)).sched_priority)
               for tid in os.listdir("/proc/self/task")}
print(json.dumps({"refused": refused, "threads": threads}))
"""


PR_CAPBSET_DROP, CAP_SYS_NICE = 24, 23   # <linux/prctl.h>, <linux/capability.h>


def run_child(priority: int, unprivileged: bool = False) -> dict:
    def drop() -> None:   # no real-time priority allowed, and no capability that overrides the limit
        resource.setrlimit(resource.RLIMIT_RTPRIO, (0, 0))
        if os.geteuid() == 0:   # root's program keeps the capabilities of its bounding set: CAP_SYS_NICE out of it
            libc = ctypes.CDLL(None, use_errno=True)
            if libc.prctl(PR_CAPBSET_DROP, CAP_SYS_NICE, 0, 0, 0) != 0:
                raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP, CAP_SYS_NICE)")
    done = subprocess.run([sys.executable, "-c", CHILD, str(priority), str(free_loopback_port())],
                          capture_output=True, text=True, timeout=60, preexec_fn=drop if unprivileged else None,
                          cwd="/")
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_every_thread_and_those_started_after_run_under_sched_fifo() -> None:
    got = run_child(20)
    if got["refused"] is not None:
        pytest.skip(f"this machine grants no real-time priority: {got['refused']}")
    assert len(got["threads"]) > 1   # the session's runtime threads among them
    assert set(map(tuple, got["threads"].values())) == {(os.SCHED_FIFO, 20)}


def test_a_refusal_is_one_line_and_the_daemon_runs_on_under_the_normal_scheduler() -> None:
    got = run_child(20, unprivileged=True)
    assert got["refused"].startswith("daemon.realtime_priority = 20 refused (Operation not permitted)")
    assert "CAP_SYS_NICE" in got["refused"] and "\n" not in got["refused"]
    assert {policy for policy, _ in got["threads"].values()} == {os.SCHED_OTHER}


def test_priority_zero_leaves_the_scheduler_alone() -> None:
    got = run_child(0)
    assert got["refused"] is None
    assert {policy for policy, _ in got["threads"].values()} == {os.SCHED_OTHER}

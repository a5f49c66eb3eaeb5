"""An alignment pipeline that starts over: when the sample gate asks (an outage, a saturated sample, a clock that
went back), and when the estimator itself fails.

The daemon (through :class:`~.ingest.Ingest`) and the replay of its recording hold their pipeline in one of these,
so both make the same decisions from the same samples: the recording marks each restart (:data:`RESTART_MARKER`
lines, which an IMU log's reader hands over with the samples after them), and a replay restarts where the daemon did.
"""
from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable

import numpy as np

from ..protocol.results import ResultRecord
from .pipeline import AlignmentPipeline


def summed(before: dict[str, int], now: dict[str, int]) -> dict[str, int]:
    """Counters ``before`` a restart plus the new pipeline's ``now``, key by key (a key in either)."""
    return {**before, **{key: before.get(key, 0) + count for key, count in now.items()}}


class RestartingPipeline:
    """The current pipeline of ``make``, replaced by a fresh one on :meth:`restart` or when a step fails; the
    disturbance and aiding counts of the pipelines before carry on. ``report`` gets a line per failure and per new
    event (:meth:`report_events`)."""

    def __init__(self, make: Callable[[], AlignmentPipeline], report: Callable[[str], None]) -> None:
        self._make = make
        self._report = report
        self.pipeline = make()
        self.failures = 0
        """Steps that raised or put out a non-finite number: the pipeline started over each time."""
        self._disturbances_before = 0
        self._aiding_before: dict[str, int] = {}
        self._reported: dict[str, str] = {}   # each source's last event text reported
        self._lock = threading.Lock()   # the status (a Zenoh query's thread too) sees a restart whole

    def restart(self) -> None:
        """A fresh pipeline: an aid that had begun stays begun (an observation without it is a dropout, not a wait)."""
        with contextlib.suppress(Exception):   # replaced anyway: only the counts of a step it left carry on
            self.pipeline.settle()
        pipeline = self._make()
        pipeline.carry_aid_start(self.pipeline)
        with self._lock:
            self._disturbances_before += self.pipeline.disturbances
            self._aiding_before = summed(self._aiding_before, self.pipeline.aiding_counters())
            self.pipeline = pipeline

    def report_events(self) -> None:
        """The pipeline's new events (a disturbance, a notice for the operator), each once through ``report``."""
        self.report_new("disturbance", self.pipeline.last_disturbance)
        self.report_new("alignment", self.pipeline.last_notice)

    def report_new(self, source: str, text: str | None) -> None:
        """``text`` through ``report`` unless it is None or ``source``'s last one (an event reported once, whatever
        its source: this pipeline's, or the gate's, the aiding's or the input's of the daemon that holds it)."""
        if text and text != self._reported.get(source):
            self._reported[source] = text
            self._report(text)

    def process(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, aid: np.ndarray | None = None,
                defer_control: bool = False) -> tuple[list[ResultRecord], str | None]:
        """The records of these samples (:meth:`AlignmentPipeline.process`), and None; or, if the estimator fails on
        them (raises, or puts out a non-finite number), no records and why, the pipeline started over from the next
        samples: its state cannot be trusted, and a service that published nothing after one bad step would be down
        for good."""
        try:
            records = self.pipeline.process(t, dtheta, dv, aid, defer_control)
            if all(r.finite for r in records):
                return records, None
            failure = "a non-finite attitude or σ"
        except Exception as exc:   # whatever the estimator raised, the alignment goes on
            failure = f"{type(exc).__name__}: {str(exc)[:80]}"
        return [], self._failed(f"on the samples t = {t[0]:.6f}..{t[-1]:.6f} s ({failure})")

    def settle(self) -> str | None:
        """The control step a deferred call left (:meth:`AlignmentPipeline.settle`): None, or why it failed, the
        pipeline started over as after a failed :meth:`process`."""
        try:
            self.pipeline.settle()
            return None
        except Exception as exc:   # whatever the estimator raised, the alignment goes on
            return self._failed(f"in a control step ({type(exc).__name__}: {str(exc)[:80]})")

    def _failed(self, where: str) -> str:
        """Count, report and restart after a failed step; the report's line."""
        self.failures += 1
        why = f"alignment failed {where}: restarted"
        self._report(why)
        self.restart()
        return why

    def counters(self) -> dict[str, int]:
        """The failed steps (``estimator_restarts``), disturbances and the aiding counters, summed over the pipelines
        since the start."""
        with self._lock:
            return {"estimator_restarts": self.failures,
                    "disturbances": self._disturbances_before + self.pipeline.disturbances,
                    **summed(self._aiding_before, self.pipeline.aiding_counters())}

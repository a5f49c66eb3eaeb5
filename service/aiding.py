"""Aiding epochs on the IMU's time line: latency, order, gaps, and interpolation to IMU samples.

Whatever the source (an aiding log, the serial aiding message, ``…/aid/<kind>`` on Zenoh),
epochs pass through an :class:`AidingTrack`: their time stamps are moved back by the configured
latency, an epoch not after the previous one is dropped and counted (a repeat if it carries the
same time, out of order otherwise), and values at IMU sample times come from linear
interpolation between the two epochs around each, or NaN (counted) when the two are a gap apart
or the sample lies outside the epochs held. A gap is judged against the stream's own rate: two
epochs are a gap apart when further apart than ``max_gap_s`` and than :data:`GAP_INTERVALS` of
the stream's usual interval (the median of its last :data:`INTERVAL_HISTORY`), so a 1-Hz receiver
is not one long run of gaps. Nothing here is fatal.

Each value row comes with the sequence number of the newest epoch at or before its time
(:meth:`AidingTrack.aid_at`): an estimator takes one observation or update per aiding epoch, not
one per interpolated sample of the same two epochs (those are not independent).

The track holds the epochs not yet passed by the IMU samples asked for (:meth:`release`), so its
memory is bounded by the aiding latency (daemon) or the replay chunk, whatever the run length. An
aiding stream that runs far ahead of the IMU (the IMU link down while the aiding keeps coming, or a
clock mismatch) fills it to ``capacity`` epochs; beyond that new epochs are dropped and counted.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..protocol.aiding_log import KINDS
from ..protocol.counters import Counters, count
from ..protocol.imu_log import IMU_WIDTH

if TYPE_CHECKING:
    from .config import AidingConfig

TIME_TOLERANCE_S = 1e-6
"""Time stamps travel as integer ns or decimal text: an IMU sample this close to an epoch is at it."""


def with_room(buffer: np.ndarray, rows: int, limit: int | None = None) -> np.ndarray:
    """``buffer`` (R, C) if it has ``rows`` rows, else a copy at least twice as long (at most ``limit`` rows) with the
    same rows first: a store that grows in doublings, not on every push."""
    if rows <= len(buffer):
        return buffer
    size = max(rows, 2 * len(buffer))
    bigger = np.empty((size if limit is None else min(size, limit), buffer.shape[1]))
    bigger[:len(buffer)] = buffer
    return bigger


@dataclass(slots=True)
class AidingCounters(Counters):
    """What one aiding stream's track saw (status names prefixed by the kind: ``gnss_epochs``)."""

    epochs: int = count("epochs the track took")
    repeats: int = count("epochs with the time of the one before (dropped)")
    out_of_order: int = count("epochs before the one before (dropped)")
    non_finite: int = count("epochs with a non-finite value (dropped)")
    gaps: int = count("epochs that follow the previous one by a gap (not interpolated across)")
    unaided_queries: int = count("IMU times asked for without two epochs around them")
    overflow: int = count("epochs dropped because the track was full (the aiding far ahead of the IMU)")


MAX_HELD_EPOCHS = 1 << 16
"""Epochs a track holds ahead of the IMU (10 min of 100-Hz aiding, 5 MiB for GNSS)."""
GAP_INTERVALS = 2.5
"""Epochs further apart than this many of the stream's usual intervals (and than ``max_gap_s``) are a gap: one
missing epoch is not, two are."""
INTERVAL_HISTORY = 16
"""The stream's usual interval is the median of this many latest intervals (a gap does not move it)."""


class AidingTrack:
    """The usable epochs of one aiding stream (time, then ``width`` values per epoch).

    latency_s : how late the stream's time stamps are (subtracted).
    max_gap_s : two epochs further apart than this and than :data:`GAP_INTERVALS` of the stream's usual interval
        are not interpolated across (a gap).
    capacity : epochs held at most; further ones are dropped (``overflow``) until the IMU passes some.
    longitude_column : the value column (0-based) holding a longitude in degrees, interpolated the short way
        round ±180° (:meth:`for_kind` sets it from the kind's columns).
    quaternion_column : the first of four value columns holding a unit quaternion [w, x, y, z], interpolated
        between the pair's nearer signs (q and −q are one attitude; a master may flip it) and renormalised.
    """

    def __init__(self, width: int, latency_s: float = 0.0, max_gap_s: float = 1.0,
                 capacity: int = MAX_HELD_EPOCHS, longitude_column: int | None = None,
                 quaternion_column: int | None = None) -> None:
        self.width = width
        self.latency_s = latency_s
        self.max_gap_s = max_gap_s
        self.capacity = capacity
        self.longitude_column = longitude_column
        self.quaternion_column = quaternion_column
        self.counters = AidingCounters()
        # per epoch: time, sequence number, whether it may be interpolated from the one before (1.0) or follows
        # a gap (0.0), the values. Judged once, as the epoch arrives: the same whenever the track is asked
        self._epochs = np.empty((64, _VALUES + width))
        self._n = 0
        self._intervals: deque[float] = deque(maxlen=INTERVAL_HISTORY)   # the latest intervals (s), oldest first

    @classmethod
    def for_kind(cls, kind: str, latency_s: float = 0.0, max_gap_s: float = 1.0) -> AidingTrack:
        """The track of a pinned aiding kind (odo, gnss, master): its width, its longitude interpolated the short
        way round ±180° and its attitude quaternion as a rotation."""
        values = KINDS[kind].columns[1:]
        return cls(len(values), latency_s, max_gap_s,
                   longitude_column=values.index("lon_deg") if "lon_deg" in values else None,
                   quaternion_column=values.index("qw") if "qw" in values else None)

    @classmethod
    def configured(cls, kind: str, aiding: AidingConfig) -> AidingTrack:
        """:meth:`for_kind` with the configuration's latency of that kind and ``max_gap_s``."""
        return cls.for_kind(kind, getattr(aiding, kind).latency_s, aiding.max_gap_s)

    def push(self, rows: np.ndarray) -> None:
        """Epochs (N, 1 + width): time stamp (s, the stream's clock) then the values."""
        rows = np.atleast_2d(np.asarray(rows, dtype=float))
        if rows.shape[1] != 1 + self.width:
            raise ValueError(f"aiding epochs need {1 + self.width} columns, got {rows.shape[1]}")
        for row in rows:
            if not np.isfinite(row).all():
                self.counters.non_finite += 1
                continue
            t = row[0] - self.latency_s
            last = self.latest_time
            if last is not None and not t > last:
                if t == last:
                    self.counters.repeats += 1
                else:
                    self.counters.out_of_order += 1
                continue
            if self._n >= self.capacity:
                self.counters.overflow += 1
                continue
            bridged = 0.0
            if last is not None:
                bridged = float(t - last <= self.gap_s(t - last))
                self.counters.gaps += int(not bridged)
                self._intervals.append(float(t - last))
            self._epochs = with_room(self._epochs, self._n + 1, self.capacity)
            self._epochs[self._n, :_VALUES] = t, self.counters.epochs, bridged
            self._epochs[self._n, _VALUES:] = row[1:]
            self._n += 1
            self.counters.epochs += 1

    def gap_s(self, interval_s: float) -> float:
        """The longest interval (s) before a new one of ``interval_s`` that is not a gap: ``max_gap_s`` or
        :data:`GAP_INTERVALS` times the stream's usual interval (the new one's own before there is a history)."""
        usual = self.usual_interval_s
        return max(self.max_gap_s, GAP_INTERVALS * (interval_s if usual is None else usual))

    @property
    def usual_interval_s(self) -> float | None:
        """The stream's usual interval between epochs (s): the median of its last :data:`INTERVAL_HISTORY`; None
        before two epochs."""
        if not self._intervals:
            return None
        ordered = sorted(self._intervals)   # a few floats: numpy's median costs 10 µs a call, at every epoch
        middle = len(ordered) // 2
        return ordered[middle] if len(ordered) % 2 else (ordered[middle - 1] + ordered[middle]) / 2.0

    @property
    def latest_time(self) -> float | None:
        """Time (IMU clock) of the newest epoch; values up to it can be interpolated."""
        return None if self._n == 0 else float(self._epochs[self._n - 1, 0])

    def aid_at(self, t: np.ndarray) -> np.ndarray:
        """Rows (N, 1 + width) at increasing IMU times ``t`` (N,): the sequence number of the newest epoch at or
        before the time (counting every epoch the track took), then the values; NaN rows where nothing is known."""
        t = np.asarray(t, dtype=float).reshape(-1)
        out = np.full((len(t), 1 + self.width), np.nan)
        held = self._epochs[:self._n]
        if self._n >= 2:
            k = np.clip(np.searchsorted(held[:, 0], t, side="right"), 1, self._n - 1)
            t0, t1 = held[k - 1, 0], held[k, 0]
            ok = (t >= t0 - TIME_TOLERANCE_S) & (t <= t1 + TIME_TOLERANCE_S) & (held[k, 2] > 0.0)
            f = ((t - t0) / (t1 - t0))[ok, None]
            before, after = held[k[ok] - 1, _VALUES:], held[k[ok], _VALUES:].copy()
            q, lon = self.quaternion_column, self.longitude_column
            if q is not None:     # the nearer sign: interpolating q towards -q would pass through zero
                flip = np.einsum("ij,ij->i", before[:, q:q + 4], after[:, q:q + 4]) < 0.0
                after[flip, q:q + 4] *= -1.0
            step = after - before
            if lon is not None:   # the short way round: 179.99° to -179.99° is 0.02° east
                step[:, lon] = np.mod(step[:, lon] + 180.0, 360.0) - 180.0
            out[ok, 1:] = before + f * step
            if q is not None:
                out[ok, 1 + q:5 + q] /= np.linalg.norm(out[ok, 1 + q:5 + q], axis=1, keepdims=True)
            if lon is not None:
                out[:, 1 + lon] = np.mod(out[:, 1 + lon] + 180.0, 360.0) - 180.0
            out[ok, 0] = np.where(t[ok] >= t1[ok] - TIME_TOLERANCE_S, held[k[ok], 1], held[k[ok] - 1, 1])
        if self._n:
            # a time at a held epoch takes that epoch's values, whatever its neighbours: the newest epoch (live,
            # before the next arrives) and the first after a gap give the same as in a replay
            k = np.clip(np.searchsorted(held[:, 0], t), 0, self._n - 1)
            below = np.maximum(k - 1, 0)
            nearest = np.where(np.abs(held[below, 0] - t) < np.abs(held[k, 0] - t), below, k)
            at = np.abs(held[nearest, 0] - t) <= TIME_TOLERANCE_S
            out[at, 0] = held[nearest[at], 1]
            out[at, 1:] = held[nearest[at], _VALUES:]
        self.counters.unaided_queries += int(np.isnan(out[:, 0]).sum())
        return out

    def values_at(self, t: np.ndarray) -> np.ndarray:
        """Values (N, width) at increasing IMU times ``t`` (N,), NaN rows where nothing is known."""
        return self.aid_at(t)[:, 1:]

    def at(self, t: float) -> np.ndarray | None:
        """Values (width,) at one IMU time, or None."""
        value = self.values_at(np.array([t]))[0]
        return None if np.isnan(value[0]) else value

    def release(self, t: float) -> None:
        """Forget the epochs no query from time ``t`` on needs (all but the last one at or before it)."""
        keep = max(int(np.searchsorted(self._epochs[:self._n, 0], t, side="right")) - 1, 0)
        if keep:
            self._epochs[:self._n - keep] = self._epochs[keep:self._n]
            self._n -= keep


_VALUES = 3
"""Where an epoch's values start in the track's rows (after its time, sequence number and bridged flag)."""


class AidingFeed:
    """An aiding stream read as far ahead as the IMU samples need it (a log, a simulated sensor).

    ``blocks`` yields epoch arrays (N, 1 + width) in the stream's order; :meth:`aid_at` pulls
    blocks into the track until it reaches the last IMU time asked for, then interpolates.
    """

    def __init__(self, track: AidingTrack, blocks: Iterator[np.ndarray]) -> None:
        self.track = track
        self._blocks = blocks
        self._exhausted = False

    def aid_at(self, t: np.ndarray) -> np.ndarray:
        """Rows (N, 1 + width) at IMU times t (N,), increasing: epoch number, values (:meth:`AidingTrack.aid_at`);
        NaN where the stream has nothing."""
        while not self._exhausted and (self.track.latest_time is None or self.track.latest_time < t[-1]):
            block = next(self._blocks, None)
            if block is None:
                self._exhausted = True
            else:
                self.track.push(block)
        rows = self.track.aid_at(t)
        self.track.release(float(t[-1]))
        return rows


def aid_rows(feeds: Mapping[str, AidingFeed], kinds: Sequence[str], t: np.ndarray) -> np.ndarray | None:
    """The aiding of samples at IMU times t (N,) for a pipeline that takes ``kinds`` (its ``aid_kinds``): each kind's
    rows (:meth:`AidingFeed.aid_at`) side by side, in that order; None without aiding."""
    if not kinds:
        return None
    return feeds[kinds[0]].aid_at(t) if len(kinds) == 1 else np.hstack([feeds[kind].aid_at(t) for kind in kinds])


MAX_INTERVAL_S = 2.0
"""The longest stream interval the wait covers by itself (s), and the one it assumes until two epochs show the
stream's own (a 0.5-Hz receiver's first interval is waited for; a fast stream shows its interval at once); a slower
stream needs ``max_wait_s`` raised. The bound keeps a long silence from holding the output: a lone fix after ten
minutes would set a ten-minute interval."""


class AidingWait:
    """IMU samples held until the aiding streams have caught up with them (the daemon's side of the tracks).

    Aiding arrives late (its own latency, transport); a sample leaves once, for every track, the track holds
    an epoch at or after it or the sample is that track's :meth:`wait_s` older than the newest sample (data
    clock, so the outcome does not depend on the machine's speed), then unaided where a track has nothing. The
    wait covers each stream's own interval, so a slow stream (a 1-Hz receiver) needs no setting.
    """

    def __init__(self, tracks: Sequence[AidingTrack], max_wait_s: float) -> None:
        self.tracks = tuple(tracks)
        self.max_wait_s = max_wait_s
        self._rows = np.empty((256, IMU_WIDTH))   # grows to the most ever held (the wait × the IMU rate), then stays
        self._n = 0

    def push(self, rows: np.ndarray) -> None:
        """IMU samples (N, :data:`IMU_WIDTH`): t, Δθ (3), Δv (3), in time order."""
        end = self._n + len(rows)
        self._rows = with_room(self._rows, end)
        self._rows[self._n:end] = rows
        self._n = end

    def release(self, everything: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """(samples (M, :data:`IMU_WIDTH`), aiding rows (M, Σ(1 + width)): per track the epoch number and the values
        (:meth:`AidingTrack.aid_at`), side by side) of the samples whose wait is over (all if ``everything``)."""
        t = self._rows[:self._n, 0]
        if len(t) == 0:
            return np.empty((0, IMU_WIDTH)), np.empty((0, sum(1 + track.width for track in self.tracks)))
        until = np.inf
        if not everything:
            for track in self.tracks:
                latest = track.latest_time
                until = min(until, max(-np.inf if latest is None else latest + TIME_TOLERANCE_S,
                                       t[-1] - self.wait_s(track) + TIME_TOLERANCE_S))
        n = int(np.searchsorted(t, until, side="right"))
        out = self._rows[:n].copy()
        self._rows[:self._n - n] = self._rows[n:self._n]
        self._n -= n
        aid = [track.aid_at(out[:, 0]) for track in self.tracks]
        if n:
            for track in self.tracks:
                track.release(float(out[-1, 0]))
        return out, aid[0] if len(aid) == 1 else np.hstack(aid)

    @property
    def held(self) -> int:
        return self._n

    def wait_s(self, track: AidingTrack) -> float:
        """How long (s of data) a sample waits for ``track``'s epoch after it: ``max_wait_s`` for the stream's
        latency, plus its usual interval once it has started (at most :data:`MAX_INTERVAL_S`, and that until two
        epochs show it). Before the first epoch ``max_wait_s`` alone: nothing earlier than the first epoch can be
        interpolated anyway."""
        if track.latest_time is None:
            return self.max_wait_s
        interval = track.usual_interval_s
        return self.max_wait_s + min(MAX_INTERVAL_S if interval is None else interval, MAX_INTERVAL_S)

"""Turns of a fixed base: whether the body's mean attitude on the Earth has moved (a turntable indexed, a vehicle
turned in place), from the gyros' attitude C_b^{b0} at each control step.

The compass loops' steady state holds the sensors' biases as they were seen in the navigation frame: the
accelerometer bias as a tilt, the east gyro bias as a heading. A turn moves both, and the loops take the change
for a tilt rate and a heading error over their time constants: after a 90° index of a navigation-grade IMU
(50 µg, 0.01°/h) the loops' heading wandered 0.4-0.6° off for minutes while their σ said 0.078°. The
inertial-frame coarse stage carries any rotation by the gyros and its fit spans every position, so on a turn
the pipeline drops the loops and reports the coarse stage's attitude and σ, and starts fresh loops once the
body has stayed put (the loops' stored data then hold no turn either).

A swinging base (a ship, a vehicle rocked by wind) turns back and forth about a steady mean: what the loops
average over their time constants is that mean, so the watch compares means over :data:`TURN_WINDOW_S`. The
gyros' C_b^{b0} of a body at rest on the Earth turns with it at 15°/h; the reference mean is renewed every
:data:`ANCHOR_REFRESH_S`, so that adds at most 0.5° to what the watch sees, with no estimate of the Earth's axis
(a MEMS gyro never has one) and the same events however the steps come in calls.
"""
from __future__ import annotations

import numpy as np

from .conventions import DEG

TURN_DEG = 5.0
"""A turn: the mean attitude moved this far (deg) from the last steady one. Over a 90° index the loops' heading went
0.5° off; 5° moves the accelerometer bias's tilt by a twelfth of that, a heading transient within their σ."""
TURN_WINDOW_S = 20.0
"""The mean attitude's window (s): two periods of a slow swing (a 10-s roll of ±10° leaves its mean within 1.6°),
short against the loops' time constants."""
ANCHOR_REFRESH_S = 120.0
"""A steady body's reference mean is renewed this often (s): the Earth turns it by at most 0.5° in between. A body
turning slower than :data:`TURN_DEG` per refresh is not a turn: the loops follow it within a twentieth of a bias.
A body that turned is steady again once its mean has stayed within :data:`TURN_DEG` of where it was this long: the
same rate both ways, so a table turning steadily between the two (0.04-0.25°/s with a shorter wait) is not taken
for steady and restarted loops that it then turns under (0.9° off under σ 0.08°)."""

WATCHING, TURNING = 0, 1
"""The watch's states: a steady body (watching for a turn), and one that turned (waiting until it is steady)."""
TURNED, STEADY = 1, 2
"""Events of :meth:`TurnWatch.scan`: the body turned; it has been steady again for :data:`ANCHOR_REFRESH_S`."""


class TurnWatch:
    """Watches the control steps' body attitudes for turns (module docstring); ``window_steps`` control steps make
    :data:`TURN_WINDOW_S`."""

    def __init__(self, window_steps: int) -> None:
        self.window_steps = max(int(window_steps), 1)
        self.state = WATCHING
        self.turned = False   # whether any turn has been seen: the coarse fit then spans more than one attitude
        self._sums = np.zeros((0, 4))          # the last window_steps running sums of the sign-continued quaternions
        self._seen = 0                         # control steps taken
        self._q_last: np.ndarray | None = None   # the last quaternion taken (the sign continues from it)
        self._anchor: np.ndarray | None = None   # the unit quaternion of the mean at the last event or refresh
        self._since_s = 0.0                    # when the state last changed or the anchor moved (s)

    def scan(self, t_s: np.ndarray, q_b_b0: np.ndarray) -> list[tuple[int, int]]:
        """Control steps at times ``t_s`` (K,) s with the body attitudes ``q_b_b0`` (K, 4) → the events among them,
        (index, :data:`TURNED` or :data:`STEADY`), in order. The same steps give the same events however they are
        split into calls."""
        if len(t_s) == 0:
            return []
        seen = self._seen
        means = self._window_means(np.asarray(q_b_b0, dtype=float))
        # a window not yet full is no mean of a swing: the watch starts at the first full one
        k = max(self.window_steps - 1 - seen, 0)
        events: list[tuple[int, int]] = []
        if self._anchor is None and k < len(t_s):
            self._anchor, self._since_s = means[k], float(t_s[k])
        while k < len(t_s):
            angle = self._angles_from_anchor(means[k:])
            moved = np.flatnonzero(angle > TURN_DEG * DEG)
            waited = np.flatnonzero(t_s[k:] - self._since_s >= ANCHOR_REFRESH_S)
            first = min(moved[0] if len(moved) else len(angle), waited[0] if len(waited) else len(angle))
            if first == len(angle):
                break
            k += int(first)
            if len(moved) and moved[0] == first:
                if self.state == WATCHING:
                    events.append((k, TURNED))
                self.state, self.turned = TURNING, True
            elif self.state == TURNING:
                events.append((k, STEADY))
                self.state = WATCHING
            self._anchor, self._since_s = means[k], float(t_s[k])
            k += 1
        return events

    def _window_means(self, q: np.ndarray) -> np.ndarray:
        """The mean attitude (K, 4: unit quaternions) over the window ending at each step: the normalised mean of
        the quaternions, their signs continued from step to step (q and −q are one attitude), from running sums
        kept in order."""
        signs = np.sign(np.einsum("ij,ij->i", q[1:], q[:-1]))
        first = 1.0 if self._q_last is None or float(q[0] @ self._q_last) >= 0.0 else -1.0
        signs = np.cumprod(np.concatenate(([first], np.where(signs == 0.0, 1.0, signs))))
        q = q * signs[:, None]
        self._q_last = q[-1].copy()
        self._seen += len(q)
        carried = self._sums[-1:] if len(self._sums) else np.zeros((1, 4))
        sums = np.cumsum(np.concatenate((carried, q)), axis=0)[1:]
        n = self.window_steps
        # each step's sum n steps back (zero while fewer have been seen)
        history = np.concatenate((np.zeros((n - len(self._sums), 4)), self._sums, sums))
        before = history[:len(q)]
        self._sums = history[-n:]
        means = sums - before
        return means / np.linalg.norm(means, axis=1, keepdims=True)

    def _angles_from_anchor(self, means: np.ndarray) -> np.ndarray:
        """The rotation angles (K,) rad of the mean attitudes (K, 4) from the anchor's: 2 acos |⟨q, q_anchor⟩|."""
        return 2.0 * np.arccos(np.minimum(np.abs(means @ self._anchor), 1.0))

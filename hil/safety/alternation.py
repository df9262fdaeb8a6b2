"""Second differences of a reading and how often their sign alternates: what the link noise
watch (hil/safety/link_watches.py) judges the link, the motor and the goal by.

Arrays over the joints, updated in place: the common tick (every joint read, usable
timestamps) is a dozen numpy calls for all joints, whatever their number.

    scaled_second_difference  (slope now - slope before) x period over the sampling instants,
                              or the plain second difference where they are not usable
    SecondDifference          the next second difference of a signal read for every joint at
                              one instant (the motor angle, the goal)
    AlternationCounter        per joint, how many of the last `window` second differences
                              were jumps whose sign is opposite to the previous one's
    CounterPart               some of a counter's joints as a counter (the motor's and the
                              link's counts of the same joints, kept by one counter)
"""

from __future__ import annotations

import math

import numpy as np


def scaled_second_difference(
    step_now: np.ndarray,
    step_before: np.ndarray,
    dt_now: np.ndarray | float,
    dt_before: np.ndarray | float,
    period_s: float,
) -> np.ndarray:
    """(step_now / dt_now - step_before / dt_before) x period where both intervals are > 0,
    else step_now - step_before (timestamps not increasing, or NaN); per joint."""
    if isinstance(dt_now, float) and isinstance(dt_before, float):  # one instant for all
        if dt_now > 0 and dt_before > 0:
            return (step_now / dt_now - step_before / dt_before) * period_s
        return step_now - step_before
    usable = (dt_now > 0) & (dt_before > 0)
    n_usable = np.count_nonzero(usable)
    if n_usable == np.size(usable):
        return (step_now / dt_now - step_before / dt_before) * period_s
    plain = step_now - step_before
    if not n_usable:
        return plain
    with np.errstate(divide="ignore", invalid="ignore"):
        scaled = (step_now / dt_now - step_before / dt_before) * period_s
    return np.where(usable, scaled, plain)


class SecondDifference:
    """The second differences of a signal read for every joint at the same instant.

    It keeps the last reading, the last step (last - before) and the last slope (that step
    over its interval): the next second difference is (slope now - last slope) x period, or
    step now - last step, the same operations on the same numbers as
    `scaled_second_difference` of the last three readings. Defined where the last three
    readings are finite."""

    def __init__(self, n_joints: int) -> None:
        self.n = n_joints
        self.last = np.full(n_joints, math.nan)
        self.time_s = math.nan
        self._step = np.full(n_joints, math.nan)  # last - before
        self._slope = np.full(n_joints, math.nan)  # _step / _dt where _dt > 0
        self._dt = math.nan  # last instant - the one before
        self._step_now = np.empty(n_joints)
        self._slope_now = np.empty(n_joints)
        self._second = np.empty(n_joints)
        self._finite = [np.zeros(n_joints, dtype=bool) for _ in range(3)]  # now, last, before
        self._all_finite = [False, False, False]

    def update(
        self, value: np.ndarray, time_s: float, period_s: float, out: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray | bool | None]:
        """This reading's second differences (into `out` if given) and where they are
        defined: True (every joint), None (no joint) or a mask. The returned array is reused
        by the next update."""
        dt_now = time_s - self.time_s
        step_now = np.subtract(value, self.last, out=self._step_now)
        usable_now = dt_now > 0
        if usable_now:
            np.divide(step_now, dt_now, out=self._slope_now)
        second = self._second if out is None else out
        if usable_now and self._dt > 0:
            np.subtract(self._slope_now, self._slope, out=second)
            second *= period_s
        else:
            np.subtract(step_now, self._step, out=second)
        finite, finite_last, finite_before = self._finite
        np.isfinite(value, out=finite)
        all_finite = np.count_nonzero(finite) == self.n
        defined: np.ndarray | bool | None = True
        if not (all_finite and self._all_finite[1] and self._all_finite[2]):
            mask = finite & finite_last & finite_before
            count = np.count_nonzero(mask)
            defined = None if not count else True if count == self.n else mask
        # shift: the oldest buffers take the newest values
        self.last[:] = value
        self._step, self._step_now = step_now, self._step
        if usable_now:
            self._slope, self._slope_now = self._slope_now, self._slope
        self._dt, self.time_s = dt_now, time_s
        self._finite = [finite_before, finite, finite_last]
        self._all_finite = [False, all_finite, self._all_finite[1]]
        return second, defined


class AlternationCounter:
    """Per joint, how many of the last `window` ticks had a second difference above
    `threshold` whose sign is opposite to the previous tick's (a reading that jumps back and
    forth; a physical motion's second difference changes sign only where its acceleration
    does, a few times per oscillation). Each joint has its own ring and counts only the ticks
    it was added on; while every joint was added on every tick, one slot serves them all."""

    def __init__(self, n_joints: int, window: int, threshold: float) -> None:
        self.threshold = threshold
        self.jumps = np.zeros((window, n_joints), dtype=bool)  # slot x joint
        self.count = np.zeros(n_joints, dtype=int)
        self.last = np.zeros(n_joints)
        self._slot = 0  # every joint's next slot, while they are aligned
        self._index: np.ndarray | None = None  # each joint's next slot, once they are not
        self._joints = np.arange(n_joints)
        self._jump = np.zeros(n_joints, dtype=bool)
        self._opposite = np.zeros(n_joints, dtype=bool)
        self._scratch = np.zeros(n_joints)

    @property
    def window(self) -> int:
        return self.jumps.shape[0]

    def add(self, second_difference: np.ndarray, joints: np.ndarray | None = None) -> None:
        """Count this tick's second differences of the joints in `joints` (a mask; None: all)."""
        second, jump = second_difference, self._jump
        np.greater(np.abs(second, out=self._scratch), self.threshold, out=jump)
        np.less(np.multiply(second, self.last, out=self._scratch), 0.0, out=self._opposite)
        jump &= self._opposite
        if joints is None and self._index is None:
            row = self.jumps[self._slot]
            self.count += jump
            self.count -= row
            row[:] = jump
            self._slot = (self._slot + 1) % self.window
            self.last[:] = second
            return
        index = self._index if self._index is not None else np.full(self.count.size, self._slot)
        rows = self._joints if joints is None else self._joints[joints]
        slot = index[rows]
        added = jump[rows]
        self.count[rows] += added
        self.count[rows] -= self.jumps[slot, rows]
        self.jumps[slot, rows] = added
        slot += 1
        slot[slot == self.window] = 0
        index[rows] = slot
        self.last[rows] = second[rows]
        if np.count_nonzero(index == index[0]) == index.size:  # aligned (again)
            self._index, self._slot = None, int(index[0])
        else:
            self._index = index

    def reset_sign(self, joints: np.ndarray | None = None) -> None:
        """A gap in the readings of these joints (a mask; None: all): the next difference has
        no previous sign to alternate with."""
        if joints is None:
            self.last.fill(0.0)
        else:
            self.last[joints] = 0.0


class CounterPart:
    """A contiguous part of a counter's joints, seen as a counter of its own (two signals of
    the same joints counted by one counter: one set of numpy calls for both)."""

    def __init__(self, counter: AlternationCounter, part: slice) -> None:
        self._counter = counter
        self._part = part

    @property
    def count(self) -> np.ndarray:
        return self._counter.count[self._part]

    @property
    def last(self) -> np.ndarray:
        return self._counter.last[self._part]

    @property
    def window(self) -> int:
        return self._counter.window

    def reset_sign(self, joints: np.ndarray | None = None) -> None:
        if joints is None:
            self.last.fill(0.0)
        else:
            self.last[joints] = 0.0

"""The plan's timeline on the control grid: which foot supports at each tick, and for how long.

Segments, in order (durations from `StepTiming`, each a whole number of ticks):

    INITIAL_REST     double support, nothing moves
    for footstep i:  DOUBLE_SUPPORT (weight moves onto the stance foot; after i > 0 this is the
                     double support that follows footstep i-1's touchdown),
                     SINGLE_SUPPORT (footstep i's foot swings; touchdown at the segment's end)
    DOUBLE_SUPPORT   after the last touchdown (weight back between the feet)
    FINAL_REST       double support, nothing moves

Tick k is at t = k dt; a segment covers ticks [start_tick, start_tick + n_ticks). The nominal
touchdown of footstep i is the first tick after its single support.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from controller.walking.footsteps import FootstepPlan, FootstepPlanError, Side


class Support(Enum):
    """Which foot carries the robot."""

    LEFT = "left"
    RIGHT = "right"
    DOUBLE = "double"

    @staticmethod
    def single(side: Side) -> Support:
        return Support.LEFT if side is Side.LEFT else Support.RIGHT


class SegmentKind(Enum):
    INITIAL_REST = "initial_rest"
    DOUBLE_SUPPORT = "double_support"
    SINGLE_SUPPORT = "single_support"
    FINAL_REST = "final_rest"


@dataclass(frozen=True)
class Segment:
    """One phase of the walk on the tick grid.

    landing_side: in SINGLE_SUPPORT the swinging foot (it lands at the end); in a
    DOUBLE_SUPPORT that follows a touchdown, the foot that just landed; else None.
    footstep_index: the index in `plan.footsteps` of that foot's footstep, or None.
    touchdown_time_s: the nominal touchdown time of that footstep, or None.
    """

    kind: SegmentKind
    support: Support
    start_tick: int
    n_ticks: int
    landing_side: Side | None
    footstep_index: int | None
    touchdown_time_s: float | None

    @property
    def end_tick(self) -> int:
        return self.start_tick + self.n_ticks


@dataclass(frozen=True)
class PhaseSample:
    """The phase signal at one tick (what a controller schedules on, e.g. Kdist)."""

    kind: SegmentKind
    support: Support
    time_in_phase_s: float
    phase_duration_s: float
    landing_side: Side | None
    footstep_index: int | None
    touchdown_time_s: float | None

    @property
    def time_to_phase_end_s(self) -> float:
        return self.phase_duration_s - self.time_in_phase_s


def duration_ticks(duration_s: float, dt_s: float, name: str) -> int:
    """duration_s as a whole number of ticks, or FootstepPlanError."""
    n = round(duration_s / dt_s)
    if n < 1 or abs(n * dt_s - duration_s) > 1e-9 * max(1.0, duration_s):
        raise FootstepPlanError(
            f"{name} = {duration_s} s is not a whole number (>= 1) of control periods dt = {dt_s} s"
        )
    return n


class WalkTimeline:
    """The plan's segments on the tick grid, and the phase signal per tick."""

    def __init__(self, plan: FootstepPlan, dt_s: float) -> None:
        if not (math.isfinite(dt_s) and dt_s > 0):
            raise FootstepPlanError(f"dt_s must be finite and > 0, got {dt_s}")
        self.plan = plan
        self.dt_s = dt_s
        timing = plan.timing
        n_ss = duration_ticks(timing.single_support_s, dt_s, "single_support_s")
        n_ds = duration_ticks(timing.double_support_s, dt_s, "double_support_s")
        n_init = duration_ticks(timing.initial_rest_s, dt_s, "initial_rest_s")
        n_final = duration_ticks(timing.final_rest_s, dt_s, "final_rest_s")

        segments: list[Segment] = []
        tick = 0

        def add(kind, support, n, side, index, touchdown_tick) -> None:
            nonlocal tick
            touchdown = None if touchdown_tick is None else touchdown_tick * dt_s
            segments.append(Segment(kind, support, tick, n, side, index, touchdown))
            tick += n

        add(SegmentKind.INITIAL_REST, Support.DOUBLE, n_init, None, None, None)
        touchdown_ticks: list[int] = []
        liftoff_ticks: list[int] = []
        previous: int | None = None
        for i, step in enumerate(plan.footsteps):
            if previous is None:
                add(SegmentKind.DOUBLE_SUPPORT, Support.DOUBLE, n_ds, None, None, None)
            else:
                prev_side = plan.footsteps[previous].side
                add(
                    SegmentKind.DOUBLE_SUPPORT,
                    Support.DOUBLE,
                    n_ds,
                    prev_side,
                    previous,
                    touchdown_ticks[previous],
                )
            liftoff_ticks.append(tick)
            touchdown_ticks.append(tick + n_ss)
            add(
                SegmentKind.SINGLE_SUPPORT,
                Support.single(step.side.other),
                n_ss,
                step.side,
                i,
                touchdown_ticks[i],
            )
            previous = i
        last = len(plan.footsteps) - 1
        add(
            SegmentKind.DOUBLE_SUPPORT,
            Support.DOUBLE,
            n_ds,
            plan.footsteps[last].side,
            last,
            touchdown_ticks[last],
        )
        add(SegmentKind.FINAL_REST, Support.DOUBLE, n_final, None, None, None)

        self.segments: tuple[Segment, ...] = tuple(segments)
        self.n_ticks: int = tick
        self.liftoff_ticks = np.array(liftoff_ticks, dtype=int)
        self.touchdown_ticks = np.array(touchdown_ticks, dtype=int)
        self.liftoff_times_s = self.liftoff_ticks * dt_s
        self.touchdown_times_s = self.touchdown_ticks * dt_s
        segment_of_tick = np.empty(self.n_ticks, dtype=np.int32)
        for index, seg in enumerate(self.segments):
            segment_of_tick[seg.start_tick : seg.end_tick] = index
        segment_of_tick.setflags(write=False)
        self.segment_of_tick = segment_of_tick

    def __len__(self) -> int:
        return self.n_ticks

    def time_s(self) -> np.ndarray:
        return np.arange(self.n_ticks) * self.dt_s

    def segment(self, tick: int) -> Segment:
        return self.segments[self.segment_of_tick[tick]]

    def phase(self, tick: int) -> PhaseSample:
        """The phase signal at `tick` (0 <= tick < n_ticks)."""
        seg = self.segments[self.segment_of_tick[tick]]
        return PhaseSample(
            kind=seg.kind,
            support=seg.support,
            time_in_phase_s=(tick - seg.start_tick) * self.dt_s,
            phase_duration_s=seg.n_ticks * self.dt_s,
            landing_side=seg.landing_side,
            footstep_index=seg.footstep_index,
            touchdown_time_s=seg.touchdown_time_s,
        )

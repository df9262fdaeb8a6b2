"""The words of `hil`, as types: controller choices, safety causes and reactions, run endings.

Everything above this module compares these types, never the strings users type; the strings
appear once, here (and the controller names once, in `controller.ControllerKind`).
"""

from __future__ import annotations

import abc
import enum
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING

from controller import COMPOSITION_READINGS, ControllerKind
from controller.gravity import GcCompliance

if TYPE_CHECKING:
    from drivers.joint_bus import JointSample

__all__ = [
    "ControllerChoice",
    "ControllerKind",
    "ControllerRef",
    "EmulatorClock",
    "NoticeKind",
    "Reaction",
    "ReactionPolicy",
    "RestCondition",
    "Robot",
    "RunEnding",
    "SafetyCause",
    "SafetyEvent",
    "SafetyNotice",
    "Termination",
]


class Reaction(enum.StrEnum):
    """What the supervisor does when a watch fires (configured per cause in `[safety]`; an
    experiment may do one as another on its robot: `ReactionPolicy`, below).

    hold         hold the motors where they are
    back_off     move each goal away from the direction its motor current pushes, then hold
    torque_off   torque off on every joint
    finish_step  the controller goes on along the experiment's reference until the experiment's
                 rest is reached (a walk: both feet carry the robot), then hold; `hold` at once
                 in an experiment that names no rest
    """

    HOLD = "hold"
    BACK_OFF = "back_off"
    TORQUE_OFF = "torque_off"
    FINISH_STEP = "finish_step"


# --- how a robot does the reactions ---------------------------------------------------------
# [safety] on_<cause> says what to do about a cause; what a reaction does to a robot depends on
# the robot. Backing each joint off against its own current relieves the testbed's link pressed
# on its block, and throws a walking humanoid over (twelve joints moved 0.05 rad each its own
# way, on one foot). So an experiment declares, once, how its robot does the reactions
# (`Experiment.reaction_policy`, hil/experiments/base.py): which it does as another
# (`instead`), and its `RestCondition`, where a `finish_step` ends and the supervisor holds.
# The supervisor (hil/safety/supervisor.py) applies it and records both the configured reaction
# and the one done; it knows nothing of feet or steps. The humanoid's: hil/experiments/legs.py
# `on_feet`.


class RestCondition(abc.ABC):
    """Where a `finish_step` ends: asked once per tick while it runs, in tick order (it may
    count), with that tick's sample; made fresh for each run."""

    @abc.abstractmethod
    def reached(self, sample: JointSample) -> str | None:
        """What shows the robot at rest on this tick (for the record), or None: not yet."""

    @abc.abstractmethod
    def describe(self) -> str:
        """The condition, in a line."""


@dataclass(frozen=True)
class ReactionPolicy:
    """How one run's robot does the reactions (the comment above).

    instead: reaction configured -> reaction done (absent: as configured).
    rest: where `finish_step` ends (None: it holds at once).
    within_s: how long a `finish_step` may take to reach its rest; past it the supervisor holds
        where the robot is (a step that cannot be finished is not walked on for ever).
    """

    instead: Mapping[Reaction, Reaction] = field(default_factory=lambda: MappingProxyType({}))
    rest: RestCondition | None = None
    within_s: float = 0.0

    def __post_init__(self) -> None:
        if Reaction.TORQUE_OFF in self.instead or Reaction.TORQUE_OFF in self.instead.values():
            raise ValueError("torque_off is done as configured: a policy cannot change it")
        if not self.within_s >= 0:
            raise ValueError(f"within_s must be >= 0, got {self.within_s}")
        object.__setattr__(self, "instead", MappingProxyType(dict(self.instead)))

    def done_as(self, reaction: Reaction) -> Reaction:
        return self.instead.get(reaction, reaction)


class SafetyCause(enum.StrEnum):
    """Why the supervisor fired; `[safety] on_<value>` holds each cause's reaction."""

    HARDWARE_ERROR = "hardware_error"
    TORQUE_LOST = "torque_lost"
    BUS_ERROR = "bus_error"
    LINK_STALE = "link_stale"
    LINK_NOISY = "link_noisy"  # the link encoder jumps, the motor does not: the sensor
    OSCILLATION = "oscillation"  # link and motor move back and forth together: the joint
    DEFLECTION = "deflection"
    CURRENT = "current"
    COMMAND_INVALID = "command_invalid"
    GOAL_SATURATED = "goal_saturated"
    GAIN_OUT_OF_RANGE = "gain_out_of_range"
    OVERRUN = "overrun"
    CONTROLLER_FAULT = "controller_fault"  # the controller raised or broke its contract

    @property
    def config_key(self) -> str:
        return f"on_{self.value}"


class Termination(enum.StrEnum):
    """How a run ended."""

    COMPLETED = "completed"
    SAFETY_STOP = "safety stop"  # ran its course, but a watch latched a safe state
    INTERRUPTED = "interrupted"
    START_REFUSED = "start refused"
    BUS_FAILURE = "bus failure"
    ERROR = "error"

    @property
    def ran_its_course(self) -> bool:
        """The experiment's timeline ran to its end (a safety stop is a result, not a failure
        of the run)."""
        return self in (Termination.COMPLETED, Termination.SAFETY_STOP)


@dataclass(frozen=True)
class RunEnding:
    """A termination and what it was about, e.g. safety stop: hardware_error (torque_off)."""

    termination: Termination
    detail: str = ""

    @property
    def text(self) -> str:
        return f"{self.termination}: {self.detail}" if self.detail else str(self.termination)

    @property
    def ok(self) -> bool:
        return self.termination is Termination.COMPLETED

    def __str__(self) -> str:
        return self.text


class Robot(enum.StrEnum):
    """The robots hil knows, each one folder (hil/robots/<name>/, registered in
    hil/robots/registry.py): what `[model] robot` and `--robot` name.

    testbed        the paper's 1-DoF testbed (several joints: independent copies of it)
    dyros-jet      the humanoid's 12 leg joints (Kim et al., Sec. IV-C)
    fixed-base     your own fixed-base robot from its URDF (`[model] description`)
    manipulator-h  ROBOTIS MANIPULATOR-H, 6 DoF, a fixed-base robot from its published URDF

    The testbed's old name "single_link" is read as "testbed" (a silent alias: configuration
    files and the meta.json of runs made before the name changed load as they did)."""

    TESTBED = "testbed"
    DYROS_JET = "dyros-jet"
    FIXED_BASE = "fixed-base"
    MANIPULATOR_H = "manipulator-h"

    @classmethod
    def _missing_(cls, value: object) -> Robot | None:
        return cls.TESTBED if value == _TESTBED_OLD_NAME else None


_TESTBED_OLD_NAME = "single_link"  # [model] robot before the robots had one name each


class EmulatorClock(enum.StrEnum):
    """How the emulated plant keeps time."""

    LOCKSTEP = "lockstep"  # one loop period per CAN SYNC: deterministic, faster than real time
    REALTIME = "realtime"  # the wall clock, with wire time: like the hardware


@dataclass(frozen=True)
class ControllerRef:
    """Which controller a run uses, as the record names it and as a worker process finds it
    again (`hil.controllers.load_controller`); made by the registry (`hil.controllers.resolve`)
    for plug-ins, and here for the paper's four.

    name        what the record calls it: "gc+lqr+dob", or a plug-in's class name "PdGravity"
    spec        where it is loaded from: a registry name ("pid"), "path/to/file.py:Class",
                "package.module:Class"
    paper       which of the paper's four controllers it is (its comparisons' relations are
                about those), or None
    uses_kdist  the DOB's gain Kdist applies (--kdist, [safety] max_kdist, Kdist schedules)
    has_composition  a reading of the paper's (25) applies (--composition)
    has_gravity_compensator  the compliance (8) of a gravity compensator applies
    needs_link_angle  it reads the link encoders (refused on a robot without them)
    """

    name: str
    spec: str
    paper: ControllerKind | None = None
    uses_kdist: bool = False
    has_composition: bool = False
    has_gravity_compensator: bool = False
    needs_link_angle: bool = True

    @classmethod
    def of_paper(cls, kind: ControllerKind) -> ControllerRef:
        """One of the paper's four controllers (what each has: `ControllerKind`)."""
        kind = ControllerKind(kind)
        return cls(
            name=kind.value,
            spec=kind.value,
            paper=kind,
            uses_kdist=kind.has_dob,
            has_composition=kind.has_lqr,
            has_gravity_compensator=kind is not ControllerKind.PID,
            needs_link_angle=kind.has_lqr,
        )

    @property
    def built_in(self) -> bool:
        return ":" not in self.spec

    @property
    def dir_name(self) -> str:
        """The controller's part of a run directory's name: 'gc-lqr-dob', 'pd-gravity'."""
        text = self.name.replace("+", "-")
        text = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "-", text).lower()
        return re.sub(r"[^a-z0-9.-]+", "-", text).strip("-") or "controller"

    def __str__(self) -> str:
        return self.name


@dataclass(frozen=True)
class ControllerChoice:
    """A controller to run: which one (`controller`: one of the paper's four by its
    `ControllerKind`, or any `ControllerRef`), its DOB gain, and (optionally) its reading of
    (25) and the compliance its gravity compensator offsets.

    kdist counts only for a controller with a DOB (it is 0 for the others); reading None means
    the configuration's `[controller] composition`, gc_compliance None its `gc_compliance` (the
    comparisons run GC once more with the other reading, "gear": the paper's literal K^-1).
    """

    controller: ControllerRef | ControllerKind | str
    kdist: float = 0.0
    reading: str | None = None
    gc_compliance: GcCompliance | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.controller, ControllerRef):
            try:
                kind = ControllerKind(self.controller)
            except ValueError:
                raise ValueError(
                    f"{self.controller!r} is not one of the paper's controllers "
                    f"{[k.value for k in ControllerKind]}: a plug-in's ControllerRef comes from "
                    "hil.controllers.resolve"
                ) from None
            object.__setattr__(self, "controller", ControllerRef.of_paper(kind))
        ref = self.ref
        if not ref.uses_kdist:
            object.__setattr__(self, "kdist", 0.0)
        if not (math.isfinite(self.kdist) and self.kdist >= 0):
            raise ValueError(f"kdist must be finite and >= 0, got {self.kdist}")
        if self.reading is not None and self.reading not in COMPOSITION_READINGS:
            raise ValueError(f"reading must be one of {COMPOSITION_READINGS}, got {self.reading!r}")
        if self.gc_compliance is not None:
            if not ref.has_gravity_compensator:
                raise ValueError(
                    f"{ref.name} has no gravity compensator: gc_compliance does not apply"
                )
            object.__setattr__(self, "gc_compliance", GcCompliance(self.gc_compliance))

    @property
    def ref(self) -> ControllerRef:
        assert isinstance(self.controller, ControllerRef)  # (made one by __post_init__)
        return self.controller

    @property
    def kind(self) -> ControllerKind | None:
        """Which of the paper's four controllers this is (None: another one)."""
        return self.ref.paper

    @property
    def name(self) -> str:
        return self.ref.name

    @property
    def uses_kdist(self) -> bool:
        return self.ref.uses_kdist

    @property
    def label(self) -> str:
        """'gc+lqr+dob (Kdist 1)', with ', literal (25)' when a reading is named and ', gear
        (8)' when the compliance is."""
        name = self.ref.name
        label = f"{name} (Kdist {self.kdist:g})" if self.uses_kdist else name
        if self.reading:
            label += f", {self.reading} (25)"
        return f"{label}, {self.gc_compliance} (8)" if self.gc_compliance else label

    @property
    def dir_name(self) -> str:
        """'gc-lqr-dob-k1-literal': a directory name for a run of this controller."""
        name = self.ref.dir_name
        if self.uses_kdist:
            name += f"-k{self.kdist:g}"
        if self.reading:
            name += f"-{self.reading}"
        return f"{name}-{self.gc_compliance}" if self.gc_compliance else name

    def with_reading(self, reading: str | None) -> ControllerChoice:
        return ControllerChoice(self.controller, self.kdist, reading, self.gc_compliance)


@dataclass(frozen=True)
class SafetyEvent:
    """A watch fired: `action` is the reaction configured for the cause, `state` the
    supervisor's state after it (a milder cause after a severe one leaves the severe state)."""

    tick: int
    time_s: float
    cause: SafetyCause
    joint: str | None
    action: Reaction
    message: str
    state: str = ""

    def record(self) -> dict[str, object]:
        return {
            "tick": self.tick,
            "time_s": self.time_s,
            "cause": str(self.cause),
            "joint": self.joint,
            "action": str(self.action),
            "message": self.message,
            "state": self.state,
        }


class NoticeKind(enum.StrEnum):
    """Things worth a line in the log that do not change the supervisor's state."""

    BUS_GLITCH = "bus_glitch"
    BUS_RECOVERED = "bus_recovered"
    LINK_GLITCH = "link_glitch"
    LINK_RECOVERED = "link_recovered"
    GOAL_LIMITED = "goal_limited"


@dataclass(frozen=True)
class SafetyNotice:
    """A tolerated bus or encoder glitch, a goal clipped at a position limit."""

    tick: int
    time_s: float
    kind: NoticeKind
    joint: str | None
    message: str

    def record(self) -> dict[str, object]:
        return {
            "tick": self.tick,
            "time_s": self.time_s,
            "kind": str(self.kind),
            "joint": self.joint,
            "message": self.message,
        }

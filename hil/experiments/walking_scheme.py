"""The lab's walking scheme on a run: the walking pattern's reference, corrected each tick.

`LabWalkingScheme` is the walks' `ReferenceFeedback` (hil/experiments/base.py). Its terms are
`controller.walking.lab_terms`' (the lab's psh117/dyros_jet, walking_controller.cpp), switched
by `[walking]`:

    CoM feedback       every controller: the measured CoM - this tick's link angles around
                       the pelvis where the scheme puts it (the lab's), or the whole robot
                       with the stance sole (hil/experiments/legs.py `anchor_feet`) flat at
                       its planned place - corrects the pelvis by kp per tick, and the legs'
                       IK is solved again for the corrected pelvis
    deflection model   the default controller only (`pid`): gain (a tau + b) on hip pitch,
                       knee and ankle pitch, tau the gravity torque (5) of the planned posture
    support hip roll   the default controller only: the support hip roll's ramped offset
    CoM stabiliser     ours (controller/walking/com_stabiliser.py), every controller: the
                       pelvis moves by -(gain e + damping e'), e the whole CoM's error from the
                       link encoders with the stance sole flat

The default controller is the paper's "default controller" as the lab ran it: the actuator's
own position control (`pid`) with the lab's walking scheme (its three terms).
"""

from __future__ import annotations

import numpy as np

from controller.walking import (
    CenterOfMassFeedback,
    CenterOfMassMeasurement,
    CenterOfMassStabiliser,
    DeflectionModel,
    LegIkError,
    SupportHipRollOffsets,
    WalkingPattern,
    yaw_rotation,
)
from hil.config import Config
from hil.experiments.base import ReferenceFeedback
from hil.experiments.legs import anchor_feet, leg_model, placed_configuration, support_state
from hil.vocabulary import ControllerChoice, ControllerKind


class LabWalkingScheme(ReferenceFeedback):
    """The pattern's joint angles, corrected by the lab's terms (module docstring)."""

    def __init__(
        self,
        pattern: WalkingPattern,
        *,
        com_feedback: CenterOfMassFeedback | None = None,
        deflection: DeflectionModel | None = None,
        hip_roll: SupportHipRollOffsets | None = None,
        stabiliser: CenterOfMassStabiliser | None = None,
        feedback_from_motors: bool = False,
    ) -> None:
        self.pattern = pattern
        self.com_feedback = com_feedback
        self.deflection = deflection
        self.hip_roll = hip_roll
        self.stabiliser = stabiliser
        # the CoM feedback's angles: the motors' (the lab's code) or the links' (default)
        self.feedback_from_motors = feedback_from_motors
        self._stabiliser = None if stabiliser is None else stabiliser.tracker(pattern.dt_s)
        self.correction_m = np.zeros(2)  # the lab's feedback's
        self.stabiliser_correction_m = np.zeros(2)
        self._model = leg_model()
        self._anchors = anchor_feet(pattern)
        self._hip_roll_table = None if hip_roll is None else hip_roll.table(pattern.timeline)
        self._gravity = None
        if deflection is not None:
            from controller.humanoid import HumanoidLegGravity

            self._gravity = HumanoidLegGravity(self._model)
        self.ik_failures = 0

    @classmethod
    def for_run(
        cls, pattern: WalkingPattern, config: Config, choice: ControllerChoice
    ) -> LabWalkingScheme | None:
        """The terms `[walking]` switches on for this controller; None when there are none."""
        walking = config.walking
        position_mode = choice.kind is ControllerKind.PID
        feedback = (
            CenterOfMassFeedback(
                walking.com_feedback_gain,
                walking.com_feedback_limit_m,
                walking.com_measured_from,
            )
            if walking.com_feedback_gain > 0
            else None
        )
        deflection = DeflectionModel() if position_mode and walking.deflection_model else None
        hip_roll = (
            SupportHipRollOffsets() if position_mode and walking.support_hip_roll_offsets else None
        )
        gain, damping = walking.com_stabiliser_gain, walking.com_stabiliser_damping_s
        stabiliser = CenterOfMassStabiliser(gain, damping) if gain or damping else None
        if feedback is None and deflection is None and hip_roll is None and stabiliser is None:
            return None
        return cls(
            pattern,
            com_feedback=feedback,
            deflection=deflection,
            hip_roll=hip_roll,
            stabiliser=stabiliser,
            feedback_from_motors=walking.com_feedback_angles == "motor",
        )

    def describe(self) -> str:
        terms = []
        if self.com_feedback is not None:
            feedback = self.com_feedback
            terms.append(
                f"CoM feedback on the pelvis ({feedback.measured_from}), kp "
                f"{feedback.gain_per_tick:g}" + (" per tick" if feedback.integrates else "")
            )
        if self.deflection is not None:
            terms.append("deflection model (Humanoids 2016)")
        if self.hip_roll is not None:
            terms.append("support hip-roll offsets")
        text = "the lab's walking scheme: " + ", ".join(terms) if terms else ""
        if self.stabiliser is not None:
            ours = (
                f"the CoM stabiliser (ours), gain {self.stabiliser.gain:g}, damping "
                f"{self.stabiliser.damping_s:g} s"
            )
            text = f"{text}; {ours}" if text else ours
        return text

    def reference(
        self,
        time_s: float,
        planned_rad: np.ndarray,
        link_angle_rad: np.ndarray,
        motor_angle_rad: np.ndarray | None = None,
    ) -> np.ndarray:
        pattern = self.pattern
        tick = min(pattern.n_ticks - 1, max(0, int(round(time_s / pattern.dt_s))))
        angles = np.asarray(planned_rad, dtype=float)
        if self.com_feedback is not None or self._stabiliser is not None:
            measured = link_angle_rad
            if self.feedback_from_motors and motor_angle_rad is not None:
                measured = motor_angle_rad
            angles = self._com_corrected(tick, angles, measured)
        if self.deflection is not None:
            gravity = self._gravity
            gravity.set_support(support_state(pattern.timeline.phase(tick).support))
            angles = angles + self.deflection.offsets(gravity.gravity_torque(planned_rad))
        if self._hip_roll_table is not None:
            angles = angles + self._hip_roll_table[tick]
        return angles

    def _com_corrected(self, tick: int, planned: np.ndarray, links: np.ndarray) -> np.ndarray:
        """The planned angles with the pelvis moved by the corrections (the plan's own angles,
        and the corrections kept, where the IK cannot reach)."""
        pattern, model = self.pattern, self._model
        pelvis = np.array(pattern.pelvis_position_m[tick], dtype=float)
        desired = pattern.com_position_m[tick]
        placed = None  # the robot from its encoders, the stance sole flat at its planned place
        feedback = self.com_feedback
        correction = self.correction_m
        if feedback is not None:
            source = feedback.measured_from
            if source is CenterOfMassMeasurement.COMMANDED_PELVIS:
                # the measured legs around the pelvis where the last correction puts it
                around = pelvis + np.array([*self.correction_m, 0.0])
                q = model.configuration(links, around, yaw_rotation(pattern.pelvis_yaw_rad[tick]))
            else:
                q = placed = placed_configuration(
                    model, links, int(self._anchors[tick]), pattern, tick
                )
            measured = model.centre_of_mass(q)
            if source is CenterOfMassMeasurement.MEASURED_PELVIS:
                correction = feedback.measured_pelvis_correction(pelvis, q[:3], desired, measured)
            else:
                correction = feedback.update(self.correction_m, desired, measured)
        stabilising = self.stabiliser_correction_m
        if self._stabiliser is not None:
            if placed is None:
                placed = placed_configuration(model, links, int(self._anchors[tick]), pattern, tick)
            stabilising = self._stabiliser.correction(model.centre_of_mass(placed), desired)
        moved = pelvis.copy()
        moved[:2] += correction + stabilising
        try:
            angles = pattern.leg_angles_with_pelvis(tick, moved)
        except LegIkError:  # out of reach: keep the last corrections (or the plan's pelvis)
            self.ik_failures += 1
            moved[:2] = pelvis[:2] + self.correction_m + self.stabiliser_correction_m
            try:
                return pattern.leg_angles_with_pelvis(tick, moved)
            except LegIkError:
                return planned
        self.correction_m = correction
        self.stabiliser_correction_m = stabilising
        return angles

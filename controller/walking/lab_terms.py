"""The lab's walking scheme around the pattern: its CoM feedback and its position-mode terms.

Source: the lab's public code, psh117/dyros_jet (BSD-2-Clause, (c) 2017 Suhan Park),
`dyros_jet_controller/src/walking_controller.cpp`, master 5f542dd4 unless stated. Three terms,
each a small frozen dataclass, each switchable by its caller:

CenterOfMassFeedback (`WalkingController::getPelvTrajectory`, with `getRobotState`)
    Every tick the pelvis is placed at the pelvis it had plus kp (CoM desired - CoM measured),
    x and y, kp = 0.15 on master (0.9 in 5628d3b7, May 2018; 1.0 in e65f1a41 and 08561284,
    June 2018). Here the correction is kept apart from the plan (the lab's pattern has no
    pelvis of its own: it is this iteration; ours is solved for the planned CoM):

        correction(k) = correction(k-1) + kp (c_desired(k) - c_measured(k))      (x, y)
        pelvis(k) = pattern's pelvis(k) + correction(k)

    What "measured" is (`CenterOfMassMeasurement`):
    - "commanded-pelvis" (the lab's master): the CoM of the measured joint angles hung from
      the pelvis where the scheme places it (master: `pelv_support_current_` from the previous
      tick's IK output, the CoM around it from the motor angles; here from the link angles).
      With c_desired = pelvis + r(planned angles), c_measured = pelvis + correction(k-1) +
      r(measured angles), so correction -> r(planned) - r(measured), a first-order filter
      (dt / kp = 33 ms): the pelvis moves so that the legs' measured shape puts the CoM where
      the plan's shape would. It does not see the robot sway on its compliant joints (the
      pelvis is placed, not measured), and it is stable whatever that sway does.
    - "measured-pelvis" (the lab's May-June 2018 form, 5628d3b7 kp 0.9, e65f1a41 and 08561284
      kp 1.0: `pelv_support_current_` and `com_support_current_` both from the measured joint
      angles with the support foot as the root): no integral,

          pelvis(k) = pelvis measured(k) + kp (c_desired(k) - c_measured(k))      (x, y),

      both measured with the stance sole flat at its planned place (the lab's robot measured
      its motor angles; here the link angles). With c = pelvis + r(angles), the sway the
      robot makes on its joints enters pelvis measured and c_measured alike: at kp = 1 the
      pelvis goes to c_desired - r(measured angles), the plan's pelvis moved by the measured
      legs' shape, and the sway cancels; at kp < 1 a share 1 - kp of the measured CoM error
      is added to the command (a positive feedback of 0.1 at kp = 0.9, softening the sway).
    - "stance-sole": the whole CoM from the link angles with the stance sole flat at its
      planned place (what the robot's own encoders say of the sway). The correction then
      integrates the whole CoM error at kp / dt (30 1/s at 0.15): in steady state the CoM is
      where the plan wants it, whatever the legs' compliance. On the emulated DYROS-JET this
      loop goes through the robot's sway on its ankles (gear and servo in series, 1130 N m/rad
      for both ankles against m g h = 410 N m/rad: about 4.6 rad/s) and makes it grow
      (docs/walking.md); the May-June 0.9-1.0 belong to the lab's proportional form around
      the measured pelvis and are no integral gains.
    `max_correction_m` bounds the correction (ours, not the lab's: a falling robot's CoM error
    must not drag the pelvis out of the legs' reach).

DeflectionModel (`WalkingController::hipCompensation`; J. Kim, M. Kim, J. Park, "Improvement
    of Humanoid Walking Control by Compensating Actuator Elasticity", Humanoids 2016, which the
    file's header cites as ICHR_2016_JS.pdf)
    With the LQR off, the lab adds to the IK angles gain (a tau + b), a = -0.0012 rad/N m,
    b = 0.000874 rad: gain 0.2 on the hip pitch, 0.3 on the knee, 0.2 on the ankle pitch, per
    leg. Its tau is the leg's share of the weight through hand-derived rows of each leg's
    Jacobian (hip roll, hip pitch, knee; none for the ankle, so the ankle pitch gets b alone),
    with the opposite sign of (5)'s tau_g (checked: at the walking-ready posture its knees
    carry +38.7 / -37.5 N m where (5) gives -31.9 / +31.8). Here tau is (5)'s, sign turned:
    offset = gain (-a tau_g + b).

SupportHipRollOffsets (`WalkingController::hipCompensator`)
    With the LQR off, the support leg's hip roll gets a fixed offset: +4 deg on the left hip
    roll in left support, -8.5 deg on the right in right support (master; the robot's own
    asymmetry, kept as published). It rises along a cubic over the first 0.1 s of the single
    support and falls along a cubic from 0.1 s before its end to the end of the lab's second
    double support (0.1 s after touchdown). The lab's later right-support steps fall from the
    left's 4 deg instead of 8.5 (a jump); here each falls from its own offset.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from controller.walking.footsteps import Side
from controller.walking.timeline import SegmentKind, WalkTimeline

N_LEG_JOINTS = 12
HIP_ROLL, HIP_PITCH, KNEE, ANKLE_PITCH = 1, 2, 3, 4  # within one leg (lab order)
LAB_COM_FEEDBACK_GAIN = 0.15  # master's kp


class CenterOfMassMeasurement(enum.StrEnum):
    """Where the CoM feedback's measured CoM comes from (module docstring)."""

    COMMANDED_PELVIS = "commanded-pelvis"  # the lab's master: measured shape, placed pelvis
    MEASURED_PELVIS = "measured-pelvis"  # the lab's 2018: pelvis and CoM both measured
    STANCE_SOLE = "stance-sole"  # the whole robot from its encoders, the stance sole flat


@dataclass(frozen=True)
class CenterOfMassFeedback:
    """The pelvis correction from the measured CoM (module docstring): gain_per_tick kp,
    max_correction_m the bound on the correction's length [m], measured_from the CoM's
    source."""

    gain_per_tick: float = LAB_COM_FEEDBACK_GAIN
    max_correction_m: float = 0.05
    measured_from: CenterOfMassMeasurement = CenterOfMassMeasurement.COMMANDED_PELVIS

    def __post_init__(self) -> None:
        if not (math.isfinite(self.gain_per_tick) and 0 < self.gain_per_tick <= 1):
            raise ValueError(f"gain_per_tick must be in (0, 1], got {self.gain_per_tick}")
        if not (math.isfinite(self.max_correction_m) and self.max_correction_m > 0):
            raise ValueError(f"max_correction_m must be > 0, got {self.max_correction_m}")
        object.__setattr__(self, "measured_from", CenterOfMassMeasurement(self.measured_from))

    @property
    def integrates(self) -> bool:
        """The correction accumulates per tick (every form but "measured-pelvis")."""
        return self.measured_from is not CenterOfMassMeasurement.MEASURED_PELVIS

    def update(
        self, correction_m: np.ndarray, desired_com_m: np.ndarray, measured_com_m: np.ndarray
    ) -> np.ndarray:
        """correction + kp (desired - measured) in x, y, its length capped: the new (2,)."""
        error = np.asarray(desired_com_m, dtype=float)[:2] - np.asarray(measured_com_m)[:2]
        updated = np.asarray(correction_m, dtype=float) + self.gain_per_tick * error
        return self._bounded(updated)

    def measured_pelvis_correction(
        self,
        planned_pelvis_m: np.ndarray,
        measured_pelvis_m: np.ndarray,
        desired_com_m: np.ndarray,
        measured_com_m: np.ndarray,
    ) -> np.ndarray:
        """The "measured-pelvis" form (module docstring): pelvis measured + kp (desired -
        measured CoM), returned as its offset from the planned pelvis (x, y), capped."""
        error = np.asarray(desired_com_m, dtype=float)[:2] - np.asarray(measured_com_m)[:2]
        pelvis = np.asarray(measured_pelvis_m, dtype=float)[:2] + self.gain_per_tick * error
        return self._bounded(pelvis - np.asarray(planned_pelvis_m, dtype=float)[:2])

    def _bounded(self, correction_m: np.ndarray) -> np.ndarray:
        length = float(np.hypot(*correction_m))
        if length > self.max_correction_m:
            correction_m = correction_m * (self.max_correction_m / length)
        return correction_m


@dataclass(frozen=True)
class DeflectionModel:
    """The Humanoids-2016 deflection model as the lab applied it (module docstring):
    offset = gain (a tau_lab + b) with tau_lab = -tau_g of (5)."""

    slope_rad_per_nm: float = -0.0012  # a
    offset_rad: float = 0.000874  # b (the code's 0.00087420)
    hip_pitch_gain: float = 0.2
    knee_gain: float = 0.3
    ankle_pitch_gain: float = 0.2

    def offsets(self, gravity_torque_nm: np.ndarray) -> np.ndarray:
        """The 12 leg joints' offsets [rad] for (5)'s tau_g (lab order)."""
        tau = np.asarray(gravity_torque_nm, dtype=float)
        if tau.shape != (N_LEG_JOINTS,):
            raise ValueError(f"gravity_torque_nm must have {N_LEG_JOINTS} entries")
        a, b = self.slope_rad_per_nm, self.offset_rad
        offsets = np.zeros(N_LEG_JOINTS)
        for leg in (0, 6):
            for joint, gain in ((HIP_PITCH, self.hip_pitch_gain), (KNEE, self.knee_gain)):
                offsets[leg + joint] = gain * (a * -tau[leg + joint] + b)
            offsets[leg + ANKLE_PITCH] = self.ankle_pitch_gain * b  # no ankle row: b alone
        return offsets


@dataclass(frozen=True)
class SupportHipRollOffsets:
    """The support hip roll's ramped offsets (module docstring)."""

    left_rad: float = math.radians(4.0)
    right_rad: float = math.radians(8.5)
    ramp_s: float = 0.1
    release_after_touchdown_s: float = 0.1  # the lab's second double support

    def table(self, timeline: WalkTimeline) -> np.ndarray:
        """The offsets on the timeline's grid: (n_ticks, 12) [rad], zero on every joint but the
        support leg's hip roll."""
        dt = timeline.dt_s
        table = np.zeros((timeline.n_ticks, N_LEG_JOINTS))
        time_s = np.arange(timeline.n_ticks) * dt
        for segment in timeline.segments:
            if segment.kind is not SegmentKind.SINGLE_SUPPORT:
                continue
            stance = segment.landing_side.other
            if stance is Side.LEFT:
                joint, peak = HIP_ROLL, self.left_rad
            else:
                joint, peak = 6 + HIP_ROLL, -self.right_rad
            start, end = segment.start_tick * dt, segment.end_tick * dt
            rise = _cubic((time_s - start) / self.ramp_s)
            fall = 1.0 - _cubic(
                (time_s - (end - self.ramp_s)) / (self.ramp_s + self.release_after_touchdown_s)
            )
            window = (time_s >= start) & (time_s < end + self.release_after_touchdown_s)
            table[window, joint] += peak * np.minimum(rise, fall)[window]
        return table


def _cubic(s: np.ndarray) -> np.ndarray:
    """3 s^2 - 2 s^3 on [0, 1], 0 before, 1 after (the lab's DyrosMath::cubic, zero slopes)."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)

"""The four controllers of Kim et al., ICRA 2018, Sec. IV, behind one interface the loop uses.

    "pid"         the actuator's own position control: the desired link angle goes straight
                  to the servo as its goal (the paper's "PID" / default controller; on the
                  walks the lab's scheme shapes that reference: hil/experiments/walking_scheme.py).
    "gc"          gravity compensator only: u = theta_d + ug(theta_d), (8) (ug = C tau_g, C the
                  paper's K^-1 or the whole joint's compliance: controller/gravity.py).
    "gc+lqr"      GC + the discrete derivative-form LQR (21)-(24): u = uc + ug.
    "gc+lqr+dob"  GC + LQR + DOB (9)-(11), composed by (25) in the chosen reading.

The interface and its calling order: controller/joint_controller.py; the parameters:
controller/params.py.
"""

from __future__ import annotations

import numpy as np

from controller.composition import Composition
from controller.dob import DisturbanceObserver
from controller.estimation import (
    FlexibleJointStateEstimator,
)
from controller.gravity import GravityCompensator, GravityModel
from controller.joint_controller import ControllerUsageError, ControlTerms, JointController
from controller.lqr import (
    TrackingGain,
    servo_discretisation,
)
from controller.model import validate_sm
from controller.params import CONTROLLER_NAMES, ControllerKind, ControllerParams
from controller.planned_motion import PlannedMotion


class _FeedForwardController(JointController):
    """The "pid" (no gravity compensator) and "gc" controllers: u = theta_d (+ ug(theta_d))."""

    def __init__(
        self,
        name: str,
        n_joints: int,
        compensator: GravityCompensator | None,
        servo_lead_per_rad: np.ndarray | None = None,
    ) -> None:
        super().__init__(n_joints)
        self.name = name
        self._compensator = compensator
        self._reference = np.zeros(n_joints)
        self._ug = np.zeros(n_joints)
        self._u = np.zeros(n_joints)
        # servo_feedforward: the goal's lead per rad of planned increment, 1 / (Kp dt)
        self._servo_lead_per_rad = servo_lead_per_rad
        self._servo_lead = np.zeros(n_joints)

    def set_planned_motion(self, motion: PlannedMotion | None) -> None:
        if self._servo_lead_per_rad is None:
            return
        if motion is None:
            self._servo_lead[:] = 0.0
            return
        increment = self._joint_array(motion.reference_increment_rad, "reference_increment_rad")
        np.multiply(increment, self._servo_lead_per_rad, out=self._servo_lead)

    def _reset(
        self, motor: np.ndarray, link: np.ndarray, reference: np.ndarray, goal: np.ndarray
    ) -> None:
        self._reference[:] = reference
        self._ug[:] = 0.0
        self._u[:] = goal

    def _resync(self, motor: np.ndarray, link: np.ndarray) -> None:
        return  # no sample history: u depends on the reference only

    def _step(self, motor: np.ndarray, link: np.ndarray, reference: np.ndarray) -> np.ndarray:
        self._reference[:] = reference
        if self._compensator is not None:
            self._ug[:] = self._compensator.input_rad(reference)
        np.add(self._reference, self._ug, out=self._u)
        if self._servo_lead_per_rad is not None:
            self._u += self._servo_lead
        return self._u

    def _notify_applied(self, applied: np.ndarray) -> None:
        self._u[:] = applied

    @property
    def terms(self) -> ControlTerms:
        zero = np.zeros(self.n_joints)
        uc = self._u - self._ug  # the reference, or what of it survived the supervisor
        return ControlTerms(uc, zero, self._ug.copy(), self._u.copy(), zero.copy())


class _LqrController(JointController):
    """The "gc+lqr" and "gc+lqr+dob" controllers: estimator, LQR (+ DOB), composition (25)."""

    def __init__(
        self,
        name: str,
        params: ControllerParams,
        gain: TrackingGain,
        dt_s: float,
        compensator: GravityCompensator,
        use_dob: bool,
    ) -> None:
        n = params.n_joints
        super().__init__(n)
        self.name = name
        self.params = params
        self.dt_s = dt_s
        self._gain = gain
        self._compensator = compensator
        self._estimator = FlexibleJointStateEstimator(
            n, dt_s, params.link_velocity_cutoff_hz, params.link_velocity_increment
        )
        self._dob = (
            DisturbanceObserver(
                params.joints.servo_gain_per_s,
                None,
                dt_s,
                params.kdist,
                servo_discretisation(params.discretisation),
                filter_pole=params.q_filter_pole(dt_s),
                kdist_ramp_ticks=params.kdist_ramp_ticks(dt_s),
            )
            if use_dob
            else None
        )
        integral_time = params.dob_integral_time_s
        self._composition = Composition(
            n,
            params.composition,
            None if integral_time is None else min(1.0, dt_s / integral_time),
        )
        self._error = np.zeros(n)
        self._reference = np.zeros(n)  # the last tick's, for the reference feed-forward
        self._increment = np.zeros(n)
        self._scratch = np.zeros(n)
        self._dob_scaled = np.zeros(n)
        self._no_dob = np.zeros(n)
        self._planned_state_increment = np.zeros(3 * n)
        self._planned_velocity_increment = np.zeros(n)
        self._planned = False
        self._fed_back = np.zeros(3 * n)
        self._servo_increment = np.zeros(n)  # servo_feedforward's increment of the lead
        self._servo_gain = params.joints.servo_gain_per_s
        # dob_expects_gravity_lag: the servo's static lag per rad of ug, (1/(Kpp kv)) / C
        self._expected_lag_per_ug: np.ndarray | None = None
        cascade = params.servo_cascade
        if use_dob and params.dob_expects_gravity_lag and cascade is not None:
            servo = 1.0 / cascade.static_stiffness_nm_per_rad(params.joints)
            self._expected_lag_per_ug = servo / params.compensator_compliance_rad_per_nm
        self._expected_sent = np.zeros(n)

    @property
    def lqr_gain(self) -> TrackingGain:
        return self._gain

    def set_lqr_gain(self, gain: TrackingGain) -> None:
        """Swap the LQR gain between ticks (e.g. Sm scheduled on posture and support foot)."""
        if not isinstance(gain, TrackingGain) or gain.n_joints != self.n_joints:
            raise ValueError(f"gain must be a TrackingGain for {self.n_joints} joints")
        if not np.isclose(gain.dt_s, self.dt_s):
            raise ValueError(f"gain designed for dt {gain.dt_s} s, the loop runs at {self.dt_s} s")
        self._gain = gain

    def set_kdist(self, kdist: np.ndarray | float) -> None:
        """Ramp the DOB gain to `kdist` over params.kdist_ramp_s (the lab's cubic)."""
        if self._dob is None:
            super().set_kdist(kdist)
            return
        self._dob.set_kdist(kdist)

    @property
    def kdist(self) -> np.ndarray:
        """The DOB gain of the last tick (during a ramp: the ramp's value)."""
        if self._dob is None:
            raise ControllerUsageError(f"{self.name!r} has no disturbance observer")
        return self._dob.kdist

    def set_planned_motion(self, motion: PlannedMotion | None) -> None:
        self._servo_increment[:] = 0.0
        if motion is not None and self.params.servo_feedforward:
            np.divide(
                motion.reference_velocity_increment_rad_s,
                self._servo_gain,
                out=self._servo_increment,
            )
        if motion is None or not self.params.reference_feedforward:
            self._planned = False
            return
        n = self.n_joints
        increment = self._joint_array(motion.reference_increment_rad, "reference_increment_rad")
        velocity = self._joint_array(
            motion.reference_velocity_increment_rad_s, "reference_velocity_increment_rad_s"
        )
        planned = self._planned_state_increment
        planned[:n] = increment
        planned[n : 2 * n] = increment
        planned[2 * n :] = velocity
        self._planned_velocity_increment[:] = velocity
        self._planned = True

    def _reset(
        self, motor: np.ndarray, link: np.ndarray, reference: np.ndarray, goal: np.ndarray
    ) -> None:
        self._estimator.reset(motor, link)
        if self._dob is not None:
            self._dob.reset(motor)
        self._composition.reset(goal, self._compensator.input_rad(reference))
        self._reference[:] = reference

    def _resync(self, motor: np.ndarray, link: np.ndarray) -> None:
        self._estimator.resync(motor, link)
        if self._dob is not None:
            self._dob.resync()

    def _step(self, motor: np.ndarray, link: np.ndarray, reference: np.ndarray) -> np.ndarray:
        self._estimator.update(motor, link)
        np.subtract(link, reference, out=self._error)
        # duc(k) = -(Ke e(k) + Kx dx(k))   (24), discrete
        np.matmul(self._gain.error_gain, self._error, out=self._increment)
        fed_back = self._estimator.increment
        motor_velocity = self._estimator.motor_velocity_increment
        if self._planned:  # about the plan's motion (reference_feedforward)
            fed_back = np.subtract(fed_back, self._planned_state_increment, out=self._fed_back)
            motor_velocity = motor_velocity - self._planned_velocity_increment
        np.matmul(self._gain.state_increment_gain, fed_back, out=self._scratch)
        self._increment += self._scratch
        velocity_gain = self._gain.motor_velocity_increment_gain
        if velocity_gain is not None:
            np.matmul(velocity_gain, motor_velocity, out=self._scratch)
            self._increment += self._scratch
        np.negative(self._increment, out=self._increment)
        if self.params.reference_feedforward:  # uc moves with theta_d (d theta_d added)
            self._increment += reference
            self._increment -= self._reference
        self._increment += self._servo_increment  # servo_feedforward (zero without a plan)
        self._reference[:] = reference
        if self._dob is not None:
            # compares against the goal sent last tick (composition.u after notify_applied)
            sent = self._composition.u
            lag = self._expected_lag_per_ug
            if lag is not None:  # the nominal servo under ug's load
                np.multiply(self._composition.ug, lag, out=self._expected_sent)
                sent = np.subtract(sent, self._expected_sent, out=self._expected_sent)
            dob_term = self._dob.update(motor, sent)
            scale = self._gain.dob_gain_scale
            if scale is not None:
                dob_term = np.multiply(dob_term, scale, out=self._dob_scaled)
        else:
            dob_term = self._no_dob
        return self._composition.compose(
            self._increment, dob_term, self._compensator.input_rad(reference)
        )

    def _notify_applied(self, applied: np.ndarray) -> None:
        self._composition.notify_applied(applied)

    @property
    def terms(self) -> ControlTerms:
        composition = self._composition
        estimate = (
            self._dob.filtered_estimate_rad if self._dob is not None else np.zeros(self.n_joints)
        )
        return ControlTerms(
            composition.uc.copy(),
            composition.d_hat.copy(),
            composition.ug.copy(),
            composition.u.copy(),
            estimate,
        )


def make_controller(
    name: ControllerKind | str,
    params: ControllerParams,
    *,
    sm: np.ndarray,
    dt_s: float,
    gravity: GravityModel,
) -> JointController:
    """Build one of `ControllerKind` (or its name) for n = params.n_joints joints at period dt_s.

    sm: Sm of (19), n x n (1-DoF testbed: `controller.model.single_link_sm(I_link)`).
    gravity: the model whose holding torque the compensator feeds forward ("pid" ignores it).
    """
    try:
        kind = ControllerKind(name)
    except ValueError:
        raise ValueError(
            f"unknown controller {name!r}; expected one of {CONTROLLER_NAMES}"
        ) from None
    if not isinstance(params, ControllerParams):
        raise TypeError(f"params must be ControllerParams, got {type(params).__name__}")
    if not (np.isfinite(dt_s) and dt_s > 0):
        raise ValueError(f"dt_s must be finite and > 0, got {dt_s}")
    if not isinstance(gravity, GravityModel):
        raise TypeError(f"gravity must be a controller.gravity.GravityModel, got {type(gravity)}")
    n = params.n_joints
    sm = validate_sm(sm, n)
    probe = np.asarray(gravity.gravity_torque(np.zeros(n)))
    if probe.shape != (n,):
        raise ValueError(
            f"gravity model returns shape {probe.shape} for {n} joints; expected ({n},)"
        )
    compensator = GravityCompensator(gravity, params.compensator_compliance_rad_per_nm)
    if kind is ControllerKind.PID:
        return _FeedForwardController(kind.value, n, None)
    if kind is ControllerKind.GC:
        lead = 1.0 / (params.joints.servo_gain_per_s * dt_s) if params.servo_feedforward else None
        return _FeedForwardController(kind.value, n, compensator, lead)
    gain = params.design_gain(sm, dt_s)
    return _LqrController(kind.value, params, gain, dt_s, compensator, use_dob=kind.has_dob)

"""The four controllers of Kim et al., ICRA 2018, Sec. IV, behind one interface the loop uses.

    "pid"         the actuator's own position control: the desired link angle goes straight
                  to the servo as its goal (the paper's "PID" / default controller; on the
                  walks the lab's scheme shapes that reference: hil/experiments/walking_scheme.py).
    "gc"          gravity compensator only: u = theta_d + ug(theta_d), (8) (ug = C tau_g, C the
                  paper's K^-1 or the whole joint's compliance: controller/gravity.py).
    "gc+lqr"      GC + the discrete derivative-form LQR (21)-(24): u = uc + ug.
    "gc+lqr+dob"  GC + LQR + DOB (9)-(11), composed by (25) in the chosen reading.

Conventions: reference_rad is the desired LINK angle theta_d; the output is the goal MOTOR angle
u for the actuator's position servo; angles in rad; arrays of length n.

Each tick the loop calls `step(theta_m, theta_j, theta_d)`, sends the goal (possibly clipped by
the supervisor), then `notify_applied(goal_sent)`: the DOB and the accumulation use what was
really sent (anti-windup). `reset` must come first and gives a bumpless start from the goal in
force (the hold or homing goal the servo was driven with; see `JointController.reset`). Calling
out of this order raises `ControllerUsageError`.
"""

from __future__ import annotations

import abc
import enum
from dataclasses import dataclass, field

import numpy as np

from controller.composition import COMPOSITION_READINGS, Composition, CompositionReading
from controller.dob import LAB_DOB_CUTOFF_HZ, DisturbanceObserver, resolve_q_filter_pole
from controller.estimation import (
    LINK_VELOCITY_INCREMENTS,
    FlexibleJointStateEstimator,
    LinkVelocityIncrement,
)
from controller.gravity import GravityCompensator, GravityModel
from controller.lqr import (
    COUPLINGS,
    LQR_DESIGNS,
    Coupling,
    LqrDesign,
    LqrWeights,
    TrackingGain,
    servo_discretisation,
)
from controller.lqr_designs import (
    KDIST_REFERENCES,
    GainDesigner,
    KdistReference,
)
from controller.model import FlexibleJointParams, per_joint_array, validate_sm
from controller.planned_motion import PlannedMotion
from controller.servo_cascade import ServoCascadeParams

LAB_KDIST_RAMP_S = 0.1  # the lab's compliant_tick: 0.1 s x 200 Hz = 20 ticks, cubic


class ControllerKind(enum.StrEnum):
    """The four controllers of the paper's comparison (Sec. IV); the value is the name users
    type (`--controller`)."""

    PID = "pid"
    GC = "gc"
    GC_LQR = "gc+lqr"
    GC_LQR_DOB = "gc+lqr+dob"

    @property
    def has_dob(self) -> bool:
        return self is ControllerKind.GC_LQR_DOB

    @property
    def has_lqr(self) -> bool:
        return self in (ControllerKind.GC_LQR, ControllerKind.GC_LQR_DOB)


CONTROLLER_NAMES: tuple[str, ...] = tuple(kind.value for kind in ControllerKind)


class ControllerUsageError(RuntimeError):
    """A controller was called out of order (step before reset, no notify_applied, ...)."""


@dataclass(frozen=True)
class ControllerParams:
    """Everything a controller needs besides Sm, the period and the gravity model.

    joints: K, D, Kp per joint (the nominal model of (1), (4)).
    lqr_weights: Qe, Qx, R of (22) (default: the paper's 10 and 1, as the lab coded them).
    kdist: DOB weighting gain per joint (scalar = all joints); the paper's testbed uses 1.0
        and 0.5, the humanoid 0.2 scheduled to 1.0 at landing. Changeable while running
        (`set_kdist`), along a cubic ramp of kdist_ramp_s.
    kdist_ramp_s: how long a Kdist change takes (default the lab's 0.1 s = 20 ticks at 200 Hz;
        0 = a step); rounded to whole ticks.
    dob_cutoff_hz / dob_filter_pole: the Q filter, by its cut-off or by its pole (at most one;
        neither: the lab's pole 0.7 at 200 Hz, i.e. `LAB_DOB_CUTOFF_HZ` = 11.3533 Hz).
    composition: "accumulated" (the lab's code, default), "literal" or "accumulated-integral"
        (bounded contact against an integrating servo; needs dob_integral_time_s); see
        composition.py.
    dob_integral_time_s: Ti_d of "accumulated-integral" (the servo's velocity-loop integral
        time makes the contact force constant; only with that reading).
    discretisation: the LQR design, "zoh" (default), "euler" (the lab's) or "continuous-cost"
        (the paper's cost (22) over each tick); the DOB's Pn^-1 is Euler with "euler", ZOH
        otherwise (`controller.lqr.servo_discretisation`).
    lqr_coupling: "full" (whole Sm, default), "diagonal" (the lab's: diagonal of Sm only) or
        "closed-chain" (whole Sm, on the motions a closed chain allows: double support; see
        controller/closed_chain.py and controller/lqr_designs.py).
    link_velocity_cutoff_hz: None = plain backward difference (default), else a low pass.
    link_velocity_increment: "backward-difference" (default) or "zero" (the lab's); see
        controller/estimation.py.
    gc_compliance_rad_per_nm: C of the gravity compensator, ug = C tau_g, per joint (scalar =
        all joints); None (default): the paper's K^-1 (controller/gravity.py: `GcCompliance`,
        `joint_static_compliance` for the whole joint's).
    servo_cascade: the LQR's servo model: None for the paper's first-order (4), else the
        actuator's position/velocity cascade with these figures (controller/servo_cascade.py;
        needs discretisation "zoh" or "continuous-cost").
    kdist_reference: what Kdist is measured against: "per-tick" (the lab's: the DOB term
        Kdist q is added per tick whatever the LQR) or "paper-yield" (Kdist scaled per joint so
        that the static yield Ke^-1 Kdist d is the paper's design's; controller/lqr_designs.py).
    reference_feedforward: False (the paper's (21), which takes d theta_d/dt ~ 0: the goal
        follows a moving reference only through the error's integral) or True (the reference's
        increment is added to duc, so uc moves with theta_d and the LQR corrects about it: a
        gentle integral can then follow a walk; docs/humanoid.md). Given a planned motion
        (`set_planned_motion`, a walk's pattern), the fed-back increments are taken about the
        plan's: dx - dx_plan, dx_plan = [d theta_p; d theta_p; d dtheta_p] (and d omega_m -
        d dtheta_p), so that the state-increment gains act on departures from the planned
        motion, not on the motion itself (without it they brake the joint to a fraction of
        the reference's speed; docs/walking.md).
    servo_feedforward: with a planned motion, add the servo's velocity lag on the plan to the
        goal of "gc" and the LQR controllers: u += dtheta_plan/dt / Kp, the inverse of the
        paper's servo model (4) (theta_m follows u with the lag 1/Kp), which under a moving
        reference leaves the motor behind by its velocity over Kp (ours; docs/walking.md).
    dob_expects_gravity_lag: the DOB's nominal servo holds the gravity compensator's load with
        the servo cascade's static stiffness (ours; needs servo_cascade, else no effect). The
        paper's nominal (4) holds any load without lag, so on a servo of finite static
        stiffness Kpp kv (the H54's velocity loop) the DOB reads the compensated weight's lag
        tau_g / (Kpp kv) as a disturbance and yields to it by Kdist: the joint gives way to
        the very load (8) offsets. With it, the DOB compares Pn^-1 theta_m against the goal
        sent minus that expected lag, (1/(Kpp kv)) / C x ug, and yields to the rest: the
        unplanned loads (docs/walking.md).
    """

    joints: FlexibleJointParams
    lqr_weights: LqrWeights = field(default_factory=LqrWeights)
    kdist: np.ndarray | float = 1.0
    kdist_ramp_s: float = LAB_KDIST_RAMP_S
    dob_cutoff_hz: float | None = None
    dob_filter_pole: float | None = None
    composition: CompositionReading = "accumulated"
    dob_integral_time_s: float | None = None
    discretisation: LqrDesign = "zoh"
    lqr_coupling: Coupling = "full"
    link_velocity_cutoff_hz: float | None = None
    link_velocity_increment: LinkVelocityIncrement = "backward-difference"
    gc_compliance_rad_per_nm: np.ndarray | float | None = None
    servo_cascade: ServoCascadeParams | None = None
    kdist_reference: KdistReference = "per-tick"
    reference_feedforward: bool = False
    servo_feedforward: bool = False
    dob_expects_gravity_lag: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.joints, FlexibleJointParams):
            raise TypeError(f"joints must be FlexibleJointParams, got {type(self.joints).__name__}")
        if not isinstance(self.lqr_weights, LqrWeights):
            raise TypeError(
                f"lqr_weights must be LqrWeights, got {type(self.lqr_weights).__name__}"
            )
        object.__setattr__(
            self, "kdist", per_joint_array(self.kdist, "kdist", self.joints.n_joints)
        )
        if not (np.isfinite(self.kdist_ramp_s) and self.kdist_ramp_s >= 0):
            raise ValueError(f"kdist_ramp_s must be finite and >= 0, got {self.kdist_ramp_s}")
        if self.dob_cutoff_hz is not None and self.dob_filter_pole is not None:
            raise ValueError("give dob_cutoff_hz or dob_filter_pole, not both")
        if self.dob_cutoff_hz is not None and not (
            np.isfinite(self.dob_cutoff_hz) and self.dob_cutoff_hz > 0
        ):
            raise ValueError(f"dob_cutoff_hz must be finite and > 0, got {self.dob_cutoff_hz}")
        if self.dob_filter_pole is not None and not (
            np.isfinite(self.dob_filter_pole) and 0 <= self.dob_filter_pole < 1
        ):
            raise ValueError(f"dob_filter_pole must be in [0, 1), got {self.dob_filter_pole}")
        if self.composition not in COMPOSITION_READINGS:
            raise ValueError(
                f"composition must be one of {COMPOSITION_READINGS}, got {self.composition!r}"
            )
        integral = self.dob_integral_time_s
        if (self.composition == "accumulated-integral") != (integral is not None):
            raise ValueError(
                "dob_integral_time_s is required by composition 'accumulated-integral' and "
                f"refused otherwise (composition {self.composition!r}, {integral})"
            )
        if integral is not None and not (np.isfinite(integral) and integral > 0):
            raise ValueError(f"dob_integral_time_s must be finite and > 0, got {integral}")
        if self.discretisation not in LQR_DESIGNS:
            raise ValueError(
                f"discretisation must be one of {LQR_DESIGNS}, got {self.discretisation!r}"
            )
        if self.link_velocity_increment not in LINK_VELOCITY_INCREMENTS:
            raise ValueError(
                f"link_velocity_increment must be one of {LINK_VELOCITY_INCREMENTS}, "
                f"got {self.link_velocity_increment!r}"
            )
        if self.lqr_coupling not in COUPLINGS:
            raise ValueError(f"lqr_coupling must be one of {COUPLINGS}, got {self.lqr_coupling!r}")
        cutoff = self.link_velocity_cutoff_hz
        if cutoff is not None and not (np.isfinite(cutoff) and cutoff > 0):
            raise ValueError(f"link_velocity_cutoff_hz must be None or > 0, got {cutoff}")
        if self.gc_compliance_rad_per_nm is not None:
            compliance = per_joint_array(
                self.gc_compliance_rad_per_nm, "gc_compliance_rad_per_nm", self.joints.n_joints
            )
            if np.any(compliance <= 0):
                raise ValueError(f"gc_compliance_rad_per_nm must be > 0, got {compliance}")
            object.__setattr__(self, "gc_compliance_rad_per_nm", compliance)

    @property
    def compensator_compliance_rad_per_nm(self) -> np.ndarray:
        """C of (8) per joint: gc_compliance_rad_per_nm, or the paper's K^-1."""
        if self.gc_compliance_rad_per_nm is None:
            return 1.0 / self.joints.stiffness_nm_per_rad
        return np.asarray(self.gc_compliance_rad_per_nm)
        if self.kdist_reference not in KDIST_REFERENCES:
            raise ValueError(
                f"kdist_reference must be one of {KDIST_REFERENCES}, got {self.kdist_reference!r}"
            )
        cascade = self.servo_cascade
        if cascade is not None:
            if cascade.n_joints != self.n_joints:
                raise ValueError(
                    f"servo_cascade has {cascade.n_joints} joints, not {self.n_joints}"
                )
            if self.discretisation == "euler":
                raise ValueError(
                    "the servo cascade cannot be designed by forward Euler (its fast pole lies "
                    "beyond -2/dt): use discretisation 'zoh' or 'continuous-cost'"
                )

    @property
    def n_joints(self) -> int:
        return self.joints.n_joints

    def q_filter_pole(self, dt_s: float) -> float:
        """The DOB's Q-filter pole at period dt_s (see dob_cutoff_hz / dob_filter_pole)."""
        if self.dob_cutoff_hz is None and self.dob_filter_pole is None:
            return resolve_q_filter_pole(LAB_DOB_CUTOFF_HZ, None, dt_s)
        return resolve_q_filter_pole(self.dob_cutoff_hz, self.dob_filter_pole, dt_s)

    def kdist_ramp_ticks(self, dt_s: float) -> int:
        return int(round(self.kdist_ramp_s / dt_s))

    @classmethod
    def paper(cls, n_joints: int = 1, **overrides: object) -> ControllerParams:
        """The paper's K = 2000, D = 100, Kp = 10, Q/R "10 and 1"; other fields as given."""
        return cls(joints=FlexibleJointParams.uniform(n_joints), **overrides)  # type: ignore[arg-type]

    def gain_designer(self, dt_s: float) -> GainDesigner:
        """A designer for this controller's LQR (it keeps its last coupled solution to
        warm-start the next; controller/lqr_designs.py)."""
        return GainDesigner(
            self.joints,
            dt_s,
            self.lqr_weights,
            self.discretisation,
            self.lqr_coupling,
            self.servo_cascade,
            self.kdist_reference,
        )

    def design_gain(self, sm: np.ndarray, dt_s: float) -> TrackingGain:
        """The discrete LQR gain for this Sm, from scratch (milliseconds for 12 joints: not
        for every tick)."""
        return self.gain_designer(dt_s).design(validate_sm(sm, self.n_joints))


@dataclass(frozen=True)
class ControlTerms:
    """One tick's parts of the goal, for the log: u = uc + d_hat + ug [rad, per joint].

    uc: LQR part (the reference itself for "pid" and "gc"); d_hat: the DOB's contribution to u
    (in the accumulated reading, its running sum); ug: gravity feed-forward (8); u: the goal
    (after notify_applied: what was sent). disturbance_estimate_rad: q(k), the Q-filtered
    estimate before Kdist (zero for controllers without DOB).
    """

    uc: np.ndarray
    d_hat: np.ndarray
    ug: np.ndarray
    u: np.ndarray
    disturbance_estimate_rad: np.ndarray


class JointController(abc.ABC):
    """One controller for n joints, stepped once per tick by the loop (see module docstring)."""

    name: str

    def __init__(self, n_joints: int) -> None:
        self.n_joints = n_joints
        self._phase = "needs_reset"

    def _joint_array(self, value: np.ndarray, what: str) -> np.ndarray:
        array = np.asarray(value, dtype=float)
        if array.shape != (self.n_joints,):
            raise ValueError(f"{what} must have shape ({self.n_joints},), got {array.shape}")
        if np.count_nonzero(np.isfinite(array)) != array.size:
            bad = np.flatnonzero(~np.isfinite(array)).tolist()
            raise ValueError(f"{what} is not finite for joints {bad}: do not step on invalid data")
        return array

    def reset(
        self,
        motor_angle_rad: np.ndarray,
        link_angle_rad: np.ndarray,
        reference_rad: np.ndarray,
        goal_in_force_rad: np.ndarray | None = None,
    ) -> None:
        """Bumpless start from the goal the servo is being driven with.

        goal_in_force_rad: the goal sent on the last tick before this controller takes over
        (the hold or homing goal). Under a load the servo rests short of its goal (by
        tau / k_s: gravity on the testbed, ~8 mrad), so the measured motor angle is NOT the goal
        in force; starting from it would step the goal by that lag. None: take the measured
        motor angle (only right when the servo rests exactly at its goal)."""
        motor = self._joint_array(motor_angle_rad, "motor_angle_rad")
        goal = (
            motor
            if goal_in_force_rad is None
            else self._joint_array(goal_in_force_rad, "goal_in_force_rad")
        )
        self._reset(
            motor,
            self._joint_array(link_angle_rad, "link_angle_rad"),
            self._joint_array(reference_rad, "reference_rad"),
            goal,
        )
        self._phase = "ready"

    def step(
        self, motor_angle_rad: np.ndarray, link_angle_rad: np.ndarray, reference_rad: np.ndarray
    ) -> np.ndarray:
        """One tick: measured angles and desired link angles in, goal motor angles out [rad]."""
        if self._phase != "ready":
            raise ControllerUsageError(
                f"{self.name}: step() called "
                + (
                    "before reset()"
                    if self._phase == "needs_reset"
                    else "again without notify_applied() for the previous goal"
                )
            )
        goal = self._step(
            self._joint_array(motor_angle_rad, "motor_angle_rad"),
            self._joint_array(link_angle_rad, "link_angle_rad"),
            self._joint_array(reference_rad, "reference_rad"),
        )
        self._phase = "awaiting_applied"
        return goal.copy()

    def resync(self, motor_angle_rad: np.ndarray, link_angle_rad: np.ndarray) -> None:
        """Before a step that follows a gap (ticks without a step: a skipped deadline, a failed
        read). The discrete model differences the samples over one period; without this the gap
        would read as one period's motion (the DOB would add a spike of ~(gap - 1) x velocity x
        dt / (Kp dt) for good in the accumulated reading). Call it with the angles the next
        step() gets; that step then holds the disturbance estimate and reads no increment."""
        if self._phase != "ready":
            raise ControllerUsageError(f"{self.name}: resync() is for between ticks, after reset()")
        self._resync(
            self._joint_array(motor_angle_rad, "motor_angle_rad"),
            self._joint_array(link_angle_rad, "link_angle_rad"),
        )

    @abc.abstractmethod
    def _resync(self, motor: np.ndarray, link: np.ndarray) -> None: ...

    def notify_applied(self, applied_goal_rad: np.ndarray) -> None:
        """The goal actually sent after the last step (clipped or not). Call after every step."""
        if self._phase != "awaiting_applied":
            raise ControllerUsageError(f"{self.name}: notify_applied() without a preceding step()")
        self._notify_applied(self._joint_array(applied_goal_rad, "applied_goal_rad"))
        self._phase = "ready"

    def set_kdist(self, kdist: np.ndarray | float) -> None:
        """Change the DOB gain per joint between ticks (only controllers with a DOB); the change
        ramps over ControllerParams.kdist_ramp_s."""
        raise ControllerUsageError(
            f"{self.name!r} has no disturbance observer; set_kdist needs 'gc+lqr+dob'"
        )

    def set_planned_motion(self, motion: PlannedMotion | None) -> None:  # noqa: B027
        """The plan's motion at the coming tick (controller/planned_motion.py), or None; only
        the LQR controllers use it (reference_feedforward). Call before `step`."""

    @property
    @abc.abstractmethod
    def terms(self) -> ControlTerms:
        """The last tick's parts (copies)."""

    @abc.abstractmethod
    def _reset(
        self, motor: np.ndarray, link: np.ndarray, reference: np.ndarray, goal: np.ndarray
    ) -> None: ...

    @abc.abstractmethod
    def _step(self, motor: np.ndarray, link: np.ndarray, reference: np.ndarray) -> np.ndarray: ...

    @abc.abstractmethod
    def _notify_applied(self, applied: np.ndarray) -> None: ...


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

"""Which controller (`ControllerKind`: the paper's four) and its parameters (`ControllerParams`):
per-joint models, the LQR's weights and design (21)-(24), the DOB (9)-(11) and its Kdist, the
reading of (25), the gravity compensator's compliance (8), validated once at construction."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

from controller.composition import COMPOSITION_READINGS, CompositionReading
from controller.dob import LAB_DOB_CUTOFF_HZ, resolve_q_filter_pole
from controller.estimation import (
    LINK_VELOCITY_INCREMENTS,
    LinkVelocityIncrement,
)
from controller.lqr import (
    COUPLINGS,
    LQR_DESIGNS,
    Coupling,
    LqrDesign,
    LqrWeights,
    TrackingGain,
)
from controller.lqr_designs import (
    KDIST_REFERENCES,
    GainDesigner,
    KdistReference,
)
from controller.model import FlexibleJointParams, per_joint_array, validate_sm
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
        if (self.composition == CompositionReading.ACCUMULATED_INTEGRAL) != (integral is not None):
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
            if self.discretisation == LqrDesign.EULER:
                raise ValueError(
                    "the servo cascade cannot be designed by forward Euler (its fast pole lies "
                    "beyond -2/dt): use discretisation 'zoh' or 'continuous-cost'"
                )

    @property
    def compensator_compliance_rad_per_nm(self) -> np.ndarray:
        """C of (8) per joint: gc_compliance_rad_per_nm, or the paper's K^-1."""
        if self.gc_compliance_rad_per_nm is None:
            return 1.0 / self.joints.stiffness_nm_per_rad
        return np.asarray(self.gc_compliance_rad_per_nm)

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

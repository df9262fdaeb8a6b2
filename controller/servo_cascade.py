"""The actuator's own position servo as a cascade, instead of the paper's first-order (4).

The paper models the position-controlled actuator as d theta_m/dt = Kp (u - theta_m) (4): the
motor is a kinematic source that follows its goal with a lag and ignores the load. The
Dynamixel Pro H54 runs a cascade (its e-Manual: position P gain -> velocity PI loop -> current):

    J d omega_m/dt = kv (Kpp (u - theta_m) - omega_m) + iota - b omega_m - tau_j
    d iota/dt      = (kv / Ti) (Kpp (u - theta_m) - omega_m)
    tau_j          = K (theta_m - theta_j) + D (omega_m - dtheta_j)      (1)

J the rotor's reflected inertia, kv the velocity-loop gain, b the gearbox's viscous friction,
Ti the velocity loop's integral time. Its static stiffness against the load is Kpp kv
(785 N m/rad at the stock registers, in series with the gear's K = 2000): the motor does not
hold its goal when the link pushes back, which (4) cannot say. With J -> 0 and b -> 0 the
cascade is (4) with Kp = Kpp (the transfer from u to theta_m is Kpp kv / (J s^2 + (kv + b) s +
Kpp kv) -> Kpp / (s + Kpp)).

The model here leaves out iota: the stock integral is weak (Ti = 15 s on the H54 at its factory
registers; `hil identify` measures it), far slower than anything the LQR acts on, and its state
cannot be measured (it can be inferred from the current, noisily). The state per joint is
x = [theta_m, omega_m, theta_j, dtheta_j], y = theta_j; omega_m is the motor velocity the loop
estimates by the difference of the motor encoder (or reads as Present Velocity).

Why it matters on DYROS-JET (docs/studies/lqr_design): with (4) the LQR's gains on the link
increments assume the goal moves the motor; on the real cascade, the motor is a spring-damper
to its goal and those gains feed the link's motion back into a soft actuator.

The cascade's fast pole (about -(kv + b + D) / J = -720 rad/s for the H54 on DYROS-JET) lies
beyond forward Euler's limit 2 / dt = 400 rad/s at 200 Hz: designs on it sample it exactly
("zoh" or "continuous-cost"), never by Euler.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controller.model import FlexibleJointParams, StateSpace, per_joint_array, validate_sm

# sim_backend/servo.py and the H54's figures (testbed identification): kv = 2 pi 50 Hz x
# 0.25 kg m^2, the reflected rotor inertia 0.25 kg m^2, gearbox viscous friction 1.14 N m s/rad.
H54_VELOCITY_GAIN_NMS_PER_RAD = 78.5
H54_ROTOR_INERTIA_KG_M2 = 0.25
H54_VISCOUS_FRICTION_NMS_PER_RAD = 1.14

N_CASCADE_MOTOR_STATES = 2  # theta_m, omega_m per joint


@dataclass(frozen=True)
class ServoCascadeParams:
    """Per-joint figures of the servo's velocity loop and motor side (arrays of length n).

    velocity_gain_nms_per_rad: kv > 0; rotor_inertia_kg_m2: J > 0 (reflected to the output);
    viscous_friction_nms_per_rad: b >= 0. The position gain Kpp is the joint's
    `FlexibleJointParams.servo_gain_per_s`.
    """

    velocity_gain_nms_per_rad: np.ndarray
    rotor_inertia_kg_m2: np.ndarray
    viscous_friction_nms_per_rad: np.ndarray

    def __post_init__(self) -> None:
        kv = per_joint_array(self.velocity_gain_nms_per_rad, "velocity_gain_nms_per_rad")
        n = kv.size
        inertia = per_joint_array(self.rotor_inertia_kg_m2, "rotor_inertia_kg_m2", n)
        friction = per_joint_array(
            self.viscous_friction_nms_per_rad, "viscous_friction_nms_per_rad", n
        )
        if np.any(kv <= 0) or np.any(inertia <= 0) or np.any(friction < 0):
            raise ValueError(
                f"the servo cascade needs kv > 0, J > 0 and b >= 0, got {kv}, {inertia}, {friction}"
            )
        object.__setattr__(self, "velocity_gain_nms_per_rad", kv)
        object.__setattr__(self, "rotor_inertia_kg_m2", inertia)
        object.__setattr__(self, "viscous_friction_nms_per_rad", friction)

    @property
    def n_joints(self) -> int:
        return int(self.velocity_gain_nms_per_rad.size)

    @classmethod
    def h54(cls, n_joints: int) -> ServoCascadeParams:
        """n joints with the H54's figures (module constants)."""
        return cls(
            np.full(n_joints, H54_VELOCITY_GAIN_NMS_PER_RAD),
            np.full(n_joints, H54_ROTOR_INERTIA_KG_M2),
            np.full(n_joints, H54_VISCOUS_FRICTION_NMS_PER_RAD),
        )

    def joint(self, index: int) -> ServoCascadeParams:
        return ServoCascadeParams(
            self.velocity_gain_nms_per_rad[index : index + 1],
            self.rotor_inertia_kg_m2[index : index + 1],
            self.viscous_friction_nms_per_rad[index : index + 1],
        )

    def static_stiffness_nm_per_rad(self, joints: FlexibleJointParams) -> np.ndarray:
        """Kpp kv: how hard the servo holds its goal against a load [N m/rad]."""
        return joints.servo_gain_per_s * self.velocity_gain_nms_per_rad


def cascade_state_space(
    joints: FlexibleJointParams, servo: ServoCascadeParams, sm: np.ndarray
) -> StateSpace:
    """The model with the cascade (module docstring) for n joints and the links' (19):
    x = [theta_m; omega_m; theta_j; dtheta_j] stacked by quantity (4n), y = theta_j, input u."""
    n = joints.n_joints
    if servo.n_joints != n:
        raise ValueError(f"servo figures for {servo.n_joints} joints, the model has {n}")
    sm = validate_sm(sm, n)
    stiffness = np.diag(joints.stiffness_nm_per_rad)
    damping = np.diag(joints.damping_nms_per_rad)
    inverse_inertia = np.diag(1.0 / servo.rotor_inertia_kg_m2)
    position_stiffness = np.diag(joints.servo_gain_per_s * servo.velocity_gain_nms_per_rad)
    motor_damping = np.diag(servo.velocity_gain_nms_per_rad + servo.viscous_friction_nms_per_rad)
    zero, eye = np.zeros((n, n)), np.eye(n)
    a = np.block(
        [
            [zero, eye, zero, zero],
            [
                -inverse_inertia @ (position_stiffness + stiffness),
                -inverse_inertia @ (motor_damping + damping),
                inverse_inertia @ stiffness,
                inverse_inertia @ damping,
            ],
            [zero, zero, zero, eye],
            [sm @ stiffness, sm @ damping, -sm @ stiffness, -sm @ damping],
        ]
    )
    b = np.vstack([zero, inverse_inertia @ position_stiffness, zero, zero])
    c = np.hstack([zero, zero, eye, zero])
    return StateSpace(a=a, b=b, c=c)

"""The emulated DYROS-JET linearised about its present state and sampled at the loop's tick:
the plant a controller on the lock-step buses actually meets, as a linear model.

    z(k+1) = F z(k) + G u(k),   theta_m(k) = Cm z(k),  theta_j(k) = Cj z(k),  omega_m(k) = Cw z(k)

u the goal angles written at tick k (held for the period), z = [dq (nv); qvel (nv); iota (12)]:
MuJoCo's state in its tangent space and the 12 firmware velocity-loop integrals.

How: one 1 ms physics step is MuJoCo's own finite-difference transition Jacobian
(`mujoco.mjd_transitionFD`: implicitfast, the soft contacts, the gears, the actuators' kv) with
respect to the state and ctrl; around it, the H54 firmware exactly as sim_backend/servo.py runs
it each step (the integral first, iota' = iota + (kv/Ti) dt (Kpp (u - theta_m) - omega_m), then
ctrl = Kpp (u - theta_m) + iota' / kv); the loop period's steps chained with the goal held. In
lock-step (sim_backend/server.py) the goals written after tick k's sample act from tick k's
SYNC on, over the whole period, and tick k + 1's sample is the plant one period later: no delay
beyond the hold, so this is the sampled plant the loop sees (the mounting's direction and offset
are the identity on the emulated legs).

Coulomb friction is not linear. MuJoCo's frictionloss is a soft constraint: about a state at
rest the transition Jacobian holds the rotors "stuck" (their friction's stiff damping), which is
the small-signal truth while the servo's torque changes stay below 2 x 3.95 N m; a motion that
breaks the friction loose sees no friction increment at all. `Friction.SLIDING` linearises the
same state with the gearbox's Coulomb friction removed: a loop should be stable in both.

Matched against the nonlinear robot: a 2 mrad goal step on one joint, less the same robot's own
drift, agrees to 0.1 % over 200 ms (tests/sim_backend/test_humanoid_linear.py).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import mujoco
import numpy as np

from sim_backend.humanoid.params import N_LEG_JOINTS
from sim_backend.humanoid.robot import EmulatedRobot

FD_EPSILON = 1e-6  # MuJoCo's finite-difference step (its documentation's default)


class Friction(enum.Enum):
    """Which side of the gearbox's Coulomb friction the linear model is on (module docstring)."""

    STUCK = "stuck"
    SLIDING = "sliding"


@dataclass(frozen=True)
class TickModel:
    """See the module docstring. `rigid_body_dofs`: indices in z of the floating base's
    velocity-free coordinates (the robot's position and heading on the floor)."""

    f: np.ndarray
    g: np.ndarray
    motor_angle: np.ndarray  # Cm, 12 x size
    link_angle: np.ndarray  # Cj
    motor_velocity: np.ndarray  # Cw
    period_s: float
    friction: Friction

    @property
    def size(self) -> int:
        return int(self.f.shape[0])


def linearise(
    robot: EmulatedRobot, period_s: float, friction: Friction = Friction.STUCK
) -> TickModel:
    """The robot's tick model about its present state (module docstring)."""
    plant = robot.plant
    model, data = plant.model, plant.data
    saved_friction = model.dof_frictionloss.copy()
    if friction is Friction.SLIDING:
        model.dof_frictionloss[:] = 0.0
    try:
        n_x = 2 * model.nv + model.na
        a = np.zeros((n_x, n_x))
        b = np.zeros((n_x, model.nu))
        mujoco.mjd_transitionFD(model, data, FD_EPSILON, True, a, b, None, None)
    finally:
        model.dof_frictionloss[:] = saved_friction
    n = N_LEG_JOINTS
    registers = [firmware.registers for firmware in robot.firmware]
    kpp = np.diag([r.position_gain_per_s for r in registers])
    kv = np.array([r.velocity_gain_nms_per_rad for r in registers])
    integral_rate = np.array([r.integral_rate_nm_per_rad for r in registers])
    dt = plant.physics_timestep_s
    joints = np.arange(n)
    motor = np.zeros((n, n_x))
    motor[joints, plant.motor_dof_indices] = 1.0
    velocity = np.zeros((n, n_x))
    velocity[joints, model.nv + plant.motor_dof_indices] = 1.0
    deflection = np.zeros((n, n_x))
    deflection[joints, plant.gear_dof_indices] = 1.0
    b_ctrl = b[:, plant.actuator_indices]
    size = n_x + n
    # one physics step on s = [x; iota] with the goal u held
    integral_rows = np.hstack([-np.diag(integral_rate * dt) @ (kpp @ motor + velocity), np.eye(n)])
    integral_input = np.diag(integral_rate * dt) @ kpp
    ctrl_rows = -kpp @ np.hstack([motor, np.zeros((n, n))]) + integral_rows / kv[:, None]
    ctrl_input = kpp + integral_input / kv[:, None]
    step = np.zeros((size, size))
    step[:n_x, :n_x] = a
    step[:n_x] += b_ctrl @ ctrl_rows
    step[n_x:] = integral_rows
    step_input = np.vstack([b_ctrl @ ctrl_input, integral_input])
    f, g = np.eye(size), np.zeros((size, n))
    for _ in range(int(round(period_s / dt))):
        f, g = step @ f, step @ g + step_input
    pad = np.zeros((n, n))
    return TickModel(
        f=f,
        g=g,
        motor_angle=np.hstack([motor, pad]),
        link_angle=np.hstack([motor + deflection, pad]),
        motor_velocity=np.hstack([velocity, pad]),
        period_s=period_s,
        friction=friction,
    )


def rigid_body_mode(model: TickModel, eigenvector: np.ndarray, tolerance: float = 1e-6) -> bool:
    """Whether an eigenvector moves no motor and no link (the robot sliding or turning on the
    floor, which no goal moves and no encoder sees): its joint content below `tolerance` of
    its largest entry."""
    vector = eigenvector[: model.size] / np.max(np.abs(eigenvector))
    return bool(
        np.max(np.abs(model.link_angle @ vector)) < tolerance
        and np.max(np.abs(model.motor_angle @ vector)) < tolerance
    )

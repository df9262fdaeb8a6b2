"""The emulated DYROS-JET legs: 12 H54 firmware models in front of the MuJoCo plant.

Like the testbed's `EmulatedJoint`/`VirtualTestbed` (sim_backend/testbed.py), for 12 joints on
one physics clock: the loop of sim_backend/flexible_robot.py (`FlexibleJointRobot`), the
pushes on the pelvis. The motors' angles and velocities are views into MuJoCo's state (no copy
per step). Each joint has its own servo, its own torque cap and its own overload timer, read
from and written to its own control table (an `sim_backend.dynamixel.H54Device`, or any
`ControlTable`).
Present Current carries its noise (one seeded Generator for the 12, joint by joint); Present
Velocity has none here (the testbed's has).
The emulator's buses serve the tables (Dynamixel), `link_angle_rad(joint)` (CAN encoders) and
`foot_wrench(side)` (CAN force/torque sensors).

Mounting (`sim_backend.testbed.Mounting`) maps each joint's physical angle to what its actuator
counts, as on the testbed; the host's configuration undoes it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim_backend.flexible_robot import FlexibleJointRobot
from sim_backend.humanoid.params import N_LEG_JOINTS, RobotTruthParams
from sim_backend.humanoid.plant import HumanoidPlant
from sim_backend.servo import ControlTable
from sim_backend.servo_bank import H54FirmwareBank
from sim_backend.spec import FloorBox
from sim_backend.testbed import Mounting


@dataclass(frozen=True)
class PelvisPush:
    """A constant force [N] (world frame) on the pelvis's CoM from start_s for duration_s."""

    start_s: float
    duration_s: float
    force_n: tuple[float, float, float]

    def __post_init__(self) -> None:
        if self.start_s < 0 or self.duration_s <= 0 or len(self.force_n) != 3:
            raise ValueError("a pelvis push needs start_s >= 0, duration_s > 0 and a 3-D force")

    def force_at(self, time_s: float) -> np.ndarray:
        active = self.start_s <= time_s < self.start_s + self.duration_s
        return np.asarray(self.force_n, dtype=float) if active else np.zeros(3)


class EmulatedRobot(FlexibleJointRobot):
    """The truth of a humanoid run: 12 firmware-driven flexible joints and the MuJoCo robot.

    urdf_text: the robot description (the same text the controller's model reads).
    tables: 12 control tables in the lab's leg order (L hip yaw ... R ankle roll).
    truth: physical parameters (RobotTruthParams; override for robustness runs).
    initial_leg_angles_rad / support_feet: the robot is placed at rest at these link angles with
        these soles flat on the floor (plant.place_standing); each device's goal is where it
        stands, as a powered-up servo's.
    suspended: the robot hangs by its pelvis from a gantry instead, its feet clear of the floor
        (plant.hang at initial_leg_angles_rad; support_feet unused).
    motor_mountings: per joint, how the actuator is mounted (default: direction +1, offset 0).
    floor_boxes: objects lying on the floor (none by default).
    `pushes` act on the pelvis (`PelvisPush`).
    """

    def __init__(
        self,
        urdf_text: str,
        tables: Sequence[ControlTable],
        *,
        truth: RobotTruthParams | None = None,
        initial_leg_angles_rad: Sequence[float] | np.ndarray,
        support_feet: Sequence[int] = (0, 1),
        motor_mountings: Sequence[Mounting] | None = None,
        rng: np.random.Generator | None = None,
        floor_boxes: Sequence[FloorBox] = (),
        suspended: bool = False,
    ) -> None:
        if len(tables) != N_LEG_JOINTS:
            raise ValueError(f"an emulated robot needs {N_LEG_JOINTS} control tables")
        self.truth = truth or RobotTruthParams()
        self.mountings = list(motor_mountings or [Mounting()] * N_LEG_JOINTS)
        if len(self.mountings) != N_LEG_JOINTS:
            raise ValueError(f"motor_mountings needs {N_LEG_JOINTS} entries")
        bank = H54FirmwareBank(
            list(tables),
            [self.truth.servo_params(i) for i in range(N_LEG_JOINTS)],
            directions=[m.direction for m in self.mountings],
            offsets_rad=[m.offset_rad for m in self.mountings],
            rng=rng or np.random.default_rng(0),
            velocity_noise=False,
        )
        plant = HumanoidPlant(
            urdf_text,
            self.truth,
            velocity_gains_nms_per_rad=bank.velocity_gains(),
            floor_boxes=floor_boxes,
            suspended=suspended,
        )
        if suspended:
            plant.hang(initial_leg_angles_rad)
        else:
            plant.place_standing(initial_leg_angles_rad, support_feet)
        super().__init__(bank, plant, self.truth.position_gain_registers, plant.set_pelvis_force)
        self.plant: HumanoidPlant = plant

    def foot_wrench(self, side: int) -> tuple[np.ndarray, np.ndarray]:
        """The ground's (force [N], moment [N m]) on foot `side` in its sensor frame."""
        return self.plant.foot_wrench(side)

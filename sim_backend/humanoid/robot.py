"""The emulated DYROS-JET legs: 12 H54 firmware models in front of the MuJoCo plant.

Like the testbed's `EmulatedJoint`/`VirtualTestbed` (sim_backend/testbed.py), for 12 joints on
one physics clock. Every physics step, for the 12 joints at once (`H54FirmwareBank`, numpy
arrays in the lab's leg order):

    firmware.command(motor angles, motor velocities) -> velocity-loop inputs, torque caps, brakes
    plant.set_velocity_commands                         (every step)
    plant.set_servos / set_brakes                       (when the registers or torque changed:
                                                         kv follows the Velocity P Gain register)
then one MuJoCo step, then
    firmware.measure(...)  -> overload protection; Present Position/Velocity/Current when read
The motors' angles and velocities are views into MuJoCo's state (no copy per step), and an
`advance` of several steps has MuJoCo compute its sensors in the last one only.

so each joint has its own servo, its own torque cap and its own overload timer, read from and
written to its own control table (an `sim_backend.dynamixel.H54Device`, or any `ControlTable`).
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

import mujoco
import numpy as np

from sim_backend.firmware import H54Firmware
from sim_backend.humanoid.params import N_LEG_JOINTS, RobotTruthParams
from sim_backend.humanoid.plant import HumanoidPlant
from sim_backend.servo import ControlTable
from sim_backend.servo_bank import H54FirmwareBank
from sim_backend.spec import FloorBox
from sim_backend.step_clock import StepClock
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


class EmulatedRobot:
    """The truth of a humanoid run: 12 firmware-driven flexible joints and the MuJoCo robot.

    urdf_text: the robot description (the same text the controller's model reads).
    tables: 12 control tables in the lab's leg order (L hip yaw ... R ankle roll).
    truth: physical parameters (RobotTruthParams; override for robustness runs).
    initial_leg_angles_rad / support_feet: the robot is placed at rest at these link angles with
        these soles flat on the floor (plant.place_standing); each device's goal is where it
        stands, as a powered-up servo's.
    motor_mountings: per joint, how the actuator is mounted (default: direction +1, offset 0).
    floor_boxes: objects lying on the floor (none by default).
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
    ) -> None:
        if len(tables) != N_LEG_JOINTS:
            raise ValueError(f"an emulated robot needs {N_LEG_JOINTS} control tables")
        self.truth = truth or RobotTruthParams()
        self.tables = list(tables)
        self.mountings = list(motor_mountings or [Mounting()] * N_LEG_JOINTS)
        if len(self.mountings) != N_LEG_JOINTS:
            raise ValueError(f"motor_mountings needs {N_LEG_JOINTS} entries")
        self.bank = H54FirmwareBank(
            self.tables,
            [self.truth.servo_params(i) for i in range(N_LEG_JOINTS)],
            directions=[m.direction for m in self.mountings],
            offsets_rad=[m.offset_rad for m in self.mountings],
            rng=rng or np.random.default_rng(0),
            velocity_noise=False,
        )
        self.firmware = [H54Firmware(bank=self.bank, joint=i) for i in range(N_LEG_JOINTS)]
        self.plant = HumanoidPlant(
            urdf_text,
            self.truth,
            velocity_gains_nms_per_rad=self.bank.velocity_gains(),
            floor_boxes=floor_boxes,
        )
        self.pushes: list[PelvisPush] = []
        self._dt = self.plant.physics_timestep_s
        self._limits_in_plant = -1  # the bank's limits_revision the actuators were given
        self.clock = StepClock(self._dt)  # time in whole physics steps
        self._link_cache: tuple[int, list[float], list[float]] = (-1, [], [])
        self.plant.place_standing(initial_leg_angles_rad, support_feet)
        for joint, table in enumerate(self.tables):
            table.set_item("Position P Gain", self.truth.position_gain_registers[joint])
            self._report(joint)
            table.set_item("Goal Position", table.item("Present Position"))
            add_listener = getattr(table, "add_reboot_listener", None)
            if add_listener is not None:
                add_listener(lambda joint=joint: self.on_reboot(joint))

    # --- clock --------------------------------------------------------------------------------
    @property
    def physics_timestep_s(self) -> float:
        return self._dt

    @property
    def time_s(self) -> float:
        return self.clock.time_s

    def start_scenario(self) -> None:
        """The scenario clock (pushes) starts now (the emulator calls it at the first SYNC)."""
        self.clock.start_scenario()

    @property
    def scenario_time_s(self) -> float | None:
        return self.clock.scenario_time_s

    def advance(self, duration_s: float) -> int:
        """Advance by whole physics steps covering duration_s (remainders carry over). MuJoCo
        computes its sensors (the feet's force/torque) only in the last of them: they are read
        between two calls, and they feed nothing in the dynamics (the same state, bit for bit)."""
        steps = self.clock.steps_covering(duration_s)
        if steps > 1:
            options = self.plant.model.opt
            flags = options.disableflags
            options.disableflags = flags | mujoco.mjtDisableBit.mjDSBL_SENSOR
            try:
                for _ in range(steps - 1):
                    self.step()
            finally:
                options.disableflags = flags
            self.step()
        elif steps:
            self.step()
        return steps

    # --- one physics step ---------------------------------------------------------------------
    def step(self) -> None:
        """Firmware -> motors -> MuJoCo -> overload protection, for all 12 joints at once. The
        actuators' caps, gains and brakes are written to MuJoCo only when the firmware's
        registers or torque changed (`H54FirmwareBank.limits_revision`), the velocity-loop
        inputs every step."""
        plant, bank, dt = self.plant, self.bank, self._dt
        out = bank.command(*plant.motor_state_arrays(), dt)
        if self._limits_in_plant != bank.limits_revision:
            self._limits_in_plant = bank.limits_revision
            plant.set_servos(
                out.velocity_command_rad_s, out.torque_limit_nm, out.velocity_gain_nms_per_rad
            )
            plant.set_brakes(out.brake_damping_nms_per_rad)
        else:
            plant.set_velocity_commands(out.velocity_command_rad_s)
        if self.pushes:
            scenario_time = self.scenario_time_s
            push = np.zeros(3)
            if scenario_time is not None:
                push = sum((event.force_at(scenario_time) for event in self.pushes), push)
            plant.set_pelvis_force(push)
        plant.step()
        self.clock.steps += 1
        angles, velocities = plant.motor_state_arrays()
        bank.measure(plant.motor_torque_nm, angles, velocities, dt)

    def on_reboot(self, joint: int) -> None:
        """After a device REBOOT (RAM at its defaults): the servo holds where it stands."""
        self.bank.on_reboot(joint)
        self._report(joint)
        table = self.tables[joint]
        table.set_item("Goal Position", table.item("Present Position"))

    def _report(self, joint: int) -> None:
        """One joint's measurements now (power-on, reboot), its noise drawn as a step's."""
        angle, velocity = self.plant.motor_state(joint)
        self.bank.report_joint(
            joint, self.plant.joint_motor_torque_nm(joint), angle, velocity, self._dt
        )

    # --- what the sensors read (sources for the bus emulators) --------------------------------
    def link_angle_rad(self, joint: int) -> float:
        """True link angle of one joint (the CAN link encoder quantises it)."""
        return self._link_state()[0][joint]

    def link_velocity_rad_s(self, joint: int) -> float:
        """True link velocity of one joint."""
        return self._link_state()[1][joint]

    def _link_state(self) -> tuple[list[float], list[float]]:
        """The 12 link angles and velocities after the last physics step, computed once per
        step (12 encoders read them at every SYNC); only `step` moves the plant."""
        steps = self.clock.steps
        if self._link_cache[0] != steps:
            plant = self.plant
            self._link_cache = (
                steps,
                plant.link_angle_rad.tolist(),
                plant.link_velocity_rad_s.tolist(),
            )
        return self._link_cache[1], self._link_cache[2]

    def foot_wrench(self, side: int) -> tuple[np.ndarray, np.ndarray]:
        """The ground's (force [N], moment [N m]) on foot `side` in its sensor frame."""
        return self.plant.foot_wrench(side)

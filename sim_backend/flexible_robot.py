"""n firmware-driven flexible joints on one MuJoCo plant (`FlexibleJointRobot`): the loop the
humanoid (sim_backend/humanoid/robot.py) and a fixed-base robot (sim_backend/fixed_base/) share.

Every physics step, for the n joints at once (`H54FirmwareBank`, numpy arrays in the plant's
joint order):

    firmware.command(motor angles, motor velocities) -> velocity-loop inputs, torque caps, brakes
    plant.set_velocity_commands                         (every step)
    plant.set_servos / set_brakes                       (when the registers or torque changed:
                                                         kv follows the Velocity P Gain register)
    the robot's pushes, summed, to the plant            (a force on a body, while one acts)
then one MuJoCo step, then
    firmware.measure(...)  -> overload protection; Present Position/Velocity/Current when read
An `advance` of several steps has MuJoCo compute its sensors in the last one only.

Each joint has its own servo, torque cap and overload timer, read from and written to its own
control table. The buses serve the tables (Dynamixel) and `link_angle_rad(joint)` (CAN encoders).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

import mujoco
import numpy as np

from sim_backend.firmware import H54Firmware
from sim_backend.servo import ControlTable
from sim_backend.servo_bank import H54FirmwareBank
from sim_backend.step_clock import StepClock


class FlexibleJointPlant(Protocol):
    """What the loop steps: a MuJoCo plant of n flexible joints (HumanoidPlant, FixedBasePlant)."""

    model: mujoco.MjModel

    @property
    def physics_timestep_s(self) -> float: ...

    @property
    def motor_torque_nm(self) -> np.ndarray: ...

    @property
    def link_angle_rad(self) -> np.ndarray: ...

    @property
    def link_velocity_rad_s(self) -> np.ndarray: ...

    def motor_state(self, joint: int) -> tuple[float, float]: ...

    def motor_state_arrays(self) -> tuple[np.ndarray, np.ndarray]: ...

    def joint_motor_torque_nm(self, joint: int) -> float: ...

    def set_servos(
        self, velocity_commands_rad_s: np.ndarray, torque_limits_nm: np.ndarray, kv: np.ndarray
    ) -> None: ...

    def set_velocity_commands(self, velocity_commands_rad_s: np.ndarray) -> None: ...

    def set_brakes(self, brake_damping_nms_per_rad: np.ndarray) -> None: ...

    def step(self) -> None: ...


class Push(Protocol):
    """A force [N] (world frame) on a body of the plant while it acts (scenario time)."""

    def force_at(self, time_s: float) -> np.ndarray: ...


class FlexibleJointRobot:
    """The truth of a run: n firmware-driven flexible joints and their MuJoCo plant.

    bank: the joints' firmwares (their tables, servo figures and mountings).
    plant: built for the bank's velocity gains, placed where the robot starts.
    position_gain_registers: Position P Gain (594) per joint at power-on (a REBOOT returns a
        device's RAM to its model's default: the host re-writes it, as on the real robot).
    apply_push: where `pushes` act (the humanoid's pelvis, a fixed-base robot's tool).
    """

    def __init__(
        self,
        bank: H54FirmwareBank,
        plant: FlexibleJointPlant,
        position_gain_registers: Sequence[int],
        apply_push: Callable[[np.ndarray], None],
    ) -> None:
        self.bank = bank
        self.tables: list[ControlTable] = bank.tables
        n = len(self.tables)
        self.firmware = [H54Firmware(bank=bank, joint=i) for i in range(n)]
        self.plant = plant
        self.pushes: list[Push] = []
        self._apply_push = apply_push
        self._dt = plant.physics_timestep_s
        self._limits_in_plant = -1  # the bank's limits_revision the actuators were given
        self.clock = StepClock(self._dt)  # time in whole physics steps
        self._link_cache: tuple[int, list[float], list[float]] = (-1, [], [])
        for joint, table in enumerate(self.tables):
            table.set_item("Position P Gain", position_gain_registers[joint])
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
        computes its sensors only in the last of them: they are read between two calls, and
        they feed nothing in the dynamics (the same state, bit for bit)."""
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
        """Firmware -> motors -> MuJoCo -> overload protection, for every joint at once. The
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
            self._apply_push(push)
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
        """The link angles and velocities after the last physics step, computed once per step
        (every encoder reads them at every SYNC); only `step` moves the plant."""
        steps = self.clock.steps
        if self._link_cache[0] != steps:
            plant = self.plant
            self._link_cache = (
                steps,
                plant.link_angle_rad.tolist(),
                plant.link_velocity_rad_s.tolist(),
            )
        return self._link_cache[1], self._link_cache[2]


def strided_view(array: np.ndarray, indices: np.ndarray) -> np.ndarray | None:
    """array[indices] as a view (a slice) when the indices are evenly spaced, else None (a
    plant's motor angles every step without a copy: its motor and gear hinges alternate)."""
    if len(indices) < 2:
        return array[indices[0] : indices[0] + 1] if len(indices) else None
    step = int(indices[1] - indices[0])
    if step <= 0 or np.any(np.diff(indices) != step):
        return None
    view = array[int(indices[0]) : int(indices[-1]) + 1 : step]
    return view if np.array_equal(view, array[indices]) else None

"""The virtual testbed's physics: one MuJoCo plant per joint, each behind its H54 firmware.

This module knows nothing of buses: the bus emulators read what the devices would measure
(`motor_device_pulses` via the control table, `link_angle_rad` for the encoder, the contact
force for the force sensor) and the firmware reads its goals from the control table.

Mounting: the device frame of an actuator or encoder differs from the physical frame by a
direction and a zero offset (where the device reads zero). The same figures are in the
configuration file, so the host's drivers undo exactly what the emulated mounting does.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim_backend.firmware import H54Firmware
from sim_backend.plant import TestbedPlant, TestbedPlantParams
from sim_backend.scenario import PushEvent
from sim_backend.servo import ControlTable, H54ServoParams
from sim_backend.servo_bank import H54FirmwareBank
from sim_backend.step_clock import StepClock


@dataclass(frozen=True)
class Mounting:
    """How a device is mounted: physical = direction * (device - offset_rad).

    offset_rad is the device's reading when the joint is at zero, the convention of the
    configuration file and of the host's drivers, so the drivers undo exactly this.
    """

    direction: int = 1
    offset_rad: float = 0.0

    def __post_init__(self) -> None:
        if self.direction not in (1, -1):
            raise ValueError(f"mounting direction must be +1 or -1, got {self.direction}")

    def to_device(self, physical: float) -> float:
        return self.direction * physical + self.offset_rad

    def to_physical(self, device: float) -> float:
        return self.direction * (device - self.offset_rad)


class EmulatedJoint:
    """One actuator + elastic gear + link: a plant driven by its firmware."""

    def __init__(
        self,
        table: ControlTable,
        plant_params: TestbedPlantParams,
        servo_params: H54ServoParams,
        *,
        motor_mounting: Mounting = Mounting(),
        rng: np.random.Generator | None = None,
    ) -> None:
        self.table = table
        self.bank = H54FirmwareBank(
            [table],
            [servo_params],
            directions=[motor_mounting.direction],
            offsets_rad=[motor_mounting.offset_rad],
            rng=rng or np.random.default_rng(0),
        )
        self.firmware = H54Firmware(bank=self.bank)
        self.plant = TestbedPlant(plant_params, servo_params.velocity_gain_nms_per_rad)
        self.motor_mounting = motor_mounting
        self.pushes: list[PushEvent] = []
        self._dt = plant_params.physics_timestep_s
        self._brake_damping = servo_params.dynamic_brake_damping_nms_per_rad
        # The device starts holding where it stands (a powered-up servo's goal is its position).
        self._report()
        table.set_item("Goal Position", table.item("Present Position"))

    def on_reboot(self) -> None:
        self.bank.on_reboot(0)
        self._report()
        self.table.set_item("Goal Position", self.table.item("Present Position"))

    def step(self, scenario_time_s: float | None) -> None:
        """One physics step: firmware -> motor -> MuJoCo -> overload protection (the Present*
        items carry the servo's noise, `H54ServoParams`, drawn from this joint's seeded
        generator: current first, then velocity, every physics step).

        scenario_time_s: time since the run's first SYNC (None before it: no pushes yet).
        """
        plant = self.plant
        torque_on, command, cap = self.bank.command_one(
            plant.motor_angle_rad, plant.motor_velocity_rad_s, self._dt
        )
        plant.set_servo(command, cap)
        plant.set_brake(0.0 if torque_on else self._brake_damping)
        push = 0.0
        if scenario_time_s is not None and self.pushes:
            push = sum(p.force_at(scenario_time_s) for p in self.pushes)
        plant.set_external_force(push)
        plant.step()
        self.bank.measure_one(
            plant.motor_torque_nm, plant.motor_angle_rad, plant.motor_velocity_rad_s, self._dt
        )

    def _report(self) -> None:
        """The measurements now (power-on, reboot), the noise drawn as a step's."""
        plant = self.plant
        self.bank.report_joint(
            0, plant.motor_torque_nm, plant.motor_angle_rad, plant.motor_velocity_rad_s, self._dt
        )


class VirtualTestbed:
    """All emulated joints on one physics clock.

    `advance(period_s)` runs whole physics steps; in lock-step mode the emulator calls it once per
    CAN SYNC with the loop period, in real-time mode with the elapsed wall time. The scenario
    clock (pushes, faults) starts when `start_scenario()` is called, at the run's first SYNC.
    """

    def __init__(self, joints: Sequence[EmulatedJoint]) -> None:
        if not joints:
            raise ValueError("a virtual testbed needs at least one joint")
        self.joints = list(joints)
        self._dt = joints[0].plant.params.physics_timestep_s
        self.clock = StepClock(self._dt)

    @property
    def physics_timestep_s(self) -> float:
        return self._dt

    @property
    def time_s(self) -> float:
        return self.clock.time_s

    def start_scenario(self) -> None:
        self.clock.start_scenario()

    @property
    def scenario_time_s(self) -> float | None:
        """Time since the first SYNC on the plant's clock, None before it."""
        return self.clock.scenario_time_s

    def advance(self, duration_s: float) -> int:
        """Advance by whole physics steps covering duration_s (remainders carry over)."""
        steps = self.clock.steps_covering(duration_s)
        for _ in range(steps):
            scenario_time = self.scenario_time_s
            for joint in self.joints:
                joint.step(scenario_time)
            self.clock.steps += 1
        return steps

"""The emulated robot without its buses, for loops that run in this process (`DirectTestbed`).

The same devices, firmware, plant, scenario and faults as `hil emulate` (both build them with
`sim_backend.hardware.build_hardware`, the testbed or the humanoid), but read and commanded in
SI instead of over
Protocol 2.0 and CANopen - what python-can's `virtual` interface is to a CAN adapter. It exists
so that the loop, the supervisor and the start gate can be tested in milliseconds; the emulated
buses on pseudo-terminals stay the end-to-end path.

What a reading holds is what the drivers would report: the motor angle, velocity and current
from the control table (Present Position/Velocity/Current, undoing the actuator's mounting as
the driver's offset and direction do), the link angle and the contact force from the very CAN
sensor nodes `hil emulate` serves (`CanopenSlave.sample`: their noise, faults, rounding and random
draws), converted as the CiA 406 / 404 objects define them. Faults act on the reading: a silent,
dropped or corrupted reply makes the actuator's values invalid that tick (a silent actuator also
ignores goals and torque commands); a dead encoder gives nothing, a stale one its last count, a
noisy one Gaussian count noise. A lock-step run in-process writes the same log, byte for byte,
as the same run through the emulated buses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim_backend.robots import build_hardware
from sim_backend.scenario import ActiveFaults, FaultSchedule
from sim_backend.servo import (
    AMPERE_PER_CURRENT_UNIT,
    RAD_PER_PULSE,
    RAD_S_PER_VELOCITY_UNIT,
)
from sim_backend.spec import EmulatorSpec

FORCE_SENSOR_NEWTONS_PER_COUNT = 1e-3  # the emulated CiA 404 sensor's PV is in mN


@dataclass
class DirectReading:
    """One sample of every joint (arrays of length n; NaN / False where nothing was read)."""

    motor_angle_rad: np.ndarray
    motor_velocity_rad_s: np.ndarray
    motor_current_a: np.ndarray
    hardware_error: np.ndarray  # the actuator's Hardware Error Status bits
    torque_enabled: np.ndarray
    motor_valid: np.ndarray
    link_angle_rad: np.ndarray
    link_valid: np.ndarray
    contact_force_n: float
    wrenches: list[tuple[np.ndarray, np.ndarray] | None]  # per force/torque sensor, SI


class DirectTestbed:
    """See the module docstring. `sync()` is the SYNC of a tick: the first starts the scenario,
    each later one advances the plant by one period (lock-step)."""

    def __init__(self, spec: EmulatorSpec) -> None:
        self.spec = spec
        self.robot = build_hardware(spec)
        n = len(spec.joints)
        self.n_joints = n
        self.schedule = FaultSchedule(spec.scenario.faults, n)
        self.sync_count = 0
        self.time_s = 0.0  # the plant's time since the first sync
        self._faults = self.schedule.at(None)
        self._drops_pending: list[int] = []
        self._corrupt_pending: list[int] = []
        self.encoders = self.robot.encoders
        self.force_sensor = self.robot.force_sensor
        self.ft_sensors = self.robot.ft_sensors
        self._counts_per_rad = np.array(
            [j.encoder_counts_per_rev / (2.0 * math.pi) for j in spec.joints]
        )

    # --- time --------------------------------------------------------------------------------
    def sync(self) -> None:
        testbed = self.robot
        if self.sync_count == 0:
            testbed.start_scenario()
        else:
            testbed.advance(self.spec.period_s)
        self.sync_count += 1
        self.time_s = testbed.scenario_time_s or 0.0
        self._faults = self.schedule.at(testbed.scenario_time_s)
        self._drops_pending += self._faults.drop_next
        self._corrupt_pending += self._faults.corrupt_next
        for node, mode, noise in zip(
            self.encoders,
            self._faults.encoder_mode,
            self._faults.encoder_noise_counts_rms,
            strict=True,
        ):
            node.fault.mode = mode
            node.fault.noise_counts_rms = noise

    @property
    def faults(self) -> ActiveFaults:
        return self._faults

    # --- reading -----------------------------------------------------------------------------
    def read(self) -> DirectReading:
        n = self.n_joints
        nan = np.full(n, np.nan)
        reading = DirectReading(
            nan.copy(), nan.copy(), nan.copy(), np.zeros(n, dtype=np.uint8),
            np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), nan.copy(),
            np.zeros(n, dtype=bool), self._force_n(),
            [node.sample_wrench(self.time_s) for node in self.ft_sensors],
        )  # fmt: skip
        for i in range(n):
            if self._actuator_answers(i):
                self._read_actuator(i, reading)
            counts = self.encoders[i].sample(self.time_s)
            if counts is not None:
                joint = self.spec.joints[i]
                angle = counts / self._counts_per_rad[i] - joint.encoder_offset_rad
                reading.link_angle_rad[i] = joint.encoder_direction * angle
                reading.link_valid[i] = True
        return reading

    def _actuator_answers(self, i: int) -> bool:
        faults = self._faults
        if i in faults.silent or i in faults.dropped or i in faults.corrupted:
            return False
        if not self.robot.devices[i].available(self.time_s):
            return False  # rebooting
        for pending in (self._drops_pending, self._corrupt_pending):
            if i in pending:
                pending.remove(i)
                return False
        return True

    def _read_actuator(self, i: int, reading: DirectReading) -> None:
        device = self.robot.devices[i]
        mount = self.robot.mountings[i]
        pulses = device.item("Present Position")
        reading.motor_angle_rad[i] = mount.to_physical(pulses * RAD_PER_PULSE)
        velocity = device.item("Present Velocity") * RAD_S_PER_VELOCITY_UNIT
        reading.motor_velocity_rad_s[i] = mount.direction * velocity
        current = device.item("Present Current") * AMPERE_PER_CURRENT_UNIT
        reading.motor_current_a[i] = mount.direction * current
        reading.hardware_error[i] = device.hardware_error_status
        reading.torque_enabled[i] = device.torque_enabled
        reading.motor_valid[i] = True

    def _force_n(self) -> float:
        if self.force_sensor is None:
            return math.nan
        counts = self.force_sensor.sample(self.time_s)
        return math.nan if counts is None else counts * FORCE_SENSOR_NEWTONS_PER_COUNT

    # --- commands ----------------------------------------------------------------------------
    def hears(self, i: int) -> bool:
        """A command to joint i's actuator reaches it (not silent, not rebooting)."""
        return i not in self._faults.silent and self.robot.devices[i].available(self.time_s)

    def write_goal(self, i: int, goal_rad: float) -> bool:
        """Goal Position of joint i (joint frame); False when the actuator did not hear it or
        refused it (the device's own rules: outside its position limits, in shutdown)."""
        if not self.hears(i):
            return False
        device = self.robot.devices[i]
        pulses = round(self.robot.mountings[i].to_device(goal_rad) / RAD_PER_PULSE)
        return device.write_item("Goal Position", pulses) == 0

    def set_torque(self, i: int, on: bool) -> bool:
        """Torque Enable of joint i; False when the actuator did not hear it or refused it."""
        if not self.hears(i):
            return False
        return self.robot.devices[i].write_item("Torque Enable", int(on)) == 0

    def reboot(self, i: int) -> bool:
        if not self.hears(i):
            return False
        self.robot.devices[i].reboot(self.time_s)
        return True

    def set_current_limit_a(self, i: int, limit_a: float) -> bool:
        if not self.hears(i):
            return False
        units = round(limit_a / AMPERE_PER_CURRENT_UNIT)
        return self.robot.devices[i].write_item("Torque Limit", units) == 0

    def current_limit_a(self, i: int) -> float:
        return self.robot.devices[i].item("Torque Limit") * AMPERE_PER_CURRENT_UNIT

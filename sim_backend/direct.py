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
import struct
from dataclasses import dataclass

import numpy as np

from sim_backend.dynamixel import Firmware
from sim_backend.robots import build_hardware
from sim_backend.scenario import ActiveFaults, FaultSchedule
from sim_backend.spec import EmulatorSpec

FORCE_SENSOR_NEWTONS_PER_COUNT = 1e-3  # the emulated CiA 404 sensor's PV is in mN
# Present Position, Velocity (611, 615), two undefined bytes, Present Current (621): the block
# the drivers' sync read takes, one READ per device (the legacy PRO table: other layouts are
# served over the emulated buses only)
_PRESENT_BLOCK = (611, 12)


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
        pro_plus = [d.model.name for d in self.robot.devices if d.model.figures.firmware.pro_plus]
        if pro_plus:
            raise ValueError(
                f"the in-process testbed reads the legacy PRO table; {', '.join(pro_plus)} "
                f"have the {Firmware.PRO_A.value}/{Firmware.P.value} table: use the emulated buses"
            )
        # each device's units (its model's)
        self._units = [device.model.units for device in self.robot.devices]
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
        self._encoder_offset = np.array([j.encoder_offset_rad for j in spec.joints])
        self._encoder_direction = np.array([j.encoder_direction for j in spec.joints], float)
        mountings = self.robot.mountings
        self._motor_direction = np.array([m.direction for m in mountings], float)
        self._motor_offset = np.array([m.offset_rad for m in mountings])
        self._present_block = struct.Struct("<" + "ii2xh" * n)  # (position, velocity, current)

    # --- time --------------------------------------------------------------------------------
    def sync(self) -> None:
        testbed = self.robot
        if self.sync_count == 0:
            testbed.start_scenario()
        else:
            testbed.advance(self.spec.period_s)
        self.sync_count += 1
        self.time_s = testbed.scenario_time_s or 0.0
        if self.schedule.faults or self.sync_count == 1:  # (none injected: nothing changes)
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
        """Every joint at once: the Present* blocks of the devices that answer converted on
        arrays, every encoder's count (each node samples: its noise, faults, rounding)."""
        n = self.n_joints
        force = self._force_n()
        wrenches = [node.sample_wrench(self.time_s) for node in self.ft_sensors]
        answers = [self._actuator_answers(i) for i in range(n)]
        counts = [node.sample(self.time_s) for node in self.encoders]
        link_counts = np.array([np.nan if c is None else c for c in counts], dtype=float)
        angle = link_counts / self._counts_per_rad - self._encoder_offset  # NaN: no count
        return DirectReading(
            *self._read_actuators(answers),
            link_angle_rad=self._encoder_direction * angle,
            link_valid=~np.isnan(link_counts),
            contact_force_n=force,
            wrenches=wrenches,
        )

    def _read_actuators(self, answers: list[bool]) -> tuple[np.ndarray, ...]:
        """(angle, velocity, current, hardware error, torque on, valid) of every actuator in
        the joint frame (the mounting undone), NaN / 0 where it did not answer: the Present*
        blocks of every device (one READ each) unpacked at once."""
        devices = self.robot.devices
        address, length = _PRESENT_BLOCK
        values = self._present_block.unpack(
            b"".join([device.read(address, length)[1] for device in devices])
        )
        n = len(devices)
        angle, velocity, current = [math.nan] * n, [math.nan] * n, [math.nan] * n
        errors, torque = [0] * n, [False] * n
        for i, (device, mount) in enumerate(zip(devices, self.robot.mountings, strict=True)):
            if answers[i]:
                pulses, speed, amperes = values[3 * i : 3 * i + 3]
                units = self._units[i]
                angle[i] = mount.to_physical(pulses * units.rad_per_pulse)
                velocity[i] = mount.direction * (speed * units.rad_s_per_velocity_unit)
                current[i] = mount.direction * (amperes * units.ampere_per_current_unit)
                errors[i] = device.hardware_error_status
                torque[i] = device.torque_enabled
        return (
            np.array(angle),
            np.array(velocity),
            np.array(current),
            np.array(errors, dtype=np.uint8),
            np.array(torque, dtype=bool),
            np.array(answers, dtype=bool),
        )

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
        pulses = round(self.robot.mountings[i].to_device(goal_rad) / self._units[i].rad_per_pulse)
        return device.write_item("Goal Position", pulses) == 0

    def write_goals(self, goals_rad: np.ndarray) -> list[bool]:
        """`write_goal` of every joint (joint frame) in one call: the in-process bus's sync
        write. (The device's checks are the cost; numpy for the pulses saved nothing.)"""
        return [self.write_goal(i, goal) for i, goal in enumerate(np.asarray(goals_rad).tolist())]

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
        units = round(limit_a / self._units[i].ampere_per_current_unit)
        return self.robot.devices[i].write_item("Torque Limit", units) == 0

    def current_limit_a(self, i: int) -> float:
        return self.robot.devices[i].item("Torque Limit") * self._units[i].ampere_per_current_unit

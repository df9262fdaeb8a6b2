"""A JointBus on the emulated robot in this process: no pseudo-terminals, no child process.

python-can's `virtual` interface is the model: a full backend, chosen like the others, for
tests that need the loop, the supervisor, the start gate or the session to run in
milliseconds. Behind it is `sim_backend.direct.DirectTestbed` - the same devices, firmware,
plant, scenario and faults as `hil emulate`, read and commanded in SI. It steps the plant one
period per `read()` (lock-step), so a run on it is deterministic. `hil run` never uses it: the
emulated buses stay the default and the end-to-end path.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from drivers.dynamixel import actuator_fault
from drivers.joint_bus import (
    ActuatorFault,
    BusError,
    BusFault,
    DeviceRole,
    Diagnostic,
    JointBus,
    JointDevices,
    JointSample,
    add_wrench,
)
from hil.config import Config, ConfigError
from hil.experiments import Experiment
from hil.wiring.emulation import emulator_spec
from sim_backend.direct import DirectTestbed
from sim_backend.scenario import FaultEvent
from sim_backend.spec import EmulatorSpec

INPUT_VOLTAGE_V_PER_UNIT = 0.1  # Present Input Voltage (623) is in 0.1 V (e-Manual H54)


class _Remount:
    """From the emulated devices' mounting (the spec) to the one the configuration assumes.

    DirectTestbed reports angles in the joint frame of the emulator's own mounting; the drivers
    read the device with the configuration's (q = d (r - o)). When the two differ (a robot whose
    configuration is not calibrated), the device reading r = o_spec + d_spec q_spec is read with
    the configuration's: q = d_cfg (r - o_cfg); rates only change sign (d_cfg d_spec)."""

    def __init__(self, spec_d: list[int], spec_o: list[float], d: list[int], o: list[float]):
        self.same = spec_d == d and spec_o == o
        self.spec_d, self.spec_o = np.array(spec_d, dtype=float), np.array(spec_o)
        self.d, self.o = np.array(d, dtype=float), np.array(o)

    def angle(self, spec_frame: np.ndarray) -> np.ndarray:
        if self.same:
            return spec_frame
        return self.d * (self.spec_o + self.spec_d * spec_frame - self.o)

    def rate(self, spec_frame: np.ndarray) -> np.ndarray:
        return spec_frame if self.same else self.d * self.spec_d * spec_frame

    def to_spec(self, angles: np.ndarray) -> np.ndarray:
        if self.same:
            return angles
        return self.spec_d * ((self.o + self.d * angles) - self.spec_o)


class InProcessJointBus(JointBus):
    """See the module docstring. Build with `in_process_bus(config, experiment, faults)`; a
    spec built from another configuration emulates devices mounted otherwise (`_Remount`)."""

    def __init__(self, config: Config, spec: EmulatorSpec) -> None:
        self.config = config
        self.spec = spec
        self.joint_names = config.joint_names
        self.testbed: DirectTestbed | None = None
        self._min = np.array([j.min_angle_rad for j in config.joints])
        self._max = np.array([j.max_angle_rad for j in config.joints])
        joints, emulated = config.joints, spec.joints
        self._motor = _Remount(
            [j.motor_direction for j in emulated],
            [j.motor_offset_rad for j in emulated],
            [j.motor_direction for j in joints],
            [j.motor_offset_rad for j in joints],
        )
        self._link = _Remount(
            [j.encoder_direction for j in emulated],
            [j.encoder_offset_rad for j in emulated],
            [j.encoder_direction for j in joints],
            [j.encoder_offset_rad for j in joints],
        )
        self.reads = 0
        self.closed = False
        self._devices = tuple(
            JointDevices(f"actuator {j.dynamixel_id}", f"link encoder node {j.encoder_node_id}")
            for j in config.joints
        )

    def _require(self) -> DirectTestbed:
        if self.testbed is None or self.closed:
            raise BusError("the in-process bus is not open")
        return self.testbed

    # --- lifecycle -------------------------------------------------------------------------
    def open(self) -> None:
        self.testbed = DirectTestbed(self.spec)
        for i, joint in enumerate(self.config.joints):
            if joint.torque_limit_a is not None and not self.testbed.set_current_limit_a(
                i, joint.torque_limit_a
            ):
                raise BusError(f"actuator {joint.dynamixel_id}: Torque Limit refused")

    def close(self) -> None:
        self.closed = True

    # --- the 200 Hz path -------------------------------------------------------------------
    def read(self) -> JointSample:
        testbed = self._require()
        testbed.sync()
        self.reads += 1
        reading = testbed.read()
        sample = JointSample.empty(self.n_joints, timestamp_s=testbed.time_s)
        sample.motor_angle_rad[:] = self._motor.angle(reading.motor_angle_rad)
        sample.motor_velocity_rad_s[:] = self._motor.rate(reading.motor_velocity_rad_s)
        sample.motor_current_a[:] = self._motor.rate(reading.motor_current_a)
        sample.fault_code[:] = reading.hardware_error
        sample.torque_enabled[:] = reading.torque_enabled
        sample.motor_valid[:] = reading.motor_valid
        sample.link_angle_rad[:] = self._link.angle(reading.link_angle_rad)
        sample.link_valid[:] = reading.link_valid
        sample.link_age_s[:] = np.where(reading.link_valid, 0.0, np.inf)
        n = self.n_joints
        for i in np.flatnonzero(reading.hardware_error).tolist():
            sample.actuator_fault[i] = actuator_fault(int(reading.hardware_error[i]))
        if np.count_nonzero(reading.motor_valid) + np.count_nonzero(reading.link_valid) != 2 * n:
            devices = self.devices()
            for i in range(n):  # the bus's faults of the joint, its actuator's first
                if not reading.motor_valid[i]:
                    sample.bus_errors.append(
                        BusFault(i, DeviceRole.ACTUATOR, devices[i].actuator, "no valid reply")
                    )
                if not reading.link_valid[i]:
                    sample.bus_errors.append(
                        BusFault(i, DeviceRole.LINK_SENSOR, devices[i].link_sensor, "no answer")
                    )
        sample.extra["contact_force_n"] = reading.contact_force_n
        for sensor, wrench in zip(self.config.force_torque_sensors, reading.wrenches, strict=False):
            if wrench is None:
                add_wrench(sample.extra, sensor.name, np.full(3, np.nan), np.full(3, np.nan))
            else:
                add_wrench(sample.extra, sensor.name, *wrench)
        self._diagnostics(testbed, sample)
        return sample

    def _diagnostics(self, testbed: DirectTestbed, sample: JointSample) -> None:
        """Temperature and input voltage from the control table, as the chain reads them."""
        temperature = np.full(self.n_joints, np.nan)
        voltage = np.full(self.n_joints, np.nan)
        for i, device in enumerate(testbed.robot.devices):
            if sample.motor_valid[i]:
                temperature[i] = device.item("Present Temperature")
                voltage[i] = device.item("Present Input Voltage") * INPUT_VOLTAGE_V_PER_UNIT
        sample.diagnostics[Diagnostic.ACTUATOR_TEMPERATURE_C] = temperature
        sample.diagnostics[Diagnostic.ACTUATOR_INPUT_VOLTAGE_V] = voltage

    def write(self, goal_motor_angle_rad: np.ndarray) -> None:
        testbed = self._require()
        goal = np.asarray(goal_motor_angle_rad, dtype=float)
        if (
            goal.shape != self._min.shape
            or np.count_nonzero(
                (goal >= self._min) & (goal <= self._max)  # False for NaN
            )
            != goal.size
        ):
            raise ValueError(f"goal position refused, nothing sent: {goal.tolist()}")
        testbed.write_goals(self._motor.to_spec(goal))

    # --- torque ----------------------------------------------------------------------------
    def enable(self) -> None:
        testbed = self._require()
        for i, joint in enumerate(self.config.joints):
            if testbed.robot.devices[i].hardware_error_status:
                raise BusError(f"actuator {joint.dynamixel_id}: reports a hardware error")
            if not testbed.set_torque(i, True):
                raise BusError(f"actuator {joint.dynamixel_id}: torque on not taken")

    def disable(self) -> None:
        testbed = self._require()
        missed = [
            j.dynamixel_id
            for i, j in enumerate(self.config.joints)
            if not testbed.set_torque(i, False)
        ]
        if missed:
            raise BusError(f"torque off did not reach actuator(s) {missed}")

    def reboot(self, joints: Sequence[int] | None = None) -> dict[str, ActuatorFault]:
        testbed = self._require()
        selected = range(self.n_joints) if joints is None else joints
        result = {}
        for i in selected:
            testbed.reboot(i)
            bits = testbed.robot.devices[i].hardware_error_status
            result[self.joint_names[i]] = actuator_fault(bits)
        return result

    # --- what it is ------------------------------------------------------------------------
    def current_limits_a(self) -> np.ndarray:
        testbed = self._require()
        return np.array([testbed.current_limit_a(i) for i in range(self.n_joints)])

    def devices(self) -> tuple[JointDevices, ...]:
        return self._devices

    def describe(self) -> dict[str, object]:
        return {"joints": list(self.joint_names), "in_process": True, "seed": self.spec.seed}


def in_process_bus(
    config: Config,
    experiment: Experiment | None = None,
    faults: tuple[FaultEvent, ...] = (),
    seed: int | None = None,
) -> InProcessJointBus:
    """The in-process bus for this configuration and experiment (its world, these faults); a
    robot without link encoders runs on the emulated buses only (ConfigError)."""
    if config.joints_without_link_encoder:
        raise ConfigError(
            f"{config.source}: joints {list(config.joints_without_link_encoder)} have no link "
            "encoder (encoder_node_id = 0): the in-process bus has one on every joint; run it "
            "on the emulated buses (--emulate, or a sweep's setup = 'embedded')"
        )
    spec = emulator_spec(config, experiment=experiment, faults=faults, seed=seed)
    return InProcessJointBus(config, spec)

"""The emulated humanoid's physics step as it is now (the actuators' caps, gains and brakes
written to MuJoCo only when the firmware's registers change, the motors' state read through
views of MuJoCo's arrays, the pelvis force written when it changes, MuJoCo's sensors computed
in the last step of an `advance` only) against the step written out as it was: every input
written before every step, state copied, sensors every step. Two robots side by side through
register writes, torque toggles and a push: MuJoCo's state and sensors, the firmware's state and
every byte of every control table must be equal, not close."""

from __future__ import annotations

import numpy as np

from hil.config import load_config
from hil.wiring.emulation import emulator_spec
from sim_backend.dynamixel.control_table import H54_LAYOUT
from sim_backend.humanoid.hardware import EmulatedHumanoid
from sim_backend.humanoid.robot import EmulatedRobot, PelvisPush

TICK_S = 0.005


def reference_step(robot: EmulatedRobot) -> None:
    """One physics step with every input written (the step before its short paths)."""
    plant, bank, dt = robot.plant, robot.bank, robot.physics_timestep_s
    angles, velocities = (state.copy() for state in plant.motor_state_arrays())
    out = bank.command(angles, velocities, dt)
    plant.set_servos(out.velocity_command_rad_s, out.torque_limit_nm, out.velocity_gain_nms_per_rad)
    plant.set_brakes(out.brake_damping_nms_per_rad)
    scenario_time = robot.scenario_time_s
    push = np.zeros(3)
    if scenario_time is not None:
        push = sum((event.force_at(scenario_time) for event in robot.pushes), push)
    plant.set_pelvis_force(push)
    plant.step()
    robot.clock.steps += 1
    angles, velocities = (state.copy() for state in plant.motor_state_arrays())
    bank.measure(plant.motor_torque_nm.copy(), angles, velocities, dt)


def test_the_step_equals_the_step_with_every_input_written() -> None:
    spec = emulator_spec(load_config(robot="dyros-jet"))
    fast, slow = EmulatedHumanoid.build(spec), EmulatedHumanoid.build(spec)
    rng = np.random.default_rng(11)
    for hardware in (fast, slow):
        hardware.robot.pushes = [PelvisPush(0.10, 0.08, (40.0, -15.0, 0.0))]
        for device in hardware.devices:
            device.write_item("Torque Enable", 1)
        hardware.start_scenario()
    toggled = 0
    for tick in range(80):
        # the same writes on both: goals every tick, now and then a gain, a cap, torque off/on
        joint = int(rng.integers(0, 12))
        kind = int(rng.integers(0, 8))
        value = int(rng.integers(200, 600))
        goals = rng.normal(0, 2000, 12).astype(int)
        for hardware in (fast, slow):
            devices = hardware.devices
            for device, offset in zip(devices, goals, strict=True):
                device.write_item("Goal Position", device.item("Present Position") + int(offset))
            if kind == 0:
                devices[joint].write_item("Velocity P Gain", value)
            elif kind == 1:
                devices[joint].write_item("Goal Torque", value // 2)
            elif kind == 2 and tick < 60:
                on = int(not devices[joint].torque_enabled)
                devices[joint].write_item("Torque Enable", on)
                toggled += hardware is fast
        fast.advance(TICK_S)
        for _ in range(round(TICK_S / slow.physics_timestep_s)):
            reference_step(slow.robot)
        a, b = fast.robot.plant.data, slow.robot.plant.data
        for name in ("qpos", "qvel", "qacc", "ctrl", "actuator_force", "sensordata"):
            assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), (tick, name)
        assert fast.robot.bank.integral_nm.tobytes() == slow.robot.bank.integral_nm.tobytes()
        assert fast.robot.bank.last_current_a.tobytes() == slow.robot.bank.last_current_a.tobytes()
        for x, y in zip(fast.devices, slow.devices, strict=True):
            assert x.read(0, H54_LAYOUT.size_bytes) == y.read(0, H54_LAYOUT.size_bytes)
    assert toggled > 3
    assert fast.robot.plant.model.actuator_gainprm.tobytes() == (
        slow.robot.plant.model.actuator_gainprm.tobytes()
    )

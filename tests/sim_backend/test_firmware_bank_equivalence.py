"""The vectorised firmware (`H54FirmwareBank`) against a per-joint reference of servo.py's law.

The reference below is the documented law written out joint by joint in Python numbers, the
way the firmware was stepped before the bank: per step and joint, torque off -> no torque, the
integral and the overload timer reset; position modes -> w* = Kpp (goal + homing - angle)
clipped to the speed cap (Goal Velocity if within Velocity Limit), velocity mode -> Goal
Velocity, torque mode -> Goal Torque through the current loop; the integral of kv/Ti (w* - w)
only while kv (w* - w) + integral is inside the torque cap or unwinding, itself clipped to the
cap; after the step Present Position (- Homing Offset), Velocity (+ noise), Current (torque /
Kt + noise), Moving, and the overload timer (up at |I| >= fraction x cap, down below, never < 0,
the Overload bit at the trip time). Its noise comes from one `normal(0, rms)` call per draw.

Both run side by side on their own devices over random registers, goals, mountings, torque
toggles, REBOOTs and currents near the cap (trips happen), for 12 joints (the bank's numpy
path) and for one (its Python-number path); every output and every byte of every control table
must be equal, not close.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_backend.dynamixel.control_table import H54_LAYOUT
from sim_backend.dynamixel.device import H54Device
from sim_backend.servo import (
    AMPERE_PER_CURRENT_UNIT,
    OVERLOAD_BIT,
    RAD_PER_PULSE,
    RAD_S_PER_VELOCITY_UNIT,
    H54ServoParams,
    Measurements,
)
from sim_backend.servo_bank import H54FirmwareBank

DT_S = 0.001
TABLE_BYTES = H54_LAYOUT.size_bytes


class ReferenceFirmware:
    """One joint of servo.py's law in Python numbers (see the module docstring)."""

    def __init__(self, table: H54Device, params: H54ServoParams, direction: int, offset: float):
        self.table, self.p = table, params
        self.direction, self.offset = direction, offset
        self.integral = 0.0
        self.timer = 0.0
        self.kv = self.registers()["kv"]  # the plant's velocity gain: its last torque-on value

    def registers(self) -> dict[str, float]:
        p, item = self.p, self.table.item
        goal_torque, torque_limit = item("Goal Torque"), item("Torque Limit")
        current = abs(goal_torque) if 0 < abs(goal_torque) <= torque_limit else torque_limit
        goal_velocity, velocity_limit = item("Goal Velocity"), item("Velocity Limit")
        speed = abs(goal_velocity) if 0 < abs(goal_velocity) <= velocity_limit else velocity_limit
        return {
            "kpp": p.position_gain_per_s
            * item("Position P Gain")
            / p.default_position_gain_register,
            "kv": p.velocity_gain_nms_per_rad
            * item("Velocity P Gain")
            / p.default_velocity_p_gain_register,
            "ki": p.velocity_gain_nms_per_rad
            / p.velocity_integral_time_s
            * item("Velocity I Gain")
            / p.default_velocity_i_gain_register,
            "cap_a": current * AMPERE_PER_CURRENT_UNIT,
            "speed_cap": speed * RAD_S_PER_VELOCITY_UNIT,
            "goal": (item("Goal Position") + item("Homing Offset")) * RAD_PER_PULSE,
            "goal_velocity": goal_velocity * RAD_S_PER_VELOCITY_UNIT,
            "goal_torque_a": goal_torque * AMPERE_PER_CURRENT_UNIT,
            "mode": item("Operating Mode"),
            "homing": item("Homing Offset"),
            "threshold": item("Moving Threshold") * RAD_S_PER_VELOCITY_UNIT,
        }

    def command(self, angle: float, velocity: float) -> tuple[bool, float, float]:
        """(torque on, velocity-loop input, torque cap), physical frame."""
        if not self.table.torque_enabled:
            self.integral = 0.0
            return False, 0.0, 0.0
        r = self.registers()
        angle = self.direction * angle + self.offset
        velocity = self.direction * velocity
        cap = r["cap_a"] * self.p.torque_constant_nm_per_a
        kv = self.kv = r["kv"]
        if r["mode"] in (3, 4):
            speed_command = max(
                -r["speed_cap"], min(r["speed_cap"], r["kpp"] * (r["goal"] - angle))
            )
        elif r["mode"] == 1:
            speed_command = r["goal_velocity"]
        else:
            torque = r["goal_torque_a"] * self.p.torque_constant_nm_per_a
            return True, self.direction * (velocity + torque / kv), cap
        error = speed_command - velocity
        unclipped = kv * error + self.integral
        if abs(unclipped) < cap or unclipped * error < 0:
            self.integral += r["ki"] * error * DT_S
            self.integral = max(-cap, min(cap, self.integral))
        return True, self.direction * (speed_command + self.integral / kv), cap

    def report(
        self, torque: float, angle: float, velocity: float, noise_current: float, noise_vel: float
    ) -> None:
        r = self.registers()
        torque, velocity = self.direction * torque, self.direction * velocity
        angle = self.direction * angle + self.offset
        current = torque / self.p.torque_constant_nm_per_a + noise_current
        self.table.set_measurements(
            Measurements(
                moving=int(abs(velocity) > r["threshold"]),
                position_pulses=max(
                    -(2**31), min(2**31 - 1, round(angle / RAD_PER_PULSE - r["homing"]))
                ),
                velocity_units=max(
                    -(2**31),
                    min(2**31 - 1, round((velocity + noise_vel) / RAD_S_PER_VELOCITY_UNIT)),
                ),
                current_units=max(-32768, min(32767, round(current / AMPERE_PER_CURRENT_UNIT))),
                input_voltage_decivolts=round(self.p.input_voltage_v * 10),
                temperature_c=round(self.p.temperature_c),
            )
        )
        if not self.table.torque_enabled:
            self.timer = 0.0
            return
        near = abs(current) >= self.p.overload_current_fraction * r["cap_a"]
        self.timer = max(0.0, self.timer + (DT_S if near else -DT_S))
        if self.timer >= self.p.overload_trip_time_s:
            self.table.raise_hardware_error(OVERLOAD_BIT)
            self.timer = 0.0


def random_params(rng: np.random.Generator) -> H54ServoParams:
    return H54ServoParams(
        velocity_gain_nms_per_rad=float(rng.uniform(40, 120)),
        velocity_integral_time_s=float(rng.uniform(0.05, 20)),
        current_noise_a=float(rng.choice([0.0, 0.02, 0.05])),
        velocity_noise_rad_s=float(rng.choice([0.0, 5.1e-3])),
        overload_trip_time_s=float(rng.uniform(0.005, 0.03)),  # short: trips within the test
        overload_current_fraction=float(rng.uniform(0.5, 0.9)),
    )


RANDOM_WRITES = {
    "Position P Gain": (0, 200),
    "Velocity P Gain": (1, 400),
    "Velocity I Gain": (0, 2000),
    "Goal Position": (-60_000, 60_000),
    "Goal Velocity": (-3000, 3000),
    "Goal Torque": (-620, 620),
    "Torque Limit": (0, 620),
    "Velocity Limit": (0, 2900),
    "Homing Offset": (-5000, 5000),
    "Moving Threshold": (0, 2000),
}


def random_write(
    rng: np.random.Generator, pair: tuple[H54Device, H54Device], toggles: bool = True
) -> None:
    """The same write on both tables: firmware-side (registers, mode, torque toggle), or Goal
    Position the host's way (a WRITE packet's rules; the bank then decodes it alone)."""
    kind = int(rng.integers(0, 14))
    if kind >= 12:
        value = int(rng.integers(-60_000, 60_000))
        assert len({device.write_item("Goal Position", value) for device in pair}) == 1
        return
    if kind < len(RANDOM_WRITES):
        name = list(RANDOM_WRITES)[kind]
        value = int(rng.integers(*RANDOM_WRITES[name]))
    elif kind == 10:
        name, value = "Operating Mode", int(rng.choice([3, 3, 4, 1, 0]))
    elif toggles:
        name, value = "Torque Enable", int(rng.integers(0, 2))
    else:
        return
    for device in pair:
        device.set_item(name, value)


@pytest.mark.parametrize(
    ("n_joints", "mounted"),
    [(12, True), (1, True), (12, False), (1, False)],
    ids=["12-mounted", "1-mounted", "12-identity", "1-identity"],
)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_bank_equals_the_per_joint_law_byte_for_byte(
    n_joints: int, mounted: bool, seed: int
) -> None:
    """mounted: random directions and offsets, torque toggled at random; identity: direction
    +1, offset 0 and torque toggled only by trips and reboots (the bank's short paths)."""
    rng = np.random.default_rng(seed)
    params = [random_params(rng) for _ in range(n_joints)]
    directions = [int(rng.choice([1, -1])) if mounted else 1 for _ in range(n_joints)]
    offsets = [float(rng.uniform(-0.5, 0.5)) if mounted else 0.0 for _ in range(n_joints)]
    bank_devices = [H54Device(j + 1) for j in range(n_joints)]
    ref_devices = [H54Device(j + 1) for j in range(n_joints)]
    noise_seed = [seed, 1000]
    bank = H54FirmwareBank(
        bank_devices,
        params,
        directions=directions,
        offsets_rad=offsets,
        rng=np.random.default_rng(noise_seed),
    )
    reference = [
        ReferenceFirmware(ref_devices[j], params[j], directions[j], offsets[j])
        for j in range(n_joints)
    ]
    ref_rng = np.random.default_rng(noise_seed)  # one normal() per draw, joint by joint

    def ref_noise(joint: int) -> tuple[float, float]:
        p = params[joint]
        current = float(ref_rng.normal(0.0, p.current_noise_a)) if p.current_noise_a else 0.0
        vel = float(ref_rng.normal(0.0, p.velocity_noise_rad_s)) if p.velocity_noise_rad_s else 0.0
        return current, vel

    state = {"angle": rng.uniform(-1, 1, n_joints), "velocity": rng.uniform(-1, 1, n_joints)}
    state["torque"] = rng.uniform(-50, 50, n_joints)

    def reboot(joint: int) -> None:
        for device in (bank_devices[joint], ref_devices[joint]):
            device.reboot(0.0)
        bank.on_reboot(joint)
        reference[joint].integral = reference[joint].timer = 0.0
        args = (state["torque"][joint], state["angle"][joint], state["velocity"][joint])
        bank.report_joint(joint, *args, DT_S)
        reference[joint].report(*args, *ref_noise(joint))
        if not mounted:  # the host turns torque on again after a reboot
            for device in (bank_devices[joint], ref_devices[joint]):
                device.set_item("Torque Enable", 1)

    for device_pair in zip(bank_devices, ref_devices, strict=True):
        for device in device_pair:
            device.set_item("Torque Enable", 1)
    trips = reboots = 0
    for _ in range(1500):
        for _ in range(int(rng.integers(0, 4))):
            joint = int(rng.integers(0, n_joints))
            random_write(rng, (bank_devices[joint], ref_devices[joint]), toggles=mounted)
        if rng.random() < 0.01:
            reboot(int(rng.integers(0, n_joints)))
            reboots += 1
        angles, velocities = state["angle"], state["velocity"]
        if n_joints == 1:
            out = bank.command_one(float(angles[0]), float(velocities[0]), DT_S)
            got = [out]
        else:
            commands = bank.command(angles, velocities, DT_S)
            got = list(
                zip(
                    commands.torque_on.tolist(),
                    commands.velocity_command_rad_s.tolist(),
                    commands.torque_limit_nm.tolist(),
                    strict=True,
                )
            )
        expected = [reference[j].command(angles[j], velocities[j]) for j in range(n_joints)]
        assert got == expected
        if n_joints > 1:
            assert commands.velocity_gain_nms_per_rad.tolist() == [r.kv for r in reference]
            brakes = [
                0.0 if on else p.dynamic_brake_damping_nms_per_rad
                for (on, _, _), p in zip(expected, params, strict=True)
            ]
            assert commands.brake_damping_nms_per_rad.tolist() == brakes
        assert bank.integral_nm.tolist() == [r.integral for r in reference]
        # "the plant": a new state, torques around the caps so that the timers run and trip
        caps = np.array([max(c, 1.0) for _, _, c in expected])
        state["angle"] = angles + rng.normal(0, 0.01, n_joints)
        state["velocity"] = rng.normal(0, rng.choice([0.5, 0.001]), n_joints)  # small: unwinding
        state["torque"] = caps * rng.choice([-1, 1], n_joints) * rng.uniform(0.75, 1.15, n_joints)
        before = [device.hardware_error_status for device in ref_devices]
        if n_joints == 1:
            bank.measure_one(
                float(state["torque"][0]),
                float(state["angle"][0]),
                float(state["velocity"][0]),
                DT_S,
            )
        else:
            bank.measure(state["torque"], state["angle"], state["velocity"], DT_S)
        for j in range(n_joints):
            reference[j].report(
                state["torque"][j], state["angle"][j], state["velocity"][j], *ref_noise(j)
            )
        trips += sum(
            not b & OVERLOAD_BIT and d.hardware_error_status & OVERLOAD_BIT
            for b, d in zip(before, ref_devices, strict=True)
        )
        assert bank.overload_timer_s.tolist() == [r.timer for r in reference]
        for bank_device, ref_device in zip(bank_devices, ref_devices, strict=True):
            assert bank_device.read(0, TABLE_BYTES) == ref_device.read(0, TABLE_BYTES)
        if any(d.hardware_error_status for d in ref_devices) and rng.random() < 0.05:
            reboot(int(np.argmax([d.hardware_error_status for d in ref_devices])))
            reboots += 1
    assert trips > 0 and reboots > 0  # the test reached the overload trip and the reboot
    assert math.isfinite(float(bank.integral_nm.sum()))

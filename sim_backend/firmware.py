"""One H54 actuator's firmware as an object: a view of one joint of an `H54FirmwareBank`."""

from __future__ import annotations

import numpy as np

from sim_backend.servo import ControlTable, H54ServoParams, Registers, ServoOutput
from sim_backend.servo_bank import H54FirmwareBank


class H54Firmware:
    """One actuator's firmware: joint `joint` of an `H54FirmwareBank` (sim_backend/servo_bank.py,
    which runs the law above for n actuators at once). Made from a table, it is a bank of one
    (identity mounting, no noise of its own: `report` takes this step's noise)."""

    def __init__(
        self,
        table: ControlTable | None = None,
        params: H54ServoParams | None = None,
        *,
        bank: H54FirmwareBank | None = None,
        joint: int = 0,
    ) -> None:
        if bank is None:
            if table is None or params is None:
                raise ValueError("H54Firmware needs a control table and its params, or a bank")
            bank = H54FirmwareBank([table], [params])
        self.bank = bank
        self.joint = joint
        self.table = bank.tables[joint]
        self.params = bank.params[joint]

    def on_reboot(self) -> None:
        self.bank.on_reboot(self.joint)

    @property
    def integral_nm(self) -> float:
        return float(self.bank.integral_nm[self.joint])

    @property
    def overload_timer_s(self) -> float:
        return float(self.bank.overload_timer_s[self.joint])

    @property
    def last_current_a(self) -> float:
        return float(self.bank.last_current_a[self.joint])

    @property
    def registers(self) -> Registers:
        """The control table's registers in SI, decoded again only after a write."""
        return self.bank.registers(self.joint)

    def _position_gain(self) -> float:
        return self.registers.position_gain_per_s

    def velocity_gain(self) -> float:
        return self.registers.velocity_gain_nms_per_rad

    def current_cap_a(self) -> float:
        return self.registers.current_cap_a

    def speed_cap_rad_s(self) -> float:
        return self.registers.speed_cap_rad_s

    def goal_angle_rad(self) -> float:
        return self.bank.goal_angle_rad(self.joint)

    # --- one physics step of a bank of one ----------------------------------------------------
    def compute(
        self, motor_angle_rad: float, motor_velocity_rad_s: float, dt_s: float
    ) -> ServoOutput:
        """The velocity-loop input and torque cap for this step (device frame)."""
        return ServoOutput(
            *self._own_bank().command_one(motor_angle_rad, motor_velocity_rad_s, dt_s)
        )

    def report(
        self,
        motor_torque_nm: float,
        motor_angle_rad: float,
        motor_velocity_rad_s: float,
        dt_s: float,
        current_noise_a: float = 0.0,
        velocity_noise_rad_s: float = 0.0,
    ) -> None:
        """After a physics step: the overload protection now, the Present* items (written when
        the table is next read). current_noise_a, velocity_noise_rad_s: this step's measurement
        noise (the current the firmware measures is also what its protection sees)."""
        self._own_bank().measure(
            np.array([motor_torque_nm]),
            np.array([motor_angle_rad]),
            np.array([motor_velocity_rad_s]),
            dt_s,
            current_noise_a=np.array([current_noise_a]),
            velocity_noise_rad_s=np.array([velocity_noise_rad_s]),
        )

    def _own_bank(self) -> H54FirmwareBank:
        if self.bank.n != 1:
            raise RuntimeError("step a multi-joint bank as a whole (H54FirmwareBank)")
        return self.bank

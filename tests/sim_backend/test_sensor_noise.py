"""Every emulated sensor carries its nominal noise, seeded: same seed -> the same samples,
another seed -> other samples, and the rms matches the parameter within statistical bounds.

Rounding a noisy value: for a true value x spread uniformly over the quantum (a moving link) and
noise n ~ N(0, s^2) independent of it, round(x + n) - x = n + (round(y) - y) with y = x + n also
uniform and independent of n, so the error's mean square is s^2 + 1/12 quanta exactly. For a
fixed x and s >= 1 the same holds to within 1 % (Sheppard's correction).
"""

from __future__ import annotations

import math
import struct

import can
import numpy as np
import pytest

from sim_backend.canbus import ForceSensorNode, LinkEncoderNode
from sim_backend.canbus.encoder_node import RLC2IC_NOISE_COUNTS_RMS
from sim_backend.canbus.force_sensor_node import FORCE_SENSOR_NOISE_N_RMS
from sim_backend.dynamixel import H54Device
from sim_backend.plant import TestbedPlantParams as PlantParams
from sim_backend.server import SensorNoise
from sim_backend.servo import AMPERE_PER_CURRENT_UNIT, RAD_S_PER_VELOCITY_UNIT, H54ServoParams
from sim_backend.testbed import EmulatedJoint

SYNC = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)
START_ALL = can.Message(arbitration_id=0x000, data=bytes([0x01, 0]), is_extended_id=False)
COUNTS_PER_REV = 983_040
N_SAMPLES = 20_000


def _tpdo_values(node, node_id: int, n: int, before_sync=None) -> np.ndarray:
    node.poll(0.0)
    node.handle(START_ALL, 0.0)
    values = []
    for k in range(n):
        if before_sync is not None:
            before_sync(k)
        frames = node.handle(SYNC, 0.001 * (k + 1))
        tpdo = next(f for f in frames if f.arbitration_id == 0x180 + node_id)
        values.append(struct.unpack("<i", bytes(tpdo.data[:4]))[0])
    return np.array(values, dtype=float)


def _encoder_errors(seed: int, noise: float) -> np.ndarray:
    angle = [0.0]
    node = LinkEncoderNode(5, lambda: angle[0], seed=seed, noise_counts_rms=noise)

    def move(k: int) -> None:  # 0.37 count per sample: the true value sweeps the quantum
        angle[0] = 0.37 * k * 2 * math.pi / COUNTS_PER_REV

    counts = _tpdo_values(node, 5, N_SAMPLES, move)
    return counts - 0.37 * np.arange(N_SAMPLES)


def test_link_encoder_noise_is_seeded_and_has_its_rms() -> None:
    first = _encoder_errors(3, RLC2IC_NOISE_COUNTS_RMS)
    np.testing.assert_array_equal(first, _encoder_errors(3, RLC2IC_NOISE_COUNTS_RMS))
    assert np.count_nonzero(first != _encoder_errors(4, RLC2IC_NOISE_COUNTS_RMS)) > N_SAMPLES / 4
    expected = math.sqrt(RLC2IC_NOISE_COUNTS_RMS**2 + 1 / 12)  # 0.577 count
    assert np.sqrt(np.mean(first**2)) == pytest.approx(expected, rel=0.02)
    assert abs(np.mean(first)) < 0.02
    ideal = _encoder_errors(3, 0.0)  # without noise: only the rounding, |error| <= 1/2
    assert np.max(np.abs(ideal)) <= 0.5 + 1e-9
    assert np.sqrt(np.mean(ideal**2)) == pytest.approx(math.sqrt(1 / 12), rel=0.02)


def _force_readings_n(seed: int) -> np.ndarray:
    node = ForceSensorNode(7, lambda: 31.4159, seed=seed, noise_n_rms=FORCE_SENSOR_NOISE_N_RMS)
    return _tpdo_values(node, 7, N_SAMPLES) / 1000.0  # the PV is in mN


def test_force_sensor_noise_is_seeded_and_has_its_rms() -> None:
    first = _force_readings_n(3)
    np.testing.assert_array_equal(first, _force_readings_n(3))
    assert np.count_nonzero(first != _force_readings_n(4)) > N_SAMPLES / 2
    error = first - 31.4159
    assert np.std(error) == pytest.approx(FORCE_SENSOR_NOISE_N_RMS, rel=0.02)
    assert abs(np.mean(error)) < 4 * FORCE_SENSOR_NOISE_N_RMS / math.sqrt(N_SAMPLES)


SERVO_SAMPLES = 5000


def _servo_readings(seed: int, servo: H54ServoParams) -> tuple[np.ndarray, np.ndarray]:
    """Present Current and Velocity of a powered, holding H54, one per 1 ms step, minus the true
    values (plant torque / Kt, plant velocity), in device units."""
    device = H54Device(1)
    joint = EmulatedJoint(device, PlantParams(), servo, rng=np.random.default_rng([seed, 1000]))
    device.set_item("Torque Enable", 1)
    for _ in range(500):  # settle the hold (the servo takes the gravity load)
        joint.step(None)
    currents, velocities = [], []
    for _ in range(SERVO_SAMPLES):
        joint.step(None)
        true_current = joint.plant.motor_torque_nm / servo.torque_constant_nm_per_a
        currents.append(device.item("Present Current") - true_current / AMPERE_PER_CURRENT_UNIT)
        velocities.append(
            device.item("Present Velocity")
            - joint.plant.motor_velocity_rad_s / RAD_S_PER_VELOCITY_UNIT
        )
    return np.array(currents), np.array(velocities)


def test_h54_current_and_velocity_noise_are_seeded_and_have_their_rms() -> None:
    nominal = H54ServoParams()
    current, velocity = _servo_readings(3, nominal)
    again_current, again_velocity = _servo_readings(3, nominal)
    np.testing.assert_array_equal(current, again_current)
    np.testing.assert_array_equal(velocity, again_velocity)
    other_current, other_velocity = _servo_readings(4, nominal)
    assert np.count_nonzero(current != other_current) > SERVO_SAMPLES / 2
    assert np.count_nonzero(velocity != other_velocity) > SERVO_SAMPLES / 2
    sigma_current = nominal.current_noise_a / AMPERE_PER_CURRENT_UNIT  # 1.24 units
    sigma_velocity = nominal.velocity_noise_rad_s / RAD_S_PER_VELOCITY_UNIT  # 24.4 units
    rms_current = np.sqrt(np.mean(current**2))
    rms_velocity = np.sqrt(np.mean(velocity**2))
    assert rms_current == pytest.approx(math.sqrt(sigma_current**2 + 1 / 12), rel=0.03)
    assert rms_velocity == pytest.approx(math.sqrt(sigma_velocity**2 + 1 / 12), rel=0.03)
    ideal = H54ServoParams(current_noise_a=0.0, velocity_noise_rad_s=0.0)
    ideal_current, ideal_velocity = _servo_readings(3, ideal)
    assert np.max(np.abs(ideal_current)) <= 0.5 + 1e-9  # rounding only
    assert np.max(np.abs(ideal_velocity)) <= 0.5 + 1e-9


def test_the_emulators_nominal_figures() -> None:
    noise = SensorNoise()
    assert noise.link_encoder_counts_rms == RLC2IC_NOISE_COUNTS_RMS == 0.5
    assert noise.force_sensor_n_rms == FORCE_SENSOR_NOISE_N_RMS == 0.05
    servo = H54ServoParams()
    assert servo.current_noise_a == 0.02
    # the velocity figure is one encoder pulse differenced over 1 ms: q / (T sqrt 6)
    assert servo.velocity_noise_rad_s == pytest.approx(
        2 * math.pi / 501_923 / (1e-3 * math.sqrt(6)), rel=0.01
    )
    with pytest.raises(ValueError, match="finite rms"):
        SensorNoise(link_encoder_counts_rms=-1.0)
    with pytest.raises(ValueError, match="finite rms"):
        H54ServoParams(velocity_noise_rad_s=math.nan)
    with pytest.raises(ValueError, match="finite rms"):
        LinkEncoderNode(5, lambda: 0.0, noise_counts_rms=-0.1)

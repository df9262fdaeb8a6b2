"""The emulated gearbox's friction models (sim_backend/friction.py) against their laws, in MuJoCo,
and as [emulator] plant keys.

The breakaway test: gravity off, the link free, the servo asked for far more speed than it can
reach with its torque capped at T, so the motor sees T alone: it sticks while T is below the
friction bound at rest and slides above it. Coulomb-viscous breaks away at F_c, Stribeck at
F_c + F_s; load-dependent's bound, written before each step, is F_c + mu |K d + D d'|.
"""

from __future__ import annotations

import math

import pytest

from hil.config import ConfigError, load_config
from sim_backend.friction import GearboxFriction, GearboxFrictionParams
from sim_backend.plant import TestbedPlant, TestbedPlantParams


def test_laws() -> None:
    stribeck = GearboxFrictionParams("stribeck", 2.0, 3.0, 0.1)
    assert stribeck.loss_nm(0.0, 99.0) == pytest.approx(5.0)
    assert stribeck.loss_nm(0.1, 0.0) == pytest.approx(2.0 + 3.0 * math.exp(-1.0))
    assert stribeck.loss_nm(-1.0, 0.0) == pytest.approx(2.0, abs=1e-12)
    load = GearboxFrictionParams(GearboxFriction.LOAD_DEPENDENT, 2.0, load_ratio=0.25)
    assert load.loss_nm(5.0, -8.0) == pytest.approx(4.0)
    assert GearboxFrictionParams("coulomb-viscous", 2.0).loss_nm(0.0, 50.0) == 2.0


def _slides(params: TestbedPlantParams, torque_nm: float) -> float:
    """The motor's travel [rad] in 0.3 s under a constant torque T from rest."""
    plant = TestbedPlant(params, velocity_gain_nms_per_rad=1000.0)
    start = plant.motor_angle_rad
    for _ in range(300):
        plant.set_servo(100.0, torque_nm)  # kv (100 - w) capped at T: T while w is small
        plant.step()
    return plant.motor_angle_rad - start


FREE = {"gravity_m_s2": 0.0, "gearbox_viscous_friction_nms_per_rad": 0.0}


@pytest.mark.parametrize(
    ("params", "breakaway_nm"),
    [
        (TestbedPlantParams(**FREE, gearbox_coulomb_friction_nm=2.0), 2.0),
        (
            TestbedPlantParams(
                **FREE,
                gearbox_coulomb_friction_nm=2.0,
                gearbox_friction_model="stribeck",
                gearbox_stribeck_friction_nm=3.0,
                gearbox_stribeck_velocity_rad_s=0.05,
            ),
            5.0,
        ),
    ],
    ids=["coulomb-viscous", "stribeck"],
)
def test_breakaway_torque(params: TestbedPlantParams, breakaway_nm: float) -> None:
    stuck = _slides(params, 0.9 * breakaway_nm)
    slid = _slides(params, 1.1 * breakaway_nm)
    # MuJoCo's friction is a soft constraint: a stuck motor creeps (~4 mrad/s per N m here)
    assert abs(stuck) < 1.5e-3 * breakaway_nm, stuck
    assert slid > 4 * abs(stuck), (slid, stuck)


def test_load_dependent_bound_follows_the_gear_torque() -> None:
    params = TestbedPlantParams(
        gearbox_friction_model="load-dependent",
        gearbox_coulomb_friction_nm=1.0,
        gearbox_load_friction_ratio=0.3,
    )
    plant = TestbedPlant(params, velocity_gain_nms_per_rad=78.5)
    dof = plant.model.jnt_dofadr[plant.model.joint("motor").id]
    for _ in range(50):
        plant.set_servo(0.5, 48.0)
        expected = 1.0 + 0.3 * abs(plant.gear_torque_nm)
        plant.step()
        assert plant.model.dof_frictionloss[dof] == pytest.approx(expected, rel=1e-12)
    assert abs(plant.gear_torque_nm) > 5.0  # gravity's load is in the gear: the law is seen


def test_default_keeps_the_constant_bound() -> None:
    plant = TestbedPlant(TestbedPlantParams(), velocity_gain_nms_per_rad=78.5)
    dof = plant.model.jnt_dofadr[plant.model.joint("motor").id]
    for _ in range(20):
        plant.set_servo(1.0, 48.0)
        plant.step()
    assert plant.model.dof_frictionloss[dof] == 3.95


def test_configuration_keys() -> None:
    config = load_config()
    config.changed(
        "emulator",
        plant={"gearbox_friction_model": "stribeck", "gearbox_stribeck_friction_nm": 1.0},
    )
    from hil.wiring.emulation import plant_servo_noise

    with pytest.raises(ConfigError, match="gearbox_load_friction_ratio"):
        plant_servo_noise(
            config.changed("emulator", plant={"gearbox_load_friction_ratio": 0.2})
        )  # not read by the default model: said, not ignored
    with pytest.raises(ConfigError, match="gearbox_friction_model must be one of"):
        plant_servo_noise(config.changed("emulator", plant={"gearbox_friction_model": "bam"}))
    with pytest.raises(ConfigError, match="gearbox_load_friction_ratio"):
        config.changed("emulator", plant={"gearbox_load_friction_ratio": 0.9})  # its range

"""The emulated fixed-base robot's physical parameters: the TRUTH of a run (the controller's
model is nominal and separate; a run can make them differ to test robustness).

The links are the URDF's (mass, CoM, inertia). Each flexible joint's gear and motor side are
its actuator model's (`model_gear_figures`):

    H54-200-S500-R   the testbed's (sim_backend.plant.TestbedPlantParams): K = 2000 N m/rad and
                     D = 100 N m s/rad (Kim et al., Sec. IV-A), reflected rotor inertia
                     0.25 kg m^2, gearbox friction 3.95 N m Coulomb + 1.14 N m s/rad viscous
                     (assumptions documented there)
    any other model  ASSUMED: the H54-200-S500-R's figures scaled by the model's continuous
                     torque over the H54-200-S500-R's 44.7 N m (e-Manual specification tables,
                     sim_backend/dynamixel/models.py): the same deflection at rated torque, the
                     same gear damping ratio, a rotor and gearbox growing with the motor
                     (ROBOTIS publish no gear stiffness, rotor inertia or friction for any
                     model). The velocity loop's gain scales the same way
                     (sim_backend/servo_models.py), so every model's velocity-loop bandwidth
                     kv / J is the H54-200's 50 Hz.

Every per-joint figure can be overridden (`[emulator] plant`): one value for every joint or one
per joint, in the configuration's joint order.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from sim_backend.dynamixel.models import DEFAULT_MODEL, figures_of
from sim_backend.plant import GRAVITY_M_S2, TestbedPlantParams
from sim_backend.urdf_mjcf import LinkChanges

PerJoint = float | tuple[float, ...] | None

_GEAR_FIELDS = (
    "gear_stiffness_nm_per_rad",
    "gear_damping_nms_per_rad",
    "motor_reflected_inertia_kg_m2",
    "gearbox_coulomb_friction_nm",
    "gearbox_viscous_friction_nms_per_rad",
)


@dataclass(frozen=True)
class GearFigures:
    """One joint's gear and motor side (see the module docstring)."""

    gear_stiffness_nm_per_rad: float
    gear_damping_nms_per_rad: float
    motor_reflected_inertia_kg_m2: float
    gearbox_coulomb_friction_nm: float
    gearbox_viscous_friction_nms_per_rad: float


def model_gear_figures(model: str) -> GearFigures:
    """The gear and motor side of a joint of `model` (e-Manual name; the module docstring)."""
    testbed = TestbedPlantParams()
    scale = figures_of(model).continuous_torque_nm / figures_of(DEFAULT_MODEL).continuous_torque_nm
    return GearFigures(**{name: getattr(testbed, name) * scale for name in _GEAR_FIELDS})


@dataclass(frozen=True)
class FixedBaseTruthParams:
    """The emulated robot's physics (module docstring). Per-joint figures: None (each joint's
    model's), one value for every joint, or one per joint.

    mass_scale: every link's mass and inertia times this (1 = the URDF's).
    com_offset_link / com_offset_m: a shift of one link's centre of mass (a payload the
        controller does not know of).
    block_time_constant_s / block_damping_ratio: the block's MuJoCo contact (solref): 5 ms, a
        steel block on a force sensor (as the testbed's, sim_backend.plant.ObstacleParams).
    physics_timestep_s: MuJoCo step (implicitfast); the firmware runs once per step.
    """

    gear_stiffness_nm_per_rad: PerJoint = None
    gear_damping_nms_per_rad: PerJoint = None
    motor_reflected_inertia_kg_m2: PerJoint = None
    gearbox_coulomb_friction_nm: PerJoint = None
    gearbox_viscous_friction_nms_per_rad: PerJoint = None
    mass_scale: float = 1.0
    com_offset_link: str = ""
    com_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    block_time_constant_s: float = 0.005
    block_damping_ratio: float = 1.0
    physics_timestep_s: float = 0.001
    gravity_m_s2: float = GRAVITY_M_S2

    def __post_init__(self) -> None:
        for name in _GEAR_FIELDS:
            value = getattr(self, name)
            values = () if value is None else (value,) if isinstance(value, int | float) else value
            if any(not math.isfinite(v) or v < 0 for v in values) or (
                name in ("gear_stiffness_nm_per_rad", "motor_reflected_inertia_kg_m2")
                and any(v <= 0 for v in values)
            ):
                raise ValueError(f"{name} must be positive, got {value}")
        if not (math.isfinite(self.mass_scale) and self.mass_scale > 0):
            raise ValueError(f"mass_scale must be > 0, got {self.mass_scale}")
        if not (math.isfinite(self.physics_timestep_s) and 0 < self.physics_timestep_s <= 0.002):
            raise ValueError(
                f"physics_timestep_s must be in (0, 2 ms] (implicitfast), got "
                f"{self.physics_timestep_s}"
            )
        if not (self.block_time_constant_s > 0 and self.block_damping_ratio > 0):
            raise ValueError("the block's time constant and damping ratio must be > 0")
        if len(self.com_offset_m) != 3:
            raise ValueError("com_offset_m needs 3 entries")

    def gears(self, models: Sequence[str]) -> tuple[GearFigures, ...]:
        """Each joint's gear figures, for joints of these actuator models (overrides applied)."""
        n = len(models)
        own = [model_gear_figures(model) for model in models]
        columns = {}
        for name in _GEAR_FIELDS:
            value = getattr(self, name)
            if value is None:
                columns[name] = [getattr(g, name) for g in own]
            elif isinstance(value, int | float):
                columns[name] = [float(value)] * n
            elif len(value) == n:
                columns[name] = [float(v) for v in value]
            else:
                raise ValueError(f"{name} needs one value or {n} (one per joint), got {value}")
        return tuple(GearFigures(*(columns[k][i] for k in _GEAR_FIELDS)) for i in range(n))

    @property
    def link_changes(self) -> LinkChanges:
        return LinkChanges(self.mass_scale, self.com_offset_link, tuple(self.com_offset_m))

"""The emulated gearbox's friction: which model, and the friction torque it bounds each step.

MuJoCo applies a joint's `frictionloss` as a soft constraint: the friction torque is whatever
stops the joint, up to the loss (the joint sticks when that suffices), so stick-slip needs no
switching logic of ours. Every model below is a law for that bound, written into
`dof_frictionloss` before each physics step from the state at its start (as Rhoban's BAM does
for its servos: Duclusaud et al., "Extended Friction Models for the Physics Simulation of Servo
Actuators", ICRA 2025); the viscous part stays MuJoCo's joint `damping`, implicit in the
integrator.

    coulomb-viscous  F = F_c                                     (the default; a constant bound,
                                                                  written once in the MJCF)
    stribeck         F = F_c + F_s exp(-(w / w_s)^2)             breakaway friction above the
                                                                  sliding one near rest
    load-dependent   F = F_c + mu |tau_t|                        friction growing with the
                                                                  torque the gearbox transmits

w is the motor side's speed at the output [rad/s], tau_t the torque the gear carries to the link
(K deflection + D deflection rate) [N m]. F_s, w_s and mu are the models' own figures
(`GearboxFrictionParams`); a figure of a model not chosen must stay at its neutral value, so
that a configuration says only what the emulator does.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

# The configuration's key of each figure ([emulator] plant), for messages.
KEYS = {
    "model": "gearbox_friction_model",
    "coulomb_nm": "gearbox_coulomb_friction_nm",
    "stribeck_nm": "gearbox_stribeck_friction_nm",
    "stribeck_velocity_rad_s": "gearbox_stribeck_velocity_rad_s",
    "load_ratio": "gearbox_load_friction_ratio",
}


class GearboxFriction(enum.StrEnum):
    """The emulated gearbox's friction law (see the module docstring)."""

    COULOMB_VISCOUS = "coulomb-viscous"
    STRIBECK = "stribeck"
    LOAD_DEPENDENT = "load-dependent"


# The neutral values of the models' own figures (what a model that does not use them holds).
NEUTRAL_STRIBECK_FRICTION_NM = 0.0
NEUTRAL_STRIBECK_VELOCITY_RAD_S = 0.05
NEUTRAL_LOAD_FRICTION_RATIO = 0.0


@dataclass(frozen=True)
class GearboxFrictionParams:
    """One gearbox's friction: the model and every figure it reads (SI, at the output).

    coulomb_nm: F_c, the sliding friction every model has.
    stribeck_nm: F_s, the extra friction at rest of the Stribeck model (breakaway F_c + F_s).
    stribeck_velocity_rad_s: w_s, the speed over which the extra friction fades.
    load_ratio: mu, N m of friction per N m the gearbox transmits (load-dependent model).
    """

    model: GearboxFriction | str  # a word is read as the model it names
    coulomb_nm: float
    stribeck_nm: float = NEUTRAL_STRIBECK_FRICTION_NM
    stribeck_velocity_rad_s: float = NEUTRAL_STRIBECK_VELOCITY_RAD_S
    load_ratio: float = NEUTRAL_LOAD_FRICTION_RATIO

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "model", GearboxFriction(self.model))
        except ValueError:
            choices = ", ".join(repr(m.value) for m in GearboxFriction)
            raise ValueError(
                f"gearbox_friction_model must be one of {choices}, got {self.model!r}"
            ) from None
        for name in ("coulomb_nm", "stribeck_nm", "load_ratio"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{KEYS[name]} must be finite and >= 0, got {value}")
        if not (math.isfinite(self.stribeck_velocity_rad_s) and self.stribeck_velocity_rad_s > 0):
            raise ValueError(
                "gearbox_stribeck_velocity_rad_s must be finite and > 0, got "
                f"{self.stribeck_velocity_rad_s}"
            )
        unused = {
            GearboxFriction.STRIBECK: ("load_ratio",),
            GearboxFriction.LOAD_DEPENDENT: ("stribeck_nm", "stribeck_velocity_rad_s"),
            GearboxFriction.COULOMB_VISCOUS: (
                "load_ratio",
                "stribeck_nm",
                "stribeck_velocity_rad_s",
            ),
        }[self.law]
        neutral = {
            "load_ratio": NEUTRAL_LOAD_FRICTION_RATIO,
            "stribeck_nm": NEUTRAL_STRIBECK_FRICTION_NM,
            "stribeck_velocity_rad_s": NEUTRAL_STRIBECK_VELOCITY_RAD_S,
        }
        for name in unused:
            if getattr(self, name) != neutral[name]:
                raise ValueError(
                    f"{KEYS[name]} = {getattr(self, name)} is not read by the "
                    f"{self.law.value!r} model (gearbox_friction_model)"
                )

    @property
    def law(self) -> GearboxFriction:
        assert isinstance(self.model, GearboxFriction)  # (converted at construction)
        return self.model

    @property
    def varies(self) -> bool:
        """Whether the bound changes with the state (else MuJoCo's constant frictionloss)."""
        return self.law is not GearboxFriction.COULOMB_VISCOUS

    def loss_nm(self, motor_velocity_rad_s: float, transmitted_torque_nm: float) -> float:
        """The friction bound F at this state (the module docstring's laws)."""
        if self.law is GearboxFriction.STRIBECK:
            ratio = motor_velocity_rad_s / self.stribeck_velocity_rad_s
            return self.coulomb_nm + self.stribeck_nm * math.exp(-ratio * ratio)
        if self.law is GearboxFriction.LOAD_DEPENDENT:
            return self.coulomb_nm + self.load_ratio * abs(transmitted_torque_nm)
        return self.coulomb_nm

"""A sweep's plan (the spec is hil/sweep/spec.py): the configuration at each point, and the
list of runs - one per (point, experiment, controller), each with an id hashed from everything
that defines it, so that rerunning the same spec finds the runs already done."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from typing import Any

from hil.config import Config
from hil.sweep.ranges import SpecError, check_range
from hil.sweep.spec import ModelFollows, SweepSpec, Task, Value
from hil.wiring.emulation import plant_servo_noise


# --- the configuration at a point --------------------------------------------------------------
def configured_value(config: Config, target: str) -> Any:
    """The value `target` ('model.stiffness_nm_per_rad', 'emulator.plant.load_mass_kg', ...)
    has in `config` (for the emulator's plant and servo: the override or the default)."""
    section, _, key = target.partition(".")
    if section == "emulator" and key.split(".")[0] in ("plant", "servo"):
        part, _, name = key.partition(".")
        plant, servo, _ = plant_servo_noise(config)
        holder = plant if part == "plant" else servo
        if not hasattr(holder, name):
            raise SpecError(f"target {target!r}: the emulator's {part} has no {name!r}")
        return getattr(holder, name)
    table = getattr(config, section, None)
    if table is None or not hasattr(table, key):
        raise SpecError(f"target {target!r}: no such configuration key")
    return getattr(table, key)


def resolved(spec: SweepSpec, config: Config) -> SweepSpec:
    """Every target checked against the configuration, and `relative = [a, b]` ranges made
    absolute against the configured value of the first target."""
    parameters = []
    for p in spec.parameters:
        nominal = [configured_value(config, target) for target in p.targets]
        if p.relative is not None:
            low, high = (factor * float(nominal[0]) for factor in p.relative)
            p = dataclasses.replace(p, low=low, high=high, relative=None)
            check_range(p)
        parameters.append(p)
    return dataclasses.replace(spec, parameters=tuple(parameters))


def config_at(base: Config, targets: dict[str, Value], model: ModelFollows) -> Config:
    """The configuration with these target values (each validated like the file); with
    ModelFollows.PLANT the controller's [model] then takes the plant's figures."""
    config = base
    plant_changes: dict[str, dict[str, Any]] = {"plant": {}, "servo": {}}
    for target, value in targets.items():
        section, _, key = target.partition(".")
        part, _, name = key.partition(".")
        if section == "emulator" and part in plant_changes and name:
            plant_changes[part][name] = value
        else:
            config = config.changed(section, option=target, **{key: value})
    if any(plant_changes.values()):
        config = config.changed(
            "emulator",
            plant={**config.emulator.plant, **plant_changes["plant"]},
            servo={**config.emulator.servo, **plant_changes["servo"]},
        )
    if model is ModelFollows.PLANT:
        plant, servo, _ = plant_servo_noise(config)
        config = config.changed(
            "model",
            stiffness_nm_per_rad=plant.gear_stiffness_nm_per_rad,
            damping_nms_per_rad=plant.gear_damping_nms_per_rad,
            servo_gain_per_s=servo.position_gain_per_s,
            # the cascade's Kpp follows servo_gain_per_s (and its per-joint overrides)
            velocity_gain_nms_per_rad=servo.velocity_gain_nms_per_rad,
            velocity_integral_time_s=servo.velocity_integral_time_s,
            link_inertia_kg_m2=plant.link_inertia_kg_m2,
            gravity_moment_kg_m=plant.gravity_moment_kg_m,
        )
    return config


def _digest(data: Any, length: int) -> str:
    text = json.dumps(data, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:length]


def plan(spec: SweepSpec, base: Config) -> list[Task]:
    """Every run of the sweep, in order: per point, per experiment, per controller.

    The base configuration's changes ([base]) apply first; a point's values are applied in the
    worker. `hil.sweep.checks.checked_plan` sizes the plan before listing it and checks every
    point's configuration once: what `run_sweep` runs."""
    spec = resolved(spec, base)
    for key, value in spec.base.items():
        section, _, option = key.partition(".")
        base = base.changed(section, option=f"[base] {key}", **{option: value})
    record = base.record()
    tasks = []
    for values in spec.points():
        point_id = _digest(values, 10)
        for experiment in spec.experiments:
            for controller in spec.controllers:
                identity = {
                    "values": values, "experiment": experiment, "controller": controller,
                    "setup": spec.setup, "model": spec.model, "seed": spec.seed,
                    "duration_s": spec.duration_s, "base": spec.base,
                    "targets": {p.name: p.targets for p in spec.parameters},
                }  # fmt: skip
                tasks.append(
                    Task(
                        run_id=_digest(identity, 16),
                        point_id=point_id,
                        values=values,
                        targets=targets_of(spec, values),
                        experiment=experiment,
                        controller=controller,
                        config_record=record,
                        model=spec.model,
                        setup=spec.setup,
                        seed=spec.seed,
                        duration_s=spec.duration_s,
                        keep_log=spec.keep_logs,
                    )
                )
    return tasks


def targets_of(spec: SweepSpec, values: dict[str, Value]) -> dict[str, Value]:
    """A point's values by configuration target."""
    return {target: values[p.name] for p in spec.parameters for target in p.targets}


__all__ = ["config_at", "configured_value", "plan", "resolved", "targets_of"]

"""A sweep's plan (the spec is hil/sweep/spec.py): the configuration at each point, and the
list of runs - one per (point, experiment, controller), each with an id hashed from the run as
it will be run (`run_identity`: the sweep's identity - the base configuration's content, the
spec's settings for every run, the code's versions; hil/sweep/identity.py - the experiment, the
controller with its reading of (25) resolved, and the configuration keys the point sets, less
those this controller does not read), so that rerunning the same sweep finds the runs already
done, a run of another configuration never passes for one of them, and two (point, controller)
pairs that are one run share one id and are run once (a composition grid: a controller that
names its reading runs the same at every composition; dob_integral_time_s counts only for the
"accumulated-integral" reading; a Monte Carlo draw repeated)."""

from __future__ import annotations

import dataclasses
from typing import Any

from hil.config import Config
from hil.sweep.identity import SweepIdentity, digest, sweep_identity
from hil.sweep.ranges import SpecError, check_range
from hil.sweep.spec import ModelFollows, SweepSpec, Task, Value, parse_controller
from hil.wiring.emulation import plant_servo_noise

COMPOSITION = "controller.composition"
INTEGRAL_TIME = "controller.dob_integral_time_s"
BOUNDED_READING = "accumulated-integral"  # the reading that reads dob_integral_time_s


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


def with_base(spec: SweepSpec, config: Config) -> Config:
    """The configuration with the spec's [base] changes applied (each validated)."""
    for key, value in spec.base.items():
        section, _, option = key.partition(".")
        config = config.changed(section, option=f"[base] {key}", **{option: value})
    return config


def identity_of(spec: SweepSpec, base: Config) -> SweepIdentity:
    """The identity of this sweep (hil/sweep/identity.py) on this base configuration."""
    return sweep_identity(resolved(spec, base), with_base(spec, base))


def plan(spec: SweepSpec, base: Config) -> list[Task]:
    """Every run of the sweep, in order: per point, per experiment, per controller.

    The base configuration's changes ([base]) apply first; a point's values are applied in the
    worker. `hil.sweep.checks.checked_plan` sizes the plan before listing it and checks every
    point's configuration once: what `run_sweep` runs."""
    spec = resolved(spec, base)
    base = with_base(spec, base)
    sweep = sweep_identity(spec, base).digest
    record = base.record()
    tasks = []
    for values in spec.points():
        point_id = digest(values, 10)
        targets = targets_of(spec, values)
        for experiment in spec.experiments:
            for controller in spec.controllers:
                identity = run_identity(sweep, experiment, controller, targets, base)
                tasks.append(
                    Task(
                        run_id=digest(identity, 16),
                        point_id=point_id,
                        values=values,
                        targets=targets,
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


def run_identity(
    sweep: str, experiment: str, controller: str, targets: dict[str, Value], base: Config
) -> dict[str, Any]:
    """What one run is (module docstring): two tasks with the same identity run the same.
    `base` has [base] applied; `sweep` is the sweep's identity's digest."""
    choice = parse_controller(controller)
    composition = targets.get(COMPOSITION, base.controller.composition)
    # only the LQR's composition (25) has a reading; pid and gc do not read it
    reading = (choice.reading or str(composition)) if choice.kind.has_lqr else None
    read = {
        target: value
        for target, value in targets.items()
        if target != COMPOSITION and (target != INTEGRAL_TIME or reading == BOUNDED_READING)
    }
    return {
        "sweep": sweep,
        "experiment": experiment,
        "controller": {"kind": str(choice.kind), "kdist": choice.kdist, "reading": reading},
        "targets": read,
    }


def distinct_runs(tasks: list[Task]) -> list[Task]:
    """The first task of each run id, in order: each run once."""
    first: dict[str, Task] = {}
    for task in tasks:
        first.setdefault(task.run_id, task)
    return list(first.values())


def targets_of(spec: SweepSpec, values: dict[str, Value]) -> dict[str, Value]:
    """A point's values by configuration target."""
    return {target: values[p.name] for p in spec.parameters for target in p.targets}


__all__ = [
    "config_at",
    "configured_value",
    "distinct_runs",
    "identity_of",
    "plan",
    "resolved",
    "run_identity",
    "targets_of",
    "with_base",
]

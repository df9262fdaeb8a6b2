"""Every figure of the configuration has a physical range, judged when the file is read (issue
25: absurd but finite figures were acted on: `gravity_moment_kg_m = 1e300` drove the link into
the block at 172.7 N, `bus_error_ticks = 1e9` and `max_goal_rate_rad_s = 1e300` switched their
watches off, `q_error = 1e300` failed only after the emulator started).

Systematic: every number the schema declares is walked (hil.config.ranges.figures), an absurdly
large and (where the figure must be positive) an absurdly small value is refused naming the key
and its range; the few that the schema leaves to the drivers or to a check across sections are
refused there. The ranges admit every real value: the built-in configurations, every point of
the shipped sweeps (robustness at +-30 %, the ringing grid's loads) with its controller designs.
"""

from __future__ import annotations

import dataclasses
import re
import typing
from typing import Any

import pytest

from hil.cli.design import check_designs
from hil.config import ConfigError, config_from_record, load_config
from hil.config.emulator_overrides import RANGES
from hil.config.ranges import figures
from hil.config.schema import ConfigFile
from hil.robots import get_experiment
from hil.sweep import load_spec
from hil.sweep.checks import checked_plan
from hil.sweep.plan import config_at
from hil.sweep.spec import shipped_specs
from hil.wiring import check_devices
from sim_backend.humanoid.params import ContactParams, RobotTruthParams
from sim_backend.plant import TestbedPlantParams as PlantParams
from sim_backend.servo import H54ServoParams
from sim_backend.spec import SensorNoise

TESTBED = load_config()
HUMANOID = load_config(robot="dyros-jet")
# Numbers the schema leaves unbounded, and who bounds them (each checked below).
JUDGED_ELSEWHERE = {
    "dynamixel.baudrate": "the model's Baud Rate item (drivers)",
    "joint.dynamixel_id": "0..252 (drivers)",
    "joint.encoder_node_id": "1..127 (drivers)",
    "joint.encoder_offset_rad": "the encoder's INTEGER32 reach (hil.wiring.checks)",
    "joint.motor_offset_rad": "the H54's position-mode range (drivers)",
    "joint.min_angle_rad": "the H54's position-mode range (drivers)",
    "joint.max_angle_rad": "the H54's position-mode range (drivers)",
    "joint.torque_limit_a": "the H54's Torque Limit range (drivers)",
    "safety.zero_offset_margin_rad": "at most max_deflection_rad",
    "controller.dob_cutoff_hz": "below the Nyquist frequency of [loop] rate_hz",
}
HUGE = {float: 1e300, int: 2**70}
# The drivers name a device figure by their own word for it.
DRIVERS_WORD = {
    "dynamixel_id": "dxl_id",
    "encoder_node_id": "node_id",
    "motor_offset_rad": "offset",
    "min_angle_rad": "position range",
    "max_angle_rad": "position range",
}


def _record_with(base: Any, key: str, value: Any) -> dict[str, Any]:
    """The configuration's record with one dotted key set (a list section: its first table;
    [model.joint]: the first joint's overrides)."""
    record = base.record()
    section, *rest = key.split(".")
    table = record["joint" if section == "joint" else section]
    if isinstance(table, list):
        table = table[0]
    if section == "model" and rest[0] == "joint":
        table = table["joint"].setdefault(base.joint_names[0], {})
        rest = rest[1:]
    if isinstance(table.get(rest[0]), list):  # a vector: its first element
        value = [value, *table[rest[0]][1:]]
    table[rest[0]] = value
    return record


def _sample_for(key: str) -> Any:
    return HUMANOID if key.startswith("force_torque_sensor") else TESTBED


def _refused(key: str, value: Any) -> str:
    base = _sample_for(key)
    with pytest.raises(ConfigError) as caught:
        config = config_from_record(_record_with(base, key, value))
        check_devices(config)
    return str(caught.value)


NUMBERS = [(key, kind, allowed) for key, kind, allowed in figures(ConfigFile)]


def test_every_number_has_a_range_or_a_named_judge() -> None:
    unbounded = {key for key, _, allowed in NUMBERS if allowed.low is None or allowed.high is None}
    assert unbounded == set(JUDGED_ELSEWHERE), sorted(unbounded ^ set(JUDGED_ELSEWHERE))


@pytest.mark.parametrize("key", [key for key, _, _ in NUMBERS])
def test_an_absurdly_large_figure_is_refused_naming_the_key(key: str) -> None:
    kind = next(k for name, k, _ in NUMBERS if name == key)
    message = _refused(key, HUGE[kind])
    name = key.split(".")[-1]
    assert name in message or DRIVERS_WORD.get(name, name) in message, message


@pytest.mark.parametrize(
    "key",
    [key for key, kind, allowed in NUMBERS if kind is float and allowed.low and allowed.low > 0],
)
def test_an_absurdly_small_positive_figure_is_refused_with_its_range(key: str) -> None:
    message = _refused(key, 1e-300)
    assert key.split(".")[-1] in message and "physical range is [" in message, message


@pytest.mark.parametrize(
    ("section", "key", "value"),
    [
        ("model", "gravity_moment_kg_m", 1e300),
        ("safety", "max_goal_rate_rad_s", 1e300),
        ("safety", "bus_error_ticks", 10**9),
        ("controller", "q_error", 1e300),
        ("controller", "r_input", 1e-300),
        ("model", "link_inertia_kg_m2", 1e-300),
        ("model", "stiffness_nm_per_rad", 1e-300),
    ],
)
def test_the_issues_figures_are_refused_at_load(section: str, key: str, value: float) -> None:
    with pytest.raises(ConfigError, match=rf"\[{section}\] {key}: .*physical range is"):
        TESTBED.changed(section, **{key: value})


def test_a_watch_cannot_be_switched_off_by_its_count_outgrowing_its_window() -> None:
    with pytest.raises(ConfigError, match="overrun_limit .* must be below the ticks"):
        TESTBED.changed("safety", overrun_limit=200)  # 1 s at 200 Hz holds 200 ticks
    with pytest.raises(ConfigError, match="bus_read_timeout_ms .* below the period"):
        TESTBED.changed("loop", bus_read_timeout_ms=5.0)


# --- the emulated robot's truth ([emulator] plant / servo / sensor_noise) --------------------
PARTS = {
    "plant": (PlantParams, RobotTruthParams),
    "servo": (H54ServoParams,),
    "sensor_noise": (SensorNoise,),
}
WORDS_AND_STRUCTURES = {
    "obstacle",
    "servo",
    "contact",
    "com_offset_link",
    "friction_cone",
    "gearbox_friction_model",
}


def _numbers_of(cls: type) -> list[str]:
    names = []
    hints = typing.get_type_hints(cls)
    for field in dataclasses.fields(cls):
        if field.name in WORDS_AND_STRUCTURES:
            continue
        names.append(field.name)
    assert all(name in hints for name in names)
    return names


@pytest.mark.parametrize("part", sorted(PARTS))
def test_every_emulated_figure_has_a_range_that_holds_its_default(part: str) -> None:
    ranges = RANGES[part]
    for cls in PARTS[part]:
        default = cls()
        for name in _numbers_of(cls):
            assert name in ranges, f"[emulator] {part}.{name} has no range"
            low, high, _ = ranges[name]
            value = getattr(default, name)
            values = (
                value.values()
                if isinstance(value, dict)
                else (value if isinstance(value, tuple) else (value,))
            )
            # (None: the humanoid's per-joint servo figures default to the servo's own)
            assert all(low <= float(v) <= high for v in values if v is not None), (name, value)
    if part == "plant":
        contact = ContactParams()
        for name in ("friction", "time_constant_s", "damping_ratio", "friction_impedance_ratio"):
            low, high, _ = ranges[f"contact.{name}"]
            assert low <= getattr(contact, name) <= high


@pytest.mark.parametrize(
    ("part", "values", "where"),
    [
        ("plant", {"gear_stiffness_nm_per_rad": 1e300}, "plant.gear_stiffness_nm_per_rad"),
        ("plant", {"load_mass_kg": 1e9}, "plant.load_mass_kg"),
        ("plant", {"gear_damping_nms_per_rad": [100.0] * 11 + [1e300]}, r"\[11\]"),
        ("plant", {"contact": {"friction": 1e300}}, "plant.contact.friction"),
        ("servo", {"overload_trip_time_s": 1e300}, "servo.overload_trip_time_s"),
        ("servo", {"position_gain_per_s": 1e-300}, "servo.position_gain_per_s"),
        ("sensor_noise", {"link_encoder_counts_rms": 1e300}, "link_encoder_counts_rms"),
    ],
)
def test_an_absurd_emulated_figure_is_refused_naming_it(
    part: str, values: dict[str, Any], where: str
) -> None:
    with pytest.raises(ConfigError, match=where):
        TESTBED.changed("emulator", **{part: values})


# --- the ranges admit every real value -------------------------------------------------------
def test_the_built_in_configurations_are_within_their_ranges() -> None:
    for config in (TESTBED, HUMANOID):
        check_devices(config)
        for key, _, allowed in NUMBERS:
            section, *rest = key.split(".")
            if section in ("joint", "dynamixel", "can", "force_torque_sensor"):
                continue  # tables: checked by loading them
            value: Any = config
            for part in [section, *rest]:
                value = getattr(value, part, None) if not isinstance(value, dict) else None
            if isinstance(value, int | float) and None not in (allowed.low, allowed.high):
                assert allowed.low <= value <= allowed.high, key


@pytest.mark.parametrize("name", sorted(shipped_specs()))
def test_every_point_of_every_shipped_sweep_is_within_the_ranges_and_has_its_design(
    name: str,
) -> None:
    spec = load_spec(name)
    tasks = checked_plan(spec, TESTBED)  # every point's configuration, checked
    planned = config_from_record(tasks[0].config_record)
    seen: set[tuple[str, str, str]] = set()
    for task in tasks:
        if (task.point_id, task.experiment, task.controller) in seen:
            continue
        seen.add((task.point_id, task.experiment, task.controller))
        config = config_at(planned, task.targets, task.model)
        check_designs(config, [(get_experiment(task.experiment), task.choice)])


def test_a_design_that_does_not_exist_within_the_ranges_is_a_configuration_error() -> None:
    """Each figure within its range, the corner together has no LQR: said with its keys."""
    config = TESTBED.changed(
        "model", stiffness_nm_per_rad=100.0, link_inertia_kg_m2=1e-3, servo_gain_per_s=0.1
    ).changed("controller", q_error=1e-6, r_input=1e6, q_state=0.0)
    with pytest.raises(ConfigError, match=r"has no design .*q_error, q_state, r_input") as caught:
        check_designs(config, [(get_experiment("impact"), _choice("gc+lqr+dob"))])
    assert re.search(r"LinAlgError|Riccati", str(caught.value))


def _choice(name: str):
    from hil.vocabulary import ControllerChoice

    return ControllerChoice(name, 1.0)

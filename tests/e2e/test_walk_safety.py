"""The humanoid's safety reaction must not make it fall (issue 25).

Before: `hil run walk-slow --controller pid` with the default configuration was backed off at
14.40 s by the software current guard (80 % of the limit for 0.6 s, while the actuator's own
overload timer stood at 0.55 s of its 1.5 s) and fell; with the guard off, as the comparison
runs it, the same walk completed 4/4. Now the guard mirrors the actuator's protection and acts
0.8 s before it (hil/safety/overload.py), and on a robot on its feet a `back_off` is done as
`finish_step`: the walk goes on to a double support that shares the weight, then holds
(hil/experiments/legs.py `on_feet`). Here:

    - the default walk through the emulated buses: completes, the guard's record in summary.json
    - the guard made to act early (a margin of 1.3 s: at 0.2 s of the actuator's timer, in the
      stance of 13.75-14.65 s on the left foot): the run ends standing - both feet loaded, the
      pelvis up and level, from the robot's own sensors in the log; and, on the in-process
      emulator, from the emulated robot's own pelvis (MuJoCo), for walk-slow and walk-dynamic
"""

from __future__ import annotations

import contextlib
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from hil.cli import main
from hil.config import default_config_text, load_config
from hil.experiments.legs import leg_model, pelvis_rotation
from hil.robots import get_experiment
from hil.wiring.in_process import InProcessJointBus, in_process_bus
from tests.support.rig import assert_log_complete, load_run, run_in_process

pytestmark = [pytest.mark.faults, pytest.mark.timeout(300)]

MARGIN_LINE = "current_guard_margin_s = 0.8"
STANDING_TILT_RAD = 0.1  # the walk itself tilts the pelvis up to 0.19 rad; standing, < 0.01
STANDING_DROP_M = 0.05  # below its height at the start (0.87 m): a fall ends near the floor


def _run_cli(args: list[str], out: Path) -> tuple[int, dict, object]:
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        code = main(["run", *args, "--json", "--no-plots", "--no-mcap", "--out", str(out)])
    metrics = json.loads(text.getvalue().strip().splitlines()[-1])
    (run_dir,) = out.iterdir()
    return code, metrics, load_run(run_dir, code)


def test_walk_slow_with_pid_and_the_default_configuration_completes(tmp_path: Path) -> None:
    code, metrics, run = _run_cli(["walk-slow", "--controller", "pid"], tmp_path)
    assert run.summary["termination"] == "completed" and code == 0
    assert metrics["steps_completed"] == 4 and metrics["fell"] is False
    assert run.trips() == []
    assert_log_complete(run)
    guard = run.summary["safety_counters"]["current_guard"]
    assert guard["on"] is True and guard["rule"] == "protection" and guard["margin_s"] == 0.8
    assert list(guard["fires_at_s"].values()) == pytest.approx([1.5 - 0.8] * 12)
    # the stance on the left foot (13.75-14.65 s) ran the knee's timer, not to the guard's time
    peak = guard["peak_timer_s"]
    assert 0.4 < peak["L_KneePitch"] < 0.7
    assert max(v for k, v in peak.items() if k != "L_KneePitch") < 0.4


def _early_guard_config(tmp_path: Path) -> Path:
    text = default_config_text("dyros-jet")
    assert text.count(MARGIN_LINE) == 1
    path = tmp_path / "early_guard.toml"
    path.write_text(text.replace(MARGIN_LINE, "current_guard_margin_s = 1.3"))
    return path


def test_a_guard_that_acts_mid_walk_leaves_the_robot_standing(tmp_path: Path) -> None:
    config = _early_guard_config(tmp_path)
    out = tmp_path / "runs"
    code, metrics, run = _run_cli(
        ["walk-slow", "--controller", "pid", "--config", str(config), "--emulate"], out
    )
    assert run.summary["termination"] == "safety stop: current (finish_step)" and code == 1
    trip, held = (e for e in run.trips() if e["cause"] == "current")
    assert (trip["joint"], trip["action"]) == ("L_KneePitch", "finish_step")
    assert "on_current = back_off: on this robot done as finish_step" in trip["message"]
    assert (held["action"], held["state"]) == ("hold", "hold")
    assert "both feet carry the robot" in held["message"]
    assert 13.75 < trip["time_s"] < held["time_s"] < 15.0
    # events.jsonl says the same, with the reaction and the state it led to
    logged = [(e["action"], e["state"]) for e in run.events_of("current")]
    assert logged == [("finish_step", "finish_step"), ("hold", "hold")]
    assert metrics["fell"] is False
    columns = run.columns
    assert (columns["supervisor_state"][-200:] == "hold").all()
    assert not np.any(np.column_stack(run.data.per_joint("actuator_fault"))), "the actuator tripped"
    # standing at the end, as the robot's own sensors say: both feet carry it, pelvis up, level
    weight = leg_model().total_mass_kg * 9.81
    last = slice(-100, None)  # the last 0.5 s
    left, right = columns["left_foot_fz_n"][last], columns["right_foot_fz_n"][last]
    assert np.all(np.minimum(left, right) > 0.2 * (left + right))
    assert np.all(np.abs(left + right - weight) < 0.1 * weight)
    links = np.column_stack(run.data.per_joint("link_angle_rad"))
    start, end = (leg_model().standing_configuration(links[k], side=0) for k in (0, -1))
    assert start[2] - end[2] < STANDING_DROP_M
    assert math.acos(pelvis_rotation(end)[2, 2]) < STANDING_TILT_RAD


class _TruthBus(InProcessJointBus):
    """The in-process bus, keeping the emulated robot's own pelvis and overload timers."""

    def read(self):  # type: ignore[no-untyped-def]
        sample = super().read()
        assert self.testbed is not None
        robot = self.testbed.robot.robot
        self.pelvis.append((robot.plant.pelvis_position_m[2], robot.plant.pelvis_tilt_rad))
        self.timers.append(robot.bank.overload_timer_s.max())
        return sample


@pytest.mark.parametrize(
    ("experiment", "safety"),
    [
        ("walk-slow", {"current_guard_margin_s": 1.3}),
        # the fixed rule at 60 % of the limit for 0.05 s: it acts in walk-dynamic's first step,
        # where a back-off made the robot fall 2 s later
        (
            "walk-dynamic",
            {
                "current_guard_margin_s": None,
                "current_guard_fraction": 0.6,
                "current_guard_time_s": 0.05,
            },
        ),
    ],
)
def test_after_the_reaction_the_emulated_robot_stands(
    tmp_path: Path, experiment: str, safety: dict
) -> None:
    config = load_config(robot="dyros-jet").changed("safety", **safety)
    walk = get_experiment(experiment)
    bus = _TruthBus(config, in_process_bus(config, walk).spec)
    bus.pelvis, bus.timers = [], []
    result, run = run_in_process(config, walk, "pid", tmp_path / "run", bus=bus)
    assert result.ending.text == "safety stop: current (finish_step)"
    actions = [e.action for e in result.safety_events if e.cause == "current"]
    assert actions[0] == "finish_step" and actions[-1] == "hold"
    pelvis = np.array(bus.pelvis)
    height, tilt = pelvis[:, 0], pelvis[:, 1]
    assert height.min() > height[0] - STANDING_DROP_M
    assert tilt[-200:].max() < STANDING_TILT_RAD
    assert max(bus.timers) < 1.5  # the actuators' own protection never tripped
    left, right = run.columns["left_foot_fz_n"][-1], run.columns["right_foot_fz_n"][-1]
    assert min(left, right) > 0.1 * (left + right)  # both feet on the ground

"""The `finish_step` reaction and an experiment's `ReactionPolicy`, tick by tick on hand-made
samples (no bus): the controller's goals go through until the policy's rest, then the
supervisor holds; the humanoid's rest (both feet carry the robot) and its policy."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.joint_bus import JointSample, add_wrench
from hil.config import ConfigError, load_config
from hil.experiments.legs import REST_TICKS, FeetCarryTheRobot
from hil.robots import get_experiment
from hil.safety import SafeState, Supervisor
from hil.vocabulary import Reaction, ReactionPolicy, RestCondition
from tests.support.one_joint import one_joint_supervisor

CONFIG = load_config()
PERIOD_S = CONFIG.loop.period_s
LIMIT_A = 10.0
WEIGHT_N = 490.0


class _RestAfter(RestCondition):
    """At rest from tick `at` on (counts the ticks it is asked)."""

    def __init__(self, at: int | None) -> None:
        self.at = at
        self.asked = 0

    def reached(self, sample: JointSample) -> str | None:
        self.asked += 1
        return "the test's rest" if self.at is not None and self.asked > self.at else None

    def describe(self) -> str:
        return "the test's condition"


def _supervisor(policy: ReactionPolicy | None = None, **safety: object) -> Supervisor:
    supervisor = one_joint_supervisor(CONFIG.changed("safety", **safety).safety, PERIOD_S, LIMIT_A)
    if policy is not None:
        supervisor.set_reaction_policy(policy)
    return supervisor


def _sample(motor: float = 0.0, current: float = 0.0) -> JointSample:
    sample = JointSample.empty(1)
    sample.motor_angle_rad[:] = sample.link_angle_rad[:] = motor
    sample.motor_velocity_rad_s[:] = 0.0
    sample.motor_current_a[:] = current
    sample.motor_valid[:] = sample.link_valid[:] = sample.torque_enabled[:] = True
    return sample


def _tick(supervisor: Supervisor, k: int, sample: JointSample, goal: float) -> float | None:
    supervisor.observe(k, k * PERIOD_S, sample)
    sent = supervisor.command(np.array([goal]), sample)
    return None if sent is None else float(sent[0])


def _deflect(supervisor: Supervisor, k: int = 0) -> None:
    """A deflection beyond the bound on tick k (its configured reaction follows)."""
    sample = _sample(0.0)
    sample.link_angle_rad[:] = 0.1
    _tick(supervisor, k, sample, 0.0)


def test_finish_step_lets_the_controller_on_until_the_rest_then_holds() -> None:
    rest = _RestAfter(at=30)
    supervisor = _supervisor(ReactionPolicy(rest=rest, within_s=1.0), on_deflection="finish_step")
    _deflect(supervisor)
    assert supervisor.state == SafeState.FINISH_STEP and supervisor.controller_steps
    sent = [_tick(supervisor, k, _sample(0.001 * k), 0.001 * k) for k in range(1, 40)]
    held_from = sent.index(sent[-1])
    assert sent[:held_from] == pytest.approx([0.001 * k for k in range(1, held_from + 1)])
    assert held_from == 29  # the rest came on tick 30: from then on the motor's angle, held
    assert sent[held_from:] == pytest.approx([0.030] * (len(sent) - held_from))
    assert supervisor.state == SafeState.HOLD and not supervisor.controller_steps
    trip, done = supervisor.events
    assert (trip.cause, trip.action, trip.state) == ("deflection", "finish_step", "finish_step")
    assert "until the test's condition" in trip.message
    assert (done.cause, done.action, done.state, done.tick) == ("deflection", "hold", "hold", 30)
    assert "the step is finished (the test's rest): holding" in done.message


def test_finish_step_holds_where_it_is_when_no_rest_comes_in_time() -> None:
    supervisor = _supervisor(
        ReactionPolicy(rest=_RestAfter(at=None), within_s=0.1), on_deflection="finish_step"
    )
    _deflect(supervisor)
    for k in range(1, 40):
        _tick(supervisor, k, _sample(0.001 * k), 0.001 * k)
        # 0.1 s: 20 ticks, the trip's own (tick 0) the first
        assert supervisor.state == (SafeState.FINISH_STEP if k < 19 else SafeState.HOLD), k
    assert "no rest (the test's condition) within 0.1 s" in supervisor.events[-1].message


def test_without_a_rest_finish_step_holds_at_once() -> None:
    supervisor = _supervisor(on_deflection="finish_step")  # the default policy: no rest
    _deflect(supervisor)
    assert supervisor.state == SafeState.HOLD
    assert _tick(supervisor, 1, _sample(0.01), 0.5) == pytest.approx(0.0)


def test_a_policy_does_a_reaction_as_another_and_the_event_says_both() -> None:
    policy = ReactionPolicy({Reaction.BACK_OFF: Reaction.FINISH_STEP}, _RestAfter(5), 1.0)
    supervisor = _supervisor(policy, current_guard_time_s=0.01)
    for k in range(3):
        _tick(supervisor, k, _sample(0.0, current=LIMIT_A), 0.0)
    event = supervisor.events[0]
    assert (event.cause, event.action) == ("current", "finish_step")
    assert "(on_current = back_off: on this robot done as finish_step)" in event.message
    assert _tick(supervisor, 3, _sample(0.0, current=LIMIT_A), 0.02) == pytest.approx(0.01)
    # a more severe cause still escalates: torque off is never done as anything else
    sample = _sample(0.0)
    sample.torque_enabled[:] = False
    assert _tick(supervisor, 4, sample, 0.0) is None
    assert supervisor.state == SafeState.TORQUE_OFF
    with pytest.raises(ValueError, match="torque_off is done as configured"):
        ReactionPolicy({Reaction.TORQUE_OFF: Reaction.HOLD})


def test_finish_step_is_no_exit_state() -> None:
    with pytest.raises(ConfigError, match="on_exit"):
        CONFIG.changed("safety", on_exit="finish_step")


def _feet(left_n: float, right_n: float) -> JointSample:
    sample = _sample()
    for foot, fz in (("left_foot", left_n), ("right_foot", right_n)):
        add_wrench(sample.extra, foot, np.array([0.0, 0.0, fz]), np.zeros(3))
    return sample


def test_the_feets_rest_is_the_weight_shared_for_a_while() -> None:
    rest = FeetCarryTheRobot(WEIGHT_N)
    # the pid walk-slow's rocking touchdown (log.csv, 13.40-13.55 s): shared only briefly
    for left, right in ((217, 426), (95, 364), (100, 409), (0, 351)):
        assert rest.reached(_feet(left, right)) is None
    assert rest.reached(_feet(np.nan, 250)) is None  # a sensor not read
    assert all(rest.reached(_feet(240, 250)) is None for _ in range(REST_TICKS - 1))
    assert rest.reached(_feet(240, 250)) == (
        "both feet carry the robot: left 240 N (49%), right 250 N (51%) for 10 ticks"
    )
    assert rest.reached(_feet(60, 40)) is None  # too little of the weight: not standing on them


def test_the_humanoids_experiments_do_back_off_as_finish_step() -> None:
    for name in ("walk-slow", "walk-dynamic", "step-on-object", "stand", "push"):
        policy = get_experiment(name).reaction_policy()
        assert policy.done_as(Reaction.BACK_OFF) is Reaction.FINISH_STEP, name
        assert policy.done_as(Reaction.HOLD) is Reaction.HOLD, name
        assert isinstance(policy.rest, FeetCarryTheRobot), name
    assert get_experiment("walk-slow").reaction_policy().within_s == pytest.approx(0.8 + 3.2)
    testbed = get_experiment("contact").reaction_policy()
    assert testbed.done_as(Reaction.BACK_OFF) is Reaction.BACK_OFF and testbed.rest is None

"""The supervisor's rules, tick by tick, on hand-made samples (no bus): each watch fires on the
documented tick and not before, each safe state commands what docs/safety.md says; and the slow
re-homing plan (hil/loop/homing.py) against its analytic figures."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from drivers.dynamixel import HardwareError, actuator_fault
from drivers.joint_bus import BusFault, DeviceRole, JointDevices, JointSample
from hil.config import ConfigError, load_config
from hil.loop import plan_homing
from hil.safety import SafeState, Supervisor

CONFIG = load_config()
DEVICES = (JointDevices("actuator 1", "link encoder node 5"),)
PERIOD_S = CONFIG.loop.period_s
LIMIT_A = 10.0
COUNT_RAD = 2 * math.pi / 983_040  # one link-encoder count
MOTOR_PULSE_RAD = 2 * math.pi / 501_923  # one H54 motor-encoder pulse


def _supervisor(**safety: object) -> Supervisor:
    config = CONFIG.changed("safety", **safety).safety
    joint = CONFIG.joints[0]
    supervisor = Supervisor(
        config,
        CONFIG.joint_names,
        DEVICES,
        np.array([joint.min_angle_rad]),
        np.array([joint.max_angle_rad]),
        PERIOD_S,
        np.array([CONFIG.model.stiffness_nm_per_rad]),
    )
    supervisor.set_current_limits(np.array([LIMIT_A]))
    supervisor.torque_enabled(np.array([0.0]))
    return supervisor


def _sample(
    motor: float = 0.0,
    link: float | None = None,
    *,
    current: float = 0.0,
    hardware_error: int = 0,
    torque: bool = True,
    motor_valid: bool = True,
    link_valid: bool = True,
) -> JointSample:
    link = motor if link is None else link
    return JointSample(
        timestamp_s=0.0,
        motor_angle_rad=np.array([motor if motor_valid else np.nan]),
        link_angle_rad=np.array([link if link_valid else np.nan]),
        motor_velocity_rad_s=np.zeros(1),
        motor_current_a=np.array([current if motor_valid else np.nan]),
        actuator_fault=np.array([actuator_fault(hardware_error)], dtype=np.uint8),
        fault_code=np.array([hardware_error]),
        torque_enabled=np.array([torque and motor_valid]),
        motor_valid=np.array([motor_valid]),
        link_valid=np.array([link_valid]),
        link_age_s=np.zeros(1),
        bus_errors=[]
        if motor_valid
        else [BusFault(0, DeviceRole.ACTUATOR, "actuator 1", "no valid sync-read reply (timeout)")],
    )


def _tick(supervisor: Supervisor, k: int, sample: JointSample, goal: float | None = None):
    supervisor.observe(k, k * PERIOD_S, sample)
    return supervisor.command(None if goal is None else np.array([goal]), sample)


# --- command limits -----------------------------------------------------------------------


def test_goals_are_clipped_to_the_joint_limits_and_rate_limited() -> None:
    # no goal_saturated here: 1000 clipped ticks are half of its longest window
    supervisor = _supervisor(goal_saturation_window_ticks=2000, goal_saturation_fraction=1.0)
    step = CONFIG.safety.max_goal_rate_rad_s * PERIOD_S
    goals = [float(_tick(supervisor, k, _sample(), 5.0)[0]) for k in range(1000)]
    assert np.allclose(np.diff([0.0, *goals]), np.minimum(step, np.diff([0.0, *goals])))
    assert goals[0] == pytest.approx(step)  # at most 2 rad/s x 5 ms from the last goal
    assert max(goals) == CONFIG.joints[0].max_angle_rad  # never beyond the limit
    assert supervisor.state == SafeState.RUN
    assert supervisor.counters()["goals_clipped_at_limit"]["testbed"] == 1000
    assert len([n for n in supervisor.notices if n.kind == "goal_limited"]) == 20  # then counted


def test_a_non_finite_goal_is_never_sent_the_joint_holds() -> None:
    supervisor = _supervisor()
    assert _tick(supervisor, 0, _sample(0.01), 0.01)[0] == pytest.approx(0.01)
    goal = _tick(supervisor, 1, _sample(0.012), math.nan)
    assert goal[0] == pytest.approx(0.012)  # hold where the motor is
    assert supervisor.state == SafeState.HOLD
    assert supervisor.events[-1].cause == "command_invalid"
    assert _tick(supervisor, 2, _sample(0.013), 0.5)[0] == pytest.approx(0.012)


def test_a_reference_beyond_the_limits_is_refused_before_anything_moves() -> None:
    with pytest.raises(ValueError, match="beyond joint 'testbed'"):
        _supervisor().check_reference(np.array([-0.9]), np.array([0.0]))
    _supervisor().check_reference(np.array([-0.8]), np.array([0.8]))


# --- the actuator's own protection --------------------------------------------------------


def test_a_hardware_error_trips_on_its_tick_decoded_and_stops_commanding() -> None:
    supervisor = _supervisor()
    for k in range(10):
        assert _tick(supervisor, k, _sample(), 0.0) is not None
    bits = HardwareError.OVERLOAD | HardwareError.OVERHEATING
    goal = _tick(supervisor, 10, _sample(hardware_error=bits, torque=False), 0.0)
    assert goal is None
    (event,) = supervisor.events
    assert (event.tick, event.cause, event.joint, event.action) == (
        10,
        "hardware_error",
        "testbed",
        "torque_off",
    )
    assert "OVERLOAD|OVERHEATING (device code 0x24)" in event.message
    _tick(supervisor, 11, _sample(hardware_error=bits, torque=False))
    assert len(supervisor.events) == 1  # reported once
    _tick(supervisor, 12, _sample(hardware_error=bits | HardwareError.INPUT_VOLTAGE, torque=False))
    assert len(supervisor.events) == 2  # a new bit is news
    assert supervisor.state == SafeState.TORQUE_OFF


def test_torque_found_off_without_an_error_is_caught() -> None:
    supervisor = _supervisor()
    _tick(supervisor, 0, _sample(torque=False))
    assert supervisor.events[0].cause == "torque_lost"
    supervisor = _supervisor()
    supervisor.torque_disabled()  # the loop turned it off itself
    _tick(supervisor, 0, _sample(torque=False))
    assert supervisor.events == []


# --- bus and encoders -----------------------------------------------------------------------


def test_bus_errors_are_tolerated_below_bus_error_ticks_and_trip_on_the_nth() -> None:
    n = CONFIG.safety.bus_error_ticks
    supervisor = _supervisor()
    k = 0
    for streak in range(1, n):  # streaks shorter than n: tolerated, noted, last goal repeated
        for _ in range(streak):
            assert _tick(supervisor, k, _sample(motor_valid=False))[0] == 0.0
            k += 1
        _tick(supervisor, k, _sample())
        k += 1
    assert supervisor.state == SafeState.RUN
    assert [n.kind for n in supervisor.notices] == ["bus_glitch"] * (n - 1)
    for j in range(n):
        goal = _tick(supervisor, k + j, _sample(motor_valid=False))
    assert supervisor.events[0].tick == k + n - 1 and supervisor.events[0].cause == "bus_error"
    assert goal is None  # on_bus_error = torque_off


def test_a_dead_encoder_trips_on_the_link_stale_ticks_th_tick() -> None:
    n = CONFIG.safety.link_stale_ticks
    supervisor = _supervisor()
    _tick(supervisor, 0, _sample(0.1, 0.1))
    for k in range(1, n + 1):
        goal = _tick(supervisor, k, _sample(0.1 + 0.001 * k, link_valid=False))
    assert supervisor.events[0].cause == "link_stale" and supervisor.events[0].tick == n
    assert goal[0] == pytest.approx(0.1 + 0.001 * n)  # hold where the motor is


def test_a_frozen_encoder_trips_only_once_the_motor_moved_beyond_any_windup() -> None:
    # an obstacle: the link stops, the motor winds the gear up to the torque limit
    # (48 N m / K = 0.024 rad) and stays there - not a stale sensor
    supervisor = _supervisor()
    windup = np.minimum(np.arange(400) * 0.0005, 0.024)
    for k, w in enumerate(windup):
        _tick(supervisor, k, _sample(-0.2 - w, -0.2))
    assert supervisor.events == []
    # a hung counter: the motor keeps going at 1 mrad per tick; the link repeats its reading
    # from tick 1 (motor at -0.001) and the watch fires once the motor moved more than
    # 0.03 rad from there: at -0.032, tick 32
    supervisor = _supervisor()
    for k in range(200):
        _tick(supervisor, k, _sample(-0.001 * k, 0.0))
        if supervisor.events:
            break
    assert supervisor.events[0].cause == "link_stale" and supervisor.events[0].tick == 32


def _second_difference_noise_trip(
    link: np.ndarray, motor: np.ndarray | None = None, cause: str = "link_noisy"
) -> int | None:
    """The tick the noise watch fires at (None: never) with these readings; the motor follows
    the link's true motion (`motor`, default the link itself)."""
    supervisor = _supervisor(max_deflection_rad=0.5)
    motor = link if motor is None else motor
    for k, value in enumerate(link):
        _tick(supervisor, k, _sample(float(motor[k]), float(value)))
        if supervisor.events:
            assert supervisor.events[0].cause == cause, supervisor.events[0]
            return k
    return None


def test_the_noise_watch_fires_on_noise_and_not_on_motion() -> None:
    rng = np.random.default_rng(1)
    t = np.arange(2000) * PERIOD_S
    quantise = np.vectorize(lambda x: round(x / COUNT_RAD) * COUNT_RAD)
    slow = 0.2 * np.sin(2 * np.pi * 0.5 * t)
    # physical motion, however violent, has a smooth second difference: a 10 Hz, 0.08 rad
    # oscillation (2nd difference up to 8e-3 rad, changing sign only twice per 20 ticks),
    # a step of acceleration (an impact), quantisation flicker of one count
    assert _second_difference_noise_trip(quantise(0.08 * np.sin(2 * np.pi * 10 * t))) is None
    assert _second_difference_noise_trip(quantise(np.where(t > 1, 50 * (t - 1) ** 2, 0))) is None
    flicker = quantise(slow) + COUNT_RAD * rng.integers(0, 2, t.size)
    assert _second_difference_noise_trip(flicker) is None
    # the emulator's noisy_encoder: 50 counts rms on the same motion - found within 20 ticks;
    # the motor (its own encoder, 501,923 pulses/rev) follows the true motion
    noisy = quantise(slow + rng.normal(0, 50 * COUNT_RAD, t.size))
    motor = np.round(slow / MOTOR_PULSE_RAD) * MOTOR_PULSE_RAD
    tick = _second_difference_noise_trip(noisy, motor)
    assert tick is not None and tick <= CONFIG.safety.link_noise_window_ticks


def _chatter(amplitude_rad: float, n: int = 400) -> np.ndarray:
    """A joint oscillating at the loop's rate on a slow motion: +-amplitude every other tick."""
    t = np.arange(n) * PERIOD_S
    return 0.05 * np.sin(2 * np.pi * 0.5 * t) + amplitude_rad * (-1.0) ** np.arange(n)


def test_the_noise_watch_tells_a_noisy_encoder_from_an_oscillating_joint() -> None:
    """The link jumps and the motor does not: the encoder (`link_noisy`). The link and the
    motor jump together, the goal alternating: the joint (`oscillation`). Either stops the run
    (hold), each with the counts of all three in its message."""
    # the motor chattering +-0.3 mrad with the link, the goal +-5 mrad (a controller at the
    # loop's rate; the servo follows a fraction of it, the gear passes it to the link)
    motion = _chatter(3e-4)
    link = np.round((motion * 0.8) / COUNT_RAD) * COUNT_RAD
    motor = np.round(motion / MOTOR_PULSE_RAD) * MOTOR_PULSE_RAD
    goal = _chatter(5e-3)
    supervisor = _supervisor(max_deflection_rad=0.5)
    for k in range(len(link)):
        _tick(supervisor, k, _sample(float(motor[k]), float(link[k])), float(goal[k]))
        if supervisor.events:
            break
    (event,) = supervisor.events
    assert event.cause == "oscillation" and event.action == "hold"
    assert supervisor.state is SafeState.HOLD
    assert event.tick <= CONFIG.safety.link_noise_window_ticks + 2
    counts = re.search(r"link (\d+), motor (\d+), goal (\d+) of the last 20", event.message)
    assert counts is not None and min(int(c) for c in counts.groups()) >= 5, event.message
    assert "not the sensor" in event.message
    # the same link readings with a still motor: the encoder is to blame
    still = np.round(0.05 * np.sin(np.pi * np.arange(400) * PERIOD_S) / MOTOR_PULSE_RAD)
    assert _second_difference_noise_trip(link, still * MOTOR_PULSE_RAD) is not None
    # ... and with the motor moving with it, without a goal: the joint, whoever drives it
    assert _second_difference_noise_trip(link, motor, cause="oscillation") is not None


def test_an_oscillation_has_its_own_reaction() -> None:
    """`[safety] on_oscillation` is the oscillation's reaction, `on_link_noisy` the encoder's."""
    motion = _chatter(3e-4)
    link = np.round((motion * 0.8) / COUNT_RAD) * COUNT_RAD
    motor = np.round(motion / MOTOR_PULSE_RAD) * MOTOR_PULSE_RAD
    for reactions, expected in (
        ({"on_oscillation": "torque_off"}, SafeState.TORQUE_OFF),
        ({"on_link_noisy": "torque_off"}, SafeState.HOLD),
    ):
        supervisor = _supervisor(max_deflection_rad=0.5, **reactions)
        for k in range(len(link)):
            _tick(supervisor, k, _sample(float(motor[k]), float(link[k])))
        assert [e.cause for e in supervisor.events] == ["oscillation"]
        assert supervisor.state is expected


def test_the_noise_watch_uses_the_sampling_instants_not_the_nominal_grid() -> None:
    """On the wall clock the SYNC instants jitter: a plain second difference of a link swinging
    at 2.5 rad/s (0.08 rad at 5 Hz) sampled with 0.3 ms rms jitter looks like noise; over the
    readings' own timestamps it does not."""
    rng = np.random.default_rng(3)
    instants = np.arange(400) * PERIOD_S + rng.normal(0.0, 3e-4, 400)
    link = np.round(0.08 * np.sin(2 * np.pi * 5 * instants) / COUNT_RAD) * COUNT_RAD
    # the motor read on the nominal grid (only the link's instants jitter here)
    motor = 0.08 * np.sin(2 * np.pi * 5 * np.arange(400) * PERIOD_S)
    trips = {}
    for stamped in (True, False):
        supervisor = _supervisor(max_deflection_rad=0.5)
        for k in range(400):
            sample = _sample(float(motor[k]), float(link[k]))
            sample.timestamp_s = float(instants[k]) if stamped else 0.0  # 0: no usable stamps
            supervisor.observe(k, k * PERIOD_S, sample)
        trips[stamped] = [e.cause for e in supervisor.events]
    assert trips == {True: [], False: ["link_noisy"]}


def test_the_deflection_bound_holds_the_joint() -> None:
    supervisor = _supervisor()
    _tick(supervisor, 0, _sample(0.0, 0.059))
    assert supervisor.events == []
    assert _tick(supervisor, 1, _sample(0.0, 0.061), 0.3)[0] == 0.0
    assert supervisor.events[0].cause == "deflection" and supervisor.state == SafeState.HOLD


# --- loop overruns --------------------------------------------------------------------------


def test_overruns_trip_when_more_than_the_limit_fall_within_a_second() -> None:
    limit = CONFIG.safety.overrun_limit
    sparse = _supervisor()
    for k in range(0, 20_000, 40):  # one every 0.2 s: 5 per second, for 100 s
        sparse.note_overrun(k, k * PERIOD_S, 0)
    assert sparse.events == [] and sparse.overruns == 500
    burst = _supervisor()
    for k in range(limit + 1):
        burst.note_overrun(k, k * PERIOD_S, 0)
        assert (burst.state == SafeState.HOLD) == (k == limit)
    stall = _supervisor()
    stall.note_overrun(0, 0.0, skipped=limit)  # a 100 ms stall counts its skipped ticks
    assert stall.events[0].cause == "overrun"


# --- the software overload guard ------------------------------------------------------------


def _actuator_trip_tick(current_a: np.ndarray) -> int | None:
    """The emulated actuator's documented overload rule (sim_backend/servo.py): a timer runs
    up while |I| >= 0.9 x limit and down otherwise; the protection trips at 1.5 s."""
    timer = 0.0
    for k, current in enumerate(np.abs(current_a)):
        timer = max(0.0, timer + (PERIOD_S if current >= 0.9 * LIMIT_A else -PERIOD_S))
        if timer >= 1.5:
            return k
    return None


def _guard_tick(current_a: np.ndarray, guard: bool = True) -> int | None:
    supervisor = _supervisor(current_guard=guard)
    for k, current in enumerate(current_a):
        _tick(supervisor, k, _sample(current=float(current)))
        if supervisor.events:
            assert supervisor.events[0].cause == "current"
            return k
    return None


def test_the_current_guard_fires_after_its_time_and_before_the_actuator_would_trip() -> None:
    held = np.full(1000, -LIMIT_A)
    assert _guard_tick(held) == round(CONFIG.safety.current_guard_time_s / PERIOD_S) - 1
    assert _guard_tick(held, guard=False) is None
    # dithering around the threshold still adds up (a timer that reset below it would not)
    dither = np.tile([-LIMIT_A, -LIMIT_A, -0.5 * LIMIT_A], 1000)
    assert _guard_tick(dither) is not None
    # noisy loads near the limit: whenever the actuator's rule would trip, the guard was first
    rng = np.random.default_rng(0)
    trips = 0
    for mean in np.linspace(0.85, 1.0, 16):
        current = LIMIT_A * np.clip(rng.normal(mean, 0.1, 3000), 0, 1)
        actuator = _actuator_trip_tick(current)
        guard = _guard_tick(current)
        if actuator is not None:
            trips += 1
            assert guard is not None and guard < actuator
    assert trips >= 8


def test_back_off_moves_the_goal_away_from_the_push_and_escalation_never_reverts() -> None:
    supervisor = _supervisor(on_deflection="hold")
    _tick(supervisor, 0, _sample(-0.22, -0.2, current=-9.0), -0.3)
    goal = _tick(supervisor, 1, _sample(-0.22, -0.3, current=-9.0), -0.3)  # deflection 0.08
    assert supervisor.state == SafeState.HOLD and goal[0] == pytest.approx(-0.22)
    for k in range(2, 400):
        goal = _tick(supervisor, k, _sample(-0.22, -0.2, current=-LIMIT_A), -0.3)
    assert supervisor.state == SafeState.BACK_OFF
    assert goal[0] == pytest.approx(-0.22 + CONFIG.safety.current_guard_backoff_rad)
    _tick(supervisor, 400, _sample(hardware_error=HardwareError.OVERLOAD, torque=False))
    assert supervisor.state == SafeState.TORQUE_OFF
    _tick(supervisor, 401, _sample(0.0, 0.2))  # a milder cause later changes nothing
    assert supervisor.state == SafeState.TORQUE_OFF
    assert [e.cause for e in supervisor.events] == ["deflection", "current", "hardware_error"]


def test_an_unknown_reaction_is_refused() -> None:
    reactions = "'hold', 'back_off', 'torque_off' or 'finish_step'"
    with pytest.raises(ConfigError, match=f"on_overrun: Input should be {reactions}"):
        _supervisor(on_overrun="panic")


# --- slow re-homing -------------------------------------------------------------------------


def test_no_homing_when_the_link_starts_at_the_experiments_start() -> None:
    assert plan_homing(np.array([0.004]), 0.0) is None


def test_homing_ramps_the_reference_no_faster_than_its_rate() -> None:
    plan = plan_homing(np.array([-0.2, 0.1]), 0.0, rate_rad_s=0.1, settle_s=0.5)
    assert plan is not None
    # cosine ramp: peak speed pi/2 x distance / duration = the rate, for the farther joint
    assert plan.ramp_s == pytest.approx(math.pi / 2 * 0.2 / 0.1)
    t = np.arange(0.0, plan.duration_s + 0.1, PERIOD_S)
    reference = np.array([plan.reference(float(x)) for x in t])
    speed = np.abs(np.diff(reference, axis=0)) / PERIOD_S
    assert speed.max() <= 0.1 + 1e-9 and speed[:, 0].max() > 0.099
    assert np.allclose(reference[0], [-0.2, 0.1]) and np.allclose(reference[-1], 0.0)
    assert plan.ticks(PERIOD_S) == math.ceil(plan.duration_s / PERIOD_S)
    with pytest.raises(ValueError, match="every link angle must be known"):
        plan_homing(np.array([math.nan]), 0.0)


def test_a_fault_the_actuator_reports_with_torque_still_on_trips_too() -> None:
    """Overheating is outside the H54's default Shutdown mask: the device keeps its torque on and
    only reports the bit. The supervisor must act on the report, not wait for torque off."""
    supervisor = _supervisor()
    _tick(supervisor, 0, _sample(), 0.0)
    goal = _tick(supervisor, 1, _sample(hardware_error=HardwareError.OVERHEATING, torque=True), 0.0)
    (event,) = supervisor.events
    assert (event.tick, event.cause, event.action) == (1, "hardware_error", "torque_off")
    assert "OVERHEATING" in event.message and "torque is on" in event.message
    assert goal is None and supervisor.state == SafeState.TORQUE_OFF


def test_goals_clipped_on_most_ticks_are_a_safety_stop_not_a_completed_run() -> None:
    window = CONFIG.safety.goal_saturation_window_ticks
    supervisor = _supervisor()
    for k in range(2 * window):
        _tick(supervisor, k, _sample(0.79, 0.79), 5.0)  # far beyond max_angle_rad 0.8
        if supervisor.events:
            break
    (event,) = supervisor.events
    assert event.cause == "goal_saturated" and event.action == "hold"
    # half of the window, counted from the first clipped goal (the rate limit reaches the limit
    # on tick 0: 0.79 + 0.01)
    assert event.tick == window // 2 - 1


def test_a_kdist_beyond_the_analysed_range_is_a_safety_stop_at_the_start() -> None:
    supervisor = _supervisor()
    supervisor.check_settings(1.0)
    assert supervisor.events == []
    supervisor.check_settings(1.5)
    (event,) = supervisor.events
    assert event.cause == "gain_out_of_range" and supervisor.state == SafeState.HOLD

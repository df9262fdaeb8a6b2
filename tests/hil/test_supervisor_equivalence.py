"""The supervisor's watches over all joints at once decide what the per-joint watches they
replaced decided (tests/support/per_joint_watches.py, kept as the reference): the same events
and notices, word for word and in the same order, the same safe state, the same goals sent and
the same counters, tick by tick, on random runs of twelve joints with every fault the watches
look for - actuator replies lost in streaks, dead and frozen link encoders, noisy encoders,
joints chattering at the loop's rate, actuator faults and torque found off, currents held near
the limit, deflections beyond the bound, goals beyond the limits or not finite, timestamps
that repeat or are missing - mixed at random."""

from __future__ import annotations

import math
from dataclasses import asdict

import numpy as np
import pytest

from drivers.dynamixel import HardwareError, actuator_fault
from drivers.joint_bus import BusFault, DeviceRole, JointDevices, JointSample
from hil.config import load_config
from hil.safety import Supervisor
from tests.support.per_joint_watches import PerJointSupervisor

CONFIG = load_config(robot="dyros-jet")
N = len(CONFIG.joints)
PERIOD_S = CONFIG.loop.period_s
DEVICES = tuple(JointDevices(f"actuator {i + 1}", f"link encoder node {i + 21}") for i in range(N))
LIMITS_A = np.full(N, 10.0)
COUNT_RAD = 2 * math.pi / 983_040


def _pair(rng: np.random.Generator, **safety: object) -> tuple[Supervisor, Supervisor]:
    config = CONFIG.changed("safety", **safety).safety if safety else CONFIG.safety
    args = (
        config,
        CONFIG.joint_names,
        DEVICES,
        np.array([j.min_angle_rad for j in CONFIG.joints]),
        np.array([j.max_angle_rad for j in CONFIG.joints]),
        PERIOD_S,
        np.full(N, 2000.0),
    )
    pair = Supervisor(*args), PerJointSupervisor(*args)
    limits = LIMITS_A.copy()
    limits[rng.random(N) < 0.1] = math.nan  # an actuator whose limit is unknown
    for supervisor in pair:
        supervisor.set_current_limits(limits)
    return pair


class _Scenario:
    """A random run: smooth motion per joint, with faults switched on and off at random."""

    def __init__(self, rng: np.random.Generator, ticks: int, fault_rate: float) -> None:
        self.rng = rng
        self.ticks = ticks
        t = np.arange(ticks)[:, None] * PERIOD_S
        amplitude = rng.uniform(0.0, 0.3, N)
        frequency = rng.uniform(0.1, 3.0, N)
        self.motor = amplitude * np.sin(2 * np.pi * frequency * t + rng.uniform(0, 6, N))
        self.link = self.motor + rng.normal(0, 0.005, N)
        self.frozen_at = np.zeros(N)
        self.faults = {
            kind: self._episodes(fault_rate)
            for kind in (
                "motor_invalid",
                "link_invalid",
                "frozen",
                "noisy",
                "chatter",
                "fault",
                "torque_off",
                "current",
                "deflection",
                "beyond",
            )
        }

    def _episodes(self, rate: float) -> np.ndarray:
        """ticks x joints: True inside episodes of random length (1 to 60 ticks)."""
        on = np.zeros((self.ticks, N), dtype=bool)
        for j in range(N):
            k = 0
            while k < self.ticks:
                if self.rng.random() < rate:
                    length = int(self.rng.integers(1, 60))
                    on[k : k + length, j] = True
                    k += length
                k += 1
        return on

    def sample(self, k: int) -> JointSample:
        rng, f = self.rng, self.faults
        motor = self.motor[k].copy()
        link = np.round(self.link[k] / COUNT_RAD) * COUNT_RAD
        chatter = f["chatter"][k]
        motor[chatter] += 4e-4 * (-1) ** k
        link[chatter] += 3e-4 * (-1) ** k
        noisy = f["noisy"][k]
        link[noisy] += rng.normal(0, 50 * COUNT_RAD, int(noisy.sum()))
        frozen = f["frozen"][k]
        starts = frozen & ~f["frozen"][k - 1] if k > 0 else frozen
        self.frozen_at[starts] = link[starts]
        link[frozen] = self.frozen_at[frozen]  # a hung counter repeats its reading...
        motor[frozen] -= 0.002 * (k % 40)  # ...while the motor walks away
        link[f["deflection"][k]] += 0.1
        current = rng.normal(0, 2.0, N)
        current[f["current"][k]] = rng.choice([-1, 1]) * rng.uniform(7.5, 10.0)
        bits = np.where(
            f["fault"][k], rng.choice([HardwareError.OVERLOAD, HardwareError.OVERHEATING], N), 0
        )
        motor_valid = ~f["motor_invalid"][k]
        link_valid = ~f["link_invalid"][k]
        torque = motor_valid & ~f["torque_off"][k]
        errors = [
            BusFault(int(i), DeviceRole.ACTUATOR, DEVICES[i].actuator, f"timeout {k % 3}")
            for i in np.flatnonzero(~motor_valid)
        ]
        stamp = k * PERIOD_S + rng.normal(0, 3e-4)
        roll = rng.random()
        if roll < 0.03:
            stamp = math.nan  # no usable stamp
        elif roll < 0.06 and k > 0:
            stamp = (k - 1) * PERIOD_S  # a repeated one
        return JointSample(
            timestamp_s=stamp,
            motor_angle_rad=np.where(motor_valid, motor, np.nan),
            link_angle_rad=np.where(link_valid, link, np.nan),
            motor_velocity_rad_s=np.zeros(N),
            motor_current_a=np.where(motor_valid, current, np.nan),
            actuator_fault=np.array([actuator_fault(int(b)) for b in bits], dtype=np.uint8),
            fault_code=bits.astype(np.int64),
            torque_enabled=torque,
            motor_valid=motor_valid,
            link_valid=link_valid,
            link_age_s=np.where(link_valid, 0.0, 0.005 * (k % 7)),
            bus_errors=errors,
        )

    def goal(self, k: int) -> np.ndarray | None:
        roll = self.rng.random()
        if roll < 0.02:
            return None
        goal = self.motor[k] + self.rng.normal(0, 0.003, N)
        if roll < 0.04:
            goal[int(self.rng.integers(N))] = math.nan
        beyond = self.faults["beyond"][k]
        goal[beyond] = 5.0 * np.sign(self.rng.normal(size=int(beyond.sum())))
        return goal


def _state(supervisor: Supervisor, events: int, notices: int) -> dict[str, object]:
    """The supervisor's state and its events and notices from these on; and what the watches
    counted on the way (the jumps in each noise window, the timers and streaks), which a
    decision shows only when it crosses a bound."""
    watches = supervisor.watches
    noise = watches.link_noise
    return {
        "counted": [
            [None if math.isnan(x) else x for x in counts.tolist()]  # NaN == NaN here
            for counts in (
                noise.link.count,
                noise.motor.count,
                noise.goal.count,
                noise.link.last,  # the last second differences, to the bit
                noise.motor.last,
                noise.goal.last,
                watches.current.timer_s,
                watches.link_stale.frozen_ticks,
                watches.link_stale.bad_ticks,
                watches.bus.bad_ticks,
            )
        ],
        "state": supervisor.state,
        "events": [asdict(e) for e in supervisor.events[events:]],
        "notices": [asdict(n) for n in supervisor.notices[notices:]],
        "counters": supervisor.counters(),
    }


def _run(seed: int, fault_rate: float, ticks: int = 400, **safety: object) -> int:
    """Both supervisors through one random run; returns how many events they saw."""
    rng = np.random.default_rng(seed)
    vectorised, reference = _pair(rng, **safety)
    scenario = _Scenario(rng, ticks, fault_rate)
    kdist = np.where(rng.random(N) < 0.05, 1.2, 0.5)
    for supervisor in (vectorised, reference):
        supervisor.torque_enabled(scenario.motor[0])
        supervisor.check_settings(kdist)
    seen = (0, 0)
    for k in range(ticks):
        sample = scenario.sample(k)
        goal = scenario.goal(k)
        if rng.random() < 0.02:
            skipped = int(rng.integers(0, 3))
            for supervisor in (vectorised, reference):
                supervisor.note_overrun(k, k * PERIOD_S, skipped)
        if rng.random() < 0.01:
            torque = rng.random() < 0.5
            for supervisor in (vectorised, reference):
                (supervisor.torque_enabled if torque else supervisor.torque_disabled)(
                    *((scenario.motor[k],) if torque else ())
                )
        sent = []
        for supervisor in (vectorised, reference):
            supervisor.observe(k, k * PERIOD_S, sample)
            sent.append(supervisor.command(None if goal is None else goal.copy(), sample))
        if sent[1] is None:
            assert sent[0] is None, k
        else:
            np.testing.assert_array_equal(sent[0], sent[1], err_msg=f"tick {k}")
            assert np.array_equal(np.signbit(sent[0]), np.signbit(sent[1])), k
        assert _state(vectorised, *seen) == _state(reference, *seen), f"tick {k}"
        seen = len(reference.events), len(reference.notices)
    return len(reference.events)


# the current guard's two rules (hil/safety/overload.py): the fixed figures, and the one derived
# from the actuator's protection (90 % of the limit, here 0.01 s before its 1.5 s trip)
GUARD_RULES = {
    "fixed": {"current_guard_margin_s": None, "current_guard_time_s": 0.1},
    "derived": {"current_guard_margin_s": 1.49},
}


@pytest.mark.parametrize("rule", sorted(GUARD_RULES))
@pytest.mark.parametrize("seed", range(8))
def test_faulty_runs_decide_the_same(seed: int, rule: str) -> None:
    assert _run(seed, fault_rate=0.01, **GUARD_RULES[rule]) > 0


@pytest.mark.parametrize("seed", range(3))
def test_rare_faults_keep_the_run_going_and_decide_the_same(seed: int) -> None:
    """Faults rare and tolerated long (large bounds): the run path (clipping, the rate limit,
    goal saturation) and the watches' counting go on for the whole run."""
    _run(
        100 + seed,
        fault_rate=0.002,
        ticks=600,
        bus_error_ticks=50,
        link_stale_ticks=80,
        max_deflection_rad=0.5,
        current_guard_margin_s=None,
        current_guard_time_s=0.25,
        goal_saturation_window_ticks=50,
        goal_saturation_fraction=1.0,
        link_noise_fraction=1.0,
    )

"""The current guard against the actuator's own overload protection (hil/safety/overload.py).

The protection is the emulated firmware's own law (`sim_backend.servo_law.overload_timer`, run
at the emulator's 1 kHz physics step on the current the host samples at 200 Hz); the guard is
the product's supervisor. Analysis, for a current held at |I| from t = 0 (T = 1.5 s the trip
time, 0.9 the protection's fraction, m the margin):

    |I| >= 0.9 limit           the protection trips at T, the derived guard at T - m
    0.8 <= |I| / limit < 0.9   the protection never trips, nor the derived guard; the fixed
                               rule (0.8, 0.6 s: the testbed's) fires at 0.6 s
    a duty cycle d (> 1/2) at the limit, 0.5 limit otherwise: the timers run up at r = 2d - 1
                               on average and peak the on-time t_on above that line: the
                               protection trips between (T - t_on) / r and T / r, the guard
                               between (T - m - t_on) / r and (T - m) / r
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from drivers.joint_bus import JointSample
from hil.config import SafetySection, load_config
from hil.safety import OverloadProtection, Supervisor, protections_of
from hil.safety.overload import H54_200_S500_R
from sim_backend.servo import H54ServoParams
from sim_backend.servo_law import SCALAR, overload_timer
from tests.support.one_joint import one_joint_supervisor

JET = load_config(robot="dyros-jet")
TESTBED = load_config()
PERIOD_S = JET.loop.period_s
PHYSICS_STEPS = 5  # the emulator's 1 kHz per 200 Hz tick
LIMIT_A = 19.98  # the DYROS-JET legs' Torque Limit 1240 x 16.11328 mA
TRIP_S = H54_200_S500_R.trip_time_s


def _protection_trip_s(current_a: np.ndarray) -> float | None:
    """When the emulated firmware's overload law trips on this current (held over each tick)."""
    params = H54ServoParams()
    d = SimpleNamespace(
        overload_threshold_a=params.overload_current_fraction * LIMIT_A, torque_on=True
    )
    dt, timer = PERIOD_S / PHYSICS_STEPS, 0.0
    for k, current in enumerate(np.abs(current_a)):
        for step in range(PHYSICS_STEPS):
            timer = overload_timer(SCALAR, d, float(current), timer, dt)
            if timer >= params.overload_trip_time_s:
                return (k * PHYSICS_STEPS + step + 1) * dt
    return None


def _guard(safety: SafetySection, current_a: np.ndarray) -> tuple[float | None, Supervisor]:
    """When the supervisor's guard fires on these samples (the tick's end), and the supervisor."""
    supervisor = one_joint_supervisor(safety, PERIOD_S, LIMIT_A)
    for k, current in enumerate(current_a):
        sample = JointSample.empty(1, timestamp_s=k * PERIOD_S)
        sample.motor_angle_rad[:] = sample.link_angle_rad[:] = 0.0
        sample.motor_current_a[:] = current
        sample.motor_valid[:] = sample.link_valid[:] = sample.torque_enabled[:] = True
        supervisor.observe(k, k * PERIOD_S, sample)
        if supervisor.events:
            assert supervisor.events[0].cause == "current"
            return (k + 1) * PERIOD_S, supervisor
    return None, supervisor


def _held(fraction: float, seconds: float = 5.0) -> np.ndarray:
    return np.full(round(seconds / PERIOD_S), -fraction * LIMIT_A)


def test_the_hosts_protection_model_is_the_emulated_firmwares() -> None:
    params = H54ServoParams()
    assert H54_200_S500_R.fraction == params.overload_current_fraction
    assert H54_200_S500_R.trip_time_s == params.overload_trip_time_s
    # the configuration's bound on the margin is that trip time (hil/config/schema.py)
    metadata = SafetySection.model_fields["current_guard_margin_s"].metadata
    (bound,) = [m.lt for m in metadata if hasattr(m, "lt")]
    assert bound == H54_200_S500_R.trip_time_s
    assert protections_of(JET) == (H54_200_S500_R,) * len(JET.joints)


def test_dyros_jets_guard_mirrors_the_protection_and_fires_its_margin_before_it() -> None:
    margin = JET.safety.current_guard_margin_s
    assert margin == 0.8  # a single support of the walks (hil/data/dyros_jet.toml)
    for fraction in (0.9, 1.0):
        protection = _protection_trip_s(_held(fraction))
        guard, supervisor = _guard(JET.safety, _held(fraction))
        assert TRIP_S <= protection <= TRIP_S + 1.5 * PERIOD_S / PHYSICS_STEPS  # (a float sum)
        assert guard == pytest.approx(TRIP_S - margin)
        record = supervisor.counters()["current_guard"]
        assert record["rule"] == "protection" and record["fires_at_s"] == {"joint": TRIP_S - margin}
        assert "0.8 s before the protection" in supervisor.events[0].message


def test_the_derived_guard_does_not_act_where_the_protection_would_not() -> None:
    """Between 80 and 90 % of the limit the actuator never trips: the old rule of DYROS-JET (and
    still the testbed's fixed one) fired there after 0.6 s - the walk-slow finding of issue 25."""
    for fraction in (0.8, 0.85, 0.899):
        assert _protection_trip_s(_held(fraction)) is None
        assert _guard(JET.safety, _held(fraction))[0] is None
        fixed, _ = _guard(TESTBED.safety, _held(fraction))
        assert fixed == pytest.approx(0.6)


@pytest.mark.parametrize("duty", [0.6, 0.7, 0.9])
def test_a_duty_cycle_trips_both_at_the_analysed_times(duty: float) -> None:
    period = 10  # ticks: `duty` of them at the limit, the others at half of it
    cycle = np.where(np.arange(period) < round(duty * period), LIMIT_A, 0.5 * LIMIT_A)
    current = np.tile(cycle, 2000)
    rate, on_s = 2 * duty - 1, round(duty * period) * PERIOD_S
    margin = JET.safety.current_guard_margin_s
    protection = _protection_trip_s(current)
    guard, _ = _guard(JET.safety, current)
    assert protection is not None and guard is not None
    assert (TRIP_S - on_s) / rate <= protection <= TRIP_S / rate + PERIOD_S
    assert (TRIP_S - margin - on_s) / rate <= guard <= (TRIP_S - margin) / rate + PERIOD_S
    assert protection - guard >= margin - PERIOD_S


def test_on_random_loads_the_guard_acts_first_and_only_near_a_trip() -> None:
    """Whenever the protection trips the guard fired at least the margin earlier; whenever the
    guard fires the protection's own timer had run to within a tick of trip time - margin."""
    rng = np.random.default_rng(1)
    margin = JET.safety.current_guard_margin_s
    trips = fires = 0
    for mean in np.linspace(0.8, 1.0, 21):
        current = LIMIT_A * np.clip(rng.normal(mean, 0.08, 1500), 0.0, 1.0)
        protection = _protection_trip_s(current)
        guard, supervisor = _guard(JET.safety, current)
        if protection is not None:
            trips += 1
            assert guard is not None and protection - guard >= margin - PERIOD_S
        if guard is not None:
            fires += 1
            ticks = round(guard / PERIOD_S)
            timer = _protection_timer_s(current[:ticks])
            assert timer >= TRIP_S - margin - PERIOD_S
            assert supervisor.watches.current.peak_timer_s[0] == pytest.approx(timer, abs=1e-9)
    assert trips >= 5 and fires > trips


def _protection_timer_s(current_a: np.ndarray) -> float:
    params = H54ServoParams()
    d = SimpleNamespace(
        overload_threshold_a=params.overload_current_fraction * LIMIT_A, torque_on=True
    )
    timer = 0.0
    for current in np.abs(current_a):
        for _ in range(PHYSICS_STEPS):
            timer = overload_timer(SCALAR, d, float(current), timer, PERIOD_S / PHYSICS_STEPS)
    return timer


def test_the_testbeds_guard_is_the_fixed_rule_as_before() -> None:
    """The testbed keeps its figures (0.8 of the limit, 0.6 s): it fires 0.9 s before the
    protection on a current held at the limit, as Fig. 5's contact run records."""
    assert TESTBED.safety.current_guard_margin_s is None
    guard, supervisor = _guard(TESTBED.safety, _held(1.0))
    assert guard == pytest.approx(TESTBED.safety.current_guard_time_s)
    assert supervisor.counters()["current_guard"]["rule"] == "fixed"


def test_a_margin_for_a_model_with_a_shorter_trip_is_refused() -> None:
    quick = OverloadProtection("quick", fraction=0.9, trip_time_s=0.5, source="a test")
    with pytest.raises(ValueError, match="not below the quick's overload trip time"):
        one_joint_supervisor(JET.safety, PERIOD_S, LIMIT_A, protections=(quick,))

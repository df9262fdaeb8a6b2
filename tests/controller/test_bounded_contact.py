"""Contact that stays compliant: the "accumulated-integral" reading of (25) against the emulated
testbed (sim_backend's H54 firmware with its velocity-loop integral, the MuJoCo plant, the
block of Fig. 5), stepped in process at 200 Hz (tests/controller/sim_harness.py).

Analysis (controller/composition.py, docs/reproduction.md). Servo static stiffness
k_s = Kpp kv = 10 x 78.5 = 785 N m/rad, integral time Ti_s = 15 s; the lab's Euler LQR
Ke = 0.21697 per tick; the reference ends e_b = 0.1 rad beyond the block at -0.2 rad; gravity at
the block tau_g = 0.63 x 9.81 x cos(0.2) = 6.057 N m; lever L = 0.7 m.
- lab ("accumulated"): the balance holds a lag Ke e_b / Kdist on which the servo's integral
  keeps growing: the force creeps at k_s Ke e_b / (Kdist Ti_s L) = 1.62 N/s (Kdist 1).
- bounded ("accumulated-integral", Ti_d = Ti_s): the force is constant from contact on,
  F = (tau_g + k_s Ke e_b / Kdist) / L (the servo's integral state at the controller's reset,
  25 ms after power-on, is ~0): 32.98 N at Kdist 1, 57.3 N at Kdist 0.5.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from sim_harness import (
    IMPACT_PUSH_START_S,
    Trace,
    configured_controller,
    contact_scene,
    emulated_plant,
    impact_scene,
    simulate,
)

from sim_backend.servo import H54ServoParams

SERVO = H54ServoParams()
SERVO_STIFFNESS_NM_PER_RAD = SERVO.position_gain_per_s * SERVO.velocity_gain_nms_per_rad  # 785
LEVER_M = emulated_plant().link_length_m
BLOCK_RAD, REFERENCE_END_RAD = -0.2, -0.3
GRAVITY_AT_BLOCK_NM = emulated_plant().gravity_moment_kg_m * 9.81 * math.cos(BLOCK_RAD)
CONTACT_RUN_S = 32.0  # 30 s of contact (contact near 2.25 s)


def _bounded(kdist: float):  # noqa: ANN202
    return configured_controller(
        "gc+lqr+dob",
        kdist,
        composition="accumulated-integral",
        dob_integral_time_s=SERVO.velocity_integral_time_s,
    )


def _predicted_force_n(kdist: float, error_gain: float) -> float:
    e_b = BLOCK_RAD - REFERENCE_END_RAD
    return (GRAVITY_AT_BLOCK_NM + SERVO_STIFFNESS_NM_PER_RAD * error_gain * e_b / kdist) / LEVER_M


def _force_at(trace: Trace, time_s: float) -> float:
    return float(trace.contact_force_n[np.searchsorted(trace.time_s, time_s)])


@pytest.mark.slow
def test_bounded_reading_holds_20_to_40_n_for_30_s_of_contact_at_kdist_1() -> None:
    controller = _bounded(1.0)
    trace = simulate(controller, contact_scene(CONTACT_RUN_S))
    contact = trace.contact_time_s()
    assert contact is not None and contact < 2.5
    assert trace.time_s[-1] - contact >= 29.5
    assert not trace.overload_tripped()
    assert trace.torque_enabled.all()
    touching = trace.time_s >= contact + 0.5
    force = trace.contact_force_n[touching]
    assert force.min() >= 20.0 and force.max() <= 40.0, (force.min(), force.max())
    assert trace.contact_force_n.max() <= 40.0  # the impact on the block included
    error_gain = controller.lqr_gain.error_gain[0, 0]  # type: ignore[attr-defined]
    predicted = _predicted_force_n(1.0, error_gain)
    assert predicted == pytest.approx(32.98, abs=0.05)
    # constant from the end of the reference ramp (3 s) on: no creep
    settled = trace.contact_force_n[trace.time_s >= 4.0]
    assert np.ptp(settled) < 0.02 * predicted
    assert np.mean(settled) == pytest.approx(predicted, rel=0.03)


@pytest.mark.slow
def test_bounded_reading_at_kdist_half_is_bounded_where_the_statics_say() -> None:
    """Kdist 0.5 presses twice the servo lag: 57 N, outside 20-40 N, but constant, no trip."""
    controller = _bounded(0.5)
    trace = simulate(controller, contact_scene(CONTACT_RUN_S))
    assert not trace.overload_tripped()
    error_gain = controller.lqr_gain.error_gain[0, 0]  # type: ignore[attr-defined]
    settled = trace.contact_force_n[trace.time_s >= 4.0]
    assert np.ptp(settled) < 0.02 * np.mean(settled)
    assert np.mean(settled) == pytest.approx(_predicted_force_n(0.5, error_gain), rel=0.03)


@pytest.mark.slow
def test_the_labs_reading_creeps_at_the_rate_the_servo_integral_sets() -> None:
    controller = configured_controller("gc+lqr+dob", 1.0)  # the lab's accumulated reading
    trace = simulate(controller, contact_scene(CONTACT_RUN_S))
    error_gain = controller.lqr_gain.error_gain[0, 0]  # type: ignore[attr-defined]
    e_b = BLOCK_RAD - REFERENCE_END_RAD
    rate = (
        SERVO_STIFFNESS_NM_PER_RAD * error_gain * e_b / (SERVO.velocity_integral_time_s * LEVER_M)
    )
    assert rate == pytest.approx(1.62, abs=0.01)
    measured = (_force_at(trace, 12.0) - _force_at(trace, 4.0)) / 8.0
    assert measured == pytest.approx(rate, rel=0.15)
    assert trace.contact_force_n.max() > 55.0  # past 40 N within the 30 s
    assert trace.overload_tripped()  # ... and into the actuator's overload protection


def _first_peak_rad(trace: Trace) -> float:
    """As hil.metrics: the largest |link - link before the push| within 0.5 s of the push."""
    before = np.flatnonzero(trace.time_s < IMPACT_PUSH_START_S)[-1]
    window = (trace.time_s >= IMPACT_PUSH_START_S) & (trace.time_s < IMPACT_PUSH_START_S + 0.5)
    return float(np.max(np.abs(trace.link_angle_rad[window] - trace.link_angle_rad[before])))


@pytest.mark.slow
def test_impact_first_peak_relations_hold_with_the_bounded_reading() -> None:
    """Fig. 6: the DOB yields more than pid, and Kdist 1 more than Kdist 0.5."""
    pid = _first_peak_rad(simulate(configured_controller("pid"), impact_scene()))
    half = _first_peak_rad(simulate(_bounded(0.5), impact_scene()))
    one = _first_peak_rad(simulate(_bounded(1.0), impact_scene()))
    assert one > half > pid
    assert one > 1.5 * pid

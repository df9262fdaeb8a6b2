"""The DOB's expected gravity lag (ControllerParams.dob_expects_gravity_lag), by hand.

A servo of static stiffness Kpp kv holds a load tau with the motor tau / (Kpp kv) behind its
goal. Here the "robot" is the DOB's own nominal servo (ZOH-sampled first order, Kp = 10) driven
by the goal minus that lag: theta_m(k) = a theta_m(k-1) + b (u(k-1) - tau / (Kpp kv)), its link
held on the reference. The inverse nominal model then gives u_hat(k-1) = u(k-1) - tau / (Kpp kv)
exactly, so the DOB's raw estimate is -tau / (Kpp kv) every tick: the paper's DOB reads the
compensated weight as a disturbance (and yields to it by Kdist); the DOB that expects the lag
reads nothing.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller import (
    ControllerParams,
    PendulumGravity,
    ServoCascadeParams,
    joint_static_compliance,
    make_controller,
)
from controller.servo_cascade import H54_VELOCITY_GAIN_NMS_PER_RAD

DT_S = 0.005
KPP = 10.0
KV = H54_VELOCITY_GAIN_NMS_PER_RAD  # 2 pi 50 Hz x 0.25 kg m^2
GRAVITY = PendulumGravity(5.0, 0.4)
TAU_NM = float(GRAVITY.gravity_torque(np.zeros(1))[0])  # m g r at theta = 0


def _estimate(expects_lag: bool) -> float:
    compliance = joint_static_compliance(2000.0, KPP, KV)
    params = ControllerParams.paper(
        1,
        kdist=0.0,  # observe only: the estimate q(k) does not depend on Kdist
        servo_cascade=ServoCascadeParams.h54(1),
        gc_compliance_rad_per_nm=compliance,
        dob_expects_gravity_lag=expects_lag,
    )
    controller = make_controller(
        "gc+lqr+dob",
        params,
        sm=np.array([[1 / 0.376]]),
        dt_s=DT_S,
        gravity=GRAVITY,
    )
    a = math.exp(-KPP * DT_S)
    b = 1.0 - a
    reference = np.zeros(1)
    motor = np.zeros(1)
    controller.reset(motor, reference, reference, np.zeros(1))
    goal = np.zeros(1)
    for _ in range(200):
        motor = a * motor + b * (goal - TAU_NM / (KPP * KV))
        goal = controller.step(motor, reference, reference)
        controller.notify_applied(goal)
    return float(controller.terms.disturbance_estimate_rad[0])


def test_the_papers_dob_reads_the_compensated_weights_lag_as_a_disturbance() -> None:
    assert _estimate(False) == pytest.approx(-TAU_NM / (KPP * KV), rel=1e-6)


def test_the_dob_that_expects_the_lag_reads_nothing() -> None:
    assert abs(_estimate(True)) < 1e-9

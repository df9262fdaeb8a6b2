"""Closed-loop poles of the SAMPLED loop: the true plant (20) sampled exactly (ZOH) at 5 ms, in
feedback with the discrete controller (estimator, LQR increment, DOB, composition (25)).

The loop is written out here from the paper's equations, independently of controller/, as a
linear map z(k) -> z(k+1) whose matrix gives the poles; a last test checks that the product's
controller, stepped against the same plant, follows exactly that map.

Loop state z = [x (3n), previous measured state (3n), u(k-1) (n), uc(k-1) (n, "literal" only),
q(k-1) (n, with DOB)]. Per tick, with the measured angles theta_m, theta_j:
    v = beta v_prev + (1 - beta) (theta_j - theta_j_prev) / dt     (beta = 0: plain difference)
    dx = [theta_m, theta_j, v] - previous;   e = theta_j - theta_d
    duc = -(Ke e + Kx dx)
    q = alpha q_prev + (1 - alpha) ((theta_m - a theta_m_prev) / b - u_prev)
    accumulated: u = u_prev + duc + Kdist q      literal: uc = uc_prev + duc, u = uc + Kdist q
    x(k+1) = Phi x + Gamma u   (true K, D, Kp, Sm; exact ZOH)
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from controller import (
    ControllerParams,
    FlexibleJointParams,
    LqrWeights,
    NoGravity,
    design_continuous_tracking_lqr,
    design_discrete_tracking_lqr,
    discretise,
    flexible_joint_state_space,
    make_controller,
    single_link_sm,
)
from controller.lqr import TrackingGain, sample_continuous_gain

DT_S = 0.005
PAPER = FlexibleJointParams.uniform(1)
TESTBED_INERTIAS_KG_M2 = (0.05, 0.25, 1.25, 2.0)
CORNERS = list(itertools.product((0.7, 1.3), repeat=3))  # K, D, Kp factors of the true plant


def _scaled(params: FlexibleJointParams, k: float, d: float, kp: float) -> FlexibleJointParams:
    return FlexibleJointParams(
        stiffness_nm_per_rad=params.stiffness_nm_per_rad * k,
        damping_nms_per_rad=params.damping_nms_per_rad * d,
        servo_gain_per_s=params.servo_gain_per_s * kp,
    )


class SampledLoop:
    """The sampled closed loop, written from the equations (see module docstring)."""

    def __init__(
        self,
        nominal: FlexibleJointParams,
        gain: TrackingGain,
        true_plant: FlexibleJointParams,
        true_sm: np.ndarray,
        *,
        kdist: float | None,
        reading: str = "accumulated",
        dob_cutoff_hz: float = -math.log(0.7) / (2 * math.pi * DT_S),
        velocity_cutoff_hz: float | None = None,
        servo_discretisation: str = "zoh",
        zero_velocity_increment: bool = False,
    ) -> None:
        n = nominal.n_joints
        self.n = n
        plant = discretise(flexible_joint_state_space(true_plant, true_sm), DT_S, "zoh")
        self.phi, self.gamma = plant.a, plant.b
        self.ke, self.kx = gain.error_gain, gain.state_increment_gain
        self.kdist = kdist
        self.reading = reading
        self.alpha = math.exp(-2 * math.pi * dob_cutoff_hz * DT_S)
        self.beta = (
            0.0
            if velocity_cutoff_hz is None
            else math.exp(-2 * math.pi * velocity_cutoff_hz * DT_S)
        )
        kp = nominal.servo_gain_per_s
        if servo_discretisation == "euler":
            self.a, self.b = 1 - kp * DT_S, kp * DT_S
        else:  # "zoh" (with the "zoh" and "continuous-cost" designs)
            self.a = np.exp(-kp * DT_S)
            self.b = 1 - self.a
        self.zero_velocity_increment = zero_velocity_increment
        # Slices of z.
        self.sx = slice(0, 3 * n)
        self.sm = slice(3 * n, 6 * n)
        self.su = slice(6 * n, 7 * n)
        self.suc = slice(7 * n, 8 * n)
        self.sq = slice(8 * n, 9 * n)
        self.size = 9 * n

    def step(self, z: np.ndarray, reference: np.ndarray) -> np.ndarray:
        n = self.n
        x, previous = z[self.sx], z[self.sm]
        u_prev, uc_prev, q_prev = z[self.su], z[self.suc], z[self.sq]
        theta_m, theta_j = x[:n], x[n : 2 * n]
        velocity = (
            self.beta * previous[2 * n :] + (1 - self.beta) * (theta_j - previous[n : 2 * n]) / DT_S
        )
        measured = np.concatenate([theta_m, theta_j, velocity])
        increment = measured - previous
        if self.zero_velocity_increment:  # the lab's code: d dtheta_j fed as zero
            increment[2 * n :] = 0.0
        duc = -(self.ke @ (theta_j - reference) + self.kx @ increment)
        if self.kdist is None:
            dob = np.zeros(n)
            q = q_prev
        else:
            raw = (theta_m - self.a * previous[:n]) / self.b - u_prev
            q = self.alpha * q_prev + (1 - self.alpha) * raw
            dob = self.kdist * q
        if self.reading == "accumulated":
            u = u_prev + duc + dob
            uc = uc_prev  # not part of this loop's state (dropped from the matrix)
        else:
            uc = uc_prev + duc
            u = uc + dob
        return np.concatenate([self.phi @ x + self.gamma @ u, measured, u, uc, q])

    def matrix(self) -> np.ndarray:
        columns = [self.step(column, np.zeros(self.n)) for column in np.eye(self.size)]
        full = np.array(columns).T
        keep = list(range(7 * self.n))
        if self.reading == "literal":
            keep += list(range(7 * self.n, 8 * self.n))
        if self.kdist is not None:
            keep += list(range(8 * self.n, 9 * self.n))
        return full[np.ix_(keep, keep)]

    def spectral_radius(self) -> float:
        return float(np.max(np.abs(np.linalg.eigvals(self.matrix()))))


def _radius(
    inertia: float,
    *,
    kdist: float | None,
    reading: str = "accumulated",
    corner: tuple[float, float, float] = (1.0, 1.0, 1.0),
    method: str = "zoh",
    velocity_cutoff_hz: float | None = None,
    zero_velocity_increment: bool = False,
    dob_cutoff_hz: float = -math.log(0.7) / (2 * math.pi * DT_S),
) -> float:
    sm = single_link_sm(inertia)
    gain = design_discrete_tracking_lqr(PAPER, sm, DT_S, LqrWeights(), method)  # type: ignore[arg-type]
    loop = SampledLoop(
        PAPER,
        gain,
        _scaled(PAPER, *corner),
        sm,
        kdist=kdist,
        reading=reading,
        velocity_cutoff_hz=velocity_cutoff_hz,
        servo_discretisation=method,
        zero_velocity_increment=zero_velocity_increment,
        dob_cutoff_hz=dob_cutoff_hz,
    )
    return loop.spectral_radius()


@pytest.mark.parametrize("inertia", TESTBED_INERTIAS_KG_M2)
@pytest.mark.parametrize(
    "kdist, reading",
    [
        (None, "literal"),
        (0.5, "accumulated"),
        (1.0, "accumulated"),
        (0.5, "literal"),
        (1.0, "literal"),
    ],
)
def test_sampled_loop_stable_with_paper_parameters(
    inertia: float, kdist: float | None, reading: str
) -> None:
    assert _radius(inertia, kdist=kdist, reading=reading) < 0.93


@pytest.mark.parametrize("inertia", TESTBED_INERTIAS_KG_M2)
@pytest.mark.parametrize(
    "kdist, reading", [(None, "literal"), (0.5, "accumulated"), (0.5, "literal"), (1.0, "literal")]
)
def test_sampled_loop_stable_for_30_percent_model_error_in_every_corner(
    inertia: float, kdist: float | None, reading: str
) -> None:
    radii = [_radius(inertia, kdist=kdist, reading=reading, corner=c) for c in CORNERS]
    assert max(radii) < 0.99, dict(zip(CORNERS, np.round(radii, 4), strict=True))


@pytest.mark.parametrize("inertia", TESTBED_INERTIAS_KG_M2)
def test_accumulated_reading_at_kdist_1_holds_20_percent_error_in_every_corner(
    inertia: float,
) -> None:
    corners = list(itertools.product((0.7, 1.3), (0.7, 1.3), (0.8, 1.2)))
    radii = [_radius(inertia, kdist=1.0, reading="accumulated", corner=c) for c in corners]
    assert max(radii) < 1.0, dict(zip(corners, np.round(radii, 4), strict=True))


@pytest.mark.parametrize("inertia", (0.05, 0.25))
def test_accumulated_reading_at_kdist_1_fails_when_the_servo_is_30_percent_faster(
    inertia: float,
) -> None:
    """A documented limit, not a wish: see the DOB-only analysis below for the mechanism."""
    assert _radius(inertia, kdist=1.0, reading="accumulated", corner=(1.0, 1.0, 1.3)) > 1.0
    assert _radius(inertia, kdist=1.0, reading="accumulated", corner=(1.0, 1.0, 0.7)) < 1.0


@pytest.mark.parametrize(
    "inertia, method, stable, unstable",
    [
        (0.05, "zoh", 1.20, 1.25),
        (0.376, "zoh", 1.30, 1.36),
        (0.376, "euler", 1.17, 1.22),  # the testbed's running configuration
        (1.25, "euler", 2.15, 2.25),
    ],
)
def test_accumulated_reading_at_kdist_1_tolerates_a_faster_servo_as_documented(
    inertia: float, method: str, stable: float, unstable: float
) -> None:
    """controller/composition.py's table: the largest true Kp (times nominal) at Kdist 1."""
    assert _radius(inertia, kdist=1.0, corner=(1.0, 1.0, stable), method=method) < 1.0
    assert _radius(inertia, kdist=1.0, corner=(1.0, 1.0, unstable), method=method) > 1.0


def test_accumulated_dob_alone_loses_stability_where_the_quasi_static_analysis_says() -> None:
    """Servo alone, u(k) = u(k-1) + Kdist q(k), true servo a', b' vs nominal a, b.

    A ramp u(k) = s k makes the true servo lag by s / b' and the nominal inverse expect s / b,
    so raw = s (1/b - 1/b'), and the accumulation reproduces the ramp's own slope when
    Kdist (1/b - 1/b') = 1. For a faster true servo beyond that, the loop has a real pole > 1.
    Besides it always has the pole z = 1 of the unregulated angle (no reference here).
    """
    kdist, kp, alpha = 1.0, 10.0, 0.7
    b = 1 - math.exp(-kp * DT_S)
    b_critical = 1 / (1 / b - 1 / kdist)

    def second_pole(b_true: float) -> float:
        a_true = 1 - b_true
        a = 1 - b
        # state [theta_m, theta_m_prev, u_prev, q_prev]
        matrix = np.zeros((4, 4))
        for column in range(4):
            theta_m, theta_m_prev, u_prev, q_prev = np.eye(4)[column]
            raw = (theta_m - a * theta_m_prev) / b - u_prev
            q = alpha * q_prev + (1 - alpha) * raw
            u = u_prev + kdist * q
            matrix[:, column] = [a_true * theta_m + b_true * u, theta_m, u, q]
        poles = sorted(np.linalg.eigvals(matrix), key=lambda p: abs(p - 1))
        assert abs(poles[0] - 1) < 1e-6  # the unregulated angle: theta_m = u, q = 0 is a rest
        return max(abs(p) for p in poles[1:])

    assert second_pole(b_critical * 0.99) < 1.0
    assert second_pole(b_critical * 1.01) > 1.0
    # Kp equivalent: 5 % faster than nominal already destabilises the DOB alone at Kdist = 1.
    assert -math.log(1 - b_critical) / DT_S / kp == pytest.approx(1.0526, abs=1e-3)


@pytest.mark.parametrize("weights", [LqrWeights(), LqrWeights(state_increment_weight=10.0)])
@pytest.mark.parametrize("inertia", TESTBED_INERTIAS_KG_M2)
def test_continuous_design_run_at_200_hz_is_unstable(weights: LqrWeights, inertia: float) -> None:
    """Why the loop uses the discrete design: the paper's continuous gain, sampled, diverges."""
    sm = single_link_sm(inertia)
    continuous = design_continuous_tracking_lqr(PAPER, sm, weights)
    fastest = np.min(continuous.closed_loop_eigenvalues.real)
    sampled = sample_continuous_gain(continuous, DT_S)
    loop = SampledLoop(PAPER, sampled, PAPER, sm, kdist=None, reading="literal")
    assert loop.spectral_radius() > 1.0
    if inertia <= 1.25:  # the fast pole is beyond what 200 Hz can represent
        assert fastest < -math.pi / DT_S
    discrete = design_discrete_tracking_lqr(PAPER, sm, DT_S, weights)
    loop = SampledLoop(PAPER, discrete, PAPER, sm, kdist=None, reading="literal")
    assert loop.spectral_radius() < 0.97


@pytest.mark.parametrize(
    "weights, radius", [(LqrWeights(), 2.989), (LqrWeights(state_increment_weight=10.0), 13.00)]
)
def test_continuous_gain_at_200_hz_on_the_testbed_link(weights: LqrWeights, radius: float) -> None:
    """I = 0.376 kg m^2 (the figures docs/reproduction.md and controller/lqr.py quote)."""
    sm = single_link_sm(0.376)
    sampled = sample_continuous_gain(design_continuous_tracking_lqr(PAPER, sm, weights), DT_S)
    loop = SampledLoop(PAPER, sampled, PAPER, sm, kdist=None, reading="literal")
    assert loop.spectral_radius() == pytest.approx(radius, abs=0.005)


def test_lab_euler_design_breaks_for_light_links_where_zoh_holds() -> None:
    """Forward Euler misplaces the gear's fast pole for I < 0.2375 kg m^2 (model.discretise)."""
    euler = [_radius(0.05, kdist=1.0, reading="literal", corner=c, method="euler") for c in CORNERS]
    zoh = [_radius(0.05, kdist=1.0, reading="literal", corner=c, method="zoh") for c in CORNERS]
    assert max(euler) > 1.0
    assert max(zoh) < 0.97


@pytest.mark.parametrize(
    "kdist, reading", [(None, "literal"), (0.5, "accumulated"), (1.0, "accumulated")]
)
def test_continuous_cost_design_runs_stably_at_its_designed_speed(
    kdist: float | None, reading: str
) -> None:
    """The paper's cost sampled exactly (controller/lqr.py): designed radius 0.99242
    (0.657 s, the continuous design's dominant mode); the loop as it runs (the goal held over
    the tick, dx/dt read as a backward difference) keeps that mode, with or without the DOB."""
    radius = _radius(0.376, kdist=kdist, reading=reading, method="continuous-cost")
    assert 0.99 < radius < 0.998


@pytest.mark.parametrize("inertia", (0.376, 1.25, 2.0))
@pytest.mark.parametrize("kdist", (0.5, 1.0))
def test_the_labs_zero_velocity_increment_keeps_the_running_loop_stable(
    inertia: float, kdist: float
) -> None:
    """The lab's Euler design, Euler Pn^-1, 11.4 Hz Q filter, accumulated reading, and zero fed
    for d dtheta_j (tests/controller/test_running_configuration.py pins I = 0.376)."""
    radius = _radius(
        inertia,
        kdist=kdist,
        method="euler",
        zero_velocity_increment=True,
        dob_cutoff_hz=11.4,
    )
    assert radius < 0.96  # 0.919 .. 0.952 (0.91155 at I = 0.376, Kdist 1)


@pytest.mark.parametrize("reading", ["accumulated", "literal"])
def test_filtered_link_velocity_keeps_the_loop_stable(reading: str) -> None:
    for inertia in TESTBED_INERTIAS_KG_M2:
        assert _radius(inertia, kdist=1.0, reading=reading, velocity_cutoff_hz=30.0) < 0.95


def _two_link_sm() -> np.ndarray:
    """A coupled 2-joint Sm: inverse of a planar 2-link arm's inertia matrix (0.3 m links)."""
    inertia = np.array([[0.9, 0.25], [0.25, 0.15]])
    return np.linalg.inv(inertia)


@pytest.mark.parametrize("reading, kdist", [("accumulated", 0.5), ("literal", 1.0)])
def test_coupled_two_joint_loop_is_stable_in_every_corner(reading: str, kdist: float) -> None:
    nominal = FlexibleJointParams.uniform(2)
    sm = _two_link_sm()
    gain = design_discrete_tracking_lqr(nominal, sm, DT_S, LqrWeights(), "zoh", "full")
    radii = []
    for corner in CORNERS:
        loop = SampledLoop(
            nominal, gain, _scaled(nominal, *corner), sm, kdist=kdist, reading=reading
        )
        radii.append(loop.spectral_radius())
    assert max(radii) < 0.99


@pytest.mark.parametrize("reading", ["accumulated", "literal"])
@pytest.mark.parametrize("velocity_cutoff_hz", [None, 30.0])
def test_product_controller_follows_the_analysed_loop(
    reading: str, velocity_cutoff_hz: float | None
) -> None:
    """The controller stepped against the true plant reproduces SampledLoop to round-off."""
    n = 2
    nominal = FlexibleJointParams.uniform(n)
    sm = _two_link_sm()
    true_plant = _scaled(nominal, 1.3, 0.7, 1.1)
    params = ControllerParams(
        joints=nominal,
        kdist=np.array([0.8, 0.3]),
        composition=reading,  # type: ignore[arg-type]
        link_velocity_cutoff_hz=velocity_cutoff_hz,
    )
    controller = make_controller("gc+lqr+dob", params, sm=sm, dt_s=DT_S, gravity=NoGravity())
    loop = SampledLoop(
        nominal,
        controller.lqr_gain,  # type: ignore[attr-defined]
        true_plant,
        sm,
        kdist=np.array([0.8, 0.3]),  # type: ignore[arg-type]
        reading=reading,
        velocity_cutoff_hz=velocity_cutoff_hz,
    )
    rng = np.random.default_rng(7)
    x0 = np.concatenate([rng.normal(0, 0.05, 2 * n), np.zeros(n)])
    reference = np.array([0.3, -0.2])
    controller.reset(x0[:n], x0[n : 2 * n], reference)
    z = np.zeros(loop.size)
    z[loop.sx] = x0
    z[loop.sm] = x0  # reset: previous measurement = first one, velocity 0
    z[loop.su] = x0[:n]  # the servo holds its present angle
    z[loop.suc] = x0[:n]
    x = x0.copy()
    for _ in range(300):
        goal = controller.step(x[:n], x[n : 2 * n], reference)
        controller.notify_applied(goal)
        x = loop.phi @ x + loop.gamma @ goal
        z = loop.step(z, reference)
        np.testing.assert_allclose(goal, z[loop.su], rtol=0, atol=1e-12)
        np.testing.assert_allclose(x, z[loop.sx], rtol=0, atol=1e-12)
    np.testing.assert_allclose(x[n : 2 * n], reference, atol=1e-3)  # it also tracks

"""The configuration that actually runs on the testbed, analysed by hand and pinned:
the lab's Euler LQR and Euler inverse model, I_link = 0.376 kg m^2, K 2000, D 100, Kp 10,
Qe 10, Qx 1, R 1, 200 Hz, the accumulated reading of (25), the 11.4 Hz Q filter.

Hand calculation (everything below is written here from (20)-(24), independently of
controller/):

    Sm = 1 / 0.376 = 2.65957 1/(kg m^2)
    A  = [[-10, 0, 0], [0, 0, 1], [Sm (K - D Kp), -Sm K, -Sm D]]
       = [[-10, 0, 0], [0, 0, 1], [2659.57, -5319.15, -265.957]],   B = [10, 0, 265.957]'
    Euler, dt = 0.005 s:
    Ad = I + A dt = [[0.95, 0, 0], [0, 1, 0.005], [13.2979, -26.5957, -0.329787]]
    Bd = B dt     = [0.05, 0, 1.32979]'
    augmented (e; dx):  A_aug = [[1, C Ad], [0, Ad]] with C Ad = [0, 1, 0.005],
                        B_aug = [C Bd; Bd] = [0; 0.05; 0; 1.32979]
    Riccati value iteration from P = Q = diag(10, 1, 1, 1):
        G = (R + B'PB)^-1 B'PA,   P <- Q + A'PA - A'PB G
    converges in ~130 iterations (relative change < 1e-12) to
        B'PB = 211.42,  K = [0.216969, 0.998439, 0.671154, -0.0113720]
    and the (1,1) block of the DARE gives Ke exactly as sqrt(Qe / (R + B'PB)) (the first column
    of A_aug is e1, so P11 cancels): sqrt(10 / 212.42) = 0.216969.
    Designed closed loop eig(A_aug - B_aug K): spectral radius 0.91493 (56 ms).
    Ke / dt = 43.39 1/s, against sqrt(Qe / R) = 3.162 1/s for the paper's continuous cost.

The sampled loop (the true plant (20) sampled exactly, the controller as it runs), per tick:
    v = (th_j - th_j_prev) / dt;  dx = [th_m, th_j, v] - previous;  e = th_j - th_d
    duc = -(Ke e + Kx dx);  q = alpha q_prev + (1 - alpha) ((th_m - 0.95 th_m_prev) / 0.05 - u_prev)
    u = u_prev + duc + Kdist q;  x' = Phi x + Gamma u,   alpha = exp(-2 pi 11.4 0.005) = 0.698974
Its spectral radius, from the 8 x 8 map below: 0.91387 at Kdist 1 (a real pole: 57 ms) and
0.90836 at Kdist 0.5; with the lab's zero link-velocity increment 0.91155 and 0.91903. Stable,
with the design's speed (the designed loop's 0.91493).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg

from controller import (
    ControllerParams,
    FlexibleJointParams,
    LqrWeights,
    NoGravity,
    make_controller,
    single_link_sm,
)

DT_S = 0.005
INERTIA = 0.376
K, D, KP = 2000.0, 100.0, 10.0
ALPHA_11_4_HZ = math.exp(-2 * math.pi * 11.4 * DT_S)


def _continuous() -> tuple[np.ndarray, np.ndarray]:
    sm = 1.0 / INERTIA
    a = np.array([[-KP, 0, 0], [0, 0, 1], [sm * (K - D * KP), -sm * K, -sm * D]])
    b = np.array([[KP], [0.0], [sm * D * KP]])
    return a, b


def _hand_riccati() -> tuple[np.ndarray, float, float]:
    """Gain, B'PB and designed spectral radius by value iteration on the Euler model."""
    a, b = _continuous()
    ad, bd = np.eye(3) + a * DT_S, b * DT_S
    c = np.array([[0.0, 1.0, 0.0]])
    a_aug = np.block([[np.eye(1), c @ ad], [np.zeros((3, 1)), ad]])
    b_aug = np.vstack([c @ bd, bd])
    q, r = np.diag([10.0, 1.0, 1.0, 1.0]), np.eye(1)
    p = q.copy()
    for _ in range(10_000):
        g = np.linalg.solve(r + b_aug.T @ p @ b_aug, b_aug.T @ p @ a_aug)
        p_next = q + a_aug.T @ p @ a_aug - a_aug.T @ p @ b_aug @ g
        converged = np.max(np.abs(p_next - p)) < 1e-12 * np.max(np.abs(p))
        p = p_next
        if converged:
            break
    else:
        raise AssertionError("the Riccati iteration did not converge")
    gain = np.linalg.solve(r + b_aug.T @ p @ b_aug, b_aug.T @ p @ a_aug)
    radius = float(np.max(np.abs(np.linalg.eigvals(a_aug - b_aug @ gain))))
    return gain[0], float((b_aug.T @ p @ b_aug)[0, 0]), radius


def _loop_matrix(gain: np.ndarray, kdist: float, zero_velocity_increment: bool) -> np.ndarray:
    a, b = _continuous()
    block = np.zeros((4, 4))
    block[:3, :3], block[:3, 3:] = a, b
    exponential = scipy.linalg.expm(block * DT_S)
    phi, gamma = exponential[:3, :3], exponential[:3, 3]
    ke, kx = gain[0], gain[1:]
    columns = []
    for z in np.eye(8):  # z = [x (3), previous measured (3), u_prev, q_prev]
        x, previous, u_prev, q_prev = z[:3], z[3:6], z[6], z[7]
        velocity = (x[1] - previous[1]) / DT_S
        measured = np.array([x[0], x[1], velocity])
        increment = measured - previous
        if zero_velocity_increment:
            increment[2] = 0.0
        duc = -(ke * x[1] + kx @ increment)  # reference 0: e = th_j
        raw = (x[0] - 0.95 * previous[0]) / 0.05 - u_prev
        q = ALPHA_11_4_HZ * q_prev + (1 - ALPHA_11_4_HZ) * raw
        u = u_prev + duc + kdist * q
        columns.append(np.concatenate([phi @ x + gamma * u, measured, [u, q]]))
    return np.array(columns).T


def _product_controller(kdist: float, increment: str = "backward-difference"):
    params = ControllerParams(
        joints=FlexibleJointParams.uniform(1),
        lqr_weights=LqrWeights(10.0, 1.0, 1.0),
        kdist=kdist,
        dob_cutoff_hz=11.4,
        composition="accumulated",
        discretisation="euler",
        link_velocity_increment=increment,  # type: ignore[arg-type]
    )
    return make_controller(
        "gc+lqr+dob", params, sm=single_link_sm(INERTIA), dt_s=DT_S, gravity=NoGravity()
    )


def test_hand_riccati_gives_the_pinned_gain_and_the_product_designs_the_same() -> None:
    gain, bpb, radius = _hand_riccati()
    np.testing.assert_allclose(gain, [0.216969, 0.998439, 0.671154, -0.0113720], rtol=2e-5)
    assert bpb == pytest.approx(211.42, abs=0.01)
    assert gain[0] == pytest.approx(math.sqrt(10.0 / (1.0 + bpb)), rel=1e-9)  # the (1,1) block
    assert radius == pytest.approx(0.91493, abs=1e-5)
    assert gain[0] / DT_S == pytest.approx(43.39, abs=0.01)
    product = _product_controller(1.0).lqr_gain  # type: ignore[attr-defined]
    np.testing.assert_allclose(product.stacked[0], gain, rtol=1e-7)
    assert product.spectral_radius == pytest.approx(radius, rel=1e-9)
    assert product.dominant_time_constant_s == pytest.approx(0.05624, rel=1e-3)


@pytest.mark.parametrize(
    "kdist, zero_increment, radius",
    [(1.0, False, 0.91387), (0.5, False, 0.90836), (1.0, True, 0.91155), (0.5, True, 0.91903)],
)
def test_sampled_loop_of_the_running_configuration(
    kdist: float, zero_increment: bool, radius: float
) -> None:
    gain, _, _ = _hand_riccati()
    eigenvalues = np.linalg.eigvals(_loop_matrix(gain, kdist, zero_increment))
    assert np.max(np.abs(eigenvalues)) == pytest.approx(radius, abs=2e-5)


@pytest.mark.parametrize("increment", ["backward-difference", "zero"])
def test_the_product_controller_steps_exactly_the_analysed_loop(increment: str) -> None:
    gain, _, _ = _hand_riccati()
    matrix = _loop_matrix(gain, 0.7, increment == "zero")
    controller = _product_controller(0.7, increment)
    a, b = _continuous()
    block = np.zeros((4, 4))
    block[:3, :3], block[:3, 3:] = a, b
    exponential = scipy.linalg.expm(block * DT_S)
    phi, gamma = exponential[:3, :3], exponential[:3, 3]
    x = np.array([0.02, 0.015, 0.0])
    zero = np.zeros(1)
    controller.reset(x[:1], x[1:2], zero, goal_in_force_rad=x[:1])
    z = np.concatenate([x, x[:2], [0.0], x[:1], [0.0]])  # previous = first sample, u = goal
    for _ in range(400):
        goal = controller.step(x[:1], x[1:2], zero)
        controller.notify_applied(goal)
        x = phi @ x + gamma * goal[0]
        z = matrix @ z
        np.testing.assert_allclose(goal[0], z[6], atol=1e-12)
        np.testing.assert_allclose(x, z[:3], atol=1e-12)

"""The controller's model of a fixed-base robot (controller/fixed_base.py) against the two-link
arm's statics and inertia by hand (hil/data/robots/two_link_arm.urdf: both joints turn about
-y, angle 0 horizontal, a positive angle raises the arm):

    tau_g = g [(m1 c1 + m2 l1) cos q1 + m2 c2 cos(q1 + q2),  m2 c2 cos(q1 + q2)]
    M11 = I1 + m1 c1^2 + I2 + m2 (l1^2 + c2^2 + 2 l1 c2 cos q2)
    M12 = I2 + m2 (c2^2 + l1 c2 cos q2),   M22 = I2 + m2 c2^2

with m1 = 1.0 kg, c1 = 0.15 m, l1 = 0.30 m, I1 = 0.0075 kg m^2 (about its CoM, along y),
m2 = 0.6 kg, c2 = 0.125 m, I2 = 0.003125 kg m^2. The joints are coupled: the shoulder carries
the forearm at the elbow's angle, and M has off-diagonal terms (Sm = M^-1 is not diagonal)."""

from __future__ import annotations

from importlib import resources

import numpy as np
import pytest

from controller.fixed_base import FixedBaseGravity, FixedBaseInertia, FixedBaseModel

URDF = resources.files("hil").joinpath("data", "robots", "two_link_arm.urdf").read_text()
M1, C1, L1, I1 = 1.0, 0.15, 0.30, 0.0075
M2, C2, I2 = 0.6, 0.125, 0.003125
G = 9.81


def gravity_by_hand(q1: float, q2: float) -> np.ndarray:
    return G * np.array(
        [(M1 * C1 + M2 * L1) * np.cos(q1) + M2 * C2 * np.cos(q1 + q2), M2 * C2 * np.cos(q1 + q2)]
    )


def mass_by_hand(q2: float) -> np.ndarray:
    m11 = I1 + M1 * C1**2 + I2 + M2 * (L1**2 + C2**2 + 2 * L1 * C2 * np.cos(q2))
    m12 = I2 + M2 * (C2**2 + L1 * C2 * np.cos(q2))
    m22 = I2 + M2 * C2**2
    return np.array([[m11, m12], [m12, m22]])


@pytest.mark.parametrize("q", [(0.0, 0.0), (0.5, -0.3), (-1.1, 1.4), (1.3, 0.7)])
def test_the_gravity_compensator_holds_the_coupled_joints(q: tuple[float, float]) -> None:
    model = FixedBaseModel(URDF, ("shoulder", "elbow"))
    np.testing.assert_allclose(
        FixedBaseGravity(model).gravity_torque(np.array(q)), gravity_by_hand(*q), rtol=1e-9
    )
    # the caller's order, whatever pinocchio's
    reversed_model = FixedBaseModel(URDF, ("elbow", "shoulder"))
    np.testing.assert_allclose(
        reversed_model.gravity_torque(q[::-1]), gravity_by_hand(*q)[::-1], rtol=1e-9
    )


@pytest.mark.parametrize("q2", [0.0, 0.8, -1.7])
def test_sm_is_the_inverse_of_the_coupled_mass_matrix(q2: float) -> None:
    model = FixedBaseModel(URDF, ("shoulder", "elbow"))
    inertia = FixedBaseInertia(model)
    expected = np.linalg.inv(mass_by_hand(q2))
    np.testing.assert_allclose(inertia.sm(np.array([0.3, q2])), expected, rtol=1e-9)
    assert abs(expected[0, 1]) > 0.1 * abs(expected[0, 0])  # coupled, not two pendulums
    diagonal = inertia.sm(np.array([0.3, q2]), diagonal=True)
    np.testing.assert_allclose(diagonal, np.diag(np.diag(expected)), rtol=1e-9)


def test_a_locked_joint_is_carried_at_its_angle() -> None:
    model = FixedBaseModel(URDF, ("shoulder",), {"elbow": 0.5})
    for q1 in (0.0, 0.7):
        assert model.gravity_torque([q1])[0] == pytest.approx(gravity_by_hand(q1, 0.5)[0], rel=1e-9)


def test_joints_the_description_lacks_are_refused() -> None:
    with pytest.raises(ValueError, match="no joints \\['wrist'\\]"):
        FixedBaseModel(URDF, ("shoulder", "wrist"))
    with pytest.raises(ValueError, match="lacks: \\['wrist'\\]"):
        FixedBaseModel(URDF, ("shoulder",), {"wrist": 0.0})

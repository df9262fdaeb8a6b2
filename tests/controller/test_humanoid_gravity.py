"""The humanoid gravity compensator (5)-(8) against independent statics.

The plant-side check of the sign (MuJoCo's spring torques) is in
tests/sim_backend/test_humanoid_statics.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from controller import ControllerParams, make_controller
from controller.humanoid import (
    WALKING_READY_LEG_ANGLES_RAD,
    HumanoidLegGravity,
    LegModel,
    SupportState,
)

URDF_PATH = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"
G = 9.81

# Postures: the walking-ready one, and a random bent one (feet need not be flat for the
# single-support check: the support sole is the root there).
READY = np.array(WALKING_READY_LEG_ANGLES_RAD)
BENT = np.deg2rad([4.0, 3.0, -15.0, 35.0, -18.0, 2.0, -3.0, -6.0, 12.0, -50.0, 30.0, 4.0])


@pytest.fixture(scope="module")
def model() -> LegModel:
    return LegModel(URDF_PATH.read_text())


def potential_energy_torque(model: LegModel, angles: np.ndarray, side: int) -> np.ndarray:
    """dV/dtheta by central differences, V = m g z_com, with sole `side` held flat at the origin
    (the support foot as the fixed root): the exact holding torque, no Jacobian involved."""
    torque = np.zeros(12)
    h = 1e-6
    for j in range(12):
        heights = []
        for sign in (+1, -1):
            perturbed = angles.copy()
            perturbed[j] += sign * h
            q = model.standing_configuration(perturbed, side)
            heights.append(model.centre_of_mass(q)[2])
        torque[j] = model.total_mass_kg * G * (heights[0] - heights[1]) / (2 * h)
    return torque


@pytest.mark.parametrize("angles", [READY, BENT], ids=["ready", "bent"])
@pytest.mark.parametrize("support", [SupportState.LEFT, SupportState.RIGHT])
def test_single_support_equals_potential_energy_gradient(
    model: LegModel, angles: np.ndarray, support: SupportState
) -> None:
    gc = HumanoidLegGravity(model, support)
    expected = potential_energy_torque(model, angles, support.feet[0])
    assert np.allclose(gc.gravity_torque(angles), expected, atol=1e-6)
    # the naive sign of (5) (support force up, or J from the contact to the CoM) is the opposite
    assert not np.allclose(-gc.gravity_torque(angles), expected, atol=1.0)


@pytest.mark.parametrize("support", list(SupportState))
def test_floating_base_statics_of_eq3(model: LegModel, support: SupportState) -> None:
    """(3) at rest: g(theta) = S^T tau_g + sum_i J_i^T F_i with F_i = -f_i the ground's force at
    the contact point. The 6 base rows check that the split forces balance the robot (force
    AND moment: the contact points are chosen for that); the leg rows that tau_g is (5)."""
    gc = HumanoidLegGravity(model, support)
    tau = gc.gravity_torque(READY)
    split = gc.last_split
    assert split is not None
    q = model.configuration(READY, base_rotation=gc.pelvis_rotation(READY))
    model.update_jacobians(q)
    generalized = np.zeros(model.nv)
    generalized[model.leg_v_index] = tau
    for side, force, point in (
        (0, split.left_force_n, split.left_point_m),
        (1, split.right_force_n, split.right_point_m),
    ):
        frame = model.sole_frame_ids[side]
        jacobian = pin.getFrameJacobian(
            model.model, model.data, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        )
        lever = point - model.data.oMf[frame].translation
        point_jacobian = jacobian[:3] - pin.skew(lever) @ jacobian[3:]
        generalized += point_jacobian.T @ (-force)
    gravity = pin.computeGeneralizedGravity(model.model, model.data, q)  # RNEA, independent
    assert np.allclose(generalized, gravity, atol=1e-9)


def test_split_and_knee_sign_in_double_support(model: LegModel) -> None:
    gc = HumanoidLegGravity(model, SupportState.DOUBLE)
    tau = gc.gravity_torque(READY)
    split = gc.last_split
    assert split is not None
    # CoM over the middle of the soles (the posture's definition): mu = 1/2, half the weight each
    assert split.mu == pytest.approx(0.5, abs=1e-6)
    weight = model.total_mass_kg * G
    assert split.left_force_n[2] == pytest.approx(-weight / 2, rel=1e-5)
    assert np.allclose(split.left_force_n + split.right_force_n, [0, 0, -weight])
    # Hand check of the sign: both knees are bent forward (left +42 deg about +y, right -42 deg
    # about -y); gravity bends them further, so the springs push back: the left knee's torque
    # is negative about +y, the right knee's positive about -y, each carrying about a quarter
    # of the weight at a ~0.13 m lever: ~32 N m.
    assert -36 < tau[3] < -28 and 28 < tau[9] < 36


def test_double_support_interpolates_the_split(model: LegModel) -> None:
    """Move the CoM towards the left foot by tilting the posture: mu follows (7)."""
    gc = HumanoidLegGravity(model, SupportState.DOUBLE)
    angles = READY.copy()
    angles[[1, 5, 7, 11]] += np.deg2rad([-4, 4, -4, 4])  # pelvis shifts to +y (left)
    gc.gravity_torque(angles)
    split = gc.last_split
    assert split is not None
    left = split.left_point_m
    right = split.right_point_m
    expected_mu = (split.com_m[1] - left[1]) / (right[1] - left[1])
    assert split.mu == pytest.approx(expected_mu, abs=1e-9)
    assert split.mu < 0.45


def test_total_mass_override_scales_the_forces(model: LegModel) -> None:
    lab = HumanoidLegGravity(model, SupportState.LEFT, total_mass_kg=46.892)
    nominal = HumanoidLegGravity(model, SupportState.LEFT)
    lab.gravity_torque(READY)
    nominal.gravity_torque(READY)
    assert lab.last_split.left_force_n[2] == pytest.approx(-46.892 * G)
    with pytest.raises(ValueError):
        HumanoidLegGravity(model, total_mass_kg=0.0)


def test_measured_pelvis_orientation_changes_tau(model: LegModel) -> None:
    gc = HumanoidLegGravity(model, SupportState.LEFT)
    flat = gc.gravity_torque(READY)
    gc.set_base_rotation(gc.pelvis_rotation(READY) @ pin.exp3(np.array([0.0, 0.05, 0.0])))
    tilted = gc.gravity_torque(READY)
    assert np.max(np.abs(tilted - flat)) > 1.0
    gc.set_base_rotation(None)
    assert np.allclose(gc.gravity_torque(READY), flat)


def test_plugs_into_make_controller(model: LegModel) -> None:
    """The loop's "gc" controller with this model: u = theta_d + K^-1 tau_g (8)."""
    gc = HumanoidLegGravity(model, SupportState.DOUBLE)
    params = ControllerParams.paper(12)
    controller = make_controller("gc", params, sm=np.eye(12), dt_s=0.005, gravity=gc)
    controller.reset(READY, READY, READY)
    goal = controller.step(READY, READY, READY)
    assert np.allclose(goal, READY + gc.gravity_torque(READY) / 2000.0)


def test_support_switch_with_the_same_reference(model: LegModel) -> None:
    """The held-reference cache must not hide a change of support state."""
    gc = HumanoidLegGravity(model, SupportState.LEFT)
    left = gc.gravity_torque(READY)
    gc.set_support(SupportState.RIGHT)
    right = gc.gravity_torque(READY)
    assert np.max(np.abs(left - right)) > 10.0
    gc.set_support(SupportState.LEFT)
    again = gc.gravity_torque(READY)
    assert np.array_equal(again, left)
    again[:] = 0.0  # the caller owns the returned array; the cache keeps its own copy
    assert np.array_equal(gc.gravity_torque(READY), left)


def test_half_rotation_matches_pinocchio() -> None:
    from controller.humanoid.gravity import _half_rotation

    rng = np.random.default_rng(3)
    for angle in (1e-9, 1e-4, 0.3, 2.5, 3.1):  # below pi, where the rotation vector is unique
        direction = rng.normal(0, 1, 3)
        vector = angle * direction / np.linalg.norm(direction)
        rotation = pin.exp3(vector)
        assert np.allclose(_half_rotation(rotation), pin.exp3(0.5 * vector), atol=1e-12)


def accelerating_potential_torque(
    model: LegModel, angles: np.ndarray, side: int, acceleration: np.ndarray
) -> np.ndarray:
    """d/dtheta of m (g z + a) . c by central differences, sole `side` the fixed root: the
    holding torque of the robot whose every body accelerates with its CoM at `a` (d'Alembert:
    gravity g - a), no Jacobian of ours involved."""
    direction = np.array([0.0, 0.0, G]) + acceleration
    torque = np.zeros(12)
    h = 1e-6
    for j in range(12):
        values = []
        for sign in (+1, -1):
            perturbed = angles.copy()
            perturbed[j] += sign * h
            q = model.standing_configuration(perturbed, side)
            values.append(model.total_mass_kg * direction @ model.centre_of_mass(q))
        torque[j] = (values[0] - values[1]) / (2 * h)
    return torque


@pytest.mark.parametrize("angles", [READY, BENT], ids=["ready", "bent"])
def test_the_planned_load_is_the_holding_torque_under_g_minus_a(
    model: LegModel, angles: np.ndarray
) -> None:
    """(5) for a planned motion (ours): f = m (g - a) through the CoM. On one foot it equals the
    gradient of m (g z + a) . c with the stance sole fixed, for a walk's accelerations (~1 m/s^2
    sideways and forwards), and the stance ankle roll's torque changes by m a_y times the CoM's
    height above the ankle axis (the cart-table's ZMP shift (z_c / g) a_y, times m g)."""
    acceleration = np.array([0.6, -1.1, 0.0])
    gc = HumanoidLegGravity(model, SupportState.LEFT)
    static = gc.gravity_torque(angles)
    gc.set_planned_load(acceleration, None)
    planned = gc.gravity_torque(angles)
    expected = accelerating_potential_torque(model, angles, 0, acceleration)
    assert np.allclose(planned, expected, atol=1e-5)
    q = model.standing_configuration(angles, 0)
    model.update_kinematics(q)
    height = model.centre_of_mass(q)[2] - model.ft_sensor_placement(0).translation[2]
    if np.allclose(angles, READY):  # the ankle roll axis is level at the walking-ready posture
        roll_change = abs(planned[5] - static[5])
        assert roll_change == pytest.approx(model.total_mass_kg * 1.1 * height, rel=0.02)
    gc.set_planned_load(None, None)
    assert np.array_equal(gc.gravity_torque(angles), static)


def test_the_planned_split_replaces_the_coms_in_double_support(model: LegModel) -> None:
    """In double support the planned ZMP's mu replaces the CoM's in (6)-(7) (the forces split
    (1 - mu, mu)); given the CoM's own mu it is the paper's split, to round-off; the support
    state's 0 and 1 stay in single support."""
    gc = HumanoidLegGravity(model, SupportState.DOUBLE)
    static = gc.gravity_torque(BENT)
    mu = gc.last_split.mu
    gc.set_planned_load(None, 0.3)
    planned = gc.gravity_torque(BENT)
    split = gc.last_split
    assert split.mu == 0.3
    assert np.allclose(split.left_force_n, 0.7 * gc.weight_n)
    assert np.max(np.abs(planned - static)) > 1.0
    gc.set_planned_load(None, mu)
    assert np.allclose(gc.gravity_torque(BENT), static, atol=1e-9)
    gc.set_support(SupportState.RIGHT)
    gc.set_planned_load(None, 0.3)
    gc.gravity_torque(BENT)
    assert gc.last_split.mu == 1.0

"""Sm of (19) with the support foot's contact, against a projection built by hand with numpy."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from controller import ControllerParams
from controller.humanoid import (
    WALKING_READY_LEG_ANGLES_RAD,
    ContactProjectedInertia,
    LegModel,
    SmCoupling,
    SupportState,
)
from controller.model import validate_sm

URDF_PATH = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"
READY = np.array(WALKING_READY_LEG_ANGLES_RAD)
BENT = np.deg2rad([4.0, 3.0, -15.0, 35.0, -18.0, 2.0, -3.0, -6.0, 12.0, -50.0, 30.0, 4.0])


@pytest.fixture(scope="module")
def model() -> LegModel:
    return LegModel(URDF_PATH.read_text())


def hand_built_sm(model: LegModel, angles: np.ndarray, support: SupportState) -> np.ndarray:
    """S M^-1 (I - Jc^T Jc_bar^T) S^T with M from crba, Jc from the sole frames, numpy only."""
    data = model.model.createData()
    q = model.configuration(angles)
    inertia = pin.crba(model.model, data, q)
    inertia = np.triu(inertia) + np.triu(inertia, 1).T
    pin.computeJointJacobians(model.model, data, q)
    pin.updateFramePlacements(model.model, data)
    jacobian = np.vstack(
        [
            pin.getFrameJacobian(
                model.model, data, model.sole_frame_ids[side], pin.ReferenceFrame.WORLD
            )
            for side in support.feet
        ]
    )
    m_inv = np.linalg.inv(inertia)
    lam = np.linalg.inv(jacobian @ m_inv @ jacobian.T)
    jc_bar = m_inv @ jacobian.T @ lam  # dynamically consistent inverse
    projector = np.eye(model.nv) - jacobian.T @ jc_bar.T  # I - Pc
    full = m_inv @ projector
    legs = model.leg_v_index
    return full[np.ix_(legs, legs)]


@pytest.mark.parametrize("angles", [READY, BENT], ids=["ready", "bent"])
@pytest.mark.parametrize("support", list(SupportState))
def test_sm_equals_hand_built_projection(
    model: LegModel, angles: np.ndarray, support: SupportState
) -> None:
    sm = ContactProjectedInertia(model).sm(angles, support)
    expected = hand_built_sm(model, angles, support)
    assert np.allclose(sm, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    diagonal = ContactProjectedInertia(model).sm(angles, support, SmCoupling.DIAGONAL)
    assert np.allclose(diagonal, np.diag(np.diag(expected)), rtol=1e-9)


@pytest.mark.parametrize("support", list(SupportState))
def test_support_feet_cannot_accelerate(model: LegModel, support: SupportState) -> None:
    """Jc M^-1 (I - Pc) = 0: no joint torque accelerates a foot the ground holds."""
    projection = ContactProjectedInertia(model)
    projected = projection.projected_inverse_inertia(BENT, support)
    jacobian = projection.contact_jacobian(support)
    assert np.abs(jacobian @ projected).max() < 1e-9 * np.abs(projected).max()


@pytest.mark.parametrize("support", list(SupportState))
def test_sm_is_a_valid_symmetric_psd_matrix(model: LegModel, support: SupportState) -> None:
    sm = ContactProjectedInertia(model).sm(READY, support)
    validate_sm(sm, 12)
    assert np.linalg.eigvalsh(sm).min() > -1e-9


def test_support_leg_is_stiffer_than_swing_leg(model: LegModel) -> None:
    """Left support: the left leg's diagonal (ground-held) is far below the free right leg's."""
    diagonal = np.diag(ContactProjectedInertia(model).sm(READY, SupportState.LEFT))
    assert diagonal[1:6].max() < diagonal[7:12].min()
    # double support holds both legs: every entry below the swing leg's single-support value
    double = np.diag(ContactProjectedInertia(model).sm(READY, SupportState.DOUBLE))
    assert np.all(double[6:] <= diagonal[6:] + 1e-12)


def test_invariant_to_the_base_pose(model: LegModel) -> None:
    """The documented reason only leg angles are needed: a turned, moved base changes nothing."""
    projection = ContactProjectedInertia(model)
    reference = projection.sm(BENT, SupportState.RIGHT)
    data = model.model.createData()
    q = model.configuration(BENT, [0.3, -1.0, 0.8], pin.exp3(np.array([0.2, -0.4, 1.0])))
    pin.computeJointJacobians(model.model, data, q)
    pin.updateFramePlacements(model.model, data)
    jacobian = pin.getFrameJacobian(
        model.model, data, model.sole_frame_ids[1], pin.ReferenceFrame.LOCAL
    )
    kkt = pin.computeKKTContactDynamicMatrixInverse(model.model, data, q, jacobian)
    legs = model.leg_v_index
    assert np.allclose(kkt[np.ix_(legs, legs)], reference, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("coupling", ["full", "diagonal"])
def test_sm_feeds_the_lqr_design(model: LegModel, coupling: str) -> None:
    """The LQR gain for 12 joints from this Sm (single support) exists and its sampled loop is
    stable (what it costs: `hil bench loop --robot dyros-jet`)."""
    projection = ContactProjectedInertia(model)
    params = ControllerParams.paper(12, lqr_coupling=coupling)
    sm = projection.sm(READY, SupportState.LEFT, SmCoupling(coupling))
    gain = params.design_gain(sm, 0.005)
    assert gain.n_joints == 12
    assert gain.spectral_radius < 1.0

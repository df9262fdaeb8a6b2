"""The controller's rigid-body model of DYROS-JET's legs (pinocchio), built from URDF text.

The robot description is a URDF (the product ships `hil/data/robots/dyros_jet.urdf`); the caller
passes its text, so the controller and the emulator read the same figures. This module:

- builds the whole robot with pinocchio; the URDF's own floating joint ("virtual") becomes the
  free flyer (no extra root joint is added: that would stack a second one);
- locks the waist and both arms with `pinocchio.buildReducedModel` at a stated posture
  (`UpperBodyPosture`), leaving nq = 7 + 12, nv = 6 + 12: the floating base and the 12 leg
  joints, which is what the paper's (3) and (19) need;
- orders the 12 leg joints as the lab's code does (`LEG_JOINT_NAMES`: left hip yaw, roll, pitch,
  knee, ankle pitch, ankle roll, then the right leg), whatever order pinocchio uses inside;
- adds one frame per foot at the centre of the sole's bottom face, read from the URDF's box
  collision under each `*_AnkleRoll_Link` (the description's only geometry).

Conventions: angles rad, lengths m, the world z axis up, gravity -9.81 m/s^2 along z (pinocchio's
default). A configuration is given as (base pose, 12 link angles); `configuration` packs it into
pinocchio's q = [position (3), quaternion x y z w (4), joints in pinocchio's order].
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

# DYROS-JET's leg joints and upper body: the controller's one copy (the emulator holds its own,
# sim_backend/humanoid/params.py; tests/hil/test_dyros_jet_facts.py keeps them equal).
LEFT_LEG_JOINT_NAMES: tuple[str, ...] = (
    "L_HipYaw",
    "L_HipRoll",
    "L_HipPitch",
    "L_KneePitch",
    "L_AnklePitch",
    "L_AnkleRoll",
)
RIGHT_LEG_JOINT_NAMES: tuple[str, ...] = tuple("R" + name[1:] for name in LEFT_LEG_JOINT_NAMES)
LEG_JOINT_NAMES: tuple[str, ...] = LEFT_LEG_JOINT_NAMES + RIGHT_LEG_JOINT_NAMES
N_LEG_JOINTS = len(LEG_JOINT_NAMES)
FOOT_LINK_NAMES: tuple[str, str] = ("L_AnkleRoll_Link", "R_AnkleRoll_Link")
SOLE_FRAME_NAMES: tuple[str, str] = ("L_sole", "R_sole")
# The feet's force/torque sensors sit at the ankle axis, in the *_AnkleRoll_Link frame (where the
# lab's MuJoCo model has its foot F/T sites; the emulated robot measures there).
FT_SENSOR_FRAME_NAMES: tuple[str, str] = FOOT_LINK_NAMES
FLOATING_JOINT_NAME = "virtual"

# The lab's "Init Walking" posture for the upper body (psh117/dyros_jet, dyros_jet_gui
# task_window.cpp, on_button_walk_init_wholebody_clicked; rad, URDF joint conventions):
# waist straight, arms hanging bent beside the body (the shoulder-roll limits of the published
# URDF exclude 0, so "all zero" is not a posture of this robot).
LAB_WALK_INIT_UPPER_BODY_RAD: Mapping[str, float] = {
    "WaistPitch": 0.0,
    "WaistYaw": 0.0,
    "L_ShoulderPitch": 0.6981317008,
    "L_ShoulderRoll": -1.6580627893,
    "L_ShoulderYaw": -1.3962634016,
    "L_ElbowRoll": -1.9198621771,
    "L_WristYaw": 0.0,
    "L_WristRoll": -1.2217304764,
    "L_HandYaw": -0.1745329252,
    "R_ShoulderPitch": -0.6981317008,
    "R_ShoulderRoll": 1.6580627893,
    "R_ShoulderYaw": 1.3962634016,
    "R_ElbowRoll": 1.9198621771,
    "R_WristYaw": 0.0,
    "R_WristRoll": 1.2217304764,
    "R_HandYaw": 0.17453292519,
}


@dataclass(frozen=True)
class UpperBodyPosture:
    """The angles [rad] at which the waist and arm joints are locked (every non-leg joint).

    Default: the lab's "Init Walking" upper body (LAB_WALK_INIT_UPPER_BODY_RAD).
    """

    joint_angles_rad: Mapping[str, float] = field(
        default_factory=lambda: dict(LAB_WALK_INIT_UPPER_BODY_RAD)
    )


@dataclass(frozen=True)
class SoleBox:
    """A foot's sole box as the URDF gives it: centre and full size in the foot link's frame."""

    link_name: str
    centre_m: np.ndarray
    size_m: np.ndarray

    @property
    def bottom_centre_m(self) -> np.ndarray:
        """Centre of the sole's bottom face (the contact plane) in the foot link's frame."""
        return self.centre_m - np.array([0.0, 0.0, self.size_m[2] / 2.0])


def sole_boxes_from_urdf(urdf_text: str) -> tuple[SoleBox, SoleBox]:
    """The box collision of each foot link (left, right); the URDF must give exactly one each."""
    root = ET.fromstring(urdf_text)
    boxes = []
    for link_name in FOOT_LINK_NAMES:
        link = root.find(f"link[@name='{link_name}']")
        if link is None:
            raise ValueError(f"the robot description has no link {link_name!r}")
        found = [
            collision
            for collision in link.findall("collision")
            if collision.find("geometry/box") is not None
        ]
        if len(found) != 1:
            raise ValueError(f"{link_name} needs exactly one box collision (the sole)")
        collision = found[0]
        origin = collision.find("origin")
        xyz = origin.get("xyz", "0 0 0") if origin is not None else "0 0 0"
        rpy = origin.get("rpy", "0 0 0") if origin is not None else "0 0 0"
        if np.any(np.abs(np.fromstring(rpy, sep=" ")) > 0):
            raise ValueError(f"{link_name}: a rotated sole box is not supported")
        size = collision.find("geometry/box").get("size")
        boxes.append(SoleBox(link_name, np.fromstring(xyz, sep=" "), np.fromstring(size, sep=" ")))
    return boxes[0], boxes[1]


class LegModel:
    """pinocchio model of the floating base and the 12 leg joints (upper body locked).

    Attributes: `model`, `data` (pinocchio; one `data` per LegModel: not thread-safe),
    `full_model` (all 28 joints), `sole_frame_ids` (left, right), `total_mass_kg`.
    """

    def __init__(self, urdf_text: str, upper_body: UpperBodyPosture | None = None) -> None:
        upper_body = upper_body or UpperBodyPosture()
        full = pin.buildModelFromXML(urdf_text)
        if full.names[1] != FLOATING_JOINT_NAME or full.joints[1].nv != 6:
            raise ValueError(
                f"the robot description must start with the floating joint {FLOATING_JOINT_NAME!r}"
            )
        self.full_model = full
        q_lock = pin.neutral(full)
        lock_ids = []
        for joint_id in range(2, full.njoints):
            name = full.names[joint_id]
            if name in LEG_JOINT_NAMES:
                continue
            if name not in upper_body.joint_angles_rad:
                raise ValueError(f"no locked angle given for the upper-body joint {name!r}")
            q_lock[full.joints[joint_id].idx_q] = upper_body.joint_angles_rad[name]
            lock_ids.append(joint_id)
        unknown = set(upper_body.joint_angles_rad) - {full.names[i] for i in lock_ids}
        if unknown:
            raise ValueError(f"upper-body posture names joints the model lacks: {sorted(unknown)}")
        self.upper_body = upper_body
        model = pin.buildReducedModel(full, lock_ids, q_lock)
        missing = [name for name in LEG_JOINT_NAMES if not model.existJointName(name)]
        if missing:
            raise ValueError(f"the robot description lacks the leg joints {missing}")
        for side, box in zip(SOLE_FRAME_NAMES, sole_boxes_from_urdf(urdf_text), strict=True):
            parent_frame = model.getFrameId(box.link_name)
            frame = model.frames[parent_frame]
            placement = frame.placement * pin.SE3(np.eye(3), box.bottom_centre_m)
            model.addFrame(
                pin.Frame(side, frame.parentJoint, parent_frame, placement, pin.FrameType.OP_FRAME)
            )
        self.model = model
        self.data = model.createData()
        self.sole_boxes = sole_boxes_from_urdf(urdf_text)
        self.sole_frame_ids = tuple(model.getFrameId(name) for name in SOLE_FRAME_NAMES)
        self.ft_sensor_frame_ids = tuple(model.getFrameId(name) for name in FT_SENSOR_FRAME_NAMES)
        # Index maps between the lab's leg order and pinocchio's q / v vectors.
        self.leg_q_index = np.array(
            [model.joints[model.getJointId(name)].idx_q for name in LEG_JOINT_NAMES]
        )
        self.leg_v_index = np.array(
            [model.joints[model.getJointId(name)].idx_v for name in LEG_JOINT_NAMES]
        )
        self.total_mass_kg = float(pin.computeTotalMass(model))

    # --- configuration ------------------------------------------------------------------------
    @property
    def nq(self) -> int:
        return int(self.model.nq)

    @property
    def nv(self) -> int:
        return int(self.model.nv)

    def configuration(
        self,
        leg_angles_rad: Sequence[float] | np.ndarray,
        base_position_m: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
        base_rotation: np.ndarray | None = None,
    ) -> np.ndarray:
        """pinocchio's q for this base pose (rotation matrix, world <- pelvis) and leg angles."""
        angles = np.asarray(leg_angles_rad, dtype=float)
        if angles.shape != (N_LEG_JOINTS,):
            raise ValueError(f"leg_angles_rad must have {N_LEG_JOINTS} entries, got {angles.shape}")
        q = np.zeros(self.nq)
        q[:3] = base_position_m
        if base_rotation is None:
            q[6] = 1.0  # identity quaternion, x y z w
        else:
            q[3:7] = pin.Quaternion(np.asarray(base_rotation, dtype=float)).coeffs()
        q[self.leg_q_index] = angles
        return q

    def leg_angles(self, q: np.ndarray) -> np.ndarray:
        """The 12 leg angles (lab order) of a configuration."""
        return np.asarray(q)[self.leg_q_index].copy()

    # --- kinematics ---------------------------------------------------------------------------
    def update_kinematics(self, q: np.ndarray) -> None:
        """Forward kinematics and frame placements for q (results in self.data)."""
        pin.forwardKinematics(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)

    def update_jacobians(self, q: np.ndarray) -> None:
        """Forward kinematics, frame placements, joint Jacobians (data.J) and the CoM Jacobian
        (data.Jcom) and CoM (data.com[0]) for q."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        pin.jacobianCenterOfMass(self.model, self.data, True)

    def sole_placement(self, side: int) -> pin.SE3:
        """World placement of the sole frame (0 left, 1 right) after update_kinematics."""
        return self.data.oMf[self.sole_frame_ids[side]]

    def ft_sensor_placement(self, side: int) -> pin.SE3:
        """World placement of foot `side`'s force/torque sensor frame after update_kinematics
        (e.g. for `zmp_from_foot_wrenches`, with q from `standing_configuration`)."""
        return self.data.oMf[self.ft_sensor_frame_ids[side]]

    def centre_of_mass(self, q: np.ndarray) -> np.ndarray:
        """World position of the whole robot's centre of mass [m] (upper body included)."""
        return pin.centerOfMass(self.model, self.data, q).copy()

    def base_rotation_for_flat_sole(self, leg_angles_rad: np.ndarray, side: int) -> np.ndarray:
        """Pelvis rotation (world <- pelvis) that puts sole `side` flat (sole frame = world axes).

        With a free base the pelvis orientation follows from the support foot: a foot flat on
        level ground fixes it (up to a yaw, which gravity does not see; the foot's yaw is zero).
        """
        self.update_kinematics(self.configuration(leg_angles_rad))
        return self.sole_placement(side).rotation.T.copy()

    def standing_configuration(
        self, leg_angles_rad: np.ndarray, side: int = 0, ground_height_m: float = 0.0
    ) -> np.ndarray:
        """q with sole `side` flat on the ground plane, its centre at the origin's x y = 0; the
        frames (sole_placement, ft_sensor_placement) are left at this q."""
        rotation = self.base_rotation_for_flat_sole(leg_angles_rad, side)
        q = self.configuration(leg_angles_rad, base_rotation=rotation)
        self.update_kinematics(q)
        sole = self.sole_placement(side).translation
        q[:3] = -sole + np.array([0.0, 0.0, ground_height_m])
        self.update_kinematics(q)
        return q

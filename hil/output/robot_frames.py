"""Every link's frame from a run's logged link angles: the controller's model of the robot
(pinocchio) forward, one transform per URDF joint (parent link -> child link), as /tf carries it.

    moving   the joints the run logs (their measured link angles) and, on the humanoid, the
             floating base world -> base_link
    static   every other joint: fixed joints, and the humanoid's waist and arms, which the
             controller's model locks at its upper-body posture (the emulator welds them there)

The humanoid's floating base is not in log.csv (no sensor of the robot measures it). Where an
embedded emulator ran the robot, its ground truth is beside the run (emulator_truth.csv,
sim_backend/truth_log.py: `BaseTruth`), and a finished run's viewers use it (TRUTH_NOTE says
so); otherwise, and live, it is estimated by leg odometry on the same model
(`StanceFootOdometry`): the stance foot stays where it landed and the pelvis hangs from it
through the measured leg angles (BASE_POSE_NOTE says so).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hil.output.robot_description import RunRobot

if TYPE_CHECKING:
    import pinocchio as pin

    from controller.humanoid import LegModel

WORLD_FRAME = "world"
BASE_POSE_NOTE = (
    "world -> base_link is not measured: the emulator's pelvis pose is not in log.csv. It is "
    "leg odometry on the controller's model: the stance foot (the one its force sensor loads "
    "more) is held where it landed, the pelvis placed from it through the measured link "
    "angles; at the start the soles' midpoint is at the origin and the stance sole flat at z = 0"
)
TRUTH_NOTE = (
    "world -> base_link is the emulator's ground truth (its pelvis pose in its world, "
    "emulator_truth.csv), not a measurement: the robot's own sensors do not report it"
)
TRUTH_LOG_NAME = "emulator_truth.csv"  # (sim_backend/truth_log.py writes it)
# A foot becomes the stance foot when it carries this fraction of the feet's vertical load
# more than the stance foot does (no chatter while both are loaded alike)
STANCE_SWITCH_MARGIN = 0.2


@dataclass(frozen=True)
class FrameTransform:
    """The child frame's pose in the parent frame: translation [m], rotation (x, y, z, w)."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


@dataclass(frozen=True)
class _UrdfJoint:
    name: str
    kind: str
    parent: str
    child: str


def _urdf_joints(urdf: str) -> list[_UrdfJoint]:
    return [
        _UrdfJoint(
            joint.get("name", ""),
            joint.get("type", ""),
            joint.find("parent").get("link", ""),  # type: ignore[union-attr]
            joint.find("child").get("link", ""),  # type: ignore[union-attr]
        )
        for joint in ET.fromstring(urdf).findall("joint")
    ]


class BaseTruth:
    """The emulator's pelvis pose per SYNC (emulator_truth.csv), looked up by the run's time."""

    def __init__(self, time_s: np.ndarray, positions: np.ndarray, quaternions: np.ndarray) -> None:
        self.time_s = time_s
        self.positions = positions  # (n, 3) [m]
        self.quaternions = quaternions  # (n, 4): x, y, z, w

    @classmethod
    def of_run(cls, run_dir: Path) -> BaseTruth | None:
        """The truth beside a run, or None (not emulated by an embedded emulator, or torn)."""
        path = Path(run_dir) / TRUTH_LOG_NAME
        try:
            table = np.genfromtxt(path, delimiter=",", names=True, invalid_raise=False)
        except (OSError, ValueError):
            return None
        names = table.dtype.names or ()
        wanted = ("base_x_m", "base_y_m", "base_z_m", "base_qx", "base_qy", "base_qz", "base_qw")
        if table.size == 0 or "time_s" not in names or not set(wanted) <= set(names):
            return None
        table = np.atleast_1d(table)
        columns = np.column_stack([table[name] for name in wanted])
        return cls(np.asarray(table["time_s"]), columns[:, :3], columns[:, 3:])

    def at(self, time_s: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(position, quaternion x y z w) at the run's time, None where the truth has no row
        within a millisecond of it."""
        i = int(np.searchsorted(self.time_s, time_s))
        near = [j for j in (i - 1, i) if 0 <= j < len(self.time_s)]
        if not near:
            return None
        best = min(near, key=lambda j: abs(self.time_s[j] - time_s))
        if abs(self.time_s[best] - time_s) > 1e-3:
            return None
        return self.positions[best], self.quaternions[best]


class RobotFrames:
    """The transforms of a run's robot (module docstring); a robot without a description has
    no frames (`robot_frames` returns None). `truth`: the emulator's pelvis pose, if known."""

    def __init__(self, robot: RunRobot, truth: BaseTruth | None = None) -> None:
        import pinocchio as pin

        assert robot.urdf is not None
        self._pin = pin
        self.joint_names = robot.joint_names
        joints = _urdf_joints(robot.urdf)
        self._odometry: StanceFootOdometry | None = None
        if robot.floating_base:
            from controller.humanoid import LegModel

            legs = LegModel(robot.urdf)
            self.model, self.data = legs.model, legs.model.createData()
            self._odometry = StanceFootOdometry(legs, robot)
            self._q_index = legs.leg_q_index
        else:
            self.model = pin.buildModelFromXML(robot.urdf)
            self.data = self.model.createData()
            missing = [n for n in self.joint_names if not self.model.existJointName(n)]
            if missing:
                raise ValueError(f"the robot's URDF has no joints {missing}")
            self._q_index = np.array(
                [self.model.joints[self.model.getJointId(n)].idx_q for n in self.joint_names]
            )
        self._truth = truth if robot.floating_base else None
        moved = set(self.joint_names)
        self._moving = [j for j in joints if j.name in moved]
        self._frames = {
            j: (self.model.getFrameId(j.parent), self.model.getFrameId(j.child))
            for j in joints
            if j.kind != "floating"
        }
        self._base = next((j for j in joints if j.kind == "floating"), None)
        self._q = pin.neutral(self.model)  # the base (if any) at the origin, for ever
        self._forward(self._q)
        self.static_transforms = tuple(
            self._relative(j) for j in joints if j.kind != "floating" and j.name not in moved
        )

    @property
    def base_estimated(self) -> bool:
        return self._odometry is not None and self._truth is None

    @property
    def base_note(self) -> str:
        """Where world -> base_link comes from, for the channels' metadata ("" no base)."""
        if self._odometry is None:
            return ""
        return TRUTH_NOTE if self._truth is not None else BASE_POSE_NOTE

    def at(
        self,
        link_angles_rad: np.ndarray,
        sensors: Mapping[str, float],
        time_s: float | None = None,
    ) -> list[FrameTransform] | None:
        """The moving transforms at these link angles (joint order), `sensors` the tick's
        sensor columns (the feet's loads for the odometry), `time_s` the run's time (for the
        truth); None while an angle is not read."""
        angles = np.asarray(link_angles_rad, dtype=float)
        if not np.all(np.isfinite(angles)):
            return None
        self._q[self._q_index] = angles  # the base at the origin: link to link is the same
        self._forward(self._q)
        transforms = []
        if self._odometry is not None:
            assert self._base is not None
            base = self._odometry.base_pose(self.data.oMf, sensors)  # (kept up to date)
            pose = self._truth_at(time_s)
            if pose is not None:
                transforms.append(FrameTransform(self._base.parent, self._base.child, *pose))
            else:
                transforms.append(
                    _transform(self._base.parent, self._base.child, base.translation, base.rotation)
                )
        transforms.extend(self._relative(j) for j in self._moving)
        return transforms

    def _truth_at(
        self, time_s: float | None
    ) -> tuple[tuple[float, float, float], tuple[float, float, float, float]] | None:
        if self._truth is None or time_s is None:
            return None
        found = self._truth.at(time_s)
        if found is None:
            return None
        (tx, ty, tz), (qx, qy, qz, qw) = found[0].tolist(), found[1].tolist()
        return (tx, ty, tz), (qx, qy, qz, qw)

    def _forward(self, q: np.ndarray) -> None:
        self._pin.forwardKinematics(self.model, self.data, q)
        self._pin.updateFramePlacements(self.model, self.data)

    def _relative(self, joint: _UrdfJoint) -> FrameTransform:
        parent, child = self._frames[joint]
        placement = self.data.oMf[parent].actInv(self.data.oMf[child])
        return _transform(joint.parent, joint.child, placement.translation, placement.rotation)


def robot_frames(robot: RunRobot, truth: BaseTruth | None = None) -> RobotFrames | None:
    """The frames of a run's robot, or None if there is no description of it."""
    return RobotFrames(robot, truth) if robot.urdf is not None else None


def _transform(
    parent: str, child: str, translation: np.ndarray, rotation: np.ndarray
) -> FrameTransform:
    x, y, z, w = _quaternion(rotation)
    tx, ty, tz = (float(v) for v in translation)
    return FrameTransform(parent, child, (tx, ty, tz), (x, y, z, w))


def _quaternion(rotation: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation matrix, w >= 0 (Shepperd's method, as Eigen's)."""
    m = np.asarray(rotation, dtype=float)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = ((m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4)
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(max(1.0 + m[i, i] - m[j, j] - m[k, k], 0.0))
        v = [0.0, 0.0, 0.0]
        v[i] = s / 4
        v[j] = (m[j, i] + m[i, j]) / s
        v[k] = (m[k, i] + m[i, k]) / s
        q = (v[0], v[1], v[2], (m[k, j] - m[j, k]) / s)
    if q[3] < 0:
        q = tuple(-c for c in q)  # type: ignore[assignment]
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


class StanceFootOdometry:
    """The humanoid's pelvis pose from its leg angles and foot loads (BASE_POSE_NOTE)."""

    def __init__(self, legs: LegModel, robot: RunRobot) -> None:
        self.legs = legs
        loads = {s.frame_id: s.columns[2] for s in robot.force_sensors}
        from controller.humanoid.leg_model import FOOT_LINK_NAMES

        # the vertical-force column of each foot (left, right), "" where the log has none
        self._load_columns = tuple(loads.get(link, "") for link in FOOT_LINK_NAMES)
        self._stance: int | None = None
        self._stance_sole: pin.SE3 | None = None  # world <- stance sole

    def base_pose(self, placements: Sequence[pin.SE3], sensors: Mapping[str, float]) -> pin.SE3:
        """base_link in world, from the frame placements of forward kinematics with the base at
        the origin (pinocchio's data.oMf) and the tick's sensor columns."""
        soles = [placements[frame] for frame in self.legs.sole_frame_ids]  # base <- sole
        loads = [float(sensors.get(c, math.nan)) if c else math.nan for c in self._load_columns]
        if self._stance is None or self._stance_sole is None:
            self._start(soles, loads)
        assert self._stance is not None and self._stance_sole is not None
        base = self._stance_sole * soles[self._stance].inverse()
        other = 1 - self._stance
        if _loaded_more(loads[other], loads[self._stance]):
            self._stance, self._stance_sole = other, base * soles[other]
        return base

    def _start(self, soles: Sequence[pin.SE3], loads: Sequence[float]) -> None:
        import pinocchio as pin

        stance = 1 if _loaded_more(loads[1], loads[0]) else 0
        base = pin.SE3(soles[stance].rotation.T.copy(), np.zeros(3))  # the stance sole flat
        left, right = (base * sole for sole in soles)
        shift = -0.5 * (left.translation + right.translation)
        shift[2] = -(base * soles[stance]).translation[2]
        base.translation = shift
        self._stance, self._stance_sole = stance, base * soles[stance]


def _loaded_more(load: float, than: float) -> bool:
    if not (math.isfinite(load) and math.isfinite(than)):
        return False
    return load - than > STANCE_SWITCH_MARGIN * max(abs(load) + abs(than), 1e-9)

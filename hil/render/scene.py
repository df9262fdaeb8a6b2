"""A run's robot in MuJoCo for drawing: the emulator's own model of it (sim_backend), with the
shapes of its viewer URDF (hil/output/robot_description.py) added as geoms that take no part in
contact, a floor, light, and the experiment's world (the testbed's block, the humanoid's box),
posed tick by tick from the run's log.

    testbed    sim_backend/plant.py's MJCF: rotor hinge = the logged motor angle, gear hinge =
               the logged deflection (so the link is at the logged link angle)
    DYROS-JET  sim_backend/humanoid/mjcf.py's rigid robot: the 12 leg hinges at the logged link
               angles; the floating base is not in log.csv: the emulator's truth beside the
               run (emulator_truth.csv) where there is one, else the leg odometry of the ROS 2
               bag's /tf (hil/output/robot_frames.py, BASE_POSE_NOTE): the stance foot held
               where it landed (measured against the emulator's pelvis: within 7 mm over an 8 s
               slow walk, 6 cm sideways after the step onto the box)

Nothing here steps the physics: every frame is the kinematics of one logged tick.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from hil.output.robot_description import RunRobot, robot_of_run
from hil.output.robot_frames import BaseTruth, RobotFrames, robot_frames
from hil.output.run_samples import run_joint_names, sensor_columns
from hil.output.rundir import RunData

if TYPE_CHECKING:
    pass

OBJECT_RGBA = (0.55, 0.38, 0.22, 1.0)
TESTBED_FLOOR_Z_M = -0.85  # the testbed's link swings 0.7 m about an axis this high


@dataclass(frozen=True)
class WorldObjects:
    """What the experiment puts in the robot's world: the testbed's block (the link angle at
    which the load touches it) and the humanoid's boxes (centre x y, size x y z)."""

    block_contact_angle_rad: float | None = None
    boxes: tuple[tuple[tuple[float, float], tuple[float, float, float]], ...] = ()


class RunScene:
    """The MuJoCo model of a run's robot and its world; `pose(i)` puts it at log row i."""

    def __init__(self, run: RunData, world: WorldObjects) -> None:
        import mujoco

        self._mj = mujoco
        self.run = run
        self.robot: RunRobot = robot_of_run(run.meta, run_joint_names(run), sensor_columns(run))
        if self.robot.viewer_urdf is None:
            raise ValueError(f"{run.out_dir}: no robot description to draw this run's robot")
        self.humanoid = self.robot.floating_base
        floor_z = 0.0 if self.humanoid else TESTBED_FLOOR_Z_M
        spec = mujoco.MjSpec.from_string(_staged(self._mjcf(world), floor_z))
        _add_viewer_shapes(spec, self.robot.viewer_urdf, mujoco)
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self._link = np.array(run.per_joint("link_angle_rad"))
        self._motor = np.array(run.per_joint("motor_angle_rad"))
        truth = BaseTruth.of_run(run.out_dir) if self.humanoid else None
        self.base_from_truth = truth is not None
        self._frames: RobotFrames | None = (
            robot_frames(self.robot, truth) if self.humanoid else None
        )
        self._bases: list[np.ndarray] = []  # the odometry is sequential: every row, once
        names = self.robot.joint_names if self.humanoid else ("gear",)
        self._hinges = [self.model.jnt_qposadr[self.model.joint(n).id] for n in names]

    def _mjcf(self, world: WorldObjects) -> str:
        if self.humanoid:
            from sim_backend.humanoid.mjcf import build_mjcf
            from sim_backend.humanoid.params import RobotTruthParams
            from sim_backend.spec import FloorBox
            from sim_backend.urdf_description import parse_urdf

            boxes = [FloorBox(centre, size) for centre, size in world.boxes]
            assert self.robot.urdf is not None
            return build_mjcf(
                parse_urdf(self.robot.urdf), RobotTruthParams(), rigid=True, floor_boxes=boxes
            )
        from sim_backend.hardware import with_obstacle
        from sim_backend.plant import TestbedPlantParams, build_mjcf

        params = with_obstacle(TestbedPlantParams(), world.block_contact_angle_rad)
        return build_mjcf(params, velocity_gain_nms_per_rad=1.0)

    @property
    def rows(self) -> int:
        return self._link.shape[1]

    def row_at(self, time_s: float) -> int:
        """The log row nearest a run time."""
        return int(np.argmin(np.abs(self.run.time_s - time_s)))

    def pose(self, row: int) -> None:
        """The model at log row `row` (a row whose angles are not read keeps the last pose)."""
        link = self._link[:, row]
        if not np.all(np.isfinite(link)):
            return
        qpos = self.data.qpos
        if self.humanoid:
            qpos[:7] = self.base(row)
            qpos[self._hinges] = link
        else:
            motor = self._motor[:, row]
            qpos[self._hinges] = link - motor  # the gear hinge: the deflection
            qpos[self.model.jnt_qposadr[self.model.joint("motor").id]] = motor[0]
        self._mj.mj_kinematics(self.model, self.data)

    def base(self, row: int) -> np.ndarray:
        """MuJoCo's free-joint qpos (x y z, qw qx qy qz) of the pelvis at row `row`."""
        assert self._frames is not None
        while len(self._bases) <= row:
            i = len(self._bases)
            sensors = {c: float(self.run.columns[c][i]) for c in sensor_columns(self.run)}
            transforms = self._frames.at(self._link[:, i], sensors, float(self.run.time_s[i]))
            if transforms is None:
                self._bases.append(self._bases[-1] if self._bases else _standing_base())
                continue
            t = transforms[0]
            x, y, z, w = t.rotation
            self._bases.append(np.array([*t.translation, w, x, y, z]))
        return self._bases[row]

    def pelvis_x(self, row: int) -> float:
        return float(self.base(row)[0]) if self.humanoid else 0.0


def _standing_base() -> np.ndarray:
    return np.array([0.0, 0.0, 0.87, 1.0, 0.0, 0.0, 0.0])


def _rotation_of_rpy(rpy: np.ndarray) -> np.ndarray:
    """URDF rpy: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def _add_viewer_shapes(spec: Any, urdf: str, mujoco: Any) -> None:
    """Every <visual> of the viewer URDF as a geom of its link's body (no contact)."""
    kinds = {
        "box": mujoco.mjtGeom.mjGEOM_BOX,
        "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
        "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
    }
    bodies = {body.name for body in spec.bodies}
    for link in ET.fromstring(urdf).findall("link"):
        name = link.get("name", "")
        if name in bodies:
            body = spec.body(name)
        elif name == "base_link":  # the testbed's fixed base: the world's in its MJCF
            body = spec.worldbody
        else:
            continue
        for visual in link.findall("visual"):
            geometry = visual.find("geometry")
            shape = next(iter(list(geometry)), None) if geometry is not None else None
            if shape is None or shape.tag not in kinds:
                continue
            origin = visual.find("origin")
            xyz = np.fromstring(origin.get("xyz", "0 0 0") if origin is not None else "0 0 0",
                                sep=" ")  # fmt: skip
            rpy = np.fromstring(origin.get("rpy", "0 0 0") if origin is not None else "0 0 0",
                                sep=" ")  # fmt: skip
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, _rotation_of_rpy(rpy).ravel())
            colour = visual.find("material/color")
            rgba = np.fromstring(colour.get("rgba"), sep=" ") if colour is not None else None
            body.add_geom(
                type=kinds[shape.tag],
                size=_mujoco_size(shape),
                pos=xyz,
                quat=quat,
                rgba=rgba if rgba is not None else np.array([0.6, 0.6, 0.6, 1.0]),
                contype=0,
                conaffinity=0,
                group=1,
            )


def _mujoco_size(shape: ET.Element) -> np.ndarray:
    """MuJoCo's size of a URDF shape: half sizes of a box, radius and half length of a
    cylinder, a sphere's radius."""
    if shape.tag == "box":
        return np.fromstring(shape.get("size", "0 0 0"), sep=" ") / 2
    radius = float(shape.get("radius", "0"))
    if shape.tag == "cylinder":
        return np.array([radius, float(shape.get("length", "0")) / 2, 0.0])
    return np.array([radius, 0.0, 0.0])


def _staged(mjcf: str, floor_z_m: float) -> str:
    """The model with a stage to draw it on: a sky, a chequered floor (drawn only, where the
    model has none), two lights, and the world's own objects (a block, a box) coloured."""
    root = ET.fromstring(mjcf)
    visual = ET.SubElement(root, "visual")
    ET.SubElement(visual, "headlight", ambient="0.4 0.4 0.4", diffuse="0.5 0.5 0.5")
    ET.SubElement(visual, "global", offwidth="1920", offheight="1080")
    asset = ET.SubElement(root, "asset")
    for name, kind, builtin, rgb1, rgb2 in (
        ("sky", "skybox", "gradient", "0.93 0.95 0.98", "0.75 0.80 0.88"),
        ("chequer", "2d", "checker", "0.86 0.86 0.84", "0.74 0.74 0.72"),
    ):
        ET.SubElement(asset, "texture", name=name, type=kind, builtin=builtin, rgb1=rgb1,
                      rgb2=rgb2, width="256", height="256")  # fmt: skip
    ET.SubElement(asset, "material", name="floor", texture="chequer", texrepeat="8 8",
                  reflectance="0")  # fmt: skip
    world = root.find("worldbody")
    assert world is not None
    planes = [g for g in world.iter("geom") if g.get("type") == "plane"]
    if not planes:
        planes = [ET.SubElement(world, "geom", name="stage_floor", type="plane",
                                pos=f"0 0 {floor_z_m}", contype="0", conaffinity="0")]  # fmt: skip
    for plane in planes:
        plane.set("size", "4 4 0.05")
        plane.set("material", "floor")
    for geom in world.iter("geom"):
        if geom.get("name", "").startswith(("floor_box_", "obstacle")):
            geom.set("rgba", " ".join(str(c) for c in OBJECT_RGBA))
    ET.SubElement(world, "light", pos="1 -2 3", dir="-0.3 0.6 -1", diffuse="0.6 0.6 0.6")
    ET.SubElement(world, "light", pos="-1 2 3", dir="0.3 -0.6 -1", diffuse="0.3 0.3 0.3")
    return ET.tostring(root, encoding="unicode")


def world_objects_of(run: RunData) -> WorldObjects:
    """The world of the run's experiment (by its name in meta.json; none if unknown)."""
    from hil.robots import get_experiment

    try:
        experiment = get_experiment(str(run.meta.get("experiment", "")))
    except ValueError:
        return WorldObjects()
    world = experiment.world
    angle = world.obstacle.contact_angle_rad if world.obstacle is not None else None
    boxes = tuple((tuple(o.centre_m), tuple(o.size_m)) for o in world.floor_objects)
    return WorldObjects(angle, boxes)  # type: ignore[arg-type]

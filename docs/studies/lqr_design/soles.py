"""How soft the emulated soles are: a small constant push on the standing robot's pelvis, the
stance sole's tilt (MuJoCo's own pose of the foot) against the moment the foot's force/torque
sensor sees about the sole's centre.

Run from this folder: PYTHONPATH=../../.. python soles.py
"""

import numpy as np

from controller.humanoid import SupportState
from sim_backend.humanoid.robot import PelvisPush
from tests.support.humanoid_loop import settled_robot
from designs import postures

SOLE_CENTRE_IN_SENSOR_M = np.array([0.01, 0.0, -0.105])  # the box sole below the ankle axis


def sole(robot, side):
    _, rotation = robot.plant.ft_sensor_pose(side)
    force, moment = robot.foot_wrench(side)
    about_centre = moment - np.cross(SOLE_CENTRE_IN_SENSOR_M, force)
    tilt = np.array([np.arctan2(rotation[2, 1], rotation[2, 2]), -np.arcsin(rotation[2, 0])])
    return tilt, about_centre[:2]


def main() -> None:
    for state in ("left", "double"):
        angles, support = postures()[state]
        for axis, force in (("roll", (0.0, 20.0, 0.0)), ("pitch", (20.0, 0.0, 0.0))):
            robot = settled_robot(angles, support)
            tilt0, moment0 = sole(robot, 0)
            robot.start_scenario()
            robot.pushes = [PelvisPush(0.0, 100.0, force)]
            robot.advance(1.5)
            tilt1, moment1 = sole(robot, 0)
            i = 0 if axis == "roll" else 1
            d_tilt, d_moment = tilt1[i] - tilt0[i], moment1[i] - moment0[i]
            print(
                f"{state:6s} support, 20 N push -> left sole {axis}: {d_tilt * 1e3:+.2f} mrad under "
                f"{d_moment:+.1f} N m: {abs(d_moment / d_tilt):.0f} N m/rad"
            )


if __name__ == "__main__":
    main()

"""DYROS-JET figures the walking pattern generator uses, each with its public source (the leg
joints' names and the upper body's posture are controller/humanoid/leg_model.py's, the
controller's one copy).

Leg geometry (joint placements and axes): DYROS-JET URDF, psh117/dyros_jet,
`dyros_jet_description/robots/dyros_jet_robot.urdf`, BSD-2-Clause (c) 2017 Suhan Park.
All leg joint origins have rpy = 0, so every joint frame is parallel to the pelvis frame at the
zero pose; the zero pose is a bent leg (knee ahead of the hip-ankle line).

    joint         parent -> child origin xyz [m]     axis
    L_HipYaw      base_link  (0,  0.105, -0.1119)    (0, 0, -1)
    L_HipRoll     (0, 0, 0)                          (1, 0, 0)
    L_HipPitch    (0, 0, 0)                          (0, 1, 0)
    L_KneePitch   (0.1515, 0, -0.339)                (0, 1, 0)
    L_AnklePitch  (0.06,   0, -0.368)                (0, 1, 0)
    L_AnkleRoll   (0, 0, 0)                          (1, 0, 0)
    R_*           same, hip at (0, -0.105, -0.1119); R_HipPitch, R_KneePitch, R_AnklePitch
                  axes (0, -1, 0); R_HipYaw (0, 0, -1); R_HipRoll, R_AnkleRoll (1, 0, 0)

Foot: DYROS-JET MuJoCo model, psh117/dyros_jet, `dyros_jet_description/robots/dyros_jet_robot.xml`
(BSD-2-Clause (c) 2017 Suhan Park): the sole is a box of half-size 0.15 x 0.085 x 0.01 m centred
at (0.01, 0, -0.095) in `*_AnkleRoll_Link`, so the sole is 0.105 m below the ankle axes and the
support polygon of one foot is 0.30 m x 0.17 m.

Nominal lateral foot offset 0.127794 m from the walking line (each side), and "right foot will be
the first swing foot": the lab's footstep planner, psh117/dyros_jet,
`dyros_jet_controller/src/walking_controller.cpp`, BSD-2-Clause (c) 2017 Suhan Park.
"""

from __future__ import annotations

HIP_IN_PELVIS_LEFT_M: tuple[float, float, float] = (0.0, 0.105, -0.1119)
HIP_IN_PELVIS_RIGHT_M: tuple[float, float, float] = (0.0, -0.105, -0.1119)
KNEE_FROM_HIP_M: tuple[float, float, float] = (0.1515, 0.0, -0.339)
ANKLE_FROM_KNEE_M: tuple[float, float, float] = (0.06, 0.0, -0.368)

# Signs of each joint axis against its canonical direction (z, x, y, y, y, x).
AXIS_SIGNS_LEFT: tuple[int, ...] = (-1, 1, 1, 1, 1, 1)
AXIS_SIGNS_RIGHT: tuple[int, ...] = (-1, 1, -1, -1, -1, 1)

SOLE_BELOW_ANKLE_M = 0.105  # 0.095 (box centre) + 0.01 (box half-thickness)
FOOT_LENGTH_M = 0.30
FOOT_WIDTH_M = 0.17
SOLE_CENTRE_AHEAD_OF_ANKLE_M = 0.01

NOMINAL_LATERAL_FOOT_OFFSET_M = 0.127794

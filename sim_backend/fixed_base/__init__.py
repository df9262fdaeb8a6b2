"""The emulated fixed-base robot from its URDF: a MuJoCo plant with a flexible joint per
actuated joint (plant.py), each joint's gear and motor side from its actuator model
(params.py), behind the joints' firmwares and on the buses (hardware.py)."""

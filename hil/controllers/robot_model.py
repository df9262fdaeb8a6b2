"""The controller's model of the robot (`RobotModel`, hil/robots/model.py), made by the robot's
profile from `[model]` (hil/robots/<name>/model.py): where the controllers find it."""

from hil.robots import RobotModel, robot_model

__all__ = ["RobotModel", "robot_model"]

"""Kinematics on Pinocchio: the robot model, D-H construction and URDF loading."""

from redundik.kinematics.dh import DHRow, dh_matrix, from_dh
from redundik.kinematics.model import AXES, JointInfo, RobotModel
from redundik.kinematics.urdf import EXAMPLE_ROBOTS, example_robot_data_dir, from_urdf, load_example_robot

__all__ = [
    "AXES",
    "EXAMPLE_ROBOTS",
    "DHRow",
    "JointInfo",
    "RobotModel",
    "dh_matrix",
    "example_robot_data_dir",
    "from_dh",
    "from_urdf",
    "load_example_robot",
]

"""Kinematics on Pinocchio: the robot model, D-H construction and URDF loading.

Also the chapter's A-matrix Jacobians of D-H trees and the degree of redundancy (:mod:`.jacobians`), the
hyper-redundant snake generator (:mod:`.snake`) and one-shot evaluations at one configuration (:mod:`.analysis`).
"""

from redundik.kinematics.dh import DHRow, dh_matrix, from_dh
from redundik.kinematics.jacobians import (
    augmented_jacobian,
    chain_jacobian,
    degree_of_redundancy,
    dh_forward,
    joint_variables,
    numeric_rank,
)
from redundik.kinematics.model import AXES, JointInfo, RobotModel
from redundik.kinematics.snake import snake, snake_config, snake_rows
from redundik.kinematics.urdf import EXAMPLE_ROBOTS, example_robot_data_dir, from_urdf, load_example_robot

__all__ = [
    "AXES",
    "EXAMPLE_ROBOTS",
    "DHRow",
    "JointInfo",
    "RobotModel",
    "augmented_jacobian",
    "chain_jacobian",
    "degree_of_redundancy",
    "dh_forward",
    "dh_matrix",
    "example_robot_data_dir",
    "from_dh",
    "from_urdf",
    "joint_variables",
    "load_example_robot",
    "numeric_rank",
    "snake",
    "snake_config",
    "snake_rows",
]

"""Parallel and hybrid mechanisms of chapter section 5.4: Stewart platforms, the 3+3 hybrid arm, Delta, mobility.

The math modules import only numpy / scipy; their figures live in the application layer
(:mod:`redundik.reporting.parallel_plots`, matplotlib imported lazily), their YAML in :mod:`redundik.config.parallel`.
Deviations from the printed chapter are listed in the docstrings of :mod:`~redundik.parallel.stewart_fk`,
:mod:`~redundik.parallel.differential`, :mod:`~redundik.parallel.upr`, :mod:`~redundik.parallel.hybrid33` and
:mod:`~redundik.parallel.mobility`.
"""

from __future__ import annotations

from redundik.parallel.delta import DeltaLegs, DeltaRobot, leg_frame, planar_link, urr_angles
from redundik.parallel.differential import FKStep, Trajectory, fk_update, follow_leg_profile, ik_update
from redundik.parallel.hybrid33 import (
    ArmPose,
    Hybrid33Arm,
    HybridIK,
    PathResult,
    linear_path,
    run_path,
    wrist_angles,
)
from redundik.parallel.mobility import JOINT_DOF, JointGroup, Mobility, grubler
from redundik.parallel.stewart import LegSolution, StewartPlatform, book_66_pose
from redundik.parallel.stewart_fk import FKSolution, forward_kinematics, grid_search_fk, nearest_solution
from redundik.parallel.upr import AXIS_TABLE, Orientation, PlatformPose, UPRPlatform

__all__ = [
    "AXIS_TABLE",
    "JOINT_DOF",
    "ArmPose",
    "DeltaLegs",
    "DeltaRobot",
    "FKSolution",
    "FKStep",
    "Hybrid33Arm",
    "HybridIK",
    "JointGroup",
    "LegSolution",
    "Mobility",
    "Orientation",
    "PathResult",
    "PlatformPose",
    "StewartPlatform",
    "Trajectory",
    "UPRPlatform",
    "book_66_pose",
    "fk_update",
    "follow_leg_profile",
    "forward_kinematics",
    "grid_search_fk",
    "grubler",
    "ik_update",
    "leg_frame",
    "linear_path",
    "nearest_solution",
    "planar_link",
    "run_path",
    "urr_angles",
    "wrist_angles",
]

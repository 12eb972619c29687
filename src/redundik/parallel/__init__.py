"""Parallel and hybrid mechanisms of chapter section 5.4: Stewart platforms, the 3+3 hybrid arm, Delta, mobility.

The math modules import only numpy / scipy; plotting lives in :mod:`redundik.parallel.plots` and imports
matplotlib lazily.
"""

from __future__ import annotations

from redundik.parallel.differential import FKStep, Trajectory, fk_update, follow_leg_profile, ik_update
from redundik.parallel.stewart import LegSolution, StewartPlatform, book_66_pose
from redundik.parallel.stewart_fk import FKSolution, forward_kinematics, grid_search_fk, nearest_solution

__all__ = [
    "FKSolution",
    "FKStep",
    "LegSolution",
    "StewartPlatform",
    "Trajectory",
    "book_66_pose",
    "fk_update",
    "follow_leg_profile",
    "forward_kinematics",
    "grid_search_fk",
    "ik_update",
    "nearest_solution",
]

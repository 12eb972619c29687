"""Helpers for the chapter's redundant and hybrid-chain robots (sections 5.2, 5.3).

* :mod:`.jacobians`: the chapter's A-matrix Jacobians (4.14, 4.15), the augmented Jacobian (5.17) of a tree, and
  the degree of redundancy from the generic Jacobian rank;
* :mod:`.relative`: the coordination task of two end-effectors (relative pose held);
* :mod:`.potentials`: a joint visiting waypoints (the (6+1) robot's round trip);
* :mod:`.snake`: the hyper-redundant snake generator;
"""

from redundik.robots.jacobians import (
    augmented_jacobian,
    chain_jacobian,
    degree_of_redundancy,
    dh_forward,
    joint_variables,
    numeric_rank,
)
from redundik.robots.potentials import JointWaypoints
from redundik.robots.relative import RelativePoseTask
from redundik.robots.snake import snake, snake_config, snake_rows

__all__ = [
    "JointWaypoints",
    "RelativePoseTask",
    "augmented_jacobian",
    "chain_jacobian",
    "degree_of_redundancy",
    "dh_forward",
    "joint_variables",
    "numeric_rank",
    "snake",
    "snake_config",
    "snake_rows",
]

"""QP resolution: tasks as QP terms, joint limits, the ``wqp`` and ``hqp`` resolvers and their backends."""

from redundik.resolvers.qp.backends import (
    DEFAULT_BACKEND,
    TOLERANCE,
    Backend,
    available_backends,
    make_backend,
)
from redundik.resolvers.qp.hqp import HierarchicalQPResolver
from redundik.resolvers.qp.limits import JointLimits, LimitBox
from redundik.resolvers.qp.problem import QPProblem, QPSolution
from redundik.resolvers.qp.terms import Level, build_levels
from redundik.resolvers.qp.wqp import WeightedQPResolver

__all__ = [
    "DEFAULT_BACKEND",
    "TOLERANCE",
    "Backend",
    "HierarchicalQPResolver",
    "JointLimits",
    "Level",
    "LimitBox",
    "QPProblem",
    "QPSolution",
    "WeightedQPResolver",
    "available_backends",
    "build_levels",
    "make_backend",
]

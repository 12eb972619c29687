"""Resolvers: turn a task stack into a joint velocity. Closed forms here; QP resolvers beside them."""

from redundik.resolvers.base import Resolver, StepResult
from redundik.resolvers.batch import BatchResolver, BatchResult, solve_batch
from redundik.resolvers.feedback import FeedbackResolver
from redundik.resolvers.linalg import PseudoInverse, pseudo_inverse
from redundik.resolvers.pinv import PinvResolver
from redundik.resolvers.qp import HierarchicalQPResolver, JointLimits, WeightedQPResolver, available_backends
from redundik.resolvers.registry import RESOLVERS, make_resolver
from redundik.resolvers.singularity import SingularityGuard

__all__ = [
    "RESOLVERS",
    "BatchResolver",
    "BatchResult",
    "FeedbackResolver",
    "HierarchicalQPResolver",
    "JointLimits",
    "PinvResolver",
    "PseudoInverse",
    "Resolver",
    "SingularityGuard",
    "StepResult",
    "WeightedQPResolver",
    "available_backends",
    "make_resolver",
    "pseudo_inverse",
    "solve_batch",
]

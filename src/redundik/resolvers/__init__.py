"""Resolvers: turn a task stack into a joint velocity. Closed forms here; QP resolvers beside them."""

from redundik.resolvers.base import Resolver, StepResult
from redundik.resolvers.feedback import FeedbackResolver
from redundik.resolvers.linalg import PseudoInverse, pseudo_inverse
from redundik.resolvers.pinv import PinvResolver
from redundik.resolvers.registry import RESOLVERS, make_resolver

__all__ = [
    "RESOLVERS",
    "FeedbackResolver",
    "PinvResolver",
    "PseudoInverse",
    "Resolver",
    "StepResult",
    "make_resolver",
    "pseudo_inverse",
]

"""Resolvers by name, for configuration files and the CLI: ``make_resolver("pinv", epsilon=1e-2)``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from redundik._names import did_you_mean
from redundik.errors import ResolverError, short_repr
from redundik.resolvers.base import Resolver
from redundik.resolvers.feedback import FeedbackResolver
from redundik.resolvers.pinv import PinvResolver
from redundik.resolvers.qp.hqp import HierarchicalQPResolver
from redundik.resolvers.qp.wqp import WeightedQPResolver

#: Factories by resolver name. QP resolvers add themselves in :mod:`redundik.resolvers` when importable.
RESOLVERS: dict[str, Callable[..., Resolver]] = {
    "pinv": PinvResolver,
    "feedback": FeedbackResolver,
    "wqp": WeightedQPResolver,
    "hqp": HierarchicalQPResolver,
}


def make_resolver(name: str, **options: Any) -> Resolver:
    """Build a resolver by name with keyword options.

    Raises:
        ResolverError: unknown name (lists the known ones) or bad options (names them).
    """
    if not isinstance(name, str) or name not in RESOLVERS:
        hint = did_you_mean(name, RESOLVERS)
        raise ResolverError(f"unknown resolver {short_repr(name)}; {hint}available: {sorted(RESOLVERS)}")
    try:
        return RESOLVERS[name](**options)
    except TypeError as exc:
        raise ResolverError(f"resolver '{name}': bad options {sorted(options)}: {exc}") from exc

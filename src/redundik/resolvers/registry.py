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


#: Options of every resolver that configure its command watchdog (:mod:`redundik.resolvers.watchdog`): the timeout
#: [s], the deceleration limit [rad/s²] and the jerk limit [rad/s³] of the stop.
WATCHDOG_OPTIONS = ("command_timeout", "stop_acceleration", "stop_jerk")


def make_resolver(name: str, **options: Any) -> Resolver:
    """Build a resolver by name with keyword options (and the watchdog's, ``WATCHDOG_OPTIONS``).

    Raises:
        ResolverError: unknown name (lists the known ones) or bad options (names them).
    """
    if not isinstance(name, str) or name not in RESOLVERS:
        hint = did_you_mean(name, RESOLVERS)
        raise ResolverError(f"unknown resolver {short_repr(name)}; {hint}available: {sorted(RESOLVERS)}")
    dog = {k: options.pop(k) for k in WATCHDOG_OPTIONS if k in options}
    try:
        resolver = RESOLVERS[name](**options)
    except TypeError as exc:
        raise ResolverError(f"resolver '{name}': bad options {sorted(options)}: {exc}") from exc
    if dog:
        from redundik.resolvers.watchdog import Watchdog

        if "command_timeout" not in dog:
            raise ResolverError(f"resolver '{name}': {sorted(dog)} configure the watchdog: give command_timeout too")
        resolver.watchdog = Watchdog(
            dog["command_timeout"], acceleration=dog.get("stop_acceleration"), jerk=dog.get("stop_jerk")
        )
    return resolver

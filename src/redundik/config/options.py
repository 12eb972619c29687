"""Resolver options as written in YAML (``runs.NAME.options``, a sweep's ``resolver.options``), checked before the
resolver sees them.

A resolver turns its options into numbers and flags with ``float(...)`` / ``bool(...)``; from YAML that accepts
values nobody meant: ``limits: {position: "no"}`` is ``bool("no") = True`` (the limits stay on), ``damping: true``
is a damping of 1, a NaN nested under ``limits`` passes as a truthy flag. Here every option whose parameter is a
flag must be ``true``/``false``, every number must be a number (not a boolean) and finite at any depth, and the
``limits`` and ``levels`` mappings must have their shape — each problem one :class:`~redundik.errors.ConfigError`
with its key path. The kinds come from the resolvers' own signatures, so a new option is checked too.
"""

from __future__ import annotations

import inspect
import math
import re
from collections.abc import Callable
from typing import Any

from redundik.config.yamlio import join_path
from redundik.errors import ConfigError, short_repr

#: ``limits:`` keys whose value maps joint names to numbers.
_PER_JOINT = ("lower", "upper", "velocity_limits")
#: ``limits:`` keys that take one number for every joint or a mapping of joint names to numbers (> 0).
_RATE_LIMITS = ("acceleration", "jerk")


def _kinds(factory: Callable[..., Any] | None) -> dict[str, str]:
    """Parameter name → ``"flag"`` (annotated ``bool``), ``"number"`` (a float/int, not a bool) or ``"other"``."""
    if factory is None:
        return {}
    try:
        params = inspect.signature(factory).parameters
    except (TypeError, ValueError):
        return {}
    out: dict[str, str] = {}
    for name, param in params.items():
        ann = param.annotation
        text = ann if isinstance(ann, str) else inspect.formatannotation(ann)
        if text == "bool":
            out[name] = "flag"
        elif re.search(r"\b(float|int)\b", text) and "bool" not in text:
            out[name] = "number"
        else:
            out[name] = "other"
    return out


def _finite(value: Any, path: str) -> None:
    if isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"expected a finite number, got {value}", path)
    if isinstance(value, dict):
        for key, item in value.items():
            _finite(item, join_path(path, str(key)))
    elif isinstance(value, list):
        for i, item in enumerate(value):
            _finite(item, join_path(path, i))


def _kind(value: Any, kind: str | None, path: str) -> None:
    if kind == "flag" and not isinstance(value, bool):
        raise ConfigError(f"expected true or false, got {short_repr(value)}", path)
    if kind == "number" and isinstance(value, bool):
        raise ConfigError(f"expected a number, got {value}", path)


def _check_limits(limits: Any, path: str) -> None:
    from redundik.resolvers.qp.limits import JointLimits

    if not isinstance(limits, dict):
        return  # true / false / null: the resolver's own message covers anything else
    kinds = _kinds(JointLimits)
    for key, value in limits.items():
        where = join_path(path, str(key))
        _kind(value, kinds.get(str(key)), where)
        if key in _PER_JOINT or (key in _RATE_LIMITS and isinstance(value, dict)):
            if value is None:
                continue
            if not isinstance(value, dict):
                raise ConfigError(f"expected a mapping of joint name → number, got {short_repr(value)}", where)
            for joint, number in value.items():
                if isinstance(number, bool) or not isinstance(number, (int, float)):
                    raise ConfigError(f"expected a number, got {short_repr(number)}", join_path(where, str(joint)))
                if key in _RATE_LIMITS and not number > 0:
                    raise ConfigError(f"expected a number > 0, got {number}", join_path(where, str(joint)))
        elif key in _RATE_LIMITS and value is not None:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise ConfigError(
                    f"expected a number > 0 (every joint) or a mapping of joint name → number, got {short_repr(value)}",
                    where,
                )


def check_resolver_options(resolver: str, options: dict[str, Any], path: str) -> None:
    """Check ``options`` of resolver ``resolver`` as given in YAML at key path ``path`` (see the module docstring).

    Raises:
        ConfigError: the first problem, at its key path (``runs.wqp.options.limits.position``).
    """
    from redundik.resolvers import RESOLVERS

    _finite(options, path)
    kinds = _kinds(RESOLVERS.get(resolver))
    for key, value in options.items():
        _kind(value, kinds.get(str(key)), join_path(path, str(key)))
    if "limits" in options:
        _check_limits(options["limits"], join_path(path, "limits"))
    levels = options.get("levels")
    if levels is not None and not isinstance(levels, (dict, list)):
        raise ConfigError(
            "expected a mapping {task or subtask name: level} or a list of levels (each a list of names), "
            f"got {short_repr(levels)}",
            join_path(path, "levels"),
        )

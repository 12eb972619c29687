"""Resolver settings validated on assignment and used from the next step.

A resolver's numeric and on/off options (``wqp.damping``, ``hqp.regularization``, ``hqp.level_shortcut``, …) are
public attributes a user may set after construction. Each is a :class:`Setting`: an assignment is checked by the
constructor's rule (a clear :class:`~redundik.errors.ResolverError` naming the resolver, the option and what is
expected — never a NaN step or a silent wrong answer later), and it drops the caches built from the old value (the
level weights of ``wqp``, the plan and cascade settings of ``hqp``), so that the next step uses the new one.
Reading one is a plain attribute lookup on the hot path.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Generic, TypeVar, overload

import numpy as np

from redundik.errors import ResolverError

T = TypeVar("T")


def _number(who: str, key: str, val: object) -> float:
    if isinstance(val, (bool, np.bool_)) or not isinstance(val, (int, float, np.integer, np.floating)):
        raise ResolverError(f"{who}: {key} must be a number, got {type(val).__name__} {val!r}")
    return float(val)


def nonnegative(who: str, key: str, val: object) -> float:
    """A finite number ≥ 0."""
    x = _number(who, key, val)
    if not (math.isfinite(x) and x >= 0.0):
        raise ResolverError(f"{who}: {key} must be a finite number ≥ 0, got {val!r}")
    return x


def positive(who: str, key: str, val: object) -> float:
    """A finite number > 0."""
    x = _number(who, key, val)
    if not (math.isfinite(x) and x > 0.0):
        raise ResolverError(f"{who}: {key} must be a finite number > 0, got {val!r}")
    return x


def unit_interval(who: str, key: str, val: object) -> float:
    """A number in the open interval (0, 1)."""
    x = _number(who, key, val)
    if not 0.0 < x < 1.0:
        raise ResolverError(f"{who}: {key} must be in (0, 1), got {val!r}")
    return x


def flag(who: str, key: str, val: object) -> bool:
    """True or False."""
    if not isinstance(val, (bool, np.bool_)):
        raise ResolverError(f"{who}: {key} must be True or False, got {type(val).__name__} {val!r}")
    return bool(val)


def count(who: str, key: str, val: object) -> int:
    """An integer ≥ 0."""
    if isinstance(val, (bool, np.bool_)) or not isinstance(val, (int, np.integer)) or val < 0:
        raise ResolverError(f"{who}: {key} must be an integer ≥ 0, got {val!r}")
    return int(val)


_UNSET: Any = object()


class Setting(Generic[T]):
    """A resolver option checked on assignment by ``check(resolver name, option name, value)``; an assignment
    sets each attribute named in ``resets`` to ``None`` (the caches built from the old value). ``default``: the
    value read before any assignment (none: the constructor assigns it)."""

    def __init__(
        self, check: Callable[[str, str, object], T], resets: tuple[str, ...] = (), default: T = _UNSET
    ) -> None:
        self._check = check
        self._resets = resets
        self._default = default
        self._name = ""
        self._slot = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self._name, self._slot = name, f"_setting_{name}"

    @overload
    def __get__(self, obj: None, objtype: type | None = None) -> Setting[T]: ...

    @overload
    def __get__(self, obj: object, objtype: type | None = None) -> T: ...

    def __get__(self, obj: object | None, objtype: type | None = None) -> Setting[T] | T:
        if obj is None:
            return self
        try:
            return obj.__dict__[self._slot]
        except KeyError:
            if self._default is not _UNSET:
                return self._default
            raise AttributeError(f"{type(obj).__name__}.{self._name} is not set") from None

    def __set__(self, obj: Any, value: object) -> None:
        d = obj.__dict__
        d[self._slot] = self._check(str(getattr(obj, "name", type(obj).__name__)), self._name, value)
        for attr in self._resets:
            d[attr] = None

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
from typing import TYPE_CHECKING, Any, Generic, TypeVar, overload

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


class Setting(Generic[T]):
    """A resolver option checked on assignment by ``check(resolver name, option name, value)``; an assignment
    sets each attribute named in ``resets`` to ``None`` (the caches built from the old value).

    The value lives in the instance's ``__dict__`` under the option's own name and the descriptor defines no
    ``__get__`` (only for the type checker): reading it is Python's plain attribute lookup, as fast as before on
    the hot path; the resolver's constructor assigns every one of its settings.
    """

    def __init__(self, check: Callable[[str, str, object], T], resets: tuple[str, ...] = ()) -> None:
        self._check = check
        self._resets = resets
        self._name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self._name = name

    if TYPE_CHECKING:

        @overload
        def __get__(self, obj: None, objtype: type | None = None) -> Setting[T]: ...

        @overload
        def __get__(self, obj: object, objtype: type | None = None) -> T: ...

        def __get__(self, obj: object | None, objtype: type | None = None) -> Setting[T] | T: ...

    def __set__(self, obj: Any, value: object) -> None:
        d = obj.__dict__
        d[self._name] = self._check(str(getattr(obj, "name", type(obj).__name__)), self._name, value)
        for attr in self._resets:
            d[attr] = None

"""The record of one resolved step: :class:`StepResult`, its lazy form ``LazyStepResult`` (diagnostics computed
on first read, through a ``LazyInfo`` that shares them), and ``nonfinite_sources``, which names what made a
step's intermediates non-finite."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any, TypeVar

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.tasks.base import TaskTerm
from redundik.tasks.stack import TaskStack

__all__ = ["LazyInfo", "LazyStepResult", "StepResult", "nonfinite_sources"]


@dataclass
class StepResult:
    """One resolved control step.

    Attributes:
        dq: Joint velocity q̇, shape (nv,), always finite.
        terms: The task terms the step was computed from (main and regularisation tasks, in stack order).
        dq_rank: The rank (main-task) part J⁺V when the resolver separates it, else ``None``.
        dq_null: The null-space part when the resolver separates it, else ``None``.
        gains: Subtask gains k actually used (state-feedback law), or ``None``.
        damped: True when a singular direction was damped.
        damping: Largest λ used.
        sigma_min: Smallest nonzero singular value of the main-task Jacobian (or of the top level) [unit of J].
        fallback: Why the resolver fell back to a simpler method, or ``None``.
        info: Resolver-specific diagnostics by name (numbers go to the run's CSV).
        build_time: Seconds spent building the problem.
        solve_time: Seconds spent solving it.
        main: Indices into ``terms`` of the main tasks (``None``: all of them).
        scale: The fraction α ∈ [0, 1] of the main tasks' commanded velocity the step delivers when the resolver
            scales it to keep its direction (``scaling="direction"``); 1.0 when it does not scale.
        stuck: True when ``scale`` fell below the resolver's threshold (the limits leave almost no motion along V).
        relaxed: The documented relaxations this step made (for instance an inequality level that could not be
            fully met), by member name; empty when the stack was met as asked. Not an alarm: ``fallback`` is.
    """

    dq: np.ndarray
    terms: list[TaskTerm]
    dq_rank: np.ndarray | None = None
    dq_null: np.ndarray | None = None
    gains: np.ndarray | None = None
    damped: bool = False
    damping: float = 0.0
    sigma_min: float = math.inf
    fallback: str | None = None
    info: dict[str, object] = field(default_factory=dict)
    build_time: float = 0.0
    solve_time: float = 0.0
    main: list[int] | None = None
    scale: float = 1.0
    stuck: bool = False
    relaxed: tuple[str, ...] = ()

    @property
    def main_terms(self) -> list[TaskTerm]:
        """The main tasks' terms (regularisation tasks left out)."""
        return self.terms if self.main is None else [self.terms[i] for i in self.main]

    @property
    def task_error(self) -> float:
        """Norm of the stacked main-task error."""
        terms = self.terms
        main = self.main
        total = 0.0
        if main is None:
            for term in terms:
                e = term.error
                total += e.dot(e)  # the method: half the dispatch of ``@`` on small vectors
        else:
            for i in main:
                e = terms[i].error
                total += e.dot(e)
        return math.sqrt(total)


F = TypeVar("F", bound=Callable[..., Any])


def info_keys(*keys: str) -> Callable[[F], F]:
    """Declare the ``info`` entries a pending-diagnostics function adds (a decorator): reading any other absent key
    of the step's ``info`` (``info.get("qp")`` on a ``pinv`` step, ``"x" in info``) then answers at once instead of
    computing the diagnostics. An undeclared function may add anything: every absent key computes them."""

    def mark(fn: F) -> F:
        fn.info_keys = frozenset(keys)  # type: ignore[attr-defined]
        return fn

    return mark


def declared_keys(fn: Callable[..., Any] | None) -> frozenset[str] | None:
    """The keys :func:`info_keys` declared for ``fn`` (or the function a ``functools.partial`` wraps); ``None``."""
    target = fn.func if isinstance(fn, functools.partial) else fn
    return getattr(target, "info_keys", None)


class LazyInfo(dict):  # type: ignore[type-arg]
    """``StepResult.info`` whose costly entries are computed on first read (the keys given eagerly stay cheap).

    Reading a key that is present returns it at once; reading a key the pending diagnostics may add (``keys``; all
    keys when ``None``), iterating, or asking the size runs them once (a QP step's residuals, σ_min, active-limit
    labels), then it behaves as a plain dict. Any other key is absent without computing anything.
    """

    __slots__ = ("_keys", "_pending")

    def __init__(
        self,
        eager: dict[str, object],
        pending: Callable[[], dict[str, object]] | None,
        keys: frozenset[str] | None = None,
    ) -> None:
        super().__init__(eager)
        self._pending = pending
        self._keys = keys

    def _fill(self) -> None:
        pending, self._pending = self._pending, None
        if pending is not None:
            dict.update(self, pending())

    def _may_add(self, key: object) -> bool:
        """Whether the pending diagnostics may add ``key`` (absent now, diagnostics pending): they must run to tell."""
        keys = self._keys
        return keys is None or key in keys

    def __getitem__(self, key: str) -> object:
        if self._pending is not None and not dict.__contains__(self, key) and self._may_add(key):
            self._fill()
        return dict.__getitem__(self, key)

    def get(self, key: str, default: object = None) -> object:
        if self._pending is not None and not dict.__contains__(self, key) and self._may_add(key):
            self._fill()
        return dict.get(self, key, default)

    def __contains__(self, key: object) -> bool:
        if self._pending is not None and not dict.__contains__(self, key) and self._may_add(key):
            self._fill()
        return dict.__contains__(self, key)

    def __iter__(self):  # type: ignore[no-untyped-def]
        self._fill()
        return dict.__iter__(self)

    def __len__(self) -> int:
        self._fill()
        return dict.__len__(self)

    def keys(self):  # type: ignore[no-untyped-def]
        self._fill()
        return dict.keys(self)

    def values(self):  # type: ignore[no-untyped-def]
        self._fill()
        return dict.values(self)

    def items(self):  # type: ignore[no-untyped-def]
        self._fill()
        return dict.items(self)

    def copy(self) -> dict[str, object]:
        self._fill()
        return dict(dict.items(self))

    def __eq__(self, other: object) -> bool:
        self._fill()
        return dict.__eq__(self, other)

    __hash__ = None

    def __repr__(self) -> str:
        self._fill()
        return dict.__repr__(self)


class _Deferred:
    """A step's pending diagnostics (σ_min, damped, info entries), computed once and shared by its result and the
    result's ``LazyInfo``. Neither of those holds the other through it, so a step's result is freed as soon as
    the loop drops it: no reference cycle is left for the cyclic garbage collector, whose collections would otherwise
    interrupt a control loop that reads ``info``."""

    __slots__ = ("fn", "keys", "out")

    def __init__(self, fn: Callable[[], tuple[float, bool, dict[str, object]]]) -> None:
        self.fn: Callable[[], tuple[float, bool, dict[str, object]]] | None = fn
        self.out: tuple[float, bool, dict[str, object]] | None = None
        self.keys = declared_keys(fn)  # the info entries fn may add (None: any)

    def __call__(self) -> tuple[float, bool, dict[str, object]]:
        out = self.out
        if out is None:  # (fn kept until it returns: a diagnostics error is raised again at the next read)
            fn = self.fn
            assert fn is not None
            out = self.out = fn()
            self.fn = None
        return out

    def extra(self) -> dict[str, object]:
        """The info entries (what ``LazyInfo`` adds on first read)."""
        return self()[2]


class LazyStepResult(StepResult):
    """A :class:`StepResult` whose diagnostics (``sigma_min``, ``damped``, ``info``) are computed on first read.

    The resolver sets :attr:`pending`, a callable returning (σ_min, damped, info entries) that holds no reference
    to the result; nothing is computed on a step whose result is only used for q̇ — the hot path of a control
    loop — while a logger that reads them gets exactly what an eager step would have reported.
    """

    @property
    def pending(self) -> Callable[[], tuple[float, bool, dict[str, object]]] | bool | None:
        """The diagnostics still to compute (``None`` once computed)."""
        p = self.__dict__.get("pending")
        if type(p) is _Deferred and p.out is not None:
            return None
        return p

    @pending.setter
    def pending(self, value: Callable[[], tuple[float, bool, dict[str, object]]] | None) -> None:
        self.__dict__["pending"] = value

    def _pending_fn(self) -> Callable[[], tuple[float, bool, dict[str, object]]]:
        """The pending diagnostics as a callable that holds no reference to this result (a subclass that defers
        with a sentinel builds it from its step's arrays)."""
        return self.__dict__["pending"]

    def _deferred(self) -> _Deferred | None:
        """The pending diagnostics as the :class:`_Deferred` shared with the info (``None``: none pending)."""
        d = self.__dict__
        p = d.get("pending")
        if p is None or type(p) is _Deferred:
            return p
        p = d["pending"] = _Deferred(self._pending_fn())
        return p

    @classmethod
    def make(
        cls,
        dq: np.ndarray,
        terms: list[TaskTerm],
        fallback: str | None,
        info: dict[str, object],
        build_time: float,
        solve_time: float,
        main: list[int] | None,
        pending: Callable[[], tuple[float, bool, dict[str, object]]],
        dq_rank: np.ndarray | None = None,
        dq_null: np.ndarray | None = None,
    ) -> LazyStepResult:
        """The result of a step whose diagnostics ``pending`` computes on first read (the hot path's constructor:
        the same object as the dataclass constructor plus ``pending`` would give, with the attributes set at once)."""
        res = cls.__new__(cls)
        res.__dict__ = {
            "dq": dq,
            "terms": terms,
            "dq_rank": dq_rank,
            "dq_null": dq_null,
            "gains": None,
            "damping": 0.0,
            "fallback": fallback,
            "_info": info,  # a plain dict until first read (the ``info`` property wraps it then)
            "build_time": build_time,
            "solve_time": solve_time,
            "main": main,
            "pending": pending,
        }
        return res

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickled and copied (``copy.deepcopy``) as the plain :class:`StepResult` it reads as: the diagnostics and
        the terms computed now, ``info`` a plain dict. What a lazy result holds to compute them on request — the
        step's buffers, its plan, the robot, closures, which do not all pickle — does not go with it."""
        values = {f.name: getattr(self, f.name) for f in fields(StepResult)}
        values["info"] = dict(self.info.items())
        return (_plain_result, (values,))

    def _resolve(self) -> None:
        d = self.__dict__
        pending = d.get("pending")
        if pending is not None:
            fn = pending if type(pending) is _Deferred else self._pending_fn()
            d["pending"] = None
            smin, damped, extra = fn()
            d["_sigma_min"], d["_damped"] = smin, damped
            info = d["_info"]
            if isinstance(info, LazyInfo):
                info._pending = None
            dict.update(info, extra)

    @property
    def sigma_min(self) -> float:
        self._resolve()
        return self.__dict__.get("_sigma_min", math.inf)

    @sigma_min.setter
    def sigma_min(self, value: float) -> None:
        self.__dict__["_sigma_min"] = value

    @property
    def damped(self) -> bool:
        self._resolve()
        return self.__dict__.get("_damped", False)

    @damped.setter
    def damped(self, value: bool) -> None:
        self.__dict__["_damped"] = value

    @property
    def info(self) -> dict[str, object]:
        d = self.__dict__
        info = d["_info"]
        if type(info) is dict:  # the eager entries of a step, wrapped on first read
            deferred = self._deferred()
            info = d["_info"] = (
                LazyInfo(info, None) if deferred is None else LazyInfo(info, deferred.extra, deferred.keys)
            )
        return info

    @info.setter
    def info(self, value: dict[str, object]) -> None:
        if not isinstance(value, LazyInfo):
            value = LazyInfo(value, None)
        deferred = self._deferred()
        value._pending = None if deferred is None else deferred.extra
        value._keys = None if deferred is None else deferred.keys
        self.__dict__["_info"] = value


def _plain_result(values: dict[str, Any]) -> StepResult:
    """A :class:`StepResult` of the field ``values`` (the unpickling of a :class:`LazyStepResult`)."""
    return StepResult(**values)


def nonfinite_sources(
    terms: list[TaskTerm], robot: RobotModel | None = None, stack: TaskStack | None = None, **arrays: np.ndarray | None
) -> list[str]:
    """Names of the terms, of the stack's subtasks (with ``robot`` and ``stack``: a potential's value or gradient, a
    barrier's rows) and of the named arrays holding NaN or infinite values, for a diagnosed fallback (a path taken
    only after a non-finite q̇: the subtasks are evaluated once more here)."""
    bad = [t.name for t in terms if not (np.isfinite(t.J).all() and np.isfinite(t.v).all())]
    if robot is not None and stack is not None:
        for sub in stack.subtasks:
            source = getattr(sub, "potential", None) or getattr(sub, "source", None)
            if source is None:
                continue
            try:  # (by what the source offers: a potential's value and gradient, or a barrier's rows)
                if hasattr(source, "gradient"):
                    ok = math.isfinite(source.value(robot)) and bool(np.isfinite(source.gradient(robot)).all())
                else:
                    bt = source.evaluate(robot)
                    ok = bool(np.isfinite(bt.h).all() and np.isfinite(bt.H).all())
            except Exception:  # a diagnostic: a subtask that cannot be evaluated is named as a source
                ok = False
            if not ok:
                bad.append(f"subtask '{sub.name}'")
    bad += [k for k, a in arrays.items() if a is not None and not np.isfinite(a).all()]
    return bad

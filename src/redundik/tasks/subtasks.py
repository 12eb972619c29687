"""Typed subtasks: how a resolver uses a potential or a barrier (section 5.2). One type per use, one formula each.

* :class:`GradientSubtask` — z = k η in the null space of the main tasks (eq. 5.8; several: z = Σ k_i η_i, 5.15).
  Its strength is its gain k (> 0 increases p, < 0 decreases it); it has no weight and no level of its own: every
  gradient subtask belongs to the stack's null-space objective (see :mod:`redundik.tasks.stack`).
* :class:`TargetSubtask` — drive p to p_d at rate K: ṗ = ṗ_d + K(p_d − p). The state-feedback law computes the
  gains k that achieve it (``feedback``); a QP places it as the 1-row task ηᵀq̇ = ṗ_d + K(p_d − p) (``wqp``, ``hqp``).
* :class:`BoundSubtask` — keep lower ≤ p ≤ upper, or a vector barrier h(q) ≥ 0, as the inequality rows of the
  velocity damper ḣ ≥ −γ h (Faverjon & Tournassoud 1987), γ = min(K, 1/dt) (γ = 1/dt when K = 0): with γ = 1/dt it
  is the first-order prediction h + ḣ·dt ≥ 0 itself; with γ < 1/dt, h can shrink at most like exp(−γt), so the
  bound is approached smoothly and never crossed to first order. QP resolvers only.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import Any, ClassVar, overload

import numpy as np

from redundik.errors import NonFiniteRows, TaskError, short_repr
from redundik.kinematics.model import RobotModel
from redundik.tasks.barrier_rows import barrier_values, barrier_writer
from redundik.tasks.base import (
    Barrier,
    ClearanceForm,
    Edits,
    Potential,
    check_name,
    check_number,
    check_priority,
    default_name,
    source_name,
)
from redundik.tasks.conform import conform_barrier_term, real_array, real_value
from redundik.tasks.potential_rows import compiled_writer

_ROW_SOURCES: dict[type, bool] = {}


def _rows_of_its_own(obj: object) -> bool:
    """Whether a bound subtask's source makes its rows itself — a Barrier (even if also a Potential), or a source
    with ``bound_rows`` —, remembered per class (the ABCs' checks are slow calls on the hot path)."""
    kind = type(obj)
    known = _ROW_SOURCES.get(kind)
    if known is None:
        known = _ROW_SOURCES[kind] = issubclass(kind, Barrier) or hasattr(kind, "bound_rows")
    return known


_WRITES_INTO: dict[type, bool] = {}


def _writes_into(obj: object) -> bool:
    """Whether a potential writes its gradient into a caller's array (``value_and_gradient_into(robot, out, scale)
    -> p``, e.g. :class:`~redundik.tasks.potentials.Clearance`), remembered per class."""
    kind = type(obj)
    known = _WRITES_INTO.get(kind)
    if known is None:
        known = _WRITES_INTO[kind] = callable(getattr(kind, "value_and_gradient_into", None))
    return known


class _Number:
    """A subtask's number attribute, checked on every assignment as its constructor checks it (``check_number``:
    finite, and ≥ or > ``low``); the error names the subtask and the attribute."""

    def __init__(self, label: str, *, low: float | None = None, strict: bool = False) -> None:
        self.label, self.low, self.strict = label, low, strict
        self.slot = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.slot = f"_{name}"

    @overload
    def __get__(self, obj: None, objtype: type | None = None) -> _Number: ...
    @overload
    def __get__(self, obj: object, objtype: type | None = None) -> float: ...
    def __get__(self, obj: object | None, objtype: type | None = None) -> float | _Number:
        if obj is None:
            return self
        value: float = getattr(obj, self.slot)
        return value

    def __set__(self, obj: object, value: float) -> None:
        what = f"subtask '{getattr(obj, 'name', '?')}': {self.label}"
        setattr(obj, self.slot, check_number(value, what, low=self.low, strict=self.strict))
        Edits.count += 1  # (a fused step's packed copy compares it)


class _Level:
    """A target or bound subtask's ``priority``: ``None`` (the first level below the main tasks) or a level ≥ 0,
    checked on every assignment as the constructor checks it; a change moves ``Edits.layout`` (a resolver lays the
    stack out again)."""

    @overload
    def __get__(self, obj: None, objtype: type | None = None) -> _Level: ...
    @overload
    def __get__(self, obj: object, objtype: type | None = None) -> int | None: ...
    def __get__(self, obj: object | None, objtype: type | None = None) -> int | _Level | None:
        if obj is None:
            return self
        level: int | None = obj.__dict__["_priority"]
        return level

    def __set__(self, obj: object, value: int | None) -> None:
        level = check_priority(value, f"subtask '{getattr(obj, 'name', '?')}'")
        state = obj.__dict__
        if "_priority" in state and state["_priority"] != level:
            Edits.layout += 1
        state["_priority"] = level


class _Source:
    """A subtask's potential (``potential``) or source (``source``: a potential or a barrier), checked on every
    assignment as the constructor checks it; a new object moves ``Edits.layout`` (a resolver checks it against the
    robot and plans the stack again: a compiled step packed the old one's writer)."""

    def __init__(self, barrier: bool) -> None:
        self.barrier = barrier
        self.slot = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.slot = f"_{name}"

    @overload
    def __get__(self, obj: None, objtype: type | None = None) -> _Source: ...
    @overload
    def __get__(self, obj: object, objtype: type | None = None) -> Any: ...
    def __get__(self, obj: object | None, objtype: type | None = None) -> Any:
        if obj is None:
            return self
        return obj.__dict__[self.slot]

    def __set__(self, obj: object, value: object) -> None:
        kinds: tuple[type, ...] = (Potential, Barrier) if self.barrier else (Potential,)
        what = type(obj).__name__ if "_name" not in obj.__dict__ else f"subtask '{obj.__dict__['_name']}'"
        if not isinstance(value, kinds):
            expected = "a Potential or a Barrier" if self.barrier else "a Potential (p(q) with its gradient)"
            raise TaskError(f"{what}: expected {expected}, got {type(value).__name__}")
        state = obj.__dict__
        old = state.get(self.slot)
        if old is not None and old is not value:
            check = getattr(obj, "_check_source", None)
            if check is not None:
                check(value)
            Edits.layout += 1
            Edits.count += 1
        state[self.slot] = value


_OWN_ROWS: dict[type, bool] = {}


def _own_rows(kind: type[BoundSubtask]) -> bool:
    """Whether a subclass of ``BoundSubtask`` overrides ``rows`` but not ``rows_into`` (its rows are its own),
    remembered per class."""
    known = _OWN_ROWS.get(kind)
    if known is None:
        rows, rows_into = BoundSubtask.rows, BoundSubtask.rows_into
        known = _OWN_ROWS[kind] = kind.rows is not rows and kind.rows_into is rows_into
    return known


class Subtask(ABC):
    """Base of the typed subtasks: a name (the potential's or barrier's by default) and a ``kind``."""

    kind: ClassVar[str] = "subtask"
    _name: str

    @property
    def name(self) -> str:
        """Subtask name (unique in a stack)."""
        return self._name

    @name.setter
    def name(self, value: str) -> None:
        name = check_name(value, f"{type(self).__name__}")
        if self.__dict__.get("_name", name) != name:  # (a level override names it: the layout is made again)
            Edits.layout += 1
        self._name = name
        Edits.count += 1  # (a fused step's packed row names compare it)

    @abstractmethod
    def check(self, robot: RobotModel) -> None:
        """Validate against a robot (frames, joints, sizes); raise :class:`TaskError` if not."""

    @abstractmethod
    def __repr__(self) -> str: ...


def _value(owner: str, potential: Potential, p: object) -> float:
    """A potential's value p(q) as a float; a :class:`TaskError` naming the subtask and the potential when it is
    not one real number (a string, a complex, an array of several)."""
    try:
        return real_value(p)
    except (TypeError, ValueError) as exc:
        raise TaskError(
            f"subtask '{owner}': the value of potential '{source_name(potential)}' is not one real number ({exc}): "
            f"{short_repr(p)}"
        ) from None


def _gradient(owner: str, potential: Potential, eta: object, robot: RobotModel) -> np.ndarray:
    """``eta``, a potential's η = ∂p/∂q, as a float vector (nv,); a :class:`TaskError` naming the subtask and the
    potential when it is not one (a user's potential giving another size used to end in numpy's broadcast error)."""
    nv = robot.nv
    if type(eta) is np.ndarray and eta.shape == (nv,) and eta.dtype == np.float64:
        return eta
    what = f"subtask '{owner}': the gradient of potential '{source_name(potential)}'"
    try:
        arr = real_array(eta)
    except (TypeError, ValueError) as exc:
        raise TaskError(f"{what} is not a vector of numbers ({exc})") from exc
    if arr.shape != (nv,):
        raise TaskError(
            f"{what} has shape {arr.shape}, expected ({nv},) (one entry per velocity coordinate of the robot)"
        )
    return arr


class GradientSubtask(Subtask):
    """z = k η in the null space of the main tasks (eq. 5.8).

    Args:
        potential: p(q).
        gain: k [1/s · unit of q per unit of p]: > 0 climbs p, < 0 descends it.
        name: Defaults to the potential's name.

    Raises:
        TaskError: not a potential, or a non-finite gain.
    """

    kind: ClassVar[str] = "gradient"
    #: p(q): a :class:`~redundik.tasks.base.Potential`; another one assigned is checked and planned anew.
    potential = _Source(barrier=False)

    def __init__(self, potential: Potential, gain: float = 1.0, *, name: str | None = None) -> None:
        self.potential = potential
        self.name = default_name(name, source_name(potential), "GradientSubtask")
        self.gain = gain

    @property
    def gain(self) -> float:
        """k of eq. (5.8)."""
        return self._gain

    @gain.setter
    def gain(self, value: float) -> None:
        self._gain = check_number(value, f"subtask '{self.name}': gain")
        Edits.count += 1

    def check(self, robot: RobotModel) -> None:
        self.potential.check(robot)

    def direction(self, robot: RobotModel) -> np.ndarray:
        """This subtask's part of z: k η, shape (nv,) (eq. 5.8)."""
        potential = self.potential
        return self._gain * _gradient(self.name, potential, potential.gradient(robot), robot)

    def __repr__(self) -> str:
        return f"GradientSubtask({self.potential!r}, gain={self._gain})"


class TargetSubtask(Subtask):
    """Drive p to p_d: ṗ = ṗ_d + K (p_d − p), exponential convergence at rate K.

    Args:
        potential: p(q).
        target: p_d [unit of p]; settable between ticks (:meth:`set_target`).
        rate: K [1/s] ≥ 0.
        target_rate: ṗ_d [unit of p / s].
        weight: > 0, among the rows of its level in a QP.
        priority: ``None`` (the first level below the main tasks) or an explicit level ≥ 0.
        name: Defaults to the potential's name.

    Raises:
        TaskError: non-finite numbers, negative rate, non-positive weight, bad priority.
    """

    kind: ClassVar[str] = "target"
    #: p(q): a :class:`~redundik.tasks.base.Potential`; another one assigned is checked and planned anew.
    potential = _Source(barrier=False)
    #: Its level: ``None`` (the first level below the main tasks) or an explicit level ≥ 0.
    priority = _Level()

    def __init__(
        self,
        potential: Potential,
        target: float,
        *,
        rate: float = 1.0,
        target_rate: float = 0.0,
        weight: float = 1.0,
        priority: int | None = None,
        name: str | None = None,
    ) -> None:
        self.potential = potential
        self.name = default_name(name, source_name(potential), "TargetSubtask")
        self.set_target(target, target_rate)
        self.rate = rate
        self.weight = weight
        self.priority = priority

    def set_target(self, target: float, target_rate: float = 0.0) -> None:
        """Move the target p_d (and its rate ṗ_d) at run time, between ticks."""
        self.target = target
        self.target_rate = target_rate

    # checked on assignment as the constructor checks them (a NaN or negative rate or weight used to reach the
    # resolvers: a bare LinAlgError from hqp, a silent push away from the target)
    target = _Number("target")
    target_rate = _Number("target_rate")
    rate = _Number("rate (K)", low=0.0)
    weight = _Number("weight", low=0.0, strict=True)

    def check(self, robot: RobotModel) -> None:
        self.potential.check(robot)

    def row(self, robot: RobotModel) -> tuple[np.ndarray, float, float]:
        """(η, v, e): the 1-row task ηᵀq̇ = v with v = ṗ_d + K e and e = p_d − p."""
        potential = self.potential
        e = self.target - _value(self.name, potential, potential.value(robot))
        eta = _gradient(self.name, potential, potential.gradient(robot), robot)
        if not (math.isfinite(e) and math.isfinite(float(np.add.reduce(eta)))):
            raise NonFiniteRows(self.name)  # (a row the step cannot solve: it stops, naming this subtask)
        return eta, self.target_rate + self.rate * e, e

    def __repr__(self) -> str:
        return f"TargetSubtask({self.potential!r}, target={self.target}, rate={self.rate})"


class BoundSubtask(Subtask):
    """Keep ``lower ≤ p ≤ upper`` (a potential) or h(q) ≥ 0 (a barrier) with the velocity damper (module docstring).

    Args:
        source: A :class:`~redundik.tasks.base.Potential` (give ``lower`` and/or ``upper``) or a
            :class:`~redundik.tasks.base.Barrier` (no bounds: it is kept ≥ 0).
        lower: Lower bound [unit of p] or ``None``.
        upper: Upper bound [unit of p] or ``None``.
        rate: Approach gain K [1/s] ≥ 0 (0: γ = 1/dt).
        priority: ``None`` (the first level below the main tasks) or an explicit level ≥ 0.
        name: Defaults to the source's name.

    Raises:
        TaskError: neither bound for a potential, bounds for a barrier, lower > upper, non-finite numbers.
    """

    kind: ClassVar[str] = "bound"
    #: The potential or barrier kept within bounds; another one assigned is checked (against the bounds) and
    #: planned anew.
    source = _Source(barrier=True)
    #: Its level: ``None`` (the first level below the main tasks) or an explicit level ≥ 0.
    priority = _Level()

    def __init__(
        self,
        source: Potential | Barrier,
        *,
        lower: float | None = None,
        upper: float | None = None,
        rate: float = 0.0,
        priority: int | None = None,
        name: str | None = None,
    ) -> None:
        self.source = source
        self.name = default_name(name, source_name(source), "BoundSubtask")
        self._lower = None if lower is None else check_number(lower, f"subtask '{self.name}': lower")
        self._upper = None if upper is None else check_number(upper, f"subtask '{self.name}': upper")
        self._check_bounds(self._lower, self._upper)
        self.rate = rate
        self.priority = priority
        self._names_of: tuple[str, list[str]] | None = None  # (name, a barrier's last row names), prefixed:
        self._names: list[str] = []
        self._row_names_of: tuple[str, bool, bool] | None = None  # (name, lower set, upper set) of _row_names
        self._row_names: list[str] = []

    # lower, upper and rate are validated properties: assigned between ticks they are checked as the constructor
    # checks them (a NaN bound or rate used to reach the resolvers: the level skipped, or the bound silently ignored)
    def _check_source(self, source: Potential | Barrier) -> None:
        """A new source must suit the bounds set (``source``'s check on assignment)."""
        self._check_bounds(self._lower, self._upper, source)

    def _check_bounds(self, lower: float | None, upper: float | None, source: object = None) -> None:
        if lower is not None and upper is not None and lower > upper:
            raise TaskError(f"subtask '{self.name}': lower ({lower}) > upper ({upper})")
        if isinstance(self.source if source is None else source, Barrier):
            if lower is not None or upper is not None:
                raise TaskError(f"subtask '{self.name}': a barrier is kept ≥ 0; lower/upper apply to potentials only")
        elif lower is None and upper is None:
            raise TaskError(f"subtask '{self.name}': a bound subtask needs lower and/or upper")

    @property
    def lower(self) -> float | None:
        """Lower bound [unit of p], or ``None``."""
        return self._lower

    @lower.setter
    def lower(self, value: float | None) -> None:
        lower = None if value is None else check_number(value, f"subtask '{self.name}': lower")
        self._check_bounds(lower, self._upper)
        self._lower = lower
        Edits.count += 1

    @property
    def upper(self) -> float | None:
        """Upper bound [unit of p], or ``None``."""
        return self._upper

    @upper.setter
    def upper(self, value: float | None) -> None:
        upper = None if value is None else check_number(value, f"subtask '{self.name}': upper")
        self._check_bounds(self._lower, upper)
        self._upper = upper
        Edits.count += 1

    rate = _Number("rate (K)", low=0.0)

    @property
    def potential(self) -> Potential | None:
        """The potential, or ``None`` for a barrier source."""
        return self.source if isinstance(self.source, Potential) else None

    @property
    def critical(self) -> bool:
        """True for a safety barrier's rows (:attr:`~redundik.tasks.base.Barrier.critical`): never relaxed."""
        return isinstance(self.source, Barrier) and self.source.critical

    def check(self, robot: RobotModel) -> None:
        self.source.check(robot)

    @property
    def fixed_rows(self) -> int | None:
        """The number of damper rows when known before evaluating — a potential's bounds: 1 (lower or upper) or 2 —,
        ``None`` for a barrier or a source with ``bound_rows`` (their rows are their own: ``rows``), and for a
        subclass that overrides ``rows`` but not ``rows_into`` (its rows come from its ``rows``)."""
        if _rows_of_its_own(self.source) or _own_rows(type(self)):
            return None
        return (self.lower is not None) + (self.upper is not None)

    def rows_compiled(self, robot: RobotModel) -> bool:
        """Whether this subtask's rows have a compiled form: the damper rows of a potential with a linear gradient,
        a compiled writer or a clearance form, or of a barrier with a compiled writer (``Barrier.compiled_barrier``:
        the support polygon). ``False`` for a barrier without one (coal's distances), a potential with only a Python
        gradient, or a subclass with rows of its own: a compiled step writes those from Python and names the subtask
        (``info["interpreted"]``, a mixed step)."""
        source = self.source
        if self.fixed_rows is None:  # a barrier: its rows from its compiled writer, when it has one
            kind = type(self)
            return (
                kind.rows is BoundSubtask.rows
                and kind.values is BoundSubtask.values
                and getattr(source, "bound_rows", None) is None
                and barrier_writer(source, robot) is not None
            )
        if type(self).rows_into is not BoundSubtask.rows_into:
            return False
        return isinstance(source, Potential) and (
            self.clearance_form(robot) is not None
            or source.linear_gradient(robot) is not None
            or compiled_writer(source, robot) is not None
        )

    def clearance_form(self, robot: RobotModel) -> ClearanceForm | None:
        """The source's ``ClearanceForm`` when this subtask's rows are the damper rows of
        ``rows_into`` on a clearance (a fused step then computes them itself from ``lower``, ``upper`` and
        ``rate``); ``None`` otherwise — another source, or a subclass with rows of its own."""
        if self.fixed_rows is None or type(self).rows_into is not BoundSubtask.rows_into:
            return None
        source = self.source
        return source.clearance_form(robot) if isinstance(source, Potential) else None

    @property
    def row_names(self) -> list[str]:
        """A potential's row names, ``name:lower`` then ``name:upper`` (built once per name and bounds; not to be
        mutated)."""
        key = (self.name, self.lower is not None, self.upper is not None)
        if self._row_names_of != key:
            names = [f"{self.name}:lower"] if self.lower is not None else []
            names += [f"{self.name}:upper"] if self.upper is not None else []
            self._row_names_of, self._row_names = key, names
        return self._row_names

    def rows_into(self, robot: RobotModel, dt: float, C: np.ndarray, d: np.ndarray, offset: int) -> int:
        """A potential's damper rows C q̇ ≤ d (module docstring) written into the caller's buffers at row ``offset``:
        lower: C = −η, d = γ (p − lower); upper: C = η, d = γ (upper − p) [unit of p / s], γ = min(K or 1/dt, 1/dt)
        [1/s]. The one implementation of these rows (:meth:`rows` and :meth:`values` go through it).

        Args:
            robot: Updated robot.
            dt: Time step [s].
            C: (≥ offset + :attr:`fixed_rows`, nv) buffer; d: its right-hand sides.
            offset: First row written.

        Returns:
            The number of rows written (:attr:`fixed_rows`).

        Raises:
            TaskError: a source whose rows are its own (:attr:`fixed_rows` is ``None``: use :meth:`rows`).
        """
        if _rows_of_its_own(self.source):
            raise TaskError(f"subtask '{self.name}': a barrier's rows come from rows(), not rows_into()")
        cap = 1.0 / dt
        return self._damper_into(robot, cap if self.rate == 0 else min(self.rate, cap), C, d, offset)

    def _damper_into(self, robot: RobotModel, gamma: float, C: np.ndarray, d: np.ndarray, offset: int) -> int:
        """:meth:`rows_into` at a given γ [1/s] (γ = 1: d = h, C = −H) for a potential source."""
        lower, upper = self.lower, self.upper
        src: Potential = self.source  # (not a barrier: the callers checked)
        row = C[offset]
        if _writes_into(src):  # η written in place (e.g. Clearance's kernel)
            p = src.value_and_gradient_into(robot, row, -1.0 if lower is not None else 1.0)  # type: ignore[attr-defined]
        else:
            p, eta = src.value_and_gradient(robot)
            p = _value(self.name, src, p)
            eta = _gradient(self.name, src, eta, robot)
            if not math.isfinite(float(np.add.reduce(eta))):
                raise NonFiniteRows(self.name)  # (a row the step cannot keep: it stops, naming this subtask)
            if lower is not None:
                np.negative(eta, out=row)
            else:
                row[:] = eta
        if not math.isfinite(p):
            raise NonFiniteRows(self.name)
        if lower is not None:
            d[offset] = gamma * (p - lower)
            if upper is None:
                return 1
            np.negative(row, out=C[offset + 1])
            d[offset + 1] = gamma * (upper - p)
            return 2
        assert upper is not None  # (the constructor refuses a potential without bounds)
        d[offset] = gamma * (upper - p)
        return 1

    def values(self, robot: RobotModel) -> tuple[np.ndarray, np.ndarray, list[str], np.ndarray | None]:
        """(h, H, row names, per-row γ or ``None``) with h ≥ 0 the safe side."""
        src = self.source
        if isinstance(src, Barrier):
            form = barrier_writer(src, robot)
            if form is not None:  # (its compiled writer: the same rows as its evaluate)
                h, H = barrier_values(form, robot)
                names, gamma = form.names, None if form.gamma == 0 else np.full(h.shape[0], float(form.gamma))
            else:
                term = conform_barrier_term(src.evaluate(robot), robot._nv, self.name)
                h, H, names, gamma = term.h, term.H, term.names, term.gamma
            if not (math.isfinite(float(np.add.reduce(h))) and math.isfinite(float(np.add.reduce(H, axis=None)))):
                raise NonFiniteRows(self.name)  # (a row the step cannot keep: it stops, naming this subtask)
            return h, H, self._prefixed(names), gamma
        k = (self.lower is not None) + (self.upper is not None)
        C, d = np.empty((k, robot.nv)), np.empty(k)
        self._damper_into(robot, 1.0, C, d, 0)  # γ = 1: d = h, C = −H
        return d, -C, list(self.row_names), None

    def _prefixed(self, names: list[str]) -> list[str]:
        """``name:row`` per row name, built once per set of rows (e.g. a collision barrier's active pairs)."""
        if self._names_of != (self.name, names):
            self._names_of, self._names = (self.name, list(names)), [f"{self.name}:{n}" for n in names]
        return self._names

    def rows(self, robot: RobotModel, dt: float) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """The damper ḣ ≥ −γh as QP rows C q̇ ≤ d: C = −H, d = γ h (module docstring), γ = min(K or 1/dt, 1/dt)."""
        k = self.fixed_rows
        if k is not None:  # a potential: its rows written by rows_into
            C, d = np.empty((k, robot.nv)), np.empty(k)
            self.rows_into(robot, dt, C, d, 0)
            return C, d, list(self.row_names)
        cap = 1.0 / dt
        direct = getattr(self.source, "bound_rows", None)  # a barrier making its rows itself (collision avoidance)
        if direct is not None:
            return direct(robot, cap, self.name)
        h, H, names, gamma_rows = self.values(robot)
        gamma: float | np.ndarray
        if gamma_rows is not None:
            gamma = np.minimum(gamma_rows, cap)
        else:
            gamma = cap if self.rate == 0 else min(self.rate, cap)
        return -H, gamma * h, names

    def __repr__(self) -> str:
        return f"BoundSubtask({self.source!r}, lower={self.lower}, upper={self.upper}, rate={self.rate})"

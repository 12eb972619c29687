"""The task contract every resolver reads.

* A **task** (a main task, or a regularisation task such as a posture) gives, at the current kinematic state, a
  :class:`TaskTerm`: a Jacobian J (m×n), a desired velocity V (m,) and an error e (m,), so that J q̇ = V is what it
  asks for (eq. 5.6). Its shared fields — ``name``, ``weight``, ``gain``, ``priority`` — live here with one
  validation. A task *declares* what a resolver may exploit (:attr:`Task.identity_jacobian`: J = I, a diagonal
  update; :attr:`Task.regularization`: it lies below every main task and subtask), so no resolver tests classes.
* A **potential** is a scalar p(q) with its exact gradient η = ∂p/∂q (n,) — the subtasks of section 5.2.
* A **barrier** is a vector h(q) ≥ 0 with its Jacobian H = ∂h/∂q (k×n): a clearance, a collision distance, a
  support polygon. Bound subtasks keep it non-negative.
* How a resolver uses a potential or a barrier is a typed subtask (:mod:`redundik.tasks.subtasks`).
* The meaning of a stack under every resolver is fixed in one place: :mod:`redundik.tasks.stack`.
"""

from __future__ import annotations

import math
import re
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar, NamedTuple

import numpy as np

from redundik.errors import TaskError, short_repr
from redundik.kinematics.model import RobotModel

#: Task, subtask and potential names: a letter or digit first, then letters, digits, ``_ . : -`` (≤ 64 chars).
NAME_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.:\-]{0,63}$")


def check_name(name: object, what: str) -> str:
    """Return ``name`` if it is a valid task / subtask name (see :data:`NAME_PATTERN`).

    Raises:
        TaskError: not a string, empty, too long, or with characters outside the set.
    """
    if not isinstance(name, str) or not NAME_PATTERN.match(name) or ".." in name:
        shown = repr(name)[:70]
        raise TaskError(
            f"{what}: name {shown} is not valid: use 1-64 characters among letters, digits and _ . : - "
            "(starting with a letter or digit, no '..')"
        )
    return name


def source_name(source: object) -> str:
    """The name of a potential or barrier, the default name of a subtask on it: its ``name`` attribute, or — when a
    user's class sets none — its class name in snake case (``MyPotential`` → ``my_potential``).

    Raises:
        TaskError: a ``name`` that is not a valid name (:data:`NAME_PATTERN`).
    """
    name = getattr(source, "name", None)
    if name is None:
        name = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", type(source).__name__).lower().strip("_") or "potential"
    return check_name(name, f"{type(source).__name__}.name")


def default_name(name: object, default: str, what: str) -> str:
    """``default`` when ``name`` is ``None``, else ``name`` if it is a non-empty str (the ``name or default`` of the
    constructors, which took ``""`` for ``None`` and failed on an array's truth value).

    Raises:
        TaskError: ``name`` neither ``None`` nor a non-empty str; the message names ``what`` and the default.
    """
    if name is None:
        return default
    if not isinstance(name, str) or not name:
        raise TaskError(
            f"{what}: name must be a non-empty string (or None for the default '{default}'), got "
            f"{type(name).__name__} {short_repr(name)}"
        )
    return name


def check_number(value: object, what: str, *, low: float | None = None, strict: bool = False) -> float:
    """A finite float ≥ ``low`` (> ``low`` when ``strict``).

    Raises:
        TaskError: not a real number, NaN/inf, beyond the float range, or out of range; the message names ``what``.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TaskError(f"{what} must be a number, got {type(value).__name__}")
    try:
        val = float(value)
    except OverflowError:  # an int beyond the float range (10**400)
        raise TaskError(f"{what} must be a finite number, got {short_repr(value)}: out of the float range") from None
    if not math.isfinite(val):
        raise TaskError(f"{what} must be a finite number, got {val}")
    if low is not None and (val <= low if strict else val < low):
        raise TaskError(f"{what} must be {'>' if strict else '≥'} {low:g}, got {val:g}")
    return val


def check_priority(value: object, what: str) -> int | None:
    """``None`` or an integer level ≥ 0 (0 is the highest)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or int(value) < 0:
        raise TaskError(f"{what}: priority must be an integer level ≥ 0 (0 = highest) or None, got {value!r}")
    return int(value)


#: What ``Task.frame_form`` returns while a frame task cannot describe its rows yet (not evaluated on this robot).
NOT_READY = "not ready"


class FrameForm(NamedTuple):
    """The rows of a frame task in the form a fused step computes itself (``Task.frame_form``): the selected
    rows of the frame's base-aligned Jacobian, e = (p_d − p, log3(R_d Rᵀ))[rows], v = V_d[rows] + K e, with
    (p_d, R_d, V_d) the trajectory's reference.

    Attributes:
        task: The task (its ``gain`` and ``weight`` are read when :class:`Edits` moved).
        fid: The frame's id in the robot's model.
        rows: The controlled rows of the twist (int array, read-only).
        rotation_rows: Whether any of them is a rotation row.
        all_rows: Whether they are all six, in order.
        trajectory: The reference (its compiled parameter row is packed; ``revision`` says when it was rewritten).
        revision: The task's ``Task.form_revision`` when the form was made.
    """

    task: Any
    fid: int
    rows: np.ndarray
    rotation_rows: bool
    all_rows: bool
    trajectory: Any
    revision: int


class ClearanceForm(NamedTuple):
    """The clearance of a frame point to a round obstacle, p = ‖S(p_f − p_o)‖ − r, in the form a fused step computes
    itself (``Potential.clearance_form``; the one kernel is
    ``potential_kernels.clearance_into``).

    Attributes:
        fid: The frame's id in the robot's model.
        rows: The axes S selects (indices into x, y, z; int array).
        center: The obstacle's centre p_o (3,) [m].
        radius: Its radius r [m].
        columns: Per velocity column, nonzero where a joint that supports the frame acts (int array, (nv,)).
    """

    fid: int
    rows: np.ndarray
    center: np.ndarray
    radius: float
    columns: np.ndarray


class CompiledRows(NamedTuple):
    """A task's rows as a compiled writer: the optional compiled form of the row protocol (``Task.compiled_rows``).

    A step calls ``kernel(q, t, poses, jw, ints, floats, gain, J, e, v)`` — a ``numba.njit`` function — with

    * ``q`` (nq,) the configuration, ``t`` [s] the time;
    * ``poses`` (nframes, 12): per frame of the model, its placement in the world at q: the rotation column-major
      (R[i, j] = ``poses[f, 3 j + i]``) then the origin (``poses[f, 9:12]``) [m] (Pinocchio's ``data.oMf``);
    * ``jw`` (6, nv): the joint Jacobians in the world frame (Pinocchio's ``data.J`` after
      ``computeJointJacobians``; ``frame_jacobian_lwa`` turns a frame's columns
      into its base-aligned Jacobian);
    * ``ints``, ``floats``: the task's own data (its frame ids, its target …), arrays it may rewrite in place between
      steps — a new target is data, not a new plan;
    * ``gain`` K [1/s], the task's current gain;

    and the kernel writes the task's ``rows`` rows: its Jacobian into ``J`` (rows, nv; zeros on entry), its error
    into ``e`` and its desired velocity (feed-forward + K e) into ``v``. The same kernel gives the per-task path's
    :meth:`Task.evaluate` (:class:`redundik.tasks.rows.CompiledTask`): one formula, two paths.

    Attributes:
        kernel: The compiled writer.
        rows: Its number of rows (fixed while the task's ``form_revision`` is unchanged).
        ints: int64 data (1-D).
        floats: float64 data (1-D).
    """

    kernel: Any
    rows: int
    ints: np.ndarray
    floats: np.ndarray


class CompiledGradient(NamedTuple):
    """A potential's p(q) and η = ∂p/∂q as a compiled writer: the optional compiled form of a potential
    (``Potential.compiled_gradient``), which a compiled step calls in place of ``gradient`` (a gradient subtask's
    z = k η, eq. 5.8).

    A step calls ``kernel(q, poses, jw, ints, floats, eta)`` — a ``numba.njit`` function — with ``q``, ``poses``
    and ``jw`` as for :class:`CompiledRows` (the configuration, the frames' placements, the joint Jacobians in the
    world frame) and ``ints``, ``floats`` the potential's own data (rewritten in place when it is assigned: data, not
    a new plan); the kernel writes η into ``eta`` (nv,; zeros on entry) and returns p.
    :class:`redundik.tasks.potential_rows.CompiledPotential` derives ``value`` and ``gradient`` from the same kernel:
    one formula, two paths.

    Attributes:
        kernel: The compiled writer.
        ints: int64 data (1-D).
        floats: float64 data (1-D).
    """

    kernel: Any
    ints: np.ndarray
    floats: np.ndarray


class CompiledBarrier(NamedTuple):
    """A barrier's h(q) ≥ 0 and H = ∂h/∂q as a compiled writer: the optional compiled form of a barrier
    (``Barrier.compiled_barrier``), which a bound subtask calls in place of ``evaluate``.

    A step calls ``kernel(q, poses, jw, ints, floats, h, H)`` — a ``numba.njit`` function — with ``q``, ``poses``
    and ``jw`` as for :class:`CompiledRows` and ``ints``, ``floats`` the barrier's own data; the kernel writes the
    ``rows`` values h into ``h`` (rows,) and their Jacobian into ``H`` (rows, nv; zeros on entry).

    Attributes:
        kernel: The compiled writer.
        rows: Its number of rows.
        ints: int64 data (1-D).
        floats: float64 data (1-D).
        names: One name per row (``BarrierTerm.names``).
        gamma: The damper's gain γ [1/s] of every row, or 0: the bound subtask's rate (``BarrierTerm.gamma``
            ``None``).
    """

    kernel: Any
    rows: int
    ints: np.ndarray
    floats: np.ndarray
    names: list[str]
    gamma: float = 0.0


class Edits:
    """A counter that every change of a task's or a gradient subtask's gain or weight moves (their validated setters):
    a fused step (:mod:`redundik.resolvers.fused`) re-reads its coefficients when it has moved."""

    count: ClassVar[int] = 0
    #: Moved by every change, once a member exists, of what a resolver checks and lays out from a stack: a task's or
    #: a target or bound subtask's ``priority``, a member's ``name`` (a resolver's level overrides name them), a
    #: subtask's potential or source. It is part of ``TaskStack.signature``: a resolver checks the stack and lays it
    #: out again when it has moved.
    layout: ClassVar[int] = 0


@dataclass
class TaskTerm:
    """A task evaluated at one instant: ask for J q̇ = v.

    Attributes:
        name: Task name.
        J: Jacobian, shape (m, nv).
        v: Desired velocity (feed-forward plus feedback on the error), shape (m,).
        error: Task error (desired minus actual), shape (m,).
        weight: Weight of the term in a weighted QP.
    """

    name: str
    J: np.ndarray
    v: np.ndarray
    error: np.ndarray
    weight: float = 1.0

    @property
    def error_norm(self) -> float:
        """Euclidean norm of the error."""
        return float(np.linalg.norm(self.error))


class Task(ABC):
    """A velocity-level task J q̇ = v (a main task of the chapter, a QP level, or a regulariser).

    Shared fields (validated on every assignment):

    * ``name``: unique in a stack (see :data:`NAME_PATTERN`);
    * ``weight`` > 0: the task's weight among the rows of its level (``wqp``: relative to the other tasks of the
      level; ``pinv``/``hqp`` ignore it within a single task);
    * ``gain`` K ≥ 0 [1/s]: feedback on the task error, v = v_d + K e; with a first-order loop the error decays as
      (1 − K dt)^k, so resolvers refuse K·dt > 2 (unstable);
    * ``priority``: ``None`` (the default level of the task's role, see :mod:`redundik.tasks.stack`) or an
      integer level ≥ 0 (0 = highest).

    Declarations for resolvers (class attributes, overridable per instance):

    * ``identity_jacobian``: J is the n×n identity (a posture): the QP adds it as a diagonal update;
    * ``regularization``: the task lies strictly below every main task and subtask (a posture / damping task):
      without a ``priority``, its J⁺v joins z of the null-space objective (:mod:`redundik.tasks.stack`).
    """

    identity_jacobian: ClassVar[bool] = False
    regularization: ClassVar[bool] = False

    _name: str
    _weight: float = 1.0
    _gain: float = 0.0
    _priority: int | None = None
    _form_revision: int = 0

    def _init_task(self, name: str, *, weight: float = 1.0, gain: float = 0.0, priority: int | None = None) -> None:
        """Set the shared fields with their validation (call from a subclass's ``__init__``)."""
        self.name = name
        self.weight = weight
        self.gain = gain
        self.priority = priority

    # -- shared fields with one validation
    @property
    def name(self) -> str:
        """Task name."""
        return self._name

    @name.setter
    def name(self, value: str) -> None:
        name = check_name(value, f"task {type(self).__name__}")
        if self.__dict__.get("_name", name) != name:  # (a level override names it: the layout is made again)
            Edits.layout += 1
        self._name = name

    @property
    def weight(self) -> float:
        """Weight (> 0) among the rows of the task's level."""
        return self._weight

    @weight.setter
    def weight(self, value: float) -> None:
        self._weight = check_number(value, f"task '{self._label}': weight", low=0.0, strict=True)
        Edits.count += 1

    @property
    def gain(self) -> float:
        """Feedback gain K [1/s] ≥ 0 on the task error."""
        return self._gain

    @gain.setter
    def gain(self, value: float) -> None:
        self._gain = check_number(value, f"task '{self._label}': gain", low=0.0)
        Edits.count += 1

    @property
    def priority(self) -> int | None:
        """Explicit level (0 = highest), or ``None`` for the default of the task's role."""
        return self._priority

    @priority.setter
    def priority(self, value: int | None) -> None:
        level = check_priority(value, f"task '{self._label}'")
        if "_priority" in self.__dict__ and self._priority != level:  # (a stack holding it is laid out again)
            Edits.layout += 1
        self._priority = level

    @property
    def gain_tracked(self) -> bool:
        """True when ``gain`` is this base class's validated property, whose assignments move ``Edits`` (a resolver
        re-reads the gains only when ``Edits`` moved); False for a subclass with a ``gain`` of its own (read every
        step)."""
        return type(self).gain is Task.gain

    @property
    def _label(self) -> str:
        return getattr(self, "_name", type(self).__name__)

    # -- the contract
    def reset(self, robot: RobotModel) -> None:  # noqa: B027 - optional hook
        """Capture what the task needs at t = 0 (e.g. the start pose of a trajectory); ``robot`` is updated.

        A target set explicitly (``set_target``) survives a reset.
        """

    @abstractmethod
    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        """The task at time ``t`` [s]; ``robot`` has been :meth:`~RobotModel.update`-d at the current q."""

    @property
    def form_revision(self) -> int:
        """A counter the task moves whenever the form of its rows changes (another frame, axes or trajectory, a
        reset on another robot): a fused step plans the stack again when it moved. Targets, gains and weights are
        data and do not move it."""
        return self._form_revision

    def frame_form(self, robot: RobotModel) -> FrameForm | str | None:
        """The ``FrameForm`` of this task's rows, when they are those of a frame task that a fused step may
        compute itself; ``NOT_READY`` when they will be (after the first evaluation on ``robot``); ``None``
        (the default): only :meth:`evaluate` gives them."""
        return None

    def compiled_rows(self, robot: RobotModel) -> CompiledRows | None:
        """The task's rows as a compiled writer (:class:`CompiledRows`) on ``robot``, which a compiled step calls in
        place of :meth:`evaluate`; ``None`` (the default): only :meth:`evaluate` gives them. The returned arrays stay
        the task's (rewritten in place); a change of the rows' form (their number, their frames) must move
        :attr:`form_revision`."""
        return None

    def reference_sampled(self, R_d: np.ndarray) -> None:  # noqa: B027 - optional hook
        """Told by a fused step that sampled this task's reference itself (its ``frame_form`` rows): the desired
        orientation R_d (3, 3) of that step (a frame task keeps it for a later position-only target)."""

    def joint_form(self, robot: RobotModel) -> tuple[np.ndarray, np.ndarray] | None:
        """(sel, q_ref) when this task's rows are J = I[sel], e = (q_ref ⊖ q)[sel], v = K e — a posture on the
        velocity coordinates ``sel`` (int array) towards q_ref (nq,) — so that a fused step
        (:mod:`redundik.resolvers.fused`) can compute them itself; ``None`` (the default): only :meth:`evaluate`.

        The arrays returned must be the same objects while the task is unchanged (a new target: new arrays)."""
        return None

    @abstractmethod
    def __repr__(self) -> str: ...


class Potential(ABC):
    """A scalar subtask potential p(q) with exact gradient η = ∂p/∂q (section 5.2)."""

    name: str

    def check(self, robot: RobotModel) -> None:  # noqa: B027 - optional hook
        """Validate against a robot (frames and joints exist, sizes match); raise :class:`TaskError` if not."""

    @abstractmethod
    def value(self, robot: RobotModel) -> float:
        """p(q) at the robot's current (updated) state."""

    @abstractmethod
    def gradient(self, robot: RobotModel) -> np.ndarray:
        """η = ∂p/∂q, shape (nv,), exact (analytic or from Pinocchio's kinematic derivatives)."""

    def value_and_gradient(self, robot: RobotModel) -> tuple[float, np.ndarray]:
        """(p, η) at once, for the rows of a bound subtask (a potential may share the work of the two)."""
        return self.value(robot), self.gradient(robot)

    def clearance_form(self, robot: RobotModel) -> ClearanceForm | None:
        """The ``ClearanceForm`` of p when p is a clearance that a fused step may compute itself on ``robot``;
        ``None`` (the default): only ``value_and_gradient`` gives it."""
        return None

    def linear_gradient(self, robot: RobotModel) -> tuple[np.ndarray, np.ndarray] | None:
        """(w (nv,), q_c (nq,)) when η = w ⊙ (q ⊖ q_c) (a weighted joint centering), for a fused step; else ``None``.

        The arrays returned must be the same objects while the potential is unchanged."""
        return None

    #: Moved whenever the form of the potential's compiled writer changes (another frame, other axes): a compiled
    #: step plans its stack again. Values it reads (a centre, a radius, a point) are data and do not move it.
    form_revision: int = 0

    def compiled_gradient(self, robot: RobotModel) -> CompiledGradient | None:
        """p and η as a compiled writer (:class:`CompiledGradient`) on ``robot``, which a compiled step calls in
        place of :meth:`gradient`; ``None`` (the default): only :meth:`gradient` gives η. The returned arrays stay
        the potential's (rewritten in place); a change of their size or meaning must move :attr:`form_revision`."""
        return None

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={getattr(self, 'name', None)!r})"


@dataclass
class BarrierTerm:
    """A barrier evaluated at one instant: keep h(q) ≥ 0.

    Attributes:
        h: Barrier values, shape (k,) (distance-like; ≥ 0 is safe).
        H: Their Jacobian ∂h/∂q, shape (k, nv).
        names: One name per row, for diagnostics.
        gamma: Optional per-row approach gain γ [1/s] of the damper ḣ ≥ −γ h (``None``: the subtask's rate).
    """

    h: np.ndarray
    H: np.ndarray
    names: list[str]
    gamma: np.ndarray | None = None


class Barrier(ABC):
    """A vector-valued constraint h(q) ≥ 0 with its Jacobian (pink's barriers; Kanoun et al. 2011 inequalities).

    Attributes:
        critical: ``True`` for a safety constraint (a collision distance): a QP resolver that has to relax its
            problem keeps these rows, and a fallback velocity is scaled down until they hold.
    """

    name: str
    critical: ClassVar[bool] = False

    def check(self, robot: RobotModel) -> None:  # noqa: B027 - optional hook
        """Validate against a robot; raise :class:`TaskError` if not."""

    @abstractmethod
    def evaluate(self, robot: RobotModel) -> BarrierTerm:
        """h(q), ∂h/∂q at the robot's current (updated) state."""

    def compiled_barrier(self, robot: RobotModel) -> CompiledBarrier | None:
        """h and H as a compiled writer (:class:`CompiledBarrier`) on ``robot`` (checked), which a bound subtask
        calls in place of :meth:`evaluate`; ``None`` (the default): only :meth:`evaluate` gives them. The returned
        arrays stay the barrier's (rewritten in place)."""
        return None

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={getattr(self, 'name', None)!r})"


def stack_terms(terms: list[TaskTerm], nv: int) -> tuple[np.ndarray, np.ndarray]:
    """Stack task terms into one Jacobian (Σm, nv) and one velocity (Σm,)."""
    if not terms:
        return np.zeros((0, nv)), np.zeros(0)
    if len(terms) == 1:
        return terms[0].J, terms[0].v
    try:
        return np.vstack([t.J for t in terms]), np.concatenate([t.v for t in terms])
    except ValueError:  # a term of the wrong shape (a user's evaluate): say which
        for t in terms:
            check_term(t, nv)
        raise


def check_term(term: TaskTerm, nv: int) -> None:
    """``term`` is a (m, nv) Jacobian with a velocity and an error of shape (m,).

    Raises:
        TaskError: naming the task and the shapes it gave.
    """
    J, v, e = term.J, term.v, term.error
    try:
        shapes: list[tuple[int, ...] | None] = [tuple(np.shape(x)) for x in (J, v, e)]
    except ValueError:  # ragged nested lists
        shapes = [None, None, None]
    m = shapes[0][0] if shapes[0] is not None and len(shapes[0]) == 2 else None
    if m is None or shapes[0] != (m, nv) or shapes[1] != (m,) or shapes[2] != (m,):
        raise TaskError(
            f"task '{term.name}': evaluate returned J of shape {shapes[0]}, v of shape {shapes[1]} and error of "
            f"shape {shapes[2]}; expected J (m, {nv}) and v, error (m,) (m rows, {nv} velocity coordinates)"
        )

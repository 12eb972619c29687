"""What every resolver shares: input validation and the abstract interface (the step result record is
:mod:`redundik.resolvers.result`, re-exported here).

The contract of :meth:`Resolver.step` (the call a control loop makes once per tick):

* q must be finite and of size nq, dt finite and > 0, t finite: otherwise a :class:`ResolverError` naming the value;
* the stack is checked on first use and whenever its membership changes (:meth:`TaskStack.signature`): subtask
  kinds the resolver does not accept are refused with an error that names the subtask and lists what it accepts;
* a task gain K with K·dt > 2 is refused (the first-order loop e ← (1 − K dt) e diverges);
* ‖q̇‖ or the task error growing geometrically over consecutive steps is flagged (``info["diverging"]``, a
  :class:`~redundik.resolvers.divergence.DivergenceWarning`; :mod:`redundik.resolvers.divergence`);
* the returned q̇ is always finite; when an intermediate is not, the step says so in ``fallback`` with the terms
  that caused it, and q̇ is the safest value the resolver has (zero, clipped to the limits).
"""

from __future__ import annotations

import logging
import math
import os
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from redundik.errors import NonFiniteRows, ResolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.divergence import DivergenceWatch
from redundik.resolvers.result import LazyInfo as LazyInfo
from redundik.resolvers.result import LazyStepResult as LazyStepResult
from redundik.resolvers.result import StepResult as StepResult
from redundik.resolvers.result import nonfinite_sources as nonfinite_sources
from redundik.resolvers.singularity import LimiterOption, SpeedLimiter
from redundik.tasks.base import Edits
from redundik.tasks.potential_rows import compiled_writer
from redundik.tasks.stack import TaskStack

if TYPE_CHECKING:
    from redundik.resolvers.watchdog import Watchdog

#: Largest stable K·dt of the first-order update (e ← (1 − K dt) e).
STABLE_GAIN_DT = 2.0
#: From this many velocity coordinates on, a step limits BLAS to one thread (see ``Resolver.blas_threads``): below
#: it, toggling the BLAS pool costs more than it saves (measured on Talos, nv = 38: +20 µs a step).
BLAS_LIMIT_NV = 64
_USER_CHOSE_THREADS = any(os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"))
_F64 = np.dtype(np.float64)
#: Largest magnitude of a configuration coordinate [rad or length unit] a step accepts (the simulation's divergence
#: bound, ``simulation.integrators.MAX_COORDINATE``): beyond it sin/cos of an angle have no significant digit left.
MAX_Q = 1e9
_MAX_Q2 = MAX_Q * MAX_Q


def _squares_below(q: np.ndarray, bound2: float) -> bool:
    """qᵀq < ``bound2`` (False for a NaN or infinite entry, or one whose square overflows): the compiled
    :func:`redundik.resolvers.kernels.squares_below`, which replaces this function at its first call (numba is not
    imported with redundik). ``Resolver.step`` checks ‖q‖ < MAX_Q with it on every tick."""
    global _squares_below
    from redundik._coldstart import cold, twin
    from redundik.resolvers.linalg import K

    if cold():  # no kernel compiled yet: its own code, interpreted (bound at a later call; redundik._coldstart)
        return bool(twin(K.squares_below)(q, bound2))
    _squares_below = K.squares_below
    return bool(_squares_below(q, bound2))


_CONTROLLER: Any = None  # the process's _BlasLimit, built on first use


class _BlasLimit:
    """Sets the BLAS libraries' thread count for the span of a step and puts back what was there: the libraries'
    own setters, found once through threadpoolctl (not its ``limit`` context, which builds a limiter and queries
    every library at each call, several times the cost of these setters)."""

    def __init__(self) -> None:
        # SciPy's OpenBLAS (the LAPACK the compiled kernels call, through scipy.linalg.cython_lapack) is loaded first:
        # a controller built before it never limits it (the snake's n = 160 SVDs would run on two threads)
        import scipy.linalg  # noqa: F401
        from threadpoolctl import ThreadpoolController

        self.libs: list[Any] = list(ThreadpoolController().select(user_api="blas").lib_controllers)

    def set(self, n: int) -> list[tuple[Any, int]]:
        """Limit every BLAS library to ``n`` threads; returns what :meth:`restore` puts back."""
        changed = []
        for lib in self.libs:
            now = lib.get_num_threads()
            if now is not None and now != n:
                lib.set_num_threads(n)
                changed.append((lib, now))
        return changed

    @staticmethod
    def restore(changed: list[tuple[Any, int]]) -> None:
        """Put back the thread counts :meth:`set` changed."""
        for lib, now in changed:
            lib.set_num_threads(now)


def _blas_limiter() -> _BlasLimit:
    """The process's ``_BlasLimit``, built on first use."""
    global _CONTROLLER
    if _CONTROLLER is None:
        _CONTROLLER = _BlasLimit()
    return _CONTROLLER


#: ``result.info["path"]``: the step's rows were written by compiled writers (the fused step), by compiled writers
#: and the Python ``evaluate`` of the members without a compiled form before one compiled solve (mixed), or by every
#: member's Python ``evaluate``; ``result.info["interpreted"]`` names the members written from Python (empty when
#: compiled).
COMPILED, MIXED, INTERPRETED = "compiled", "mixed", "interpreted"
_LOG = logging.getLogger("redundik")
_WARNED_INTERPRETED: set[tuple[str, tuple[str, ...]]] = set()
_WARNED_MIXED: set[tuple[str, tuple[str, ...]]] = set()


class Resolver(ABC):
    """Turns a task stack into a joint velocity, one control tick at a time.

    Subclasses implement :meth:`solve`, which reads a robot already updated at the current configuration, and
    declare the subtask kinds they accept in :attr:`accepts`. :meth:`step` is the call for a control loop.

    Threads: use one resolver per thread (and one robot and stack per thread). A resolver keeps scratch buffers,
    warm starts and plans between steps, so it is not safe to share: a :meth:`step` called while another thread is
    inside a step of the same resolver raises :class:`ResolverError` instead of mixing the two (which gave silently
    wrong answers). Copies (``copy.deepcopy``, ``pickle``) of a resolver are independent and may go to other threads.
    """

    name: str = "resolver"
    #: Subtask kinds (``Subtask.kind``) this resolver resolves; others are refused by :meth:`check`.
    accepts: ClassVar[tuple[str, ...]] = ()

    _checked: tuple[int, ...] | None = None
    #: (stack, robot, its tasks, its subtasks) as last checked: a step whose stack has the same members (by identity)
    #: skips recomputing the signature
    _members: tuple[TaskStack, RobotModel, list[Any], list[Any], int] | None = None
    _watch: DivergenceWatch | None = None
    _gain_members: tuple[tuple[Any, ...], tuple[Any, ...]] = ((), ())
    _plain_gains = False
    _gains_seen: tuple[int, float] | None = None  # (Edits.count, 2/dt) at the last gain check that passed
    _stepping: TaskStack | None = None
    #: The command watchdog (:mod:`redundik.resolvers.watchdog`), or ``None``; :attr:`command_timeout` makes one.
    watchdog: Watchdog | None = None
    #: The checked value of :attr:`blas_threads` (the class default until one is assigned): what a step reads.
    _blas_threads: int | str | None = "auto"
    #: The joint-speed cap [rad/s] and the singularity guard (:mod:`redundik.resolvers.singularity`): options of
    #: the built-in resolvers' constructors; ``None`` (no cap, no guard) unless assigned.
    max_joint_speed = LimiterOption()
    singularity = LimiterOption()
    _limiter: SpeedLimiter | None = None

    @property
    def blas_threads(self) -> int | str | None:
        """BLAS threads inside a step: an integer ≥ 1, or ``None`` to leave the process's setting alone. The default
        ``"auto"`` limits BLAS to one thread for robots with nv ≥ :data:`BLAS_LIMIT_NV` = 64 (threaded products on
        small matrices stall on busy cores) unless the user set ``OMP_NUM_THREADS``/``OPENBLAS_NUM_THREADS``/
        ``MKL_NUM_THREADS``. Checked on assignment (``check_blas_threads``), used from the next step."""
        return self._blas_threads

    @blas_threads.setter
    def blas_threads(self, value: int | str | None) -> None:
        self._blas_threads = check_blas_threads(self.name, "blas_threads", value)

    def check(self, robot: RobotModel, stack: TaskStack) -> None:
        """Refuse a stack this resolver cannot handle.

        Raises:
            ResolverError: a subtask kind the resolver does not accept (names it, lists the accepted kinds), or a
                malformed stack.
        """
        if not isinstance(stack, TaskStack):
            raise ResolverError(f"{self.name}: expected a TaskStack, got {type(stack).__name__}")
        stack.check(robot)
        for sub in stack.subtasks:
            if sub.kind not in self.accepts:
                raise ResolverError(
                    f"{self.name}: subtask '{sub.name}' is a {sub.kind} subtask; {self.name} accepts "
                    f"{', '.join(self.accepts) or 'no'} subtasks{self._hint(sub.kind)}"
                )

    def _hint(self, kind: str) -> str:
        return {
            "target": " (use 'feedback', 'wqp' or 'hqp' to drive a potential to a target)",
            "bound": " (use 'wqp' or 'hqp' for bounds and barriers)",
        }.get(kind, "")

    @property
    def command_timeout(self) -> float | None:
        """Stop the robot when no target has been set for this long [s] (:mod:`redundik.resolvers.watchdog`);
        ``None``: no watchdog. Assigning a number makes a :class:`~redundik.resolvers.watchdog.Watchdog` (or sets its
        timeout); ``None`` removes it."""
        return None if self.watchdog is None else self.watchdog.timeout

    @command_timeout.setter
    def command_timeout(self, value: float | None) -> None:
        from redundik.resolvers.watchdog import Watchdog

        if value is None:
            self.watchdog = None
        elif self.watchdog is None:
            self.watchdog = Watchdog(value)
        else:
            self.watchdog.timeout = value

    def reset(self) -> None:
        """Forget any state kept between steps (warm starts, previous q̇, the checked stack, the divergence watch)."""
        if self.watchdog is not None:  # (its last command and q̇ sent: the next step counts as a command)
            self.watchdog.reset()
        self._checked = None
        self._members = None
        self._gains_seen = None
        self._watch = None
        if self._limiter is not None:
            self._limiter.reset()

    @abstractmethod
    def solve(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> StepResult:
        """Resolve the stack at the robot's current state, time t [s], for a step dt [s]."""

    def step(self, robot: RobotModel, stack: TaskStack, q: np.ndarray, t: float, dt: float) -> StepResult:
        """Validate, update the kinematics at ``q`` and resolve one step; the call to make once per control tick.

        Raises:
            ResolverError: q not finite or of the wrong size, dt not finite and > 0, t not finite, a refused stack,
                a task gain with K·dt > 2, or another thread inside a step of this resolver (one resolver per thread).
        """
        state, token = self.__dict__, object()
        # dict.setdefault is one atomic operation under the GIL: the first caller's token wins; no lock object, so
        # pickling and copying a resolver are unaffected (the entry exists only during a step)
        if state.setdefault("_stepping_token", token) is not token:
            raise ResolverError(
                f"{self.name}: step() called while another thread is inside a step of this resolver; a resolver keeps "
                "buffers between steps and is not thread-safe: use one resolver per thread (copy.deepcopy it)"
            )
        try:
            return self._step_owned(robot, stack, q, t, dt)
        finally:
            del state["_stepping_token"]

    def _step_owned(self, robot: RobotModel, stack: TaskStack, q: np.ndarray, t: float, dt: float) -> StepResult:
        """:meth:`step` once this thread holds the resolver."""
        if (  # the common case checked in a few operations; anything unusual goes through check_inputs
            type(q) is np.ndarray
            and q.dtype is _F64
            and type(robot) is RobotModel
            and q.shape == (robot._nq,)
            and type(dt) is float
            and type(t) is float
            and 0.0 < dt < math.inf
            and math.isfinite(t)
            and _squares_below(q, _MAX_Q2)  # every entry finite and ‖q‖ < MAX_Q (NaN, inf, huge: the full check)
        ):
            robot._update_checked(q)
        else:
            q = self.check_inputs(robot, q, t, dt)
            t, dt = float(t), float(dt)
            robot.update(q)
        members = self._members
        if not (  # the membership seen at the last check, compared by identity (the lists hold the members alive)
            members is not None
            and members[0] is stack
            and members[1] is robot
            and stack.tasks == members[2]
            and stack.subtasks == members[3]
            and members[4] == Edits.layout  # (a member's priority or name changed: laid out again)
        ):
            self._check_membership(robot, stack)
        tasks, targets = self._gain_members
        limit = STABLE_GAIN_DT / dt
        if self._gains_seen != (Edits.count, limit):  # the tasks' gains (or dt) changed since they were checked
            for member in tasks:
                if member.gain > limit:
                    check_gains(stack, dt, self.name)  # raises with the offending member named
            self._gains_seen = (Edits.count, limit) if self._plain_gains else None
        for sub in targets:
            if sub.rate > limit:
                check_gains(stack, dt, self.name)
        self._stepping = stack  # the stack whose membership was just checked (``stack_key``)
        try:
            if self._blas_threads == "auto" and (robot._nv < BLAS_LIMIT_NV or _USER_CHOSE_THREADS):
                res = self.solve(robot, stack, t, dt)
            else:
                res = self._solve_blas_limited(robot, stack, t, dt)
        except NonFiniteRows as exc:  # a bound subtask's rows are NaN this step: stop, and say which
            res = self.stopped(robot, stack, t, dt, str(exc))
        finally:
            self._stepping = None
        d, d_self = res.__dict__, self.__dict__
        info = d["_info"] if "_info" in d else d.get("info")
        if info is not None:  # which path wrote the rows (issue 31): one entry, not a diagnostic to compute
            compiled = d.get("_compiled")
            if compiled is True:
                dict.__setitem__(info, "path", COMPILED)
                dict.__setitem__(info, "interpreted", ())
            elif compiled and compiled is d_self.get("_mixed_seen"):  # the same mixed plan as the last step's
                dict.__setitem__(info, "path", MIXED)
                dict.__setitem__(info, "interpreted", compiled)
            else:
                self._record_path(info, compiled, robot, stack)
        dog = self.watchdog
        if dog is not None:  # the command watchdog (redundik.resolvers.watchdog): stale targets → a stop within limits
            dog.apply(self, robot, stack, t, dt, res)
        watch = self._watch
        if watch is None:
            watch = self._watch = DivergenceWatch()
        norm = d.get("_dq_norm")  # ‖q̇‖ of a fused step's compiled call (the watchdog drops it when it replaces q̇)
        if norm is None:
            dq = res.dq
            norm = math.sqrt(dq.dot(dq))
        speed = self._limiter  # the joint-speed cap and the singularity guard (issue 33; resolvers/singularity.py)
        if speed is not None:
            over = d.get("_cap_ratio", -1.0)  # max_i |q̇_i| / c_i, when the compiled call tested the cap
            if over > 1.0 or (over < 0.0 and speed.binds(res.dq, norm)):
                res, norm = speed.apply(self, robot, stack, res, dt, norm)
            speed.seen = d_self.get("_dq_prev")  # (a QP resolver's rate window of the next step)
        factor = watch.update(norm, res.task_error)
        if factor is not None:
            watch.flag(self.name, norm, factor, res.info)
        return res

    def stopped(self, robot: RobotModel, stack: TaskStack, t: float, dt: float, why: str) -> StepResult:
        """The result of a step that cannot be solved as asked (``why``) and stops: q̇ = 0 (a QP resolver clips it
        to its limits), the terms evaluated at t, the ``fallback`` saying why."""
        dq = np.zeros(robot.nv)
        return StepResult(dq=dq, terms=stack.evaluate(robot, t), fallback=f"{why}: q̇ = 0 this step")

    def _check_membership(self, robot: RobotModel, stack: TaskStack) -> None:
        """The stack's membership changed since the last step (or the robot did): check it when its signature is
        new, note its gain-carrying members, and remember it (the fast test of :meth:`step`)."""
        members = self._members
        if members is not None and members[1] is not robot:  # another robot: nothing kept of the last one's
            self.reset()  # (its previous q̇ for a rate window, warm starts, plans sized for it)
        try:
            sig = (id(robot), *stack.signature())
        except AttributeError:  # not a TaskStack (a list of tasks, one task, None): say so, not AttributeError
            raise ResolverError(
                f"{self.name}: stack must be a TaskStack (tasks, subtasks), got {type(stack).__name__}"
            ) from None
        if sig != self._checked:
            self.check(robot, stack)
            self._checked = sig
            self._gain_members = (tuple(stack.tasks), tuple(stack.target_subtasks))
            # gains set through Task's validated property move Edits; a task with its own ``gain`` is read each step
            self._plain_gains = all(m.gain_tracked for m in stack.tasks)
            self._gains_seen = None
        self._members = (stack, robot, list(stack.tasks), list(stack.subtasks), Edits.layout)

    def _solve_blas_limited(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> StepResult:
        """:meth:`solve` with BLAS limited to :attr:`blas_threads` threads (``"auto"``: one, on a large robot)."""
        threads = self._blas_threads
        if threads is None:
            return self.solve(robot, stack, t, dt)
        limiter = _blas_limiter()
        changed = limiter.set(1 if threads == "auto" else int(threads))
        try:
            return self.solve(robot, stack, t, dt)
        finally:
            limiter.restore(changed)

    def _record_path(
        self, info: dict[str, object], compiled: tuple[str, ...] | None, robot: RobotModel, stack: TaskStack
    ) -> None:
        """``info["path"]`` and ``info["interpreted"]`` of a step that was not wholly compiled: ``compiled`` names
        the members a mixed plan wrote from Python (a one-time warning names them), or is empty (interpreted)."""
        if compiled:
            dict.__setitem__(info, "path", MIXED)
            dict.__setitem__(info, "interpreted", compiled)
            self.__dict__["_mixed_seen"] = compiled  # (the next step of the same plan skips this function)
            if (self.name, compiled) not in _WARNED_MIXED:
                _WARNED_MIXED.add((self.name, compiled))
                _LOG.warning(
                    "%s: the stack runs mixed: %s %s no compiled form; %s rows are written from Python (%s evaluate, "
                    "or a bound's rows) before the compiled solve (result.info['path'] == 'mixed')",
                    self.name,
                    ", ".join(compiled),
                    "has" if len(compiled) == 1 else "have",
                    "its" if len(compiled) == 1 else "their",
                    "its" if len(compiled) == 1 else "their",
                )
        else:
            dict.__setitem__(info, "path", INTERPRETED)
            dict.__setitem__(info, "interpreted", self._interpreted_members(robot, stack))

    def compiled_off(self) -> str | None:
        """Why this resolver's options keep every step off its compiled step (a one-time warning says it), or
        ``None``: the reasons are then the members' (their compiled forms)."""
        return None

    def _interpreted_members(self, robot: RobotModel, stack: TaskStack) -> tuple[str, ...]:
        """The names of the stack's members whose rows only their Python ``evaluate`` gives (no frame or joint form;
        a subtask without a linear gradient), worked out once per checked membership; a one-time ``logging``
        warning names them when this resolver could have taken the compiled step. Every member when the resolver
        has no compiled step (``feedback``) or it is switched off (``fuse = False``)."""
        cached = self.__dict__.get("_interpreted_cache")
        off = self.compiled_off()
        if cached is not None and cached[0] is self._checked and cached[1] is stack and cached[3] == off:
            return cached[2]
        compiled_capable = bool(getattr(self, "fuse", False)) and off is None
        names: list[str] = []
        for task in stack.tasks:
            if not compiled_capable or (
                task.frame_form(robot) is None and task.joint_form(robot) is None and task.compiled_rows(robot) is None
            ):
                names.append(task.name)
        for sub in stack.subtasks:
            potential = getattr(sub, "potential", None)
            rows_compiled = getattr(sub, "rows_compiled", None)  # (a bound subtask: its rows' compiled form)
            if (
                not compiled_capable
                or (rows_compiled is not None and not rows_compiled(robot))  # (a bound subtask: its rows decide)
                or (rows_compiled is None and potential is None)
                or (
                    rows_compiled is None
                    and potential is not None
                    and potential.linear_gradient(robot) is None
                    and compiled_writer(potential, robot) is None
                )
            ):
                names.append(str(getattr(sub, "name", type(sub).__name__)))
        self.__dict__["_interpreted_cache"] = (self._checked, stack, tuple(names), off)
        if off is not None and (self.name, (off,)) not in _WARNED_INTERPRETED:
            _WARNED_INTERPRETED.add((self.name, (off,)))
            _LOG.warning(
                "%s: every step runs interpreted (each member's Python evaluate, then the solve): %s", self.name, off
            )
        if compiled_capable and names:
            key = (self.name, tuple(names))
            if key not in _WARNED_INTERPRETED:
                _WARNED_INTERPRETED.add(key)
                _LOG.warning(
                    "%s: the stack runs interpreted (each member's Python evaluate, then the solve): %s %s no "
                    "compiled form; result.info['path'] says which path each step took",
                    self.name,
                    ", ".join(names),
                    "has" if len(names) == 1 else "have",
                )
        return tuple(names)

    def stack_key(self, stack: TaskStack) -> tuple[int, ...]:
        """The membership key of ``stack`` (its :meth:`TaskStack.signature`), for caches of what depends on it.

        Inside :meth:`step` the key checked at the start of the step is returned without recomputing it.
        """
        if stack is self._stepping and self._checked is not None:
            return self._checked
        return (-1, *stack.signature())

    def check_inputs(self, robot: RobotModel, q: np.ndarray, t: float, dt: float) -> np.ndarray:
        """Validated q (as a float array) after checking t and dt; raises :class:`ResolverError` otherwise."""
        if not isinstance(robot, RobotModel):
            raise ResolverError(f"{self.name}: robot must be a RobotModel, got {type(robot).__name__}")
        try:
            raw = np.asarray(q)
            if raw.dtype.kind not in "fiuO":  # bool, complex, strings: not joint values (no silent cast)
                raise TypeError(f"got dtype {raw.dtype}")
            if raw.ndim > 1 and max(raw.shape) != raw.size:  # (nq,), (1, nq) or (nq, 1); never a (2, 3) for nq = 6
                raise ValueError(f"got shape {raw.shape}")
            arr = np.asarray(raw, dtype=float).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise ResolverError(f"{self.name}: q must be an array of {robot.nq} real numbers: {exc}") from None
        if arr.shape[0] != robot.nq:
            raise ResolverError(f"{self.name}: q has {arr.shape[0]} entries, the robot has nq = {robot.nq}")
        if not np.isfinite(arr).all():
            idx = np.flatnonzero(~np.isfinite(arr)).tolist()
            raise ResolverError(f"{self.name}: q contains NaN or infinite values at indices {idx[:8]}")
        if arr.size and float(np.max(np.abs(arr))) > MAX_Q:
            k = int(np.argmax(np.abs(arr)))
            raise ResolverError(
                f"{self.name}: q[{k}] = {arr[k]:g} is beyond ±{MAX_Q:g} [rad or length unit]: not a configuration "
                "(a diverged loop, or a unit mistake?)"
            )
        for key, val in (("dt", dt), ("t", t)):
            if isinstance(val, bool) or not isinstance(val, (int, float, np.integer, np.floating)):
                raise ResolverError(f"{self.name}: {key} must be a number [s], got {type(val).__name__}")
            try:
                finite = math.isfinite(float(val))
            except OverflowError:  # an int beyond the float range (10**400)
                finite = False
            if not finite:
                raise ResolverError(f"{self.name}: {key} must be finite [s] (within the float range), got {val!r:.60}")
        if not dt > 0:
            raise ResolverError(f"{self.name}: dt must be > 0 [s], got {dt}")
        return arr

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


#: Most BLAS threads :attr:`Resolver.blas_threads` accepts (the libraries take a C int).
MAX_BLAS_THREADS = 2**31 - 1


def check_blas_threads(who: str, key: str, value: object) -> int | str | None:
    """``None``, ``"auto"`` or an integer 1 ≤ n ≤ :data:`MAX_BLAS_THREADS`: :attr:`Resolver.blas_threads`'s check,
    with the signature of a :class:`~redundik.resolvers.settings.Setting` check (resolver name, option name, value).

    Raises:
        ResolverError: anything else (a bool, a float such as 2.5 or NaN, 0, a negative number, another string).
    """
    if value is None or (isinstance(value, str) and value == "auto"):
        return "auto" if value is not None else None
    if (
        isinstance(value, (int, np.integer))
        and not isinstance(value, (bool, np.bool_))
        and 1 <= value <= MAX_BLAS_THREADS
    ):
        return int(value)
    raise ResolverError(
        f"{who}: {key} must be None (leave BLAS alone), 'auto' or an integer number of threads ≥ 1, got "
        f"{type(value).__name__} {value!r:.60}"
    )


def check_gains(stack: TaskStack, dt: float, who: str) -> None:
    """Refuse a task or target-subtask gain K with K·dt > 2 (the first-order loop would diverge).

    Raises:
        ResolverError: names the task, its gain, dt and the stable range.
    """
    limit = STABLE_GAIN_DT / dt
    for task in stack.tasks:
        if task.gain > limit:
            raise ResolverError(
                f"{who}: task '{task.name}' has gain {task.gain:g} /s with dt = {dt:g} s: K·dt = {task.gain * dt:g} "
                f"> 2 makes the first-order loop diverge; use a gain < {limit:g} /s "
                f"(≤ {1 / dt:g} closes the error in one step)"
            )
    for sub in stack.target_subtasks:
        if sub.rate > limit:
            raise ResolverError(
                f"{who}: subtask '{sub.name}' has rate {sub.rate:g} /s with dt = {dt:g} s: K·dt > 2 diverges; "
                f"use a rate < {limit:g} /s"
            )

"""What ``wqp`` and ``hqp`` share: limits, the backend, and one solve skeleton — build → solve → fallback →
diagnostics — with a typed diagnostics record (:class:`QPDiagnostics`) that the run's CSV reads through
``StepResult.info``.

Safety rows (the rows of a bound subtask whose barrier is ``critical``: collision distances) are guarded last: a
q̇ that violates one by more than 1e-6 — a closed-form fallback, an early-stopped backend, a contradicted ``hqp``
level — is scaled down until it keeps them all (``keep_safe``; q̇ = 0 always does while the pairs are apart),
and the step's fallback note says so."""

from __future__ import annotations

import math
import time
from abc import abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from redundik.errors import ResolverError, SolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import LazyStepResult, Resolver, StepResult, nonfinite_sources
from redundik.resolvers.linalg import K, pseudo_inverse_unchecked
from redundik.resolvers.pinv import check_damping_options, main_system
from redundik.resolvers.qp.backends import CHECKED_ANSWERS, DEFAULT_BACKEND, Backend, finite, make_backend
from redundik.resolvers.qp.limits import JointLimits, LimitBox
from redundik.resolvers.qp.problem import QPProblem, QPSolution
from redundik.resolvers.settings import Setting, nonnegative
from redundik.tasks.base import TaskTerm
from redundik.tasks.stack import StackLayout, TaskStack

LimitsOption = JointLimits | Mapping[str, object] | bool | None
LevelsOption = Mapping[str, int] | Sequence[Sequence[str]] | None


def make_limits(limits: LimitsOption) -> JointLimits:
    """``JointLimits`` from an instance, a dict of its keyword arguments, ``None``/``True`` (model defaults) or
    ``False`` (no limits).

    Raises:
        ResolverError: unknown keys (lists the valid ones) or bad values.
    """
    if isinstance(limits, JointLimits):
        return limits
    if limits is None or limits is True:
        return JointLimits()
    if limits is False:
        return JointLimits(position=False, velocity=False)
    if isinstance(limits, Mapping):
        valid = ["position", "velocity", "lower", "upper", "velocity_limits", "acceleration", "position_gain", "jerk"]
        bad = [k for k in limits if k not in valid]
        if bad:
            raise ResolverError(f"limits: unknown option(s) {bad}; valid: {valid}")
        return JointLimits(**limits)  # type: ignore[arg-type]
    raise ResolverError(f"limits: expected a mapping, true/false or JointLimits, got {limits!r}")


def _is_name(name: object) -> bool:
    """A task or subtask name of a level override: a non-empty string, or an integer (YAML reads ``3:`` as one)."""
    if isinstance(name, str):
        return bool(name.strip())
    return isinstance(name, (int, np.integer)) and not isinstance(name, bool)


def make_levels(levels: LevelsOption) -> dict[str, int]:
    """Level overrides by name, from a mapping ``{name: level}`` or a list of levels ``[[names of level 0], ...]``.

    Raises:
        ResolverError: a negative or non-integer level, a name given twice, a name that is not a non-empty string,
            or levels given as anything else (a string: its characters are not names).
    """
    if levels is None:
        return {}
    out: dict[str, int] = {}
    if isinstance(levels, Mapping):
        for name, lv in levels.items():
            if not _is_name(name):
                raise ResolverError(f"levels: {name!r:.80} is not a task or subtask name")
            if isinstance(lv, bool) or not isinstance(lv, (int, np.integer)) or lv < 0:
                raise ResolverError(f"levels: '{name}' must be an integer level ≥ 0, got {lv!r}")
            out[str(name)] = int(lv)
        return out
    if isinstance(levels, (str, bytes)) or not isinstance(levels, (list, tuple)):  # (a string: one name per char)
        raise ResolverError(
            "levels: expected a mapping {name: level} or a list of levels, each a name or a list of names, got "
            f"{levels!r:.80}"
        )
    for k, names in enumerate(levels):
        if _is_name(names):
            names = [names]
        if not isinstance(names, (list, tuple)):
            raise ResolverError(f"levels: level {k} must be a name or a list of names, got {names!r:.80}")
        for name in names:
            if not _is_name(name):
                raise ResolverError(f"levels: level {k} has {name!r:.80}, expected a task or subtask name")
            name = str(name)
            if name in out:
                raise ResolverError(f"levels: '{name}' appears in level {out[name]} and level {k}")
            out[str(name)] = k
    return out


@dataclass
class QPDiagnostics:
    """What a QP step reports (typed; :meth:`as_info` gives the ``StepResult.info`` dict the CSV reads).

    Attributes:
        backend: Backend that produced q̇ (``"closed-form"`` when no QP was needed, ``"fallback"``).
        qp: Number of QPs solved this step.
        iterations: Backend iterations summed over them.
        sigma_min: Smallest nonzero singular value of the top level's (main-task) Jacobian.
        level_sigma_min: Per level, σ_min of its projected Jacobian (hqp).
        level_residuals: Per level, its residual at the returned q̇
            (:meth:`~redundik.resolvers.qp.terms.Level.residual`).
        damped_levels: Levels whose solve damped a direction.
        rank_loss_levels: Levels whose projected Jacobian lost rank while their own did not (algorithmic
            singularity).
        contradicted: Per level, how far its bound rows are violated at the returned q̇ (> tolerance only).
        active_limits: Joint-limit bounds q̇ sits on.
        bound_violation: Largest bound-subtask violation (wqp), or ``None`` without bound subtasks.
        regularization_retry: 1 when a level QP was retried with a stronger regulariser.
        relaxed: The members this step relaxed as documented (an ``hqp`` level's bound rows contradicted by the
            levels above and the limits, the bound subtasks ``wqp`` dropped from an infeasible QP), by name:
            ``StepResult.relaxed``.
        retries: Per QP that a backend failed on and a documented retry then solved (the backend's own retry,
            ``QPSolution.retried``, or ``hqp``'s stronger regulariser), (its label, what failed): each is counted
            in ``StepResult.relaxed`` as ``"<label> (backend retried)"`` and told in ``info["retries"]``. A
            failure no retry rescued is a fallback.
    """

    backend: str = "closed-form"
    qp: int = 0
    iterations: int = 0
    sigma_min: float = math.inf
    level_sigma_min: dict[int, float] = field(default_factory=dict)
    level_residuals: dict[int, float] = field(default_factory=dict)
    damped_levels: list[int] = field(default_factory=list)
    rank_loss_levels: list[int] = field(default_factory=list)
    contradicted: dict[int, float] = field(default_factory=dict)
    active_limits: list[str] = field(default_factory=list)
    bound_violation: float | None = None
    regularization_retry: int = 0
    relaxed: list[str] = field(default_factory=list)
    retries: list[tuple[str, str]] = field(default_factory=list)

    def as_info(self) -> dict[str, object]:
        """The flat dict of ``StepResult.info`` (numbers are logged per step)."""
        info: dict[str, object] = {
            "backend": self.backend,
            "qp": self.qp,
            "iterations": self.iterations,
            "sigma_min": self.sigma_min,
            "rank_loss": len(self.rank_loss_levels),
            "rank_loss_levels": list(self.rank_loss_levels),
            "active_limits": list(self.active_limits),
            "n_active": len(self.active_limits),
        }
        for k, v in self.level_residuals.items():
            info[f"residual_L{k}"] = v
        for k, v in self.level_sigma_min.items():
            info[f"sigma_min_L{k}"] = v
        if self.damped_levels:
            info["damped_levels"] = list(self.damped_levels)
        if self.bound_violation is not None:
            info["bound_violation"] = self.bound_violation
        if self.regularization_retry:
            info["regularization_retry"] = self.regularization_retry
        if self.contradicted:
            info["contradicted_levels"] = dict(self.contradicted)
        return info


#: How far a q̇ may break a safety row before :func:`keep_safe` scales it [row units: m/s for the dampers].
SAFETY_TOLERANCE = 1e-6


def keep_safe(dq: np.ndarray, C: np.ndarray, d: np.ndarray, tol: float = SAFETY_TOLERANCE) -> tuple[np.ndarray, float]:
    """(α q̇, α): the largest α ∈ [0, 1] with C (α q̇) ≤ d + tol, when ``dq`` violates a row by more than ``tol``.

    The last guard of the safety rows (collision dampers, d = γh ≥ 0 [m/s] while the pair is apart): whatever
    produced q̇ (the closed-form fallback, a backend stopped early), α q̇ keeps every row, since q̇ = 0 does. ``tol``
    [row units; m/s for the dampers, i.e. 1e-8 m over a 10 ms step] leaves a backend's own tolerance alone. A row
    with d < 0 (a moving obstacle already closer than d_s) gives α ≈ 0, the best a scaling can do.
    """
    if not C.shape[0]:
        return dq, 1.0
    v = C @ dq
    over = v > d + tol
    if not over.any():
        return dq, 1.0
    alpha = float(np.clip(np.min((np.maximum(d[over], 0.0) + tol) / v[over]), 0.0, 1.0))
    return alpha * dq, alpha


def with_relaxed(res: StepResult, relaxed: tuple[str, ...]) -> StepResult:
    """``res`` with :attr:`StepResult.relaxed` set to ``relaxed`` (left at its default ``()`` when empty)."""
    if relaxed:
        res.__dict__["relaxed"] = relaxed
    return res


class QPResolverBase(Resolver):
    """Shared machinery of the QP resolvers (not registered itself): the template :meth:`solve`.

    Subclasses implement :meth:`build` (the problem, without solving it — for inspection and tests) and
    :meth:`_resolve` (q̇ from a built problem, or :class:`SolverError`).

    Args:
        backend: QP backend name (see :func:`~redundik.resolvers.qp.backends.make_backend`) or instance.
        limits: Joint limits (see :func:`make_limits`).
        levels: Level overrides by task / subtask name, or a list of levels of names.
        epsilon: Singular value under which the closed forms are damped (as :mod:`redundik.resolvers.linalg`).
        max_damping: λ_max of that damping rule.
    """

    accepts: ClassVar[tuple[str, ...]] = ("gradient", "target", "bound")
    epsilon = Setting(nonnegative, resets=("_plan",))
    max_damping = Setting(nonnegative, resets=("_plan",))
    #: The QP backend: a name or a ``Backend`` (:func:`~redundik.resolvers.qp.backends.make_backend`).
    backend = Setting(lambda who, key, val: make_backend(val), resets=("_plan",))  # type: ignore[arg-type]
    #: The joint limits: as the constructor's ``limits`` (:func:`make_limits`); the next step checks the stack again,
    #: which binds them to the robot.
    limits = Setting(
        lambda who, key, val: make_limits(val),  # type: ignore[arg-type]
        resets=("_plan", "_checked", "_members"),
    )
    #: Level overrides: as the constructor's ``levels`` (:func:`make_levels`); the next step checks their names
    #: against the stack and lays it out again.
    levels = Setting(
        lambda who, key, val: make_levels(val),  # type: ignore[arg-type]
        resets=("_layout", "_plan", "_checked", "_members"),
    )

    def __init__(
        self,
        backend: str | Backend = DEFAULT_BACKEND,
        limits: LimitsOption = None,
        levels: LevelsOption = None,
        epsilon: float = 1e-2,
        max_damping: float = 5e-2,
    ) -> None:
        self.epsilon, self.max_damping = check_damping_options(self.name, epsilon, max_damping)
        self.backend = make_backend(backend)
        self.limits = make_limits(limits)
        self.levels = make_levels(levels)
        self._dq_prev: np.ndarray | None = None
        #: (q̇ kept by the last template step, the q̇ kept before it): the jerk limit's second q̇ (see ``_box``).
        self._dq_hist: tuple[np.ndarray | None, np.ndarray | None] = (None, None)
        self._layout: tuple[tuple[int, ...], StackLayout] | None = None

    def compiled_off(self) -> str | None:
        """A jerk limit (its box needs the last two q̇) or ``scaling="direction"`` keeps the steps interpreted."""
        if self.limits.has_jerk:
            return "a jerk limit (the limit box reads the last two q̇) has no compiled step"
        scaling = getattr(self, "scaling", "off")  # (wqp and hqp have it)
        if scaling != "off":
            return f"scaling={scaling!r} has no compiled step"
        return None

    def check(self, robot: RobotModel, stack: TaskStack) -> None:
        super().check(robot, stack)
        self.limits.bind(robot)
        stack.layout(self.levels)  # unknown level names are refused here, with the valid ones listed

    def reset(self) -> None:
        super().reset()
        self._dq_prev = None
        self._dq_hist = (None, None)
        self._layout = None
        self.backend.reset()

    def layout(self, stack: TaskStack) -> StackLayout:
        """The stack's levels with this resolver's overrides (cached while the stack's membership is unchanged)."""
        sig = self.stack_key(stack)
        cached = self._layout
        if cached is None or (cached[0] is not sig and cached[0] != sig):
            self._layout = cached = (sig, stack.layout(self.levels))
        return cached[1]

    @abstractmethod
    def build(
        self, robot: RobotModel, stack: TaskStack, t: float, dt: float, terms: list[TaskTerm] | None = None
    ) -> Any:
        """Evaluate the stack and build the problem (without solving it)."""

    @abstractmethod
    def _resolve(self, built: Any, diag: QPDiagnostics) -> tuple[np.ndarray, str | None]:
        """(q̇ before clipping, a fallback note or ``None``); raises :class:`SolverError` when nothing is usable."""

    @abstractmethod
    def _diagnose(self, built: Any, dq: np.ndarray, diag: QPDiagnostics) -> None:
        """Fill the per-level residuals at the returned q̇."""

    def solve(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> StepResult:
        t0 = time.perf_counter()
        terms = stack.evaluate(robot, t)
        built = self.build(robot, stack, t, dt, terms)
        return self._finish(robot, stack, terms, built, t0, time.perf_counter())

    def _finish(
        self, robot: RobotModel, stack: TaskStack, terms: list[TaskTerm], built: Any, t0: float, t1: float
    ) -> StepResult:
        """Solve a built step, fall back if needed, clip to the limits, guard the safety rows, and report (the
        template's second half; ``t0``/``t1`` [s]: when the step started and its build ended)."""
        dq, diagnostics, fallback, relaxed, info, t2 = self._settle(robot, stack, lambda: terms, built)
        res = LazyStepResult.make(dq, terms, fallback, info, t1 - t0, t2 - t1, self.layout(stack).main, diagnostics)
        if built.box.relaxed:  # the limits' documented relaxations (jerk, then acceleration)
            relaxed = (*relaxed, *built.box.relaxed)
        return with_relaxed(res, relaxed)

    def _settle(
        self, robot: RobotModel, stack: TaskStack, terms_of: Callable[[], list[TaskTerm]], built: Any
    ) -> tuple[
        np.ndarray,
        Callable[[], tuple[float, bool, dict[str, object]]],
        str | None,
        tuple[str, ...],
        dict[str, object],
        float,
    ]:
        """:meth:`_finish` but its result: (q̇, the diagnostics to compute on first read, the fallback note, the
        members relaxed as documented, the info, when it ended [s]). ``terms_of`` gives the step's terms; only a
        fallback asks for them.

        The fallback note says what is not what the stack asked beyond its documented relaxations — a backend
        failure no retry rescued (the closed form, an ``hqp`` level skipped), a non-finite q̇, a q̇ scaled to keep
        the safety rows; the relaxations (:attr:`QPDiagnostics.relaxed`, and the QPs a documented retry solved,
        :attr:`QPDiagnostics.retries`) are the step's ``relaxed``, not an alarm."""
        box: LimitBox = built.box
        diag = QPDiagnostics()
        try:
            x, fallback = self._resolve(built, diag)
        except SolverError as exc:
            terms = terms_of()
            x = self._closed_form(robot, stack, terms)
            fallback = f"{self.name} failed, damped closed form clipped to the limits: {exc}"
            bad = nonfinite_sources(terms, robot, stack)  # (a rare path: a QP posed on NaN rows says where from)
            if bad:
                fallback += f" (non-finite values from {', '.join(bad)})"
            diag.backend = "fallback"
        if not finite(x):  # (one dot product when all is well)
            bad = nonfinite_sources(terms_of(), robot, stack)
            fallback = f"non-finite q̇ (from {', '.join(bad) or 'the solver'}): q̇ = 0 clipped to the limits"
            x = np.zeros(robot.nv)
            diag.backend = "fallback"
        out = np.empty((2, x.shape[0]))
        K.clip_twice(x, box.lb, box.ub, out)  # the limits hold whatever happened (solver tolerance, fallback)
        dq, dq_kept = out[0], out[1]  # q̇ returned, and the copy kept (warm start, rate window): one call
        safe = self._safety_rows(built, stack)
        if safe is not None:
            dq, alpha = keep_safe(dq, *safe)
            if alpha < 1.0:  # (else dq is the clipped q̇ still)
                note = f"q̇ scaled by {alpha:.3g} to keep the safety rows (collision distances)"
                fallback = note if fallback is None else f"{fallback}; {note}"
                dq = box.clip(dq)
                dq_kept = dq.copy()
        before = self._dq_prev
        self._dq_hist = (dq_kept, np.zeros_like(dq_kept) if before is None else before)  # None: at rest before
        self._dq_prev = dq_kept
        t2 = time.perf_counter()

        def diagnostics() -> tuple[float, bool, dict[str, object]]:  # on first read of the result's diagnostics
            diag.active_limits = box.active(dq_kept, self.limits.joint_names)
            self._diagnose(built, dq_kept, diag)
            return diag.sigma_min, bool(diag.damped_levels), diag.as_info()

        info: dict[str, object] = {"backend": diag.backend, "qp": diag.qp, "iterations": diag.iterations}
        relaxed: tuple[str, ...] = ()
        if diag.retries:  # counted in relaxed, told here (eager: a logger reads it without the diagnostics)
            info["retries"] = [f"{label}: {why}" for label, why in diag.retries]
            relaxed = tuple(f"{label} (backend retried)" for label, _ in diag.retries)
        if diag.relaxed or relaxed:
            relaxed = tuple(dict.fromkeys([*diag.relaxed, *relaxed]))  # (in order, each name once)
        return dq, diagnostics, fallback, relaxed, info, t2

    def _safety_rows(self, built: Any, stack: TaskStack) -> tuple[np.ndarray, np.ndarray] | None:
        """The built step's safety rows (C, d) of C q̇ ≤ d (:attr:`BoundSubtask.critical`), or ``None`` without any."""
        return None

    def _solve_qp(
        self, problem: QPProblem, warm: np.ndarray | None = None, diag: QPDiagnostics | None = None
    ) -> QPSolution:
        """The backend's answer; anything it raises (also a user backend's own exception) becomes SolverError, and
        an answer that is not a finite x of size n does too (tested here unless the backend is one of
        :data:`~redundik.resolvers.qp.backends.CHECKED_ANSWERS`, which test it themselves). With ``diag``, a
        backend's own retry (``QPSolution.retried``) is noted in :attr:`QPDiagnostics.retries`."""
        try:
            sol = self.backend.solve(problem, warm)
        except SolverError:
            raise
        except Exception as exc:  # a failed QP must never crash a control loop
            raise SolverError(
                f"{self.backend.name} raised {type(exc).__name__} on {problem.label}: {exc}", problem
            ) from exc
        if diag is not None:
            retried = getattr(sol, "retried", None)
            if retried:
                diag.retries.append((problem.label, str(retried)))
        try:
            x = sol.x
            if type(sol) is QPSolution and type(self.backend) in CHECKED_ANSWERS:
                return sol  # (that backend checked x itself: finite, float, of shape (n,))
            if type(x) is not np.ndarray or x.dtype != np.float64:  # (a built-in backend's x already is one)
                x = np.asarray(x, dtype=float)
            ok = x.shape == (problem.q.shape[0],) and finite(x)
        except (TypeError, ValueError, AttributeError):  # not a solution record, or not an array of numbers
            ok = False
        if not ok:
            raise SolverError(
                f"{self.backend.name}: no finite solution of size {problem.n} for {problem.label}", problem
            )
        if x is not sol.x:
            sol.x = x
        return sol

    def stopped(self, robot: RobotModel, stack: TaskStack, t: float, dt: float, why: str) -> StepResult:
        """:meth:`Resolver.stopped` with q̇ = 0 clipped to the step's limits (a joint outside its limits is brought
        back), kept as the last q̇ for the next step's rate window."""
        res = super().stopped(robot, stack, t, dt, why)
        res.fallback = f"{why}: q̇ = 0 clipped to the limits"
        box = self._box(robot, dt)
        out = np.empty((2, robot.nv))
        K.clip_twice(res.dq, box.lb, box.ub, out)
        res.dq = out[0]
        before = self._dq_prev
        self._dq_hist = (out[1], np.zeros_like(out[1]) if before is None else before)
        self._dq_prev = out[1]
        return res

    def _box(self, robot: RobotModel, dt: float) -> LimitBox:
        """The step's box; with a jerk limit also the q̇ before the last one (``None`` when the last q̇ came from a
        path that keeps no history: ``JointLimits.box`` then takes the last acceleration as zero)."""
        if not self.limits.has_jerk:
            return self.limits.box(robot, robot.q, dt, self._dq_prev)
        last, before = self._dq_hist
        return self.limits.box(robot, robot.q, dt, self._dq_prev, before if last is self._dq_prev else None)

    def _closed_form(self, robot: RobotModel, stack: TaskStack, terms: list[TaskTerm]) -> np.ndarray:
        """The damped closed form J⁺V + (I − J⁺J)z on the main tasks and the null-space objective (the fallback)."""
        J, V, z = main_system(robot, stack, terms, self.layout(stack))
        pi = pseudo_inverse_unchecked(J, self.epsilon, max(self.max_damping, 1e-3))
        out = pi.solve(V)
        if z is not None:
            out = out + pi.null_project(z)
        return out

    def __repr__(self) -> str:
        return f"{type(self).__name__}(backend={self.backend.name!r}, limits={self.limits!r})"

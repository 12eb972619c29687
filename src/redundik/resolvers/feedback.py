"""The chapter's nonlinear state-feedback law for the subtask gains (section 5.2, after eq. 5.15).

With N = (η_1 … η_r) of the target subtasks and y = (p_1 … p_r)ᵀ, eq. (5.15) gives, for
q̇ = J⁺V + P(N k + z) (P = I − J⁺J, z the stack's null-space objective: gradient subtasks and posture),

    ẏ = NᵀJ⁺V + D k + NᵀP z,   D = Nᵀ P N.

Asking ẏ = ẏ_d + K(y_d − y) yields the chapter's law, extended by the z term:

    k = D⁻¹[ẏ_d + K(y_d − y) − NᵀJ⁺V − NᵀP z],

so each p_i converges to p_i^d exponentially at rate K_i (exactly in continuous time, to O(dt) with Euler steps)
and, with no target subtasks, the law is exactly ``pinv``. D is r×r and can be non-singular only if
r ≤ dim N(J) = n − rank(J). D is inverted by the shared damped-SVD kernel with scale-free thresholds
(ε_D = d_epsilon·‖N‖_F², truncation of exact zeros): a gradient that vanishes (N = 0 at a potential's own
optimum) gives k = 0, never 0/0.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from redundik._coldstart import HOT, ready
from redundik.errors import ResolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import Resolver, StepResult, nonfinite_sources
from redundik.resolvers.fused import FusedPlan
from redundik.resolvers.fused_result import FusedStepResult
from redundik.resolvers.layouts import (
    CF_ROWS,
    FB_D_DAMPING,
    FB_D_EPSILON,
    FB_D_RANK,
    FB_DAMPING,
    FB_DQ,
    FB_EPSILON,
    FB_J_RANK,
    FB_MAX_DAMPING,
    FB_NULL,
    FB_RANK,
    FB_RCOND,
    FB_REPORT,
    FB_ROWS,
    FB_SETTINGS,
    FB_SIGMA_MIN,
    FRAME_ROWS,
)
from redundik.resolvers.linalg import FK, RCOND, _Kernels, contiguous, gram_sigma_min, pseudo_inverse
from redundik.resolvers.pinv import main_system
from redundik.resolvers.result import info_keys
from redundik.resolvers.settings import Setting, flag, nonnegative
from redundik.resolvers.singularity import SingularityGuard
from redundik.tasks.base import CompiledGradient, TaskTerm
from redundik.tasks.potential_rows import compiled_writer
from redundik.tasks.stack import StackLayout, TaskStack

#: The compiled law (:mod:`redundik.resolvers.feedback_kernels`), loaded on first use.
FBK = _Kernels("feedback_kernels")
_NO_ROWS: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # nv → (N (0, nv), rhs (0,)) of a stack without targets


class FeedbackResolver(Resolver):
    """Nonlinear state-feedback control of the subtask gains k (the chapter's decoupling law).

    Accepts target subtasks (target p_d, rate K, optional ṗ_d) and gradient subtasks (the null-space objective,
    as ``pinv``).

    Args:
        epsilon: Damping threshold of J⁺ (see :mod:`redundik.resolvers.linalg`).
        max_damping: λ_max of J⁺.
        d_epsilon: Relative threshold: a direction of D is damped when its singular value is below
            d_epsilon·‖N‖_F² (scale-free: independent of the potentials' units), with λ_max = the same value.
        max_joint_speed: Cap on every |q̇_i| [rad/s; m/s for a prismatic joint]: ``"auto"`` = the robot's velocity
            limits (10 rad/s where it has none), a number, or ``None`` (no cap); when it acts q̇ is scaled as a whole
            and the step says so (:mod:`redundik.resolvers.singularity`).
        singularity: A :class:`~redundik.resolvers.singularity.SingularityGuard` (or a mapping of its fields,
            ``True`` for its defaults) to decelerate and halt near a singularity of the main tasks; ``None``: none.
    """

    name = "feedback"
    accepts: ClassVar[tuple[str, ...]] = ("gradient", "target")
    #: Take the compiled step when the stack allows it: the main rows and z as ``pinv``'s fused step writes them
    #: (:mod:`redundik.resolvers.fused`), the target subtasks' rows from their potentials' compiled writers (their
    #: ``row`` from Python otherwise: a mixed step), then the law in one compiled call
    #: (:mod:`redundik.resolvers.feedback_kernels`). The per-task path otherwise (the same answer: a switch for
    #: comparisons and tests).
    fuse = Setting(flag)

    epsilon = Setting(nonnegative)
    max_damping = Setting(nonnegative)
    d_epsilon = Setting(nonnegative)

    def __init__(
        self,
        epsilon: float = 1e-2,
        max_damping: float = 5e-2,
        d_epsilon: float = 1e-3,
        max_joint_speed: float | str | None = "auto",
        singularity: SingularityGuard | dict[str, float] | bool | None = None,
    ) -> None:
        self.epsilon, self.max_damping, self.d_epsilon = epsilon, max_damping, d_epsilon  # (validated: Setting)
        self.fuse = True
        self._layout: tuple[tuple[int, ...], StackLayout] | None = None
        self._fused: _FusedFeedback | None = None
        self.max_joint_speed, self.singularity = max_joint_speed, singularity  # (validated on assignment)

    def check(self, robot: RobotModel, stack: TaskStack) -> None:
        super().check(robot, stack)
        r = len(stack.target_subtasks)
        if not r:
            return
        layout = stack.layout()
        J, _, _ = main_system(robot, stack, stack.evaluate(robot, 0.0), layout)
        rank = pseudo_inverse(J, epsilon=0.0).rank
        free = robot.nv - rank
        if r > free:
            raise ResolverError(
                f"feedback: {r} target subtasks but the null space of the {J.shape[0]}×{robot.nv} main-task Jacobian "
                f"(rank {rank}) has dimension {free}; D = Nᵀ(I − J⁺J)N would be singular. Remove {r - free} "
                "target subtask(s) or use 'hqp'"
            )

    def solve(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> StepResult:
        if "feedback" not in HOT:  # (its kernels' twins while they compile in the background: redundik._coldstart)
            ready("feedback")
        t0 = time.perf_counter()
        sig = self.stack_key(stack)
        cached = self._layout
        if cached is None or (cached[0] is not sig and cached[0] != sig):
            self._layout = cached = (sig, stack.layout())
        layout = cached[1]
        if self.fuse and ready("feedback"):
            res = self._fused_solve(robot, stack, layout, t, t0)
            if res is not None:
                return res
        terms = stack.evaluate(robot, t)
        J, V, z = main_system(robot, stack, terms, layout)
        subs = stack.target_subtasks
        n, r = robot.nv, len(subs)
        Nt = np.empty((r, n))
        rhs = np.empty(r)
        for i, s in enumerate(subs):
            eta, v, _ = s.row(robot)  # v = ṗ_d + K (p_d − p)
            Nt[i] = eta
            rhs[i] = v
        t1 = time.perf_counter()
        J = contiguous(J)
        out, gains, report = self._law(J, contiguous(V), z, Nt, rhs, n)
        dq = out[FB_DQ]
        fallback = None
        if not np.isfinite(dq).all():
            bad = nonfinite_sources(terms, robot, stack, z=z, subtask_gradients=Nt.T)
            fallback = f"non-finite q̇ (from {', '.join(bad) or 'the decoupling law'}): q̇ = 0 this step"
            dq = np.zeros(n)
        error = math.sqrt(sum(float(terms[i].error.dot(terms[i].error)) for i in layout.main))
        res = _result(dq, out, gains, report, J, lambda: terms, error, t1 - t0, time.perf_counter() - t1, layout.main)
        res.__dict__["fallback"] = fallback
        return res

    def _law(
        self, J: np.ndarray, V: np.ndarray, z: np.ndarray | None, Nt: np.ndarray, rhs: np.ndarray, n: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``feedback_law`` on these rows: (J⁺V, P(N k + z), q̇) (``FB_ROWS``, n), the gains k and the report."""
        out = np.empty((FB_ROWS, n))
        gains, report = np.empty(rhs.shape[0]), np.empty(FB_REPORT)
        zc = _zeros(n) if z is None else contiguous(z)
        FBK.feedback_law(J, V, zc, z is not None, Nt, rhs, self._settings(), out, gains, report)
        return out, gains, report

    def _settings(self) -> np.ndarray:
        """``feedback_law``'s settings (ε, λ_max, rcond, d_ε) of the current options."""
        key = (self.epsilon, self.max_damping, self.d_epsilon)
        cached = self.__dict__.get("_settings_of")
        if cached is None or cached[0] != key:
            settings = np.empty(FB_SETTINGS)
            settings[FB_EPSILON], settings[FB_MAX_DAMPING], settings[FB_D_EPSILON] = key
            settings[FB_RCOND] = RCOND
            cached = self.__dict__["_settings_of"] = (key, settings)
        return cached[1]

    def reset(self) -> None:
        super().reset()
        self._fused = None

    def _fused_solve(
        self, robot: RobotModel, stack: TaskStack, layout: StackLayout, t: float, t0: float
    ) -> StepResult | None:
        """The compiled step (:attr:`fuse`); ``None`` when this step needs the per-task path (a member without a
        compiled form of its main rows, a rotation error beyond the compiled log3's range, a non-finite q̇ or target
        row to diagnose, a stack that cannot be planned yet)."""
        fused = self._fused
        if fused is None or not fused.current(robot, layout):
            fused = self._fused = _FusedFeedback.build(robot, stack, layout)
        plan = fused.plan
        if plan is None:
            return None
        external: list[TaskTerm | None] | tuple[()] = ()
        if plan.external:  # the members without a compiled form: their evaluate, written into the step's rows
            evaluated = plan.evaluate_external(robot, t, direct=True)
            if evaluated is None:
                return None
            external = evaluated
        n, m, K = robot._nv, plan.m, len(plan.frames)
        work = np.empty(plan.pinv_work)
        a = CF_ROWS * n  # (FK.pinv_work_views' J, (e, v) and the frames' Jacobians, sliced here: cheaper than a call)
        b, c = a + m * n, a + m * n + 2 * m
        Jm, ev, Jf = (
            work[a:b].reshape(m, n),
            work[b:c].reshape(2, m),
            work[c : c + FRAME_ROWS * K * n].reshape(K, FRAME_ROWS, n),
        )
        if external and plan.plain_rows:  # a user's own tasks only: their blocks put straight into work
            plan.put_plain_rows(robot, external, work, (a, 0, b, b + m, -1))
        elif external:
            end = work.shape[0]  # (the Python writers' null-space terms, before z: FK.pinv_null_views)
            plan.write_external(robot, external, Jm, 0, ev, None, work[end - 2 * n : end - n], t)
        q = robot.q
        coef = plan.coefficients((self.epsilon, self.max_damping, RCOND))
        refs = plan.given_references(t) if plan.given else plan.refs
        args = (plan.jw, plan.poses, float(t), refs, q, plan.ints, plan.floats, coef, work)
        status, has_z, err2 = FK.fused_pinv_rows(*args)
        if status < 0.0:
            return None
        Nt, rhs = fused.target_rows(robot)
        if Nt is None:
            return None
        t1 = time.perf_counter()
        out, gains, report = self._law(Jm, ev[1], work[work.shape[0] - n :] if has_z else None, Nt, rhs, n)
        dq = out[FB_DQ]
        dq2 = dq.dot(dq)
        if not math.isfinite(dq2):  # a non-finite (or overflowing) q̇: the per-task path diagnoses it
            return None
        make_terms = functools.partial(plan.terms, Jf, ev, q, robot, external)  # (built when first read)
        res = _result(dq, out, gains, report, Jm, make_terms, math.sqrt(err2), t1 - t0, time.perf_counter() - t1,
                      layout.main, math.sqrt(dq2))  # fmt: skip
        res.__dict__["_compiled"] = plan.external_names + fused.python_targets or True
        return res

    def __repr__(self) -> str:
        return f"FeedbackResolver(epsilon={self.epsilon}, d_epsilon={self.d_epsilon})"


class _FusedFeedback:
    """A ``feedback`` stack laid out for its compiled step: ``pinv``'s fused plan of the main rows and z (the
    target subtasks are not in it), and per target subtask its potential's compiled writer or ``None`` (its
    ``row`` is called)."""

    def __init__(self, robot: RobotModel, layout: StackLayout, plan: FusedPlan | None, targets: list[Any]) -> None:
        self.robot, self.layout, self.plan, self.targets = robot, layout, plan, targets
        self.writers: list[CompiledGradient | None] = []
        self.revisions: list[int] = []
        self.python_targets: tuple[str, ...] = ()
        self.retry = False  # (no plan yet: a frame task not evaluated on this robot; planned again next step)

    @classmethod
    def build(cls, robot: RobotModel, stack: TaskStack, layout: StackLayout) -> _FusedFeedback:
        targets = list(stack.target_subtasks)
        built = FusedPlan.build(robot, stack, layout, None, 1.0, mixed=True)
        out = cls(robot, layout, built if isinstance(built, FusedPlan) else None, targets)
        out.retry = built == FusedPlan.NOT_YET  # (None: no compiled form for this membership, not tried again)
        out.writers = [compiled_writer(sub.potential, robot) for sub in targets]
        out.revisions = [sub.potential.form_revision for sub in targets]
        out.python_targets = tuple(sub.name for sub, w in zip(targets, out.writers, strict=True) if w is None)
        return out

    def current(self, robot: RobotModel, layout: StackLayout) -> bool:
        """Laid out for this membership, robot and potentials' forms. Without a plan: current unless it was not
        ready yet (a membership with no compiled form is not planned again at every step)."""
        plan = self.plan
        if layout is not self.layout or robot is not self.robot:
            return False  # (a new membership, its target subtasks included, comes with a new layout)
        if plan is None:
            return not self.retry
        if not plan.current(robot):
            return False
        return all(sub.potential.form_revision == rev for sub, rev in zip(self.targets, self.revisions, strict=True))

    def target_rows(self, robot: RobotModel) -> tuple[np.ndarray | None, np.ndarray]:
        """(N as rows (r, n), ẏ_d + K(y_d − y) (r,)) at this step (``TargetSubtask.row``); N ``None``: a row that
        is not finite, or a gradient that is not a float vector (nv,) (the per-task path says what is wrong)."""
        r, n = len(self.targets), robot._nv
        if r == 0:
            return _NO_ROWS[n] if n in _NO_ROWS else _NO_ROWS.setdefault(n, (np.zeros((0, n)), np.zeros(0)))
        Nt, rhs = np.zeros((r, n)), np.empty(r)
        plan = self.plan
        assert plan is not None
        q = robot.q
        for i, (sub, writer) in enumerate(zip(self.targets, self.writers, strict=True)):
            if writer is not None:
                e = sub.target - writer.kernel(q, plan.poses, plan.jw, writer.ints, writer.floats, Nt[i])
                rhs[i] = sub.target_rate + sub.rate * e
            else:
                eta, v, _ = sub.row(robot)
                if not (type(eta) is np.ndarray and eta.dtype == np.float64 and eta.shape == (n,)):
                    return None, rhs
                Nt[i] = eta
                rhs[i] = v
        if not math.isfinite(float(Nt.sum()) + float(rhs.sum())):  # (a NaN or ±inf entry: the sum is not)
            return None, rhs
        return Nt, rhs


def _zeros(n: int) -> np.ndarray:
    """A zero vector of n (z of a stack without a null-space objective: the kernel does not read it; writable, so
    that it has the kernel's one compiled signature)."""
    z = _NO_Z.get(n)
    if z is None:
        z = _NO_Z[n] = np.zeros(n)
    return z


_NO_Z: dict[int, np.ndarray] = {}


def _result(
    dq: np.ndarray,
    out: np.ndarray,
    gains: np.ndarray,
    report: np.ndarray,
    J: np.ndarray,
    make_terms: Callable[[], list[TaskTerm]],
    task_error: float,
    build_time: float,
    solve_time: float,
    main: list[int],
    dq_norm: float | None = None,
) -> FusedStepResult:
    """The step's result from ``feedback_law``'s outputs: the terms built when first read, and σ_min of the main
    rows J computed when first read if the law took its Cholesky route (reported NaN)."""
    smin, damping, d_damping = float(report[FB_SIGMA_MIN]), float(report[FB_DAMPING]), float(report[FB_D_DAMPING])
    info: dict[str, object] = {"rank": int(report[FB_J_RANK]), "D_damped": d_damping > 0.0,
                               "D_rank": int(report[FB_D_RANK])}  # fmt: skip
    pending = None
    if smin != smin:  # (NaN: J well conditioned and undamped)
        pending = functools.partial(_sigma_min, J, d_damping > 0.0)
    else:
        info["sigma_min"] = smin
    res = FusedStepResult.fused(dq, make_terms, task_error, info, build_time, solve_time, main, pending,  # type: ignore[arg-type]
                                out[FB_RANK], out[FB_NULL], dq_norm)  # fmt: skip
    d = res.__dict__
    d["gains"], d["damping"] = gains, damping
    if pending is None:
        d["_sigma_min"], d["_damped"] = smin, damping > 0.0 or d_damping > 0.0
    return res


@info_keys("sigma_min")
def _sigma_min(J: np.ndarray, d_damped: bool) -> tuple[float, bool, dict[str, object]]:
    """σ_min of a well-conditioned, undamped J (the law's Cholesky route), on first read."""
    smin = gram_sigma_min(J)
    return smin, d_damped, {"sigma_min": smin}

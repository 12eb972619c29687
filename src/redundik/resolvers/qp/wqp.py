"""``wqp``: one QP, a weighted sum of every level of the stack, with the joint limits and bound subtasks as constraints.

    minimise   ½ Σ_k ρ^k [ Σ_{t ∈ level k} w_t ‖J_t q̇ − v_t‖² ]  + ½λ‖q̇‖²
    subject to C q̇ ≤ d (bound subtasks, every level),   lb ≤ q̇ ≤ ub (joint limits over dt)

The levels are the stack's (:mod:`redundik.tasks.stack`): main tasks, then target subtasks, then the null-space
objective ½‖q̇ − z‖² (z = Σ k_i η_i + posture), counted k = 0, 1, … over the levels present; ρ = ``level_ratio``
(default 1e-4) makes each level a small perturbation of the one above, so with no constraint active the main-task
velocity differs from the hierarchy's (``pinv``/``hqp``) by O(ρ‖z‖/σ_min²) — a stack tracks under ``wqp`` as it
does under ``pinv`` (for unit main-task weights: the weights are absolute, as any weighted QP's costs, and a main
task of weight w < 1 moves toward the level below, its bound growing as 1/w). The −ρ^k zᵀq̇ part of the null
objective is the QP twin of the null-space term kη of eq. (5.8). λ = ``damping``·ρ^(L−1) (L levels: always far below
the lowest level) + ``lm_damping``·‖e‖² (a Levenberg–Marquardt-like regulariser growing with the main-task error,
Sugihara 2011) keeps the optimum unique and bounded near singularities.

Hot loop: when the unconstrained optimum P⁻¹(−q) already satisfies every constraint it is the QP's optimum and is
returned without calling the backend (a Cholesky solve instead of a QP, flagged ``info["qp"] = 0``); otherwise the
backend solves the QP, warm-started at the previous q̇; with P = FᵀF + δI (the task rows F = √(ρ^k w) J, δ the diagonal
of identity tasks, null objective and λ) handed to it as the problem's factor, daqp solves a large QP lifted to (q̇, s =
F q̇), with a diagonal Hessian (:mod:`redundik.resolvers.qp.backends`). A backend failure or an infeasible QP (bound
subtasks that the limits do not allow) is relaxed first (the bound subtasks dropped, except safety rows — collision
distances — which stay hard), then replaced by the damped closed form clipped to the limits and scaled down until the
safety rows hold (q̇ = 0 always does). ``StepResult.relaxed`` names the bound subtasks dropped; when the QP was
infeasible (``redundik.resolvers.qp.problem.infeasible``, a linear program on its constraints) that is the
documented relaxation and no alarm, otherwise the backend failed on a feasible QP and ``StepResult.fallback`` says
so, as it does for the closed form. When the relaxed optimum keeps the rows dropped it is the QP's own optimum:
nothing was relaxed, and the refusal counts as a backend failure that a retry rescued — as a backend's own retry
that solved the QP (``QPSolution.retried``) does: in ``relaxed`` as ``"wqp (backend retried)"``, told in
``info["retries"]``.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from redundik._coldstart import ready
from redundik.errors import SolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import LazyStepResult, StepResult
from redundik.resolvers.fused import FusedPlan
from redundik.resolvers.layouts import (
    LIM_AMAX,
    LIM_HI,
    LIM_LO,
    LIM_ROWS,
    LIM_VMAX,
    OPT_DT,
    OPT_GAIN,
    OPT_POSITION,
    OPT_RATE,
    OPT_SHIFT,
    OPT_Z_SCALE,
    OUT_DQ,
    OUT_FREE,
    OUT_KEPT,
    OUT_ROWS,
    QP_G,
    QP_LIM,
    QP_P,
    TAIL_T,
    WQP_OPTS,
    WQP_TAIL,
)
from redundik.resolvers.linalg import FK, K
from redundik.resolvers.qp.backends import DEFAULT_BACKEND, Backend
from redundik.resolvers.qp.base import LevelsOption, LimitsOption, QPDiagnostics, QPResolverBase
from redundik.resolvers.qp.direction import DirectionScaling, solve_direction
from redundik.resolvers.qp.limits import LimitBox
from redundik.resolvers.qp.problem import QPProblem, infeasible
from redundik.resolvers.qp.wqp_bounds import BoundRows, PackedBoundRows, python_bound_rows
from redundik.resolvers.qp.wqp_fused import FusedWqpResult, free_diagnostics, work_views, work_with_external, write_caps
from redundik.resolvers.qp.wqp_gram import gram_factor, gram_of
from redundik.resolvers.qp.wqp_native import native_box_step
from redundik.resolvers.settings import Setting, flag, nonnegative, unit_interval
from redundik.resolvers.singularity import SingularityGuard
from redundik.tasks.base import TaskTerm
from redundik.tasks.stack import StackLayout, TaskStack
from redundik.tasks.subtasks import BoundSubtask, TargetSubtask


@dataclass
class WQPBuild:
    """A built ``wqp`` step: the problem and what the diagnostics need.

    Attributes:
        problem: The QP (inspect it, save it, solve it).
        box: The joint-limit box of the step.
        main_terms: The main tasks' terms (for the level-0 residual).
        damping: λ of the step.
        safe: Per row of ``problem.G``, whether it is a safety row (kept by the relaxed problem).
        free_outside: True when the unconstrained optimum is already known to leave the box (the lean path tested
            it): the backend is called without testing it again.
    """

    problem: QPProblem
    box: LimitBox
    main_terms: list[TaskTerm]
    damping: float = 0.0
    safe: np.ndarray | None = None
    free_outside: bool = False
    #: (F, δ) with P = FᵀF + δI, computed when the backend is called (``wqp_gram.gram_factor``); or None
    gram: Callable[[], tuple[np.ndarray, float] | None] | None = None


_NO_Z = np.zeros(0)
#: The step's time t in a fused step's ``coef``, counted from its end (the resolver's tail, ``layouts.WQP_TAIL``).
_COEF_T = TAIL_T - WQP_TAIL


class _Plan:
    """What a ``wqp`` build does per member, fixed while the stack's membership is (see ``_plan_for``)."""

    def __init__(self, layout: StackLayout) -> None:
        self.layout = layout
        self.tasks: list[tuple[int, float, bool]] = []  # (task index, ρ^k, identity Jacobian)
        self.targets: list[tuple[TargetSubtask, float]] = []
        self.bounds: list[BoundSubtask] = []
        self.bound_rows = PackedBoundRows()  # (the fused step's compiled rows of bounds on clearances)
        self.null_scale = 0.0  # ρ^k of the null-space objective's level (0: none)
        self.last_scale = 1.0  # ρ^(L−1)
        self.main: list[int] = layout.main
        #: The fused form of the stack (:mod:`redundik.resolvers.fused`): ``None`` not planned yet, False none.
        self.fused: FusedPlan | str | bool | None = None
        #: The membership key (``Resolver.stack_key`` inside ``step``) this plan was looked up with, or ``None``.
        self.key: tuple[int, ...] | None = None


class WeightedQPResolver(DirectionScaling, QPResolverBase):
    """Weighted-sum QP resolution (see the module docstring).

    Args:
        backend: QP backend (default ``"daqp"``; see :mod:`redundik.resolvers.qp.backends`).
        limits: Joint limits: ``None`` = the model's, ``False`` = none, a dict of
            :class:`~redundik.resolvers.qp.limits.JointLimits` options, or an instance.
        level_ratio: ρ ∈ (0, 1): weight of each level relative to the one above.
        damping: λ relative to the lowest level's weight ρ^(L−1), ≥ 0.
        lm_damping: Error-dependent part: λ += lm_damping·‖e‖², ≥ 0.
        levels: Level overrides by task / subtask name (as ``hqp``).
        epsilon: Damping threshold of the closed-form fallback.
        max_damping: λ_max of the closed-form fallback.
        max_joint_speed: Cap on every |q̇_i| [rad/s; m/s for a prismatic joint]: ``"auto"`` = the robot's velocity
            limits (10 rad/s where it has none), a number, or ``None`` (no cap); the QP's velocity limits hold it
            already unless they are off; when it acts q̇ is scaled as a whole and the step says so
            (:mod:`redundik.resolvers.singularity`).
        singularity: A :class:`~redundik.resolvers.singularity.SingularityGuard` (or a mapping of its fields,
            ``True`` for its defaults) to decelerate and halt near a singularity of the main tasks; ``None``: none.
        scaling: ``"off"`` (default) or ``"direction"``: scale the main tasks' velocity V to the largest α ∈ [0, 1]
            the hard limits allow along V's direction, then the lower levels in what is left
            (:mod:`redundik.resolvers.qp.direction`; the interpreted step, not the fused one).
        stuck_below: α under which ``result.stuck`` is set, in [0, 1].

    Raises:
        ResolverError: negative or non-finite numbers; SolverError: unknown or missing backend.
    """

    name = "wqp"
    #: Take the fused step (:mod:`redundik.resolvers.fused`) when the stack allows it; the per-task path otherwise
    #: (the same answer: a switch for comparisons and tests).
    fuse = Setting(flag, resets=("_plan",))
    damping = Setting(nonnegative)
    lm_damping = Setting(nonnegative, resets=("_plan",))  # (whether the stack is fused depends on it)
    level_ratio = Setting(unit_interval, resets=("_plan",))  # (the level weights ρ^k are the plan's)

    def __init__(
        self,
        backend: str | Backend = DEFAULT_BACKEND,
        limits: LimitsOption = None,
        level_ratio: float = 1e-4,
        damping: float = 1e-6,
        lm_damping: float = 0.0,
        levels: LevelsOption = None,
        epsilon: float = 1e-2,
        max_damping: float = 5e-2,
        max_joint_speed: float | str | None = "auto",
        singularity: SingularityGuard | dict[str, float] | bool | None = None,
        scaling: str = "off",
        stuck_below: float = 1e-3,
    ) -> None:
        super().__init__(backend, limits, levels, epsilon, max_damping)
        self.damping, self.lm_damping, self.level_ratio = damping, lm_damping, level_ratio  # (validated: Setting)
        self.scaling, self.stuck_below = scaling, stuck_below
        self.fuse = True
        self._P: np.ndarray | None = None  # (views on the QP record ``_qp``: ``_buffers``)
        self._q: np.ndarray | None = None
        self._qp = np.zeros((QP_P, 0))
        self._caps_seen: np.ndarray | None = None  # the caps last written into the QP record's row ``QP_CAPS``
        self._plan: _Plan | None = None
        self._no_rows, self._no_rhs = np.zeros((0, 0)), np.zeros(0)
        self._diag = np.zeros(0)
        #: (the limits' kernel arguments, λ, dt, the fused step's coefficients of the resolver) as last read
        self._tail: tuple[object, float, float, tuple[float, ...]] = (None, math.nan, math.nan, ())
        #: (the limits' kernel arguments, their record ``lim`` in ``_qp``'s rows, the options ``opts`` of the lean box)
        self._record: tuple[object, np.ndarray, np.ndarray] = (None, np.zeros((LIM_ROWS, 0)), np.zeros(WQP_OPTS))
        self.max_joint_speed, self.singularity = max_joint_speed, singularity  # (validated on assignment)

    def build(
        self, robot: RobotModel, stack: TaskStack, t: float, dt: float, terms: list[TaskTerm] | None = None
    ) -> WQPBuild:
        """Evaluate the stack (unless ``terms`` are given) and build the QP without solving it.

        Rows are accumulated straight into P = Σ ρ^k w JᵀJ and q = −Σ ρ^k w Jᵀv in preallocated arrays; a task
        that declares ``identity_jacobian`` and the null-space objective are diagonal updates.
        """
        if terms is None:
            terms = stack.evaluate(robot, t)
        layout = self.layout(stack)
        plan = self._plan_for(stack, layout)
        shift, z, lam = self._accumulate(robot, stack, terms, plan)
        G, h, names, safe = self._bound_rows(robot, plan, dt)
        P, q = self._P, self._q
        assert P is not None and q is not None  # allocated by _accumulate
        if shift:
            self._diag += shift
        if z is not None:
            q -= plan.null_scale * z
        box = self._box(robot, dt)
        prob = QPProblem(P, q, G, h, self._no_rows, self._no_rhs, box.lb, box.ub, "wqp", names)
        gram = None if plan.targets else (lambda: gram_factor(self, plan.tasks, terms, shift))
        return WQPBuild(prob, box, [terms[i] for i in plan.main], lam, safe, gram=gram)

    def _bound_rows(self, robot: RobotModel, plan: _Plan, dt: float) -> BoundRows:
        """The bound subtasks' rows G q̇ ≤ h (each subtask's ``rows``), their names and which are safety rows
        (``None``: no bound subtask)."""
        if not plan.bounds:
            return self._no_rows, self._no_rhs, [], None
        return python_bound_rows(plan.bounds, robot, dt)

    def _lambda(self, plan: _Plan, terms: list[TaskTerm]) -> float:
        """λ of the step: ``damping``·ρ^(L−1) + ``lm_damping``·‖e‖² (module docstring)."""
        lam = self.damping * plan.last_scale
        if self.lm_damping:
            lam += self.lm_damping * sum(float(terms[i].error @ terms[i].error) for i in plan.main)
        return lam

    def _accumulate(
        self, robot: RobotModel, stack: TaskStack, terms: list[TaskTerm], plan: _Plan
    ) -> tuple[float, np.ndarray | None, float]:
        """The task and target rows into P = Σ ρ^k w JᵀJ and q = −Σ ρ^k w Jᵀv (zeroed first, preallocated); a task
        that declares ``identity_jacobian`` adds its weight to the diagonal shift instead.

        Returns:
            (the diagonal shift still to add — identity tasks, the null-space objective's ρ^k, λ —, z of the
            null-space objective or ``None`` — it still has to be subtracted as ρ^k z —, λ).
        """
        n = robot._nv
        P = self._P
        q = self._q
        if P is None or q is None or P.shape[0] != n:
            P, q = self._buffers(n)
        lam = shift = self.damping * plan.last_scale  # λ (``_lambda``), its first term inlined
        if self.lm_damping:
            lam = shift = self._lambda(plan, terms)
        fresh = False  # P and q zeroed (by the first task's compiled update, or here)
        for i, scale, identity in plan.tasks:
            term = terms[i]
            w = scale * term.weight
            if identity:
                if not fresh:
                    P.fill(0.0)
                    q.fill(0.0)
                    fresh = True
                shift += w
                q -= w * term.v
            else:
                K.gram_update(P, q, term.J, term.v, w, not fresh)  # P += w JᵀJ, q −= w Jᵀv in one compiled call
                fresh = True
        if not fresh:
            P.fill(0.0)
            q.fill(0.0)
        for sub, scale in plan.targets:
            eta, v, _ = sub.row(robot)
            w = scale * sub.weight
            P += w * np.outer(eta, eta)
            q -= (w * v) * eta
        z = None
        if plan.null_scale:
            shift += plan.null_scale
            z = stack.null_target(robot, terms, plan.layout)
        return shift, z, lam

    def solve(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> StepResult:
        """One step: the fused step when the stack has a plan (its target subtasks' rows written from Python, its
        bound rows tested beside it); else, for a stack of tasks only, the lean path below: rows accumulated, then
        box, null-space objective, unconstrained optimum and its box test in one compiled call; the backend is
        called (through the shared template) only when that optimum leaves the box.
        ``scaling="direction"`` takes the interpreted step of :mod:`redundik.resolvers.qp.direction`."""
        if self.scaling != "off":
            return solve_direction(self, robot, stack, t, dt, self.stuck_below)
        plan = self._plan
        if plan is None or stack is not self._stepping or plan.key is not self._checked:  # else: the step's plan
            plan = self._plan_for(stack, self.layout(stack))
            plan.key = self._checked if stack is self._stepping else None
        if self.limits.has_jerk:  # (a jerk limit: the box needs the last two q̇)
            return super().solve(robot, stack, t, dt)
        fused = plan.fused
        if fused is None or fused == FusedPlan.NOT_YET:
            fused = plan.fused = (
                (self._fused_plan(robot, stack, plan) if ready("wqp") else FusedPlan.NOT_YET) if self.fuse else False
            )  # (NOT_YET while its kernels compile in the background: the per-task path, planned again next step)
        if isinstance(fused, FusedPlan):
            if fused.current(robot):
                res = self._fused_solve(robot, stack, fused, plan, t, dt)
                if res is not None:
                    # (Resolver.step reports the path: compiled, or mixed naming the Python-written members)
                    res.__dict__["_compiled"] = fused.external_names or True
                    return res
            else:
                plan.fused = None  # a member changed (a new target, trajectory): planned again at the next step
        if plan.bounds or plan.targets:  # the template: the bound rows as the QP's inequalities, the target rows
            return super().solve(robot, stack, t, dt)
        t0 = time.perf_counter()
        terms = stack.evaluate(robot, t)
        shift, z, lam = self._accumulate(robot, stack, terms, plan)
        t1 = time.perf_counter()
        limits = self.limits
        prev = limits.previous(self._dq_prev)
        out = np.empty((OUT_ROWS, robot._nv))
        args = limits.kernel_args(robot)
        lim, opts = self._box_record(args)
        opts[OPT_DT], opts[OPT_SHIFT], opts[OPT_Z_SCALE] = dt, shift, plan.null_scale
        z = _NO_Z if z is None else z
        inside = K.wqp_free_step(self._P, self._q, z, robot.q, args[0], lim, opts, prev, out)
        windowed = prev.shape[0] > 0
        if not inside:  # a constraint is active (or the optimum is not finite): daqp's C entry, or the template
            gram = gram_of(self, plan, terms, lam) if robot._nv >= self._lift_min_n else None
            native = native_box_step(self, stack, terms, out, windowed, lam, t0, t1, None, gram)
            return native or self._box_qp(robot, stack, terms, plan, out, windowed, lam, t0, t1)
        dq, kept = out[OUT_DQ], out[OUT_KEPT]
        self._dq_hist, self._dq_prev = (kept, self._dq_prev), kept  # (a jerk limit switched on reads both)
        diagnostics = free_diagnostics(self, lambda: terms, plan.main, out, windowed, kept, lam)
        return LazyStepResult.make(
            dq,
            terms,
            None,
            {"backend": "closed-form", "qp": 0, "iterations": 0},
            t1 - t0,
            time.perf_counter() - t1,
            plan.main,
            diagnostics,
        )

    def _buffers(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """(P, g): the QP record ``_qp`` (``QP_P`` + n, n; :mod:`.layouts`) allocated for n velocity coordinates,
        ``_P`` and ``_q`` views on its rows (``_diag`` on P's diagonal); its joint-limit rows are written at the
        next ``_box_record``."""
        qp = self._qp = np.empty((QP_P + n, n))
        self._caps_seen = None  # (the cap row written at the next fused step)
        P, g = self._P, self._q = qp[QP_P:], qp[QP_G]
        self._diag = P.reshape(-1)[:: n + 1]  # a view on P's diagonal
        self._no_rows, self._no_rhs = np.zeros((0, n)), np.zeros(0)
        self._record = (None, *self._record[1:])
        return P, g

    def _box_record(self, args: tuple[Any, ...]) -> tuple[np.ndarray, np.ndarray]:
        """The joint-limit record ``lim`` (the rows ``QP_LIM`` … of the QP record ``_qp``) and the options ``opts`` of
        ``K.wqp_free_step`` (:mod:`.layouts`) for the limits' kernel arguments ``args`` (written when they are a new
        tuple — the limits or their options changed — or the record is new); the caller writes dt, the shift and the
        null-space scale into ``opts``."""
        record = self._record
        if record[0] is not args:
            opts = np.zeros(WQP_OPTS)
            opts[OPT_POSITION], opts[OPT_RATE], opts[OPT_GAIN] = float(args[5]), float(args[6]), float(args[7])
            lim = self._qp[QP_LIM : QP_LIM + LIM_ROWS]
            lim[LIM_LO], lim[LIM_HI], lim[LIM_VMAX], lim[LIM_AMAX] = args[1], args[2], args[3], args[4]
            record = self._record = (args, lim, opts)
        return record[1], record[2]

    def _box_qp(
        self,
        robot: RobotModel,
        stack: TaskStack,
        terms: list[TaskTerm],
        plan: _Plan,
        out: np.ndarray,
        windowed: bool,
        lam: float,
        t0: float,
        t1: float,
        bounds: BoundRows | None = None,
    ) -> StepResult:
        """A lean step whose unconstrained optimum left the box (rows of ``out``: lb, ub, pos_lo, pos_hi) or the
        bound rows ``bounds`` (G, h, names, safety flags): the backend solves P, q with that box and those rows,
        through the template's second half."""
        P, q = self._P, self._q
        assert P is not None and q is not None
        box = self.limits.box_from(out, windowed)
        G, h, names, safe = bounds if bounds is not None else (self._no_rows, self._no_rhs, [], None)
        prob = QPProblem(P, q, G, h, self._no_rows, self._no_rhs, box.lb, box.ub, "wqp", names)
        gram = gram_of(self, plan, terms, lam)
        built = WQPBuild(
            prob, box, [terms[i] for i in plan.main], lam, safe, free_outside=True, gram=gram
        )  # (the free optimum is known to leave the box or to break a bound row)
        return self._finish(robot, stack, terms, built, t0, t1)

    @property
    def _lift_min_n(self) -> int:
        """The smallest n the backend may lift a QP at (``DaqpBackend.lift_min_n``; none: never)."""
        return int(getattr(self.backend, "lift_min_n", sys.maxsize))

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Restore a copy or a pickle: ``_P``, ``_q`` and ``_diag`` views on the copy's own QP record again (a copied
        view is a separate array: the rows and shifts a step wrote into it would not reach the QP solved)."""
        self.__dict__.update(state)
        self._caps_seen = None  # (the cap row written again at the next fused step)
        qp, n = self._qp, self._qp.shape[1]
        if n:  # P, g (and the limit rows, at the next box): views on the copy's own QP record again
            P, self._q, self._record = qp[QP_P:], qp[QP_G], (None, *self._record[1:])
            self._P, self._diag = P, P.reshape(-1)[:: n + 1]

    def compiled_off(self) -> str | None:
        """``QPResolverBase.compiled_off``, and ``lm_damping`` (λ grows with the error, computed per task)."""
        if self.lm_damping:
            return "lm_damping (λ grows with the task error) has no compiled step"
        return super().compiled_off()

    def _fused_plan(self, robot: RobotModel, stack: TaskStack, plan: _Plan) -> FusedPlan | str | bool:
        """The fused form of the plan's stack (:mod:`redundik.resolvers.fused`), ``NOT_YET`` or False (none)."""
        if self.lm_damping:  # λ grows with the error: the per-task path computes it
            return False
        scales = {i: (scale, identity) for i, scale, identity in plan.tasks}
        built = FusedPlan.build(robot, stack, plan.layout, scales, plan.null_scale, mixed=True, targets=plan.targets)
        if isinstance(built, FusedPlan):  # (bound rows written from Python name their subtasks)
            built.external_names += tuple(b.name for b in plan.bounds if not b.rows_compiled(robot))
        return False if built is None else built

    def _fused_solve(
        self, robot: RobotModel, stack: TaskStack, fused: FusedPlan, plan: _Plan, t: float, dt: float
    ) -> StepResult | None:
        """The lean step of a fused stack (:mod:`redundik.resolvers.fused`): one compiled call from Pinocchio's
        Jacobians to q̇, or to the QP when a limit binds; ``None`` when this step needs the per-task path (a rotation
        error beyond the compiled log3's range)."""
        t0 = time.perf_counter()
        n = robot._nv
        if self._qp.shape[1] != n:
            self._buffers(n)
        qp = self._qp
        limits = self.limits
        args = limits.kernel_args(robot)
        if self._record[0] is not args:  # the limits or their options changed (or the record is new): their rows
            self._box_record(args)
        lam = self.damping * plan.last_scale
        tail = self._tail
        if tail[0] is not args or tail[1] != lam or tail[2] != dt:  # the limits' options, λ or dt changed: re-read
            tail = self._tail = (args, lam, dt, (float(args[5]), float(args[6]), float(args[7]), lam, float(dt), 0.0))
        coef = fused.coefficients(tail[3])  # (its tail: layouts.TAIL_POSITION … TAIL_T)
        coef[_COEF_T] = t
        refs = fused.given_references(t) if fused.given else fused.refs
        prev = limits.previous(self._dq_prev)
        made = work_with_external(fused, robot, t)  # (the Python writers' rows of a mixed plan written)
        if made is None:
            return None
        work, external = made
        if fused.lie_joints:
            fused.write_joint_errors(robot, work[OUT_ROWS * n : OUT_ROWS * n + fused.m])  # (e: the first row of ev)
        self._caps_seen = write_caps(self._limiter, robot, qp, self._caps_seen)  # (the cap's test in the call)
        q = robot.q
        status, err2, dq2, over = FK.fused_wqp_step(
            fused.jw, fused.poses, refs, q, fused.ints, fused.floats, coef, qp, prev, work
        )
        if status < 0.0:
            return None
        bounds = plan.bound_rows.rows(plan.bounds, robot, fused.jw, fused.poses, dt) if plan.bounds else None
        if bounds is not None and status == 1.0:  # the optimum inside the box: is it inside the bound rows too?
            G, h = bounds[0], bounds[1]
            if G.shape[0] and not (G @ work[OUT_FREE * n : (OUT_FREE + 1) * n] <= h + 1e-12).all():
                status = 0.0
        t1 = time.perf_counter()
        windowed = prev.shape[0] > 0
        if status == 0.0:  # a limit or a bound row binds: the backend, through the template
            K, m = len(fused.frames), fused.m
            out, ev, Jf = work_views(work, K, m, n)
            terms = fused.terms(Jf, ev, q, robot, external)
            if bounds is not None:  # (the QP and the result keep them: copies of the plan's buffers)
                bounds = plan.bound_rows.kept(bounds)
            gram = gram_of(self, plan, terms, lam) if n >= self._lift_min_n else None  # (a factor to lift with)
            native = native_box_step(self, stack, terms, out, windowed, lam, t0, t1, bounds, gram)
            return native or self._box_qp(robot, stack, terms, plan, out, windowed, lam, t0, t1, bounds)
        kept = work[OUT_KEPT * n : (OUT_KEPT + 1) * n]
        self._dq_hist, self._dq_prev = (kept, self._dq_prev), kept  # (a jerk limit switched on reads both)
        return FusedWqpResult.of(
            self, fused, work, q, robot, windowed, lam, (err2, dq2, over), t1 - t0, t1, plan.main, external
        )

    def _plan_for(self, stack: TaskStack, layout: StackLayout) -> _Plan:
        """The level weights ρ^k of every member, laid out once per stack membership (the layout object)."""
        plan = self._plan
        if plan is None or plan.layout is not layout:
            plan = self._plan = _Plan(layout)
            for k, level in enumerate(layout.levels):
                scale = self.level_ratio**k
                plan.last_scale = scale
                plan.tasks += [(i, scale, bool(stack.tasks[i].identity_jacobian)) for i in level.tasks]
                plan.targets += [(sub, scale) for sub in level.targets]
                plan.bounds += level.bounds
                if level.null_objective:
                    plan.null_scale = scale
        return plan

    def _resolve(self, built: WQPBuild, diag: QPDiagnostics) -> tuple[np.ndarray, str | None]:
        prob, box = built.problem, built.box
        # the unconstrained optimum by Cholesky (P is SPD when λ > 0) and its box test, in one compiled call
        if not built.free_outside:
            x = np.empty(prob.n)
            _, inside = K.spd_solve_box_into(prob.P, prob.q, box.lb, box.ub, 1e-12, x)
            if inside and not (prob.G.shape[0] and (prob.G @ x > prob.h + 1e-12).any()):
                return x, None
        diag.qp = 1
        if built.gram is not None and prob.factor is None:
            prob.factor = built.gram()
        try:
            sol = self._solve_qp(prob, self._dq_prev, diag)
            diag.backend, diag.iterations = sol.backend, sol.iterations
            return sol.x, None
        except SolverError as exc:
            if not prob.G.shape[0]:
                raise
            keep = built.safe if built.safe is not None else np.zeros(prob.G.shape[0], dtype=bool)
            if keep.all():
                raise  # nothing to relax: the base falls back to the closed form, scaled to keep the safety rows
            kept = [r for r, k in zip(prob.row_names, keep, strict=True) if k]
            relaxed = QPProblem(
                prob.P, prob.q, prob.G[keep], prob.h[keep], prob.A, prob.b, prob.lb, prob.ub, "wqp relaxed", kept,
                prob.factor,
            )  # fmt: skip
            sol = self._solve_qp(relaxed, self._dq_prev, diag)  # a SolverError here goes to the closed form
            diag.backend, diag.iterations, diag.qp = sol.backend, sol.iterations, 2
            dropped = sorted({r.split(":")[0] for r, k in zip(prob.row_names, keep, strict=True) if not k})
            if np.all(prob.G[~keep] @ sol.x <= prob.h[~keep] + 1e-9 * np.maximum(1.0, np.abs(prob.h[~keep]))):
                # the relaxed optimum keeps the rows dropped: it is the QP's own optimum (nothing was relaxed), and
                # the backend's refusal a failure that this second solve rescued
                diag.retries.append((prob.label, f"{exc}; solved without the bound rows, whose optimum keeps them"))
                return sol.x, None
            diag.relaxed += dropped
            if infeasible(prob):  # the documented relaxation: StepResult.relaxed names them, no alarm
                return sol.x, None
            note = f"wqp relaxed a feasible QP the backend failed on (bound subtasks {dropped} dropped"
            if kept:
                note += f"; safety rows of {sorted({r.split(':')[0] for r in kept})} kept"
            return sol.x, f"{note}): {exc}"

    def _safety_rows(self, built: WQPBuild, stack: TaskStack) -> tuple[np.ndarray, np.ndarray] | None:
        safe = built.safe
        if safe is None or not safe.any():
            return None
        return (built.problem.G, built.problem.h) if safe.all() else (built.problem.G[safe], built.problem.h[safe])

    def _diagnose(self, built: WQPBuild, dq: np.ndarray, diag: QPDiagnostics) -> None:
        self._diagnose_terms(built.main_terms, built.damping, dq, diag)
        G = built.problem.G
        if G.shape[0]:
            diag.bound_violation = float(np.max(np.maximum(G @ dq - built.problem.h, 0.0)))

    def _diagnose_terms(self, main_terms: list[TaskTerm], damping: float, dq: np.ndarray, diag: QPDiagnostics) -> None:
        """Level-0 residual and σ_min of the main-task Jacobian (eigenvalues of the small JJᵀ); the step counts as
        damped when λ ≥ 1e-3·σ_min² (the regulariser then bends the main-task solution)."""
        if main_terms:
            J = main_terms[0].J if len(main_terms) == 1 else np.vstack([t.J for t in main_terms])
            if J.shape[0] and not np.isfinite(J).all():  # (a NaN row: the step fell back, its fallback names it)
                diag.sigma_min = math.nan
            elif J.shape[0]:
                gram = J @ J.T if J.shape[0] <= J.shape[1] else J.T @ J
                ev = np.linalg.eigvalsh(gram)
                nz = ev[ev > 1e-20 * max(float(ev[-1]), 1e-300)]
                diag.sigma_min = float(np.sqrt(nz[0])) if nz.size else np.inf
                if damping >= 1e-3 * diag.sigma_min**2:
                    diag.damped_levels.append(0)
            res2 = 0.0
            for tm in main_terms:
                r = tm.J @ dq - tm.v
                res2 += float(r @ r)
            diag.level_residuals[0] = res2**0.5

    def __repr__(self) -> str:
        return (
            f"WeightedQPResolver(backend={self.backend.name!r}, level_ratio={self.level_ratio}, limits={self.limits!r})"
        )

"""``hqp``: a strict hierarchy of any depth, equality and inequality tasks at every level, joint limits above all.

Method: the cascade of QPs with slack variables of Kanoun, Lamiraux & Wieber (2011), "Kinematic control of redundant
manipulators: generalizing the task-priority framework to inequality tasks", IEEE T-RO 27(4), solved in the reduced
coordinates of the null-space basis of the levels above, as in the lexicographic QP of Escande, Mansard & Wieber
(2014), "Hierarchical quadratic programming", IJRR 33(7). With x the solution so far and Z an orthonormal basis of
the directions that keep every level above at its optimum (Z = I before level 0), level k solves over q̇ = x + Z u
and slacks w:

    minimise   ½‖A_k Z u − (b_k − A_k x)‖² + ½‖w‖² + ½ε‖u‖²
    subject to C_k (x + Z u) − d_k ≤ w                       (this level's inequalities, relaxed by w)
               C_j (x + Z u) ≤ d_j + w_j*    for every j < k   (the levels above keep their optimal slack w_j*)
               lb ≤ x + Z u ≤ ub                              (joint limits: hard, above every level)

then x ← x + Z u*, w_k* = max(C_k x − d_k, 0), and Z ← Z·null(A_k Z): the optimum set of a least-squares level is
{A_k q̇ = A_k x*}, so its equalities are enforced exactly by shrinking the basis instead of adding rows. ε (default
1e-9, raised to the closed-form damping λ² near a singularity of A_k Z) only picks the minimum-norm optimum.
Two exact reformulations keep every backend's level QP well posed: a joint whose box is a single value (a rate
window squeezed to a point, a joint held at its limit) is fixed in x before level 0 and left out of Z, and the slack
is measured from its value at u = 0 (w = w₀ + w', w₀ = max(C_k x − d_k, 0)), so that u = 0, w' = 0 is feasible and
w' lives on the scale of u. Without them proxsuite called ~3 % of feasible stress-run levels "primal infeasible".

Shortcut (exact, and the common case): the same cascade without constraints is solved in closed form — level by
level u = (A_k Z)⁺(b_k − A_k x), with the damped pseudo-inverse of :mod:`redundik.resolvers.linalg` — and kept when
it satisfies every inequality and limit, since a feasible unconstrained lexicographic optimum is the constrained one.
For [main task, gradient subtask] this is q̇ = J⁺V + Z Zᵀ z = J⁺V + (I − J⁺J)z, the chapter's eq. (5.8), exactly.
The whole of it is one compiled call (:func:`redundik.resolvers.hqp_kernels.closed_cascade`) on the step's rows
written, as they are evaluated, into buffers kept while the stack's membership is unchanged (``_Plan.gather``: a
bound on a potential writes its damper rows itself, ``BoundSubtask.rows_into``); a level whose QR
certifies σ_min ≥ ε (nothing damped, full rank: M⁺ exactly) skips its SVD, a level of rows √w I with √w ≥ ε
takes Zᵀ(b − x) without a factorisation, and the per-level rows
(``StepRows``), the limit box's record, the Level records, σ_min per level and the rank-loss test are built only
when the step goes on to the QPs or its diagnostics are read (``LazyStepResult``).
Fused step (exact, :mod:`redundik.resolvers.fused`): a stack of frame tasks, joint-space tasks and linear gradient
subtasks, with bound and target subtasks (their rows from Python), skips the tasks' ``evaluate``: one compiled call
(``hqp_fused.fused_hqp_step``) writes their rows from Pinocchio's Jacobians into the same buffers at the rows
the per-task gather gives them, then runs the closed-form path above; the bound subtasks' rows are written beside
it as the gather writes them. The same q̇, terms and diagnostics (``tests/test_fused.py``).
Level shortcut (exact, at every level): when the cascade is not feasible, a level QP whose unconstrained
optimum — û = argmin ½‖A_k Z u − (b_k − A_k x)‖² + ½ε‖u‖² from the SVD of A_k Z, slack w = 0 — keeps every row of
that QP (its inequalities, the levels above, the limits, to the same margins) is that QP's optimum (the KKT
conditions hold with zero multipliers), and the backend is not called; ``info["qp"]`` counts the QPs solved. û is
exact to rounding, where a backend's answer on MᵀM + εI carries its condition number. A backend failure on a
level below the top one skips that level (reported); on the top level the step falls back to the closed form.
A level QP whose rows are √w I with √w ≥ ε (a posture given a level) takes the exact factors of A_k Z = √w Z —
(Z, √w, I), as the null-space objective's (Z, 1, I) — instead of an SVD.
Compiled constrained cascade: all of the constrained cascade but the level QPs — projections, SVDs, shortcuts,
the QP arrays, the slack bookkeeping, the bases — is one compiled call per backend call
(``hqp_kernels.qp_cascade_run``, on the plan's buffers); each level QP is written into a buffer in daqp's form,
which daqp solves as it is (``Backend.solve_stacked``; other backends get it as a ``QPProblem``); the Level
records are built only for a contradiction's row names and for the diagnostics (the tests hold it to a Python
cascade, ``tests/test_hqp_lean.py``). With daqp as the backend the cascade calls daqp's C entry point itself
(:mod:`redundik.resolvers.qp.daqp_native`) and goes on at once; a QP daqp does not solve at once comes back here
for the retries. A least-squares level of m ≤ r rows whose QR (A_k Z)ᵀ = Q [R; 0] certifies σ_min ≥ ε
(``certified_qr``; nothing damped, full rank) takes Q₂ as its null basis and the ridge û from R
(``hqp_kernels._ridge_triangular``, no normal equations) instead of the SVD — another orthonormal basis of the same
space, so the same level optima, q̇ to the level QPs' conditioning; its σ_min comes from R's singular values when
the diagnostics are read; in the complement mode the thin QR's Q₁ᵀ gives the level's fixed directions
(``hqp_kernels._certified_rows``).
A fused step whose cascade daqp settles entirely from the compiled call, no level contradicted, keeps nothing of
the template but that call and the clipping (``_native_cascade``, ``_native_result``: no HQPBuild, limit box or
QPDiagnostics until the diagnostics are read; the same q̇ and info bit for bit, ``tests/test_hqp_buffers.py``);
anything else runs the template from the start.
Complement mode (exact, large robots): below a least-squares level that leaves few directions fixed (at most a third
of nv, from nv ≥ ``complement_min_n`` = 40 on), the cascade keeps W, an orthonormal basis of the fixed directions,
instead of Z (null(W) = range(Z)), and poses each level QP over y = Z u in joint space: the joint limits become
simple bounds on y instead of 2·nv rows of Z, W y = 0 and the lifted least squares s = A_k y are equalities, the
Hessian stays diagonal (``hqp_kernels.level_qp_joint_into``); ‖u‖ = ‖y‖ and A_k Z u = A_k y on null(W), so the
QP and its optimum are the same, and no null basis is ever formed (the full SVD that forms it, with its nv × nv
factor, is costly on a large robot).

The levels are the stack's (:mod:`redundik.tasks.stack`): main tasks at their priority (0), target and bound
subtasks below them, the null-space objective ½‖q̇ − z‖² (gradient subtasks and posture) last; restricted to Z it
gives the projection Z Zᵀ(z − x). Every level's least squares goes through the shared damped-SVD kernel of
:mod:`redundik.resolvers.linalg`, which damps only small nonzero singular directions: a level that is exactly
rank-deficient (a duplicated or zero row) is solved exactly and keeps its optimum under every lower level.

Weights count within a level only: a level's rows enter as √w_i A_i, and the damping rule's ε and λ_max, and the
regulariser ε, are taken relative to the level's largest weight (``Level.scale``), so that scaling every weight of a
level leaves the step unchanged — a main task of weight 1e-4 alone at the top is tracked as one of weight 1, not
damped away (``tests/test_hqp_weights.py``); a level QP of least squares only is posed to the backend divided by its
scale², on the scale of a unit weight.

A level that cannot be met — its bound rows contradicted by the levels above and the limits (slack w_k* > 1e-6) —
is the hierarchy's documented relaxation, not an alarm: ``StepResult.relaxed`` names its members and
``info["contradicted_levels"]`` says by how much; a level QP the backend failed on and a documented retry solved (a
stronger regulariser, ``_regularized_retry``, or the backend's own retry, ``QPSolution.retried``) is counted there
too (``"hqp level k (backend retried)"``, what failed in ``info["retries"]``). A level QP no retry solves is a
recorded fallback (``StepResult.fallback``): the level skipped, or on level 0 the closed form.

Diagnostics in ``StepResult.info``: ``residual_L<k>`` (per level: ‖J_k q̇ − v_k‖ of its task rows, or ‖q̇ − z‖ for a
pure gradient level, combined with the norm of its inequality violations),
``sigma_min_L<k>`` (smallest singular value of the projected Jacobian A_k Z), ``rank_loss`` (number of levels whose
projected Jacobian lost rank while the task's own did not — an algorithmic singularity) with ``rank_loss_levels``,
``active_limits`` / ``n_active``, ``backend``, ``iterations``, ``qp`` (number of level QPs solved).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from redundik._coldstart import ready
from redundik.errors import SolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import LazyStepResult, StepResult
from redundik.resolvers.fused import (
    ROW,
    TARGET,
    FusedPlan,
    FusedStepResult,
)
from redundik.resolvers.hqp_layout import (
    OUT_DQ,
    OUT_KEPT,
    OUT_LB,
    OUT_POS_HI,
    OUT_UB,
)
from redundik.resolvers.linalg import K, _Kernels
from redundik.resolvers.qp.backends import DEFAULT_BACKEND, Backend, finite
from redundik.resolvers.qp.base import LevelsOption, LimitsOption, QPDiagnostics, with_relaxed
from redundik.resolvers.qp.direction import DirectionScaling, solve_direction
from redundik.resolvers.qp.hqp_bounds import NO_BOUNDS
from redundik.resolvers.qp.hqp_constrained import (
    COMPLEMENT_FRACTION,
    COMPLEMENT_MIN_N,
    ConstrainedCascade,
    HQPBuild,
)
from redundik.resolvers.qp.hqp_plan import HK, _Plan
from redundik.resolvers.qp.hqp_result import FusedHqpResult
from redundik.resolvers.qp.terms import Level, gather_rows
from redundik.resolvers.settings import Setting, flag
from redundik.resolvers.singularity import NO_CAPS as _NO_CAPS
from redundik.resolvers.singularity import SingularityGuard
from redundik.tasks.base import TaskTerm
from redundik.tasks.stack import StackLayout, TaskStack

#: :mod:`redundik.resolvers.hqp_fused` (the fused step), imported on first use.
HFK = _Kernels("hqp_fused")
_BOX = slice(OUT_LB, OUT_POS_HI + 1)  # the limit box's rows of ``closed_step``'s out


class HierarchicalQPResolver(DirectionScaling, ConstrainedCascade):
    """Strict task hierarchy by a cascade of QPs with slack (see the module docstring for the method and references).

    Args:
        backend: QP backend (default ``"daqp"``).
        limits: Joint limits: ``None`` = the model's, ``False`` = none, a dict of
            :class:`~redundik.resolvers.qp.limits.JointLimits` options, or an instance.
        levels: Level overrides: ``{name: level}`` or a list of levels of names.
        regularization: ε, the minimum-norm regulariser of each level QP (> 0).
        epsilon: Singular value under which a direction of a level's projected Jacobian is damped.
        max_damping: λ_max of that damping.
        rcond: Relative threshold of the numerical rank of a projected Jacobian.
        max_joint_speed: Cap on every |q̇_i| [rad/s; m/s for a prismatic joint]: ``"auto"`` = the robot's velocity
            limits (10 rad/s where it has none), a number, or ``None`` (no cap); the QP's velocity limits hold it
            already unless they are off; when it acts q̇ is scaled as a whole and the step says so
            (:mod:`redundik.resolvers.singularity`).
        singularity: A :class:`~redundik.resolvers.singularity.SingularityGuard` (or a mapping of its fields,
            ``True`` for its defaults) to decelerate and halt near a singularity of the main tasks; ``None``: none.
        scaling: ``"off"`` (default) or ``"direction"``: scale the top level's velocity V to the largest α ∈ [0, 1]
            the hard limits allow along V's direction, then the levels below in what is left
            (:mod:`redundik.resolvers.qp.direction`; the interpreted step, not the fused one).
        stuck_below: α under which ``result.stuck`` is set, in [0, 1].

    Raises:
        ResolverError: bad numbers; SolverError: unknown or missing backend.
    """

    name = "hqp"
    fuse = Setting(flag, resets=("_plan",))  # (whether the stack is fused is the plan's)
    #: (the limits' ``kernel_args`` tuple, the fused step's coefficient tail read from it): read again for a new tuple
    _coef_tail: tuple[Any, tuple[float, float, float]] = (None, (0.0, 0.0, 0.0))

    def __init__(
        self,
        backend: str | Backend = DEFAULT_BACKEND,
        limits: LimitsOption = None,
        levels: LevelsOption = None,
        regularization: float = 1e-9,
        epsilon: float = 1e-2,
        max_damping: float = 5e-2,
        rcond: float = 1e-10,
        max_joint_speed: float | str | None = "auto",
        singularity: SingularityGuard | dict[str, float] | bool | None = None,
        scaling: str = "off",
        stuck_below: float = 1e-3,
    ) -> None:
        super().__init__(backend, limits, levels, epsilon, max_damping)
        self.regularization, self.rcond = regularization, rcond  # (validated: Setting)
        self.scaling, self.stuck_below = scaling, stuck_below
        self.slack_tolerance = 1e-7  # feasibility margin of the rows that carry higher levels and limits
        self.max_joint_speed, self.singularity = max_joint_speed, singularity  # (validated on assignment)
        self._plan: _Plan | None = None
        self._cfg: np.ndarray | None = (
            None  # the cascade's settings (``_cascade_cfg``; a Setting's assignment drops it)
        )
        #: Keep a level QP's unconstrained optimum when it satisfies the level's rows (exact; ``False`` solves
        #: every level by the backend, the reference the tests hold the shortcut to).
        self.level_shortcut = True
        #: Factor a level of rows √w I (√w ≥ ε) exactly — U = Z, σ = √w, V = I — instead of by its SVD (``False``:
        #: the SVD, the reference the tests hold these factors to).
        self.identity_levels = True
        #: Smallest robot (nv) whose constrained cascade keeps, below a level that leaves few directions fixed, the
        #: complement of its free directions instead of their basis, and poses the level QPs in joint space — the
        #: limits as bounds, the fixed directions as equalities (``hqp_kernels.level_qp_joint_into``): the same
        #: optimum; measured faster from about this size on. ``10**9``: never (the reference the tests hold it to).
        self.complement_min_n = COMPLEMENT_MIN_N
        #: "Few directions fixed": at most nv / ``complement_fraction`` (0: any level of fewer rows than nv).
        self.complement_fraction = COMPLEMENT_FRACTION
        #: In the constrained cascade, factor a least-squares level whose QR certifies σ_min ≥ ε (nothing damped,
        #: full rank; ``hqp_kernels.qr_certificate``) by that QR — the same ridge step and null space, several times
        #: cheaper — instead of its SVD (``False``: the SVD at every level, the reference the tests hold it to).
        self.certified_qr = True
        #: Take the fused step (:mod:`redundik.resolvers.fused`) when the stack allows it; the per-task path otherwise
        #: (``False``: always, the reference the tests hold the fused step to).
        self.fuse = True

    def build(
        self, robot: RobotModel, stack: TaskStack, t: float, dt: float, terms: list[TaskTerm] | None = None
    ) -> HQPBuild:
        """Evaluate the stack (unless ``terms`` are given) and lay out its levels as rows, without solving."""
        if terms is None:
            terms = stack.evaluate(robot, t)
        rows = gather_rows(robot, stack, terms, self.layout(stack), dt)
        return HQPBuild(rows, self._box(robot, dt), robot.nv)

    def reset(self) -> None:
        super().reset()
        self._plan = None

    # ------------------------------------------------------------------ the two cascades
    def _record(
        self, lv: Level, sigma_min: float, damping: float, rank: int, r: int, projected: bool, diag: QPDiagnostics
    ) -> None:
        """Record a solved level: σ_min and damping of A_k Z, and a rank loss of A_k Z that A_k itself has not
        (an algorithmic singularity; A_k's own rank is computed only then)."""
        diag.level_sigma_min[lv.priority] = sigma_min
        if damping > 0.0:
            diag.damped_levels.append(lv.priority)
        if not diag.level_sigma_min or len(diag.level_sigma_min) == 1:
            diag.sigma_min = sigma_min
        rows = lv.m + (lv.z.shape[0] if lv.z is not None else 0)
        if projected and not lv.pure_null_objective and rank < min(rows, r):
            A = lv.ls_rows()[0]
            if np.isfinite(A).all() and rank < min(int(np.linalg.matrix_rank(A)), r):  # (a NaN row has no rank:
                diag.rank_loss_levels.append(lv.priority)  # its step fell back, the fallback names it)

    def _lean_cascade(self, built: HQPBuild, layout: StackLayout) -> np.ndarray | None:
        """The unconstrained cascade (the module docstring's shortcut) in one compiled call, its per-level
        statistics kept on ``built`` for the diagnostics; ``None`` when its answer breaks a limit or an inequality."""
        n = built.n
        plan = self._plan_for(layout, n)
        rows = built.rows
        plan.fill(rows)
        x = np.empty(n)
        stats = np.empty((plan.meta.shape[1] - 1, 4))
        z = rows.z if rows.z is not None else plan.zero
        box = built.box
        if not HK.closed_cascade(plan.rows(z), (box.lb, box.ub), plan.params, x, stats):
            return None
        built.stats = stats
        return x

    # ------------------------------------------------------------------ the step (skeleton in QPResolverBase.solve)
    def solve(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> StepResult:
        """One step. Without safety rows the closed-form path — limit box, unconstrained cascade, its feasibility
        test and the clipping — is one compiled call (``hqp_kernels.closed_step``), and the step's result is the
        template's (``QPResolverBase.solve``) without its glue; when the cascade is not feasible the built step goes
        on through the template's second half to the constrained cascade. ``scaling="direction"`` takes the
        interpreted step of :mod:`redundik.resolvers.qp.direction`."""
        if self.scaling != "off":
            return solve_direction(self, robot, stack, t, dt, self.stuck_below)
        layout = self.layout(stack)
        n = robot.nv
        plan = self._plan_for(layout, n)
        if self.limits.has_jerk:  # (a jerk limit: the box needs the last two q̇)
            return super().solve(robot, stack, t, dt)
        fused = plan.fused
        if fused is None or fused == FusedPlan.NOT_YET:
            fused = plan.fused = (
                (plan.fuse(robot, stack, t) if ready("hqp") else FusedPlan.NOT_YET) if self.fuse else False
            )  # (NOT_YET while its kernels compile in the background: the per-task path, planned again next step)
        if isinstance(fused, FusedPlan):
            if fused.current(robot):
                res = self._fused_solve(robot, stack, plan, fused, t, dt)
                if res is not None:
                    # (Resolver.step reports the path: compiled, or mixed naming the Python-written members)
                    res.__dict__["_compiled"] = fused.external_names or True
                    return res
            else:
                plan.fused = None  # a member changed (a new target, trajectory): planned again at the next step
        if plan.critical:  # safety rows the fused step's answer broke (or it needs a QP): the template guards them
            return super().solve(robot, stack, t, dt)
        t0 = time.perf_counter()
        terms = stack.evaluate(robot, t)
        z, targets, bounds = plan.gather(robot, stack, terms, dt)  # gather_rows + fill, in one pass
        t1 = time.perf_counter()
        limits = self.limits
        prev = limits.previous(self._dq_prev)
        out = np.empty((7, 1, n))
        stats = np.empty((plan.meta.shape[1] - 1, 4))
        rows = plan.rows(plan.zero if z is None else z)
        try:
            status = HK.closed_step(rows, plan.params, robot.q, limits.kernel_args(robot), float(dt), prev, out, stats)
        except np.linalg.LinAlgError:  # non-finite rows (a NaN gradient): the template says where from
            return super().solve(robot, stack, t, dt)
        windowed = prev.shape[0] > 0
        if status != 1:  # a constraint is active (0), or q̇ is not finite (2): the template, on the same rows
            built = HQPBuild(
                lambda: plan.step_rows(terms, z, targets, bounds), limits.box_from(out[_BOX, 0], windowed), n,
                infeasible=status == 0, layout=layout, z=z, filled=status == 0, critical=False,
            )  # fmt: skip
            return self._finish(robot, stack, terms, built, t0, t1)
        kept = out[OUT_KEPT, 0]
        self._dq_hist = (kept, self._dq_prev)  # (a jerk limit switched on later reads the last two)
        self._dq_prev = kept

        def diagnostics() -> tuple[float, bool, dict[str, object]]:  # on first read of the result's diagnostics
            box = limits.box_from(out[_BOX, 0], windowed)
            built = HQPBuild(plan.step_rows(terms, z, targets, bounds), box, n, stats)
            diag = QPDiagnostics()
            diag.active_limits = box.active(kept, limits.joint_names)
            self._diagnose(built, kept, diag)
            return diag.sigma_min, bool(diag.damped_levels), diag.as_info()

        return LazyStepResult.make(
            out[OUT_DQ, 0],
            terms,
            None,
            {"backend": "closed-form", "qp": 0, "iterations": 0},
            t1 - t0,
            time.perf_counter() - t1,
            layout.main,
            diagnostics,
        )

    @staticmethod
    def _write_external_rows(plan: _Plan, fused: FusedPlan, external: list[TaskTerm | None]) -> None:
        """The rows of the members written from Python into the cascade's least-squares buffers, at the rows
        ``dest`` gives them (their J, v and weight), as the compiled call writes the others."""
        dest, A, b, w = plan.dest, plan.A, plan.b, plan.w
        for i, role, _, _, start, end, _ in fused.writes:
            term = external[i]
            if (role == ROW or role == TARGET) and term is not None and end > start:
                d = int(dest[start])  # (a member's rows are contiguous in the buffers: ``_Plan.lay_out``)
                e = d + end - start
                A[d:e] = term.J
                b[d:e] = term.v
                w[d:e] = term.weight

    def _fused_solve(
        self, robot: RobotModel, stack: TaskStack, plan: _Plan, fused: FusedPlan, t: float, dt: float
    ) -> StepResult | None:
        """:meth:`solve` of a fused stack (:mod:`redundik.resolvers.fused`): the bound subtasks' rows as
        :meth:`_Plan.gather` writes them, then one compiled call from Pinocchio's Jacobians through the rows to the
        unconstrained cascade and its tests (``hqp_fused.fused_hqp_step``); ``None`` when this step needs the
        per-task path (a rotation error beyond the compiled log3's range) or, with safety rows (a critical barrier:
        collision distances), when neither the closed form nor the native cascade gives a q̇ that keeps them (the
        template then solves, relaxes and guards them as without the fused step)."""
        t0 = time.perf_counter()
        n = robot._nv
        external: list[TaskTerm | None] | tuple[()] = ()
        direct = fused.direct_main and fused.direct_rows == fused.external_rows  # compiled row writers only:
        if direct:  # called below, straight into the step's blocks and the cascade's rows
            fused.pending_external = None
        elif fused.external:  # members without a compiled form: their rows and z terms from Python (before the
            evaluated = fused.pending_external  # bounds: a moved row count moves the levels' offsets)
            fused.pending_external = None
            if evaluated is None:
                evaluated = fused.evaluate_external(robot, t)
                if evaluated is None:
                    plan.fused = False
                    return None
                if fused.repacked:  # a row count moved: the buffers laid out again for the new counts
                    plan.lay_out(fused)
            external = evaluated
        packed = plan.packed_bounds(robot)
        if packed is None:
            bounds = plan.fused_bounds(robot, dt)
            bint, bcols, bfl = NO_BOUNDS
        else:  # their rows written in the compiled call
            bounds = plan.written_bounds(packed)
            bint, bcols, bfl = packed.bint, packed.bcols, packed.bfl
        limits = self.limits
        args = limits.kernel_args(robot)
        tail = self._coef_tail
        if tail[0] is not args:  # (a new tuple when the limits or their options changed: ``kernel_args``)
            tail = self._coef_tail = (args, (float(args[5]), float(args[6]), float(args[7])))
        coef = fused.coefficients(tail[1])
        refs = fused.given_references(t) if fused.given else fused.refs
        prev = limits.previous(self._dq_prev)
        K_, m, levels = len(fused.frames), fused.m, plan.meta.shape[1] - 1
        size = HFK.step_work_size(K_, m, n, levels)
        # out, Jf, ev, z, stats (and the compiled writers' J rows after them): one allocation
        work = np.zeros(size + sum(fused.external_rows) * n if direct else size)
        if fused.lie_joints or external or direct:  # (Python writes into e, z before the call: the first parts)
            ev, z = work[: 2 * m].reshape(2, m), work[2 * m : 2 * m + n]
            if fused.lie_joints:
                fused.write_joint_errors(robot, ev[0])
            if direct:
                Jx = work[size:].reshape(-1, n)
                external = fused.take_direct_level_rows(robot, t, plan.dest, (plan.A, plan.b, plan.w), ev, Jx)
            elif external and fused.plain_rows:  # a user's own tasks only: their blocks put straight into the buffers
                fused.put_plain_level_rows(external, plan.dest, plan.A, plan.b, plan.w, ev)
            elif external:
                fused.write_external(robot, external, None, 0, ev, None, z)
                self._write_external_rows(plan, fused, external)
        q = robot.q
        speed = self._limiter
        try:
            status, err2, dq2, over = HFK.fused_hqp_call(
                fused.jw, fused.poses, refs, float(t), float(dt), q, prev, fused.ints, fused.floats, plan.dest, bint,
                bcols, bfl, coef, args[0], fused.limits(args), _NO_CAPS if speed is None else speed.folded_caps(robot),
                plan.A, plan.b, plan.w, plan.C, plan.d, plan.meta, plan.params, work,
            )  # fmt: skip
        except np.linalg.LinAlgError:  # non-finite rows: the per-task path (it says where from)
            return None
        if status < 0.0:
            return None
        t1 = time.perf_counter()
        targets = fused.subtask_rows(external) if external and fused.has_targets else []
        windowed = prev.shape[0] > 0
        o = 2 * m + n  # (``out`` after (e, v) and z)
        dq = work[o + OUT_DQ * n : o + (OUT_DQ + 1) * n]
        if status != 1.0 or (plan.critical and not plan.keeps_safety_rows(dq)):
            views = functools.partial(HFK.step_work_views.py_func, work, K_, m, n, levels)
            make_terms = fused.terms_once(lambda: views()[3::-3], None, q, robot, external)  # parts 3, 0: (Jf, ev)
            _, z, out, _, _ = views()
            zs = z if plan.layout.has_null_objective else None
            return self._constrained_step(
                robot, stack, plan, status, out, windowed, (zs, targets), bounds, make_terms, err2, t0, t1
            )
        kept = work[o + OUT_KEPT * n : o + (OUT_KEPT + 1) * n]
        self._dq_hist = (kept, self._dq_prev)  # (a jerk limit switched on later reads the last two)
        self._dq_prev = kept
        dims = (K_, m, n, levels)
        step: tuple[Any, ...] = (plan, fused, work, dims, q, robot, external, targets, bounds, windowed, kept, [])
        return FusedHqpResult.of(self, dq, step, (err2, dq2, over), t0, t1)

    def _constrained_step(
        self,
        robot: RobotModel,
        stack: TaskStack,
        plan: _Plan,
        status: float,
        out: np.ndarray,
        windowed: bool,
        null: tuple[np.ndarray | None, list[tuple[np.ndarray, float]]],
        bounds: list[tuple[Any, Any, list[str]]],
        make_terms: Callable[[], list[TaskTerm]],
        err2: float,
        t0: float,
        t1: float,
    ) -> StepResult | None:
        """A fused step whose closed form is not the answer: a constraint is active (``status`` 0), q̇ is not finite
        (2), or it breaks a safety row. The native cascade's answer when it settles the step (and, with safety rows,
        keeps them); else the template's second half on the same rows — or, with safety rows, ``None``: the
        template's whole step, which solves, relaxes and guards them as without the fused step. ``null``: z of the
        null-space objective (or ``None``) and the target subtasks' rows (η, v), in level order."""
        zs, targets = null
        critical = plan.critical
        if status == 0.0:  # the native cascade settles most of these steps
            lb, ub = out[OUT_LB, 0], out[OUT_UB, 0]
            lean = self._native_cascade(plan, lb, ub, plan.zero if zs is None else zs)
            if lean is not None and finite(lean[0]):  # (a non-finite q̇ takes the template: it says where from)
                if not critical or plan.keeps_safety_rows(np.clip(lean[0], lb, ub)):
                    return self._native_result(plan, lean, out, windowed, null, bounds, make_terms, err2, t0, t1)
        if critical:
            return None
        n, box = plan.n, self.limits.box_from(out[_BOX, 0], windowed)
        if status != 0.0:  # q̇ not finite: the template, its terms at hand to say where from
            terms = make_terms()
            built = HQPBuild(
                lambda: plan.step_rows(terms, zs, targets, bounds), box, n, layout=plan.layout, z=zs, critical=False
            )
            return self._finish(robot, stack, terms, built, t0, t1)
        built = HQPBuild(
            lambda: plan.step_rows(make_terms(), zs, targets, bounds), box, n,
            infeasible=True, layout=plan.layout, z=zs, filled=True, critical=False,
        )  # fmt: skip
        # the constrained cascade; the terms are built only if read (or for a fallback), the task error is the
        # compiled call's
        dq, pending, fallback, relaxed, info, t2 = self._settle(robot, stack, make_terms, built)
        res = FusedStepResult.fused(
            dq, make_terms, math.sqrt(err2), info, t1 - t0, t2 - t1, plan.layout.main, pending, fallback=fallback
        )
        return with_relaxed(res, relaxed)

    def _native_result(
        self,
        plan: _Plan,
        lean: tuple[np.ndarray, np.ndarray, np.ndarray, int, int],
        out: np.ndarray,
        windowed: bool,
        null: tuple[np.ndarray | None, list[tuple[np.ndarray, float]]],
        bounds: list[tuple[Any, Any, list[str]]],
        make_terms: Callable[[], list[TaskTerm]],
        err2: float,
        t0: float,
        t1: float,
    ) -> StepResult:
        """The result of a fused step whose constrained cascade :meth:`_native_cascade` settled: what
        :meth:`_settle` makes of it — q̇ clipped to the limit box (both rows: returned and kept), the same info,
        the same diagnostics on first read — without the template's records."""
        x, qstats, rfac, nqp, iters = lean
        zs, targets = null
        lb, ub = out[OUT_LB, 0], out[OUT_UB, 0]
        clipped = np.empty((2, x.shape[0]))
        K.clip_twice(x, lb, ub, clipped)
        kept = clipped[1]
        self._dq_hist = (kept, self._dq_prev)  # (a jerk limit switched on later reads the last two)
        self._dq_prev = kept
        t2 = time.perf_counter()
        limits, name = self.limits, self.backend.name

        def diagnostics() -> tuple[float, bool, dict[str, object]]:  # on first read of the result's diagnostics
            box = limits.box_from(out[_BOX, 0], windowed)
            built = HQPBuild(plan.step_rows(make_terms(), zs, targets, bounds), box, plan.n, infeasible=True)
            built.qp_stats, built.qp_r = qstats, rfac
            diag = QPDiagnostics(backend=name, qp=nqp, iterations=iters)
            diag.active_limits = box.active(kept, limits.joint_names)
            self._diagnose(built, kept, diag)
            return diag.sigma_min, bool(diag.damped_levels), diag.as_info()

        return FusedStepResult.fused(
            clipped[0], make_terms, math.sqrt(err2), {"backend": name, "qp": nqp, "iterations": iters}, t1 - t0,
            t2 - t1, plan.layout.main, diagnostics,
        )  # fmt: skip

    def _resolve(self, built: HQPBuild, diag: QPDiagnostics) -> tuple[np.ndarray, str | None]:
        try:
            if not built.infeasible:
                x = self._lean_cascade(built, built.layout)
                if x is not None:
                    return x, None
            x, notes = self._qp_cascade(built, diag)
        except np.linalg.LinAlgError as exc:  # non-finite rows (a NaN gradient): the template's fallback names them
            raise SolverError(f"hqp: the rows are not finite ({exc})") from exc
        return x, ("hqp: " + "; ".join(notes)) if notes else None

    def _safety_rows(self, built: HQPBuild, stack: TaskStack) -> tuple[np.ndarray, np.ndarray] | None:
        if not built.critical:
            return None
        Cs, ds = [], []
        for ineq in built.rows.ineq:
            for C, d, _, bsub in ineq:
                if bsub.critical:
                    Cs.append(C)
                    ds.append(d)
        if not Cs:
            return None
        return (Cs[0], ds[0]) if len(Cs) == 1 else (np.vstack(Cs), np.concatenate(ds))

    def _diagnose(self, built: HQPBuild, dq: np.ndarray, diag: QPDiagnostics) -> None:
        """Per-level residuals at q̇ and, when the unconstrained cascade's answer was kept, its per-level σ_min,
        damping and rank loss (from the statistics the compiled cascade left; nothing of this runs on a step
        whose diagnostics are never read)."""
        levels = built.levels
        stats = built.stats
        if stats is not None and np.isnan(stats[:, HK.SIGMA_MIN]).any():
            # a level solved by its certified QR has no σ_min yet: the cascade once more, by SVD at every level
            plan = _Plan(built.rows.layout, built.n, np.array([self.epsilon, self.max_damping, self.rcond, 1e-12, 1.0]))
            plan.fill(built.rows)
            stats = np.empty_like(stats)
            z = built.rows.z if built.rows.z is not None else plan.zero
            box = built.box
            HK.closed_cascade(plan.rows(z), (box.lb, box.ub), plan.params, np.empty(built.n), stats)
        if stats is not None:
            projected = False
            for k, lv in enumerate(levels):
                rank = int(stats[k, HK.RANK])
                if rank < 0:
                    continue
                smin, damping, r = float(stats[k, HK.SIGMA_MIN]), float(stats[k, HK.DAMPING]), int(stats[k, HK.FREE])
                self._record(lv, smin, damping, rank, r, projected, diag)
                projected = True
        qs = built.qp_stats
        if qs is not None:  # the constrained cascade's records, level by level
            for k, lv in enumerate(levels):
                if qs[k, HK.QS_SOLVED]:
                    sigma, rank = float(qs[k, HK.QS_SIGMA]), int(qs[k, HK.QS_RANK])
                    if math.isnan(sigma) and built.qp_r is not None:  # factored by its certified QR: R's σ_min
                        R = built.qp_r[k, : rank * rank].reshape(rank, rank)
                        sigma = float(np.linalg.svd(R, compute_uv=False)[-1])
                    self._record(
                        lv, sigma, float(qs[k, HK.QS_DAMPING]), rank, int(qs[k, HK.QS_FREE]),
                        bool(qs[k, HK.QS_PROJECTED]), diag,
                    )  # fmt: skip
        for lv in levels:
            diag.level_residuals[lv.priority] = lv.residual(dq)

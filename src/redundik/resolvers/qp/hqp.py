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
subtasks, with bound subtasks but no target subtask, skips the tasks' ``evaluate``: one compiled call
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
records are built only for a contradiction's row names and for the diagnostics. A QP step of the 10-joint snake
300 → 72 µs (its Python cascade is the reference of ``tests/test_hqp_lean.py``). With daqp as the backend the
cascade calls daqp's C entry point itself (:mod:`redundik.resolvers.qp.daqp_native`) and goes on at once; a QP
daqp does not solve at once comes back here for the retries (72 → ~50 µs). A least-squares level of m ≤ r rows
whose QR (A_k Z)ᵀ = Q [R; 0] certifies σ_min ≥ ε (``certified_qr``; nothing damped, full rank) takes Q₂ as its
null basis and the ridge û from R (``hqp_kernels._ridge_triangular``, no normal equations) instead of the SVD —
another orthonormal basis of the same space, so the same level optima, q̇ to the level QPs' conditioning; its σ_min
comes from R's singular values when the diagnostics are read (the snake's 6 × 10 level 7.3 → 2.3 µs, its
compiled QP cascade 21 → 16 µs); in the complement mode the thin QR's Q₁ᵀ gives the level's fixed directions
(``hqp_kernels._certified_rows``: the 40-joint snake's QP cascade 38 → 20 µs, measured on captured steps).
A fused step whose cascade daqp settles entirely from the compiled call, no level contradicted, keeps nothing of
the template but that call and the clipping (``_native_cascade``, ``_native_result``: no HQPBuild, limit box or
QPDiagnostics until the diagnostics are read; the same q̇ and info bit for bit, ``tests/test_hqp_buffers.py``; the
snake's QP step 54 → 50 µs); anything else runs the template from the start.
Complement mode (exact, large robots): below a least-squares level that leaves few directions fixed (at most a third
of nv, from nv ≥ ``complement_min_n`` = 40 on), the cascade keeps W, an orthonormal basis of the fixed directions,
instead of Z (null(W) = range(Z)), and poses each level QP over y = Z u in joint space: the joint limits become
simple bounds on y instead of 2·nv rows of Z, W y = 0 and the lifted least squares s = A_k y are equalities, the
Hessian stays diagonal (``hqp_kernels.level_qp_joint_into``); ‖u‖ = ‖y‖ and A_k Z u = A_k y on null(W), so the
QP and its optimum are the same, and no null basis is ever formed (its full SVD was 100 µs of the 160-joint
snake's step). A QP step of the 160-joint snake 660 → 365 µs.

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

import math
import time
import weakref
from collections.abc import Callable
from dataclasses import replace
from typing import Any, NamedTuple

import numpy as np

from redundik._coldstart import ready
from redundik.errors import SolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import LazyStepResult, StepResult
from redundik.resolvers.fused import (
    B_AXES,
    B_CENTER,
    B_FID,
    B_LO,
    B_LOWER,
    B_NAXES,
    B_RADIUS,
    B_RATE,
    B_ROW,
    B_UP,
    B_UPPER,
    ROW,
    FusedPlan,
    FusedStepResult,
)
from redundik.resolvers.hqp_layout import (
    H_FRAME_STARTS,
    H_J,
    H_JOINT_STARTS,
    H_K,
    META_INEQ,
    META_KIND,
    META_LS,
    OUT_DQ,
    OUT_KEPT,
    OUT_LB,
    OUT_POS_HI,
    OUT_UB,
)
from redundik.resolvers.linalg import K, _Kernels
from redundik.resolvers.qp.backends import CHECKED_ANSWERS, DEFAULT_BACKEND, Backend, DaqpBackend, finite, polish
from redundik.resolvers.qp.base import LevelsOption, LimitsOption, QPDiagnostics, QPResolverBase, with_relaxed
from redundik.resolvers.qp.daqp_native import NativeDaqp
from redundik.resolvers.qp.direction import DirectionScaling, solve_direction
from redundik.resolvers.qp.limits import LimitBox
from redundik.resolvers.qp.problem import QPProblem, QPSolution
from redundik.resolvers.qp.terms import Level, StepRows, gather_rows
from redundik.resolvers.settings import Setting, count, flag, nonnegative, positive, unit_interval
from redundik.resolvers.singularity import SingularityGuard
from redundik.tasks.base import Edits, TaskTerm
from redundik.tasks.stack import StackLayout, TaskStack
from redundik.tasks.subtasks import BoundSubtask

#: Slack above which a level's bound rows count as contradicted (reported in ``StepResult.relaxed``).
CONTRADICTION_TOLERANCE = 1e-6
#: Defaults of ``HierarchicalQPResolver.complement_min_n`` and ``complement_fraction`` (joint-space level QPs from
#: this many joints on, below levels that leave at most a third of the directions fixed).
COMPLEMENT_MIN_N, COMPLEMENT_FRACTION = 40, 3.0


#: :mod:`redundik.resolvers.hqp_kernels`, imported on first use (numba loads then, not when redundik is imported).
HK = _Kernels("hqp_kernels")
#: :mod:`redundik.resolvers.hqp_fused` (the fused step), imported on first use.
HFK = _Kernels("hqp_fused")
_NO_BASIS = np.zeros((0, 0))
_BOX = slice(OUT_LB, OUT_POS_HI + 1)  # the limit box's rows of ``closed_step``'s out
_NO_SELECTION = np.zeros(0, dtype=np.int64)
_NO_U = np.zeros(0)
_NO_NATIVE = np.zeros(0, dtype=np.int64)
#: Violation up to which a level QP's unconstrained optimum counts as satisfying the QP's rows (kept without a QP).
_FEASIBLE = 1e-12


class HQPBuild:
    """A built ``hqp`` step: its rows as evaluated, the joint-limit box, and what the lean cascade left.

    Attributes:
        rows: Every level's rows (:class:`~redundik.resolvers.qp.terms.StepRows`; given, or built on first access
            from a callable); :attr:`levels` stacks them.
        box: The joint-limit box of the step.
        n: Number of velocity coordinates.
        stats: Per level (σ_min, λ, rank, free directions before it) of the unconstrained cascade when its answer
            was kept (:func:`redundik.resolvers.hqp_kernels.closed_cascade`), else ``None``; read by the
            diagnostics only.
        infeasible: True when the unconstrained cascade was already found infeasible (the lean step): straight to
            the QPs.
        layout: The stack's layout; z: the null-space objective's target (``None`` without one) — the rows' own.
        filled: True when the plan's buffers already hold these rows (the lean step wrote them there: the
            constrained cascade reads them as they are, without :meth:`_Plan.fill`).
        critical: False when no bound subtask is critical (no safety rows to guard: the rows need not be built for
            them).
        qp_stats: Per level the constrained cascade's records (``hqp_kernels.QS_*``), read by the diagnostics;
            ``None`` when the step solved no constrained cascade.
        qp_r: Per level the R of its certified QR (``qp_cascade_run``'s ``rfac``; σ_min NaN in ``qp_stats``), the
            singular values of the level for the diagnostics.
    """

    __slots__ = ("_make_rows", "_rows", "box", "critical", "filled", "infeasible", "layout", "n", "qp_r",
                 "qp_stats", "stats", "z")  # fmt: skip

    def __init__(
        self,
        rows: StepRows | Callable[[], StepRows],
        box: LimitBox,
        n: int,
        stats: np.ndarray | None = None,
        infeasible: bool = False,
        *,
        layout: StackLayout | None = None,
        z: np.ndarray | None = None,
        filled: bool = False,
        critical: bool = True,
    ) -> None:
        if isinstance(rows, StepRows):
            self._rows: StepRows | None = rows
            self._make_rows: Callable[[], StepRows] | None = None
            self.layout: StackLayout = rows.layout
            self.z: np.ndarray | None = rows.z
        else:
            if layout is None:
                raise TypeError("HQPBuild: rows given as a callable need their layout")
            self._rows, self._make_rows, self.layout, self.z = None, rows, layout, z
        self.box, self.n, self.stats, self.infeasible = box, n, stats, infeasible
        self.filled, self.critical = filled, critical
        self.qp_stats: np.ndarray | None = None
        self.qp_r: np.ndarray | None = None

    @property
    def rows(self) -> StepRows:
        rows = self._rows
        if rows is None:
            assert self._make_rows is not None
            rows = self._rows = self._make_rows()
            self._make_rows = None
        return rows

    @property
    def levels(self) -> list[Level]:
        """The levels as :class:`~redundik.resolvers.qp.terms.Level` records (built on first access)."""
        return self.rows.levels


class _Written:
    """The damper rows one :meth:`_Plan.gather` wrote into the plan's buffers, for :meth:`_Plan.step_rows`: their
    copies, taken when first asked or before the buffers are next written while this record is still held (the
    step's lazy diagnostics hold it), never otherwise."""

    __slots__ = ("C", "__weakref__", "d")

    def __init__(self) -> None:
        self.C: np.ndarray | None = None
        self.d: np.ndarray | None = None


class _Packed(NamedTuple):
    """Bound subtasks packed for ``hqp_fused.clearance_rows`` (:meth:`_Plan.packed_bounds`)."""

    bint: np.ndarray  # (B, B_AXES + 3) integers per bound (``fused_kernels.B_FID`` …)
    bcols: np.ndarray  # (B, nv) the columns of the joints supporting each frame
    bfl: np.ndarray  # (B, B_RATE + 1) numbers per bound (``fused_kernels.B_CENTER`` …)
    offsets: list[tuple[int, int]]  # the offsets table (least-squares row, inequality row) per level
    slices: list[tuple[slice, list[str]]]  # per bound its rows of C, d and their names
    rows: int  # the rows of C, d written


#: No packed bounds (``hqp_fused.fused_hqp_step``'s arguments when :meth:`_Plan.fused_bounds` wrote the rows).
_NO_BOUNDS = (np.zeros((0, B_AXES + 3), dtype=np.int64), np.zeros((0, 0), dtype=np.int64), np.zeros((0, B_RATE + 1)))


class _Plan:
    """What the lean cascade does per level, fixed while the stack's membership is (see ``_plan_for``): the level
    kinds, the offsets table and the buffers the rows are copied into (grown when a level brings more rows)."""

    def __init__(self, layout: StackLayout, n: int, params: np.ndarray) -> None:
        self.layout, self.n, self.params = layout, n, params
        L = len(layout.levels)
        self.meta = np.zeros((3, L + 1), dtype=np.int64)
        self.mixed: list[bool] = []  # a level with rows of its own and the null-space objective: + identity rows
        for k, plan in enumerate(layout.levels):
            has_rows = bool(plan.tasks or plan.targets)
            has_z = plan.null_objective and layout.has_null_objective
            self.meta[META_KIND, k] = HK.LEAST_SQUARES if has_rows else (HK.NULL_OBJECTIVE if has_z else HK.SKIP)
            self.mixed.append(has_rows and has_z)
        self.mixed_flags = np.array(self.mixed, dtype=np.bool_)
        self.A, self.b, self.w = np.zeros((16, n)), np.zeros(16), np.ones(16)
        self.C, self.d = np.zeros((4, n)), np.zeros(4)
        self.eye, self.zero = np.eye(n), np.zeros(n)
        self.critical = any(b.critical for level in layout.levels for b in level.bounds)  # safety rows: template
        self._weights: list[tuple[int, int, float]] = []  # per block (first row, end, weight) last written into w
        #: Per level, what :meth:`gather` evaluates: (task indices, target subtasks, bound subtasks, whether the level
        #: carries the null-space objective, whether it adds the objective's identity rows after its own).
        self.members = [
            (list(lv.tasks), list(lv.targets), list(lv.bounds), lv.null_objective, mixed)
            for lv, mixed in zip(layout.levels, self.mixed, strict=True)
        ]
        self._offsets: list[tuple[int, int]] = []  # the offsets gather last wrote into meta
        #: The fused form of the stack (:meth:`fuse`): ``None`` not planned yet, False none.
        self.fused: FusedPlan | str | bool | None = None
        self.dest = np.zeros(0, dtype=np.int64)  # per fused row its row of A, then the mixed levels' first rows
        self.ls_offsets: list[int] = []
        self._written: tuple[weakref.ref[_Written], int] | None = None  # the last gather's record, its rows
        self._cascade: tuple[np.ndarray, ...] | None = None  # the constrained cascade's work arrays
        self._qp_buf = np.zeros(0)  # where the cascade writes a level QP (``hqp_kernels.level_qp_into``)
        self._qp_views: dict[tuple[int, int], tuple[np.ndarray, ...]] = {}  # its views, per (variables, rows)
        self._native: NativeDaqp | None = None  # daqp's C call from the cascade (``daqp_native``)
        self.r_size = 0  # m² of the level of most least-squares rows (``qp_arrays``): a row of the cascade's rfac
        #: (the ``_offsets`` they were read for, most variables and rows of a level QP, inequality rows in all) of
        #: :meth:`qp_arrays`: read again only when meta was rewritten
        self._dims: tuple[object, int, int, int] | None = None
        #: (Edits.count, robot data) the bound subtasks were packed for, and the packing (``packed_bounds``)
        self._packed_key: tuple[int, Any] | None = None
        self._packed: _Packed | None = None

    def __getstate__(self) -> dict[str, Any]:
        """The plan without its weak reference to the last gather's record (a copy holds no step's rows): a copy
        or a pickle of a resolver steps as the original."""
        state = self.__dict__.copy()
        state["_written"] = None
        return state

    def _keep_written(self) -> None:
        """Before the buffers are written again: copy the last gather's damper rows if their record is held."""
        last = self._written
        if last is not None:
            self._written = None
            held = last[0]()
            if held is not None and held.C is None:
                held.C, held.d = self.C[: last[1]].copy(), self.d[: last[1]].copy()

    def gather(
        self, robot: RobotModel, stack: TaskStack, terms: list[TaskTerm], dt: float
    ) -> tuple[np.ndarray | None, list[tuple[np.ndarray, float]], list[tuple[Any, Any, list[str]]]]:
        """The step's rows straight into the buffers, as ``gather_rows`` followed by :meth:`fill` would lay them
        (the members evaluated in the same order, the same rows, weights and offsets), without building the
        per-level lists. A bound subtask on a potential writes its damper rows (C = −η, d = γ(p − lower) for a lower
        bound, the velocity damper of ``BoundSubtask.rows_into``, the one implementation) into the buffers itself;
        those rows are copied (for :meth:`step_rows`, which may be asked after the buffers were reused) only when
        asked, or before the buffers are next written while this step's record of them is still held.

        Returns:
            (z of the null-space objective or ``None``, the target subtasks' (η, v) in layout order, the bound
            subtasks' (C, d, row names) in layout order — for rows written by ``rows_into``, (their
            :class:`_Written` record, the rows' slice, names)): what :meth:`step_rows` needs to build the step's
            :class:`~redundik.resolvers.qp.terms.StepRows` when it is asked for.
        """
        if self._written is not None:
            self._keep_written()
        meta, n, key = self.meta, self.n, self._weights
        A, b, w = self.A, self.b, self.w
        targets: list[tuple[np.ndarray, float]] = []
        bounds: list[tuple[Any, Any, list[str]]] = []  # (C, d, names), or (written, rows' slice, names)
        written: _Written | None = None  # the record of the rows written by rows_into
        z = None
        ms = cs = 0
        blk = 0
        offsets = []  # per level (first least-squares row, first inequality row): written into meta when they move
        for tasks, subs, bsubs, null_objective, mixed in self.members:
            offsets.append((ms, cs))
            for i in tasks:
                term = terms[i]
                J = term.J
                e = ms + J.shape[0]
                if e > A.shape[0]:
                    A, b, w = self._grow_ls(e)
                A[ms:e] = J
                b[ms:e] = term.v
                weight = term.weight
                if blk >= len(key) or key[blk] != (ms, e, weight):
                    w[ms:e] = weight
                    key[blk:] = [(ms, e, weight)]
                blk += 1
                ms = e
            for sub in subs:
                eta, vt, _ = sub.row(robot)
                targets.append((eta, vt))
                e = ms + 1
                if e > A.shape[0]:
                    A, b, w = self._grow_ls(e)
                A[ms] = eta
                b[ms] = vt
                weight = sub.weight
                if blk >= len(key) or key[blk] != (ms, e, weight):
                    w[ms:e] = weight
                    key[blk:] = [(ms, e, weight)]
                blk += 1
                ms = e
            if bsubs:
                cs, written = self._bound_rows(robot, dt, bsubs, cs, bounds, written)
            if null_objective:
                z = stack.null_target(robot, terms, self.layout)
            if mixed and z is not None:
                e = ms + n
                if e > A.shape[0]:
                    A, b, w = self._grow_ls(e)
                b[ms:e] = z
                if blk >= len(key) or key[blk] != (ms, e, -1.0):
                    A[ms:e] = self.eye
                    w[ms:e] = 1.0
                    key[blk:] = [(ms, e, -1.0)]
                blk += 1
                ms = e
        offsets.append((ms, cs))
        if written is not None:
            self._written = (weakref.ref(written), cs)
        if offsets != self._offsets:
            for k, (ls_row, ineq_row) in enumerate(offsets):
                meta[META_LS, k], meta[META_INEQ, k] = ls_row, ineq_row
            self._offsets = offsets
        return z, targets, bounds

    def _bound_rows(
        self,
        robot: RobotModel,
        dt: float,
        bsubs: list[BoundSubtask],
        cs: int,
        bounds: list[tuple[Any, Any, list[str]]],
        written: _Written | None,
    ) -> tuple[int, _Written | None]:
        """A level's bound subtasks' rows into C, d from row ``cs`` (:meth:`gather`'s, appended to ``bounds``);
        returns the next row and the record of the rows written by ``rows_into``."""
        C, d = self.C, self.d
        for bsub in bsubs:
            k = bsub.fixed_rows
            if k is not None:  # a potential's damper rows, written into the buffers by the subtask itself
                e = cs + k
                if e > C.shape[0]:
                    C, d = self._grow_ineq(e)
                bsub.rows_into(robot, dt, C, d, cs)
                if written is None:
                    written = _Written()
                bounds.append((written, slice(cs, e), bsub.row_names))
                cs = e
                continue
            Ci, di, rn = bsub.rows(robot, dt)
            bounds.append((Ci, di, rn))
            e = cs + Ci.shape[0]
            if e > C.shape[0]:
                C, d = self._grow_ineq(e)
            C[cs:e] = Ci
            d[cs:e] = di
            cs = e
        return cs, written

    def fused_bounds(self, robot: RobotModel, dt: float) -> list[tuple[Any, Any, list[str]]]:
        """The bound subtasks' rows into C, d and the offsets table, for a fused step (:meth:`fuse`): the
        least-squares rows are the compiled call's, at the offsets :meth:`fuse` laid out; :meth:`gather`'s
        ``bounds``."""
        if self._written is not None:
            self._keep_written()
        meta = self.meta
        bounds: list[tuple[Any, Any, list[str]]] = []
        written: _Written | None = None
        cs = 0
        offsets = []
        for (_, _, bsubs, _, _), ls_row in zip(self.members, self.ls_offsets, strict=False):
            offsets.append((ls_row, cs))
            if bsubs:
                cs, written = self._bound_rows(robot, dt, bsubs, cs, bounds, written)
        offsets.append((self.ls_offsets[-1], cs))
        if written is not None:
            self._written = (weakref.ref(written), cs)
        if offsets != self._offsets:
            for k, (ls_row, ineq_row) in enumerate(offsets):
                meta[META_LS, k], meta[META_INEQ, k] = ls_row, ineq_row
            self._offsets = offsets
        return bounds

    def packed_bounds(self, robot: RobotModel) -> _Packed | None:
        """The bound subtasks packed for the fused step's compiled damper rows (``hqp_fused.clearance_rows``),
        when every one gives its ``clearance_form`` (a bound on a clearance, read through verified views of
        Pinocchio's memory, as the fused step reads it); ``None``: :meth:`fused_bounds` evaluates them in Python.
        Packed again when ``Edits`` moved (an assigned centre, radius, frame, axes, bound, rate or name) or for
        another robot's data."""
        key = self._packed_key
        if key is not None and key[0] == Edits.count and key[1] is robot.data:
            return self._packed
        self._packed = self._pack_bounds(robot)
        self._packed_key = (Edits.count, robot.data)
        return self._packed

    def _pack_bounds(self, robot: RobotModel) -> _Packed | None:
        """:meth:`packed_bounds`' packing: the rows C, d of :meth:`fused_bounds`, laid out at the same offsets."""
        bsubs = [bsub for _, _, bs, _, _ in self.members for bsub in bs]
        forms = [bsub.clearance_form(robot) for bsub in bsubs]
        if any(form is None for form in forms):  # another source, rows of its own, unverified views: Python rows
            return None
        n = self.n
        bint = np.zeros((len(bsubs), B_AXES + 3), dtype=np.int64)
        bcols = np.zeros((len(bsubs), n), dtype=np.int64)
        bfl = np.zeros((len(bsubs), B_RATE + 1))
        slices: list[tuple[slice, list[str]]] = []
        offsets = []
        cs = k = 0
        for (_, _, bs, _, _), ls_row in zip(self.members, self.ls_offsets, strict=False):
            offsets.append((ls_row, cs))
            for bsub in bs:
                form = forms[k]
                assert form is not None  # (checked above)
                rows = form.rows
                lower, upper = bsub.lower, bsub.upper
                bint[k, [B_FID, B_ROW, B_LOWER, B_UPPER, B_NAXES]] = (
                    form.fid,
                    cs,
                    lower is not None,
                    upper is not None,
                    rows.shape[0],
                )
                bint[k, B_AXES : B_AXES + rows.shape[0]] = rows
                bcols[k] = form.columns
                bfl[k, B_CENTER : B_CENTER + 3] = form.center
                bfl[k, [B_RADIUS, B_LO, B_UP, B_RATE]] = (
                    form.radius,
                    0.0 if lower is None else lower,
                    0.0 if upper is None else upper,
                    bsub.rate,
                )
                e = cs + (lower is not None) + (upper is not None)
                slices.append((slice(cs, e), bsub.row_names))
                cs, k = e, k + 1
        offsets.append((self.ls_offsets[-1], cs))
        if cs > self.C.shape[0]:
            self._grow_ineq(cs)
        return _Packed(bint, bcols, bfl, offsets, slices, cs)

    def written_bounds(self, packed: _Packed) -> list[tuple[Any, Any, list[str]]]:
        """:meth:`fused_bounds` for packed bounds, whose rows the compiled call writes: the offsets table, the
        previous record's rows kept if held, and this step's record (``bounds`` of :meth:`gather`)."""
        if self._written is not None:
            self._keep_written()
        if self._offsets is not packed.offsets:
            if self._offsets != packed.offsets:
                for k, (ls_row, ineq_row) in enumerate(packed.offsets):
                    self.meta[META_LS, k], self.meta[META_INEQ, k] = ls_row, ineq_row
            self._offsets = packed.offsets
        if not packed.slices:
            return []
        written = _Written()
        self._written = (weakref.ref(written), packed.rows)
        return [(written, sl, names) for sl, names in packed.slices]

    def fuse(self, robot: RobotModel, stack: TaskStack, t: float = 0.0) -> FusedPlan | str | bool:
        """The fused form of this plan's stack (:mod:`redundik.resolvers.fused`): every task a frame task or a
        joint-space task, no target subtask (bound subtasks are evaluated as :meth:`gather` does); the rows of
        its least-squares buffers each fused row goes to (``dest``, :func:`hqp_fused.fused_hqp_step`). Returns
        the plan, ``FusedPlan.NOT_YET`` or False (the per-task path)."""
        layout = self.layout
        if any(level.targets for level in layout.levels):
            return False
        null = set(layout.null_tasks)
        scales = {i: (1.0, bool(task.identity_jacobian)) for i, task in enumerate(stack.tasks) if i not in null}
        built = FusedPlan.build(robot, stack, layout, scales, 1.0, mixed=True)
        if not isinstance(built, FusedPlan):
            return False if built is None else built
        if any(role == ROW for role, _, _ in built.external):  # their row counts size the buffers: evaluated now,
            terms = built.evaluate_external(robot, t)  # and these terms used by this step (no second evaluate)
            if terms is None:
                return False
            built.pending_external = terms
        self.lay_out(built)
        return built

    def lay_out(self, built: FusedPlan) -> None:
        """The rows of the least-squares buffers each row of the fused plan ``built`` goes to (``dest``) and the
        levels' first rows (``ls_offsets``), for its row counts now; again whenever a Python-written member's row
        count moves (the bound subtasks are packed again for the new offsets)."""
        ints = built.ints
        K, J = int(ints[H_K]), int(ints[H_J])
        starts = ints[ints[H_FRAME_STARTS] : ints[H_FRAME_STARTS] + K + 1].tolist()
        jstarts = ints[ints[H_JOINT_STARTS] : ints[H_JOINT_STARTS] + J + 1].tolist()
        mf = starts[K]
        spans: dict[int, tuple[int, int]] = {}
        for i, (kind, k) in enumerate(built.order):
            if kind == "f":
                spans[i] = (starts[k], starts[k + 1])
            elif kind == "j":
                spans[i] = (mf + jstarts[k], mf + jstarts[k + 1])
        rows_of = iter(zip(built.external_starts, built.external_rows, strict=True))
        for role, member, _ in built.external:
            if role == ROW:
                a, r = next(rows_of)
                spans[built.index[id(member)]] = (a, a + r)
        dest = [0] * built.m
        mixed_starts: list[int] = []
        ls_offsets = []
        ms = 0
        for tasks, _, _, _, mixed in self.members:
            ls_offsets.append(ms)
            for i in tasks:
                a, e = spans[i]
                dest[a:e] = range(ms, ms + e - a)
                ms += e - a
            if mixed:
                mixed_starts.append(ms)
                ms += self.n
        ls_offsets.append(ms)
        if ms > self.A.shape[0]:
            self._grow_ls(ms)
        self._weights = []  # the fused call writes the weights and identity rows: gather rewrites them after
        self.dest = np.array(dest + mixed_starts, dtype=np.int64)
        self.ls_offsets = ls_offsets
        self._packed_key = None  # (the packed bounds hold the levels' offsets)

    def step_rows(
        self,
        terms: list[TaskTerm],
        z: np.ndarray | None,
        targets: list[tuple[np.ndarray, float]],
        bounds: list[tuple[Any, Any, list[str]]],
    ) -> StepRows:
        """The :class:`~redundik.resolvers.qp.terms.StepRows` that ``gather_rows`` gives for the rows :meth:`gather`
        evaluated (the same arrays, grouped per level)."""
        n = self.n
        ls: list[list[tuple[np.ndarray, np.ndarray, float]]] = []
        ineq: list[list[tuple[np.ndarray, np.ndarray, list[str], BoundSubtask]]] = []
        it, ib = iter(targets), iter(bounds)
        for tasks, subs, bsubs, _, _ in self.members:
            blocks = [(terms[i].J, terms[i].v, terms[i].weight) for i in tasks]
            for sub in subs:
                eta, vt = next(it)
                blocks.append((eta.reshape(1, n), np.array([vt]), sub.weight))
            ls.append(blocks)
            rows = []
            for bsub in bsubs:
                Ci, di, rn = next(ib)
                if type(di) is slice:  # rows written by rows_into: their copies, as rows() gives them
                    held = Ci
                    if held.C is None:  # the buffers still hold this step's rows (_keep_written)
                        self._keep_written()
                    Ci, di = held.C[di], held.d[di]
                rows.append((Ci, di, list(rn), bsub))
            ineq.append(rows)
        return StepRows(self.layout, terms, ls, ineq, z, n)

    def fill(self, rows: StepRows) -> None:
        """Copy the step's rows into the buffers and write the offsets table (row 0: A, row 1: C); the weights and
        identity rows are rewritten only where they changed since the last step."""
        if self._written is not None:
            self._keep_written()
        meta, n, key = self.meta, self.n, self._weights
        A, b, w, C, d = self.A, self.b, self.w, self.C, self.d
        ms = cs = 0
        blk = 0
        for k, (blocks, ineq) in enumerate(zip(rows.ls, rows.ineq, strict=True)):
            meta[META_LS, k], meta[META_INEQ, k] = ms, cs
            for J, v, weight in blocks:
                e = ms + J.shape[0]
                if e > A.shape[0]:
                    A, b, w = self._grow_ls(e)
                A[ms:e] = J
                b[ms:e] = v
                if blk >= len(key) or key[blk] != (ms, e, weight):
                    w[ms:e] = weight
                    key[blk:] = [(ms, e, weight)]
                blk += 1
                ms = e
            if self.mixed[k] and rows.z is not None:
                e = ms + n
                if e > A.shape[0]:
                    A, b, w = self._grow_ls(e)
                b[ms:e] = rows.z
                if blk >= len(key) or key[blk] != (ms, e, -1.0):
                    A[ms:e] = self.eye
                    w[ms:e] = 1.0
                    key[blk:] = [(ms, e, -1.0)]
                blk += 1
                ms = e
            for Ci, di, _, _ in ineq:
                e = cs + Ci.shape[0]
                if e > C.shape[0]:
                    C, d = self._grow_ineq(e)
                C[cs:e] = Ci
                d[cs:e] = di
                cs = e
        L = meta.shape[1] - 1
        meta[META_LS, L], meta[META_INEQ, L] = ms, cs
        self._offsets = []  # (meta written here: gather rewrites it)

    def _grow_ls(self, rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        cap = max(rows, 2 * self.A.shape[0])
        # the rows written so far are copied: what ``_weights`` records still holds
        self.A = np.concatenate([self.A, np.zeros((cap - self.A.shape[0], self.n))])
        self.b = np.concatenate([self.b, np.zeros(cap - self.b.shape[0])])
        self.w = np.concatenate([self.w, np.ones(cap - self.w.shape[0])])
        return self.A, self.b, self.w

    def rows(self, z: np.ndarray) -> tuple[np.ndarray, ...]:
        """The cascade's rows record (A, b, w, C, d, z, meta) of the kernels (``hqp_layout.CascadeRows``), with the
        null-space objective's target ``z``."""
        return self.A, self.b, self.w, self.C, self.d, z, self.meta

    def cascade_buffers(self, rows: int) -> tuple[np.ndarray, ...]:
        """The constrained cascade's work arrays (Z, N, the fixed rows F, f, their slacks, its state, the free-joint
        mask and indices), kept between steps and grown to ``rows`` inequality rows; the cascade's first call
        initialises what it reads."""
        bufs = self._cascade
        if bufs is None or bufs[2].shape[0] < max(rows, 1):
            n, cap = self.n, max(rows, 1, 2 * (bufs[2].shape[0] if bufs is not None else 0))
            bufs = self._cascade = (
                np.zeros((n, n)), np.empty((n, n)), np.empty((cap, n)), np.empty(cap), np.zeros(cap),
                np.zeros(9, dtype=np.int64), np.ones(n, dtype=np.bool_), np.zeros(n, dtype=np.int64),
            )  # fmt: skip
        return bufs

    def qp_arrays(self, backend: Backend) -> tuple[np.ndarray, NativeDaqp | None]:
        """The level QPs' buffer, grown to the largest level QP of the rows now in ``meta`` (``hqp_kernels.
        cascade_qp_dims``; growing it forgets the views of :meth:`qp_views`), and, for daqp as ``backend``, the arrays
        through which the cascade calls daqp itself (:mod:`redundik.resolvers.qp.daqp_native`; ``None`` when that
        call is off)."""
        dims = self._dims
        if dims is None or dims[0] is not self._offsets:  # meta rewritten since (its writers renew _offsets)
            nvar, nr, m_max = HK.cascade_qp_dims(self.n, self.meta)
            L = self.meta.shape[1] - 1
            dims = self._dims = (self._offsets, nvar, nr, int(self.meta[META_INEQ, L]))
            self.r_size = m_max * m_max
            size = nvar * nvar + nvar + nr * nvar + 2 * (nvar + nr)
            if self._qp_buf.shape[0] < size:
                self._qp_buf = np.empty(max(size, 2 * self._qp_buf.shape[0]))
                self._qp_views = {}
        nvar, nr = dims[1], dims[2]
        if type(backend) is not DaqpBackend:
            return self._qp_buf, None
        native = self._native
        if native is None or not native.serves(backend, nvar, nr):
            native = self._native = NativeDaqp.for_backend(backend, nvar, nr, native)
        return self._qp_buf, native

    def qp_views(self, nvar: int, nr: int) -> tuple[np.ndarray, ...]:
        """(P, q, G, upper, lower) of the level QP in the buffer (``hqp_kernels.qp_views``), kept per size: the
        same few sizes come back step after step."""
        views = self._qp_views.get((nvar, nr))
        if views is None:
            views = self._qp_views[(nvar, nr)] = HK.qp_views(self._qp_buf, nvar, nr)
        return views

    def _grow_ineq(self, rows: int) -> tuple[np.ndarray, np.ndarray]:
        cap = max(rows, 2 * self.C.shape[0])
        self.C = np.concatenate([self.C, np.zeros((cap - self.C.shape[0], self.n))])
        self.d = np.concatenate([self.d, np.zeros(cap - self.d.shape[0])])
        return self.C, self.d


class HierarchicalQPResolver(DirectionScaling, QPResolverBase):
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
    epsilon = Setting(nonnegative, resets=("_plan", "_cfg"))
    max_damping = Setting(nonnegative, resets=("_plan", "_cfg"))
    regularization = Setting(positive, resets=("_cfg",))
    rcond = Setting(unit_interval, resets=("_plan", "_cfg"))
    slack_tolerance = Setting(nonnegative, resets=("_cfg",))
    level_shortcut = Setting(flag, resets=("_cfg",))
    identity_levels = Setting(flag, resets=("_cfg",))
    complement_min_n = Setting(count, resets=("_cfg",))
    complement_fraction = Setting(nonnegative, resets=("_cfg",))
    certified_qr = Setting(flag, resets=("_cfg",))
    fuse = Setting(flag, resets=("_plan",))  # (whether the stack is fused is the plan's)

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

    def _plan_for(self, layout: StackLayout, n: int) -> _Plan:
        """The lean cascade's plan and buffers, laid out once per stack membership (the layout object) and size."""
        plan = self._plan
        if plan is None or plan.layout is not layout or plan.n != n:
            params = np.array([self.epsilon, self.max_damping, self.rcond, 1e-12, 0.0])
            plan = self._plan = _Plan(layout, n, params)
        return plan

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
            if rank < min(int(np.linalg.matrix_rank(lv.ls_rows()[0])), r):
                diag.rank_loss_levels.append(lv.priority)

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

    def _regularized_retry(
        self, prob: QPProblem, r: int, eps: float, diag: QPDiagnostics, failed: SolverError | None = None
    ) -> QPSolution:
        """Solve a level QP the backend refused, with a stronger minimum-norm regulariser on u.

        Dual active-set solvers (daqp) work with P⁻¹ and can misjudge a level whose u-block is regularised by 1e-9
        only as infeasible (every level below 0 is feasible by construction: u = 0, w' = 0). First ε = 1e-6, kept as
        solved (far below the slack's unit weight); then ε = 1e-4, kept only as the verified exact optimum of the
        level as posed (``polish`` from its active set: on a degenerate vertex of the stress run, 5 rows active in
        4 unknowns, daqp needed it and quadprog agrees). ``failed``: the backend's first error (for the note the
        retry leaves in :attr:`QPDiagnostics.retries`: counted in ``StepResult.relaxed``, told in ``info``).
        """
        diag.regularization_retry = 1
        last: SolverError | None = None
        for boost, verify in ((max(1e-6, 1e3 * eps), False), (1e-4, True)):
            P = prob.P.copy()
            P[:r, :r] += (boost - eps) * np.eye(r)
            try:
                sol = self._solve_qp(replace(prob, P=P), None, diag)
            except SolverError as exc:
                last = exc
                continue
            if not verify:
                diag.retries.append((prob.label, f"{failed}; solved with the regulariser raised to {boost:.3g}"))
                return sol
            exact = polish(prob, sol.x)
            if exact is not None:
                diag.retries.append((prob.label, f"{failed}; solved with the regulariser raised to {boost:.3g}"))
                return replace(sol, x=exact)
        assert last is not None
        raise last

    def _cascade_cfg(self) -> np.ndarray:
        """The ``cfg`` array of ``hqp_kernels.qp_cascade_run`` for the resolver's settings as they are now."""
        cfg = self._cfg
        if cfg is None:  # (every setting read here is a Setting: its assignment drops the array)
            key = (self.epsilon, self.max_damping, self.rcond, self.regularization, self.slack_tolerance,
                   self.identity_levels, self.level_shortcut, self.complement_min_n, self.complement_fraction,
                   self.certified_qr)  # fmt: skip
            cfg = self._cfg = np.array(
                [*key[:5], _FEASIBLE, *map(float, key[5:7]), CONTRADICTION_TOLERANCE, *map(float, key[7:])]
            )
        return cfg

    def _native_cascade(
        self, plan: _Plan, lb: np.ndarray, ub: np.ndarray, z: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int] | None:
        """:meth:`_qp_cascade` of a fused step when daqp, called from the compiled cascade (``daqp_native``),
        solves every level QP at once and no level is contradicted: the one compiled call and nothing of the loop
        around it. Returns (x, the per-level records, the certified R's, QPs solved, iterations), or ``None`` when
        the native call is off or the cascade needs more (a level QP daqp did not solve at once, a contradicted
        level): :meth:`_qp_cascade` then runs it from the start (the same answer) and goes on."""
        qbuf, native = plan.qp_arrays(self.backend)
        if native is None:
            return None
        L = plan.meta.shape[1] - 1
        assert plan._dims is not None
        work = plan.cascade_buffers(plan._dims[3])
        _, _, _, _, _, state, _, _ = work
        x = np.empty(plan.n)
        stats = np.zeros((L, 7))
        rfac = np.empty((L, plan.r_size))
        ctl = native.ctl
        ctl[HK.NAT_SOLVED] = ctl[HK.NAT_ITERS] = 0
        status = HK.qp_cascade_run(
            plan.rows(z), plan.mixed_flags, (lb, ub), self._cascade_cfg(), work, (x, stats, rfac, qbuf),
            (0, False, _NO_U), (ctl, native.x),
        )[0]  # fmt: skip
        if status != HK.CASCADE_DONE or state[HK.ST_CONTRADICTED]:
            return None
        return x, stats, rfac, int(ctl[HK.NAT_SOLVED]), int(ctl[HK.NAT_ITERS])

    def _qp_cascade(self, built: HQPBuild, diag: QPDiagnostics) -> tuple[np.ndarray, list[str]]:
        """The constrained cascade (module docstring): every level but its QP in compiled code
        (``hqp_kernels.qp_cascade_run``, on the step's rows in the plan's buffers), each level QP it writes into the
        plan's QP buffer solved by the backend here — from the buffer as it is when the backend can
        (``Backend.solve_stacked``), else as a ``QPProblem`` with the retries; the per-level records (σ_min, damping,
        rank) are kept on ``built`` for the diagnostics.

        Returns:
            (q̇, notes: the levels skipped after a backend failure); the members of the levels contradicted by
            those above go to :attr:`QPDiagnostics.relaxed`.
        """
        n, box = built.n, built.box
        layout = built.layout
        plan = self._plan_for(layout, n)
        if not built.filled:  # (the lean steps wrote their rows into these buffers already)
            plan.fill(built.rows)
        L = len(layout.levels)
        cfg = self._cascade_cfg()
        # the start (in the first compiled call): joints whose box is one value (a rate window squeezed to a point, a
        # joint held at its limit) are not unknowns but fixed first and left out of the basis, so that no level QP
        # carries a window of zero width (as the pair of rows ±Z_j u ≤ tol, it left proxsuite a 1e-7-wide feasible
        # set that it declared infeasible)
        x = np.empty(n)
        work = plan.cascade_buffers(int(plan.meta[META_INEQ, L]))
        _, _, _, _, slack, state, _, _ = work
        stats = np.zeros((L, 7))
        z = built.z if built.z is not None else plan.zero
        notes: list[tuple[int, str]] = []
        k, absorb, u = 0, False, _NO_U
        backend = self.backend
        # daqp itself: the cascade calls its C entry point and absorbs what it solves at once (``daqp_native``)
        qbuf, native = plan.qp_arrays(backend)
        rfac = np.empty((L, plan.r_size))  # the R of the levels factored by their certified QR (σ_min when read)
        # a built-in backend that checks its answers takes the QP in the kernel's buffer as it is (daqp: no copy);
        # anything else, and any QP it does not solve at once, goes through QPProblem and the retries below
        stacked = backend.solve_stacked if type(backend) in CHECKED_ANSWERS else None
        if native is not None:
            ctl, nx = native.ctl, native.x
            ctl[HK.NAT_SOLVED] = ctl[HK.NAT_ITERS] = 0
        else:
            ctl, nx = _NO_NATIVE, _NO_U
        last_here = -1  # the last level whose QP was solved here (the record's backend is the last solver's)
        rows, outs, limits = plan.rows(z), (x, stats, rfac, qbuf), (box.lb, box.ub)
        while True:
            status, k, nvar, nr, eps = HK.qp_cascade_run(
                rows, plan.mixed_flags, limits, cfg, work, outs, (k, absorb, u), (ctl, nx)
            )
            if status == HK.CASCADE_DONE:
                break
            last_here = k
            nu, neq = int(state[HK.ST_NU]), int(state[HK.ST_NEQ])  # the step's variables, the equality rows (last)
            P, q, G, upper, lower = plan.qp_views(nvar, nr)
            quick = None if stacked is None else stacked(P, q, G, upper, lower, neq)
            if quick is not None:
                diag.qp += 1
                diag.iterations += max(quick[1], 0)
                diag.backend = backend.name
                u, absorb = quick[0][:nu], True
                continue
            priority = layout.levels[k].priority
            ni = nr - neq
            prob = QPProblem(
                P.copy(), q.copy(), G[:ni].copy(), upper[nvar : nvar + ni].copy(), G[ni:].copy(),
                upper[nvar + ni :].copy(), lower[:nvar].copy(), upper[:nvar].copy(), f"hqp level {priority}",
            )  # fmt: skip
            try:
                try:
                    sol = self._solve_qp(prob, None, diag)
                except SolverError as first:
                    sol = self._regularized_retry(prob, nu, eps, diag, first)
            except SolverError as exc:
                if k == 0:
                    raise  # nothing of the cascade is worth keeping: the base falls back to the closed form
                notes.append((k, f"level {priority} skipped ({exc})"))
                stats[k, HK.QS_SOLVED] = 0.0
                k, absorb = k + 1, False
                continue
            diag.qp += 1
            diag.iterations += max(sol.iterations, 0)
            diag.backend = sol.backend
            u, absorb = sol.x[:nu], True
        if native is not None and ctl[HK.NAT_SOLVED]:
            diag.qp += int(ctl[HK.NAT_SOLVED])
            diag.iterations += int(ctl[HK.NAT_ITERS])
            if ctl[HK.NAT_LAST] > last_here:
                diag.backend = backend.name
        contradicted: list[int] = (
            np.flatnonzero(stats[:, HK.QS_WORST] > CONTRADICTION_TOLERANCE).tolist()
            if state[HK.ST_CONTRADICTED]
            else []
        )
        for k in contradicted:  # the documented relaxation: named in StepResult.relaxed, not a fallback
            worst = float(stats[k, HK.QS_WORST])
            lv = built.levels[k]
            diag.contradicted[lv.priority] = worst
            c0, c1 = int(plan.meta[META_INEQ, k]), int(plan.meta[META_INEQ, k + 1])
            owner = [bsub.name for C, _, _, bsub in built.rows.ineq[k] for _ in range(C.shape[0])]
            over = np.flatnonzero(slack[c0:c1] > CONTRADICTION_TOLERANCE).tolist()
            diag.relaxed += [owner[i] for i in over if i < len(owner)] or [f"level {lv.priority}"]
        built.qp_stats, built.qp_r = stats, rfac
        notes.sort(key=lambda item: item[0])
        return x, [text for _, text in notes]

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
        if plan.critical or self.limits.has_jerk:  # (a jerk limit: the box needs the last two q̇)
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
        t0 = time.perf_counter()
        terms = [task.evaluate(robot, t) for task in stack.tasks]  # stack.evaluate, inlined
        z, targets, bounds = plan.gather(robot, stack, terms, dt)  # gather_rows + fill, in one pass
        t1 = time.perf_counter()
        limits = self.limits
        prev = limits.previous(self._dq_prev)
        out = np.empty((7, 1, n))
        stats = np.empty((plan.meta.shape[1] - 1, 4))
        rows = plan.rows(plan.zero if z is None else z)
        status = HK.closed_step(rows, plan.params, robot.q, limits.kernel_args(robot), float(dt), prev, out, stats)
        windowed = prev.shape[0] > 0
        if status != 1:  # a constraint is active (0), or q̇ is not finite (2): the template, on the same rows
            built = HQPBuild(
                lambda: plan.step_rows(terms, z, targets, bounds), limits.box_from(out[_BOX, 0], windowed), n,
                infeasible=status == 0, layout=layout, z=z, filled=status == 0, critical=False,
            )  # fmt: skip
            return self._finish(robot, stack, terms, built, t0, t1)
        kept = out[OUT_KEPT, 0]
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
        k = 0
        for (role, _, _), term in zip(fused.external, external, strict=True):
            if role == ROW and term is not None:
                start = fused.external_starts[k]
                k += 1
                rows = dest[start : start + term.J.shape[0]]
                A[rows] = term.J
                b[rows] = term.v
                w[rows] = term.weight

    def _fused_solve(
        self, robot: RobotModel, stack: TaskStack, plan: _Plan, fused: FusedPlan, t: float, dt: float
    ) -> StepResult | None:
        """:meth:`solve` of a fused stack (:mod:`redundik.resolvers.fused`): the bound subtasks' rows as
        :meth:`_Plan.gather` writes them, then one compiled call from Pinocchio's Jacobians through the rows to the
        unconstrained cascade and its tests (``hqp_fused.fused_hqp_step``); ``None`` when this step needs the
        per-task path (a rotation error beyond the compiled log3's range)."""
        t0 = time.perf_counter()
        n = robot._nv
        external: list[TaskTerm | None] | tuple[()] = ()
        if fused.external:  # members without a compiled form: their rows and z terms from Python (before the
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
            bint, bcols, bfl = _NO_BOUNDS
        else:  # their rows written in the compiled call
            bounds = plan.written_bounds(packed)
            bint, bcols, bfl = packed.bint, packed.bcols, packed.bfl
        limits = self.limits
        args = limits.kernel_args(robot)
        coef = fused.coefficients((float(args[5]), float(args[6]), float(args[7])))
        refs = fused.given_references(t) if fused.given else fused.refs
        prev = limits.previous(self._dq_prev)
        Jf = np.empty((len(fused.frames), 6, n))
        ev = np.empty((2, fused.m))
        z = np.zeros(n)
        if fused.lie_joints:
            fused.write_joint_errors(robot, ev[0])
        if external:
            fused.write_external(robot, external, None, 0, ev, None, z)
            self._write_external_rows(plan, fused, external)
        out = np.empty((7, 1, n))
        stats = np.empty((plan.meta.shape[1] - 1, 4))
        q = robot.q
        status, err2, dq2 = HFK.fused_hqp_step(
            (fused.jw, fused.poses, refs), (float(t), float(dt), q, prev),
            (fused.ints, fused.floats, plan.dest, bint, bcols, bfl), coef, args, (Jf, ev), plan.rows(z), plan.params,
            (out, stats),
        )  # fmt: skip
        if status < 0.0:
            return None
        t1 = time.perf_counter()
        zs = z if plan.layout.has_null_objective else None
        make_terms = fused.terms_once(Jf, ev, q, robot, external)
        windowed = prev.shape[0] > 0
        if status != 1.0:  # a constraint is active (0), or q̇ is not finite (2): the template, on the same rows
            if status != 0.0:  # q̇ not finite: the template, its terms at hand to say where from
                terms = make_terms()
                built = HQPBuild(
                    lambda: plan.step_rows(terms, zs, [], bounds), limits.box_from(out[_BOX, 0], windowed), n,
                    layout=plan.layout, z=zs, critical=False,
                )  # fmt: skip
                return self._finish(robot, stack, terms, built, t0, t1)
            lean = self._native_cascade(plan, out[OUT_LB, 0], out[OUT_UB, 0], plan.zero if zs is None else zs)
            if lean is not None and finite(lean[0]):  # (a non-finite q̇ takes the template: it says where from)
                return self._native_result(plan, lean, out, windowed, zs, bounds, make_terms, err2, t0, t1)
            built = HQPBuild(
                lambda: plan.step_rows(make_terms(), zs, [], bounds), limits.box_from(out[_BOX, 0], windowed), n,
                infeasible=True, layout=plan.layout, z=zs, filled=True, critical=False,
            )  # fmt: skip
            # the constrained cascade; the terms are built only if read (or for a fallback), the task error is the
            # compiled call's
            dq, pending, fallback, relaxed, info, t2 = self._settle(robot, stack, make_terms, built)
            res = FusedStepResult.fused(
                dq, make_terms, math.sqrt(err2), info, t1 - t0, t2 - t1, plan.layout.main, pending, fallback=fallback
            )
            return with_relaxed(res, relaxed)
        kept = out[OUT_KEPT, 0]
        self._dq_prev = kept

        def diagnostics() -> tuple[float, bool, dict[str, object]]:  # on first read of the result's diagnostics
            box = limits.box_from(out[_BOX, 0], windowed)
            built = HQPBuild(plan.step_rows(make_terms(), zs, [], bounds), box, n, stats)
            diag = QPDiagnostics()
            diag.active_limits = box.active(kept, limits.joint_names)
            self._diagnose(built, kept, diag)
            return diag.sigma_min, bool(diag.damped_levels), diag.as_info()

        return FusedStepResult.fused(
            out[OUT_DQ, 0],
            make_terms,
            math.sqrt(err2),
            {"backend": "closed-form", "qp": 0, "iterations": 0},
            t1 - t0,
            time.perf_counter() - t1,
            plan.layout.main,
            diagnostics,
            dq_norm=math.sqrt(dq2),
        )

    def _native_result(
        self,
        plan: _Plan,
        lean: tuple[np.ndarray, np.ndarray, np.ndarray, int, int],
        out: np.ndarray,
        windowed: bool,
        zs: np.ndarray | None,
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
        lb, ub = out[OUT_LB, 0], out[OUT_UB, 0]
        clipped = np.empty((2, x.shape[0]))
        K.clip_twice(x, lb, ub, clipped)
        kept = clipped[1]
        self._dq_prev = kept
        t2 = time.perf_counter()
        limits, name = self.limits, self.backend.name

        def diagnostics() -> tuple[float, bool, dict[str, object]]:  # on first read of the result's diagnostics
            box = limits.box_from(out[_BOX, 0], windowed)
            built = HQPBuild(plan.step_rows(make_terms(), zs, [], bounds), box, plan.n, infeasible=True)
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
        if not built.infeasible:
            x = self._lean_cascade(built, built.layout)
            if x is not None:
                return x, None
        x, notes = self._qp_cascade(built, diag)
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

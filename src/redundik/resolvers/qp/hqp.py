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

The levels are the stack's (:mod:`redundik.tasks.stack`): main tasks at their priority (0), target and bound
subtasks below them, the null-space objective ½‖q̇ − z‖² (gradient subtasks and posture) last; restricted to Z it
gives the projection Z Zᵀ(z − x). Every level's least squares goes through the shared damped-SVD kernel of
:mod:`redundik.resolvers.linalg`, which damps only small nonzero singular directions: a level that is exactly
rank-deficient (a duplicated or zero row) is solved exactly and keeps its optimum under every lower level.

A level that cannot be met — its bound rows contradicted by the levels above and the limits (slack w_k* > 1e-6),
or a level QP the backend fails — is a recorded fallback (``StepResult.fallback`` names the level and by how much;
``info["contradicted_levels"]``).

Diagnostics in ``StepResult.info``: ``residual_L<k>`` (per level: ‖J_k q̇ − v_k‖ of its task rows, or ‖q̇ − z‖ for a
pure gradient level, combined with the norm of its inequality violations),
``sigma_min_L<k>`` (smallest singular value of the projected Jacobian A_k Z), ``rank_loss`` (number of levels whose
projected Jacobian lost rank while the task's own did not — an algorithmic singularity) with ``rank_loss_levels``,
``active_limits`` / ``n_active``, ``backend``, ``iterations``, ``qp`` (number of level QPs solved).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from redundik.errors import ResolverError, SolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.linalg import DampedSVD, K, contiguous, damped_svd
from redundik.resolvers.qp.backends import DEFAULT_BACKEND, Backend, polish
from redundik.resolvers.qp.base import LevelsOption, LimitsOption, QPDiagnostics, QPResolverBase
from redundik.resolvers.qp.limits import LimitBox
from redundik.resolvers.qp.problem import QPProblem, QPSolution
from redundik.resolvers.qp.terms import Level, build_levels
from redundik.tasks.base import TaskTerm
from redundik.tasks.stack import TaskStack

_NO_BASIS = np.zeros((0, 0))

#: Slack above which a level's bound rows count as contradicted (reported as a fallback).
CONTRADICTION_TOLERANCE = 1e-6


@dataclass
class HQPBuild:
    """A built ``hqp`` step: its levels (rows) and the joint-limit box."""

    levels: list[Level]
    box: LimitBox
    n: int


class HierarchicalQPResolver(QPResolverBase):
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

    Raises:
        ResolverError: bad numbers; SolverError: unknown or missing backend.
    """

    name = "hqp"

    def __init__(
        self,
        backend: str | Backend = DEFAULT_BACKEND,
        limits: LimitsOption = None,
        levels: LevelsOption = None,
        regularization: float = 1e-9,
        epsilon: float = 1e-2,
        max_damping: float = 5e-2,
        rcond: float = 1e-10,
    ) -> None:
        super().__init__(backend, limits, levels, epsilon, max_damping)
        if not (isinstance(regularization, (int, float)) and np.isfinite(regularization) and regularization > 0):
            raise ResolverError(f"hqp: regularization must be a finite number > 0, got {regularization!r}")
        if not (isinstance(rcond, (int, float)) and 0 < rcond < 1):
            raise ResolverError(f"hqp: rcond must be in (0, 1), got {rcond!r}")
        self.regularization, self.rcond = float(regularization), float(rcond)
        self.slack_tolerance = 1e-7  # feasibility margin of the rows that carry higher levels and limits

    def build(
        self, robot: RobotModel, stack: TaskStack, t: float, dt: float, terms: list[TaskTerm] | None = None
    ) -> HQPBuild:
        """Evaluate the stack (unless ``terms`` are given) and lay out its levels as rows, without solving."""
        if terms is None:
            terms = stack.evaluate(robot, t)
        levels = build_levels(robot, stack, terms, self.layout(stack), dt)
        return HQPBuild(levels, self._box(robot, dt), robot.nv)

    # ------------------------------------------------------------------ the two cascades
    def _project(self, lv: Level, x: np.ndarray, Z: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        A, b = lv.ls_rows()
        M = A if Z is None else A @ Z
        return A, M, b - A @ x

    def _lsq(self, M: np.ndarray) -> DampedSVD:
        return damped_svd(M, epsilon=self.epsilon, max_damping=self.max_damping, rcond=self.rcond)

    def _note(self, lv: Level, A: np.ndarray, lsq: DampedSVD, r: int, projected: bool, diag: QPDiagnostics) -> None:
        self._record(lv, A, lsq.sigma_min, lsq.damping, lsq.rank, r, projected, diag)

    def _record(
        self,
        lv: Level,
        A: np.ndarray,
        sigma_min: float,
        damping: float,
        rank: int,
        r: int,
        projected: bool,
        diag: QPDiagnostics,
    ) -> None:
        diag.level_sigma_min[lv.priority] = sigma_min
        if damping > 0.0:
            diag.damped_levels.append(lv.priority)
        if not diag.level_sigma_min or len(diag.level_sigma_min) == 1:
            diag.sigma_min = sigma_min
        # algorithmic singularity: the projected Jacobian A Z lost rank while A itself did not
        if projected and not lv.pure_null_objective and rank < min(A.shape[0], r):
            if rank < min(int(np.linalg.matrix_rank(A)), r):
                diag.rank_loss_levels.append(lv.priority)

    def _closed_form_cascade(self, levels: list[Level], n: int, diag: QPDiagnostics) -> np.ndarray:
        x = np.zeros(n)
        Z: np.ndarray | None = None
        r = n
        for lv in levels:
            if r == 0:
                break
            if lv.pure_null_objective:  # rows = I: u = Zᵀ(z − x) exactly, nothing left below
                assert lv.z is not None
                x = lv.z.copy() if Z is None else x + Z @ (Z.T @ (lv.z - x))
                Z, r = np.zeros((n, 0)), 0
                continue
            if not lv.m:
                continue
            A, b = lv.ls_rows()
            x_new = np.empty(n)
            projected = Z is not None
            Z, smin, damping, rank = K.lsq_level(  # one compiled call: (A Z)⁺_λ(b − A x), x + Z u, Z·null(A Z)
                contiguous(A),
                contiguous(b),
                x,
                _NO_BASIS if Z is None else Z,
                Z is not None,
                self.epsilon,
                self.max_damping,
                self.rcond,
                x_new,
            )
            self._record(lv, A, float(smin), float(damping), int(rank), r, projected, diag)
            x, r = x_new, Z.shape[1]
        return x

    def _level_qp(
        self,
        lv: Level,
        x: np.ndarray,
        Z: np.ndarray | None,
        r: int,
        box: LimitBox,
        fixed: list[tuple[np.ndarray, np.ndarray]],
        diag: QPDiagnostics,
        pinned: np.ndarray,
        selection: np.ndarray | None,
    ) -> tuple[np.ndarray, DampedSVD | None, np.ndarray | None]:
        """Solve level ``lv`` over q̇ = x + Z u (module docstring); returns (u, the level's least squares, A).

        ``pinned`` marks the joints whose box is a single value (their q̇ is in x, their rows of Z are zero);
        ``selection`` is the index array of the free joints while Z is still I restricted to them (the first level
        after pinning), so that the box stays native bounds on u.
        """
        n = x.shape[0]
        Zm = np.eye(n) if Z is None else Z
        p = lv.p
        nvar = r + p
        P = np.zeros((nvar, nvar))
        q = np.zeros(nvar)
        lsq, A = None, None
        eps = self.regularization
        if lv.m or lv.z is not None:
            A, M, rhs = self._project(lv, x, Z)
            lsq = self._lsq(M)
            eps = max(eps, lsq.damping**2)
            P[:r, :r] = M.T @ M
            q[:r] = -(M.T @ rhs)
        P[:r, :r] += eps * np.eye(r)
        rows, rhs_rows = [], []
        if p:  # C(x + Zu) − d ≤ w, with w = w₀ + w' measured from its value at u = 0
            # w₀ = max(Cx − d, 0) makes u = 0, w' = 0 feasible and keeps w' on the scale of u: a level whose slack
            # is 19.5 while the limits leave u a 1e-6-wide window was otherwise called infeasible by proxsuite;
            # the change of variables is exact (½‖w₀ + w'‖² = ½‖w'‖² + w₀ᵀw' + const)
            slack0 = lv.d - lv.C @ x
            w0 = np.maximum(-slack0, 0.0)
            P[r:, r:] = np.eye(p)
            q[r:] = w0
            rows.append(np.hstack([lv.C @ Zm, -np.eye(p)]))
            rhs_rows.append(slack0 + w0)
        # Below level 0, rows that carry the levels above and the limits get the margin max(·, 0) + tol: x (the
        # answer so far, from a backend's finite tolerance) may sit up to that tolerance outside them, and without
        # the clamp a level could be declared primal-infeasible (proxsuite, osqp) though u = 0 always solves it.
        for C, d in fixed:  # levels above keep their slack
            rows.append(np.hstack([C @ Zm, np.zeros((C.shape[0], p))]))
            rhs_rows.append(np.maximum(d - C @ x, 0.0) + self.slack_tolerance)
        lb, ub = np.full(nvar, -np.inf), np.full(nvar, np.inf)
        if Z is None:
            lb[:r], ub[:r] = box.lb - x, box.ub - x  # hard (never empty: limits.py)
        elif selection is not None:
            lb[:r], ub[:r] = box.lb[selection] - x[selection], box.ub[selection] - x[selection]
        else:
            tol = self.slack_tolerance
            fu, fl = np.isfinite(box.ub) & ~pinned, np.isfinite(box.lb) & ~pinned
            if fu.any():
                rows.append(np.hstack([Z[fu], np.zeros((int(fu.sum()), p))]))
                rhs_rows.append(np.maximum(box.ub[fu] - x[fu], 0.0) + tol)
            if fl.any():
                rows.append(np.hstack([-Z[fl], np.zeros((int(fl.sum()), p))]))
                rhs_rows.append(np.maximum(x[fl] - box.lb[fl], 0.0) + tol)
        G = np.vstack(rows) if rows else np.zeros((0, nvar))
        h = np.concatenate(rhs_rows) if rhs_rows else np.zeros(0)
        prob = QPProblem(P, q, G, h, np.zeros((0, nvar)), np.zeros(0), lb, ub, f"hqp level {lv.priority}")
        try:
            sol = self._solve_qp(prob)
        except SolverError:
            sol = self._regularized_retry(prob, r, eps, diag)
        diag.qp += 1
        diag.iterations += max(sol.iterations, 0)
        diag.backend = sol.backend
        return sol.x[:r], lsq, A

    def _regularized_retry(self, prob: QPProblem, r: int, eps: float, diag: QPDiagnostics) -> QPSolution:
        """Solve a level QP the backend refused, with a stronger minimum-norm regulariser on u.

        Dual active-set solvers (daqp) work with P⁻¹ and can misjudge a level whose u-block is regularised by 1e-9
        only as infeasible (every level below 0 is feasible by construction: u = 0, w' = 0). First ε = 1e-6, kept as
        solved (far below the slack's unit weight); then ε = 1e-4, kept only as the verified exact optimum of the
        level as posed (``polish`` from its active set: on a degenerate vertex of the stress run, 5 rows active in
        4 unknowns, daqp needed it and quadprog agrees).
        """
        diag.regularization_retry = 1
        last: SolverError | None = None
        for boost, verify in ((max(1e-6, 1e3 * eps), False), (1e-4, True)):
            P = prob.P.copy()
            P[:r, :r] += (boost - eps) * np.eye(r)
            try:
                sol = self._solve_qp(replace(prob, P=P))
            except SolverError as exc:
                last = exc
                continue
            if not verify:
                return sol
            exact = polish(prob, sol.x)
            if exact is not None:
                return replace(sol, x=exact)
        assert last is not None
        raise last

    def _qp_cascade(
        self, levels: list[Level], box: LimitBox, n: int, diag: QPDiagnostics
    ) -> tuple[np.ndarray, list[str]]:
        x = np.zeros(n)
        Z: np.ndarray | None = None
        r = n
        fixed: list[tuple[np.ndarray, np.ndarray]] = []
        notes: list[str] = []
        # joints whose box is one value (a rate window squeezed to a point, a joint held at its limit) are not
        # unknowns: fixed first and removed from the basis, so no level QP carries a window of zero width (as the
        # pair of rows ±Z_j u ≤ tol, it left proxsuite a 1e-7-wide feasible set that it declared infeasible)
        pinned = box.pinned()
        selection: np.ndarray | None = None
        if pinned.any():
            x[pinned] = 0.5 * (box.lb[pinned] + box.ub[pinned])
            selection = np.flatnonzero(~pinned)
            Z, r = np.eye(n)[:, selection], int(selection.size)
        for lv in levels:
            if r == 0 and not lv.p:
                continue  # nothing left to move, but a lower level's inequalities are still checked (and reported)
            if not lv.m and lv.z is None and not lv.p:
                continue
            if lv.pure_null_objective and not lv.p and Z is not None:
                # the closed form P_Z(z − x) needs no QP when it keeps the limits and the levels above
                assert lv.z is not None
                cand = x + Z @ (Z.T @ (lv.z - x))
                tol = self.slack_tolerance
                if box.contains(cand, tol) and all(bool(np.all(C @ cand <= d + tol)) for C, d in fixed):
                    x, Z, r = cand, np.zeros((n, 0)), 0
                    continue
            try:
                u, lsq, A = self._level_qp(lv, x, Z, r, box, fixed, diag, pinned, selection)
            except SolverError as exc:
                if lv is levels[0]:
                    raise  # nothing of the cascade is worth keeping: the base falls back to the closed form
                notes.append(f"level {lv.priority} skipped ({exc})")
                continue
            x = x + (u if Z is None else Z @ u)
            if lv.p:
                w = np.maximum(lv.C @ x - lv.d, 0.0)
                fixed.append((lv.C, lv.d + w + self.slack_tolerance))
                worst = float(np.max(w))
                if worst > CONTRADICTION_TOLERANCE:
                    diag.contradicted[lv.priority] = worst
                    rows = [lv.c_names[i] for i in np.flatnonzero(w > CONTRADICTION_TOLERANCE)]
                    notes.append(
                        f"level {lv.priority} contradicted by the levels above and the limits: {rows} violated by "
                        f"up to {worst:.3g}"
                    )
            if lsq is not None and A is not None:
                self._note(lv, A, lsq, r, Z is not None and selection is None, diag)
                Z = lsq.null_basis if Z is None else Z @ lsq.null_basis
                r = Z.shape[1]
                selection = None
        return x, notes

    # ------------------------------------------------------------------ the step (skeleton in QPResolverBase.solve)
    def _resolve(self, built: HQPBuild, diag: QPDiagnostics) -> tuple[np.ndarray, str | None]:
        levels, box, n = built.levels, built.box, built.n
        x = self._closed_form_cascade(levels, n, diag)
        tol = 1e-12
        if box.contains(x, tol) and all(not lv.p or bool((lv.C @ x <= lv.d + tol).all()) for lv in levels):
            return x, None
        diag.level_sigma_min.clear()
        diag.damped_levels.clear()
        diag.rank_loss_levels.clear()
        x, notes = self._qp_cascade(levels, box, n, diag)
        return x, ("hqp: " + "; ".join(notes)) if notes else None

    def _safety_rows(self, built: HQPBuild, stack: TaskStack) -> tuple[np.ndarray, np.ndarray] | None:
        names = {b.name for b in stack.bound_subtasks if b.critical}
        if not names:
            return None
        Cs, ds = [], []
        for lv in built.levels:
            if lv.p:
                keep = np.array([r.split(":", 1)[0] in names for r in lv.c_names], dtype=bool)
                Cs.append(lv.C[keep])
                ds.append(lv.d[keep])
        return (np.vstack(Cs), np.concatenate(ds)) if Cs else None

    def _diagnose(self, built: HQPBuild, dq: np.ndarray, diag: QPDiagnostics) -> None:
        for lv in built.levels:
            diag.level_residuals[lv.priority] = lv.residual(dq)

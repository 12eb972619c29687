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

Shortcut (exact, and the common case): the same cascade without constraints is solved in closed form — level by
level u = (A_k Z)⁺(b_k − A_k x), with the damped pseudo-inverse of :mod:`redundik.resolvers.linalg` — and kept when
it satisfies every inequality and limit, since a feasible unconstrained lexicographic optimum is the constrained one.
For [main task, gradient subtask] this is q̇ = J⁺V + Z Zᵀ z = J⁺V + (I − J⁺J)z, the chapter's eq. (5.8), exactly.

Gradient subtasks at a level contribute the rows √ω(q̇ = z), z = Σ k_i η_i (see :mod:`.terms`); restricted to Z they
give the projection Z Zᵀ(z − x). Levels: main tasks at 0 unless their ``priority`` attribute or the ``levels`` option
says otherwise; subtasks at ``Subtask.priority`` (default 1).

Diagnostics in ``StepResult.info``: ``residual_L<k>`` (per level: ‖J_k q̇ − v_k‖ of its task rows, or ‖q̇ − z‖ for a
pure gradient level, combined with the norm of its inequality violations),
``sigma_min_L<k>`` (smallest singular value of the projected Jacobian A_k Z), ``rank_loss`` (number of levels whose
projected Jacobian lost rank while the task's own did not — an algorithmic singularity) with ``rank_loss_levels``,
``active_limits`` / ``n_active``, ``backend``, ``iterations``, ``qp`` (number of level QPs solved).
"""

from __future__ import annotations

import time

import numpy as np

from redundik.errors import ResolverError, SolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import StepResult
from redundik.resolvers.qp.backends import DEFAULT_BACKEND, Backend
from redundik.resolvers.qp.base import LevelsOption, LimitsOption, QPResolverBase
from redundik.resolvers.qp.limits import LimitBox
from redundik.resolvers.qp.problem import QPProblem
from redundik.resolvers.qp.terms import Level, build_levels
from redundik.tasks.base import TaskStack


class _Lsq:
    """Damped least squares of one projected level, with the null-space basis of the projected Jacobian."""

    __slots__ = ("damping", "null", "rank", "sigma_min", "u")

    def __init__(self, M: np.ndarray, rhs: np.ndarray, epsilon: float, max_damping: float, rcond: float) -> None:
        U, s, Vt = np.linalg.svd(M, full_matrices=True)  # Vt (r, r); s descending, size min(m, r)
        k = s.shape[0]
        smax = float(s[0]) if k else 0.0
        rank = int(np.count_nonzero(s > rcond * smax)) if smax > 0 else 0
        sigma_min = float(s[-1]) if k else np.inf
        lam2 = 0.0
        if k and sigma_min < epsilon and epsilon > 0:
            lam2 = (1.0 - (sigma_min / epsilon) ** 2) * max_damping**2
        if lam2 > 0:
            inv_s = s / (s * s + lam2)
        else:
            inv_s = np.zeros_like(s)
            inv_s[:rank] = 1.0 / s[:rank]
        self.u = Vt[:k].T @ (inv_s * (U[:, :k].T @ rhs))
        self.null = Vt[rank:].T  # (r, r − rank)
        self.rank, self.sigma_min, self.damping = rank, sigma_min, float(np.sqrt(lam2))


class HierarchicalQPResolver(QPResolverBase):
    """Strict task hierarchy by a cascade of QPs with slack (see the module docstring for the method and references).

    Args:
        backend: QP backend (default ``"daqp"``).
        limits: Joint limits: ``None`` = the model's, ``False`` = none, a dict of
            :class:`~redundik.resolvers.qp.limits.JointLimits` options, or an instance.
        levels: Level overrides: ``{name: level}`` or a list of levels of names.
        regularization: ε, the minimum-norm regulariser of each level QP (> 0).
        epsilon: Singular value under which a level's projected Jacobian is damped.
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
        if not (np.isfinite(regularization) and regularization > 0):
            raise ResolverError(f"hqp: regularization must be a finite number > 0, got {regularization}")
        if not (np.isfinite(rcond) and 0 < rcond < 1):
            raise ResolverError(f"hqp: rcond must be in (0, 1), got {rcond}")
        self.regularization, self.rcond = float(regularization), float(rcond)
        self.slack_tolerance = 1e-7  # feasibility margin of the rows that carry higher levels and limits

    # ------------------------------------------------------------------ the two cascades
    def _project(self, lv: Level, x: np.ndarray, Z: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        A, b = lv.ls_rows()
        M = A if Z is None else A @ Z
        return A, M, b - A @ x

    def _rank_loss(self, A: np.ndarray, lsq: _Lsq, r: int, lv: Level) -> bool:
        """Projected Jacobian A Z deficient while A itself is not (only for task rows; a gradient block never is)."""
        m = A.shape[0]
        if (lv.z is not None and not lv.m) or lsq.rank >= min(m, r):
            return False
        return lsq.rank < min(int(np.linalg.matrix_rank(A)), r)

    @staticmethod
    def _identity_target(lv: Level) -> np.ndarray | None:
        """For a level whose rows are all identity blocks (gradient ½ω‖q̇ − z‖², posture w‖q̇ − v‖²), the weighted
        target (ωz + wv)/(ω + w) that minimises it; ``None`` for any other level."""
        if lv.m and not lv.identity:
            return None
        w = float(lv.w[0]) if lv.m else 0.0
        om = lv.z_weight if lv.z is not None else 0.0
        if w + om <= 0:
            return None
        if not lv.m:
            return lv.z
        if lv.z is None:
            return lv.v
        return (om * lv.z + w * lv.v) / (om + w)

    def _closed_form_cascade(self, levels: list[Level], n: int, info: dict) -> np.ndarray:
        x = np.zeros(n)
        Z: np.ndarray | None = None
        r = n
        losses = []
        for lv in levels:
            if r == 0:
                break
            if not lv.m and lv.z is None:
                continue
            target = self._identity_target(lv)
            if target is not None:  # rows = I (gradient and/or posture): u = Zᵀ(target − x) exactly, nothing left
                x = target.copy() if Z is None else x + Z @ (Z.T @ (target - x))
                Z, r = np.zeros((n, 0)), 0
                continue
            if not lv.m:
                continue
            A, M, rhs = self._project(lv, x, Z)
            lsq = _Lsq(M, rhs, self.epsilon, self.max_damping, self.rcond)
            info[f"sigma_min_L{lv.priority}"] = lsq.sigma_min
            if lsq.damping > 0:
                info["damped_levels"] = [*info.get("damped_levels", []), lv.priority]
            if Z is not None and self._rank_loss(A, lsq, r, lv):
                losses.append(lv.priority)
            if Z is None:
                x = lsq.u
                Z = lsq.null
            else:
                x = x + Z @ lsq.u
                Z = Z @ lsq.null
            r = Z.shape[1]
        info["rank_loss"] = len(losses)
        info["rank_loss_levels"] = losses
        return x

    def _level_qp(
        self, lv: Level, x: np.ndarray, Z: np.ndarray | None, r: int, box: LimitBox, fixed: list, info: dict
    ) -> tuple[np.ndarray, _Lsq | None]:
        """Solve level ``lv`` over q̇ = x + Z u (module docstring); returns (u, the level's least squares)."""
        n = x.shape[0]
        Zm = np.eye(n) if Z is None else Z
        p = lv.p
        nvar = r + p
        P = np.zeros((nvar, nvar))
        q = np.zeros(nvar)
        lsq = None
        eps = self.regularization
        if lv.m or lv.z is not None:
            _, M, rhs = self._project(lv, x, Z)
            lsq = _Lsq(M, rhs, self.epsilon, self.max_damping, self.rcond)
            eps = max(eps, lsq.damping**2)
            P[:r, :r] = M.T @ M
            q[:r] = -(M.T @ rhs)
        P[:r, :r] += eps * np.eye(r)
        if p:
            P[r:, r:] = np.eye(p)
        rows, rhs_rows = [], []
        if p:  # C(x + Zu) − d ≤ w
            rows.append(np.hstack([lv.C @ Zm, -np.eye(p)]))
            rhs_rows.append(lv.d - lv.C @ x)
        for C, d in fixed:  # levels above keep their slack
            rows.append(np.hstack([C @ Zm, np.zeros((C.shape[0], p))]))
            rhs_rows.append(d - C @ x)
        lb, ub = np.full(nvar, -np.inf), np.full(nvar, np.inf)
        if Z is None:
            lb[:r], ub[:r] = box.lb - x, box.ub - x
        else:
            tol = self.slack_tolerance
            fu, fl = np.isfinite(box.ub), np.isfinite(box.lb)
            if fu.any():
                rows.append(np.hstack([Z[fu], np.zeros((int(fu.sum()), p))]))
                rhs_rows.append(box.ub[fu] - x[fu] + tol)
            if fl.any():
                rows.append(np.hstack([-Z[fl], np.zeros((int(fl.sum()), p))]))
                rhs_rows.append(x[fl] - box.lb[fl] + tol)
        G = np.vstack(rows) if rows else np.zeros((0, nvar))
        h = np.concatenate(rhs_rows) if rhs_rows else np.zeros(0)
        prob = QPProblem(P, q, G, h, np.zeros((0, nvar)), np.zeros(0), lb, ub, f"hqp level {lv.priority}")
        try:
            sol = self._solve_qp(prob)
        except SolverError:
            # dual active-set solvers (daqp) work with P⁻¹ and can misjudge a 1e-9-regularised level as infeasible:
            # retry once with a stronger minimum-norm regulariser (still far below the slack's unit weight)
            info["regularization_retry"] = 1
            P[:r, :r] += (max(1e-6, 1e3 * eps) - eps) * np.eye(r)
            sol = self._solve_qp(prob)
        info["qp"] = int(info.get("qp", 0)) + 1
        info["iterations"] = int(info.get("iterations", 0)) + max(sol.iterations, 0)
        info["backend"] = sol.backend
        return sol.x[:r], lsq

    def _qp_cascade(self, levels: list[Level], n: int, box: LimitBox, info: dict) -> tuple[np.ndarray, str | None]:
        x = np.zeros(n)
        Z: np.ndarray | None = None
        r = n
        fixed: list[tuple[np.ndarray, np.ndarray]] = []
        losses = []
        skipped = []
        for lv in levels:
            if r == 0:
                break
            if not lv.m and lv.z is None and not lv.p:
                continue
            try:
                u, lsq = self._level_qp(lv, x, Z, r, box, fixed, info)
            except SolverError as exc:
                skipped.append(f"level {lv.priority} skipped ({exc})")
                continue
            x = x + (u if Z is None else Z @ u)
            if lv.p:
                w = np.maximum(lv.C @ x - lv.d, 0.0)
                fixed.append((lv.C, lv.d + w + self.slack_tolerance))
            if lsq is not None:
                info[f"sigma_min_L{lv.priority}"] = lsq.sigma_min
                if Z is not None:
                    A, _ = lv.ls_rows()
                    if self._rank_loss(A, lsq, r, lv):
                        losses.append(lv.priority)
                Z = lsq.null if Z is None else Z @ lsq.null
                r = Z.shape[1]
        info["rank_loss"] = len(losses)
        info["rank_loss_levels"] = losses
        return x, ("hqp relaxed: " + "; ".join(skipped)) if skipped else None

    # ------------------------------------------------------------------ the step
    def solve(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> StepResult:
        t0 = time.perf_counter()
        terms = stack.evaluate(robot, t)
        levels = build_levels(robot, stack, terms, dt, self.levels)
        box = self._box(robot, dt)
        n = robot.nv
        t1 = time.perf_counter()
        info: dict[str, object] = {"backend": "closed-form", "qp": 0, "iterations": 0}
        fallback = None
        x = self._closed_form_cascade(levels, n, info)
        tol = 1e-12
        feasible = box.contains(x, tol) and all(not lv.p or bool(np.all(lv.C @ x <= lv.d + tol)) for lv in levels)
        if not feasible:
            x, fallback = self._qp_cascade(levels, n, box, info)
            if fallback is not None and f"level {levels[0].priority} skipped" in fallback:
                x = self._closed_form(levels, n)  # the top level failed: nothing of the cascade is worth keeping
                fallback = f"{fallback}; damped closed form clipped to the limits"
                info["backend"] = "fallback"
        dq, ok = self._finish(x, box, robot, info)
        if not ok:
            fallback = "non-finite q̇ replaced by zero"
        for lv in levels:
            res = 0.0
            if lv.m:
                res = float(np.sum((lv.J @ dq - lv.v) ** 2))
            elif lv.z is not None:
                res = float(np.sum((dq - lv.z) ** 2))
            if lv.p:
                res += float(np.sum(lv.inequality_residual(dq) ** 2))
            info[f"residual_L{lv.priority}"] = float(np.sqrt(res))
        t2 = time.perf_counter()
        return StepResult(
            dq=dq,
            terms=terms,
            fallback=fallback,
            info=info,
            damped=bool(info.get("damped_levels")),
            build_time=t1 - t0,
            solve_time=t2 - t1,
        )

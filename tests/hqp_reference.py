"""The reference for hqp's lean step: the path it replaced, in Python (the cascade level by level through
``kernels.lsq_level`` on stacked Level records, every level of the constrained cascade the shortcut does not settle
solved by the backend), random stacks, and the comparison of two steps' answers and diagnostics (shared by
``test_hqp_lean`` and ``test_hqp_gather``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import redundik as rk
from redundik.errors import SolverError
from redundik.resolvers.kernels import lsq_level
from redundik.resolvers.linalg import DampedSVD, damped_svd
from redundik.resolvers.qp.base import QPDiagnostics, QPResolverBase
from redundik.resolvers.qp.hqp import HK, HierarchicalQPResolver, HQPBuild
from redundik.resolvers.qp.hqp_constrained import _FEASIBLE, CONTRADICTION_TOLERANCE
from redundik.resolvers.qp.limits import LimitBox
from redundik.resolvers.qp.problem import QPProblem
from redundik.resolvers.qp.terms import Level
from tests.test_qp_helpers import prepared, tip

_NO_BASIS = np.zeros((0, 0))
_NO_SELECTION = np.zeros(0, dtype=np.int64)


def _reference_closed_cascade(
    res: HierarchicalQPResolver, levels: list[Level], n: int, diag: QPDiagnostics
) -> np.ndarray:
    """The replaced closed-form cascade: level by level, u = (A Z)⁺_λ (b − A x) by ``lsq_level``, eager records."""
    x = np.zeros(n)
    Z: np.ndarray | None = None
    r = n
    for lv in levels:
        if r == 0:
            break
        if lv.pure_null_objective:
            assert lv.z is not None
            x = lv.z.copy() if Z is None else x + Z @ (Z.T @ (lv.z - x))
            Z, r = np.zeros((n, 0)), 0
            continue
        if not lv.m:
            continue
        A, b = lv.ls_rows()
        x_new = np.empty(n)
        projected = Z is not None
        Z, smin, damping, rank = lsq_level(
            np.ascontiguousarray(A, dtype=float),
            np.ascontiguousarray(b, dtype=float),
            x,
            np.zeros((0, 0)) if Z is None else Z,
            Z is not None,
            res.epsilon * lv.scale,  # the rule relative to the level's largest weight (Level.scale)
            res.max_damping * lv.scale,
            res.rcond,
            x_new,
        )
        res._record(lv, float(smin), float(damping), int(rank), r, projected, diag)
        x, r = x_new, Z.shape[1]
    return x


def _ridge(lsq: DampedSVD, rhs: np.ndarray, eps: float) -> np.ndarray:
    """argmin ½‖M u − rhs‖² + ½ε‖u‖² = V diag(σ/(σ² + ε)) Uᵀ rhs from the SVD of M: the level QP's objective in u,
    its unconstrained optimum (exact to rounding where ε ≪ σ², unlike a Cholesky of MᵀM + εI)."""
    k = lsq.s.shape[0]
    return lsq.Vt[:k].T @ ((lsq.s / (lsq.s * lsq.s + eps)) * (lsq.U.T @ rhs))


class _PythonCascade(HierarchicalQPResolver):
    """The constrained cascade as it was in Python (level by level on Level records, through ``damped_svd`` and the
    per-level kernels), before ``hqp_kernels.qp_cascade_run`` took all of it but the level QPs: the slow reference
    the compiled cascade is checked against (``_agree``, to 1e-10)."""

    def _project(self, lv: Level, x: np.ndarray, Z: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(A_k Z, b_k − A_k x) of a level's weighted least-squares rows (Z = I when ``None``)."""
        A, b = lv.ls_rows()
        M = A if Z is None else A @ Z
        return M, b - A @ x

    def _lsq(self, M: np.ndarray, scale: float = 1.0) -> DampedSVD:
        """The damped SVD of a level's projected rows M, with ε and λ_max times the level's ``scale`` (√ of its
        largest weight, ``Level.scale``)."""
        return damped_svd(M, epsilon=self.epsilon * scale, max_damping=self.max_damping * scale, rcond=self.rcond)

    def _note(self, lv: Level, lsq: DampedSVD, r: int, projected: bool, diag: QPDiagnostics) -> None:
        self._record(lv, lsq.sigma_min, lsq.damping, lsq.rank, r, projected, diag)

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
        shortcut: bool = False,
    ) -> tuple[np.ndarray, DampedSVD | None]:
        """Solve level ``lv`` over q̇ = x + Z u (module docstring); returns (u, the level's least squares).

        ``pinned`` marks the joints whose box is a single value (their q̇ is in x, their rows of Z are zero);
        ``selection`` is the index array of the free joints while Z is still I restricted to them (the first level
        after pinning), so that the box stays native bounds on u. With ``shortcut`` the QP's unconstrained optimum
        is returned without calling the backend when it satisfies every row of the QP (:meth:`_level_feasible`).
        """
        n = x.shape[0]
        p = lv.p
        lsq = None
        scale = lv.scale  # the damping rule and the regulariser relative to the level's largest weight
        eps = self.regularization * scale * scale
        M = rhs = None
        orthonormal = lv.pure_null_objective and lv.z is not None
        if orthonormal:  # rows = I: M = Z has orthonormal columns, its SVD is (Z, 1, I) — no factorisation
            assert lv.z is not None
            rhs = lv.z - x
            U = np.eye(n) if Z is None else Z
            lsq = DampedSVD(U, np.ones(r), np.eye(r), np.ones(r), r, 1.0 if r else np.inf, 0.0)
        elif lv.m or lv.z is not None:
            M, rhs = self._project(lv, x, Z)
            if (
                self.identity_levels
                and r
                and lv.z is None
                and lv.m == n
                and HK.identity_rows(lv.J, lv.w, 0, n, self.epsilon * scale)
            ):
                # rows √w I (a posture given a level): M = √w Z with Z orthonormal (I at the top) has the exact SVD
                # (Z, √w, I), every direction undamped (√w ≥ ε) — no factorisation of the n×r matrix
                sw = math.sqrt(float(lv.w[0]))
                U = np.eye(n) if Z is None else Z
                lsq = DampedSVD(U, np.full(r, sw), np.eye(r), np.full(r, 1.0 / sw), r, sw, 0.0)
            else:
                lsq = self._lsq(M, scale)
            eps = max(eps, lsq.damping**2)
        if shortcut:
            u = np.zeros(r) if lsq is None or rhs is None else _ridge(lsq, rhs, eps)
            if self._level_feasible(lv, u, x, Z, box, fixed, pinned, selection):
                return u, lsq
        # the QP's arrays in one compiled call (HK.level_qp_arrays): the level's rows C(x + Zu) − d ≤ w with the
        # slack measured from its value at u = 0 (w = w₀ + w', w₀ = max(Cx − d, 0): u = 0, w' = 0 is feasible and
        # w' lives on the scale of u; a level whose slack is 19.5 while the limits left u a 1e-6-wide window was
        # otherwise called infeasible by proxsuite; exact, ½‖w₀ + w'‖² = ½‖w'‖² + w₀ᵀw' + const). Below level 0 the
        # rows that carry the levels above and the limits get the margin max(·, 0) + tol: x (from a backend's finite
        # tolerance) may sit up to that tolerance outside them, and without the clamp a level could be declared
        # primal-infeasible (proxsuite, osqp) though u = 0 always solves it.
        F, f = self._stacked(fixed, n)
        mode = 0 if Z is None else (1 if selection is not None else 2)
        if M is not None and rhs is not None and not p and scale != 1.0:
            # a level of least squares only: its objective divided by its scale², the same optimum, posed to the
            # backend on the scale of a unit weight (a weight of 1e-6 left daqp's absolute tolerances 0.3 off)
            M, rhs, eps = M / scale, rhs / scale, eps / (scale * scale)
        P, q, G, h, lb, ub = HK.level_qp_arrays(
            (M if M is not None else np.zeros((0, r)), rhs if rhs is not None else np.zeros(0), eps),
            (lv.C if p else np.zeros((0, n)), lv.d if p else np.zeros(0)),
            x,
            (Z if Z is not None else _NO_BASIS, mode, selection if selection is not None else _NO_SELECTION),
            (F, f),
            (box.lb, box.ub, ~pinned),
            self.slack_tolerance,
        )
        nvar = r + p
        if orthonormal and lsq is not None and rhs is not None:  # ½‖Zu − (z − x)‖²: MᵀM = I, Mᵀ rhs = Zᵀ(z − x)
            P.reshape(-1)[: r * (nvar + 1) : nvar + 1] += 1.0
            q[:r] = -(lsq.U.T @ rhs)
        prob = QPProblem(P, q, G, h, np.zeros((0, nvar)), np.zeros(0), lb, ub, f"hqp level {lv.priority}")
        try:
            sol = self._solve_qp(prob)
        except SolverError:
            sol = self._regularized_retry(prob, r, eps, diag)
        diag.qp += 1
        diag.iterations += max(sol.iterations, 0)
        diag.backend = sol.backend
        return sol.x[:r], lsq

    def _level_feasible(
        self,
        lv: Level,
        u: np.ndarray,
        x: np.ndarray,
        Z: np.ndarray | None,
        box: LimitBox,
        fixed: list[tuple[np.ndarray, np.ndarray]],
        pinned: np.ndarray,
        selection: np.ndarray | None,
    ) -> bool:
        """Whether the level QP's unconstrained optimum u (with slack w = 0) satisfies every row of the level QP.

        The rows are those :meth:`_level_qp` poses, to the same margins: the level's own inequalities
        C(x + Z u) ≤ d (w = 0), the levels above C Z u ≤ max(d − C x, 0) + tol, and the limits (native bounds on u
        at the first level, the rows ±Z_j u ≤ margin below it). Then (u, w = 0) meets the KKT conditions with every
        multiplier zero: it is the QP's optimum, and the backend is not called.
        """
        n = x.shape[0]
        step = u if Z is None else Z @ u
        F, f = self._stacked(fixed, n)
        C, d = (lv.C, lv.d) if lv.p else (F[:0], f[:0])
        native = Z is None or selection is not None
        return bool(
            HK.level_rows_ok(
                step, x, (box.lb, box.ub, ~pinned), native, (C, d), (F, f), self.slack_tolerance, _FEASIBLE
            )
        )

    @staticmethod
    def _stacked(fixed: list[tuple[np.ndarray, np.ndarray]], n: int) -> tuple[np.ndarray, np.ndarray]:
        """The rows of the levels above, (C, d) stacked ((0, n) and (0,) without any)."""
        if not fixed:
            return np.zeros((0, n)), np.zeros(0)
        if len(fixed) == 1:
            return fixed[0]
        return np.vstack([c for c, _ in fixed]), np.concatenate([d for _, d in fixed])

    def _py_qp_cascade(
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
                # a level whose unconstrained optimum keeps its rows needs no QP, the top level too: that optimum is
                # the SVD's ridge solution, exact to rounding, where the backend's answer on MᵀM + εI is off by
                # cond·1e-16 (2e-8 on a top level of condition 1e9). On the snake it is a clearance (level 1) or the
                # null objective that binds, never the pose (0 of 222 QP steps at n = 10, 40, 160)
                u, lsq = self._level_qp(lv, x, Z, r, box, fixed, diag, pinned, selection, self.level_shortcut)
            except SolverError as exc:
                if lv is levels[0]:
                    raise  # nothing of the cascade is worth keeping: the base falls back to the closed form
                notes.append(f"level {lv.priority} skipped ({exc})")
                continue
            x = x + (u if Z is None else Z @ u)
            if lv.p:
                w = np.maximum(lv.C @ x - lv.d, 0.0)
                fixed.append((lv.C, lv.d + w + self.slack_tolerance))
                worst = float(w.max())  # (the method: np.max costs its dispatch on a few rows)
                if worst > CONTRADICTION_TOLERANCE:  # the documented relaxation: StepResult.relaxed, no fallback
                    diag.contradicted[lv.priority] = worst
                    rows = [lv.c_names[i] for i in np.flatnonzero(w > CONTRADICTION_TOLERANCE)]
                    diag.relaxed += [row.split(":")[0] for row in rows]
            if lsq is not None:
                self._note(lv, lsq, r, Z is not None and selection is None, diag)
                Z = lsq.null_basis if Z is None else Z @ lsq.null_basis
                r = Z.shape[1]
                selection = None
        return x, notes


class _Reference(_PythonCascade):
    """hqp by the previous general path (module docstring). It keeps the level shortcut: a level QP whose
    unconstrained optimum keeps its rows is that optimum, which the backend returns only to its accuracy on MᵀM + εI
    (2e-8 off on a top level of condition 1e9, where the SVD's ridge is 2e-15 off); the shortcut's exactness is
    tested on its own (:func:`test_level_shortcut_is_the_exact_optimum_of_the_level_qp`)."""

    def __init__(self, **kw: object) -> None:
        super().__init__(**kw)  # type: ignore[arg-type]
        self.identity_levels = False

    def solve(self, robot: rk.RobotModel, stack: rk.TaskStack, t: float, dt: float) -> rk.StepResult:
        return QPResolverBase.solve(self, robot, stack, t, dt)  # the shared template, not hqp's lean step

    def _resolve(self, built: HQPBuild, diag: QPDiagnostics) -> tuple[np.ndarray, str | None]:
        levels, box, n = built.levels, built.box, built.n
        x = _reference_closed_cascade(self, levels, n, diag)
        tol = 1e-12
        if box.contains(x, tol) and all(not lv.p or bool((lv.C @ x <= lv.d + tol).all()) for lv in levels):
            return x, None
        diag.level_sigma_min.clear()
        diag.damped_levels.clear()
        diag.rank_loss_levels.clear()
        x, notes = self._py_qp_cascade(levels, box, n, diag)
        return x, ("hqp: " + "; ".join(notes)) if notes else None

    def _diagnose(self, built: HQPBuild, dq: np.ndarray, diag: QPDiagnostics) -> None:
        for lv in built.levels:
            diag.level_residuals[lv.priority] = lv.residual(dq)


def _stack(robot: rk.RobotModel, rng: np.random.Generator, depth: int, bound: bool) -> rk.TaskStack:
    """Tip position (0) > tip orientation (1) > a 1-row joint target (2) > gradients (null objective), with a bound
    subtask (a joint kept under a bound, at level 1) when ``bound``."""
    names = robot.joint_names
    tasks: list[rk.Task] = [rk.FrameTask(tip(robot), rk.Line(rng.uniform(-0.5, 0.5, 3)), axes="position", gain=1.0)]
    if depth > 1:
        ori = rk.FrameTask(tip(robot), rk.Hold(), axes="orientation", gain=1.0, name="orientation")
        ori.priority = 1  # type: ignore[attr-defined]
        tasks.append(ori)
    if depth > 2:
        tasks.append(rk.PotentialTask(rk.JointValue(names[1], 0.0), target=0.0, rate=5.0, priority=2, name="j2"))
    subs: list[rk.Subtask] = []
    if depth > 3:
        subs.append(rk.GradientSubtask(rk.JointValue(names[0], 1.0), gain=-3.0))
        subs.append(rk.GradientSubtask(rk.JointCentering(), gain=-1.0))
    if bound:
        subs.append(rk.BoundSubtask(rk.JointValue(names[2], 0.0, name="b3"), upper=float(rng.uniform(0.0, 0.5)),
                                    rate=10.0, priority=1))  # fmt: skip
    return rk.TaskStack(tasks, subs)


def _compare(
    robot: rk.RobotModel,
    stack: rk.TaskStack,
    q: np.ndarray,
    tol: float = 1e-10,
    steps: int = 1,
    shortcut: bool = True,
    complement: bool = False,
    qp_tol: float | None = None,
    certified_qr: bool = True,
    **kw: object,
) -> str:
    """Step both resolvers from q (``steps`` steps, the reference's q̇ integrated); q̇, fallback and every numeric
    diagnostic agree to ``tol`` at every step; the path taken at the last. Without ``shortcut`` both send every
    level of the constrained cascade to the backend; with ``complement`` the lean cascade poses its level QPs in
    joint space below the first level of least squares (``complement_min_n``), whatever the robot's size; without
    ``certified_qr`` the lean cascade factors every level by its SVD, as the reference does (the same null bases)."""
    lean, ref = HierarchicalQPResolver(**kw), _Reference(**kw)  # type: ignore[arg-type]
    lean.certified_qr = certified_qr
    if complement:
        lean.complement_min_n, lean.complement_fraction = 0, 0.0
    for res in (lean, ref):
        res.level_shortcut = shortcut
        prepared(res, robot, stack, q)
    path = ""
    for k in range(steps):
        a = lean.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
        b = ref.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
        path = _agree(a, b, tol, qp_tol)
        q = robot.integrate(q, b.dq, 0.01)
    return path


def _agree(a: rk.StepResult, b: rk.StepResult, tol: float, qp_tol: float | None = None) -> str:
    """q̇, fallback and diagnostics of the lean step ``a`` and the reference ``b`` agree; the reference's path.

    With ``qp_tol``, a step that called the backend is held to what the hierarchy decides (:func:`_same_optima`)
    rather than to the same q̇: see :func:`test_lean_step_equals_the_general_path_on_random_robots`."""
    if qp_tol is not None and b.info["qp"] > 0:
        _same_optima(a, b, qp_tol)
        return "qp"
    scale = max(1.0, float(np.max(np.abs(b.dq))))
    np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=tol * scale)
    assert (a.fallback is None) == (b.fallback is None), (a.fallback, b.fallback)
    closed = b.info["qp"] == 0
    keys = set(b.info) - {"qp", "iterations", "backend", "rank_loss_levels", "active_limits", "damped_levels"}
    assert set(a.info) >= keys
    for key in keys:
        va, vb = a.info[key], b.info[key]
        if isinstance(vb, float) and np.isfinite(vb):
            assert abs(float(va) - vb) <= tol * max(1.0, abs(vb)), (key, va, vb)  # type: ignore[arg-type]
        elif isinstance(vb, float):
            assert va == vb, (key, va, vb)
    assert a.info["rank_loss_levels"] == b.info["rank_loss_levels"]
    assert a.info["active_limits"] == b.info["active_limits"]
    assert a.info.get("damped_levels") == b.info.get("damped_levels")
    assert a.sigma_min == pytest.approx(b.sigma_min, rel=tol, abs=tol) or a.sigma_min == b.sigma_min
    assert a.damped == b.damped
    if closed:
        assert a.info["qp"] == 0
    assert a.info["qp"] <= b.info["qp"]
    return "closed" if closed else "qp"


def _same_optima(a: rk.StepResult, b: rk.StepResult, tol: float) -> None:
    """Two constrained steps with the same optimum of every level: the residual of each level and the slack of each
    contradicted one to ``tol`` (relative, or absolute below 1), ‖q̇‖ to ``tol``, q̇ to 10·``tol``, the same
    fallback; the lean step calls the backend no more often."""
    assert (a.fallback is None) == (b.fallback is None), (a.fallback, b.fallback)
    members = [{r for r in res.relaxed if not r.endswith("(backend retried)")} for res in (a, b)]
    assert members[0] == members[1], (a.relaxed, b.relaxed)
    for key in (k for k in b.info if k.startswith("residual_L")):
        assert a.info[key] == pytest.approx(b.info[key], rel=tol, abs=tol), key
    ca, cb = a.info.get("contradicted_levels", {}), b.info.get("contradicted_levels", {})
    assert isinstance(ca, dict) and isinstance(cb, dict) and ca.keys() == cb.keys()
    for level, slack in cb.items():
        assert ca[level] == pytest.approx(slack, rel=tol, abs=tol), level
    assert np.linalg.norm(a.dq) == pytest.approx(np.linalg.norm(b.dq), rel=tol, abs=tol)
    np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=10 * tol * max(1.0, float(np.max(np.abs(b.dq)))))
    assert 0 < a.info["qp"] <= b.info["qp"] or a.info["qp"] == b.info["qp"]

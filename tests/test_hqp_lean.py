"""hqp's lean step against the previous general path: the same q̇ and diagnostics to 1e-10.

The lean step solves the unconstrained cascade in one compiled call (``hqp_kernels.closed_cascade``, a certified QR
where no direction is damped), builds its Level records and σ_min/rank-loss diagnostics only when they are read, and
keeps a level QP's unconstrained optimum when it satisfies the level's rows. The reference here is the path it
replaced: the cascade level by level in Python through ``kernels.lsq_level`` on stacked Level records, every level of
the constrained cascade that the shortcut does not settle solved by the backend.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import redundik as rk
from redundik.errors import SolverError
from redundik.kinematics import DHRow
from redundik.resolvers.kernels import lsq_level
from redundik.resolvers.linalg import DampedSVD, damped_svd
from redundik.resolvers.qp.base import QPDiagnostics, QPResolverBase
from redundik.resolvers.qp.hqp import HK, HierarchicalQPResolver, HQPBuild
from redundik.resolvers.qp.hqp_constrained import _FEASIBLE, CONTRADICTION_TOLERANCE
from redundik.resolvers.qp.limits import LimitBox
from redundik.resolvers.qp.problem import QPProblem
from redundik.resolvers.qp.terms import Level
from tests.test_qp_helpers import prepared, random_robot, tip

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


@pytest.mark.parametrize("seed", range(40))
def test_lean_step_equals_the_general_path_on_random_robots(seed: int) -> None:
    """Closed-form steps to 1e-10 with every diagnostic; steps that call the backend to the same optimum of every
    level (1e-6). The two paths pose the same level QPs in different but equivalent forms (the buffer's stacked form
    and ``QPProblem``'s), and where the optimum sits on several nearly tied limits the solver ends at different points
    of its tolerance: over 600 seeds of this construction, 3 steps differed by up to 2.6e-8 in q̇ with LAPACK's null
    bases, 5 by up to 9.5e-7 with the Jacobi ones (seed 18: level 0's residual 4e-7 apart relative, the other path's
    the nearer in one case, this one's in another; quadprog on both paths: 1e-7 in q̇, 1e-15 in the residuals)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 9))
    tight = seed % 3 == 0  # tight velocity limits: the QP path, level by level
    robot = random_robot(rng, n, velocity=float(rng.uniform(0.2, 0.6)) if tight else np.inf)
    q = robot.random_configuration(rng)
    if seed % 4 == 1:  # near a singularity: the tip frame's joints almost aligned
        q = q * 1e-4
    stack = _stack(robot, rng, depth=int(rng.integers(1, 5)), bound=bool(seed % 2))
    if seed % 5 == 2:  # a rate limit: the window of the previous q̇ in the box (three steps)
        _compare(
            robot, stack, q, steps=3, qp_tol=1e-6, limits=rk.JointLimits(acceleration=float(rng.uniform(2.0, 20.0)))
        )
    else:
        _compare(robot, stack, q, qp_tol=1e-6)


@pytest.mark.parametrize("seed", range(12))
def test_lean_step_equals_the_general_path_with_pinned_joints(seed: int) -> None:
    """A joint whose limits are one value (its q̇ pinned to 0): the constrained cascade with the joint fixed — with
    the reference's SVD at every level to 1e-10, and with the certified QR (other null bases of the same spaces) to
    the same optimum of every level: their q̇ may differ by the level QPs' conditioning (seed 11: 1.5e-6 with daqp,
    2.5e-7 with quadprog, the residuals 1e-9 apart, the QR's level 0 the lower).

    Seed 11's ‖q̇‖ is held to 3e-6, not 1e-6: moving q by 1e-15 rad (random, 20 draws) moves the two paths' ‖q̇‖
    apart by up to 1.9e-6 relative on pin 4.1 and on pin 3.8 alike (8.5e-7 and 1.1e-6 unperturbed), while every
    level's residual stays within 1.3e-8: the level QPs' conditioning, not the QR, and not a Pinocchio version."""
    qp_tol = 3e-6 if seed == 11 else 1e-6
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(5, 9))
    robot = random_robot(rng, n, velocity=float(rng.uniform(0.3, 2.0)))
    q = robot.random_configuration(rng)
    j = int(rng.integers(n))
    name = robot.joint_names[j]
    limits = rk.JointLimits(lower={name: float(q[j])}, upper={name: float(q[j])})
    stack = _stack(robot, rng, depth=int(rng.integers(1, 5)), bound=bool(seed % 2))
    assert _compare(robot, stack, q, shortcut=False, certified_qr=False, limits=limits) == "qp"
    assert _compare(robot, stack, q, shortcut=False, qp_tol=qp_tol, limits=limits) == "qp"
    # (the cascade may settle every level itself)
    assert _compare(robot, stack, q, certified_qr=False, limits=limits) in ("qp", "closed")
    assert _compare(robot, stack, q, qp_tol=qp_tol, limits=limits) in ("qp", "closed")


def _complement_case(seed: int) -> tuple[rk.RobotModel, rk.TaskStack, np.ndarray, dict[str, object], bool]:
    """A random robot, stack and start for the complement mode's tests: pinned joints, rate windows, bound
    subtasks (often contradicted: a joint pushed past its bound) and the null-space objective; with or without the
    level shortcut."""
    rng = np.random.default_rng(300 + seed)
    n = int(rng.integers(5, 10))
    robot = random_robot(rng, n, velocity=float(rng.uniform(0.2, 0.8)))
    q = robot.random_configuration(rng)
    kw: dict[str, object] = {}
    if seed % 3 == 1:
        j = int(rng.integers(n))
        name = robot.joint_names[j]
        kw["limits"] = rk.JointLimits(lower={name: float(q[j])}, upper={name: float(q[j])})
    elif seed % 3 == 2:
        kw["limits"] = rk.JointLimits(acceleration=float(rng.uniform(2.0, 20.0)))
    stack = _stack(robot, rng, depth=int(rng.integers(1, 5)), bound=bool(seed % 2))
    return robot, stack, q, kw, bool(seed % 4 < 2)


@pytest.mark.parametrize("seed", range(24))
def test_lean_step_in_the_complement_mode_equals_the_general_path(seed: int) -> None:
    """The level QPs posed in joint space (the limits as bounds, the fixed directions as equalities: ``hqp_kernels.
    level_qp_joint_into``) have the optimum of the general path's, with every diagnostic. The regulariser is 1e-4
    here, so that the directions it alone decides are decided to the solver's accuracy (see the next test)."""
    robot, stack, q, kw, shortcut = _complement_case(seed)
    _compare(robot, stack, q, tol=1e-8, steps=3, shortcut=shortcut, complement=True, regularization=1e-4, **kw)


@pytest.mark.parametrize("seed", range(24))
def test_complement_mode_at_the_default_regularization_keeps_every_level_optimum(seed: int) -> None:
    """At the default regulariser (1e-9) the directions that no level's rows decide are set by ε‖q̇‖² alone, which
    daqp resolves to ~1e-7 in either form (~1e-5 beside a level contradicted by a slack of 50: the slack's ½‖w‖²
    outweighs ε‖q̇‖² by 1e12): there the two forms differ, neither nearer the minimum norm. What the levels decide
    is the same: the residual of every level and the slack of every contradicted one, to 1e-8, the QP count, and
    the norm of q̇ to 1e-6."""
    robot, stack, q, kw, shortcut = _complement_case(seed)
    lean, ref = HierarchicalQPResolver(**kw), _Reference(**kw)  # type: ignore[arg-type]
    lean.complement_min_n, lean.complement_fraction = 0, 0.0
    for res in (lean, ref):
        res.level_shortcut = shortcut
        prepared(res, robot, stack, q)
    for k in range(3):
        a = lean.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
        b = ref.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
        residuals = [key for key in b.info if key.startswith("residual_L")]
        for key in residuals:
            assert a.info[key] == pytest.approx(b.info[key], rel=1e-8, abs=1e-8), key
        contradicted_a = a.info.get("contradicted_levels", {})
        contradicted_b = b.info.get("contradicted_levels", {})
        assert isinstance(contradicted_a, dict) and isinstance(contradicted_b, dict)
        assert contradicted_a.keys() == contradicted_b.keys()
        for level, slack in contradicted_b.items():
            assert contradicted_a[level] == pytest.approx(slack, rel=1e-8), level
        assert (a.info["qp"], a.fallback is None) == (b.info["qp"], b.fallback is None)
        assert np.linalg.norm(a.dq) == pytest.approx(np.linalg.norm(b.dq), rel=1e-6)
        np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=1e-4)
        q = robot.integrate(q, b.dq, 0.01)


@pytest.mark.parametrize("theta", [0.0, 1e-9, 1e-6, 1e-4, 1e-3, 5e-3, 2e-2])
def test_lean_step_equals_the_general_path_near_the_straight_arm(theta: float) -> None:
    """The chapter's 3R arm stretched (θ2 = θ3 ≈ 0): σ_min → 0, damped directions, rank truncated at θ = 0."""
    robot = rk.from_dh([DHRow(str(i + 1), a=1.0) for i in range(3)], name="planar3r")
    q = np.array([0.3, theta, -theta])
    for sub in (
        [rk.GradientSubtask(rk.JointSine2("3"), gain=1.0)],
        [rk.TargetSubtask(rk.JointValue("2", 0.5), target=0.0, rate=2.0)],
        [],
    ):
        stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")], sub)
        _compare(robot, stack, q, limits=False)


def test_lean_diagnostics_are_computed_only_when_read(monkeypatch: pytest.MonkeyPatch) -> None:
    """No Level record and no SVD of a level on a step whose diagnostics are not read; exact values once read."""
    from redundik.resolvers.qp import terms

    built = []
    level = terms.StepRows._level
    monkeypatch.setattr(terms.StepRows, "_level", lambda self, k: built.append(k) or level(self, k))
    robot = random_robot(np.random.default_rng(5), 7)
    q = robot.random_configuration(np.random.default_rng(6))
    stack = _stack(robot, np.random.default_rng(7), depth=4, bound=False)
    res = HierarchicalQPResolver(limits=False)
    prepared(res, robot, stack, q)
    out = res.step(robot, stack, q, 0.0, 0.01)
    assert out.__dict__["pending"] is not None and not built and out.info["qp"] == 0
    J = robot.frame_jacobian(tip(robot))[:3]
    assert out.info["sigma_min_L0"] == pytest.approx(np.linalg.svd(J, compute_uv=False)[-1], rel=1e-10)
    assert built  # the Level records, built on the first read


def test_hqp_kernels_report_their_first_run_cost() -> None:
    from redundik.resolvers import hqp_kernels

    cost = hqp_kernels.first_run_cost()
    assert set(cost) == {"closed_cascade", "level_rows_ok", "level_qp_arrays", "clearance_into", "qp_cascade_run"}
    assert all(v >= 0.0 for v in cost.values())


def _rich_stack(robot: rk.RobotModel, rng: np.random.Generator) -> rk.TaskStack:
    """Every kind of row the lean buffers take: tasks on three levels, a target subtask, two bound subtasks (one
    two-sided) on two levels, gradients (the null-space objective)."""
    names = robot.joint_names
    base = _stack(robot, rng, depth=4, bound=True)
    subs: list[rk.Subtask] = list(base.subtasks)
    subs.append(rk.TargetSubtask(rk.JointValue(names[3], 0.0, name="t4"), target=0.1, rate=2.0, priority=1))
    subs.append(rk.BoundSubtask(rk.JointValue(names[1], 0.0, name="b2"), lower=-0.4, upper=0.4, rate=5.0, priority=2))
    # lower bounds only (the row the lean gather writes itself): γ = 1/dt (rate 0), K, and K capped at 1/dt
    subs.append(rk.BoundSubtask(rk.JointValue(names[4], 0.0, name="b5"), lower=-0.3, priority=1))
    subs.append(rk.BoundSubtask(rk.JointCentering(name="c"), lower=0.05, rate=3.0, priority=2))
    subs.append(rk.BoundSubtask(rk.JointValue(names[5], 0.0, name="b6"), lower=-0.2, rate=500.0, priority=2))
    return rk.TaskStack(list(base.tasks), subs)


@pytest.mark.parametrize("mixed", [False, True])
def test_lean_gather_lays_out_the_rows_of_gather_rows_and_fill(mixed: bool) -> None:
    """The lean step's one-pass ``_Plan.gather`` writes the buffers ``gather_rows`` + ``_Plan.fill`` write, and its
    ``step_rows`` are those of ``gather_rows`` (the same arrays per level), over several states; ``mixed``: the
    null-space objective shares its level with a task (its identity rows after the task's)."""
    from redundik.resolvers.qp.hqp import _Plan
    from redundik.resolvers.qp.terms import gather_rows

    rng = np.random.default_rng(3)
    robot = random_robot(rng, 7)
    stack = _rich_stack(robot, rng)
    res = HierarchicalQPResolver()
    q = robot.random_configuration(rng)
    prepared(res, robot, stack, q)
    layout = res.layout(stack)
    if mixed:  # (a layout by hand: TaskStack.layout gives the objective a level of its own)
        from dataclasses import replace

        *above, last = layout.levels
        assert last.null_objective and not (last.tasks or last.targets or last.bounds)
        above[-1] = replace(above[-1], null_objective=True)
        layout = replace(layout, levels=above)
    assert any(_Plan(layout, robot.nv, np.zeros(5)).mixed) == mixed
    lean, ref = _Plan(layout, robot.nv, np.zeros(5)), _Plan(layout, robot.nv, np.zeros(5))
    for k in range(4):
        q = robot.random_configuration(rng)
        robot.update(q)
        terms = stack.evaluate(robot, 0.1 * k)
        z, targets, bounds = lean.gather(robot, stack, terms, 0.01)
        assert sum(type(b[1]) is slice for b in bounds) == 5  # every bound on a potential: written by rows_into
        rows = gather_rows(robot, stack, terms, layout, 0.01)
        ref.fill(rows)
        np.testing.assert_array_equal(lean.meta, ref.meta)
        M, P = int(ref.meta[0, -1]), int(ref.meta[1, -1])
        assert M and P
        for a, b in ((lean.A, ref.A), (lean.b, ref.b), (lean.w, ref.w)):
            np.testing.assert_array_equal(a[:M], b[:M])
        for a, b in ((lean.C, ref.C), (lean.d, ref.d)):
            np.testing.assert_array_equal(a[:P], b[:P])
        got = lean.step_rows(terms, z, targets, bounds)
        np.testing.assert_array_equal(got.z, rows.z)
        for la, lb_ in zip(got.levels, rows.levels, strict=True):
            assert (la.priority, la.names, la.c_names) == (lb_.priority, lb_.names, lb_.c_names)
            for f in ("J", "v", "w", "C", "d"):
                np.testing.assert_array_equal(getattr(la, f), getattr(lb_, f))
            assert (la.z is None) == (lb_.z is None)


class _BarrierPotential(rk.Barrier, rk.Potential):
    """A source that is both (as the collision and balance barriers): ``BoundSubtask.values`` reads it as a barrier."""

    name = "both"

    def __init__(self, joint: int) -> None:
        self.joint = joint

    def value(self, robot: rk.RobotModel) -> float:
        return float(robot.q[self.joint])

    def gradient(self, robot: rk.RobotModel) -> np.ndarray:
        g = np.zeros(robot.nv)
        g[self.joint] = 1.0
        return g

    def evaluate(self, robot: rk.RobotModel) -> rk.BarrierTerm:
        h = np.array([0.5 - robot.q[self.joint], 0.7 + robot.q[self.joint]])
        H = np.zeros((2, robot.nv))
        H[0, self.joint], H[1, self.joint] = -1.0, 1.0
        return rk.BarrierTerm(h, H, ["hi", "lo"], np.array([3.0, 400.0]))


def test_lean_gather_leaves_other_bound_rows_to_rows() -> None:
    """The lean gather lets ``BoundSubtask.rows_into`` write a potential's rows (an upper and a two-sided bound here)
    but takes ``rows()`` for a barrier that is also a potential, and the buffers hold the rows of ``gather_rows``
    bitwise; the step agrees with the general path on such a stack. (A lower bound assigned to the barrier's subtask
    after construction, which this test used to set to see it ignored, is now refused as the constructor refuses
    it.)"""
    from redundik.resolvers.qp.hqp import _Plan
    from redundik.resolvers.qp.terms import gather_rows

    rng = np.random.default_rng(11)
    robot = random_robot(rng, 6)
    names = robot.joint_names
    barrier = rk.BoundSubtask(_BarrierPotential(2), priority=1)
    with pytest.raises(rk.TaskError, match="a barrier is kept ≥ 0"):
        barrier.lower = 0.0
    assert barrier.lower is None
    subs: list[rk.Subtask] = [
        barrier,
        rk.BoundSubtask(rk.JointValue(names[1], 0.0, name="u"), upper=0.3, rate=5.0, priority=1),
        rk.BoundSubtask(rk.JointValue(names[3], 0.0, name="two"), lower=-1.0, upper=0.4, priority=1),
        rk.GradientSubtask(rk.JointCentering(), gain=-1.0),
    ]
    stack = rk.TaskStack([rk.FrameTask(tip(robot), rk.Line([0.1, 0.2, -0.1]), axes="position", gain=1.0)], subs)
    res = HierarchicalQPResolver()
    q = robot.random_configuration(rng)
    prepared(res, robot, stack, q)
    layout = res.layout(stack)
    plan = _Plan(layout, robot.nv, np.zeros(5))
    terms = stack.evaluate(robot, 0.0)
    _, _, bounds = plan.gather(robot, stack, terms, 0.01)
    assert [type(b[1]) is slice for b in bounds] == [False, True, True]  # the barrier's rows from rows()
    rows = gather_rows(robot, stack, terms, layout, 0.01)
    P = int(plan.meta[1, -1])
    assert P == 5
    np.testing.assert_array_equal(plan.C[:P], np.vstack([r[0] for lv in rows.ineq for r in lv]))
    np.testing.assert_array_equal(plan.d[:P], np.concatenate([r[1] for lv in rows.ineq for r in lv]))
    for seed in range(4):
        _compare(robot, stack, robot.random_configuration(np.random.default_rng(seed)), steps=2)


@pytest.mark.parametrize(
    ("weight", "first", "epsilon", "applies"),
    [
        (1.0, False, 1e-2, True),
        (0.01, False, 1e-2, True),
        (0.01, True, 1e-2, True),
        (2e-5, False, 1e-2, True),
        (1e-4, True, 1e-2, True),
        (0.3, False, 1.0, False),
        (0.3, True, 2.0, False),
    ],
)
def test_lean_identity_level_equals_the_general_path(weight: float, first: bool, epsilon: float, applies: bool) -> None:
    """A posture given a level of its own (rows √w I): the lean cascade solves it as Zᵀ(b − x) without a
    factorisation where its singular values √w are not damped — at every weight, the rule being relative to the
    level's largest weight (σ/√w = 1 ≥ ε) — and not where ε = 1 (the margin) or ε > 1 (damped), with the same q̇ and
    diagnostics as the general path, at the top level (``first``) or below a frame task and a bound level, inside
    the box and against the limits."""
    from redundik.resolvers.hqp_kernels import identity_rows

    rng = np.random.default_rng(21)
    robot = random_robot(rng, 7)
    posture = rk.PostureTask(gain=2.0, weight=weight, priority=0 if first else 2)
    subs: list[rk.Subtask] = [] if first else [
        rk.BoundSubtask(rk.JointValue(robot.joint_names[2], 0.0, name="b3"), upper=0.6, rate=10.0, priority=1)
    ]  # fmt: skip
    tasks: list[rk.Task] = [posture] if first else [
        rk.FrameTask(tip(robot), rk.Line([0.2, -0.1, 0.1]), axes="position", gain=1.0), posture
    ]  # fmt: skip
    stack = rk.TaskStack(tasks, subs)
    qp_steps = 0
    for seed in range(6):
        q = robot.random_configuration(np.random.default_rng(seed))
        posture.set_target(robot.random_configuration(np.random.default_rng(50 + seed)))
        res = HierarchicalQPResolver(epsilon=epsilon)
        prepared(res, robot, stack, q)
        plan = res._plan_for(res.layout(stack), robot.nv)
        plan.gather(robot, stack, stack.evaluate(robot, 0.0), 0.01)
        k = len(plan.members) - 1
        s = int(plan.meta[0, k])
        assert bool(identity_rows(plan.A, plan.w, s, robot.nv, res.epsilon * np.sqrt(weight))) == applies
        tight = rk.JointLimits(velocity_limits={n: 0.3 for n in robot.joint_names}) if seed % 2 else None
        _compare(robot, stack, q, steps=2, limits=tight, epsilon=epsilon)
        if seed % 2:  # the constrained cascade: the posture level factored exactly, not by an SVD, where it applies
            from redundik.resolvers.hqp_kernels import QS_DAMPING, QS_SIGMA, QS_SOLVED

            qp = HierarchicalQPResolver(
                limits=rk.JointLimits(velocity_limits=dict.fromkeys(robot.joint_names, 0.3)), epsilon=epsilon
            )
            prepared(qp, robot, stack, q)
            qp._native_cascade = lambda *args: None  # type: ignore[method-assign]  # (the template, seen below)
            seen: list[HQPBuild] = []
            cascade = qp._qp_cascade
            qp._qp_cascade = lambda built, diag, seen=seen, cascade=cascade: (  # type: ignore[method-assign]
                seen.append(built),
                cascade(built, diag),
            )[1]
            if qp.step(robot, stack, q, 0.0, 0.01).info["qp"]:
                qp_steps += 1
                stats = seen[-1].qp_stats
                assert stats is not None
                posture_level = stats[len(plan.members) - 1]
                if posture_level[QS_SOLVED]:
                    if applies:  # the exact factors (Z, √w, I): σ = √w to the bit, nothing damped
                        assert posture_level[QS_SIGMA] == np.sqrt(weight) and posture_level[QS_DAMPING] == 0.0
                    elif epsilon > 1.0:  # the SVD, damped (σ/√w = 1 < ε)
                        assert posture_level[QS_DAMPING] > 0.0
    assert qp_steps


class _BufferedGradient(rk.Potential):
    """A potential that returns one gradient array, rewritten at every call (a user's preallocated buffer)."""

    name = "buffered"

    def __init__(self, joint: int) -> None:
        self.joint = joint
        self._g: np.ndarray | None = None

    def value(self, robot: rk.RobotModel) -> float:
        return float(np.sum(robot.q[: self.joint + 1]))

    def gradient(self, robot: rk.RobotModel) -> np.ndarray:
        if self._g is None:
            self._g = np.zeros(robot.nv)
        self._g[:] = 0.0
        self._g[: self.joint + 1] = 1.0 + robot.q[: self.joint + 1] ** 2
        return self._g


def test_lean_diagnostics_read_late_are_those_of_their_step() -> None:
    """Diagnostics read after later steps are those the step would have reported at once, also when a bound
    subtask's potential rewrites its gradient array in place at every call (the lean row keeps its own copy)."""
    rng = np.random.default_rng(31)
    robot = random_robot(rng, 6)
    stack = rk.TaskStack(
        [rk.FrameTask(tip(robot), rk.Line([0.1, 0.0, -0.1]), axes="position", gain=1.0)],
        [rk.BoundSubtask(_BufferedGradient(3), lower=-50.0, rate=2.0, priority=1),
         rk.GradientSubtask(rk.JointCentering(), gain=-1.0)],
    )  # fmt: skip
    q0 = robot.random_configuration(rng)
    bound = stack.subtasks[0]
    assert isinstance(bound, rk.BoundSubtask)
    for lower, limits in (
        (-50.0, False),
        (float(np.sum(q0[:4])) + 10.0, {"velocity_limits": dict.fromkeys(robot.joint_names, 0.3)}),
    ):
        # inactive (the closed form), then out of reach at 0.3 rad/s (the QPs: the level contradicted, its residual
        # read from its rows)
        bound.lower = lower
        now, late = HierarchicalQPResolver(limits=limits), HierarchicalQPResolver(limits=limits)
        prepared(now, robot, stack, q0)
        prepared(late, robot, stack, q0)
        q, eager, pending = q0, [], []
        for k in range(3):
            a = now.step(robot, stack, q, 0.01 * k, 0.01)
            eager.append((dict(a.info), a.fallback))
            pending.append(late.step(robot, stack, q, 0.01 * k, 0.01))
            q = robot.integrate(q, a.dq, 0.01)
        closed = lower < 0
        assert all((e["qp"] == 0) == closed for e, _ in eager)
        assert closed or all(e["residual_L1"] > 1e-3 for e, _ in eager)
        for (e, fallback), res in zip(eager, pending, strict=True):
            assert dict(res.info) == e and res.fallback == fallback


def test_lean_gather_rows_held_across_later_gathers_and_fills() -> None:
    """The rows ``rows_into`` wrote into the plan's buffers are copied before the buffers are written again while
    a step's record is held: its ``step_rows`` read after later gathers (and a fill) are those of its own state."""
    from redundik.resolvers.qp.hqp import _Plan
    from redundik.resolvers.qp.terms import gather_rows

    rng = np.random.default_rng(41)
    robot = random_robot(rng, 7)
    stack = _rich_stack(robot, rng)
    res = HierarchicalQPResolver()
    prepared(res, robot, stack, robot.random_configuration(rng))
    layout = res.layout(stack)
    plan = _Plan(layout, robot.nv, np.zeros(5))
    held, refs = [], []
    for k in range(3):
        robot.update(robot.random_configuration(rng))
        terms = stack.evaluate(robot, 0.1 * k)
        held.append((terms, *plan.gather(robot, stack, terms, 0.01)))
        refs.append(gather_rows(robot, stack, terms, layout, 0.01))
        if k == 1:
            plan.fill(refs[0])
    for (terms, z, targets, bounds), ref in zip(held, refs, strict=True):
        got = plan.step_rows(terms, z, targets, bounds)
        for la, lb_ in zip(got.levels, ref.levels, strict=True):
            np.testing.assert_array_equal(la.C, lb_.C)
            np.testing.assert_array_equal(la.d, lb_.d)
            assert la.c_names == lb_.c_names


def test_level_shortcut_is_the_exact_optimum_of_the_level_qp(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every least-squares level the constrained cascade settles without the backend (the top level included)
    gets the exact optimum of its level QP, argmin ½‖M u − rhs‖² + ½ε‖u‖² (an augmented least squares, no squared
    condition number), to 1e-12 — over random robots whose cascade a bound at level 1 or tight velocity limits
    send there. The reference cascade in Python is spied on; the compiled one (hqp's own) agrees with it at
    every step (to the backend's conditioning) when it factors every level by its SVD, as the reference does (its
    certified QR gives other null bases of the same spaces: :func:`test_certified_qr_levels_keep_the_svd_optima`)."""
    seen: list[tuple[bool, np.ndarray, np.ndarray, float, np.ndarray]] = []
    level_qp = _PythonCascade._level_qp

    def spy(self, lv, x, Z, r, box, fixed, diag, pinned, selection, shortcut=False):  # type: ignore[no-untyped-def]
        before = diag.qp
        u, lsq = level_qp(self, lv, x, Z, r, box, fixed, diag, pinned, selection, shortcut)
        if lsq is not None and lv.m and not lv.pure_null_objective and not lv.p:
            M, rhs = self._project(lv, x, Z)
            seen.append((diag.qp == before, M, rhs, max(self.regularization, lsq.damping**2), u))
        return u, lsq

    monkeypatch.setattr(_PythonCascade, "_level_qp", spy)
    for seed in range(24):
        rng = np.random.default_rng(300 + seed)
        n = int(rng.integers(5, 9))
        robot = random_robot(rng, n, velocity=float(rng.uniform(0.2, 0.6)) if seed % 3 == 0 else np.inf)
        q = robot.random_configuration(rng)
        stack = _stack(robot, rng, depth=int(rng.integers(1, 5)), bound=True)
        res, lean = _Reference(), HierarchicalQPResolver()
        lean.certified_qr = False
        prepared(res, robot, stack, q)
        prepared(lean, robot, stack, q)
        for k in range(6):
            out = res.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
            # to 1e-6: a level the backend solves on MᵀM + εI (ε = 1e-9) carries its condition number, and inputs
            # equal to rounding (numba's sums against NumPy's) give optima 2e-7 apart on seed 6's level 2
            got = lean.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
            np.testing.assert_allclose(got.dq, out.dq, rtol=0, atol=1e-6 * max(1.0, float(np.abs(out.dq).max())))
            assert (got.fallback is None) == (out.fallback is None)
            q = robot.integrate(q, out.dq, 0.01)
    settled = [(M, rhs, eps, u) for ok, M, rhs, eps, u in seen if ok]
    assert len(settled) >= 10, len(settled)  # (the backend's optima, with active rows, are not the ridge: skipped)
    for M, rhs, eps, u in settled:
        r = M.shape[1]
        exact = np.linalg.lstsq(np.vstack([M, np.sqrt(eps) * np.eye(r)]), np.concatenate([rhs, np.zeros(r)]))[0]
        scale = max(1.0, float(np.abs(exact).max()))
        np.testing.assert_allclose(u, exact, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("seed", range(8))
def test_certified_qr_factors_a_level_as_its_svd(seed: int) -> None:
    """``_certified_null`` on M (m, r), m ≤ r: when it certifies, N's first r − m columns are an orthonormal basis
    of null(M), the next m complete it to an orthogonal Q, R's singular values are M's, and ``_ridge_triangular``'s
    t gives Q₁t = argmin ‖Mu − rhs‖² + ε‖u‖² (the augmented least squares) to 1e-12; a level with σ_min < ε (what
    the SVD would damp) is refused."""
    rng = np.random.default_rng(seed)
    r = int(rng.integers(2, 12))
    m = int(rng.integers(1, r + 1))
    U, _ = np.linalg.qr(rng.standard_normal((m, m)))
    V, _ = np.linalg.qr(rng.standard_normal((r, r)))
    sigma = np.sort(10.0 ** rng.uniform(-1.5, 0.5, m))[::-1]
    M = U @ np.diag(sigma) @ V[:, :m].T
    N, rrow = np.full((r + 2, r + 2), np.nan), np.full(m * m + 3, np.nan)
    assert HK._certified_null(M, 1e-3, 1e-10, N, rrow)
    Q = N[:r, :r]
    np.testing.assert_allclose(Q.T @ Q, np.eye(r), rtol=0, atol=1e-13)
    np.testing.assert_allclose(M @ Q[:, : r - m], 0.0, rtol=0, atol=1e-13 * sigma[0])
    R = rrow[: m * m].reshape(m, m)
    np.testing.assert_allclose(np.linalg.svd(R, compute_uv=False), sigma, rtol=1e-12)
    rhs = rng.standard_normal(m)
    for eps in (0.0, 1e-9, 1e-3, 0.5):
        u = Q[:, r - m :] @ HK._ridge_triangular(rrow, m, rhs, eps)
        exact = np.linalg.lstsq(np.vstack([M, np.sqrt(eps) * np.eye(r)]), np.concatenate([rhs, np.zeros(r)]))[0]
        np.testing.assert_allclose(u, exact, rtol=0, atol=1e-12 * max(1.0, float(np.abs(exact).max())))
    # the complement mode's thin form: Q₁ᵀ in N's first m rows, an orthonormal basis of M's row space, the same R
    rows, rrow2 = np.full((m + 1, r + 2), np.nan), np.full(m * m + 3, np.nan)
    assert HK._certified_rows(M, 1e-3, 1e-10, rows, rrow2)
    Q1t = rows[:m, :r]
    np.testing.assert_allclose(Q1t @ Q1t.T, np.eye(m), rtol=0, atol=1e-13)
    np.testing.assert_allclose(M - M @ Q1t.T @ Q1t, 0.0, rtol=0, atol=1e-13 * sigma[0])
    np.testing.assert_allclose(rrow2[: m * m], rrow[: m * m], rtol=0, atol=1e-13 * sigma[0])
    np.testing.assert_allclose(np.abs(Q1t), np.abs(Q[:, r - m :].T), rtol=0, atol=1e-13)  # (the same reflections)
    weak = M.copy()
    weak -= sigma[-1] * np.outer(U[:, -1], V[:, m - 1]) * (1.0 - 1e-4 / sigma[-1])  # σ_min → 1e-4 < ε = 1e-3
    assert not HK._certified_null(weak, 1e-3, 1e-10, N, rrow)
    assert not HK._certified_rows(weak, 1e-3, 1e-10, rows, rrow2)


@pytest.mark.parametrize("complement", [False, True])
def test_certified_qr_levels_keep_the_svd_optima(monkeypatch: pytest.MonkeyPatch, complement: bool) -> None:
    """The constrained cascade with the certified QR against the same cascade with the SVD at every level, over
    random robots whose bound at level 1 or tight velocity limits send it there: the same optimum of every level
    (residuals, contradicted slacks, ‖q̇‖; q̇ to the level QPs' conditioning, :func:`_same_optima`), and the same
    σ_min per level in the diagnostics (from R's singular values, to 1e-10) — on steps where the QR did factor;
    in the basis mode and in the complement mode (joint-space level QPs, whatever the robot's size)."""
    factored = [0]
    diagnose = HierarchicalQPResolver._diagnose

    def spy(self, built, dq, diag):  # type: ignore[no-untyped-def]
        if built.qp_stats is not None:
            factored[0] += int(np.isnan(built.qp_stats[:, HK.QS_SIGMA]).sum())
        return diagnose(self, built, dq, diag)

    monkeypatch.setattr(HierarchicalQPResolver, "_diagnose", spy)
    steps = 0
    for seed in range(16):
        rng = np.random.default_rng(500 + seed)
        n = int(rng.integers(5, 9))
        robot = random_robot(rng, n, velocity=float(rng.uniform(0.2, 0.6)) if seed % 2 == 0 else np.inf)
        q = robot.random_configuration(rng)
        stack = _stack(robot, rng, depth=int(rng.integers(1, 5)), bound=True)
        qr, svd = HierarchicalQPResolver(), HierarchicalQPResolver()
        svd.certified_qr = False
        for res in (qr, svd):
            if complement:
                res.complement_min_n, res.complement_fraction = 0, 0.0
            prepared(res, robot, stack, q)
        for k in range(4):
            a = qr.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
            b = svd.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
            if b.info["qp"]:
                steps += 1
                _same_optima(a, b, 1e-6)
                sig = [key for key in b.info if key.startswith("sigma_min")]
                assert sig and set(sig) <= set(a.info)
                for key in sig:
                    assert a.info[key] == pytest.approx(b.info[key], rel=1e-10), key
            q = robot.integrate(q, b.dq, 0.01)
    assert steps >= 20 and factored[0] >= 20, (steps, factored[0])

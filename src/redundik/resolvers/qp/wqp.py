"""``wqp``: one QP, a weighted sum of every task plus damping, with the joint limits and bound subtasks as constraints.

    minimise   ½ Σ_t w_t ‖J_t q̇ − v_t‖² + ½ω‖q̇ − z‖² + ½λ‖q̇‖²
    subject to C q̇ ≤ d (bound subtasks),   lb ≤ q̇ ≤ ub (joint limits over dt)

with z = Σ k_i η_i the gradient subtasks' target (ω their mean weight; −ωzᵀq̇ is the QP twin of the null-space term
kη of eq. 5.8) and λ = ``damping`` + ``lm_damping``·‖e‖² a Levenberg–Marquardt-like regulariser that grows with the
stacked task error e (Sugihara 2011), keeping the step bounded near singularities. As the main-task weights grow
relative to ω, the solution tends to the hierarchy's J⁺V + (I − J⁺J)z (tested against ``hqp``).

Hot loop: when the unconstrained optimum P⁻¹(−q) already satisfies every constraint it is the QP's optimum and is
returned without calling the backend (a 9×9 solve instead of a QP, flagged ``info["qp"] = 0``); otherwise the backend
solves the QP, warm-started at the previous q̇. A backend failure or an infeasible QP (bound subtasks that the limits
do not allow) is relaxed first (bound subtasks dropped), then replaced by the damped closed form clipped to the
limits; ``StepResult.fallback`` says which.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.linalg.lapack import dposv as _dposv

from redundik.errors import ResolverError, SolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import StepResult
from redundik.resolvers.qp.backends import DEFAULT_BACKEND, Backend
from redundik.resolvers.qp.base import LevelsOption, LimitsOption, QPResolverBase
from redundik.resolvers.qp.problem import QPProblem
from redundik.resolvers.qp.terms import Level, build_levels
from redundik.tasks.base import TaskStack, stack_terms
from redundik.tasks.frame import PostureTask


class WeightedQPResolver(QPResolverBase):
    """Weighted-sum QP resolution (see the module docstring).

    Args:
        backend: QP backend (default ``"daqp"``; see :mod:`redundik.resolvers.qp.backends`).
        limits: Joint limits: ``None`` = the model's, ``False`` = none, a dict of
            :class:`~redundik.resolvers.qp.limits.JointLimits` options, or an instance.
        damping: Constant part of λ [unit of ‖v‖⁻²-scaled cost], ≥ 0.
        lm_damping: Error-dependent part: λ += lm_damping·‖e‖², ≥ 0.
        levels: Accepted for symmetry with ``hqp`` (a weighted QP has one level); must name existing tasks.
        epsilon: Damping threshold of the closed-form fallback.
        max_damping: λ_max of the closed-form fallback.

    Raises:
        ResolverError: negative or non-finite damping; SolverError: unknown or missing backend.
    """

    name = "wqp"

    def __init__(
        self,
        backend: str | Backend = DEFAULT_BACKEND,
        limits: LimitsOption = None,
        damping: float = 1e-6,
        lm_damping: float = 0.0,
        levels: LevelsOption = None,
        epsilon: float = 1e-2,
        max_damping: float = 5e-2,
    ) -> None:
        super().__init__(backend, limits, levels, epsilon, max_damping)
        for key, val in (("damping", damping), ("lm_damping", lm_damping)):
            if not (np.isfinite(val) and val >= 0):
                raise ResolverError(f"wqp: {key} must be a finite number ≥ 0, got {val}")
        self.damping, self.lm_damping = float(damping), float(lm_damping)
        self._P: np.ndarray | None = None
        self._q: np.ndarray | None = None
        self._empty: Level | None = None
        self._no_rows, self._no_rhs = np.zeros((0, 0)), np.zeros(0)
        self._sub_stacks: dict[int, TaskStack] = {}

    def build(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> tuple[QPProblem, Level, list]:
        """Evaluate the stack and build the QP (without solving it), for inspection and tests.

        Main tasks are accumulated straight into P = Σ w JᵀJ and q = −Σ w Jᵀv in preallocated arrays (a posture
        task's identity Jacobian as a diagonal update); subtasks go through :func:`~.terms.build_levels`.

        Returns:
            (problem, the subtasks' merged level, the main-task terms).
        """
        terms = stack.evaluate(robot, t)
        n = robot.nv
        if self._P is None or self._P.shape[0] != n:
            self._P, self._q = np.empty((n, n)), np.empty(n)
        P, q = self._P, self._q
        P.fill(0.0)
        q.fill(0.0)
        diag = P.reshape(-1)[:: n + 1]  # a view on P's diagonal
        for task, term in zip(stack.tasks, terms, strict=True):
            w, J = term.weight, term.J
            if isinstance(task, PostureTask):  # J = I
                diag += w
                q -= w * term.v
            else:
                Jw = w * J.T  # (n, m)
                P += Jw @ J
                q -= Jw @ term.v
        if stack.subtasks:
            sub_stack = self._sub_stacks.get(id(stack))
            if sub_stack is None or sub_stack.subtasks is not stack.subtasks:
                sub_stack = self._sub_stacks[id(stack)] = TaskStack([], stack.subtasks)
            lv = build_levels(robot, sub_stack, [], dt, None, merge=True)[0]
            if lv.m:
                Jw = lv.J.T * lv.w  # (n, m)
                P += Jw @ lv.J
                q -= Jw @ lv.v
        else:
            lv = self._empty_level(n)
        lam = self.damping
        if self.lm_damping and terms:
            lam += self.lm_damping * sum(float(tm.error @ tm.error) for tm in terms)
        self._last_lam = lam
        if lv.z is not None and lv.z_weight > 0:
            lam += lv.z_weight  # the gradient objective's ½ω‖q̇‖²
            q -= lv.z_weight * lv.z
        if lam:
            diag += lam
        box = self._box(robot, dt)
        self._last_box = box
        prob = QPProblem(P, q, lv.C, lv.d, self._no_rows, self._no_rhs, box.lb, box.ub, "wqp", lv.c_names)
        return prob, lv, terms

    def _empty_level(self, n: int) -> Level:
        if self._empty is None or self._empty.J.shape[1] != n:
            self._no_rows, self._no_rhs = np.zeros((0, n)), np.zeros(0)
            self._empty = Level(0, [], np.zeros((0, n)), np.zeros(0), np.zeros(0), np.zeros((0, n)), np.zeros(0))
        return self._empty

    def solve(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> StepResult:
        t0 = time.perf_counter()
        prob, lv, terms = self.build(robot, stack, t, dt)
        box = self._last_box
        t1 = time.perf_counter()
        info: dict[str, object] = {"backend": "closed-form", "qp": 0, "iterations": 0}
        fallback = None
        _, x, fail = _dposv(prob.P, -prob.q)  # Cholesky solve of the unconstrained optimum (P is SPD when λ > 0)
        feasible = not fail and box.contains(x, 1e-12) and (not lv.p or not (lv.C @ x > lv.d + 1e-12).any())
        if not feasible:
            info["qp"] = 1
            try:
                sol = self._solve_qp(prob, self._dq_prev)
                x = sol.x
                info["backend"], info["iterations"] = sol.backend, sol.iterations
            except SolverError as exc:
                x = None
                if lv.p:
                    relaxed = QPProblem(prob.P, prob.q, prob.G[:0], prob.h[:0], prob.A, prob.b, prob.lb, prob.ub, "wqp")
                    try:
                        x = self._solve_qp(relaxed, self._dq_prev).x
                        fallback = f"wqp relaxed (bound subtasks {lv.c_names} dropped): {exc}"
                    except SolverError:
                        x = None
                if x is None:
                    fallback = f"wqp failed, damped closed form clipped to the limits: {exc}"
                    J, V = stack_terms(terms, robot.nv)
                    x = self._closed_form([Level(0, [], J, V, np.ones(V.shape[0]), z=lv.z)], robot.nv)
                info["backend"] = "fallback"
        dq, ok = self._finish(x, box, robot, info)
        if not ok:
            fallback = "non-finite q̇ replaced by zero"
        if terms:
            res2 = 0.0
            for tm in terms:
                r = tm.J @ dq - tm.v
                res2 += float(r @ r)
            info["residual_L0"] = res2**0.5
        if lv.p:
            viol = lv.inequality_residual(dq)
            info["bound_violation"] = float(np.max(viol))
        t2 = time.perf_counter()
        return StepResult(
            dq=dq,
            terms=terms,
            fallback=fallback,
            info=info,
            damping=self._last_lam,
            damped=self._last_lam > self.damping,
            build_time=t1 - t0,
            solve_time=t2 - t1,
        )

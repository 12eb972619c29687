"""The chapter's nonlinear state-feedback law for the subtask gains (section 5.2, after eq. 5.15).

With N = (η_1 … η_r) and y = (p_1 … p_r)ᵀ, eq. (5.15) gives ẏ = NᵀJ⁺V + D k with the decoupling matrix
D = Nᵀ(I − J⁺J)N. Asking ẏ = ẏ_d + K(y_d − y) yields

    k = D⁻¹[ẏ_d + K(y_d − y)] − D⁻¹NᵀJ⁺V,    q̇ = J⁺V + (I − J⁺J) N k,

so each p_i converges to p_i^d exponentially at rate K_i (exactly in continuous time, to O(dt) with Euler steps).
D is r×r and can be non-singular only if r ≤ dim N(J) = n − rank(J); a singular D (e.g. a gradient that vanishes
or lies in the rank space) is handled by damped least squares on D instead of a NaN (reported as ``damped``).
"""

from __future__ import annotations

import time

import numpy as np

from redundik.errors import ResolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import Resolver, StepResult, finite_or_zero
from redundik.resolvers.linalg import pseudo_inverse
from redundik.tasks.base import TaskStack, stack_terms


class FeedbackResolver(Resolver):
    """Nonlinear state-feedback control of the subtask gains k (the chapter's decoupling law).

    Every subtask must be in mode ``"target"`` (target p_d, rate K, optional ṗ_d).

    Args:
        epsilon: Damping threshold of J⁺ (see :mod:`redundik.resolvers.linalg`).
        max_damping: λ_max of J⁺.
        d_epsilon: Relative threshold: D⁻¹ is damped when σ_min(D) < d_epsilon·‖N‖_F², i.e. when the subtask
            gradients have almost no component left in the null space (scale-free, so the rule does not depend on
            the units of the potentials). The damping is then λ = d_epsilon·‖N‖_F².
    """

    name = "feedback"

    def __init__(self, epsilon: float = 1e-2, max_damping: float = 5e-2, d_epsilon: float = 1e-3) -> None:
        self.epsilon, self.max_damping, self.d_epsilon = float(epsilon), float(max_damping), float(d_epsilon)

    def check(self, robot: RobotModel, stack: TaskStack) -> None:
        for s in stack.subtasks:
            if s.mode != "target":
                raise ResolverError(
                    f"feedback: subtask '{s.name}' has mode '{s.mode}'; the state-feedback law drives potentials "
                    "to a target: give it mode 'target' with a target value"
                )
        m = sum(len(t.evaluate(robot, 0.0).v) for t in stack.tasks)
        r = len(stack.subtasks)
        if r > robot.nv - m:
            raise ResolverError(
                f"feedback: {r} subtasks but the null space of the {m}×{robot.nv} main-task Jacobian has dimension "
                f"at most {robot.nv - m}; D = Nᵀ(I − J⁺J)N would be singular. Remove "
                f"{r - (robot.nv - m)} subtask(s) or use 'pinv' / 'hqp'"
            )

    def solve(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> StepResult:
        t0 = time.perf_counter()
        terms = stack.evaluate(robot, t)
        J, V = stack_terms(terms, robot.nv)
        subs = stack.subtasks
        r = len(subs)
        N = np.empty((robot.nv, r))
        y = np.empty(r)
        for i, s in enumerate(subs):
            N[:, i] = s.potential.gradient(robot)
            y[i] = s.potential.value(robot)
        yd = np.array([s.target for s in subs], dtype=float)
        yd_dot = np.array([s.target_rate for s in subs], dtype=float)
        K = np.array([s.rate for s in subs], dtype=float)
        t1 = time.perf_counter()
        pi = pseudo_inverse(J, epsilon=self.epsilon, max_damping=self.max_damping)
        dq_r = pi.pinv @ V
        PN = pi.null_projector @ N  # (n, r)
        D = N.T @ PN  # (r, r), symmetric positive semi-definite
        rhs = yd_dot + K * (yd - y) - N.T @ dq_r
        d_damped = False
        if r:
            U, s, Vt = np.linalg.svd(D)
            lam = self.d_epsilon * max(float(np.sum(N * N)), 1e-300)
            if s[-1] < lam:
                d_damped = True
                inv_s = s / (s * s + lam**2)
            else:
                inv_s = 1.0 / s
            k = Vt.T @ (inv_s * (U.T @ rhs))
        else:
            k = np.zeros(0)
        dq_n = PN @ k
        dq, ok = finite_or_zero(dq_r + dq_n)
        t2 = time.perf_counter()
        return StepResult(
            dq=dq,
            terms=terms,
            dq_rank=dq_r,
            dq_null=dq_n,
            gains=k,
            damped=pi.damped or d_damped,
            damping=pi.damping,
            fallback=None if ok else "non-finite q̇ replaced by zero",
            info={"sigma_min": pi.sigma_min, "rank": pi.rank, "D_damped": d_damped},
            build_time=t1 - t0,
            solve_time=t2 - t1,
        )

    def __repr__(self) -> str:
        return f"FeedbackResolver(epsilon={self.epsilon})"

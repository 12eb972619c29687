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

import time
from typing import ClassVar

import numpy as np

from redundik._coldstart import HOT, ready
from redundik.errors import ResolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import Resolver, StepResult, nonfinite_sources
from redundik.resolvers.linalg import damped_svd, pseudo_inverse, pseudo_inverse_unchecked
from redundik.resolvers.pinv import main_system
from redundik.resolvers.settings import Setting, nonnegative
from redundik.resolvers.singularity import SingularityGuard
from redundik.tasks.stack import StackLayout, TaskStack


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
        self._layout: tuple[tuple[int, ...], StackLayout] | None = None
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
        terms = stack.evaluate(robot, t)
        sig = self.stack_key(stack)
        cached = self._layout
        if cached is None or (cached[0] is not sig and cached[0] != sig):
            self._layout = cached = (sig, stack.layout())
        layout = cached[1]
        J, V, z = main_system(robot, stack, terms, layout)
        subs = stack.target_subtasks
        r = len(subs)
        N = np.empty((robot.nv, r))
        rhs = np.empty(r)
        for i, s in enumerate(subs):
            eta, v, _ = s.row(robot)  # v = ṗ_d + K (p_d − p)
            N[:, i] = eta
            rhs[i] = v
        t1 = time.perf_counter()
        pi = pseudo_inverse_unchecked(J, self.epsilon, self.max_damping)
        dq_r = pi.solve(V)
        if z is None:
            Pz = np.zeros(robot.nv)
        elif np.isfinite(z).all():
            Pz = pi.null_project(z)
        else:  # (null_project refuses a non-finite z: the NaN goes on to the step's diagnosed fallback instead)
            Pz = np.full(robot.nv, np.nan)
        d_damped, d_rank = False, 0
        k = np.zeros(r)
        if r:
            PN = pi.null_projector @ N  # (n, r)
            D = N.T @ PN  # (r, r), symmetric positive semi-definite
            scale = float(np.sum(N * N))
            dk = damped_svd(D, epsilon=self.d_epsilon * scale, max_damping=self.d_epsilon * scale)
            k = dk.solve(rhs - N.T @ dq_r - N.T @ Pz)
            d_damped, d_rank = dk.damped, dk.rank
            dq_n = PN @ k + Pz
        else:
            dq_n = Pz
        dq = dq_r + dq_n
        fallback = None
        if not np.isfinite(dq).all():
            bad = nonfinite_sources(terms, robot, stack, z=z, subtask_gradients=N)
            fallback = f"non-finite q̇ (from {', '.join(bad) or 'the decoupling law'}): q̇ = 0 this step"
            dq = np.zeros(robot.nv)
        t2 = time.perf_counter()
        return StepResult(
            dq=dq,
            terms=terms,
            dq_rank=dq_r,
            dq_null=dq_n,
            gains=k,
            damped=pi.damped or d_damped,
            damping=pi.damping,
            sigma_min=pi.sigma_min,
            fallback=fallback,
            info={"sigma_min": pi.sigma_min, "rank": pi.rank, "D_damped": d_damped, "D_rank": d_rank},
            build_time=t1 - t0,
            solve_time=t2 - t1,
            main=layout.main,
        )

    def __repr__(self) -> str:
        return f"FeedbackResolver(epsilon={self.epsilon}, d_epsilon={self.d_epsilon})"

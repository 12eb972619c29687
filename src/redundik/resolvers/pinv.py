"""The chapter's closed form: rank solution plus null-space gradient projection, eqs. (5.8) and (5.15).

q̇ = J⁺V + (I − J⁺J) Σ_i k_i η_i = J⁺V + (I − J⁺J) N k.
"""

from __future__ import annotations

import time

import numpy as np

from redundik.errors import ResolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import Resolver, StepResult, finite_or_zero
from redundik.resolvers.linalg import pseudo_inverse
from redundik.tasks.base import TaskStack, stack_terms


class PinvResolver(Resolver):
    """Pseudo-inverse resolution with null-space gradient projection (5.8, 5.15).

    Subtasks must be in mode ``"gradient"``: each contributes z += k_i η_i, projected on the null space of the
    stacked main-task Jacobian. Near a singularity J⁺ is damped (see :mod:`redundik.resolvers.linalg`) and the
    step result says so (``damped``, ``damping``, ``info["sigma_min"]``).

    Args:
        epsilon: Singular value under which damping starts.
        max_damping: Damping λ_max at σ_min = 0.
    """

    name = "pinv"

    def __init__(self, epsilon: float = 1e-2, max_damping: float = 5e-2) -> None:
        if not (epsilon >= 0 and max_damping >= 0 and np.isfinite(epsilon) and np.isfinite(max_damping)):
            raise ResolverError("pinv: epsilon and max_damping must be finite numbers ≥ 0")
        self.epsilon, self.max_damping = float(epsilon), float(max_damping)

    def check(self, robot: RobotModel, stack: TaskStack) -> None:
        for s in stack.subtasks:
            if s.mode != "gradient":
                raise ResolverError(
                    f"pinv: subtask '{s.name}' has mode '{s.mode}'; the pseudo-inverse resolver takes only "
                    "'gradient' subtasks (use 'feedback' for targets, 'wqp' or 'hqp' for bounds)"
                )

    def solve(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> StepResult:
        t0 = time.perf_counter()
        terms = stack.evaluate(robot, t)
        J, V = stack_terms(terms, robot.nv)
        z = np.zeros(robot.nv)
        for s in stack.subtasks:
            if s.gain != 0.0:
                z += s.gain * s.potential.gradient(robot)
        t1 = time.perf_counter()
        pi = pseudo_inverse(J, epsilon=self.epsilon, max_damping=self.max_damping)
        dq_r = pi.pinv @ V
        dq_n = pi.null_projector @ z
        dq, ok = finite_or_zero(dq_r + dq_n)
        t2 = time.perf_counter()
        return StepResult(
            dq=dq,
            terms=terms,
            dq_rank=dq_r,
            dq_null=dq_n,
            damped=pi.damped,
            damping=pi.damping,
            fallback=None if ok else "non-finite q̇ replaced by zero",
            info={"sigma_min": pi.sigma_min, "rank": pi.rank},
            build_time=t1 - t0,
            solve_time=t2 - t1,
        )

    def __repr__(self) -> str:
        return f"PinvResolver(epsilon={self.epsilon}, max_damping={self.max_damping})"

"""The Gram factor of a ``wqp`` step's P: P = FᵀF + δI, F the rows √(ρ^k w) J of its tasks that are not identity
blocks, δ the diagonal shift. A backend may solve the QP lifted with it (``QPProblem.factor``,
``DaqpBackend._solve_lifted``): a diagonal Hessian of n + k variables instead of the dense n × n P.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from redundik.resolvers.linalg import K
from redundik.tasks.base import TaskTerm


def gram_factor(
    resolver: Any, tasks: list[tuple[int, float, bool]], terms: list[TaskTerm], shift: float
) -> tuple[np.ndarray, float] | None:
    """(F, δ) with the resolver's P = FᵀF + δI for a stack of tasks (no target subtask): F the rows √(ρ^k w) J of
    the ``tasks`` (the plan's (index, ρ^k, identity Jacobian)) that are not identity blocks, δ = ``shift`` (λ, the
    identity tasks' ρ^k w, the null objective's ρ^k). ``None`` when the backend does not lift a QP of this size, or
    when P's diagonal is not that of FᵀF + δI (to 1e-9 relative: a member whose rows are not what the plan says; the
    dense P is then solved as it is)."""
    P = resolver._P
    lift_min_n = getattr(resolver.backend, "lift_min_n", None)
    if P is None or lift_min_n is None or P.shape[0] < lift_min_n or not shift > 0.0:
        return None
    blocks = [math.sqrt(scale * terms[i].weight) * terms[i].J for i, scale, identity in tasks if not identity]
    if not blocks:
        return None
    F = blocks[0] if len(blocks) == 1 else np.vstack(blocks)
    if not K.gram_diagonal_matches(np.ascontiguousarray(F), float(shift), resolver._diag, 1e-9):
        return None
    return F, float(shift)


def gram_of(resolver: Any, plan: Any, terms: list[TaskTerm], lam: float) -> Callable[[], Any] | None:
    """``WQPBuild.gram`` of a lean or fused step's QP (its λ ``lam``, the shift the step added to P's diagonal):
    ``None`` with target subtasks, whose rows P holds but F would not."""
    if plan.targets:
        return None
    identity = sum(scale * terms[i].weight for i, scale, ident in plan.tasks if ident)
    shift = lam + identity + plan.null_scale  # (the diagonal the lean and fused paths added to P)
    return lambda: gram_factor(resolver, plan.tasks, terms, shift)


__all__ = ["gram_factor", "gram_of"]

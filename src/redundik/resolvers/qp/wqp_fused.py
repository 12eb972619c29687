"""The result of a fused ``wqp`` step that solved no QP (``FusedWqpResult``): q̇ a view on the step's work
array, the task terms and the diagnostics computed from that array on first read."""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.resolvers.fused import FusedPlan, FusedStepResult
from redundik.resolvers.layouts import FRAME_ROWS, OUT_BOX, OUT_DQ, OUT_KEPT, OUT_ROWS, QP_CAPS
from redundik.resolvers.qp.base import QPDiagnostics
from redundik.resolvers.singularity import NO_CAPS, SpeedLimiter
from redundik.tasks.base import TaskTerm

__all__ = [
    "FusedWqpResult", "free_diagnostics", "plain_at", "work_views", "work_with_external", "write_caps",
    "write_external_rows",
]  # fmt: skip


def work_views(work: np.ndarray, K: int, m: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``FK.wqp_work_views`` sliced in Python: ``out`` (``OUT_ROWS``, n), (e, v) (2, m) and the frames' Jacobians
    (K, 6, n) of a ``wqp`` step's ``work`` (a compiled call that returns arrays costs more than these slices)."""
    a = OUT_ROWS * n
    b = a + 2 * m
    return work[:a].reshape(OUT_ROWS, n), work[a:b].reshape(2, m), work[b : b + FRAME_ROWS * K * n].reshape(K, 6, n)


def write_caps(speed: SpeedLimiter | None, robot: RobotModel, qp: np.ndarray, seen: np.ndarray | None) -> np.ndarray:
    """The joints' 1 / speed cap [s/rad] into the QP record's row ``QP_CAPS`` when the limiter ``speed`` gives them
    for the compiled step's test (``SpeedLimiter.folded_caps``; a negative first entry when it does not: a guard,
    caps not built yet, no cap), written only when they are not ``seen`` (the array written last); returns them."""
    inv = NO_CAPS if speed is None else speed.folded_caps(robot)
    if inv is not seen:
        if inv.shape[0] == qp.shape[1]:
            qp[QP_CAPS] = inv
        else:
            qp[QP_CAPS, 0] = -1.0
    return inv


def plain_at(fused: FusedPlan, n: int) -> tuple[int, int, int, int, int]:
    """Where a ``wqp`` step's ``work`` takes the Python writers' J, e, v and weights (``PythonWriters.put_plain_rows``'
    ``at``), at the parts ``FK.wqp_work_views`` and ``FK.wqp_external_views`` give (sliced here: cheaper than those
    compiled calls)."""
    m, mx = fused.m, fused.mx
    a = OUT_ROWS * n + 2 * m + FRAME_ROWS * len(fused.frames) * n
    return (a, m - mx, OUT_ROWS * n, OUT_ROWS * n + m, a + mx * n)


def work_with_external(
    fused: FusedPlan, robot: RobotModel, t: float
) -> tuple[np.ndarray, list[TaskTerm | None] | tuple[()]] | None:
    """A ``wqp`` step's ``work`` (the box and answers, e and v, the frames' Jacobians: one allocation) with the
    Python writers' rows of a mixed plan written at t, and their terms (``()``: none); ``None`` when a member's term
    sends the step to the per-task path (``PythonWriters.evaluate_external``)."""
    n = robot._nv
    if fused.plain_rows:  # a user's own tasks only: evaluated and put straight into work, in one walk
        work = np.empty(fused.wqp_work)
        taken = fused.take_plain_rows(robot, t, work, plain_at(fused, n))
        if taken is None:
            return None
        if fused.repacked:  # a row count moved: the plan was packed again, and work is sized anew
            work = np.empty(fused.wqp_work)
            fused.put_plain_rows(robot, taken, work, plain_at(fused, n))
        return work, taken
    if not fused.external:
        return np.empty(fused.wqp_work), ()
    if fused.direct_main and fused.direct_rows == fused.external_rows:  # compiled writers of tasks only: run
        # straight into work (their rows laid out as the writers give them)
        work = np.empty(fused.wqp_work)
        return work, fused.take_direct_rows(robot, t, work, plain_at(fused, n))
    evaluated = fused.evaluate_external(robot, t, direct=True)  # (their evaluate, or their compiled writers)
    if evaluated is None:
        return None
    work = np.empty(fused.wqp_work)
    write_external_rows(fused, robot, evaluated, work, t)
    return work, evaluated


def write_external_rows(fused: FusedPlan, robot: RobotModel, external: list[TaskTerm | None], work: np.ndarray,
                        t: float) -> None:  # fmt: skip
    """The Python writers' rows of a mixed plan into a ``wqp`` step's ``work``, at the parts
    ``FK.wqp_work_views`` and ``FK.wqp_external_views`` give (sliced here: cheaper than those compiled calls)."""
    n, m, mx = robot._nv, fused.m, fused.mx
    a = OUT_ROWS * n + 2 * m + FRAME_ROWS * len(fused.frames) * n
    b = a + mx * n
    if fused.plain_rows:  # a user's own tasks only: their blocks put straight into work
        fused.put_plain_rows(robot, external, work, plain_at(fused, n))
        return
    ev = work[OUT_ROWS * n : OUT_ROWS * n + 2 * m].reshape(2, m)
    Jx, wx, zx = work[a:b].reshape(mx, n), work[b : b + mx], work[b + mx : b + mx + n]
    fused.write_external(robot, external, Jx, m - mx, ev, wx, zx, t)


def free_diagnostics(
    resolver: Any,
    terms_of: Callable[[], list[TaskTerm]],
    main: list[int],
    out: np.ndarray,
    windowed: bool,
    kept: np.ndarray,
    lam: float,
) -> Callable[[], tuple[float, bool, dict[str, object]]]:
    """The diagnostics of a ``wqp`` lean step that solved no QP, computed on first read of the result's diagnostics
    (``out``: the box rows lb, ub, pos_lo, pos_hi first, as (≥ 4, n) or flat)."""
    limits = resolver.limits

    def diagnostics() -> tuple[float, bool, dict[str, object]]:
        terms = terms_of()
        diag = QPDiagnostics()
        box_rows = out if out.ndim == 2 else out[: OUT_BOX * kept.shape[0]].reshape(OUT_BOX, -1)
        diag.active_limits = limits.box_from(box_rows, windowed).active(kept, limits.joint_names)
        resolver._diagnose_terms([terms[i] for i in main], lam, kept, diag)
        return diag.sigma_min, bool(diag.damped_levels), diag.as_info()

    return diagnostics


def _fused_terms(step: tuple[Any, ...]) -> list[TaskTerm]:
    """The task terms of a fused ``wqp`` step, from its work array."""
    _, fused, work, q, robot, _, _, external = step
    _, ev, Jf = work_views(work, len(fused.frames), fused.m, robot._nv)
    return fused.terms(Jf, ev, q, robot, external)


def _fused_diagnostics(step: tuple[Any, ...], main: list[int]) -> tuple[float, bool, dict[str, object]]:
    """The diagnostics of a fused ``wqp`` step (σ_min, damped, info entries), from its work array."""
    resolver, _, work, _, robot, windowed, lam, _ = step
    n = robot._nv
    terms = _fused_terms(step)
    diag = QPDiagnostics()
    limits = resolver.limits
    kept = work[OUT_KEPT * n : (OUT_KEPT + 1) * n]
    diag.active_limits = limits.box_from(work[: OUT_BOX * n].reshape(OUT_BOX, n), windowed).active(
        kept, limits.joint_names
    )
    resolver._diagnose_terms([terms[i] for i in main], lam, kept, diag)
    return diag.sigma_min, bool(diag.damped_levels), diag.as_info()


#: The entries of a ``FusedWqpResult`` that every step shares (``pending``: the diagnostics are computed from the
#: step's work array when first read).
_TEMPLATE: dict[str, Any] = {
    "dq_rank": None, "dq_null": None, "gains": None, "damping": 0.0, "fallback": None, "pending": True,
}  # fmt: skip


class FusedWqpResult(FusedStepResult):
    """The result of a fused ``wqp`` step that solved no QP: q̇ a view on the step's work array; the task terms and
    the diagnostics (active limits, residuals, σ_min) computed from that array on first read."""

    @classmethod
    def of(
        cls,
        resolver: Any,  # the WeightedQPResolver that stepped (its module imports this one)
        fused: FusedPlan,
        work: np.ndarray,
        q: np.ndarray,
        robot: RobotModel,
        windowed: bool,
        lam: float,
        outputs: tuple[float, float, float],
        build_time: float,
        t1: float,
        main: list[int],
        external: list[TaskTerm | None] | tuple[()] = (),
    ) -> FusedWqpResult:
        """The result of ``fused_wqp_step``'s ``outputs`` (Σ e², ‖q̇‖², the cap ratio max_i |q̇_i| / c_i or −1: not
        tested; ``t1``: when the compiled call returned)."""
        err2, dq2, over = outputs
        n = robot._nv
        res = cls.__new__(cls)
        d = res.__dict__ = _TEMPLATE.copy()  # (the constant entries; one copy is cheaper than a literal)
        d["dq"] = work[OUT_DQ * n : (OUT_DQ + 1) * n]
        d["_info"] = {"backend": "closed-form", "qp": 0, "iterations": 0}
        d["build_time"], d["main"] = build_time, main
        d["_task_error"], d["_dq_norm"] = math.sqrt(err2), math.sqrt(dq2)  # (‖q̇‖: the divergence watch reads it)
        d["_cap_ratio"] = over  # (the joint-speed cap's test, when the compiled call made it: Resolver.step reads it)
        d["_step"] = (resolver, fused, work, q, robot, windowed, lam, external)
        d["solve_time"] = time.perf_counter() - t1
        return res

    def _pending_fn(self) -> Callable[[], tuple[float, bool, dict[str, object]]]:
        d = self.__dict__
        if d.get("pending") is True:  # the diagnostics from the step's work array (the step's arrays, not this result)
            return functools.partial(_fused_diagnostics, d["_step"], d["main"])
        return super()._pending_fn()

    def _build_terms(self) -> list[TaskTerm]:
        return _fused_terms(self.__dict__["_step"])

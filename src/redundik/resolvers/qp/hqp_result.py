"""The result of a fused ``hqp`` step whose unconstrained cascade was kept (:mod:`redundik.resolvers.hqp_fused`):
q̇ a view on the step's ``work`` array; the task terms and the diagnostics — what a control loop seldom reads — built
from that array when first read, with nothing made for them on the step itself."""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from redundik.resolvers.fused_result import FusedStepResult
from redundik.resolvers.hqp_layout import OUT_LB, OUT_POS_HI
from redundik.resolvers.linalg import _Kernels
from redundik.resolvers.qp.base import QPDiagnostics
from redundik.resolvers.qp.hqp_constrained import HQPBuild
from redundik.tasks.base import TaskTerm

_BOX = slice(OUT_LB, OUT_POS_HI + 1)  # the limit box's rows of the step's ``out``
HFK = _Kernels("hqp_fused")  # (imported on first use)
#: A result's entries that are the same on every step (``pending``: ``_pending_fn`` builds the diagnostics from the
#: step's arrays).
_TEMPLATE: dict[str, Any] = {
    "dq_rank": None, "dq_null": None, "gains": None, "damping": 0.0, "fallback": None, "pending": True,
}  # fmt: skip


class FusedHqpResult(FusedStepResult):
    """The result of a fused ``hqp`` step that kept its unconstrained cascade's answer (``_step``: what the terms and
    the diagnostics are built from; the terms are made once and shared by both, neither holding the result)."""

    @classmethod
    def of(
        cls,
        resolver: Any,
        dq: np.ndarray,
        step: tuple[Any, ...],
        outputs: tuple[float, float, float],
        t0: float,
        t1: float,
    ) -> FusedHqpResult:
        """The result of the step, q̇ ``dq``; ``step`` = (plan, fused plan, work, (K, m, nv, levels), q, robot,
        the Python writers' terms, the target subtasks' rows, the bound records, whether a rate window applied,
        q̇ kept, a cell for the terms); ``outputs`` = (Σ e², ‖q̇‖², the cap ratio) of the compiled call; t0, t1
        [s]: the step's start and the end of its compiled call."""
        err2, dq2, over = outputs
        res = cls.__new__(cls)
        d = res.__dict__ = _TEMPLATE.copy()  # (the constant entries; one copy is cheaper than a literal)
        d["dq"] = dq
        d["_info"] = {"backend": "closed-form", "qp": 0, "iterations": 0}
        d["build_time"], d["main"] = t1 - t0, step[0].layout.main
        d["_task_error"], d["_dq_norm"] = math.sqrt(err2), math.sqrt(dq2)  # (‖q̇‖: the divergence watch reads it)
        d["_cap_ratio"] = over  # max_i |q̇_i| / c_i from the compiled call (−1: not computed)
        d["_step"] = (resolver, *step)
        d["solve_time"] = time.perf_counter() - t1
        return res

    def _build_terms(self) -> list[TaskTerm]:
        return _terms(self.__dict__["_step"])

    def _pending_fn(self) -> Callable[[], tuple[float, bool, dict[str, object]]]:
        d = self.__dict__
        if d.get("pending") is True:
            return functools.partial(_diagnostics, d["_step"])
        return super()._pending_fn()


def _views(step: tuple[Any, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(ev, z, out, Jf, stats): the parts of the step's work array (``hqp_fused.step_work_views``)."""
    work, dims = step[3], step[4]
    views: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] = HFK.step_work_views.py_func(work, *dims)
    return views


def _terms(step: tuple[Any, ...]) -> list[TaskTerm]:
    """The step's task terms (``FusedPlan.terms``), made once: the result and its diagnostics share them."""
    cell = step[12]
    if not cell:
        ev, _, _, Jf, _ = _views(step)
        cell.append(step[2].terms(Jf, ev, step[5], step[6], step[7]))
    terms: list[TaskTerm] = cell[0]
    return terms


def _diagnostics(step: tuple[Any, ...]) -> tuple[float, bool, dict[str, object]]:
    """σ_min, whether a level was damped, and the info of the step (on first read of the result's diagnostics)."""
    resolver, plan, _, _, dims, _, _, _, targets, bounds, windowed, kept, _ = step
    _, z, out, _, stats = _views(step)
    limits = resolver.limits
    box = limits.box_from(out[_BOX, 0], windowed)
    zs = z if plan.layout.has_null_objective else None
    built = HQPBuild(plan.step_rows(_terms(step), zs, targets, bounds), box, dims[2], stats)
    diag = QPDiagnostics()
    diag.active_limits = box.active(kept, limits.joint_names)
    resolver._diagnose(built, kept, diag)
    return diag.sigma_min, bool(diag.damped_levels), diag.as_info()


__all__ = ["FusedHqpResult"]

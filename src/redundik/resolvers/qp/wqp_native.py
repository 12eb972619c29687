"""``wqp``'s box QP through daqp's C entry point: a step whose unconstrained optimum leaves the joint-limit box (a
limit binds) or breaks a bound subtask's row solves min ½ q̇ᵀP q̇ + gᵀq̇ s.t. lb ≤ q̇ ≤ ub, G q̇ ≤ h in one compiled
call instead of the template's second half (``QPProblem``, the backend's Python wrapper, the settling).

It is the template's answer, not an approximation: the same QP goes to the same daqp function with the same settings,
posed as ``DaqpBackend.solve`` poses it (checked bit for bit by :mod:`redundik.resolvers.qp.daqp_native` for the daqp
version installed) and in its order: from the backend's split size, a bounds-only QP's separable variables in closed
form and daqp on the coupled ones (``hqp_native.box_qp_native_split_into``); from its lift size, with the Gram factor
P = FᵀF + δI the template would give it, the QP lifted to (q̇, F q̇) (``hqp_native.lifted_rows_qp_native_into``);
otherwise P as given, the bound rows after the box (``box_qp_native_into``, ``rows_qp_native_into``). x is clipped to
the box as the template clips it, and the result carries the same info, diagnostics and kept q̇. Anything else —
another backend, a QP daqp does not solve at once (the template then poses it with every retry), an answer that
breaks a safety row (a collision damper's) by more than the template's last guard allows (the template scales q̇ to
keep it, and says so), the native call off — returns ``None`` and the template solves the step as before.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from redundik._coldstart import ready
from redundik.resolvers.base import LazyStepResult, StepResult
from redundik.resolvers.layouts import OUT_DQ, OUT_KEPT, OUT_LB, OUT_ROWS, OUT_UB
from redundik.resolvers.linalg import K
from redundik.resolvers.qp.base import SAFETY_TOLERANCE, QPDiagnostics
from redundik.resolvers.qp.daqp_backend import LIFT_MAX_ROWS_PER_VARIABLE, SPLIT_MIN_SAVING, DaqpBackend
from redundik.resolvers.qp.daqp_native import HK, NativeDaqp
from redundik.tasks.base import TaskTerm
from redundik.tasks.stack import TaskStack

__all__ = ["native_box_step", "warm_native_box"]


def native_box_step(
    resolver: Any,  # the WeightedQPResolver stepping (its module imports this one)
    stack: TaskStack,
    terms: list[TaskTerm],
    out: np.ndarray,
    windowed: bool,
    lam: float,
    t0: float,
    t1: float,
    bounds: tuple[np.ndarray, np.ndarray, list[str], np.ndarray | None] | None = None,
    gram: Callable[[], tuple[np.ndarray, float] | None] | None = None,
) -> StepResult | None:
    """The step's result when daqp's C entry point solves its box QP at once (module docstring), else ``None``.

        ``out`` (``layouts.OUT_ROWS``, n): the step's box rows and answers (``wqp_free_step``'s), with the resolver's
        ``_P`` and ``_q`` holding the QP; ``lam``: the step's λ; ``t0``/``t1`` [s]: when the step started and its build
        ended; ``bounds``: the bound subtasks' rows (G, h, names, safety flags) G q̇ ≤ h, kept by the result (copies of
        the plan's buffers), or ``None``; a q̇ that breaks a row with a safety flag set goes to the template (it scales
    q̇ to keep them: ``qp.base.keep_safe``), one that keeps them is the template's answer. ``gram``:
        the Gram factor (F, δ) of P = FᵀF + δI when the template would give the backend one (``WQPBuild.gram``): from
        the backend's lift size on, the QP is solved lifted as the backend lifts it."""
    backend = resolver.backend
    if type(backend) is not DaqpBackend or not ready("wqp"):
        return None  # (ready: not during a cold start, whose steps run the kernels' interpreted twins)
    G, h = (None, None) if bounds is None else bounds[:2]
    iterations = _solve(resolver, backend, out, G, h, gram)
    if iterations is None:
        return None
    if bounds is not None and not _keeps_safety_rows(out[OUT_DQ], G, h, bounds[3]):
        return None  # (the template scales q̇ to keep them, and says so)
    dq, kept = out[OUT_DQ], out[OUT_KEPT]
    before = resolver._dq_prev
    resolver._dq_hist = (kept, np.zeros_like(kept) if before is None else before)  # (as the template keeps them)
    resolver._dq_prev = kept
    t2 = time.perf_counter()
    limits = resolver.limits
    box = limits.box_from(out, windowed)
    main = resolver.layout(stack).main
    diag = QPDiagnostics()
    diag.backend, diag.qp, diag.iterations = backend.name, 1, int(iterations)

    def diagnostics() -> tuple[float, bool, dict[str, object]]:  # on first read of the result's diagnostics
        diag.active_limits = box.active(kept, limits.joint_names)
        resolver._diagnose_terms([terms[i] for i in main], lam, kept, diag)
        if G is not None and G.shape[0]:  # (as WeightedQPResolver._diagnose)
            diag.bound_violation = float(np.max(np.maximum(G @ kept - h, 0.0)))
        return diag.sigma_min, bool(diag.damped_levels), diag.as_info()

    info: dict[str, object] = {"backend": diag.backend, "qp": 1, "iterations": diag.iterations}
    return LazyStepResult.make(dq, terms, None, info, t1 - t0, t2 - t1, main, diagnostics)


def _keeps_safety_rows(dq: np.ndarray, G: np.ndarray | None, h: np.ndarray | None, safe: np.ndarray | None) -> bool:
    """Whether ``dq`` keeps the safety rows (``safe``: a flag per row of G q̇ ≤ h) within ``SAFETY_TOLERANCE``: the
    test of the template's last guard (``qp.base.keep_safe``), which leaves such a q̇ as it is."""
    if safe is None or G is None or h is None or not safe.any():
        return True
    C, d = (G, h) if safe.all() else (G[safe], h[safe])
    return bool((C @ dq <= d + SAFETY_TOLERANCE).all())


def _solve(
    resolver: Any, backend: DaqpBackend, out: np.ndarray, G: np.ndarray | None, h: np.ndarray | None,
    gram: Callable[[], tuple[np.ndarray, float] | None] | None,
) -> int | None:  # fmt: skip
    """The QP through daqp's C entry point in ``DaqpBackend.solve``'s order — the separable split (bounds only,
    from its split size), the lifted QP (from its lift size, when ``gram`` gives a factor of few rows), P as given —
    into the rows ``OUT_DQ``, ``OUT_KEPT`` of ``out``; daqp's iterations, or ``None`` when daqp did not solve it at
    once (the template then poses it with every retry)."""
    n, nr = out.shape[1], 0 if G is None else G.shape[0]
    P, g = resolver._P, resolver._q
    cached = resolver.__dict__.get("_native_box")
    if nr == 0 and n >= backend._split_min_n:  # (bounds only: the split first)
        native, qbuf, work, idx = _scratch(resolver, backend, n, 0, 0, cached)
        if native is None:
            return None
        flag, iterations, nc = HK.box_qp_native_split_into(native.ctl, native.x, qbuf, P, g, out, SPLIT_MIN_SAVING,
                                                           work, idx)  # fmt: skip
        if nc >= 0:
            return iterations if flag == 1 or flag == 2 else None
        cached = resolver.__dict__.get("_native_box")
    factor = gram() if gram is not None and n >= backend.lift_min_n else None
    if factor is not None and factor[0].shape[0] * LIFT_MAX_ROWS_PER_VARIABLE <= n and factor[1] > 0.0:
        F, delta = factor  # (DaqpBackend.solve's test of the factor: it lifts this QP)
        native, qbuf, _, _ = _scratch(resolver, backend, n, nr, F.shape[0], cached)
        if native is None:
            return None
        if G is None or h is None:  # (no rows: the lifted QP's equalities only)
            G, h = np.zeros((0, n)), np.zeros(0)
        flag, iterations = HK.lifted_rows_qp_native_into(native.ctl, native.x, qbuf, F, delta, g, out, G, h)
    else:
        native, qbuf, _, _ = _scratch(resolver, backend, n, nr, 0, cached)
        if native is None:
            return None
        if G is not None and h is not None and nr:
            flag, iterations = HK.rows_qp_native_into(native.ctl, native.x, qbuf, P, g, out, G, h)
        else:
            flag, iterations = HK.box_qp_native_into(native.ctl, native.x, qbuf, P, g, out)
    return iterations if flag == 1 or flag == 2 else None


def _scratch(resolver: Any, backend: DaqpBackend, n: int, nr: int, k: int, cached: Any) -> tuple[Any, ...]:
    """(daqp's native record, the QP buffer, the split's work and index arrays) for a QP of n variables and nr rows,
    lifted by k variables, kept by the resolver while they serve; (None, …) when the native call is off."""
    native = NativeDaqp.for_backend(backend, n + k, nr + k, None if cached is None else cached[0])
    if native is None:
        return None, None, None, None
    size = (n + k) ** 2 + 3 * (n + k) + (nr + k) * (n + k + 2)  # (qp_views' P, q, rows, upper and lower)
    if cached is None or cached[0] is not native or cached[3].shape != (n,) or cached[1].shape[0] < size:
        scratch = (np.empty(size), np.empty((4 + n, n)), np.empty(n, dtype=np.int64))
        cached = resolver.__dict__["_native_box"] = (native, *scratch)
    return cached


def warm_native_box() -> None:
    """Compile (or load) the native box QP's kernels (whole and split) on a 2-variable QP whose bound binds, with the
    argument types of a step's call (``redundik.warmup`` calls it with the ``wqp`` kernels, so that the first step
    whose limit binds does not compile them in the control loop's thread); nothing when daqp's native call is
    off."""
    backend = DaqpBackend()
    native = NativeDaqp.for_backend(backend, 2, 0, None)
    if native is None:
        return
    out = np.zeros((OUT_ROWS, 2))
    out[OUT_LB], out[OUT_UB] = -1.0, 0.5
    qbuf, work, idx = np.empty(10), np.empty((6, 2)), np.empty(2, dtype=np.int64)
    HK.box_qp_native_into(native.ctl, native.x, qbuf, np.eye(2), np.array([-1.0, 0.0]), out)
    HK.box_qp_native_split_into(native.ctl, native.x, qbuf, np.eye(2), np.array([-1.0, 0.0]), out, 0, work, idx)
    rows = NativeDaqp.for_backend(backend, 3, 2, native)
    if rows is not None:  # (a step with bound rows: one row x₀ + x₁ ≤ 0.2; lifted: P = FᵀF + I, F = (1 1))
        G, h, g = np.ones((1, 2)), np.array([0.2]), np.array([-1.0, 0.0])
        HK.rows_qp_native_into(rows.ctl, rows.x, np.empty(32), np.eye(2), g, out, G, h)
        HK.lifted_rows_qp_native_into(rows.ctl, rows.x, np.empty(32), np.ones((1, 2)), 1.0, g, out, G, h)
    diag = (2.0 * np.eye(2)).reshape(-1)[::3]  # (P's diagonal: a strided view, as wqp's ``_diag``)
    K.gram_diagonal_matches(np.ones((1, 2)), 1.0, diag, 1e-9)  # (the lifted QP's test of its factor)

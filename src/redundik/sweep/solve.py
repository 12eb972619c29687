"""One chunk of a sweep: problems ``start`` … ``stop − 1`` iterated to convergence through the batch API.

Every iteration resolves all still-active problems of the chunk in one :meth:`BatchResolver.solve` call (one step
of N problems at once, the QP backend only where a limit binds) and integrates q ← q ⊕ q̇·dt. A problem leaves the
active set when its task error ‖e‖ < tol (``converged``), when its error fell by less than the stall rule's
``min_decrease`` over ``window`` steps (``stalled``), after ``max_iterations`` steps (``max_iterations``), or if its
configuration stopped being finite (``failed``; its last finite configuration is kept, so nothing reported is NaN).

Problems are independent; a chunk's results are bit-identical wherever it runs (in-process, any Dask worker), and
BLAS is held to one thread inside a chunk (threadpoolctl) so that no threaded product reorders sums. A different
chunk size (a different batch composition) changes results only by rounding (≤ 1e-12 measured, statuses and
iteration counts equal; tested to 1e-9), which is why the chunk size is part of the sweep file.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from threadpoolctl import threadpool_limits

from redundik.resolvers.batch import BatchResolver
from redundik.sweep.plan import SweepPlan

#: Status codes of the ``status`` column.
STATUSES = ("converged", "stalled", "max_iterations", "failed")


def final_metrics(br: BatchResolver, plan: SweepPlan, q: np.ndarray, targets: np.ndarray) -> dict[str, np.ndarray]:
    """Task error, manipulability, joint-limit margin and reached frame position at the configurations q (N, nq).

    Returns:
        ``final_error`` ‖e‖ [m, rad] (the convergence test's error), ``manipulability`` √det(J Jᵀ) of the task's
        rows [m, rad per rad], ``limit_margin`` min over limited joints of the distance to the nearer limit as a
        fraction of the joint's range [1] (0.5 mid-range, 0 at a limit, < 0 beyond), ``reached_x/y/z`` [m].
    """
    J, e, _ = br._kinematics(q, targets)  # the batch's own kinematics: the same error as the iteration's
    err = np.linalg.norm(e, axis=1)
    JJt = J @ J.transpose(0, 2, 1)
    manip = np.sqrt(np.maximum(np.linalg.det(JJt), 0.0))
    model, data, fid = plan.robot.model.model, br._data, br.fid
    reached = np.empty((q.shape[0], 3))
    for i in range(q.shape[0]):
        pin.framesForwardKinematics(model, data, q[i])
        reached[i] = data.oMf[fid].translation
    joints = [j for j in plan.robot.model.joints if j.idx_q >= 0 and np.isfinite(j.lower) and np.isfinite(j.upper)]
    if joints:
        iq = np.array([j.idx_q for j in joints])
        lo = np.array([j.lower for j in joints])
        hi = np.array([j.upper for j in joints])
        span = np.where(hi > lo, hi - lo, 1.0)
        margin = np.min(np.minimum(q[:, iq] - lo, hi - q[:, iq]) / span, axis=1)
    else:
        margin = np.full(q.shape[0], np.inf)
    return {
        "final_error": err,
        "manipulability": manip,
        "limit_margin": margin,
        "reached_x": reached[:, 0],
        "reached_y": reached[:, 1],
        "reached_z": reached[:, 2],
    }


def _integrate(model: pin.Model, q: np.ndarray, dq: np.ndarray, dt: float) -> np.ndarray:
    if model.nq == model.nv:
        return q + dq * dt
    return np.stack([pin.integrate(model, q[i], dq[i] * dt) for i in range(q.shape[0])])


def run_chunk(plan: SweepPlan, start: int, stop: int, method: str = "batch") -> dict[str, np.ndarray]:
    """Iterate problems ``start`` … ``stop − 1`` to convergence; their result columns (see :mod:`redundik.sweep`).

    Args:
        plan: The sweep.
        start: First problem index.
        stop: One past the last problem index.
        method: ``"batch"`` (one :meth:`BatchResolver.solve` per iteration) or ``"loop"`` (the same problems one by
            one through ``resolver.step``, :meth:`BatchResolver.solve_loop`: the reference, and the benchmark's
            baseline).
    """
    if method not in ("batch", "loop"):
        raise ValueError(f"method must be 'batch' or 'loop', got {method!r}")
    with threadpool_limits(limits=1):
        return _run_chunk(plan, start, stop, method)


def _run_chunk(plan: SweepPlan, start: int, stop: int, method: str) -> dict[str, np.ndarray]:
    conv = plan.spec.convergence
    dt, tol, max_it = conv.dt, conv.tol, conv.max_iterations
    stall = conv.stall
    br = plan.batch_resolver()
    solve = br.solve if method == "batch" else br.solve_loop
    model = plan.robot.model.model
    ti, si, q0, T = plan.problems(start, stop)
    n = q0.shape[0]
    q = q0.copy()
    status = np.full(n, 2, dtype=np.int8)  # max_iterations unless something else happens
    iterations = np.zeros(n, dtype=np.int64)
    qp_steps = np.zeros(n, dtype=np.int64)
    active = np.ones(n, dtype=bool)
    ring = np.zeros((n, stall.window + 1)) if stall is not None else None
    for k in range(max_it + 1):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        res = solve(q[idx], T[idx], dt)
        err = res.task_error
        done = err < tol
        status[idx[done]] = 0
        iterations[idx] = k
        if stall is not None and ring is not None:
            W = stall.window
            ring[idx, k % (W + 1)] = err
            if k >= W:
                stalled = ~done & (ring[idx, (k - W) % (W + 1)] - err < stall.min_decrease)
                status[idx[stalled]] = 1
                done |= stalled
        if k == max_it:
            break
        go = ~done
        moving = idx[go]
        qn = _integrate(model, q[moving], res.dq[go], dt)
        bad = ~np.isfinite(qn).all(axis=1)
        status[moving[bad]] = 3
        active[idx[done]] = False
        active[moving[bad]] = False
        q[moving[~bad]] = qn[~bad]
        qp_steps[moving[~bad]] += res.qp[go][~bad]
        iterations[moving[~bad]] = k + 1
    out: dict[str, np.ndarray] = {
        "problem": np.arange(start, stop, dtype=np.int64),
        "target_index": ti,
        "start_index": si,
        "target_x": T[:, 0, 3].copy(),
        "target_y": T[:, 1, 3].copy(),
        "target_z": T[:, 2, 3].copy(),
        "status": status,
        "converged": status == 0,
        "iterations": iterations,
        "qp_steps": qp_steps,
    }
    out.update(final_metrics(br, plan, q, T))
    for j in range(q.shape[1]):
        out[f"start_q{j}"] = q0[:, j]
    for j in range(q.shape[1]):
        out[f"final_q{j}"] = q[:, j]
    return out

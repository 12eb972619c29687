"""One chunk of a sweep: problems ``start`` … ``stop − 1`` iterated to convergence through the batch API.

Every iteration resolves all still-active problems of the chunk in one :meth:`BatchResolver.solve` call (one step
of N problems at once, the QP backend only where a limit binds) and integrates q ← q ⊕ q̇·dt. A problem leaves the
active set when its task error ‖e‖ < tol (``converged``), when its error fell by less than the stall rule's
``min_decrease`` over ``window`` steps (``stalled``), after ``max_iterations`` steps (``max_iterations``), or if its
configuration stopped being finite (``failed``; its last finite configuration is kept, so nothing reported is NaN).

With ``method: solve_ik`` in the sweep file, each problem is instead :func:`redundik.solve_ik` from its start
(:func:`_run_chunk_ik`): Levenberg–Marquardt within the joint limits, random restarts; ``status`` is then
``converged``, ``max_restarts`` or ``timeout``.

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

#: Status codes of the ``status`` column (the last two: ``method: solve_ik``'s reasons when it did not converge).
STATUSES = ("converged", "stalled", "max_iterations", "failed", "max_restarts", "timeout")


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
            baseline). With ``method: solve_ik`` in the file, both solve each problem with
            :func:`redundik.solve_ik` (:func:`_run_chunk_ik`).
    """
    if method not in ("batch", "loop"):
        raise ValueError(f"method must be 'batch' or 'loop', got {method!r}")
    with threadpool_limits(limits=1):
        if plan.spec.method == "solve_ik":  # one problem after the other either way
            return _run_chunk_ik(plan, start, stop)
        return _run_chunk(plan, start, stop, method)


def _columns(
    br: BatchResolver, plan: SweepPlan, first: dict[str, np.ndarray], q0: np.ndarray, q: np.ndarray, T: np.ndarray
) -> dict[str, np.ndarray]:
    """The result columns: ``first`` (problem … qp_steps), the final metrics at q towards T, ``start_q*`` and
    ``final_q*``."""
    out = {**first, **final_metrics(br, plan, q, T)}
    for j in range(q.shape[1]):
        out[f"start_q{j}"] = q0[:, j]
    for j in range(q.shape[1]):
        out[f"final_q{j}"] = q[:, j]
    return out


def _run_chunk_ik(plan: SweepPlan, start: int, stop: int) -> dict[str, np.ndarray]:
    """``method: solve_ik``: problem p is ``solve_ik(robot, frame, target, q0=its start, seed=(ik.seed, p))`` with
    the file's tolerances (``convergence.tol`` [m], ``ik.orientation_tolerance`` [rad]), ``max_iterations`` per
    attempt, ``ik.max_restarts`` and ``ik.timeout``; the same columns, ``qp_steps`` 0, and a ``restarts`` column."""
    from redundik.ik.solve import solve_ik

    spec = plan.spec
    ik, conv = plan.ik_options, spec.convergence
    pose = len(plan.axes) == 6
    ti, si, q0, T = plan.problems(start, stop)
    n = q0.shape[0]
    q = q0.copy()
    status = np.zeros(n, dtype=np.int8)
    iterations, restarts = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
    for i in range(n):
        res = solve_ik(
            plan.robot.model, spec.task.frame, T[i] if pose else T[i, :3, 3], q0[i],
            position_tolerance=conv.tol, orientation_tolerance=ik.orientation_tolerance or conv.tol,
            timeout=ik.timeout, max_restarts=ik.max_restarts, max_iterations=conv.max_iterations,
            seed=(ik.seed, start + i),
        )  # fmt: skip
        q[i] = res.q
        status[i] = STATUSES.index(res.reason)
        iterations[i], restarts[i] = res.iterations, res.restarts
    first = {
        "problem": np.arange(start, stop, dtype=np.int64), "target_index": ti, "start_index": si,
        "target_x": T[:, 0, 3].copy(), "target_y": T[:, 1, 3].copy(), "target_z": T[:, 2, 3].copy(),
        "status": status, "converged": status == 0, "iterations": iterations,
        "qp_steps": np.zeros(n, dtype=np.int64), "restarts": restarts,
    }  # fmt: skip
    return _columns(plan.batch_resolver(), plan, first, q0, q, T)


def _run_chunk(plan: SweepPlan, start: int, stop: int, method: str) -> dict[str, np.ndarray]:
    conv = plan.spec.convergence
    dt, tol, max_it = conv.dt, conv.tol, conv.max_iterations
    assert dt is not None  # method: differential (load_sweep requires it)
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
    first: dict[str, np.ndarray] = {
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
    return _columns(br, plan, first, q0, q, T)

"""Compiled ``hqp`` step of a fused stack (``redundik.resolvers.fused``): the stack's rows written from Pinocchio's
Jacobians into ``hqp``'s least-squares and inequality buffers, then the unconstrained cascade and its tests
(``hqp_kernels.closed_step``), in one call.

The rows come from the one implementation of each piece: the frame rows and the null-space objective of
:mod:`redundik.resolvers.fused_kernels` (``frame_rows``, ``_null_objective``), the clearance of
:mod:`redundik.tasks.potential_kernels` (``clearance_into``, the bound subtasks' damper rows). The plan's static data
is read from its ``ints`` / ``floats`` in the layout of ``fused.HEADER``.
"""

from __future__ import annotations

import numpy as np

from redundik.kinematics.layouts import POSE_P
from redundik.resolvers.fused_kernels import _main_error2, _null_objective, _part, _sumsq, cap_ratio, frame_rows
from redundik.resolvers.hqp_kernels import closed_step
from redundik.resolvers.hqp_layout import (
    H_FRAME_ROWS,
    H_FRAME_STARTS,
    H_IQ,
    H_J,
    H_JOINT_FLAGS,
    H_JOINT_ROWS,
    H_JOINT_STARTS,
    H_JOINT_TARGETS,
    H_K,
    H_M,
    H_N,
    H_NQ,
    H_NV,
    OUT_DQ,
    OUT_ROWS,
    CascadeRows,
)
from redundik.resolvers.kernels import _jit
from redundik.resolvers.layouts import (
    B_AXES,
    B_CENTER,
    B_FID,
    B_LO,
    B_LOWER,
    B_NAXES,
    B_RADIUS,
    B_RATE,
    B_ROW,
    B_UP,
    B_UPPER,
    FRAME_ROWS,
    GIVEN_ERROR,
    H_EXTERNAL_Z,
    LIM_AMAX,
    LIM_HI,
    LIM_LO,
    LIM_VMAX,
    OPT_GAIN,
    OPT_POSITION,
    OPT_RATE,
)
from redundik.tasks.potential_kernels import clearance_into

__all__ = ["clearance_rows", "fused_hqp_step", "step_work_size", "step_work_views"]


def step_work_size(K: int, m: int, nv: int, levels: int) -> int:
    """Length of a fused ``hqp`` step's ``work`` (one allocation a step, zeroed; :func:`step_work_views` names its
    parts) for K frame tasks, m fused rows, nv velocity coordinates and the cascade's levels."""
    return 2 * m + (1 + OUT_ROWS + FRAME_ROWS * K) * nv + 4 * levels


@_jit
def step_work_views(
    work: np.ndarray, K: int, m: int, nv: int, levels: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The parts of a fused ``hqp`` step's ``work``, views in this order (the order of the block): (e, v) (2, m), z
    of the null-space objective (nv,), ``out`` (``OUT_ROWS``, 1, nv) of ``closed_step`` (its row ``OUT_DQ`` starts
    at 2m + nv + ``OUT_DQ``·nv), the frames' Jacobians (K, 6, nv) and the per-level ``stats`` (levels, 4). The parts
    Python writes before the call come first: it slices (e, v) and z itself (``HierarchicalQPResolver._fused_solve``);
    the others, seldom read, through ``step_work_views.py_func``."""
    a = 2 * m
    b = a + nv
    c = b + OUT_ROWS * nv
    e = c + FRAME_ROWS * K * nv
    return (
        work[0:a].reshape((2, m)),
        work[a:b],
        work[b:c].reshape((OUT_ROWS, 1, nv)),
        work[c:e].reshape((K, FRAME_ROWS, nv)),
        work[e : e + 4 * levels].reshape((levels, 4)),
    )


@_jit
def clearance_rows(
    Jw: np.ndarray,
    poses: np.ndarray,
    dt: float,
    bint: np.ndarray,
    bcols: np.ndarray,
    bfl: np.ndarray,
    C: np.ndarray,
    d: np.ndarray,
) -> None:
    """The damper rows of bound subtasks on clearances (``BoundSubtask.rows_into`` on a ``Clearance``, the same
    operations in the same order): per packed bound, p and −η (a lower bound) or η into C's row ``bint[k, B_ROW]``
    (``clearance_into``, from the joint Jacobians ``Jw`` and the frame's origin in ``poses``), d = γ (p − lower) and,
    with an upper bound too, the row −C, d = γ (upper − p); γ = min(K or 1/dt, 1/dt) [1/s]. ``bint``, ``bfl``: a
    row per bound (columns ``B_FID`` … and ``B_CENTER`` … of :mod:`redundik.resolvers.fused`); ``bcols``: per bound,
    the columns of the joints that support its frame.
    """
    nv = C.shape[1]
    J6 = np.empty((6, nv))
    cap = 1.0 / dt
    for k in range(bint.shape[0]):
        ib, fb = bint[k], bfl[k]
        fid, row = ib[B_FID], ib[B_ROW]
        lower, upper = ib[B_LOWER] != 0, ib[B_UPPER] != 0
        rate = fb[B_RATE]
        gamma = cap if rate == 0 else min(rate, cap)
        p = clearance_into(
            Jw, poses[fid, POSE_P : POSE_P + 3], bcols[k], ib[B_AXES : B_AXES + ib[B_NAXES]],
            fb[B_CENTER : B_CENTER + 3], fb[B_RADIUS], J6, True, C[row], -1.0 if lower else 1.0,
        )  # fmt: skip
        if lower:
            d[row] = gamma * (p - fb[B_LO])
            if upper:
                for c in range(nv):
                    C[row + 1, c] = -C[row, c]
                d[row + 1] = gamma * (fb[B_UP] - p)
        else:
            d[row] = gamma * (fb[B_UP] - p)


#: The records of :func:`fused_hqp_step`: Pinocchio's memory and the references (Jw, poses, refs); the step (t [s],
#: dt [s], q, the last q̇ kept); the plan's packing (ints, floats, dest, bint, bcols, bfl); the work arrays (Jf, ev);
#: the outputs (out, stats).
Kinematics = tuple[np.ndarray, np.ndarray, np.ndarray]
Step = tuple[float, float, np.ndarray, np.ndarray]
Packing = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
FusedWork = tuple[np.ndarray, np.ndarray]
FusedOuts = tuple[np.ndarray, np.ndarray]


@_jit
def _task_rows(
    q: np.ndarray,
    ints: np.ndarray,
    floats: np.ndarray,
    dest: np.ndarray,
    coef: np.ndarray,
    Jf: np.ndarray,
    ev: np.ndarray,
    A: np.ndarray,
    b: np.ndarray,
    w: np.ndarray,
) -> None:
    """The frame tasks' rows (their Jacobians ``Jf`` and v, written by ``frame_rows``) and the level joint tasks'
    rows (J = I[sel], e = (q_ref − q)[sel], v = K e) into A, b, w at the rows ``dest[r]`` of the stack's layout."""
    K, J, nq = ints[H_K], ints[H_J], ints[H_NQ]
    e, v = ev[0], ev[1]
    starts = _part(ints, H_FRAME_STARTS, K + 1)
    frows = _part(ints, H_FRAME_ROWS, starts[K])
    for k in range(K):
        wk = coef[K + k]
        Jk = Jf[k]
        for r in range(starts[k], starts[k + 1]):
            a = dest[r]
            A[a, :] = Jk[frows[r], :]
            b[a] = v[r]
            w[a] = wk
    jq = _part(ints, H_IQ, ints[H_NV])
    jstarts = _part(ints, H_JOINT_STARTS, J + 1)
    jsel = _part(ints, H_JOINT_ROWS, jstarts[J])
    jflags = _part(ints, H_JOINT_FLAGS, J)
    to = ints[H_JOINT_TARGETS]
    mf = starts[K]
    c0 = 2 * K  # (the joint tasks' gains, then their weights)
    for k in range(J):
        gain, wk = coef[c0 + k], coef[c0 + J + k]
        for r in range(jstarts[k], jstarts[k + 1]):
            s = jsel[r]
            j = jq[s]
            if jflags[k] & GIVEN_ERROR:  # a Lie-group coordinate: e written by the caller (Pinocchio's difference)
                err = e[mf + r]
            else:
                err = floats[to + k * nq + j] - q[j]
            e[mf + r] = err
            v[mf + r] = gain * err
            a = dest[mf + r]
            A[a, :] = 0.0
            A[a, s] = 1.0
            b[a] = gain * err
            w[a] = wk


@_jit
def _null_rows(
    q: np.ndarray,
    ints: np.ndarray,
    floats: np.ndarray,
    dest: np.ndarray,
    coef: np.ndarray,
    A: np.ndarray,
    b: np.ndarray,
    w: np.ndarray,
    z: np.ndarray,
) -> None:
    """z of the null-space objective (``_null_objective``; added to the terms Python writers put in z in a mixed
    plan) and, for a level that carries it after rows of its own, its ½‖q̇ − z‖² identity rows at the starts
    ``dest[m:]``."""
    K, J, N, m, nv = ints[H_K], ints[H_J], ints[H_N], ints[H_M], ints[H_NV]
    cn = 2 * K + 2 * J + 1  # (the null coefficients, after the joint tasks' and an unused slot)
    if N > 0:
        if ints[H_EXTERNAL_Z] != 0:  # z holds the terms Python writers gave (a mixed plan): kept, added after
            zx = z.copy()
            _null_objective(q, ints, floats, coef[cn : cn + N], z)
            for i in range(nv):
                z[i] += zx[i]
        else:
            _null_objective(q, ints, floats, coef[cn : cn + N], z)
    for i in range(m, dest.shape[0]):
        a = dest[i]
        for r in range(nv):
            A[a + r, :] = 0.0
            A[a + r, r] = 1.0
            b[a + r] = z[r]
            w[a + r] = 1.0


@_jit
def fused_hqp_step(
    kin: Kinematics,
    step: Step,
    plan: Packing,
    coef: np.ndarray,
    limits: tuple[np.ndarray, np.ndarray, np.ndarray],
    work: FusedWork,
    rows: CascadeRows,
    params: np.ndarray,
    outs: FusedOuts,
) -> tuple[float, float, float, float]:
    """One ``hqp`` step of a fused stack: the frame rows (``frame_rows``) and joint rows written into the cascade's
    least-squares buffers A, b, w at the rows ``dest[r]`` of the stack's layout (the rows ``hqp``'s per-task gather
    would give them, ``_task_rows``), z of the null-space objective and its identity rows (``_null_rows``);
    the packed bound subtasks' damper rows into C, d (``clearance_rows``; the caller wrote the others); then
    ``closed_step`` on those rows and the inequality rows C, d.

    Args:
        kin: (Jw, poses, refs): the joint Jacobians and frame poses (views of Pinocchio's memory), the reference rows.
        step: (t [s], dt [s], q, the last q̇ kept).
        plan: (ints, floats, dest, bint, bcols, bfl): the plan's packing (``fused.HEADER``), the destination row of
            each fused row, the packed bound subtasks.
        coef: gain (K), weight (K) per frame task; gain (J), weight (J) per joint task; an unused slot; the N null
            coefficients; then position (0/1), rate (0/1) and the position gain of the limits.
        limits: (iq, lim): the q index of each velocity coordinate and the (4, nv) limit rows (lower, upper [rad],
            velocity [rad/s], acceleration [rad/s²]) of ``LimitBox.kernel_args`` (``FusedPlan.limits``): fewer
            arrays for the call to unbox than the whole record; and the joints' 1 / speed cap, or empty
            (``fused_kernels.cap_ratio``).
        work: (Jf, ev): the frame tasks' Jacobians (K, 6, nv) and (e, v) (2, m).
        rows: ``closed_step``'s rows of the cascade; params: its settings (the two records passed on).
        outs: (out, stats): ``closed_step``'s.

    Returns:
        (status, Σ e² of the main rows, ‖q̇‖² and ``cap_ratio`` when feasible): status −1 — a rotation error too
        large for the compiled log3 (evaluate the tasks one by one); otherwise ``closed_step``'s: 1 feasible (q̇ in
        out[OUT_DQ, 0]), 0 a constraint is active, 2 q̇ not finite.
    """
    Jw, poses, refs = kin
    t, dt, q, dq_prev = step
    ints, floats, dest, bint, bcols, bfl = plan
    A, b, w, C, d, z = rows[0], rows[1], rows[2], rows[3], rows[4], rows[5]
    Jf, ev = work
    out, stats = outs
    K, m = ints[H_K], ints[H_M]
    if not frame_rows(Jw, poses, t, refs, ints, floats, coef[0:K], Jf, ev[0], ev[1]):
        return -1.0, 0.0, 0.0, -1.0
    _task_rows(q, ints, floats, dest, coef, Jf, ev, A, b, w)
    _null_rows(q, ints, floats, dest, coef, A, b, w, z)
    if bint.shape[0] > 0:
        clearance_rows(Jw, poses, dt, bint, bcols, bfl, C, d)
    iq, lim, inv = limits
    o = 2 * K + 2 * ints[H_J] + 1 + ints[H_N]  # the limits' options (OPT_* of a box), after the null coefficients
    position, has_rate, gain = coef[o + OPT_POSITION] != 0.0, coef[o + OPT_RATE] != 0.0, coef[o + OPT_GAIN]
    box_args = (iq, lim[LIM_LO], lim[LIM_HI], lim[LIM_VMAX], lim[LIM_AMAX], position, has_rate, gain)
    status = closed_step(rows, params, q, box_args, dt, dq_prev, out, stats)
    if status != 1:
        return float(status), _main_error2(ints, ev[0][0:m]), 0.0, -1.0
    return 1.0, _main_error2(ints, ev[0][0:m]), _sumsq(out[OUT_DQ, 0]), cap_ratio(out[OUT_DQ, 0], inv)


@_jit
def fused_hqp_call(
    Jw: np.ndarray, poses: np.ndarray, refs: np.ndarray, t: float, dt: float, q: np.ndarray, dq_prev: np.ndarray,
    ints: np.ndarray, floats: np.ndarray, dest: np.ndarray, bint: np.ndarray, bcols: np.ndarray, bfl: np.ndarray,
    coef: np.ndarray, iq: np.ndarray, lim: np.ndarray, inv: np.ndarray, A: np.ndarray, b: np.ndarray, w: np.ndarray,
    C: np.ndarray, d: np.ndarray, meta: np.ndarray, params: np.ndarray, work: np.ndarray,
) -> tuple[float, float, float, float]:  # fmt: skip
    """:func:`fused_hqp_step` for a caller in Python, its records' arrays given one by one: numba unboxes an array
    given inside a tuple more slowly than one given as an argument of its own (and each argument costs about
    60 ns), so the records are made here, in compiled code, at no cost; the step's own buffers are the parts of one
    ``work`` (:func:`step_work_views`)."""
    ev, z, out, Jf, stats = step_work_views(work, ints[H_K], ints[H_M], ints[H_NV], meta.shape[1] - 1)
    return fused_hqp_step(
        (Jw, poses, refs), (t, dt, q, dq_prev), (ints, floats, dest, bint, bcols, bfl), coef, (iq, lim, inv), (Jf, ev),
        (A, b, w, C, d, z, meta), params, (out, stats),
    )  # fmt: skip

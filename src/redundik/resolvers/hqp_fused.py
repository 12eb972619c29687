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

from redundik.resolvers.fused import (
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
    GIVEN_ERROR,
    H_EXTERNAL_Z,
)
from redundik.resolvers.fused_kernels import _main_error2, _null_objective, _part, _sumsq, frame_rows
from redundik.resolvers.hqp_kernels import closed_step
from redundik.resolvers.kernels import _jit
from redundik.tasks.potential_kernels import clearance_into

__all__ = ["clearance_rows", "fused_hqp_step"]


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
            Jw, poses[fid, 9:12], bcols[k], ib[B_AXES : B_AXES + ib[B_NAXES]], fb[B_CENTER : B_CENTER + 3],
            fb[B_RADIUS], J6, True, C[row], -1.0 if lower else 1.0,
        )  # fmt: skip
        if lower:
            d[row] = gamma * (p - fb[B_LO])
            if upper:
                for c in range(nv):
                    C[row + 1, c] = -C[row, c]
                d[row + 1] = gamma * (fb[B_UP] - p)
        else:
            d[row] = gamma * (fb[B_UP] - p)


@_jit
def fused_hqp_step(
    Jw: np.ndarray,
    poses: np.ndarray,
    t: float,
    refs: np.ndarray,
    q: np.ndarray,
    ints: np.ndarray,
    floats: np.ndarray,
    coef: np.ndarray,
    lim: np.ndarray,
    iq: np.ndarray,
    dt: float,
    dq_prev: np.ndarray,
    Jf: np.ndarray,
    ev: np.ndarray,
    dest: np.ndarray,
    A: np.ndarray,
    b: np.ndarray,
    w: np.ndarray,
    C: np.ndarray,
    d: np.ndarray,
    bint: np.ndarray,
    bcols: np.ndarray,
    bfl: np.ndarray,
    meta: np.ndarray,
    params: np.ndarray,
    z: np.ndarray,
    out: np.ndarray,
    stats: np.ndarray,
) -> tuple[float, float, float]:
    """One ``hqp`` step of a fused stack: the frame rows (``frame_rows``) and joint rows (J = I[sel],
    e = (q_ref − q)[sel], v = K e) written into the cascade's least-squares buffers A, b, w at the rows ``dest[r]``
    of the stack's layout (the rows ``hqp``'s per-task gather would give them), z of the null-space objective
    (``_null_objective``) and, for a level that carries it after rows of its own, its identity rows at the starts
    ``dest[m:]``; the packed bound subtasks' damper rows into C, d (``clearance_rows``; the caller wrote the others);
    then ``closed_step`` on those rows and the inequality rows C, d.

    ``coef``: gain (K), weight (K) per frame task; gain (J), weight (J) per joint task; an unused slot; the N null
    coefficients; then position (0/1), rate (0/1) and the position gain of the limits. ``lim`` (4, nv): lower, upper
    [rad], velocity [rad/s], acceleration [rad/s²] limits; ``iq`` their q index per velocity coordinate.

    Returns:
        (status, Σ e² of the main rows, ‖q̇‖² when feasible): status −1 — a rotation error too large for the
        compiled log3 (evaluate the tasks one by one); otherwise ``closed_step``'s: 1 feasible (q̇ in out[5, 0]),
        0 a constraint is active, 2 q̇ not finite.
    """
    K, J, N, m, nv, nq = ints[0], ints[1], ints[2], ints[3], ints[4], ints[5]
    e, v = ev[0], ev[1]
    if not frame_rows(Jw, poses, t, refs, ints, floats, coef[0:K], Jf, e, v):
        return -1.0, 0.0, 0.0
    starts = _part(ints, 8, K + 1)
    rows = _part(ints, 7, starts[K])
    for k in range(K):
        wk = coef[K + k]
        Jk = Jf[k]
        for r in range(starts[k], starts[k + 1]):
            a = dest[r]
            A[a, :] = Jk[rows[r], :]
            b[a] = v[r]
            w[a] = wk
    jq = _part(ints, 13, nv)
    jstarts = _part(ints, 11, J + 1)
    jsel = _part(ints, 10, jstarts[J])
    jflags = _part(ints, 12, J)
    to = ints[17]
    mf = starts[K]
    c0 = 2 * K
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
    if N > 0:
        if ints[H_EXTERNAL_Z] != 0:  # z holds the terms Python writers gave (a mixed plan): kept, added after
            zx = z.copy()
            _null_objective(q, ints, floats, coef[c0 + 2 * J + 1 : c0 + 2 * J + 1 + N], z)
            for i in range(nv):
                z[i] += zx[i]
        else:
            _null_objective(q, ints, floats, coef[c0 + 2 * J + 1 : c0 + 2 * J + 1 + N], z)
    for i in range(m, dest.shape[0]):  # a level with rows of its own and the null-space objective: ½‖q̇ − z‖² rows
        a = dest[i]
        for r in range(nv):
            A[a + r, :] = 0.0
            A[a + r, r] = 1.0
            b[a + r] = z[r]
            w[a + r] = 1.0
    if bint.shape[0] > 0:
        clearance_rows(Jw, poses, dt, bint, bcols, bfl, C, d)
    o = c0 + 2 * J + 1 + N
    status = closed_step(
        A, b, w, C, d, z, meta, params, q, iq, lim[0], lim[1], lim[2], lim[3],
        coef[o] != 0.0, coef[o + 1] != 0.0, coef[o + 2], dt, dq_prev, out, stats,
    )  # fmt: skip
    return float(status), _main_error2(ints, e[0:m]), _sumsq(out[5, 0]) if status == 1 else 0.0

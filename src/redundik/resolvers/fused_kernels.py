"""Compiled kernels of the fused step (``redundik.resolvers.fused``): a stack of frame tasks, joint-space tasks
and joint-space null-space terms evaluated, accumulated and solved in one call.

They compose the one implementation of each piece — the frame error (``kernels.frame_error``), the weighted rows
(``kernels.gram_update``), ``wqp``'s limit box and unconstrained optimum (``kernels.wqp_free_step``), the closed form
of eq. (5.8) (``kernels.closed_form_into``) — and the reference of the library's simple trajectories
(``target_kernels.reference_into``, which ``Line`` and ``Circle`` call too). ``hqp``'s fused step is
:mod:`redundik.resolvers.hqp_fused`.
Nothing here is a second implementation of what the per-task path computes.

A call takes few arguments (each costs the dispatcher time): the plan's static data packed in one integer array
``ints`` and one float array ``floats``, whose layout ``fused.HEADER`` describes (written by ``fused.FusedPlan``), and
the step's coefficients in ``coef`` (gains, weights × level ratios; then the limit options and λ for ``wqp``, ε,
λ_max and rcond for ``pinv``).

Reference rows (18,): p_d (3) [length], R_d (9, row-major), twist (v, ω) (6) [length/s, rad/s]. Trajectory parameter
rows (``PARAMS`` = 23,): p0 (3), R0 (9, row-major), then per kind — ``LINE``: velocity (3); ``CIRCLE``: centre (3),
r·e1 (3), r·e2 (3), ω [rad/s], φ [rad].
"""

from __future__ import annotations

import numpy as np

from redundik.kinematics.lie_kernels import frame_error_rp, frame_jacobian_lwa
from redundik.resolvers.fused import (
    GIVEN_ERROR,
    H_EXTERNAL_ROWS,
    H_EXTERNAL_Z,
    HEADER,
    IDENTITY,
    REF,
)
from redundik.resolvers.kernels import (
    _jit,
    closed_form_into,
    gram_update,
    wqp_free_step,
)
from redundik.tasks.target_kernels import reference_into
from redundik.tasks.trajectory import GIVEN, PARAMS

__all__ = ["HEADER", "REF", "frame_rows", "fused_pinv_step", "fused_wqp_step", "reference_into"]


@_jit
def _part(ints: np.ndarray, slot: int, size: int) -> np.ndarray:
    """The ``size`` entries of ``ints`` at the offset stored in header ``slot``."""
    o = ints[slot]
    return ints[o : o + size]


@_jit
def frame_rows(
    Jw: np.ndarray,
    poses: np.ndarray,
    t: float,
    refs: np.ndarray,
    ints: np.ndarray,
    floats: np.ndarray,
    gains: np.ndarray,
    Jf: np.ndarray,
    e: np.ndarray,
    v: np.ndarray,
) -> bool:
    """Every frame task's Jacobian (``frame_jacobian_lwa`` from the joint Jacobians ``Jw`` into ``Jf[k]``), its
    reference at t (compiled kinds: here; ``GIVEN``: the caller's row of ``refs``), error e and velocity v (rows
    starts[k]:starts[k+1] of e, v; ``frame_error_rp``) at the frame's placement, row ``fid`` of ``poses`` (the
    frames' placements, rotation column-major then translation).

    Returns:
        False as soon as a rotation error is too large for the compiled log3 (the caller then evaluates the tasks
        one by one, with Pinocchio's log3).
    """
    K, nv = ints[0], ints[4]
    kinds = _part(ints, 6, K)
    starts = _part(ints, 8, K + 1)
    rows = _part(ints, 7, starts[K])
    rot = _part(ints, 9, K)
    fids = _part(ints, 20, K)
    columns = _part(ints, 21, K * nv)
    po = ints[16]
    scratch = np.empty(REF)
    for k in range(K):
        pose = poses[fids[k]]
        p = pose[9:12]
        frame_jacobian_lwa(Jw, p, columns[k * nv : (k + 1) * nv], Jf[k])
        kind = kinds[k]
        if kind == GIVEN:
            r = refs[k]
        else:
            reference_into(kind, floats[po + k * PARAMS : po + (k + 1) * PARAMS], t, scratch)
            r = scratch
        a, b = starts[k], starts[k + 1]
        R = pose[0:9].reshape((3, 3)).T  # column-major storage: the C reshape is Rᵀ
        if not frame_error_rp(
            r[0:3], r[3:12].reshape((3, 3)), R, p, r[12:18], gains[k], rows[a:b], rot[k] != 0, e[a:b], v[a:b]
        ):
            return False
    return True


@_jit
def _null_objective(q: np.ndarray, ints: np.ndarray, floats: np.ndarray, coef: np.ndarray, z: np.ndarray) -> None:
    """z = Σ_k c_k w_k ⊙ (q − q_k) over 1-dof coordinates — the stack's null-space objective of eq. (5.8): a gradient
    subtask of a (weighted) joint centering (c_k its gain k), an identity regulariser such as a posture (c_k = −K,
    w_k = 1)."""
    N, nv, nq = ints[2], ints[4], ints[5]
    iq = _part(ints, 13, nv)
    wo, co = ints[18], ints[19]
    z[:] = 0.0
    for k in range(N):
        c = coef[k]
        for s in range(nv):
            w = floats[wo + k * nv + s]
            if w != 0.0:
                j = iq[s]
                z[s] += c * (w * (q[j] - floats[co + k * nq + j]))


@_jit
def _sumsq(x: np.ndarray) -> float:
    """Σ x² (‖q̇‖² for the divergence watch; NaN or inf when q̇ is not finite)."""
    total = 0.0
    for i in range(x.shape[0]):
        total += x[i] * x[i]
    return total


@_jit
def _main_error2(ints: np.ndarray, e: np.ndarray) -> float:
    """Σ e² over the main tasks' rows (the step's task error, squared)."""
    m = ints[3]
    main = _part(ints, 14, m)
    total = 0.0
    for r in range(m):
        if main[r]:
            total += e[r] * e[r]
    return total


@_jit
def fused_wqp_step(
    Jw: np.ndarray,
    poses: np.ndarray,
    t: float,
    refs: np.ndarray,
    q: np.ndarray,
    ints: np.ndarray,
    floats: np.ndarray,
    coef: np.ndarray,
    lim: np.ndarray,
    dt: float,
    dq_prev: np.ndarray,
    P: np.ndarray,
    g: np.ndarray,
    work: np.ndarray,
) -> tuple[float, float, float]:
    """One ``wqp`` step of a fused stack: frame rows (``frame_rows``) and joint rows (e = (q_ref − q)[sel],
    v = K e) into e, v (``ev`` (2, m)); P = Σ w JᵀJ and g = −Σ w Jᵀv (``gram_update``; a joint task adds w on P's
    diagonal, or to the diagonal shift when it is an identity task, as the per-task path does); the null-space
    objective z (``_null_objective``); then ``wqp_free_step`` (the limit box from ``lim`` (4, nv): lower, upper
    [rad], velocity [rad/s], acceleration [rad/s²] limits; the optimum; its test).

    ``work`` (flat, one allocation a step; :func:`wqp_work_views` names its parts): ``out`` (7, nv) — the box and
    the answers of ``wqp_free_step`` —, e and v (2, m), and the frames' Jacobians (K, 6, nv).

    ``coef``: gain (K), weight·ρ^k (K) per frame task; gain (J), weight·ρ^k (J) per joint task; ρ of the null-space
    objective; its N coefficients; then position (0/1), rate (0/1), the position gain and λ.

    Returns:
        (status, Σ e² of the main rows, ‖q̇‖² when inside): status −1 — a rotation error too large for the compiled
        log3 (evaluate the tasks one by one); 1 — the optimum is inside the box (q̇ in out[5]); 0 — a limit binds (P,
        g and the box in out[0:4] are ready for the QP).
    """
    K, J, N, m, nv = ints[0], ints[1], ints[2], ints[3], ints[4]
    out, ev, Jf = wqp_work_views(work, K, m, nv)
    e, v = ev[0], ev[1]
    if not frame_rows(Jw, poses, t, refs, ints, floats, coef[0:K], Jf, e, v):
        return -1.0, 0.0, 0.0
    starts = _part(ints, 8, K + 1)
    rows = _part(ints, 7, starts[K])
    reset = True
    for k in range(K):
        a, b = starts[k], starts[k + 1]
        if b - a == 6:
            gram_update(P, g, Jf[k], v[a:b], coef[K + k], reset)
        else:
            gram_update(P, g, np.ascontiguousarray(Jf[k][rows[a:b]]), v[a:b], coef[K + k], reset)
        reset = False
    if reset:
        P[:, :] = 0.0
        g[:] = 0.0
    iq = _part(ints, 13, nv)
    jstarts = _part(ints, 11, J + 1)
    jsel = _part(ints, 10, jstarts[J])
    jident = _part(ints, 12, J)
    nq = ints[5]
    to = ints[17]
    mf = starts[K]
    c0 = 2 * K
    shift = coef[c0 + 2 * J + N + 4]  # λ
    for k in range(J):
        gain, w = coef[c0 + k], coef[c0 + J + k]
        for r in range(jstarts[k], jstarts[k + 1]):
            s = jsel[r]
            j = iq[s]
            if jident[k] & GIVEN_ERROR:  # a Lie-group coordinate: e written by the caller (Pinocchio's difference)
                err = e[mf + r]
            else:
                err = floats[to + k * nq + j] - q[j]
            e[mf + r] = err
            v[mf + r] = gain * err
            g[s] -= w * v[mf + r]
            if jident[k] & IDENTITY == 0:
                P[s, s] += w
        if jident[k] & IDENTITY:
            shift += w
    mx = ints[H_EXTERNAL_ROWS]
    Jx, wx, zx = wqp_external_views(work, K, m, nv, mx)
    base = m - mx
    for r in range(mx):  # the rows Python writers gave (a mixed plan): P += w JᵀJ, g −= w Jᵀv, row by row
        w = wx[r]
        if w != 0.0:
            Jr = Jx[r]
            vr = w * v[base + r]
            for i in range(nv):
                a = w * Jr[i]
                if a != 0.0:
                    g[i] -= vr * Jr[i]
                    for j in range(nv):
                        P[i, j] += a * Jr[j]
    z_scale = coef[c0 + 2 * J]
    z = np.zeros(nv)
    if z_scale != 0.0:
        if N > 0:
            _null_objective(q, ints, floats, coef[c0 + 2 * J + 1 : c0 + 2 * J + 1 + N], z)
        if ints[H_EXTERNAL_Z] != 0:
            for i in range(nv):
                z[i] += zx[i]
        shift += z_scale
    o = c0 + 2 * J + 1 + N
    inside = wqp_free_step(
        P,
        g,
        shift,
        z,
        z_scale,
        q,
        iq,
        lim[0],
        lim[1],
        lim[2],
        lim[3],
        coef[o] != 0.0,
        coef[o + 1] != 0.0,
        coef[o + 2],
        dt,
        dq_prev,
        out,
    )
    return (1.0 if inside else 0.0), _main_error2(ints, e[0:m]), _sumsq(out[5]) if inside else 0.0


@_jit
def fused_pinv_step(
    Jw: np.ndarray,
    poses: np.ndarray,
    t: float,
    refs: np.ndarray,
    q: np.ndarray,
    ints: np.ndarray,
    floats: np.ndarray,
    coef: np.ndarray,
    work: np.ndarray,
) -> tuple[float, int, float, float, float, float]:
    """One ``pinv`` step of a fused stack: the frame tasks' rows stacked into J (m, n) and e, v, z of the
    null-space objective (``_null_objective``), and the closed form q̇ = J⁺V + (I − J⁺J) z (eq. 5.8,
    ``closed_form_into``, σ_min lazily).

    ``work`` (flat, one allocation a step; :func:`pinv_work_views` names its parts): J⁺V, (I − J⁺J) z and q̇
    (3, n), then J (m, n), e and v (2, m), the frames' Jacobians (K, 6, n) and z (n,). ``coef``: gain (K) per frame
    task, the N null coefficients, then ε, λ_max and rcond.

    Returns:
        (status — −1 a rotation error too large for the compiled log3, 1 done —, rank, σ_min (NaN: to compute on
        request), damping, Σ e², ‖q̇‖²).
    """
    K, N, m, nv = ints[0], ints[2], ints[3], ints[4]
    out, Jm, ev, Jf = pinv_work_views(work, K, m, nv)
    e, v = ev[0], ev[1]
    if not frame_rows(Jw, poses, t, refs, ints, floats, coef[0:K], Jf, e, v):
        return -1.0, 0, 0.0, 0.0, 0.0, 0.0
    starts = _part(ints, 8, K + 1)
    rows = _part(ints, 7, starts[K])
    for k in range(K):
        Jk = Jf[k]
        for r in range(starts[k], starts[k + 1]):
            Jm[r, :] = Jk[rows[r], :]
    z = work[work.shape[0] - nv :]  # the null-space objective's target, work's tail (zero without one)
    for i in range(nv):
        z[i] = 0.0
    if N > 0:
        _null_objective(q, ints, floats, coef[K : K + N], z)
    has_z = N > 0
    if ints[H_EXTERNAL_Z] != 0:  # the null-space terms Python writers gave (a mixed plan), before z
        zx = work[work.shape[0] - 2 * nv : work.shape[0] - nv]
        for i in range(nv):
            z[i] += zx[i]
        has_z = True
    o = K + N
    rank, sigma_min, damping = closed_form_into(Jm, v, z, has_z, coef[o], coef[o + 1], coef[o + 2], out, True)
    return 1.0, rank, sigma_min, damping, _main_error2(ints, e[0:m]), _sumsq(out[2])


def wqp_work_size(K: int, m: int, nv: int, mx: int = 0) -> int:
    """Length of :func:`fused_wqp_step`'s ``work`` for K frame tasks, m rows (mx of them written from Python) and nv
    velocity coordinates."""
    return 7 * nv + 2 * m + 6 * K * nv + mx * nv + mx + nv


@_jit
def wqp_external_views(work: np.ndarray, K: int, m: int, nv: int, mx: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts of a ``wqp`` step's ``work`` that Python writers fill (a mixed plan): their rows' Jacobian (mx, nv),
    weights × ρ^k (mx,) and null-space objective terms (nv,); views, after :func:`wqp_work_views`' parts."""
    a = 7 * nv + 2 * m + 6 * K * nv
    b = a + mx * nv
    return work[a:b].reshape((mx, nv)), work[b : b + mx], work[b + mx : b + mx + nv]


@_jit
def wqp_work_views(work: np.ndarray, K: int, m: int, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts of a ``wqp`` step's ``work``: ``out`` (7, nv: lb, ub, pos_lo, pos_hi, the unconstrained optimum,
    q̇, the copy kept), (e, v) (2, m) and the frames' Jacobians (K, 6, nv); views, in this order."""
    a = 7 * nv
    b = a + 2 * m
    return work[0:a].reshape((7, nv)), work[a:b].reshape((2, m)), work[b : b + 6 * K * nv].reshape((K, 6, nv))


def pinv_work_size(K: int, m: int, nv: int) -> int:
    """Length of :func:`fused_pinv_step`'s ``work`` for K frame tasks, m main rows and nv velocity coordinates: the
    parts of :func:`pinv_work_views`, then the null-space terms Python writers give (nv,) and z (nv,)."""
    return 3 * nv + m * nv + 2 * m + 6 * K * nv + 2 * nv


@_jit
def pinv_work_views(work: np.ndarray, K: int, m: int, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The parts of a ``pinv`` step's ``work``: (J⁺V, (I − J⁺J) z, q̇) (3, nv), J (m, nv), (e, v) (2, m) and the
    frames' Jacobians (K, 6, nv); views, in this order."""
    a = 3 * nv
    b = a + m * nv
    c = b + 2 * m
    return (
        work[0:a].reshape((3, nv)),
        work[a:b].reshape((m, nv)),
        work[b:c].reshape((2, m)),
        work[c : c + 6 * K * nv].reshape((K, 6, nv)),
    )

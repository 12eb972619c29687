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
the step's coefficients in ``coef`` (gains, weights × level ratios; then the limit options, λ, dt and t for ``wqp``,
ε, λ_max and rcond for ``pinv``); ``wqp``'s P, g and joint-limit rows in the resolver's QP record ``qp``
(``layouts.QP_P`` + nv, nv).

Reference rows (18,): p_d (3) [length], R_d (9, row-major), twist (v, ω) (6) [length/s, rad/s]. Trajectory parameter
rows (``PARAMS`` = 23,): p0 (3), R0 (9, row-major), then per kind — ``LINE``: velocity (3); ``CIRCLE``: centre (3),
r·e1 (3), r·e2 (3), ω [rad/s], φ [rad].
"""

from __future__ import annotations

import numpy as np

from redundik.kinematics.layouts import POSE_P, POSE_R
from redundik.kinematics.lie_kernels import frame_error_rp, frame_jacobian_lwa
from redundik.resolvers.kernels import (
    _jit,
    closed_form_into,
    gram_update,
    scaled_max,
    wqp_free_step,
)
from redundik.resolvers.layouts import (
    CF_DQ,
    CF_ROWS,
    FRAME_ROWS,
    GIVEN_ERROR,
    H_EXTERNAL_ROWS,
    H_EXTERNAL_Z,
    H_FRAME_COLUMNS,
    H_FRAME_IDS,
    H_FRAME_KINDS,
    H_FRAME_PARAMS,
    H_FRAME_ROTATION,
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
    H_MAIN,
    H_N,
    H_NQ,
    H_NULL_CENTRES,
    H_NULL_WEIGHTS,
    H_NV,
    HEADER,
    IDENTITY,
    LIM_ROWS,
    OPT_DT,
    OPT_GAIN,
    OPT_POSITION,
    OPT_RATE,
    OPT_SHIFT,
    OPT_Z_SCALE,
    OUT_DQ,
    OUT_ROWS,
    PINV_TAIL,
    QP_CAPS,
    QP_G,
    QP_LIM,
    QP_P,
    REF,
    TAIL_DAMPING,
    TAIL_DT,
    TAIL_EPSILON,
    TAIL_GAIN,
    TAIL_MAX_DAMPING,
    TAIL_POSITION,
    TAIL_RATE,
    TAIL_RCOND,
    TAIL_T,
    WQP_OPTS,
    WQP_TAIL,
)
from redundik.tasks.layouts import PARAMS, REF_P, REF_R, REF_TWIST
from redundik.tasks.target_kernels import reference_into
from redundik.tasks.trajectory import GIVEN

__all__ = ["HEADER", "REF", "frame_rows", "fused_pinv_rows", "fused_pinv_step", "fused_wqp_step", "reference_into"]


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
    frames' placements, ``kinematics.layouts``: the rotation column-major from ``POSE_R``, the origin [m] from
    ``POSE_P``); a reference row as ``tasks.layouts`` lays it out (``REF_P``, ``REF_R``, ``REF_TWIST``).

    Returns:
        False as soon as a rotation error is too large for the compiled log3 (the caller then evaluates the tasks
        one by one, with Pinocchio's log3).
    """
    K, nv = ints[H_K], ints[H_NV]
    kinds = _part(ints, H_FRAME_KINDS, K)
    starts = _part(ints, H_FRAME_STARTS, K + 1)
    rows = _part(ints, H_FRAME_ROWS, starts[K])
    rot = _part(ints, H_FRAME_ROTATION, K)
    fids = _part(ints, H_FRAME_IDS, K)
    columns = _part(ints, H_FRAME_COLUMNS, K * nv)
    po = ints[H_FRAME_PARAMS]
    scratch = np.empty(REF)
    for k in range(K):
        pose = poses[fids[k]]
        p = pose[POSE_P : POSE_P + 3]
        frame_jacobian_lwa(Jw, p, columns[k * nv : (k + 1) * nv], Jf[k])
        kind = kinds[k]
        if kind == GIVEN:
            r = refs[k]
        else:
            reference_into(kind, floats[po + k * PARAMS : po + (k + 1) * PARAMS], t, scratch)
            r = scratch
        a, b = starts[k], starts[k + 1]
        R = pose[POSE_R : POSE_R + 9].reshape((3, 3)).T  # column-major storage: the C reshape is Rᵀ
        p_d, R_d, twist = r[REF_P : REF_P + 3], r[REF_R : REF_R + 9].reshape((3, 3)), r[REF_TWIST : REF_TWIST + 6]
        if not frame_error_rp(p_d, R_d, R, p, twist, gains[k], rows[a:b], rot[k] != 0, e[a:b], v[a:b]):
            return False
    return True


@_jit
def _null_objective(q: np.ndarray, ints: np.ndarray, floats: np.ndarray, coef: np.ndarray, z: np.ndarray) -> None:
    """z = Σ_k c_k w_k ⊙ (q − q_k) over 1-dof coordinates — the stack's null-space objective of eq. (5.8): a gradient
    subtask of a (weighted) joint centering (c_k its gain k), an identity regulariser such as a posture (c_k = −K,
    w_k = 1)."""
    N, nv, nq = ints[H_N], ints[H_NV], ints[H_NQ]
    iq = _part(ints, H_IQ, nv)
    wo, co = ints[H_NULL_WEIGHTS], ints[H_NULL_CENTRES]
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
def cap_ratio(dq: np.ndarray, inv: np.ndarray) -> float:
    """max_i |q̇_i| / c_i with ``inv`` the joints' 1 / cap [s/rad] (``SpeedLimiter.folded_caps``): the joint-speed
    cap's test, returned by a fused step with its q̇; −1 when ``inv`` is empty (the cap tested after the step)."""
    if inv.shape[0] != dq.shape[0]:
        return -1.0
    return scaled_max(dq, inv)


@_jit
def _main_error2(ints: np.ndarray, e: np.ndarray) -> float:
    """Σ e² over the main tasks' rows (the step's task error, squared)."""
    m = ints[H_M]
    main = _part(ints, H_MAIN, m)
    total = 0.0
    for r in range(m):
        if main[r]:
            total += e[r] * e[r]
    return total


@_jit
def _frame_grams(Jf: np.ndarray, v: np.ndarray, ints: np.ndarray, w: np.ndarray, P: np.ndarray, g: np.ndarray) -> None:
    """P = Σ w_k J_kᵀJ_k and g = −Σ w_k J_kᵀv_k over the frame tasks' rows (``gram_update``; P and g zeroed first,
    also without a frame task); ``w`` (K,) the weights × ρ^k."""
    K = ints[H_K]
    starts = _part(ints, H_FRAME_STARTS, K + 1)
    rows = _part(ints, H_FRAME_ROWS, starts[K])
    reset = True
    for k in range(K):
        a, b = starts[k], starts[k + 1]
        natural = b - a == FRAME_ROWS  # (all six rows in the order of Jf's: Jf itself; any other order is taken)
        for r in range(a, b):
            natural = natural and rows[r] == r - a
        if natural:
            gram_update(P, g, Jf[k], v[a:b], w[k], reset)
        else:
            gram_update(P, g, np.ascontiguousarray(Jf[k][rows[a:b]]), v[a:b], w[k], reset)
        reset = False
    if reset:
        P[:, :] = 0.0
        g[:] = 0.0


@_jit
def _joint_grams(
    q: np.ndarray,
    ints: np.ndarray,
    floats: np.ndarray,
    coef: np.ndarray,
    ev: np.ndarray,
    P: np.ndarray,
    g: np.ndarray,
    shift: float,
) -> float:
    """The joint tasks' rows of a level, e = (q_ref − q)[sel] (or the caller's e on Lie-group coordinates) and
    v = K e, added to P (w on its diagonal) and g (−w v) as the per-task path does; ``coef``: gain (J), then
    weight × ρ^k (J). Returns ``shift`` plus the weights of the identity tasks (a diagonal shift instead)."""
    K, J, nv, nq = ints[H_K], ints[H_J], ints[H_NV], ints[H_NQ]
    e, v = ev[0], ev[1]
    iq = _part(ints, H_IQ, nv)
    jstarts = _part(ints, H_JOINT_STARTS, J + 1)
    jsel = _part(ints, H_JOINT_ROWS, jstarts[J])
    jident = _part(ints, H_JOINT_FLAGS, J)
    to = ints[H_JOINT_TARGETS]
    mf = _part(ints, H_FRAME_STARTS, K + 1)[K]
    for k in range(J):
        gain, w = coef[k], coef[J + k]
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
    return shift


@_jit
def _external_grams(Jx: np.ndarray, wx: np.ndarray, v: np.ndarray, P: np.ndarray, g: np.ndarray) -> None:
    """P += w JᵀJ, g −= w Jᵀv, row by row, over the rows Python writers gave (a mixed plan): ``Jx`` (mx, nv), their
    weights × ρ^k ``wx`` (mx,) and velocities ``v`` (mx,)."""
    nv = P.shape[0]
    for r in range(Jx.shape[0]):
        w = wx[r]
        if w != 0.0:
            Jr = Jx[r]
            vr = w * v[r]
            for i in range(nv):
                a = w * Jr[i]
                if a != 0.0:
                    g[i] -= vr * Jr[i]
                    for j in range(nv):
                        P[i, j] += a * Jr[j]


@_jit
def fused_wqp_step(
    Jw: np.ndarray,
    poses: np.ndarray,
    refs: np.ndarray,
    q: np.ndarray,
    ints: np.ndarray,
    floats: np.ndarray,
    coef: np.ndarray,
    qp: np.ndarray,
    dq_prev: np.ndarray,
    work: np.ndarray,
) -> tuple[float, float, float, float]:
    """One ``wqp`` step of a fused stack: frame rows (``frame_rows``) and joint rows (e = (q_ref − q)[sel],
    v = K e) into e, v (``ev`` (2, m)); P = Σ w JᵀJ and g = −Σ w Jᵀv (``gram_update``; a joint task adds w on P's
    diagonal, or to the diagonal shift when it is an identity task, as the per-task path does); the null-space
    objective z (``_null_objective``); then ``wqp_free_step`` (the limit box; the optimum; its test).

    ``qp``: the resolver's QP record (``layouts.QP_P`` + nv, nv): the joint-limit record (``layouts.LIM_ROWS`` rows
    from ``QP_LIM``, read), the joints' 1 / speed cap (row ``QP_CAPS``, read: a negative first entry, no cap test
    here), g (row ``QP_G``) and P (nv rows from ``QP_P``), both written.

    ``work`` (flat, one allocation a step; :func:`wqp_work_views` names its parts): ``out``
    (``layouts.OUT_ROWS``, nv) — the box and the answers of ``wqp_free_step`` —, e and v (2, m), and the frames'
    Jacobians (K, 6, nv).

    ``coef``: gain (K), weight·ρ^k (K) per frame task; gain (J), weight·ρ^k (J) per joint task; ρ of the null-space
    objective; its N coefficients; then the resolver's tail (``layouts.WQP_TAIL``: position, rate, the position
    gain, λ, dt [s], the step's time t [s]).

    Returns:
        (status, Σ e² of the main rows, ‖q̇‖² when inside, max_i |q̇_i| / c_i when inside and the caps are given,
        else −1): status −1 — a rotation error too large for the compiled log3 (evaluate the tasks one by one); 1 —
        the optimum is inside the box (q̇ in ``out[OUT_DQ]``); 0 — a limit binds (P, g and the box in ``out``'s
        first ``OUT_BOX`` rows are ready for the QP).
    """
    K, J, N, m, nv = ints[H_K], ints[H_J], ints[H_N], ints[H_M], ints[H_NV]
    out, ev, Jf = wqp_work_views(work, K, m, nv)
    e, v = ev[0], ev[1]
    P, g = qp[QP_P : QP_P + nv], qp[QP_G]
    c0 = 2 * K
    tail = coef[c0 + 2 * J + 1 + N : c0 + 2 * J + 1 + N + WQP_TAIL]
    if not frame_rows(Jw, poses, tail[TAIL_T], refs, ints, floats, coef[0:K], Jf, e, v):
        return -1.0, 0.0, 0.0, -1.0
    _frame_grams(Jf, v, ints, coef[K : 2 * K], P, g)
    shift = _joint_grams(q, ints, floats, coef[c0 : c0 + 2 * J], ev, P, g, tail[TAIL_DAMPING])  # λ + identity weights
    mx = ints[H_EXTERNAL_ROWS]
    Jx, wx, zx = wqp_external_views(work, K, m, nv, mx)
    _external_grams(Jx, wx, v[m - mx : m], P, g)
    z_scale = coef[c0 + 2 * J]
    z = np.zeros(nv)
    if z_scale != 0.0:
        if N > 0:
            _null_objective(q, ints, floats, coef[c0 + 2 * J + 1 : c0 + 2 * J + 1 + N], z)
        if ints[H_EXTERNAL_Z] != 0:
            for i in range(nv):
                z[i] += zx[i]
        shift += z_scale
    opts = np.empty(WQP_OPTS)
    opts[OPT_POSITION], opts[OPT_RATE], opts[OPT_GAIN] = tail[TAIL_POSITION], tail[TAIL_RATE], tail[TAIL_GAIN]
    opts[OPT_DT], opts[OPT_SHIFT], opts[OPT_Z_SCALE] = tail[TAIL_DT], shift, z_scale
    lim = qp[QP_LIM : QP_LIM + LIM_ROWS]
    inside = wqp_free_step(P, g, z, q, _part(ints, H_IQ, nv), lim, opts, dq_prev, out)
    if not inside:
        return 0.0, _main_error2(ints, e[0:m]), 0.0, -1.0
    inv = qp[QP_CAPS]
    over = -1.0 if inv[0] < 0.0 else scaled_max(out[OUT_DQ], inv)
    return 1.0, _main_error2(ints, e[0:m]), _sumsq(out[OUT_DQ]), over


@_jit
def fused_pinv_rows(
    Jw: np.ndarray,
    poses: np.ndarray,
    t: float,
    refs: np.ndarray,
    q: np.ndarray,
    ints: np.ndarray,
    floats: np.ndarray,
    coef: np.ndarray,
    work: np.ndarray,
) -> tuple[float, bool, float]:
    """The rows of a ``pinv`` step of a fused stack (the first half of :func:`fused_pinv_step`, and the rows of a
    ``feedback`` step): the frame tasks' rows stacked into J (m, n), e and v, and z of the null-space objective
    (``_null_objective``, plus the terms Python writers gave) — into ``work``'s parts (:func:`pinv_work_views`).

    Returns:
        (status — −1 a rotation error too large for the compiled log3, 1 done —, whether z has a term, Σ e² of the
        main rows).
    """
    K, N, m, nv = ints[H_K], ints[H_N], ints[H_M], ints[H_NV]
    _, Jm, ev, Jf = pinv_work_views(work, K, m, nv)
    e, v = ev[0], ev[1]
    if not frame_rows(Jw, poses, t, refs, ints, floats, coef[0:K], Jf, e, v):
        return -1.0, False, 0.0
    starts = _part(ints, H_FRAME_STARTS, K + 1)
    rows = _part(ints, H_FRAME_ROWS, starts[K])
    for k in range(K):
        Jk = Jf[k]
        for r in range(starts[k], starts[k + 1]):
            Jm[r, :] = Jk[rows[r], :]
    zx, z = pinv_null_views(work, nv)
    for i in range(nv):
        z[i] = 0.0
    if N > 0:
        _null_objective(q, ints, floats, coef[K : K + N], z)
    has_z = N > 0
    if ints[H_EXTERNAL_Z] != 0:  # the null-space terms Python writers gave (a mixed plan), before z
        for i in range(nv):
            z[i] += zx[i]
        has_z = True
    return 1.0, has_z, _main_error2(ints, e[0:m])


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
    inv: np.ndarray,
) -> tuple[float, int, float, float, float, float, float]:
    """One ``pinv`` step of a fused stack: its rows (:func:`fused_pinv_rows`) and the closed form
    q̇ = J⁺V + (I − J⁺J) z (eq. 5.8, ``closed_form_into``, σ_min lazily).

    ``work`` (flat, one allocation a step; :func:`pinv_work_views` names its parts): J⁺V, (I − J⁺J) z and q̇
    (``layouts.CF_ROWS``, n), then J (m, n), e and v (2, m), the frames' Jacobians (K, 6, n), the null-space terms
    Python writers give (n,) and z (n,). ``coef``: gain (K) per frame task, the N null coefficients, then the
    resolver's tail (``layouts.PINV_TAIL``: ε, λ_max and rcond).

    ``inv``: the joints' 1 / speed cap, or empty (:func:`cap_ratio`).

    Returns:
        (status — −1 a rotation error too large for the compiled log3, 1 done —, rank, σ_min (NaN: to compute on
        request), damping, Σ e², ‖q̇‖², ``cap_ratio``).
    """
    status, has_z, err2 = fused_pinv_rows(Jw, poses, t, refs, q, ints, floats, coef, work)
    if status < 0.0:
        return -1.0, 0, 0.0, 0.0, 0.0, 0.0, -1.0
    K, N, m, nv = ints[H_K], ints[H_N], ints[H_M], ints[H_NV]
    out, Jm, ev, _ = pinv_work_views(work, K, m, nv)
    _, z = pinv_null_views(work, nv)
    tail = coef[K + N : K + N + PINV_TAIL]
    eps, lmax, rcond = tail[TAIL_EPSILON], tail[TAIL_MAX_DAMPING], tail[TAIL_RCOND]
    rank, sigma_min, damping = closed_form_into(Jm, ev[1], z, has_z, eps, lmax, rcond, out, True)
    return 1.0, rank, sigma_min, damping, err2, _sumsq(out[CF_DQ]), cap_ratio(out[CF_DQ], inv)


def wqp_work_size(K: int, m: int, nv: int, mx: int = 0) -> int:
    """Length of :func:`fused_wqp_step`'s ``work`` for K frame tasks, m rows (mx of them written from Python) and nv
    velocity coordinates."""
    return OUT_ROWS * nv + 2 * m + FRAME_ROWS * K * nv + mx * nv + mx + nv


@_jit
def wqp_external_views(work: np.ndarray, K: int, m: int, nv: int, mx: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts of a ``wqp`` step's ``work`` that Python writers fill (a mixed plan): their rows' Jacobian (mx, nv),
    weights × ρ^k (mx,) and null-space objective terms (nv,); views, after :func:`wqp_work_views`' parts."""
    a = OUT_ROWS * nv + 2 * m + FRAME_ROWS * K * nv
    b = a + mx * nv
    return work[a:b].reshape((mx, nv)), work[b : b + mx], work[b + mx : b + mx + nv]


@_jit
def wqp_work_views(work: np.ndarray, K: int, m: int, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts of a ``wqp`` step's ``work``: ``out`` (``layouts.OUT_ROWS``, nv: the box, the unconstrained optimum,
    q̇, the copy kept), (e, v) (2, m) and the frames' Jacobians (K, 6, nv); views, in this order."""
    a = OUT_ROWS * nv
    b = a + 2 * m
    return (
        work[0:a].reshape((OUT_ROWS, nv)),
        work[a:b].reshape((2, m)),
        work[b : b + FRAME_ROWS * K * nv].reshape((K, FRAME_ROWS, nv)),
    )


def pinv_work_size(K: int, m: int, nv: int) -> int:
    """Length of :func:`fused_pinv_step`'s ``work`` for K frame tasks, m main rows and nv velocity coordinates: the
    parts of :func:`pinv_work_views`, then the null-space terms Python writers give (nv,) and z (nv,)."""
    return CF_ROWS * nv + m * nv + 2 * m + FRAME_ROWS * K * nv + 2 * nv


@_jit
def pinv_work_views(work: np.ndarray, K: int, m: int, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The parts of a ``pinv`` step's ``work``: (J⁺V, (I − J⁺J) z, q̇) (``layouts.CF_ROWS``, nv), J (m, nv), (e, v)
    (2, m) and the frames' Jacobians (K, 6, nv); views, in this order."""
    a = CF_ROWS * nv
    b = a + m * nv
    c = b + 2 * m
    return (
        work[0:a].reshape((CF_ROWS, nv)),
        work[a:b].reshape((m, nv)),
        work[b:c].reshape((2, m)),
        work[c : c + FRAME_ROWS * K * nv].reshape((K, FRAME_ROWS, nv)),
    )


@_jit
def pinv_null_views(work: np.ndarray, nv: int) -> tuple[np.ndarray, np.ndarray]:
    """The tail of a ``pinv`` step's ``work``: the null-space terms Python writers give (nv,) and z (nv,)."""
    end = work.shape[0]
    return work[end - 2 * nv : end - nv], work[end - nv : end]


@_jit
def put_rows(work: np.ndarray, j_at: int, e_at: int, v_at: int, J: np.ndarray, e: np.ndarray, v: np.ndarray) -> None:
    """A Python-written member's block of a step into its flat ``work`` array: J (r, nv) row by row from
    ``work[j_at]``, its error e (r,) from ``work[e_at]`` and its v (r,) from ``work[v_at]`` (one call instead of
    three NumPy copies and the views they need)."""
    r, nv = J.shape
    for i in range(r):
        base = j_at + i * nv
        for c in range(nv):
            work[base + c] = J[i, c]
        work[e_at + i] = e[i]
        work[v_at + i] = v[i]


@_jit
def put_level_rows(
    A: np.ndarray, b: np.ndarray, w: np.ndarray, ev: np.ndarray, d: int, a: int, weight: float,
    J: np.ndarray, e: np.ndarray, v: np.ndarray,
) -> None:  # fmt: skip
    """:func:`put_rows` for ``hqp``'s least-squares buffers: J's rows into A from row d, v into b and the weight into
    w from d, and e and v into the step's (e, v) rows ``ev`` (2, m) from the plan's row a."""
    r, nv = J.shape
    for i in range(r):
        for c in range(nv):
            A[d + i, c] = J[i, c]
        b[d + i] = v[i]
        w[d + i] = weight
        ev[0, a + i] = e[i]
        ev[1, a + i] = v[i]

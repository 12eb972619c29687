"""Compiled kernels of a QP's box (numba): the joint-limit box of :class:`redundik.resolvers.qp.limits.JointLimits`,
the box tests and projections, ``wqp``'s unconstrained optimum tested against its box (one problem, N problems, and
the rest of a ``wqp`` step once its task rows are in P and q), and daqp's split of a bounds-only QP into its
separable variables and the rest."""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.resolvers.cholesky_kernels import coupled_coordinates, spd_solve_into
from redundik.resolvers.layouts import (
    LIM_AMAX,
    LIM_HI,
    LIM_LO,
    LIM_VMAX,
    OPT_DT,
    OPT_GAIN,
    OPT_POSITION,
    OPT_RATE,
    OPT_SHIFT,
    OPT_Z_SCALE,
    OUT_BOX,
    OUT_DQ,
    OUT_FREE,
    OUT_KEPT,
    OUT_LB,
    OUT_POS_HI,
    OUT_POS_LO,
    OUT_UB,
)

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)


@_jit
def squares_below(q: np.ndarray, bound2: float) -> bool:
    """qᵀq < ``bound2``: False for a NaN or infinite entry, and for entries whose squares overflow (a huge q).
    ``Resolver.step``'s check of q on every tick, as one compiled loop over q's entries."""
    acc = 0.0
    for i in range(q.shape[0]):
        acc += q[i] * q[i]
    return acc < bound2


@_jit
def scaled_max(x: np.ndarray, inv: np.ndarray) -> float:
    """max_i |x_i · inv_i| (0 for an empty x): with ``inv`` the joints' 1 / cap, the largest ratio of a joint speed to
    its cap (the joint-speed cap's test, ``SpeedLimiter.apply``)."""
    out = 0.0
    for i in range(x.shape[0]):
        r = abs(x[i] * inv[i])
        if r > out:
            out = r
    return out


@_jit
def in_box(x: np.ndarray, lb: np.ndarray, ub: np.ndarray, tol: float) -> bool:
    """True when lb − tol ≤ x ≤ ub + tol elementwise."""
    for i in range(x.shape[0]):
        if x[i] < lb[i] - tol or x[i] > ub[i] + tol:
            return False
    return True


@_jit
def clip_twice(x: np.ndarray, lb: np.ndarray, ub: np.ndarray, out: np.ndarray) -> None:
    """x projected onto lb ≤ x ≤ ub, written into both rows of ``out`` (2, n): a step's q̇ and the copy the resolver
    keeps (its warm start and rate-limit reference), in one call."""
    for i in range(x.shape[0]):
        v = min(max(x[i], lb[i]), ub[i])
        out[0, i] = v
        out[1, i] = v


@_jit
def spd_solve_box_into(
    P: np.ndarray, q: np.ndarray, lb: np.ndarray, ub: np.ndarray, tol: float, x: np.ndarray
) -> tuple[bool, bool]:
    """x = −P⁻¹q into ``x``; returns (Cholesky succeeded, lb − tol ≤ x ≤ ub + tol): ``wqp``'s unconstrained
    optimum and its box test."""
    ok = spd_solve_into(P, q, x)
    return ok, ok and in_box(x, lb, ub, tol)


@_jit
def spd_solve_box(
    P: np.ndarray, q: np.ndarray, lb: np.ndarray, ub: np.ndarray, tol: float
) -> tuple[np.ndarray, bool, bool]:
    """(x = −P⁻¹q, Cholesky succeeded, lb − tol ≤ x ≤ ub + tol) (:func:`spd_solve_box_into`)."""
    x = np.empty(q.shape[0])
    ok, inside = spd_solve_box_into(P, q, lb, ub, tol, x)
    return x, ok, inside


@_jit
def spd_solve_batch(
    P: np.ndarray, q: np.ndarray, lb: np.ndarray, ub: np.ndarray, tol: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`spd_solve` for N problems (P (N, n, n), q (N, n)) and whether each optimum lies in its box.

    Returns:
        (x (N, n), ok (N,) Cholesky succeeded, inside (N,) lb − tol ≤ x ≤ ub + tol).
    """
    N, n = q.shape
    x = np.empty((N, n))
    ok = np.empty(N, dtype=np.bool_)
    inside = np.empty(N, dtype=np.bool_)
    for i in range(N):
        xi, oki, ini = spd_solve_box(np.ascontiguousarray(P[i]), q[i].copy(), lb[i].copy(), ub[i].copy(), tol)
        x[i] = xi
        ok[i] = oki
        inside[i] = ini
    return x, ok, inside


@_jit
def split_separable(
    P: np.ndarray, q: np.ndarray, lb: np.ndarray, ub: np.ndarray, min_saving: int, work: np.ndarray, idx: np.ndarray
) -> tuple[int, int]:
    """The bounds-only QP min ½xᵀPx + qᵀx s.t. lb ≤ x ≤ ub split into its separable variables and the rest (daqp's
    split, ``redundik.resolvers.qp.backends.DaqpBackend.solve``).

    The variables are separated by :func:`coupled_coordinates`: a separable variable's part of the QP is
    min ½P_ii x_i² + q_i x_i on [lb_i, ub_i], solved exactly by x_i = clip(−q_i/P_ii, lb_i, ub_i), whatever the
    other variables do (the KKT conditions decouple).

    Outputs, for n_c coupled variables: ``work`` (4 + n, n): row 0 the separable x_i (the coupled entries are left
    for the caller), rows 1–3 from column 0 on q_c, lb_c, ub_c, and rows 4 … as one C-ordered block from its first
    element on P_cc (n_c, n_c); ``idx`` (n,): the coupled variables' indices in its first n_c entries.

    Returns:
        (n_c, the number of separable variables clipped onto a bound); n_c = −1 when the split is not made: a
        separable variable with non-finite or NaN data, an empty interval (lb_i > ub_i: the backend reports the
        infeasibility itself) or an unconstrained optimum −q_i/P_ii that overflows; no coupled variable (a
        diagonal P, which daqp itself detects); or a saving n³ − n_c³ below ``min_saving``.
    """
    n = q.shape[0]
    nc = coupled_coordinates(P, idx, False)
    if nc == 0 or nc == n or n * n * n - nc * nc * nc < min_saving:
        return -1, 0
    x = work[0]
    clipped = 0
    k = 0
    for i in range(n):
        if k < nc and idx[k] == i:
            k += 1
            continue
        d = P[i, i]
        if not (math.isfinite(d) and math.isfinite(q[i])) or math.isnan(lb[i]) or math.isnan(ub[i]) or lb[i] > ub[i]:
            return -1, 0
        v = -q[i] / d
        if not math.isfinite(v):  # (a tiny P_ii: the whole problem's solve decides)
            return -1, 0
        if v < lb[i]:
            v = lb[i]
            clipped += 1
        elif v > ub[i]:
            v = ub[i]
            clipped += 1
        x[i] = v
    Pc = work[4:].reshape(-1)
    for a in range(nc):
        i = idx[a]
        work[1, a] = q[i]
        work[2, a] = lb[i]
        work[3, a] = ub[i]
        for c in range(nc):
            Pc[a * nc + c] = P[i, idx[c]]
    return nc, clipped


@_jit
def joint_box(
    q: np.ndarray, iq: np.ndarray, lim: np.ndarray, opts: np.ndarray, dq_prev: np.ndarray, out: np.ndarray
) -> None:
    """The joint-limit box of :meth:`redundik.resolvers.qp.limits.JointLimits.box` for N configurations q (N, nq).

    ``iq`` (nv,) maps each q̇ coordinate to its q index; ``lim`` (4, nv) holds the rows ``LIM_LO``,
    ``LIM_HI`` (position limits, ±inf where none), ``LIM_VMAX`` and ``LIM_AMAX`` (velocity and rate
    limits, inf where none); ``opts`` the entries ``OPT_POSITION`` and ``OPT_RATE`` (1.0 or 0.0: the
    position and rate limits apply), ``OPT_GAIN`` (the position gain g) and ``OPT_DT`` (dt [s]);
    ``dq_prev`` (N, nv) is the previous q̇ (zero rows: no rate window). The rules are those of the limits module's
    docstring (position through dt, velocity, braking with a rate limit, the way back from outside, the rate
    window moved onto the nearest feasible velocity).

    Writes the rows ``OUT_LB``, ``OUT_UB``, ``OUT_POS_LO``, ``OUT_POS_HI`` of ``out`` (4, N, nv).
    """
    N = q.shape[0]
    nv = iq.shape[0]
    lo, hi, vmax, amax = lim[LIM_LO], lim[LIM_HI], lim[LIM_VMAX], lim[LIM_AMAX]
    lb, ub, pl, pu = out[OUT_LB], out[OUT_UB], out[OUT_POS_LO], out[OUT_POS_HI]
    position = opts[OPT_POSITION] != 0.0
    has_rate = opts[OPT_RATE] != 0.0
    dt = opts[OPT_DT]
    g = opts[OPT_GAIN] / dt
    window = has_rate and dq_prev.shape[0] == N
    for k in range(N):
        for i in range(nv):
            vm = vmax[i]
            if position:
                qv = q[k, iq[i]]
                a = amax[i]
                lo_i, hi_i = lo[i], hi[i]
                l_pos = (lo_i - qv) * g  # ≤ 0 inside the range, −inf without a limit
                u_pos = (hi_i - qv) * g
                if has_rate and math.isfinite(a):
                    adt = a * dt
                    if hi_i >= qv:  # braking: q̇ ≤ B(δ) = −a·dt + √((a·dt)² + 2aδ)
                        u_pos = min(u_pos, -adt + math.sqrt(adt * adt + 2.0 * a * max(hi_i - qv, 0.0)))
                    if lo_i <= qv:
                        l_pos = max(l_pos, adt - math.sqrt(adt * adt + 2.0 * a * max(qv - lo_i, 0.0)))
                l_pos = min(l_pos, vm)  # outside a limit: back at most as fast as the velocity limit allows
                u_pos = max(u_pos, -vm)
                lo_k = max(l_pos, -vm)
                up_k = min(u_pos, vm)
                if has_rate and lo_k > up_k:  # braking of the far limit yields to the way back (hard)
                    if qv > hi_i:
                        lo_k = up_k
                        l_pos = up_k
                    elif qv < lo_i:
                        up_k = lo_k
                        u_pos = lo_k
            else:
                l_pos, u_pos = -np.inf, np.inf
                lo_k, up_k = -vm, vm
            if window:  # the rate window, moved onto the box where it does not meet it
                step = amax[i] * dt
                rl = min(max(dq_prev[k, i] - step, lo_k), up_k)
                ru = min(max(dq_prev[k, i] + step, lo_k), up_k)
                lo_k, up_k = rl, ru
            lb[k, i], ub[k, i], pl[k, i], pu[k, i] = lo_k, up_k, l_pos, u_pos


@_jit
def limit_box(
    q: np.ndarray,
    iq: np.ndarray,
    lim: np.ndarray,
    position: bool,
    has_rate: bool,
    gain: float,
    dt: float,
    dq_prev: np.ndarray,
    out: np.ndarray,
) -> None:
    """:func:`joint_box` with its options as separate arguments (position limits apply, rate limits apply, the
    position gain g, dt [s]): the form ``JointLimits.box`` calls with its joint-limit record ``lim``
    (``LIM_ROWS`` or ``LIM_JERK_ROWS``, nv; rows ``LIM_LO`` … ``LIM_AMAX`` read) and ``hqp``'s compiled step with
    a tuple of those rows; the options are a tuple here (no copy; :func:`joint_box` reads them as it reads an
    array)."""
    opts = (1.0 if position else 0.0, 1.0 if has_rate else 0.0, gain, dt)  # (OPT_POSITION, OPT_RATE, OPT_GAIN, OPT_DT)
    joint_box(q, iq, lim, opts, dq_prev, out)


@_jit
def wqp_free_step(
    P: np.ndarray,
    q: np.ndarray,
    z: np.ndarray,
    qconf: np.ndarray,
    iq: np.ndarray,
    lim: np.ndarray,
    opts: np.ndarray,
    dq_prev: np.ndarray,
    out: np.ndarray,
) -> bool:
    """The rest of a ``wqp`` step once its task rows are in P and q, in one call: P += shift·I, q −= z_scale·z (the
    null-space objective; ``z`` may be empty), the joint-limit box of :func:`joint_box` at ``qconf`` (nq,) into
    ``out``'s rows ``OUT_LB`` … ``OUT_POS_HI``, the unconstrained optimum x = −P⁻¹q by Cholesky into
    ``OUT_FREE``, and — when x lies in the box (to 1e-12) — x clipped to it into ``OUT_DQ`` and
    ``OUT_KEPT`` (q̇ and the copy the resolver keeps). ``out`` is (``OUT_ROWS``, n); ``opts`` holds
    :func:`joint_box`'s options, then shift (``OPT_SHIFT``) and z_scale (``OPT_Z_SCALE``).

    Returns:
        True when x is finite and inside the box: it is then the QP's optimum (no constraint active).
    """
    n = q.shape[0]
    shift, z_scale = opts[OPT_SHIFT], opts[OPT_Z_SCALE]
    for i in range(n):
        P[i, i] += shift
    if z.shape[0] == n and z_scale != 0.0:
        for i in range(n):
            q[i] -= z_scale * z[i]
    nq = qconf.shape[0]
    joint_box(qconf.reshape((1, nq)), iq, lim, opts, dq_prev, out[0:OUT_BOX].reshape((OUT_BOX, 1, n)))
    x = out[OUT_FREE]
    lb, ub = out[OUT_LB], out[OUT_UB]
    if not spd_solve_into(P, q, x) or not in_box(x, lb, ub, 1e-12):
        return False
    for i in range(n):
        v = min(max(x[i], lb[i]), ub[i])
        out[OUT_DQ, i] = v
        out[OUT_KEPT, i] = v
    return True

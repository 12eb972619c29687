"""Compiled kernels of ``hqp`` (numba): its unconstrained cascade of levels, and its feasibility test, in one call.

The cascade (module docstring of :mod:`redundik.resolvers.qp.hqp`, its closed-form shortcut): with x = 0 and Z = I
before level 0, every least-squares level k solves

    u = (A_k Z)⁺_λ (b_k − A_k x),   x ← x + Z u,   Z ← Z·null(A_k Z)

with the damped pseudo-inverse of :mod:`redundik.resolvers.linalg` (per-direction damping of the singular values
below ε, truncation below rcond·σ_max: ``damped_svd_factors``, the one
implementation of that rule), and the null-space objective ½‖q̇ − z‖² (identity rows) gives x ← x + Z Zᵀ(z − x)
and leaves nothing below; so does a least-squares level whose rows are exactly √w I with √w ≥ ε (a posture given a
level: :func:`identity_rows`), x ← x + Z Zᵀ(b − x). Rows are weighted by √w (‖√w ∘ (A q̇ − b)‖², as
:meth:`redundik.resolvers.qp.terms.Level.ls_rows`). The cascade is then kept when x satisfies the joint-limit box
lb − tol ≤ x ≤ ub + tol and every level's inequality rows C x ≤ d + tol (a feasible unconstrained lexicographic
optimum is the constrained one).

Why one call: per level, the NumPy route would be a handful of small-array calls (weighting, A Z, b − A x, the SVD
call, two products, the basis update) and Python glue, whose overhead outweighs the arithmetic at these sizes; fused
here, a cascade costs the SVD arithmetic plus one call's overhead. Arrays come in as preallocated buffers the caller
owns and reuses while the stack's membership is unchanged; only the per-level factors are allocated inside.
The kernels of ``hqp`` live in modules by concern, all reached through this one (``HK``, the names below):
:mod:`~redundik.resolvers.hqp_layout` (the named layouts of the packed arrays and the records the kernels take),
:mod:`~redundik.resolvers.hqp_algebra` (QR, certificate, products with the basis), this module (the unconstrained
cascade and ``hqp``'s closed-form step), :mod:`~redundik.resolvers.hqp_level_qp` (a level's QP),
:mod:`~redundik.resolvers.hqp_native` (daqp's C call), :mod:`~redundik.resolvers.hqp_cascade` (the constrained
cascade) and :mod:`~redundik.resolvers.hqp_fused` (the fused step).
"""

from __future__ import annotations

import math

import numpy as np

from redundik.resolvers.hqp_algebra import (
    _add_basis_step,
    _basis_product,
    _certified_null,
    _certified_rows,
    _level_scale,
    _projection,
    _ridge_triangular,
    _times_basis,
    _weighted_rows,
    householder_qr,
    identity_rows,
    qr_certificate,
    upper_inverse,
)
from redundik.resolvers.hqp_cascade import qp_cascade_run
from redundik.resolvers.hqp_cascade_call import (
    cascade_out_views,
    cascade_work_sizes,
    cascade_work_views,
    qp_cascade_call,
)
from redundik.resolvers.hqp_layout import (
    CASCADE_DONE,
    CASCADE_LEVEL_QP,
    CFG_CERTIFIED_QR,
    CFG_COMPLEMENT_FRACTION,
    CFG_COMPLEMENT_MIN_N,
    CFG_CONTRADICTION,
    CFG_EPSILON,
    CFG_FEASIBLE,
    CFG_IDENTITY,
    CFG_MAX_DAMPING,
    CFG_RCOND,
    CFG_REGULARIZATION,
    CFG_SHORTCUT,
    CFG_SLACK_TOL,
    COMPLEMENT_BASIS,
    DAMPING,
    FREE,
    GENERAL_BASIS,
    IDENTITY_BASIS,
    LEAST_SQUARES,
    META_INEQ,
    META_KIND,
    META_LS,
    NAT_FN,
    NAT_ITERS,
    NAT_LAST,
    NAT_PROBLEM,
    NAT_RESULT,
    NAT_SENSE,
    NAT_SETTINGS,
    NAT_SOLVED,
    NAT_SPLIT_MIN,
    NULL_OBJECTIVE,
    OUT_CASCADE,
    OUT_DQ,
    OUT_KEPT,
    OUT_LB,
    OUT_POS_HI,
    OUT_POS_LO,
    OUT_UB,
    PARAM_EPSILON,
    PARAM_EXACT,
    PARAM_MAX_DAMPING,
    PARAM_RCOND,
    PARAM_TOL,
    QS_DAMPING,
    QS_FREE,
    QS_PROJECTED,
    QS_RANK,
    QS_SIGMA,
    QS_SOLVED,
    QS_WORST,
    RANK,
    SELECTION_BASIS,
    SIGMA_MIN,
    SKIP,
    ST_CONTRADICTED,
    ST_LSQ,
    ST_MODE,
    ST_NCOLS,
    ST_NEQ,
    ST_NF,
    ST_NSEL,
    ST_NU,
    ST_R,
    CascadeRows,
    LimitArgs,
    Rows,
)
from redundik.resolvers.hqp_level_qp import (
    cascade_qp_dims,
    cascade_qp_size,
    level_qp_arrays,
    level_qp_into,
    level_qp_joint_into,
    level_rows_ok,
    qp_buffer_size,
    qp_views,
)
from redundik.resolvers.hqp_native import (
    box_qp_native_into,
    box_qp_native_split_into,
    box_qps_native,
    lifted_rows_qp_native_into,
    native_quadprog,
    rows_qp_native_into,
)
from redundik.resolvers.hqp_selection import selection_columns, selection_solve
from redundik.resolvers.kernels import _jit, clip_twice, damped_svd_factors, in_box, limit_box
from redundik.tasks.potential_kernels import clearance_into  # first_run_cost loads it too

__all__ = [
    "CASCADE_DONE",
    "CASCADE_LEVEL_QP",
    "CFG_CERTIFIED_QR",
    "CFG_COMPLEMENT_FRACTION",
    "CFG_COMPLEMENT_MIN_N",
    "CFG_CONTRADICTION",
    "CFG_EPSILON",
    "CFG_FEASIBLE",
    "CFG_IDENTITY",
    "CFG_MAX_DAMPING",
    "CFG_RCOND",
    "CFG_REGULARIZATION",
    "CFG_SHORTCUT",
    "CFG_SLACK_TOL",
    "COMPLEMENT_BASIS",
    "DAMPING",
    "FREE",
    "GENERAL_BASIS",
    "IDENTITY_BASIS",
    "LEAST_SQUARES",
    "META_INEQ",
    "META_KIND",
    "META_LS",
    "NAT_FN",
    "NAT_ITERS",
    "NAT_LAST",
    "NAT_PROBLEM",
    "NAT_RESULT",
    "NAT_SENSE",
    "NAT_SETTINGS",
    "NAT_SOLVED",
    "NAT_SPLIT_MIN",
    "NULL_OBJECTIVE",
    "OUT_CASCADE",
    "OUT_DQ",
    "OUT_KEPT",
    "OUT_LB",
    "OUT_POS_HI",
    "OUT_POS_LO",
    "OUT_UB",
    "PARAM_EPSILON",
    "PARAM_EXACT",
    "PARAM_MAX_DAMPING",
    "PARAM_RCOND",
    "PARAM_TOL",
    "QS_DAMPING",
    "QS_FREE",
    "QS_PROJECTED",
    "QS_RANK",
    "QS_SIGMA",
    "QS_SOLVED",
    "QS_WORST",
    "RANK",
    "SELECTION_BASIS",
    "SIGMA_MIN",
    "SKIP",
    "ST_CONTRADICTED",
    "ST_LSQ",
    "ST_MODE",
    "ST_NCOLS",
    "ST_NEQ",
    "ST_NF",
    "ST_NSEL",
    "ST_NU",
    "ST_R",
    "_certified_null",
    "_certified_rows",
    "_ridge_triangular",
    "box_qp_native_into",
    "box_qp_native_split_into",
    "box_qps_native",
    "cascade_out_views",
    "cascade_qp_dims",
    "cascade_qp_size",
    "cascade_work_sizes",
    "cascade_work_views",
    "clearance_into",
    "closed_cascade",
    "closed_step",
    "first_run_cost",
    "householder_qr",
    "identity_rows",
    "level_qp_arrays",
    "level_qp_into",
    "level_qp_joint_into",
    "level_rows_ok",
    "lifted_rows_qp_native_into",
    "native_quadprog",
    "qp_buffer_size",
    "qp_cascade_call",
    "qp_cascade_run",
    "qp_views",
    "qr_certificate",
    "rows_qp_native_into",
    "upper_inverse",
]


@_jit
def _qr_solve(M: np.ndarray, rhs: np.ndarray, eps_k: float, rcond: float, u: np.ndarray) -> tuple[bool, np.ndarray]:
    """M⁺ rhs into u and null(M) from the Householder QR of M (m, cols) when it certifies that no direction would
    be damped (:func:`qr_certificate`): (True, null basis); (False, empty) and u untouched otherwise. m ≤ cols:
    Mᵀ = Q₁R, M⁺ rhs = Q₁ R⁻ᵀ rhs, null(M) = Q₂; m > cols: M = Q₁R (full column rank), M⁺ rhs = R⁻¹ Q₁ᵀ rhs,
    null(M) = {0}."""
    m, cols = M.shape
    N = np.empty((cols, 0))
    if m <= cols:
        Q, R = householder_qr(np.ascontiguousarray(M.T))
        Ri, ok = upper_inverse(R)
        if not (ok and qr_certificate(R, Ri, eps_k, rcond)):
            return False, N
        y = np.zeros(m)
        for i in range(m):
            acc = 0.0
            for j in range(i + 1):
                acc += Ri[j, i] * rhs[j]
            y[i] = acc
        for c in range(cols):
            acc = 0.0
            for i in range(m):
                acc += Q[c, i] * y[i]
            u[c] = acc
        return True, np.ascontiguousarray(Q[:, m:])
    Q, R = householder_qr(M)
    Ri, ok = upper_inverse(R)
    if not (ok and qr_certificate(R, Ri, eps_k, rcond)):
        return False, N
    y = np.zeros(cols)
    for i in range(cols):
        acc = 0.0
        for j in range(m):
            acc += Q[j, i] * rhs[j]
        y[i] = acc
    for c in range(cols):
        acc = 0.0
        for i in range(c, cols):
            acc += Ri[c, i] * y[i]
        u[c] = acc
    return True, N


@_jit
def _svd_solve(
    M: np.ndarray, rhs: np.ndarray, eps_k: float, lam_k: float, rcond: float, u: np.ndarray
) -> tuple[np.ndarray, int, float, float]:
    """M⁺_λ rhs into u by the damped SVD (the rule of :mod:`redundik.resolvers.linalg`, direction by direction):
    (null(M), rank, σ_min, λ)."""
    m, cols = M.shape
    U, _, Vt, inv, rank, sigma_min, damping = damped_svd_factors(M, eps_k, lam_k, rcond)
    kk = inv.shape[0]
    t = np.zeros(kk)  # inv ∘ Uᵀ rhs
    for j in range(kk):
        acc = 0.0
        for i in range(m):
            acc += U[i, j] * rhs[i]
        t[j] = inv[j] * acc
    for j in range(kk):  # u = V_k t
        tj = t[j]
        if tj != 0.0:
            for c in range(cols):
                u[c] += Vt[j, c] * tj
    return np.ascontiguousarray(Vt[rank:].T), rank, sigma_min, damping


@_jit
def _move_to(x: np.ndarray, Z: np.ndarray, r: int, v: np.ndarray, s: int, projected: bool) -> None:
    """x ← x + Z Zᵀ(v[s:s + n] − x), or x ← v[s:s + n] before any level projected (Z = I)."""
    n = x.shape[0]
    if projected:
        dx = _projection(x, Z, r, v, s)
        for i in range(n):
            x[i] += dx[i]
    else:
        for i in range(n):
            x[i] = v[s + i]


@_jit
def _feasible(x: np.ndarray, limits: Rows, C: np.ndarray, d: np.ndarray, rows: int, tol: float) -> bool:
    """lb − tol ≤ x ≤ ub + tol and C x ≤ d + tol on the first ``rows`` rows (a NaN row is not kept)."""
    if not in_box(x, limits[0], limits[1], tol):
        return False
    n = x.shape[0]
    for i in range(rows):
        acc = 0.0
        for j in range(n):
            acc += C[i, j] * x[j]
        if not (acc <= d[i] + tol):
            return False
    return True


@_jit
def _record(stats: np.ndarray, k: int, sigma_min: float, damping: float, rank: int, r: int) -> None:
    stats[k, SIGMA_MIN] = sigma_min
    stats[k, DAMPING] = damping
    stats[k, RANK] = rank
    stats[k, FREE] = r


@_jit
def closed_cascade(rows: CascadeRows, limits: Rows, params: np.ndarray, x: np.ndarray, stats: np.ndarray) -> bool:
    """The unconstrained cascade of every level into ``x`` (n,), and whether it is feasible (module docstring).

    Args:
        rows: (A, b, w, C, d, z, meta): A the least-squares rows of all levels, stacked (≥ M, n) (a level with the
            null-space objective and rows of its own carries the identity rows after them, with weight 1); b their
            targets; w the row weights (row i enters as √w_i (A_i q̇ − b_i), unscaled where w_i = 1); C, d the
            inequality rows C q̇ ≤ d of all levels, stacked (≥ P, n); z the target of the null-space objective (n,)
            (read only by a ``NULL_OBJECTIVE`` level); meta the integer table (3, L + 1) of ``META_*`` rows: the
            level offsets into A's rows, into C's rows, the level kinds (``SKIP``, ``NULL_OBJECTIVE``,
            ``LEAST_SQUARES``) in its first L entries.
        limits: (lb, ub), the joint-limit bounds (n,) (∓inf where none).
        params: ``PARAM_*``: (ε, λ_max, rcond, tol, exact): the damping rule (ε and λ_max times the √ of each
            level's largest weight: the rule is relative to the level's scale), the feasibility tolerance, and 1 to
            take the SVD at every level (σ_min of every level for the diagnostics) or 0 to let a QR that certifies
            σ_min ≥ ε (:func:`qr_certificate`) give M⁺ exactly where nothing is damped (σ_min then NaN).
        x: Output, q̇ of the cascade (n,).
        stats: Output (L, 4), per level (σ_min of A_k Z, damping λ, rank of A_k Z, number of free directions r
            before the level); rank = −1 for a level that solved no least squares.

    Returns:
        True when lb − tol ≤ x ≤ ub + tol and C x ≤ d + tol.
    """
    A, b, w, C, d, z, meta = rows
    epsilon, max_damping, rcond = params[PARAM_EPSILON], params[PARAM_MAX_DAMPING], params[PARAM_RCOND]
    tol, exact = params[PARAM_TOL], params[PARAM_EXACT] != 0.0
    n = x.shape[0]
    L = meta.shape[1] - 1
    for i in range(n):
        x[i] = 0.0
    for k in range(L):
        _record(stats, k, np.inf, 0.0, -1, 0)
    Z = np.empty((n, 0))
    projected = False
    r = n
    for k in range(L):
        if r == 0:
            break
        kind = meta[META_KIND, k]
        if kind == NULL_OBJECTIVE:  # rows = I: u = Zᵀ(z − x), nothing left below
            _move_to(x, Z, r, z, 0, projected)
            r = 0
            continue
        s, e = meta[META_LS, k], meta[META_LS, k + 1]
        m = e - s
        if kind == SKIP or m == 0:
            continue
        # the damping rule relative to the level's largest weight (``Level.scale``): scaling every row of a level
        # leaves its optimum unchanged, and so does this cascade (a top task of weight 1e-4 is not damped away)
        sc_k = _level_scale(w, s, e)
        eps_k, lam_k = epsilon * sc_k, max_damping * sc_k
        if not exact and m == n and identity_rows(A, w, s, n, eps_k):
            # rows √w I (a posture as a level): M = √w Z has every singular value √w ≥ ε (Z orthonormal, I at the
            # top), nothing is damped and the rank is full, so M⁺ √w (b − x) = Zᵀ(b − x) with no factorisation
            # (σ_min left NaN, as a certified QR leaves it), and no direction is left below
            _move_to(x, Z, r, b, s, projected)
            _record(stats, k, np.nan, 0.0, r, r)
            projected = True
            r = 0
            continue
        Ak, rhs = _weighted_rows(A, b, w, s, m, x)  # √w A and the residual target √w b − √w A x
        M = _times_basis(Ak, Z, r) if projected else Ak  # M = A_k Z (m, r)
        cols = M.shape[1]
        u = np.zeros(cols)
        done = False
        sel = np.empty(m, np.int64)
        if projected and selection_columns(A, w, s, m, sel):  # some rows of I, one weight: from Z's other rows
            N, rank, sigma_min, damping = selection_solve(M, Z, sel, rhs, math.sqrt(w[s]), eps_k, lam_k, rcond, u)
            done = rank >= 0
        if not done and not exact:  # QR when it certifies that no direction is damped: M⁺ exactly, far cheaper
            done, N = _qr_solve(M, rhs, eps_k, rcond, u)
            rank, sigma_min, damping = (m if m <= cols else cols), np.nan, 0.0
        if not done:  # the damped SVD: the rule of redundik.resolvers.linalg, direction by direction
            N, rank, sigma_min, damping = _svd_solve(M, rhs, eps_k, lam_k, rcond, u)
        nfree = N.shape[1]
        if projected:
            _add_basis_step(x, Z, cols, u)
            Z = _basis_product(Z, cols, N, nfree)  # Z·null(A_k Z)
        else:
            for i in range(n):
                x[i] = u[i]
            Z = N
        _record(stats, k, sigma_min, damping, rank, r)
        projected = True
        r = nfree
    return _feasible(x, limits, C, d, meta[META_INEQ, L], tol)


@_jit
def closed_step(
    rows: CascadeRows,
    params: np.ndarray,
    q: np.ndarray,
    limits: LimitArgs,
    dt: float,
    dq_prev: np.ndarray,
    out: np.ndarray,
    stats: np.ndarray,
) -> int:
    """One ``hqp`` step's closed-form path in one call, into ``out`` (7, 1, n, rows ``OUT_*``): the joint-limit box
    at the configuration ``q`` (nq,) (``box_kernels.limit_box`` on the ``limits`` (iq, lo, hi, vmax, amax, position,
    has_rate, gain) of ``JointLimits.kernel_args``: rows lb, ub, pos_lo, pos_hi [rad/s or m/s]), the
    unconstrained cascade's q̇ (:func:`closed_cascade`, row ``OUT_CASCADE``) and q̇ clipped to the box
    (``kernels.clip_twice``: rows ``OUT_DQ``, ``OUT_KEPT``, the q̇ returned and the copy kept); ``stats`` as
    :func:`closed_cascade`'s.

    Returns:
        1 when the cascade is feasible and q̇ finite (row ``OUT_DQ`` is the step's q̇); 0 when it is not feasible
        (the constrained cascade is needed); 2 when it passed the feasibility tests but q̇ is not finite (a NaN or
        infinite row: the step's template decides).
    """
    iq, lo, hi, vmax, amax, position, has_rate, gain = limits
    box = out[OUT_LB : OUT_POS_HI + 1]
    limit_box(q.reshape((1, q.shape[0])), iq, (lo, hi, vmax, amax), position, has_rate, gain, dt, dq_prev, box)
    lb = out[OUT_LB, 0]
    ub = out[OUT_UB, 0]
    x = out[OUT_CASCADE, 0]
    ok = closed_cascade(rows, (lb, ub), params, x, stats)
    clip_twice(x, lb, ub, out[OUT_DQ : OUT_KEPT + 1, 0])
    if not ok:
        return 0
    acc = 0.0
    for i in range(x.shape[0]):
        acc += x[i] * x[i]
    return 1 if math.isfinite(acc) else 2


def first_run_cost() -> dict[str, float]:
    """Seconds each kernel of this module takes on its first call in this process (JIT compile, or loading the
    on-disk cache); later calls are the steady-state cost."""
    import time

    n = 3
    A = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 0.25], [1.0, 0.0, 0.0]])
    meta = np.array([[0, 2, 3], [0, 0, 0], [LEAST_SQUARES, LEAST_SQUARES, 0]], dtype=np.int64)
    params = np.array([1e-2, 5e-2, 1e-10, 1e-12, 0.0])
    inf = np.full(n, np.inf)
    none, rows = np.zeros(0), np.zeros((0, n))
    free = np.ones(n, dtype=np.bool_)
    out: dict[str, float] = {}
    cascade_rows = (A, np.ones(3), np.ones(3), rows, none, np.zeros(n), meta)
    t0 = time.perf_counter()
    closed_cascade(cascade_rows, (-inf, inf), params, np.empty(n), np.empty((2, 4)))
    out["closed_cascade"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    level_rows_ok(np.zeros(n), np.zeros(n), (-inf, inf, free), True, (rows, none), (rows, none), 1e-7, 1e-12)
    out["level_rows_ok"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    basis = (np.zeros((0, 0)), 0, np.zeros(0, dtype=np.int64))
    level_qp_arrays((A, np.ones(3), 1e-9), (rows, none), np.zeros(n), basis, (rows, none), (-inf, inf, free), 1e-7)
    out["level_qp_arrays"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    clearance_into(np.zeros((6, n)), np.ones(3), np.ones(n, dtype=np.int64), np.arange(3), np.zeros(3), 0.0,
                   np.zeros((6, n)), True, np.empty(n), 1.0)  # fmt: skip
    out["clearance_into"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    state = np.zeros(ST_NEQ + 1, dtype=np.int64)
    cfg = np.array([1e-2, 5e-2, 1e-10, 1e-9, 1e-7, 1e-12, 1.0, 1.0, 1e-6, 40.0, 3.0, 1.0])
    work = (np.zeros((n, n)), np.empty((n, n)), np.empty((1, n)), np.empty(1), np.zeros(1), state, free.copy(),
            np.zeros(n, dtype=np.int64))  # fmt: skip
    outs = (np.zeros(n), np.zeros((2, 7)), np.empty((2, 9)), np.empty(qp_buffer_size(n, 1, 1)))
    native = (np.zeros(0, dtype=np.int64), np.zeros(0))
    qp_cascade_run(cascade_rows, np.zeros(2, dtype=np.bool_), (-inf, inf), cfg, work, outs, (0, False, np.zeros(0)),
                   native)  # fmt: skip
    out["qp_cascade_run"] = time.perf_counter() - t0
    return out

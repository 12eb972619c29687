"""Compiled kernels of ``hqp`` (numba): its unconstrained cascade of levels, and its feasibility test, in one call.

The cascade (module docstring of :mod:`redundik.resolvers.qp.hqp`, its closed-form shortcut): with x = 0 and Z = I
before level 0, every least-squares level k solves

    u = (A_k Z)⁺_λ (b_k − A_k x),   x ← x + Z u,   Z ← Z·null(A_k Z)

with the damped pseudo-inverse of :mod:`redundik.resolvers.linalg` (per-direction damping of the singular values
below ε, truncation below rcond·σ_max: :func:`redundik.resolvers.kernels.damped_svd_factors`, the one
implementation of that rule), and the null-space objective ½‖q̇ − z‖² (identity rows) gives x ← x + Z Zᵀ(z − x)
and leaves nothing below; so does a least-squares level whose rows are exactly √w I with √w ≥ ε (a posture given a
level: :func:`identity_rows`), x ← x + Z Zᵀ(b − x). Rows are weighted by √w (‖√w ∘ (A q̇ − b)‖², as
:meth:`redundik.resolvers.qp.terms.Level.ls_rows`). The cascade is then kept when x satisfies the joint-limit box
lb − tol ≤ x ≤ ub + tol and every level's inequality rows C x ≤ d + tol (a feasible unconstrained lexicographic
optimum is the constrained one).

Why one call: per level the NumPy route paid a handful of small-array calls (weighting, A Z, b − A x, the SVD
call, two products, the basis update) and Python glue, ~10 µs per level on the Panda; fused here the three-level
Panda cascade is the SVD arithmetic plus one call's overhead. Arrays come in as preallocated buffers the caller
owns and reuses while the stack's membership is unchanged; only the per-level factors are allocated inside.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from redundik import _kernel_cache
from redundik.resolvers.kernels import (
    _reflect,
    clip_twice,
    damped_svd_factors,
    damped_svd_thin,
    householder_reflectors,
    in_box,
    limit_box,
)
from redundik.tasks.potential_kernels import clearance_into as clearance_into  # first_run_cost loads it too

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)


@_jit
def householder_qr(B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """B = Q[:, :q] R for B (p, q), p ≥ q, by Householder reflections H = I − 2vvᵀ/vᵀv: Q (p, p) orthogonal,
    R (q, q) upper triangular (its diagonal may be zero or negative; no pivoting)."""
    p, q = B.shape
    W = B.copy()
    Q = np.eye(p)
    v = np.empty(p)
    for j in range(q):
        nrm2 = 0.0
        for i in range(j, p):
            nrm2 += W[i, j] * W[i, j]
        if nrm2 == 0.0:
            continue
        alpha = -math.sqrt(nrm2) if W[j, j] >= 0.0 else math.sqrt(nrm2)  # reflect x onto −sign(x_0)‖x‖ e_0
        vv = 0.0
        for i in range(j, p):
            v[i] = W[i, j]
        v[j] -= alpha
        for i in range(j, p):
            vv += v[i] * v[i]
        if vv == 0.0:
            continue
        for c in range(j, q):  # W ← H W
            t = 0.0
            for i in range(j, p):
                t += v[i] * W[i, c]
            f = 2.0 * t / vv
            for i in range(j, p):
                W[i, c] -= f * v[i]
        for r in range(p):  # Q ← Q H
            t = 0.0
            for i in range(j, p):
                t += Q[r, i] * v[i]
            f = 2.0 * t / vv
            for i in range(j, p):
                Q[r, i] -= f * v[i]
    R = np.zeros((q, q))
    for i in range(q):
        for c in range(i, q):
            R[i, c] = W[i, c]
    return Q, R


@_jit
def upper_inverse(R: np.ndarray) -> tuple[np.ndarray, bool]:
    """R⁻¹ of an upper triangular R (q, q) by back substitution; False (and zeros) when a diagonal entry is 0."""
    q = R.shape[0]
    Ri = np.zeros((q, q))
    for i in range(q):
        if R[i, i] == 0.0 or not math.isfinite(R[i, i]):
            return Ri, False
    for c in range(q):
        Ri[c, c] = 1.0 / R[c, c]
        for i in range(c - 1, -1, -1):
            t = 0.0
            for k in range(i + 1, c + 1):
                t += R[i, k] * Ri[k, c]
            Ri[i, c] = -t / R[i, i]
    return Ri, True


@_jit
def qr_certificate(R: np.ndarray, Ri: np.ndarray, epsilon: float, rcond: float) -> bool:
    """True when every singular value σ of R is ≥ ε and > rcond·σ_max, so that the damping rule of
    :mod:`redundik.resolvers.linalg` leaves every direction exact (1/σ) and the rank full.

    From σ_min ≥ 1/‖R⁻¹‖_F and σ_max ≤ ‖R‖_F (‖·‖₂ ≤ ‖·‖_F): a sufficient test, two Frobenius norms.
    """
    fr = 0.0
    fi = 0.0
    for i in range(R.shape[0]):
        for c in range(R.shape[1]):
            fr += R[i, c] * R[i, c]
            fi += Ri[i, c] * Ri[i, c]
    if not (fi > 0.0) or not math.isfinite(fi) or not math.isfinite(fr):
        return False
    lo = 1.0 / math.sqrt(fi)
    return lo >= epsilon and lo > rcond * math.sqrt(fr)


@_jit
def identity_rows(A: np.ndarray, w: np.ndarray, s: int, n: int, epsilon: float) -> bool:
    """True when the rows A[s:s + n] are exactly the identity I (n, n) with one weight w for all of them and
    √w ≥ ε (with a relative margin of 1e-9): the level's least squares ‖√w (q̇ − b)‖² restricted to an orthonormal
    basis Z has the singular values √w only, none of them damped by the rule of :mod:`redundik.resolvers.linalg`."""
    w0 = w[s]
    if not (math.sqrt(w0) >= epsilon * (1.0 + 1e-9)):  # (false for a NaN or negative weight)
        return False
    for i in range(n):
        if w[s + i] != w0:
            return False
        for j in range(n):
            if A[s + i, j] != (1.0 if i == j else 0.0):
                return False
    return True


#: Level kinds in row 2 of the ``meta`` array of :func:`closed_cascade`.
SKIP, NULL_OBJECTIVE, LEAST_SQUARES = 0, 1, 2
#: Columns of the per-level ``stats`` array of :func:`closed_cascade`.
SIGMA_MIN, DAMPING, RANK, FREE = 0, 1, 2, 3


@_jit
def _level_scale(w: np.ndarray, s: int, e: int) -> float:
    """√ of the largest weight of the rows s..e (``Level.scale``; 1 when none is > 0): the damping rule relative to
    the level's scale, so that scaling every row of a level leaves its optimum unchanged."""
    wmax = 0.0
    for i in range(s, e):
        if w[i] > wmax:
            wmax = w[i]
    return math.sqrt(wmax) if wmax > 0.0 else 1.0


@_jit
def _projection(x: np.ndarray, Z: np.ndarray, r: int, v: np.ndarray, s: int) -> np.ndarray:
    """Z Zᵀ(v[s:s + n] − x) (n,): the step to the target v projected on the basis Z (its first r columns)."""
    n = x.shape[0]
    t = np.zeros(r)
    for i in range(n):
        vi = v[s + i] - x[i]
        for j in range(r):
            t[j] += Z[i, j] * vi
    out = np.empty(n)
    for i in range(n):
        acc = 0.0
        for j in range(r):
            acc += Z[i, j] * t[j]
        out[i] = acc
    return out


@_jit
def _weighted_rows(
    A: np.ndarray, b: np.ndarray, w: np.ndarray, s: int, m: int, x: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The rows s..s + m as √w A and the residual target √w b − √w A x."""
    n = x.shape[0]
    Ak = np.empty((m, n))
    rhs = np.empty(m)
    for i in range(m):
        wi = w[s + i]
        sc = math.sqrt(wi) if wi != 1.0 else 1.0
        acc = 0.0
        for j in range(n):
            a = A[s + i, j] * sc if wi != 1.0 else A[s + i, j]
            Ak[i, j] = a
            acc += a * x[j]
        bi = b[s + i] * sc if wi != 1.0 else b[s + i]
        rhs[i] = bi - acc
    return Ak, rhs


@_jit
def _times_basis(Ak: np.ndarray, Z: np.ndarray, r: int) -> np.ndarray:
    """A Z (m, r) for the basis Z's first r columns (zero entries of A skipped)."""
    m, n = Ak.shape
    M = np.zeros((m, r))
    for i in range(m):
        for l in range(n):
            a = Ak[i, l]
            if a != 0.0:
                for j in range(r):
                    M[i, j] += a * Z[l, j]
    return M


@_jit
def _add_basis_step(x: np.ndarray, Z: np.ndarray, r: int, u: np.ndarray) -> None:
    """x ← x + Z u for the basis Z's first r columns."""
    for i in range(x.shape[0]):
        acc = 0.0
        for c in range(r):
            acc += Z[i, c] * u[c]
        x[i] += acc


@_jit
def _basis_product(Z: np.ndarray, r: int, N: np.ndarray, rp: int) -> np.ndarray:
    """Z·N (n, rp): the basis Z (first r columns) times the null basis N (r, rp) of a level's projected rows."""
    n = Z.shape[0]
    T = np.zeros((n, rp))
    for i in range(n):
        for c in range(r):
            zic = Z[i, c]
            if zic != 0.0:
                for j in range(rp):
                    T[i, j] += zic * N[c, j]
    return T


@_jit
def closed_cascade(
    A: np.ndarray,
    b: np.ndarray,
    w: np.ndarray,
    C: np.ndarray,
    d: np.ndarray,
    z: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    meta: np.ndarray,
    params: np.ndarray,
    x: np.ndarray,
    stats: np.ndarray,
) -> bool:
    """The unconstrained cascade of every level into ``x`` (n,), and whether it is feasible (module docstring).

    Args:
        A: Least-squares rows of all levels, stacked (≥ M, n) (a level with the null-space objective and rows of its
            own carries the identity rows after them, with weight 1).
        b: Their targets (≥ M,).
        w: Row weights (≥ M,): row i enters as √w_i (A_i q̇ − b_i) (unscaled where w_i = 1).
        C: Inequality rows C q̇ ≤ d of all levels, stacked (≥ P, n).
        d: Their bounds (≥ P,).
        z: Target of the null-space objective (n,) (read only by a ``NULL_OBJECTIVE`` level).
        lb: Lower joint-limit bounds (n,) (−inf where none).
        ub: Upper bounds (n,).
        meta: Integer table (3, L + 1): row 0 the level offsets into A's rows, row 1 into C's rows, row 2 the level
            kinds (``SKIP``, ``NULL_OBJECTIVE``, ``LEAST_SQUARES``) in its first L entries.
        params: (ε, λ_max, rcond, tol, exact): the damping rule (ε and λ_max times the √ of each level's largest
            weight: the rule is relative to the level's scale), the feasibility tolerance, and 1 to take the SVD at
            every level (σ_min of every level for the diagnostics) or 0 to let a QR that certifies σ_min ≥ ε
            (:func:`qr_certificate`) give M⁺ exactly where nothing is damped (σ_min then NaN: not computed).
        x: Output, q̇ of the cascade (n,).
        stats: Output (L, 4), per level (σ_min of A_k Z, damping λ, rank of A_k Z, number of free directions r
            before the level); rank = −1 for a level that solved no least squares.

    Returns:
        True when lb − tol ≤ x ≤ ub + tol and C x ≤ d + tol.
    """
    epsilon, max_damping, rcond, tol = params[0], params[1], params[2], params[3]
    exact = params[4] != 0.0
    n = x.shape[0]
    L = meta.shape[1] - 1
    for i in range(n):
        x[i] = 0.0
    for k in range(L):
        stats[k, 0] = np.inf
        stats[k, 1] = 0.0
        stats[k, 2] = -1.0
        stats[k, 3] = 0.0
    Z = np.empty((n, 0))
    projected = False
    r = n
    for k in range(L):
        if r == 0:
            break
        kind = meta[2, k]
        if kind == NULL_OBJECTIVE:  # rows = I: u = Zᵀ(z − x), nothing left below
            if not projected:
                for i in range(n):
                    x[i] = z[i]
            else:
                dx = _projection(x, Z, r, z, 0)
                for i in range(n):
                    x[i] += dx[i]
            r = 0
            continue
        s, e = meta[0, k], meta[0, k + 1]
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
            if projected:
                dx = _projection(x, Z, r, b, s)
                for i in range(n):
                    x[i] += dx[i]
            else:
                for i in range(n):
                    x[i] = b[s + i]
            stats[k, 0] = np.nan
            stats[k, 1] = 0.0
            stats[k, 2] = r
            stats[k, 3] = r
            projected = True
            r = 0
            continue
        Ak, rhs = _weighted_rows(A, b, w, s, m, x)  # √w A and the residual target √w b − √w A x
        M = _times_basis(Ak, Z, r) if projected else Ak  # M = A_k Z (m, r)
        cols = M.shape[1]
        u = np.zeros(cols)
        N = np.empty((cols, 0))  # null(M), orthonormal columns
        done = False
        if not exact:  # QR when it certifies that no direction is damped: M⁺ exactly, several times cheaper
            if m <= cols:  # Mᵀ = Q₁R: M⁺ rhs = Q₁ R⁻ᵀ rhs, null(M) = Q₂
                Q, R = householder_qr(np.ascontiguousarray(M.T))
                Ri, ok = upper_inverse(R)
                if ok and qr_certificate(R, Ri, eps_k, rcond):
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
                    N = np.ascontiguousarray(Q[:, m:])
                    rank, sigma_min, damping, done = m, np.nan, 0.0, True
            else:  # M = Q₁R (full column rank): M⁺ rhs = R⁻¹ Q₁ᵀ rhs, null(M) = {0}
                Q, R = householder_qr(M)
                Ri, ok = upper_inverse(R)
                if ok and qr_certificate(R, Ri, eps_k, rcond):
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
                    rank, sigma_min, damping, done = cols, np.nan, 0.0, True
        if not done:  # the damped SVD: the rule of redundik.resolvers.linalg, direction by direction
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
            N = np.ascontiguousarray(Vt[rank:].T)
        nfree = N.shape[1]
        if projected:
            _add_basis_step(x, Z, cols, u)
            Z = _basis_product(Z, cols, N, nfree)  # Z·null(A_k Z)
        else:
            for i in range(n):
                x[i] = u[i]
            Z = N
        stats[k, 0] = sigma_min
        stats[k, 1] = damping
        stats[k, 2] = rank
        stats[k, 3] = r
        projected = True
        r = nfree
    if not in_box(x, lb, ub, tol):
        return False
    for i in range(meta[1, L]):
        acc = 0.0
        for j in range(n):
            acc += C[i, j] * x[j]
        if not (acc <= d[i] + tol):  # (a NaN row is not kept)
            return False
    return True


@_jit
def closed_step(
    A: np.ndarray,
    b: np.ndarray,
    w: np.ndarray,
    C: np.ndarray,
    d: np.ndarray,
    z: np.ndarray,
    meta: np.ndarray,
    params: np.ndarray,
    q: np.ndarray,
    iq: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    vmax: np.ndarray,
    amax: np.ndarray,
    position: bool,
    has_rate: bool,
    gain: float,
    dt: float,
    dq_prev: np.ndarray,
    out: np.ndarray,
    stats: np.ndarray,
) -> int:
    """One ``hqp`` step's closed-form path in one call, into ``out`` (7, 1, n): the joint-limit box at the
    configuration ``q`` (nq,) (``kernels.limit_box``: rows 0–3 lb, ub, pos_lo, pos_hi [rad/s or m/s]), the
    unconstrained cascade's q̇
    (:func:`closed_cascade`, row 4) and q̇ clipped to the box (``kernels.clip_twice``: rows 5–6, the q̇ returned and
    the copy kept); ``stats`` as :func:`closed_cascade`'s.

    Returns:
        1 when the cascade is feasible and q̇ finite (row 5 is the step's q̇); 0 when it is not feasible (the
        constrained cascade is needed); 2 when it passed the feasibility tests but q̇ is not finite (a NaN or
        infinite row: the step's template decides).
    """
    limit_box(q.reshape((1, q.shape[0])), iq, lo, hi, vmax, amax, position, has_rate, gain, dt, dq_prev, out[:4])
    lb = out[0, 0]
    ub = out[1, 0]
    x = out[4, 0]
    ok = closed_cascade(A, b, w, C, d, z, lb, ub, meta, params, x, stats)
    clip_twice(x, lb, ub, out[5:7, 0])
    if not ok:
        return 0
    acc = 0.0
    for i in range(x.shape[0]):
        acc += x[i] * x[i]
    return 1 if math.isfinite(acc) else 2


@_jit
def level_rows_ok(
    step: np.ndarray,
    x: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    free: np.ndarray,
    native: bool,
    C: np.ndarray,
    d: np.ndarray,
    F: np.ndarray,
    f: np.ndarray,
    margin: float,
    tol: float,
) -> bool:
    """Whether q̇ = x + step keeps the rows of an ``hqp`` level QP (``HierarchicalQPResolver._level_feasible``).

    The level's own inequalities C(x + step) ≤ d + tol (slack w = 0); the levels above F step ≤ max(f − F x, 0) +
    margin + tol; the free joints' limits, as native bounds lb − x − tol ≤ step ≤ ub − x + tol (``native``: the
    first level, Z = I on the free joints) or as the rows ±step_j ≤ max(±(ub_j or lb_j) − x_j), 0) + margin + tol.
    """
    n = x.shape[0]
    for i in range(C.shape[0]):
        acc = 0.0
        for j in range(n):
            acc += C[i, j] * (x[j] + step[j])
        if acc > d[i] + tol:
            return False
    for i in range(F.shape[0]):
        a = 0.0
        b = 0.0
        for j in range(n):
            a += F[i, j] * step[j]
            b += F[i, j] * x[j]
        if a > max(f[i] - b, 0.0) + margin + tol:
            return False
    for j in range(n):
        if not free[j]:
            continue
        if native:
            if step[j] < lb[j] - x[j] - tol or step[j] > ub[j] - x[j] + tol:
                return False
        else:
            if math.isfinite(ub[j]) and step[j] > max(ub[j] - x[j], 0.0) + margin + tol:
                return False
            if math.isfinite(lb[j]) and -step[j] > max(x[j] - lb[j], 0.0) + margin + tol:
                return False
    return True


@_jit
def _project_row(row: np.ndarray, out: np.ndarray, mode: int, sel: np.ndarray, Z: np.ndarray, r: int) -> None:
    """out[:r] = row Z for a row (n,): Z = I (mode 0), I on the joints ``sel`` (1), or the basis Z (2)."""
    if mode == 0:
        for j in range(r):
            out[j] = row[j]
    elif mode == 1:
        for j in range(r):
            out[j] = row[sel[j]]
    else:
        n = row.shape[0]
        for j in range(r):
            acc = 0.0
            for i in range(n):
                acc += row[i] * Z[i, j]
            out[j] = acc


@_jit
def qp_buffer_size(n: int, p_max: int, rows: int) -> int:
    """Length of a flat buffer that holds any level QP of :func:`level_qp_into` for n joints, at most ``p_max``
    inequality rows a level and ``rows`` in all (the levels above, fixed, are among them)."""
    nvar, nr = n + p_max, p_max + rows + 2 * n
    return nvar * nvar + nvar + nr * nvar + 2 * (nvar + nr)


@_jit
def cascade_qp_dims(n: int, meta: np.ndarray) -> tuple[int, int, int]:
    """(most variables, most rows) of a level QP of :func:`level_qp_into` or :func:`level_qp_joint_into` for the
    levels packed in ``meta`` (their least-squares rows start at ``meta[0]``, their inequality rows at ``meta[1]``),
    and the most least-squares rows of a level."""
    L = meta.shape[1] - 1
    p_max = 0
    m_max = 0
    for k in range(L):
        p_max = max(p_max, meta[1, k + 1] - meta[1, k])
        m_max = max(m_max, meta[0, k + 1] - meta[0, k])
    return n + p_max + m_max, p_max + meta[1, L] + 2 * n + m_max, m_max


@_jit
def cascade_qp_size(n: int, meta: np.ndarray) -> int:
    """Length of a buffer (the layout of :func:`qp_views`) that holds any level QP of the levels packed in
    ``meta``."""
    nvar, nr, _ = cascade_qp_dims(n, meta)
    return nvar * nvar + nvar + nr * nvar + 2 * (nvar + nr)


#: Words (int64) of the ``native`` array of :func:`native_quadprog`: the address of daqp's ``daqp_quadprog`` (0: no
#: native call), of its settings, the smallest n of a bounds-only QP the backend splits (never solved here), the
#: level QPs solved and their iterations (counted by :func:`qp_cascade_run`), the last level so solved; then daqp's
#: ``DAQPProblem`` (10 words) and ``DAQPResult`` (8 words) structs, then the constraints' ``sense`` (int32).
NAT_FN, NAT_SETTINGS, NAT_SPLIT_MIN, NAT_SOLVED, NAT_ITERS, NAT_LAST = range(6)
NAT_PROBLEM, NAT_RESULT, NAT_SENSE = 8, 18, 26


@intrinsic
def _call_ppp(typingctx, fn, a, b, c):  # type: ignore[no-untyped-def]
    """Call the C function at address ``fn`` as ``void fn(void*, void*, void*)`` with the three addresses."""
    sig = types.void(types.int64, types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        vp = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [vp, vp, vp])
        target = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(target, [builder.inttoptr(x, vp) for x in args[1:]])
        return context.get_dummy_value()

    return sig, codegen


@_jit
def native_quadprog(
    native: np.ndarray, nx: np.ndarray, qbuf: np.ndarray, nvar: int, nr: int, neq: int
) -> tuple[int, int]:
    """daqp on the level QP in ``qbuf`` (the layout of :func:`qp_views`), called through its C entry point: the call
    ``daqp.solve`` makes — the same structs, every setting but the two of the backend at daqp's defaults, the sense
    of the last ``neq`` rows equality and of the others inequality — without the Python wrapper. The solution goes to
    ``nx[:nvar]``, the multipliers after it.

    ``native`` is laid out by ``redundik.resolvers.qp.daqp_native.NativeDaqp`` (``NAT_*``), which checked the
    layout of daqp's structs for its version. Returns (daqp's exit flag, iterations); (0, 0) when the QP does not fit
    the buffers (never written past them).
    """
    m = nvar + nr
    if 2 * (native.shape[0] - NAT_SENSE) < m or nx.shape[0] < nvar + m:
        return 0, 0
    sense = native[NAT_SENSE:].view(np.int32)
    for i in range(m):
        sense[i] = 5 if i >= m - neq else 0  # (5: an equality)
    a = nvar * nvar
    b = a + nvar
    c = b + nr * nvar
    d = c + m
    base = qbuf.ctypes.data
    me = native.ctypes.data
    xa = nx.ctypes.data
    native[NAT_PROBLEM] = nvar | (m << 32)  # int n, int m
    native[NAT_PROBLEM + 1] = nvar  # int ms: the bounds on the variables
    native[NAT_PROBLEM + 2] = base  # H
    native[NAT_PROBLEM + 3] = base + 8 * a  # f
    native[NAT_PROBLEM + 4] = base + 8 * b if nr > 0 else 0  # A
    native[NAT_PROBLEM + 5] = base + 8 * c  # bupper
    native[NAT_PROBLEM + 6] = base + 8 * d  # blower
    native[NAT_PROBLEM + 7] = me + 8 * NAT_SENSE  # sense
    native[NAT_PROBLEM + 8] = 0  # break_points
    native[NAT_PROBLEM + 9] = 0  # int nh, int problem_type (a QP)
    native[NAT_RESULT] = xa  # x
    native[NAT_RESULT + 1] = xa + 8 * nvar  # lam
    for i in range(NAT_RESULT + 2, NAT_RESULT + 8):
        native[i] = 0
    _call_ppp(native[NAT_FN], me + 8 * NAT_RESULT, me + 8 * NAT_PROBLEM, native[NAT_SETTINGS])  # type: ignore[call-arg]
    flags = native[NAT_RESULT + 4 : NAT_RESULT + 5].view(np.int32)  # int exitflag, int iter
    return flags[0], flags[1]


@_jit
def box_qps_native(
    native: np.ndarray,
    nx: np.ndarray,
    qbuf: np.ndarray,
    P: np.ndarray,
    q: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    idx: np.ndarray,
    dq: np.ndarray,
    solved: np.ndarray,
) -> int:
    """The box QPs min ½xᵀP_i x + q_iᵀx s.t. lb_i ≤ x ≤ ub_i of the problems ``idx`` of a batch (P (N, n, n), q, lb,
    ub (N, n)), each through :func:`native_quadprog` — the call ``DaqpBackend.solve`` makes on a bounds-only QP
    below its split size, on the same arrays. Where daqp solves problem i at once (exit flag 1 or 2, x finite),
    ``dq[i]`` = x clipped to the box and ``solved[k]`` = True; elsewhere ``solved[k]`` = False and ``dq[i]`` is left
    as it was (the caller poses that QP with the backend's retries). Returns daqp's iterations summed."""
    n = P.shape[1]
    Pv, qv, _, upper, lower = qp_views(qbuf, n, 0)
    total = 0
    for k in range(idx.shape[0]):
        i = idx[k]
        Pv[:, :] = P[i]
        qv[:] = q[i]
        upper[:] = ub[i]
        lower[:] = lb[i]
        flag, iters = native_quadprog(native, nx, qbuf, n, 0, 0)
        ok = flag == 1 or flag == 2
        if ok:
            for j in range(n):
                if not math.isfinite(nx[j]):
                    ok = False
        solved[k] = ok
        if ok:
            total += iters
            for j in range(n):
                dq[i, j] = min(max(nx[j], lb[i, j]), ub[i, j])
    return total


@_jit
def qp_views(buf: np.ndarray, nvar: int, nr: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(P (nvar, nvar), q (nvar), G (nr, nvar), upper (nvar + nr), lower (nvar + nr)): the level QP in ``buf``, as
    views in daqp's form — the bounds on the variables first, then the rows' (their lower bounds −∞)."""
    a = nvar * nvar
    b = a + nvar
    c = b + nr * nvar
    d = c + nvar + nr
    return (
        buf[0:a].reshape((nvar, nvar)),
        buf[a:b],
        buf[b:c].reshape((nr, nvar)),
        buf[c:d],
        buf[d : d + nvar + nr],
    )


@_jit
def level_qp_into(
    M: np.ndarray,
    rhs: np.ndarray,
    eps: float,
    C: np.ndarray,
    d: np.ndarray,
    x: np.ndarray,
    Z: np.ndarray,
    mode: int,
    sel: np.ndarray,
    F: np.ndarray,
    f: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    free: np.ndarray,
    tol: float,
    buf: np.ndarray,
) -> tuple[int, int]:
    """One ``hqp`` level QP over (u, w') (module docstring of :mod:`redundik.resolvers.qp.hqp`) into ``buf``, in the
    layout of :func:`qp_views` (P, q, G, upper = (u_b, h), lower = (l, −∞)):

        minimise  ½ uᵀ(MᵀM + εI)u − (Mᵀ rhs)ᵀu + ½‖w'‖² + w₀ᵀw'
        subject to  C Z u − w' ≤ (d − C x) + w₀,  w₀ = max(C x − d, 0)          (the level's rows, w = w₀ + w')
                    F Z u ≤ max(f − F x, 0) + tol                              (the levels above)
                    l ≤ (u, w') ≤ u_b  and, below the first level, ±Z_j u ≤ max(±(ub_j or lb_j) − x_j), 0) + tol

    ``mode``: 0 — Z = I (``Z`` not read), native bounds lb − x ≤ u ≤ ub − x; 1 — Z = I on the joints ``sel``
    (native bounds on those); 2 — the limits of the ``free`` joints with a finite bound as rows of Z. M has r
    columns (r = n in mode 0) and no rows for a level without least squares.

    Returns:
        (nvar, nr): the variables (u, w') and the rows of G.
    """
    n = x.shape[0]
    r = M.shape[1]
    p = C.shape[0]
    nvar = r + p
    nfu = 0
    nfl = 0
    if mode == 2:
        for j in range(n):
            if free[j] and math.isfinite(ub[j]):
                nfu += 1
            if free[j] and math.isfinite(lb[j]):
                nfl += 1
    nf = F.shape[0]
    nr = p + nf + nfu + nfl
    if buf.shape[0] < nvar * nvar + nvar + nr * nvar + 2 * (nvar + nr):
        raise ValueError("level_qp_into: the QP buffer is too small for this level")
    P, q, G, up, low = qp_views(buf, nvar, nr)
    P[:, :] = 0.0
    q[:] = 0.0
    G[:, :] = 0.0
    lo, hi, h = low[:nvar], up[:nvar], up[nvar:]
    low[nvar:] = -np.inf
    for a in range(M.shape[0]):
        ra = rhs[a]
        for i in range(r):
            mi = M[a, i]
            if mi != 0.0:
                q[i] -= mi * ra
                for j in range(r):
                    P[i, j] += mi * M[a, j]
    for i in range(r):
        P[i, i] += eps
    for k in range(p):
        _project_row(C[k], G[k], mode, sel, Z, r)
        G[k, r + k] = -1.0
        cx = 0.0
        for j in range(n):
            cx += C[k, j] * x[j]
        s0 = d[k] - cx
        w0 = max(-s0, 0.0)
        P[r + k, r + k] = 1.0
        q[r + k] = w0
        h[k] = s0 + w0
    for k in range(nf):
        _project_row(F[k], G[p + k], mode, sel, Z, r)
        fx = 0.0
        for j in range(n):
            fx += F[k, j] * x[j]
        h[p + k] = max(f[k] - fx, 0.0) + tol
    lo[:] = -np.inf
    hi[:] = np.inf
    if mode == 0:
        for j in range(r):
            lo[j] = lb[j] - x[j]
            hi[j] = ub[j] - x[j]
    elif mode == 1:
        for j in range(r):
            lo[j] = lb[sel[j]] - x[sel[j]]
            hi[j] = ub[sel[j]] - x[sel[j]]
    else:
        o = p + nf
        for i in range(n):
            if free[i] and math.isfinite(ub[i]):
                for j in range(r):
                    G[o, j] = Z[i, j]
                h[o] = max(ub[i] - x[i], 0.0) + tol
                o += 1
        for i in range(n):
            if free[i] and math.isfinite(lb[i]):
                for j in range(r):
                    G[o, j] = -Z[i, j]
                h[o] = max(x[i] - lb[i], 0.0) + tol
                o += 1
    return nvar, nr


@_jit
def level_qp_arrays(
    M: np.ndarray,
    rhs: np.ndarray,
    eps: float,
    C: np.ndarray,
    d: np.ndarray,
    x: np.ndarray,
    Z: np.ndarray,
    mode: int,
    sel: np.ndarray,
    F: np.ndarray,
    f: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    free: np.ndarray,
    tol: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(P, q, G, h, l, u) of :func:`level_qp_into`'s level QP, in arrays of their own."""
    n = x.shape[0]
    p = C.shape[0]
    buf = np.empty(qp_buffer_size(n, p, p + F.shape[0]))
    nvar, nr = level_qp_into(M, rhs, eps, C, d, x, Z, mode, sel, F, f, lb, ub, free, tol, buf)
    P, q, G, up, low = qp_views(buf, nvar, nr)
    return P.copy(), q.copy(), G.copy(), up[nvar:].copy(), low[:nvar].copy(), up[:nvar].copy()


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
    t0 = time.perf_counter()
    closed_cascade(A, np.ones(3), np.ones(3), rows, none, np.zeros(n), -inf, inf, meta, params, np.empty(n),
                   np.empty((2, 4)))  # fmt: skip
    out["closed_cascade"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    level_rows_ok(np.zeros(n), np.zeros(n), -inf, inf, free, True, rows, none, rows, none, 1e-7, 1e-12)
    out["level_rows_ok"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    level_qp_arrays(A, np.ones(3), 1e-9, rows, none, np.zeros(n), np.zeros((0, 0)), 0, np.zeros(0, dtype=np.int64),
                    rows, none, -inf, inf, free, 1e-7)  # fmt: skip
    out["level_qp_arrays"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    clearance_into(np.zeros((6, n)), np.ones(3), np.ones(n, dtype=np.int64), np.arange(3), np.zeros(3), 0.0,
                   np.zeros((6, n)), True, np.empty(n), 1.0)  # fmt: skip
    out["clearance_into"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    state = np.zeros(ST_NEQ + 1, dtype=np.int64)
    cfg = np.array([1e-2, 5e-2, 1e-10, 1e-9, 1e-7, 1e-12, 1.0, 1.0, 1e-6, 40.0, 3.0, 1.0])
    qp_cascade_run(A, np.ones(3), np.ones(3), rows, none, np.zeros(n), meta, np.zeros(2, dtype=np.bool_), -inf, inf,
                   free.copy(), np.zeros(n, dtype=np.int64), cfg, state, np.zeros(n), np.zeros((n, n)),
                   np.empty((n, n)), np.empty((1, n)), np.empty(1), np.zeros(1), np.zeros((2, 7)), np.empty((2, 9)),
                   np.empty(qp_buffer_size(n, 1, 1)), 0, False, np.zeros(0), np.zeros(0, dtype=np.int64),
                   np.zeros(0))  # fmt: skip
    out["qp_cascade_run"] = time.perf_counter() - t0
    return out


#: Entries of the ``cfg`` array of :func:`qp_cascade_run`.
(CFG_EPSILON, CFG_MAX_DAMPING, CFG_RCOND, CFG_REGULARIZATION, CFG_SLACK_TOL, CFG_FEASIBLE, CFG_IDENTITY, CFG_SHORTCUT,
 CFG_CONTRADICTION, CFG_COMPLEMENT_MIN_N, CFG_COMPLEMENT_FRACTION, CFG_CERTIFIED_QR) = range(12)  # fmt: skip
#: Entries of the ``state`` array of :func:`qp_cascade_run`: the basis mode (0: Z = I, 1: I on the free joints,
#: 2: the basis Z), r (its columns), the fixed rows so far, the pending level's null-basis columns, whether the
#: pending level solved a least squares (its basis then shrinks to Z·N), the number of free joints (``sel``), and
#: whether a level's slack exceeded the contradiction tolerance.
ST_MODE, ST_R, ST_NF, ST_NCOLS, ST_LSQ, ST_NSEL, ST_CONTRADICTED, ST_NU, ST_NEQ = range(9)
#: Basis modes (``state[ST_MODE]``): Z = I, I on the free joints, the basis Z (n, r), or its complement W (n − r, n)
#: (orthonormal rows, kept in the rows of the ``Z`` buffer: the free directions are null(W)).
IDENTITY_BASIS, SELECTION_BASIS, GENERAL_BASIS, COMPLEMENT_BASIS = 0, 1, 2, 3
#: A level of least squares goes over to the complement mode when n ≥ ``cfg[CFG_COMPLEMENT_MIN_N]`` and the
#: complement it leaves — the directions fixed so far plus its rows — times ``cfg[CFG_COMPLEMENT_FRACTION]`` is at
#: most n (a fraction of 0: whenever it has fewer rows than n).
#: Columns of the ``stats`` array of :func:`qp_cascade_run`, per level: σ_min, damping λ, rank of A_k Z, free
#: directions r before the level, projected (1: the basis was a general Z), solved (1: a least squares was solved:
#: the record of ``HierarchicalQPResolver._record``), the worst slack w_k* of its inequality rows.
QS_SIGMA, QS_DAMPING, QS_RANK, QS_FREE, QS_PROJECTED, QS_SOLVED, QS_WORST = range(7)


@_jit
def _absorb(
    k: int,
    u: np.ndarray,
    C: np.ndarray,
    d: np.ndarray,
    meta: np.ndarray,
    tol: float,
    contradiction: float,
    state: np.ndarray,
    x: np.ndarray,
    Z: np.ndarray,
    N: np.ndarray,
    F: np.ndarray,
    f: np.ndarray,
    slack: np.ndarray,
    stats: np.ndarray,
) -> None:
    """Level k's step u into the cascade: x ← x + Z u; its inequality rows join the fixed rows with their optimal
    slack, C q̇ ≤ d + w* + tol, w* = max(C x − d, 0) (kept per row in ``slack``); and, for a level that solved a
    least squares, Z ← Z·N (N: the null basis of A_k Z, ``state[ST_NCOLS]`` columns).

    In the complement mode u is the joint-space step y itself (x ← x + y) and the level's new fixed directions —
    ``state[ST_NCOLS]`` rows of N — join the complement W; when it fills the space the mode becomes the empty basis
    (mode 2, r = 0)."""
    n = x.shape[0]
    mode, r = state[ST_MODE], state[ST_R]
    if mode == IDENTITY_BASIS or mode == COMPLEMENT_BASIS:
        for i in range(n):
            x[i] += u[i]
    else:
        _add_basis_step(x, Z, r, u)
    nf = state[ST_NF]
    worst = 0.0
    for i in range(meta[1, k], meta[1, k + 1]):
        acc = 0.0
        for j in range(n):
            acc += C[i, j] * x[j]
        wv = acc - d[i]
        if not wv > 0.0:
            wv = 0.0 if wv == wv else wv  # (a NaN row stays NaN, as np.maximum leaves it)
        slack[i] = wv
        for j in range(n):
            F[nf, j] = C[i, j]
        f[nf] = d[i] + wv + tol
        nf += 1
        if wv > worst:
            worst = wv
    state[ST_NF] = nf
    stats[k, QS_WORST] = worst
    if worst > contradiction:
        state[ST_CONTRADICTED] = 1
    if state[ST_LSQ] and mode == COMPLEMENT_BASIS:
        added = state[ST_NCOLS]
        if r - added > 0:
            nw = n - r
            for i in range(added):
                for j in range(n):
                    Z[nw + i, j] = N[i, j]
            state[ST_R] = r - added
        else:
            state[ST_MODE] = GENERAL_BASIS
            state[ST_R] = 0
    elif state[ST_LSQ]:
        rp = state[ST_NCOLS]
        if mode == 0:
            for i in range(n):
                for j in range(rp):
                    Z[i, j] = N[i, j]
        else:
            T = _basis_product(Z, r, N, rp)
            for i in range(n):
                for j in range(rp):
                    Z[i, j] = T[i, j]
        state[ST_MODE] = 2
        state[ST_R] = rp


@_jit
def _start(
    lb: np.ndarray, ub: np.ndarray, state: np.ndarray, x: np.ndarray, Z: np.ndarray, free: np.ndarray, sel: np.ndarray
) -> None:
    """The cascade's start (``LimitBox.pinned``'s rule): a joint whose box is one value, ub − lb ≤ 1e-12·max(1,
    |ub|) with both finite, is fixed at its middle and left out of the basis: Z = I on the free joints (mode 1) when
    any is pinned, else Z = I (mode 0)."""
    n = x.shape[0]
    cnt = 0
    for j in range(n):
        x[j] = 0.0
        for c in range(n):
            Z[j, c] = 0.0
        lo, hi = lb[j], ub[j]
        if math.isfinite(lo) and math.isfinite(hi) and hi - lo <= 1e-12 * max(1.0, abs(hi)):
            x[j] = 0.5 * (lo + hi)
            free[j] = False
        else:
            free[j] = True
            sel[cnt] = j
            cnt += 1
    for i in range(cnt):
        Z[sel[i], i] = 1.0
    state[ST_MODE] = 0 if cnt == n else 1
    state[ST_R] = cnt
    state[ST_NF] = 0
    state[ST_NCOLS] = 0
    state[ST_LSQ] = 0
    state[ST_NSEL] = cnt if cnt < n else 0
    state[ST_CONTRADICTED] = 0
    state[ST_NU] = 0
    state[ST_NEQ] = 0


@_jit
def _to_complement(state: np.ndarray, Z: np.ndarray, free: np.ndarray) -> None:
    """From Z = I (on the free joints) to the complement mode: W = the rows e_j of the pinned joints."""
    n = Z.shape[0]
    nw = 0
    for j in range(n):
        if not free[j]:
            for c in range(n):
                Z[nw, c] = 0.0
            Z[nw, j] = 1.0
            nw += 1
    state[ST_MODE] = COMPLEMENT_BASIS
    state[ST_R] = n - nw


@_jit
def _complement_projection(v: np.ndarray, Z: np.ndarray, nw: int) -> np.ndarray:
    """(I − WᵀW) v (n,): v projected on null(W), W the complement's nw rows (kept in ``Z``'s rows)."""
    n = v.shape[0]
    out = v.copy()
    for i in range(nw):
        acc = 0.0
        for j in range(n):
            acc += Z[i, j] * v[j]
        if acc != 0.0:
            for j in range(n):
                out[j] -= acc * Z[i, j]
    return out


@_jit
def level_qp_joint_into(
    M: np.ndarray,
    rhs: np.ndarray,
    eps: float,
    diagonal: float,
    C: np.ndarray,
    d: np.ndarray,
    x: np.ndarray,
    W: np.ndarray,
    F: np.ndarray,
    f: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    free: np.ndarray,
    native: bool,
    tol: float,
    buf: np.ndarray,
) -> tuple[int, int, int]:
    """The level QP of :func:`level_qp_into` posed in joint space, for the complement mode (the free directions
    null(W), W (nw, n) with orthonormal rows): over y = Z u ∈ null(W) — ‖u‖ = ‖y‖ and A Z u = A y there — the same
    problem, the same optimum, with the joint limits as simple bounds on y instead of 2n rows of Z, and without Z:

        minimise  ½ ε‖y‖² + ½‖s − rhs‖² + ½ diagonal·‖y‖² − diagonal·rhsᵀy + ½‖w'‖² + w₀ᵀw'
        subject to  C y − w' ≤ (d − C x) + w₀          F y ≤ max(f − F x, 0) + tol
                    M y − s = 0,  W y = 0            (equalities, the last rows)
                    −(max(x − lb, 0) + tol) ≤ y ≤ max(ub − x, 0) + tol   on the free joints with a bound
                    (``native``, the level where the mode changes: lb − x ≤ y ≤ ub − x, as :func:`level_qp_into`'s
                    modes 0 and 1 bound u)

    The least squares ½‖M y − rhs‖² is lifted (s = M y, m more variables and rows) so that the Hessian stays
    diagonal, which daqp factors in O(n); ``diagonal`` > 0 instead poses ½‖y − rhs‖² (scaled; the null-space
    objective's rows I: M then has no rows). Variables (y, s, w'), in the layout of :func:`qp_views`.

    Returns:
        (nvar, nr, neq): the variables, the rows of G, and how many of them (the last) are equalities.
    """
    n = x.shape[0]
    m = M.shape[0]
    p = C.shape[0]
    nw = W.shape[0]
    nf = F.shape[0]
    nvar = n + m + p
    neq = m + nw
    nr = p + nf + neq
    if buf.shape[0] < nvar * nvar + nvar + nr * nvar + 2 * (nvar + nr):
        raise ValueError("level_qp_joint_into: the QP buffer is too small for this level")
    P, q, G, up, low = qp_views(buf, nvar, nr)
    P[:, :] = 0.0
    q[:] = 0.0
    G[:, :] = 0.0
    lo, hi, h = low[:nvar], up[:nvar], up[nvar:]
    lo[:] = -np.inf
    hi[:] = np.inf
    for i in range(n):
        P[i, i] = eps + diagonal
        if diagonal != 0.0:
            q[i] = -diagonal * rhs[i]
    for a in range(m):
        P[n + a, n + a] = 1.0
        q[n + a] = -rhs[a]
    for k in range(p):
        G[k, :n] = C[k]
        G[k, n + m + k] = -1.0
        cx = 0.0
        for j in range(n):
            cx += C[k, j] * x[j]
        s0 = d[k] - cx
        w0 = max(-s0, 0.0)
        P[n + m + k, n + m + k] = 1.0
        q[n + m + k] = w0
        h[k] = s0 + w0
        low[nvar + k] = -np.inf
    for k in range(nf):
        G[p + k, :n] = F[k]
        fx = 0.0
        for j in range(n):
            fx += F[k, j] * x[j]
        h[p + k] = max(f[k] - fx, 0.0) + tol
        low[nvar + p + k] = -np.inf
    o = p + nf
    for a in range(m):  # M y − s = 0
        G[o + a, :n] = M[a]
        G[o + a, n + a] = -1.0
        h[o + a] = 0.0
        low[nvar + o + a] = 0.0
    o += m
    for i in range(nw):  # W y = 0
        G[o + i, :n] = W[i]
        h[o + i] = 0.0
        low[nvar + o + i] = 0.0
    for j in range(n):
        if free[j] and native:
            lo[j] = lb[j] - x[j]
            hi[j] = ub[j] - x[j]
        elif free[j]:
            if math.isfinite(ub[j]):
                hi[j] = max(ub[j] - x[j], 0.0) + tol
            if math.isfinite(lb[j]):
                lo[j] = -(max(x[j] - lb[j], 0.0) + tol)
    return nvar, nr, neq


@_jit
def _certified_null(M: np.ndarray, epsilon: float, rcond: float, N: np.ndarray, rrow: np.ndarray) -> bool:
    """For M (m, r), m ≤ r, the Householder QR Mᵀ = Q [R; 0] when it certifies σ_min(M) ≥ ε and the full rank
    (:func:`qr_certificate`: what the damped SVD would leave undamped): Q₂ = Q[:, m:] (null(M), orthonormal)
    into N[:r, :r − m], Q₁ into N[:r, r − m : r], R row by row into rrow[:m²]; False (nothing written that is
    read) otherwise."""
    m, r = M.shape
    Q, R = householder_qr(np.ascontiguousarray(M.T))
    Ri, ok = upper_inverse(R)
    if not ok or not qr_certificate(R, Ri, epsilon, rcond):
        return False
    for i in range(r):
        for j in range(r - m):
            N[i, j] = Q[i, m + j]
        for j in range(m):
            N[i, r - m + j] = Q[i, j]
    for i in range(m):
        for j in range(m):
            rrow[i * m + j] = R[i, j]
    return True


@_jit
def _certified_rows(M: np.ndarray, epsilon: float, rcond: float, N: np.ndarray, rrow: np.ndarray) -> bool:
    """:func:`_certified_null` for the complement mode, M (m, n) with m ≤ n: the thin Householder QR Mᵀ = Q₁R
    (Q₁ (n, m) formed from the reflections alone, O(n m²) — no n × n Q) when it certifies σ_min(M) ≥ ε; Q₁ᵀ, an
    orthonormal basis of M's row space (the SVD's Vt[:m] up to a rotation), into N[:m, :n], R into rrow[:m²]."""
    m, n = M.shape
    W = np.ascontiguousarray(M.T).copy()  # (n, m), reduced in place to R
    V, beta = householder_reflectors(W, m)
    R = np.zeros((m, m))
    for i in range(m):
        for c in range(i, m):
            R[i, c] = W[i, c]
    Ri, ok = upper_inverse(R)
    if not ok or not qr_certificate(R, Ri, epsilon, rcond):
        return False
    Q1 = np.zeros((n, m))  # H_0 ⋯ H_{m−1} [I; 0], from the last reflection on (H_j leaves the columns < j alone)
    for i in range(m):
        Q1[i, i] = 1.0
    for j in range(m - 1, -1, -1):
        if beta[j] != 0.0:
            _reflect(V[j], beta[j], Q1, j, j)
    for i in range(m):
        for j in range(n):
            N[i, j] = Q1[j, i]
        for j in range(m):
            rrow[i * m + j] = R[i, j]
    return True


@_jit
def _ridge_triangular(rrow: np.ndarray, m: int, rhs: np.ndarray, eps: float) -> np.ndarray:
    """t = argmin ‖Rᵀt − rhs‖² + ε‖t‖² for R (m, m) upper triangular, stored row by row in rrow[:m²]: the
    Householder QR of [Rᵀ; √ε I] (2m, m) applied to [rhs; 0] and back substitution (no normal equations: the
    accuracy of the SVD's σ/(σ² + ε), without squaring R's condition number)."""
    B = np.zeros((2 * m, m + 1))  # [Rᵀ rhs; √ε I 0]: the right-hand side as its last column
    se = math.sqrt(eps)
    for i in range(m):
        for j in range(i + 1):
            B[i, j] = rrow[j * m + i]  # Rᵀ: lower triangular
        B[m + i, i] = se
        B[i, m] = rhs[i]
    householder_reflectors(B, m)
    t = np.zeros(m)
    for i in range(m - 1, -1, -1):
        acc = B[i, m]
        for j in range(i + 1, m):
            acc -= B[i, j] * t[j]
        t[i] = acc / B[i, i]
    return t


@_jit
def qp_cascade_run(
    A: np.ndarray,
    b: np.ndarray,
    w: np.ndarray,
    C: np.ndarray,
    d: np.ndarray,
    z: np.ndarray,
    meta: np.ndarray,
    mixed: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    free: np.ndarray,
    sel_buf: np.ndarray,
    cfg: np.ndarray,
    state: np.ndarray,
    x: np.ndarray,
    Z: np.ndarray,
    N: np.ndarray,
    F: np.ndarray,
    f: np.ndarray,
    slack: np.ndarray,
    stats: np.ndarray,
    rfac: np.ndarray,
    qbuf: np.ndarray,
    k0: int,
    absorb: bool,
    u_in: np.ndarray,
    ctl: np.ndarray,
    nx: np.ndarray,
) -> tuple[int, int, int, int, float]:
    """``hqp``'s constrained cascade (module docstring of :mod:`redundik.resolvers.qp.hqp`) from level ``k0`` on,
    up to the next level that needs the backend: the whole of it but the level QPs, which the caller solves.

    The levels are the packed rows of :func:`closed_cascade` (``meta``; ``mixed[k]``: a least-squares level that
    carries the null-space objective's identity rows after its own). Per level: its least squares over
    q̇ = x + Z u — the damped SVD of A_k Z (the rule relative to the level's largest weight), exact factors for
    identity rows (√w I, or the null-space objective's I) —, the ridge solution û and, with the level shortcut,
    the test that û keeps every row of the level QP (:func:`level_rows_ok`); when it does, û is the level's
    optimum, else the level QP is written into ``qbuf`` (:func:`level_qp_into`) for the backend. A pure null-space level
    whose projection keeps the limits and the levels above takes it without a QP.

    Args:
        cfg: ``CFG_*``: ε, λ_max, rcond, the regulariser, the slack tolerance, the shortcut's feasibility
            tolerance, identity levels (1/0), the level shortcut (1/0), the contradiction tolerance, the complement
            mode's smallest n and fraction, and the certified QR (1/0: a least-squares level of m ≤ r rows whose
            QR of (A_k Z)ᵀ certifies σ_min ≥ ε, :func:`qr_certificate`, is factored by it — the same ridge and null
            basis as its SVD's, nothing damped — instead of its SVD).
        state: ``ST_*`` (int64), kept between calls; x, Z (n, n), N (n, n), F, f (fixed rows), slack (one per C
            row), stats (L, 7) likewise.
        rfac: (L, ≥ m²) per level the R (m, m) of a level of m rows whose QR certified σ_min ≥ ε (``cfg[
            CFG_CERTIFIED_QR]``; its σ_min then NaN in ``stats``: the singular values of R are the level's, for the
            diagnostics); a level of more than √(rfac.shape[1]) rows takes the SVD.
        qbuf: Where a level QP is written (:func:`qp_buffer_size` long for the largest level; read it through
            :func:`qp_views`).
        k0: The level to start at; with ``absorb``, the level whose QP the caller solved: its u (``u_in``) is
            absorbed first and the cascade goes on at k0 + 1 (without it: a level the caller skipped, or the start).
        ctl: With ``ctl[NAT_FN]`` set (daqp as the backend, ``daqp_native.NativeDaqp``), a level QP is solved
            here through daqp's C entry point (:func:`native_quadprog`) and absorbed when daqp solves it (exit flag
            1 or 2, a finite x) — what the caller would do with daqp's answer; any other QP is returned to the
            caller, which poses it with every retry. Empty: every level QP is returned.
        nx: Where daqp writes its solution and multipliers (``NativeDaqp.x``).

    Returns:
        (0, L, 0, 0, 0) when the cascade is done (q̇ in x); (1, k, nvar, nr, ε) when level k needs its QP: nvar
        variables (u, w') and nr rows, in ``qbuf``; ε its regulariser on u.
    """
    n = x.shape[0]
    L = meta.shape[1] - 1
    if state.shape[0] <= ST_NEQ or cfg.shape[0] <= CFG_CERTIFIED_QR or Z.shape[0] < n or N.shape[0] < n:
        raise ValueError("qp_cascade_run: state, cfg, Z or N is shorter than the layout it is read in")
    epsilon, max_damping, rcond = cfg[CFG_EPSILON], cfg[CFG_MAX_DAMPING], cfg[CFG_RCOND]
    reg, tol, feas = cfg[CFG_REGULARIZATION], cfg[CFG_SLACK_TOL], cfg[CFG_FEASIBLE]
    identity_levels, shortcut = cfg[CFG_IDENTITY] != 0.0, cfg[CFG_SHORTCUT] != 0.0
    contra = cfg[CFG_CONTRADICTION]
    cmin, cfrac = cfg[CFG_COMPLEMENT_MIN_N], cfg[CFG_COMPLEMENT_FRACTION]
    certified_qr = cfg[CFG_CERTIFIED_QR] != 0.0
    empty2 = np.zeros((0, 0))
    empty1 = np.zeros(0)
    if k0 == 0 and not absorb:  # the start: x = 0 but on the pinned joints, Z = I (or I on the free joints)
        _start(lb, ub, state, x, Z, free, sel_buf)
    sel = sel_buf[: state[ST_NSEL]]
    k = k0
    if absorb:
        _absorb(k, u_in, C, d, meta, tol, contra, state, x, Z, N, F, f, slack, stats)
        k += 1
    while k < L:
        kind = meta[2, k]
        c0, c1 = meta[1, k], meta[1, k + 1]
        p = c1 - c0
        s, e = meta[0, k], meta[0, k + 1]
        m = e - s if kind == LEAST_SQUARES else 0
        pure = kind == NULL_OBJECTIVE
        mode, r, nf = state[ST_MODE], state[ST_R], state[ST_NF]
        if r == 0 and p == 0:
            k += 1
            continue
        if m == 0 and not pure and p == 0:
            k += 1
            continue
        Ck = C[c0:c1]
        dk = d[c0:c1]
        Ff = F[:nf]
        ff = f[:nf]
        native = mode == IDENTITY_BASIS or mode == SELECTION_BASIS  # the limits as the variables' own bounds
        if (  # a least-squares level that leaves few fixed directions: the complement mode from here on
            native and m > 0 and m < n and n >= cmin and cfrac * ((n - r) + m) <= n
        ):
            _to_complement(state, Z, free)
            mode = COMPLEMENT_BASIS
            projected = False
        else:
            projected = mode == GENERAL_BASIS or mode == COMPLEMENT_BASIS
        comp = mode == COMPLEMENT_BASIS
        nw = n - r if comp else 0
        if pure and p == 0 and mode != 0:  # the closed form P_Z(z − x) when it keeps the limits and the levels above
            if comp:
                cand = x + _complement_projection(z - x, Z, nw)
            else:
                cand = x + _projection(x, Z, r, z, 0)
            ok = in_box(cand, lb, ub, tol)
            if ok:
                for i in range(nf):
                    acc = 0.0
                    for j in range(n):
                        acc += Ff[i, j] * cand[j]
                    if not (acc <= ff[i] + tol):
                        ok = False
                        break
            if ok:
                for i in range(n):
                    x[i] = cand[i]
                if mode == 0:
                    state[ST_MODE] = 2  # (Z = the empty basis; a selection stays one)
                if comp:
                    state[ST_MODE] = GENERAL_BASIS
                state[ST_R] = 0
                k += 1
                continue
        # the level's least squares over u: (U, σ, Vt, rank, σ_min, λ) and its null basis into N (in the complement
        # mode: over y ∈ null(W), Vt's rows in joint space, and the rows it fixes into N's rows)
        scale = 1.0
        has_lsq = False
        M = empty2
        rhs = empty1
        U = empty2
        sv = empty1
        Vt = empty2
        rank = 0
        sigma_min = np.inf
        damping = 0.0
        ncols = 0
        qr_level = False  # the level's factors are the certified QR's (rfac[k], N), not U, σ, Vt
        if pure and comp:  # rows I on null(W): every direction left, singular values 1
            has_lsq = True
            rhs = z - x
            rank, sigma_min, ncols = r, (1.0 if r else np.inf), r
        elif pure:  # rows I: M = Z (orthonormal columns), its SVD is (Z, 1, I)
            has_lsq = True
            rhs = np.empty(n)
            for i in range(n):
                rhs[i] = z[i] - x[i]
            U = np.empty((n, r))
            for i in range(n):
                for j in range(r):
                    U[i, j] = (1.0 if i == j else 0.0) if mode == 0 else Z[i, j]
            sv = np.ones(r)
            Vt = np.eye(r)
            rank, sigma_min = r, (1.0 if r else np.inf)
        elif m > 0 and comp:  # M = A_k (I − WᵀW): its thin SVD, the fixed directions Vt[:rank]
            has_lsq = True
            scale = _level_scale(w, s, e)
            Ak, rhs = _weighted_rows(A, b, w, s, m, x)
            M = np.empty((m, n))
            for a in range(m):
                M[a] = _complement_projection(Ak[a], Z, nw)
            if (
                certified_qr and m <= r and m * m <= rfac.shape[1]
                and _certified_rows(M, epsilon * scale, rcond, N, rfac[k])
            ):  # fmt: skip
                # Mᵀ = Q₁R certifies σ_min ≥ ε: the fixed directions Q₁ᵀ are N's first m rows, R in rfac[k]
                qr_level = True
                rank, sigma_min, ncols = m, np.nan, m
            else:
                U, sv, Vt, _, rank, sigma_min, damping = damped_svd_thin(M, epsilon * scale, max_damping * scale, rcond)
                rank = min(rank, r)  # (M's rows lie in null(W), of dimension r)
                for i in range(rank):
                    for j in range(n):
                        N[i, j] = Vt[i, j]
                ncols = rank
        elif m > 0:
            has_lsq = True
            scale = _level_scale(w, s, e)
            Ak, rhs = _weighted_rows(A, b, w, s, m, x)
            M = Ak if mode == 0 else _times_basis(Ak, Z, r)
            if identity_levels and r > 0 and not mixed[k] and m == n and identity_rows(A, w, s, n, epsilon * scale):
                sw = math.sqrt(w[s])
                U = np.empty((n, r))
                for i in range(n):
                    for j in range(r):
                        U[i, j] = (1.0 if i == j else 0.0) if mode == 0 else Z[i, j]
                sv = np.full(r, sw)
                Vt = np.eye(r)
                rank, sigma_min = r, sw
            elif r == 0:
                U, sv, Vt = np.zeros((m, 0)), np.zeros(0), np.eye(0)
            elif (
                certified_qr and m <= r and m * m <= rfac.shape[1]
                and _certified_null(M, epsilon * scale, rcond, N, rfac[k])
            ):  # fmt: skip
                # Mᵀ = Q₁R certifies σ_min ≥ ε (nothing damped, rank m): null(M) = Q₂ is in N, R in rfac[k] (σ_min
                # from it when the diagnostics are read), and the ridge below takes R instead of the SVD
                qr_level = True
                rank, sigma_min, ncols = m, np.nan, r - m
            else:
                U, sv, Vt, _, rank, sigma_min, damping = damped_svd_factors(
                    np.ascontiguousarray(M), epsilon * scale, max_damping * scale, rcond
                )
                ncols = Vt.shape[0] - rank
                for i in range(Vt.shape[0]):
                    for j in range(ncols):
                        N[i, j] = Vt[rank + j, i]
        eps = reg * scale * scale
        if has_lsq:
            eps = max(eps, damping * damping)
            stats[k, QS_SIGMA] = sigma_min
            stats[k, QS_DAMPING] = damping
            stats[k, QS_RANK] = rank
            stats[k, QS_FREE] = r
            stats[k, QS_PROJECTED] = 1.0 if projected else 0.0
            stats[k, QS_SOLVED] = 1.0
        state[ST_NCOLS] = ncols
        state[ST_LSQ] = 1 if has_lsq else 0
        if shortcut:
            nu = n if comp else r
            u = np.zeros(nu)
            if has_lsq and pure and comp:  # the ridge solution (I − WᵀW) rhs / (1 + ε)
                proj = _complement_projection(rhs, Z, nw)
                for i in range(n):
                    u[i] = proj[i] / (1.0 + eps)
            elif qr_level:  # the same ridge solution from M = RᵀQ₁ᵀ: u = Q₁ t, t = argmin ‖Rᵀt − rhs‖² + ε‖t‖²
                t = _ridge_triangular(rfac[k], m, rhs, eps)
                for c in range(nu):
                    acc = 0.0
                    for j in range(m):
                        acc += (N[j, c] if comp else N[c, r - m + j]) * t[j]
                    u[c] = acc
            elif has_lsq:  # the ridge solution V diag(σ/(σ² + ε)) Uᵀ rhs
                kk = sv.shape[0]
                for j in range(kk):
                    acc = 0.0
                    for i in range(rhs.shape[0]):
                        acc += U[i, j] * rhs[i]
                    tj = sv[j] / (sv[j] * sv[j] + eps) * acc
                    if tj != 0.0:
                        for c in range(nu):
                            u[c] += Vt[j, c] * tj
            if mode == 0 or comp:
                step = u
            else:
                step = np.zeros(n)
                _add_basis_step(step, Z, r, u)
            if level_rows_ok(step, x, lb, ub, free, native, Ck, dk, Ff, ff, tol, feas):
                _absorb(k, u, C, d, meta, tol, contra, state, x, Z, N, F, f, slack, stats)
                k += 1
                continue
        # the level QP's arrays, for the backend
        Mq, rq, eq = M, rhs, eps
        if m > 0 and p == 0 and scale != 1.0:  # least squares only: divided by its scale², the same optimum
            Mq = np.empty_like(M)
            rq = np.empty_like(rhs)
            for i in range(M.shape[0]):
                for j in range(M.shape[1]):
                    Mq[i, j] = M[i, j] / scale
                rq[i] = rhs[i] / scale
            eq = eps / (scale * scale)
        neq = 0
        if comp:
            if pure or m == 0:
                Mq = np.zeros((0, n))
            nvar, nr, neq = level_qp_joint_into(
                np.ascontiguousarray(Mq), rq, eq, 1.0 if pure else 0.0, np.ascontiguousarray(Ck),
                np.ascontiguousarray(dk), x, Z[:nw], np.ascontiguousarray(Ff), np.ascontiguousarray(ff), lb, ub, free,
                native, tol, qbuf,
            )  # fmt: skip
            state[ST_NU] = n
        else:
            if pure or m == 0:
                Mq, rq = np.zeros((0, r)), empty1
            qmode = 0 if mode == 0 else (1 if mode == 1 else 2)
            nvar, nr = level_qp_into(
                np.ascontiguousarray(Mq), rq, eq, np.ascontiguousarray(Ck), np.ascontiguousarray(dk), x,
                Z[:, :r] if mode == 2 else Z[:, :0], qmode, sel, np.ascontiguousarray(Ff), np.ascontiguousarray(ff),
                lb, ub, free, tol, qbuf,
            )  # fmt: skip
            if pure:  # ½‖Zu − (z − x)‖²: MᵀM = I, Mᵀ rhs = Zᵀ(z − x)
                P, q = qp_views(qbuf, nvar, nr)[:2]
                for i in range(r):
                    P[i, i] += 1.0
                    acc = 0.0
                    for l in range(n):
                        acc += U[l, i] * rhs[l]
                    q[i] = -acc
            state[ST_NU] = r
        state[ST_NEQ] = neq
        if ctl.shape[0] > NAT_SENSE and ctl[NAT_FN] != 0 and not (nr == 0 and nvar >= ctl[NAT_SPLIT_MIN]):
            flag, iters = native_quadprog(ctl, nx, qbuf, nvar, nr, neq)
            solved = flag == 1 or flag == 2
            for i in range(nvar):
                if solved and not math.isfinite(nx[i]):
                    solved = False
            if solved:
                ctl[NAT_SOLVED] += 1
                ctl[NAT_ITERS] += max(iters, 0)
                ctl[NAT_LAST] = k
                _absorb(k, nx[: state[ST_NU]], C, d, meta, tol, contra, state, x, Z, N, F, f, slack, stats)
                k += 1
                continue
        return 1, k, nvar, nr, eq
    return 0, L, 0, 0, 0.0

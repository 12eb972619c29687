"""Compiled kernels (numba): the one implementation of the closed-form linear algebra of every resolver.

Why compiled (measured on this 2-core machine, Panda 6×9 frame task, median per call): the NumPy/SciPy route of
one ``pinv`` step's algebra is about ten small-array calls — JJᵀ 2.8 µs, ``lapack.dsyevd`` 7.3 µs (its f2py wrapper,
not the 6×6 eigensolve, is the cost), Jᵀ U Λ⁻¹ 4 µs, two solves 5.6 µs — where the same arithmetic fused in one
compiled call takes ≈ 2 µs: per-call overhead, not flops, dominates at these sizes. The kernels are compiled at
first use and cached on disk (``cache=True``); the first-run cost is reported by :func:`first_run_cost`.

What lives here (nothing else in redundik computes these; the tests hold them to slow references):

* :func:`damped_inverse_values` — the damping rule of :mod:`redundik.resolvers.linalg` (per-direction
  σ/(σ² + λ²), λ² = (1 − (σ/ε)²)·λ_max², truncation below rcond·σ_max);
* :func:`factor` — the factorisation behind J⁺: the fast path Jᵀ(JJᵀ)⁻¹ from the eigendecomposition of JJᵀ when J
  has full row rank and is well conditioned (λ_min > 1e-6 λ_max and λ_min ≥ ε²), else the damped SVD;
* :func:`solve_factored` / :func:`null_project_factored` — J⁺_λ b and (I − V_r V_rᵀ) z from those factors;
* :func:`closed_form` — the chapter's q̇ = J⁺V + (I − J⁺J)z (eq. 5.8) in one call (``pinv``'s step);
* :func:`closed_form_batch` — the same over N problems, the body of :mod:`redundik.resolvers.batch`;
* :func:`coupled_coordinates` — the test that separates P's coupled coordinates from those with no off-diagonal
  entry (their optimum is −q_i/P_ii), used by :func:`spd_solve_into` (x = −P⁻¹q, ``wqp``'s unconstrained optimum,
  with only the coupled block factored by Cholesky) and by :func:`split_separable` (daqp's bounds-only QPs split);
* :func:`spd_solve_batch` — x = −P⁻¹q by Cholesky for N problems (``wqp``'s unconstrained optimum), with a flag
  per problem that says whether the optimum lies in its box lb ≤ x ≤ ub.

The frame task's error and the frame Jacobian live one layer down, in :mod:`redundik.kinematics.lie_kernels`
(the tasks call them too); their names are re-exported here.
"""

from __future__ import annotations

import math
import time

import numpy as np

from redundik import _kernel_cache
from redundik.kinematics.lie_kernels import (  # the Lie kernels, re-exported for the resolvers' ``K.frame_error`` etc.
    SMALL_ROTATION_COS as SMALL_ROTATION_COS,
)
from redundik.kinematics.lie_kernels import (
    batch_log3_small as batch_log3_small,
)
from redundik.kinematics.lie_kernels import (
    frame_error as frame_error,
)
from redundik.kinematics.lie_kernels import (
    frame_error_rp as frame_error_rp,
)
from redundik.kinematics.lie_kernels import (
    frame_jacobian_lwa as frame_jacobian_lwa,
)

#: Smallest λ_min/λ_max of JJᵀ for the eigendecomposition fast path (κ(J) ≤ 1e3).
FAST_PATH_RCOND = 1e-6

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)


#: Largest symmetric matrix (m, m) whose eigendecomposition uses the Jacobi routine below, and the largest number of
#: columns of a tall matrix whose SVD does; LAPACK beyond (measured inside compiled code: Jacobi 1.1 vs 1.8 µs at
#: m = 3 but 4.9 vs 3.3 at m = 6 for the eigenproblem, 0.8 vs 3.1 µs for a 7×3 SVD, 7.0 vs 6.7 for a 6×9).
JACOBI_EIG_MAX = 4
JACOBI_SVD_MAX = 8
#: Widest matrix (m ≤ :data:`JACOBI_SVD_MAX` rows) whose full SVD is the Jacobi SVD of its transpose plus a Householder
#: completion of the null directions (``_svd_wide``); LAPACK beyond. Measured inside compiled code: 6×10 3.4
#: against 9.3 µs for ``np.linalg.svd``, 3×10 0.9 against 4.6, 6×20 7.3 against 13.5 (the thin SVD: 6×40 11.7 against
#: 16.4); the completion's O(r n (n − r)) makes it lose beyond some 24 columns (6×32: 16.1 against 15.6).
JACOBI_WIDE_MAX = 24
#: Singular values of a wide matrix at or below this fraction of ‖M‖_F are exact zeros in ``_svd_wide`` (their
#: right singular vectors are the completion): far below any rank tolerance (``RCOND`` = 1e-10 of σ_max).
_WIDE_NULL = 1e-14
_JACOBI_TOL = 1e-15
_JACOBI_SWEEPS = 60

#: Largest SPD block :func:`spd_solve_into` factors in plain loops; LAPACK's ``dpotrf`` above.
CHOLESKY_LOOPS_MAX = 48


@_jit
def _rotation(app: float, aqq: float, apq: float) -> tuple[float, float]:
    """(c, s) of the Jacobi rotation that zeroes the off-diagonal apq of [[app, apq], [apq, aqq]]."""
    theta = (aqq - app) / (2.0 * apq)
    if abs(theta) > 1e150:
        t = 0.5 / theta
    else:
        t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
    c = 1.0 / math.sqrt(t * t + 1.0)
    return c, t * c


@_jit
def sym_eig(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (ascending) and eigenvectors (columns) of a symmetric A (m, m): the cyclic Jacobi method for
    m ≤ :data:`JACOBI_EIG_MAX` (to full accuracy), ``np.linalg.eigh`` (LAPACK) above."""
    m = A.shape[0]
    if m > JACOBI_EIG_MAX:
        return np.linalg.eigh(A)
    a = A.copy()
    V = np.eye(m)
    for _ in range(_JACOBI_SWEEPS):
        rotated = False
        for p in range(m - 1):
            for q in range(p + 1, m):
                apq = a[p, q]
                if apq == 0.0 or abs(apq) <= _JACOBI_TOL * math.sqrt(abs(a[p, p] * a[q, q])):
                    continue
                rotated = True
                c, s = _rotation(a[p, p], a[q, q], apq)
                for k in range(m):
                    akp, akq = a[k, p], a[k, q]
                    a[k, p], a[k, q] = c * akp - s * akq, s * akp + c * akq
                for k in range(m):
                    apk, aqk = a[p, k], a[q, k]
                    a[p, k], a[q, k] = c * apk - s * aqk, s * apk + c * aqk
                a[p, q] = 0.0  # zero by construction (rounding left aside)
                a[q, p] = 0.0
                for k in range(m):
                    vkp, vkq = V[k, p], V[k, q]
                    V[k, p], V[k, q] = c * vkp - s * vkq, s * vkp + c * vkq
        if not rotated:
            break
    w = np.empty(m)
    for i in range(m):
        w[i] = a[i, i]
    order = np.argsort(w)
    return w[order], np.ascontiguousarray(V[:, order])


@_jit
def svd_full(M: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """U (m, k), σ (k,) descending, Vt (n, n) of M (m, n), k = min(m, n): one-sided (Hestenes) Jacobi for tall or
    square M with n ≤ :data:`JACOBI_SVD_MAX` (orthogonalises the columns of M V), the same on Mᵀ for a wide M of at
    most that many rows and :data:`JACOBI_WIDE_MAX` columns (``_svd_wide``), LAPACK (``np.linalg.svd``)
    otherwise. Columns of U for σ = 0 are zero on the tall route (they multiply a zero inverse value)."""
    m, n = M.shape
    k = min(m, n)
    if n > m and 0 < m <= JACOBI_SVD_MAX and n <= JACOBI_WIDE_MAX:
        out = _svd_wide(M)
        if out[1].shape[0] == k:  # (empty: M not finite, LAPACK says so as before)
            return out
    if n > JACOBI_SVD_MAX or n > m:  # wide (the n − m null columns slow the sweeps down) or many columns: LAPACK
        U0, s0, Vt0 = np.linalg.svd(np.ascontiguousarray(M))
        return np.ascontiguousarray(U0[:, :k]), s0, Vt0
    return _svd_jacobi(M)


@_jit
def _svd_wide(M: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`svd_full` of a wide M (m < n) from the Jacobi SVD of Mᵀ = U' Σ V'ᵀ: M = V' Σ U'ᵀ, so U = V' and the
    first rows of Vt are U'ᵀ; the directions whose σ ≤ ``_WIDE_NULL``·‖M‖_F (set to exact zeros) and the n − m
    null directions are the orthonormal complement of the others (``_complete_rows``). Empty arrays when M is
    not finite (the caller's LAPACK call then reports it)."""
    m, n = M.shape
    fro2 = _frobenius2(M)
    if not math.isfinite(fro2):
        return np.zeros((0, 0)), np.zeros(0), np.zeros((0, 0))
    Ut, s, Vtt = _svd_jacobi(np.ascontiguousarray(M.T))  # Ut (n, m), s (m,), Vtt (m, m)
    floor = _WIDE_NULL * math.sqrt(fro2)
    r = 0
    while r < m and s[r] > floor:
        r += 1
    for i in range(r, m):
        s[i] = 0.0
    Vt = np.empty((n, n))
    for i in range(r):
        for j in range(n):
            Vt[i, j] = Ut[j, i]
    _complete_rows(Vt, r)
    return np.ascontiguousarray(Vtt.T), s, Vt


@_jit
def _frobenius2(M: np.ndarray) -> float:
    """‖M‖_F² (inf or NaN when M is not finite, or so large that the squares overflow)."""
    total = 0.0
    for i in range(M.shape[0]):
        for j in range(M.shape[1]):
            total += M[i, j] * M[i, j]
    return total


@_jit
def _reflect(v: np.ndarray, beta: float, X: np.ndarray, j: int, c0: int) -> None:
    """X[j:, c] ← (I − β v vᵀ) X[j:, c] for the columns c ≥ c0: a Householder reflection (v zero above j)."""
    n = X.shape[0]
    for c in range(c0, X.shape[1]):
        t = 0.0
        for i in range(j, n):
            t += v[i] * X[i, c]
        t *= beta
        for i in range(j, n):
            X[i, c] -= t * v[i]


@_jit
def householder_reflectors(B: np.ndarray, q: int) -> tuple[np.ndarray, np.ndarray]:
    """Reduce the first q columns of B (p, ≥ q), p ≥ q, to upper triangular form in place by Householder
    reflections H_j = I − β_j v_j v_jᵀ (each applied to B's columns ≥ j, so a column after the q-th carries the
    product Hᵀ⋯ of a right-hand side); returns the vectors V (q, p) (zero above j) and β (0: no reflection)."""
    p = B.shape[0]
    V = np.zeros((q, p))
    beta = np.zeros(q)
    for j in range(q):
        norm2 = 0.0
        for i in range(j, p):
            norm2 += B[i, j] * B[i, j]
        alpha = -math.sqrt(norm2) if B[j, j] >= 0.0 else math.sqrt(norm2)
        vv = 0.0
        for i in range(j, p):
            V[j, i] = B[i, j]
        V[j, j] -= alpha
        for i in range(j, p):
            vv += V[j, i] * V[j, i]
        if vv == 0.0:
            continue
        beta[j] = 2.0 / vv
        _reflect(V[j], beta[j], B, j, j)
    return V, beta


@_jit
def _complete_rows(Q: np.ndarray, r: int) -> None:
    """Rows r … n − 1 of Q (n, n) set to an orthonormal basis of the complement of its first r rows (orthonormal):
    the last n − r columns of H_0 ⋯ H_{r−1}, the Householder reflections of the QR factorisation of Q[:r]ᵀ."""
    n = Q.shape[1]
    B = np.ascontiguousarray(Q[:r].T).copy()  # (n, r)
    V, beta = householder_reflectors(B, r)  # the reflectors v_j (zero above j) and their 2/‖v_j‖²
    C = np.zeros((n, n - r))
    for c in range(n - r):
        C[r + c, c] = 1.0
    for j in range(r - 1, -1, -1):
        if beta[j] != 0.0:
            _reflect(V[j], beta[j], C, j, 0)
    for c in range(n - r):
        for i in range(n):
            Q[r + c, i] = C[i, c]


@_jit
def _svd_jacobi(M: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The one-sided Jacobi SVD of :func:`svd_full` for a tall or square M (m ≥ n)."""
    m, n = M.shape
    k = min(m, n)
    W = np.ascontiguousarray(M).copy()
    V = np.eye(n)
    fro2 = 0.0
    for r in range(m):
        for j in range(n):
            fro2 += W[r, j] * W[r, j]
    tiny = (_JACOBI_TOL * _JACOBI_TOL) * fro2  # a column this small is numerically zero: M v = 0 (null space)
    for _ in range(_JACOBI_SWEEPS):
        rotated = False
        for p in range(n - 1):
            for q in range(p + 1, n):
                alpha = 0.0
                beta = 0.0
                gamma = 0.0
                for r in range(m):
                    alpha += W[r, p] * W[r, p]
                    beta += W[r, q] * W[r, q]
                    gamma += W[r, p] * W[r, q]
                if gamma == 0.0 or alpha <= tiny or beta <= tiny or abs(gamma) <= _JACOBI_TOL * math.sqrt(alpha * beta):
                    continue
                rotated = True
                c, s = _rotation(alpha, beta, gamma)
                for r in range(m):
                    wp, wq = W[r, p], W[r, q]
                    W[r, p], W[r, q] = c * wp - s * wq, s * wp + c * wq
                for r in range(n):
                    vp, vq = V[r, p], V[r, q]
                    V[r, p], V[r, q] = c * vp - s * vq, s * vp + c * vq
        if not rotated:
            break
    norms = np.empty(n)
    for j in range(n):
        t = 0.0
        for r in range(m):
            t += W[r, j] * W[r, j]
        norms[j] = math.sqrt(t)
    order = np.argsort(-norms)
    sig = np.empty(k)
    U = np.zeros((m, k))
    Vt = np.empty((n, n))
    for i in range(n):
        j = order[i]
        for r in range(n):
            Vt[i, r] = V[r, j]
        if i < k:
            sig[i] = norms[j]
            if norms[j] > 0.0:
                for r in range(m):
                    U[r, i] = W[r, j] / norms[j]
    return U, sig, Vt


@_jit
def damped_inverse_values(s: np.ndarray, epsilon: float, max_damping: float, rcond: float) -> tuple[np.ndarray, int]:
    """The per-direction inverse of singular values ``s`` (descending) by the damping rule, and the numerical rank.

    σ_i ≥ ε → 1/σ_i; rcond·σ_max < σ_i < ε → σ_i/(σ_i² + λ_i²) with λ_i² = (1 − (σ_i/ε)²)·λ_max²; σ_i ≤ rcond·σ_max → 0.

    Returns:
        (inverse values (k,), rank r).
    """
    k = s.shape[0]
    inv = np.zeros(k)
    if k == 0:
        return inv, 0
    smax = s[0]
    if not (smax > 0.0) or not math.isfinite(smax):
        return inv, 0
    rank = 0
    for i in range(k):
        if s[i] > rcond * smax:
            rank += 1
    damp = epsilon > 0.0 and max_damping > 0.0
    for i in range(rank):
        si = s[i]
        if damp and si < epsilon:
            lam2 = (1.0 - (si / epsilon) ** 2) * max_damping * max_damping
            inv[i] = si / (si * si + lam2)
        else:
            inv[i] = 1.0 / si
    return inv, rank


@_jit
def damped_svd_factors(
    M: np.ndarray, epsilon: float, max_damping: float, rcond: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, float, float]:
    """The damped SVD of M (m, n), m ≥ 1: (U_k (m, k), σ (k,), Vt (n, n), inverse values, rank, σ_min, damping).

    damping = λ at σ_min, √(1 − (σ_min/ε)²)·λ_max, when σ_min < ε (else 0); σ_min = ∞ when M = 0.
    """
    U, s, Vt = svd_full(M)
    inv, rank = damped_inverse_values(s, epsilon, max_damping, rcond)
    sigma_min, damping = _damping_at(s, rank, epsilon, max_damping)
    return U, s, Vt, inv, rank, sigma_min, damping


@_jit
def _damping_at(s: np.ndarray, rank: int, epsilon: float, max_damping: float) -> tuple[float, float]:
    """(σ_min, λ at σ_min) of :func:`damped_svd_factors`: σ_min = ∞ without a direction kept."""
    sigma_min = s[rank - 1] if rank else np.inf
    damping = 0.0
    if rank and sigma_min < epsilon and epsilon > 0.0:
        damping = math.sqrt(1.0 - (sigma_min / epsilon) ** 2) * max_damping
    return sigma_min, damping


@_jit
def damped_svd_thin(
    M: np.ndarray, epsilon: float, max_damping: float, rcond: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, float, float]:
    """:func:`damped_svd_factors` without the null directions: Vt (k, n) has only its first k = min(m, n) rows
    (on a wide M of few rows, a fraction of the full SVD's cost — the snake's 6 × 160 level, ~10 against ~100 µs).
    A wide M of at most :data:`JACOBI_SVD_MAX` rows takes the Jacobi SVD of Mᵀ (σ ≤ ``_WIDE_NULL``·‖M‖_F an
    exact zero, its row of Vt zero; measured 5.1 against 8.1 µs for LAPACK's thin SVD at 6×10, 9.1 against 17.3 at
    6×40, even at 6×160), anything else LAPACK's thin SVD."""
    m, n = M.shape
    fro2 = _frobenius2(M) if n > m and 0 < m <= JACOBI_SVD_MAX else math.inf
    if math.isfinite(fro2):  # wide, few rows: the Jacobi SVD of Mᵀ, as in _svd_wide
        Ut, s, Vtt = _svd_jacobi(np.ascontiguousarray(M.T))
        U, Vt = np.ascontiguousarray(Vtt.T), np.ascontiguousarray(Ut.T)
        floor = _WIDE_NULL * math.sqrt(fro2)
        for i in range(m):
            if not s[i] > floor:  # an exact zero, its row of Vt zero (Jacobi left that column unrotated)
                s[i] = 0.0
                Vt[i, :] = 0.0
    else:
        U, s, Vt = np.linalg.svd(np.ascontiguousarray(M), full_matrices=False)
    inv, rank = damped_inverse_values(s, epsilon, max_damping, rcond)
    sigma_min, damping = _damping_at(s, rank, epsilon, max_damping)
    return U, s, Vt, inv, rank, sigma_min, damping


@_jit
def factor(
    J: np.ndarray, epsilon: float, max_damping: float, rcond: float
) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, float, float]:
    """Factor J (m, n) for its damped pseudo-inverse.

    Returns:
        (fast, U, d, Vt, inv, rank, sigma_min, damping). Fast path: U (m, m) eigenvectors of JJᵀ, d (m,) its
        eigenvalues (ascending), inv = 1/d, Vt empty. SVD path: U (m, k), d = σ (k,) descending, Vt (n, n),
        inv the damped inverse values; damping = λ at σ_min (0 when no direction is damped).
    """
    m, n = J.shape
    if m == 0:
        return False, np.zeros((0, 0)), np.zeros(0), np.eye(n), np.zeros(0), 0, np.inf, 0.0
    if m <= n:
        A = np.empty((m, m))
        for i in range(m):  # JJᵀ (m, m), symmetric by construction
            for j in range(i, m):
                t = 0.0
                for k in range(n):
                    t += J[i, k] * J[j, k]
                A[i, j] = t
                A[j, i] = t
        lam, U = sym_eig(A)
        if lam[m - 1] > 0.0 and lam[0] > FAST_PATH_RCOND * lam[m - 1] and lam[0] >= epsilon * epsilon:
            return True, np.ascontiguousarray(U), lam, np.zeros((0, n)), 1.0 / lam, m, math.sqrt(lam[0]), 0.0
    U, s, Vt, inv, rank, sigma_min, damping = damped_svd_factors(J, epsilon, max_damping, rcond)
    return False, U, s, Vt, inv, rank, sigma_min, damping


@_jit
def _jt_ainv(J: np.ndarray, U: np.ndarray, inv: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Jᵀ U diag(inv) Uᵀ b = Jᵀ(JJᵀ)⁻¹ b (n,) from the eigenvectors U (m, m) of JJᵀ, in plain loops (small sizes:
    four BLAS calls would cost more than the arithmetic)."""
    m, n = J.shape
    y = np.zeros(m)
    for k in range(m):
        t = 0.0
        for i in range(m):
            t += U[i, k] * b[i]
        y[k] = t * inv[k]
    w = np.zeros(m)
    for i in range(m):
        t = 0.0
        for k in range(m):
            t += U[i, k] * y[k]
        w[i] = t
    out = np.zeros(n)
    for i in range(m):
        wi = w[i]
        for j in range(n):
            out[j] += J[i, j] * wi
    return out


@_jit
def solve_factored(
    fast: bool, J: np.ndarray, U: np.ndarray, inv: np.ndarray, Vt: np.ndarray, rhs: np.ndarray
) -> np.ndarray:
    """x = J⁺_λ rhs (n,) from the factors of :func:`factor`: Jᵀ U Λ⁻¹ Uᵀ rhs, or V_k diag(inv) U_kᵀ rhs."""
    if fast:
        return _jt_ainv(J, U, inv, rhs)
    k = inv.shape[0]
    n = J.shape[1]
    if k == 0:
        return np.zeros(n)
    return np.ascontiguousarray(Vt[:k].T) @ (inv * (U.T @ rhs))


@_jit
def null_project_factored(
    fast: bool, J: np.ndarray, U: np.ndarray, inv: np.ndarray, Vt: np.ndarray, rank: int, z: np.ndarray
) -> np.ndarray:
    """P_n z = (I − V_r V_rᵀ) z from the factors (on the fast path V_r V_rᵀ = J⁺J)."""
    if fast:
        m, n = J.shape
        Jz = np.zeros(m)
        for i in range(m):
            for j in range(n):
                Jz[i] += J[i, j] * z[j]
        return z - _jt_ainv(J, U, inv, Jz)
    if rank == 0:
        return z.copy()
    Vr = np.ascontiguousarray(Vt[:rank])
    return z - Vr.T @ (Vr @ z)


@_jit
def _chol_in_place(A: np.ndarray) -> bool:
    """A ← L (lower triangle) with A = L Lᵀ, unblocked; False when A is not numerically positive definite."""
    m = A.shape[0]
    for j in range(m):
        s = A[j, j]
        for k in range(j):
            s -= A[j, k] * A[j, k]
        if not (s > 0.0):
            return False
        ljj = math.sqrt(s)
        A[j, j] = ljj
        for i in range(j + 1, m):
            t = A[i, j]
            for k in range(j):
                t -= A[i, k] * A[j, k]
            A[i, j] = t / ljj
    return True


@_jit
def _chol_solve(L: np.ndarray, b: np.ndarray, y: np.ndarray) -> None:
    """y = (L Lᵀ)⁻¹ b from the lower factor L, into ``y`` (which may be ``b`` itself: each entry of b is read
    before it is overwritten)."""
    m = L.shape[0]
    for i in range(m):
        t = b[i]
        for k in range(i):
            t -= L[i, k] * y[k]
        y[i] = t / L[i, i]
    for i in range(m - 1, -1, -1):
        t = y[i]
        for k in range(i + 1, m):
            t -= L[k, i] * y[k]
        y[i] = t / L[i, i]


@_jit
def _cholesky_solve_rows(
    J: np.ndarray, V: np.ndarray, z: np.ndarray, has_z: bool, epsilon: float, out: np.ndarray
) -> bool:
    """out[0] = Jᵀ(JJᵀ)⁻¹V and out[1] = z − Jᵀ(JJᵀ)⁻¹Jz (eq. 5.7 and the projector of 5.8) by Cholesky, when
    JJᵀ − sI is positive definite with s = max(ε², FAST_PATH_RCOND·tr JJᵀ): then λ_min > ε² (no direction is
    damped) and λ_min/λ_max > FAST_PATH_RCOND, the conditions of :func:`factor`'s fast path. False (nothing
    written) otherwise."""
    m, n = J.shape
    buf = np.empty(2 * m * m + m)  # A = JJᵀ, its shifted copy S and a vector of m: one allocation
    A = buf[0 : m * m].reshape((m, m))
    S = buf[m * m : 2 * m * m].reshape((m, m))
    y = buf[2 * m * m :]
    tr = 0.0
    for i in range(m):
        for j in range(i, m):
            t = 0.0
            for k in range(n):
                t += J[i, k] * J[j, k]
            A[i, j] = t
            A[j, i] = t
        tr += A[i, i]
    if not (tr > 0.0 and math.isfinite(tr)):
        return False
    shift = max(epsilon * epsilon, FAST_PATH_RCOND * tr)
    for i in range(m):
        for j in range(m):
            S[i, j] = A[i, j]
        S[i, i] -= shift
    if not _chol_in_place(S) or not _chol_in_place(A):
        return False
    _chol_solve(A, V, y)
    for j in range(n):
        t = 0.0
        for i in range(m):
            t += J[i, j] * y[i]
        out[0, j] = t
    if has_z:
        w = y  # J z, then (JJᵀ)⁻¹ J z in place (y is read no more)
        for i in range(m):
            w[i] = 0.0
            for j in range(n):
                w[i] += J[i, j] * z[j]
        _chol_solve(A, w, w)
        for j in range(n):
            t = z[j]
            for i in range(m):
                t -= J[i, j] * w[i]
            out[1, j] = t
    else:
        out[1, :] = 0.0
    return True


@_jit
def closed_form_into(
    J: np.ndarray,
    V: np.ndarray,
    z: np.ndarray,
    has_z: bool,
    epsilon: float,
    max_damping: float,
    rcond: float,
    out: np.ndarray,
    lazy_sigma: bool = False,
) -> tuple[int, float, float]:
    """q̇_r = J⁺_λ V, q̇_n = (I − J⁺J) z (eq. 5.8) and q̇ = q̇_r + q̇_n written into ``out`` (3, n), in one call.

    q̇_n is zero when ``has_z`` is false. (Results go into a buffer the caller owns: returning arrays from a compiled
    call costs about a microsecond each.)

    With ``lazy_sigma`` a full-row-rank J whose JJᵀ passes the Cholesky test λ_min(JJᵀ) > max(ε², 1e-6·tr JJᵀ)
    (so :func:`factor` would take its fast path too, undamped) is solved as Jᵀ(JJᵀ)⁻¹ by Cholesky, without the
    eigendecomposition: σ_min is then returned as NaN, for the caller to compute when it is read.

    Returns:
        (rank, σ_min, damping).
    """
    n = J.shape[1]
    m = J.shape[0]
    if lazy_sigma and 0 < m <= n and _cholesky_solve_rows(J, V, z, has_z, epsilon, out):
        for i in range(n):
            out[2, i] = out[0, i] + out[1, i]
        return m, np.nan, 0.0
    fast, U, _, Vt, inv, rank, sigma_min, damping = factor(J, epsilon, max_damping, rcond)
    if J.shape[0] == 0:
        out[0, :] = 0.0
    else:
        out[0, :] = solve_factored(fast, J, U, inv, Vt, V)
    if has_z:
        out[1, :] = null_project_factored(fast, J, U, inv, Vt, rank, z)
    else:
        out[1, :] = 0.0
    for i in range(n):
        out[2, i] = out[0, i] + out[1, i]
    return rank, sigma_min, damping


@_jit
def closed_form(
    J: np.ndarray, V: np.ndarray, z: np.ndarray, has_z: bool, epsilon: float, max_damping: float, rcond: float
) -> tuple[np.ndarray, np.ndarray, int, float, float]:
    """:func:`closed_form_into` returning (q̇_r (n,), q̇_n (n,), rank, σ_min, damping)."""
    out = np.empty((3, J.shape[1]))
    rank, sigma_min, damping = closed_form_into(J, V, z, has_z, epsilon, max_damping, rcond, out)
    return out[0].copy(), out[1].copy(), rank, sigma_min, damping


@_jit
def closed_form_batch(
    J: np.ndarray, V: np.ndarray, z: np.ndarray, has_z: bool, epsilon: float, max_damping: float, rcond: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`closed_form` for N problems: J (N, m, n), V (N, m), z (N, n).

    Returns:
        (q̇_r (N, n), q̇_n (N, n), rank (N,), σ_min (N,), damping (N,)), each problem solved exactly as
        :func:`closed_form` solves it alone.
    """
    N, _, n = J.shape
    dq_r = np.empty((N, n))
    dq_n = np.empty((N, n))
    rank = np.empty(N, dtype=np.int64)
    smin = np.empty(N)
    damp = np.empty(N)
    buf = np.empty((3, n))
    for i in range(N):
        r, s, d = closed_form_into(
            np.ascontiguousarray(J[i]), V[i].copy(), z[i].copy(), has_z, epsilon, max_damping, rcond, buf
        )
        dq_r[i] = buf[0]
        dq_n[i] = buf[1]
        rank[i], smin[i], damp[i] = r, s, d
    return dq_r, dq_n, rank, smin, damp


@_jit
def gram_diagonal_matches(F: np.ndarray, shift: float, diag: np.ndarray, rtol: float) -> bool:
    """diag(FᵀF) + shift equals ``diag`` to ``rtol`` relative (NumPy's ``allclose`` rule, |a − b| ≤ atol + rtol |b|,
    with atol = 1e-12·max|diag(FᵀF) + shift|, at least 1e-12): the test that a weighted QP's Hessian is the one its
    rows FᵀF + δI make (``wqp``'s lifted factor), in one pass."""
    m, n = F.shape
    if diag.shape[0] != n:
        return False
    g = np.empty(n)
    big = 1.0
    for j in range(n):
        t = shift
        for i in range(m):
            t += F[i, j] * F[i, j]
        g[j] = t
        if abs(t) > big or t != t:
            big = abs(t)
    atol = 1e-12 * big
    for j in range(n):
        if not abs(g[j] - diag[j]) <= atol + rtol * abs(diag[j]):
            return False
    return True


@_jit
def squares_below(q: np.ndarray, bound2: float) -> bool:
    """qᵀq < ``bound2``: False for a NaN or infinite entry, and for entries whose squares overflow (a huge q).
    ``Resolver.step``'s check of q on every tick (one compiled call: in the control loop's cold caches the
    ``math.hypot(*q.tolist())`` it replaces cost 2.9 µs of a 44 µs Panda ``pinv`` step, this 0.9)."""
    acc = 0.0
    for i in range(q.shape[0]):
        acc += q[i] * q[i]
    return acc < bound2


@_jit
def in_box(x: np.ndarray, lb: np.ndarray, ub: np.ndarray, tol: float) -> bool:
    """True when lb − tol ≤ x ≤ ub + tol elementwise."""
    for i in range(x.shape[0]):
        if x[i] < lb[i] - tol or x[i] > ub[i] + tol:
            return False
    return True


@_jit
def coupled_coordinates(P: np.ndarray, idx: np.ndarray, lower: bool) -> int:
    """The coupled coordinates of P (n, n), written in ascending order into ``idx[:n_c]``; returns n_c.

    Coordinate i is separable when P_ii > 0 and the off-diagonal entries of row i and column i of P are zero (a NaN
    counts as non-zero), coupled otherwise: its part of ½xᵀPx + qᵀx is then ½P_ii x_i² + q_i x_i, decoupled from
    the rest of any problem in P (Talos's legs, head and grippers under a posture and two hand tasks: 16 of its 38
    coordinates). With ``lower`` only the lower triangle is read — P_ij for j < i and P_ki for k > i, the entries
    a Cholesky factorisation reads of a symmetric P (:func:`spd_solve_into`) —, else both triangles (daqp's split of
    bounds-only QPs, :func:`split_separable`). The one implementation of this test.

    Cost: the scan of a row stops at its first off-diagonal non-zero (one or two reads per row of a dense P), a
    separable coordinate takes n − 1 reads (2(n − 1) without ``lower``): ≈ 0.03 µs on the Panda's P (9 × 9),
    0.85 µs on Talos's (38 × 38, lower) on this machine.
    """
    n = P.shape[0]
    nc = 0
    for i in range(n):
        coupled = not P[i, i] > 0.0
        if not coupled:
            for j in range(i):
                if P[i, j] != 0.0:
                    coupled = True
                    break
        if not coupled:
            for k in range(i + 1, n):
                if P[k, i] != 0.0:
                    coupled = True
                    break
        if not coupled and not lower:
            for j in range(i + 1, n):
                if P[i, j] != 0.0:
                    coupled = True
                    break
            if not coupled:
                for k in range(i):
                    if P[k, i] != 0.0:
                        coupled = True
                        break
        if coupled:
            idx[nc] = i
            nc += 1
    return nc


@_jit
def _all_finite(x: np.ndarray) -> bool:
    """True when every entry of x is finite."""
    ok = True
    for i in range(x.shape[0]):
        if not math.isfinite(x[i]):
            ok = False
    return ok


@_jit
def _cholesky_solve_neg(L: np.ndarray, q: np.ndarray, x: np.ndarray) -> None:
    """x = −(L Lᵀ)⁻¹ q from a lower factor L (LAPACK's)."""
    n = q.shape[0]
    y = np.empty(n)
    for i in range(n):  # L y = −q
        t = -q[i]
        for k in range(i):
            t -= L[i, k] * y[k]
        y[i] = t / L[i, i]
    for i in range(n - 1, -1, -1):  # Lᵀ x = y
        t = y[i]
        for k in range(i + 1, n):
            t -= L[k, i] * x[k]
        x[i] = t / L[i, i]


@_jit
def _spd_solve_full(P: np.ndarray, q: np.ndarray, x: np.ndarray, buf: np.ndarray) -> bool:
    """:func:`spd_solve_into` by a Cholesky factorisation of the whole of P (no separable coordinate, or the split
    solve failed); ``buf`` (≥ 2n + n², or 2n beyond :data:`CHOLESKY_LOOPS_MAX`) is scratch: y in buf[n:2n],
    the factor's rows from buf[2n] on."""
    n = q.shape[0]
    o = 2 * n
    if n > CHOLESKY_LOOPS_MAX:
        try:
            L = np.linalg.cholesky(P)
        except Exception:  # not positive definite
            x[:] = 0.0
            return False
        _cholesky_solve_neg(L, q, x)
        return _all_finite(x)
    L = buf[o : o + n * n].reshape((n, n))  # (only its lower triangle is written and read)
    y = buf[n:o]
    for j in range(n):
        s = P[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not (s > 0.0):
            x[:] = 0.0
            return False
        ljj = math.sqrt(s)
        L[j, j] = ljj
        for i in range(j + 1, n):
            t = P[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / ljj
    for i in range(n):  # L y = −q
        t = -q[i]
        for k in range(i):
            t -= L[i, k] * y[k]
        y[i] = t / L[i, i]
    for i in range(n - 1, -1, -1):  # Lᵀ x = y
        t = y[i]
        for k in range(i + 1, n):
            t -= L[k, i] * x[k]
        x[i] = t / L[i, i]
    return _all_finite(x)


@_jit
def _spd_solve_split(P: np.ndarray, q: np.ndarray, nc: int, x: np.ndarray, buf: np.ndarray) -> bool:
    """:func:`spd_solve_into` with the coupled coordinates buf[:nc] (:func:`coupled_coordinates`, stored as floats)
    solved by a Cholesky factorisation of their block P_cc alone, and each separable one as x_i = (−q_i/√P_ii)/√P_ii;
    false (x then undefined) when P_cc is not numerically SPD or x is not finite. ``buf`` (≥ 2n + n_c², or 2n beyond
    :data:`CHOLESKY_LOOPS_MAX`) is scratch:
    y in buf[n:n + n_c], the factor's rows from buf[2n] on.

    With n_c ≤ :data:`CHOLESKY_LOOPS_MAX` the arithmetic is the full factorisation's minus its exact zeros: the
    factor of P is zero off the diagonal in a separable row and column (every entry there is (0 − Σ 0·ℓ)/ℓ_jj), so
    the full loops only add and subtract exact zeros outside P_cc's factor and compute x_i as (−q_i/ℓ_ii)/ℓ_ii with
    ℓ_ii = √P_ii — the same x, bit for bit, whenever the answer is finite (every factor entry is then finite or, on
    the diagonal, only a divisor).
    """
    n = q.shape[0]
    o = 2 * n
    k = 0
    for i in range(n):  # the separable coordinates
        if k < nc and int(buf[k]) == i:
            k += 1
            continue
        lii = math.sqrt(P[i, i])
        x[i] = (-q[i] / lii) / lii
        if not math.isfinite(x[i]):
            return False
    if nc == 0:
        return True
    if nc > CHOLESKY_LOOPS_MAX:
        Pc = np.empty((nc, nc))
        qc = np.empty(nc)
        for a in range(nc):
            qc[a] = q[int(buf[a])]
            for b in range(nc):
                Pc[a, b] = P[int(buf[a]), int(buf[b])]
        try:
            L = np.linalg.cholesky(Pc)
        except Exception:  # not positive definite
            return False
        xc = np.empty(nc)
        _cholesky_solve_neg(L, qc, xc)
        if not _all_finite(xc):
            return False
        for a in range(nc):
            x[int(buf[a])] = xc[a]
        return True
    L = buf[o : o + nc * nc].reshape((nc, nc))  # (only its lower triangle is written and read)
    y = buf[n : n + nc]
    for b in range(nc):
        j = int(buf[b])
        s = P[j, j]
        for k in range(b):
            s -= L[b, k] * L[b, k]
        if not (s > 0.0):
            return False
        lbb = math.sqrt(s)
        L[b, b] = lbb
        for a in range(b + 1, nc):
            t = P[int(buf[a]), j]
            for k in range(b):
                t -= L[a, k] * L[b, k]
            L[a, b] = t / lbb
    for a in range(nc):  # L y = −q_c
        t = -q[int(buf[a])]
        for k in range(a):
            t -= L[a, k] * y[k]
        y[a] = t / L[a, a]
    for a in range(nc - 1, -1, -1):  # Lᵀ x_c = y, in place
        t = y[a]
        for k in range(a + 1, nc):
            t -= L[k, a] * y[k]
        t /= L[a, a]
        if not math.isfinite(t):
            return False
        y[a] = t
    for a in range(nc):
        x[int(buf[a])] = y[a]
    return True


@_jit
def spd_solve_into(P: np.ndarray, q: np.ndarray, x: np.ndarray) -> bool:
    """x = −P⁻¹ q by Cholesky into ``x`` (P (n, n) symmetric positive definite, its lower triangle read); false when
    P is not numerically SPD (x is then zero) or x is not finite.

    The separable coordinates of P (:func:`coupled_coordinates`) are solved in closed form and only the coupled
    block is factored (``_spd_solve_split``: the same x, bit for bit, for n_c ≤ :data:`CHOLESKY_LOOPS_MAX`;
    measured per call on the benchmark's ``wqp`` steps, detection included: Talos, 22 of 38 coordinates coupled,
    5.2 → 2.4 µs; the Panda, 7 of 9, 0.38 → 0.34 µs; a dense P (the snake, n = 160) unchanged); when that solve
    fails, or no coordinate is separable, the whole of P is factored, so that every failure (non-finite data, P not
    SPD) is the full factorisation's, x included.

    Unblocked loops up to :data:`CHOLESKY_LOOPS_MAX` coordinates (measured 6.2 vs 9.4 µs at n = 38, 30 vs 21 at
    n = 64), LAPACK ``dpotrf`` (``np.linalg.cholesky``) above.
    """
    n = q.shape[0]
    m = min(n, CHOLESKY_LOOPS_MAX)  # (a larger block is factored by LAPACK, into its own array)
    buf = np.empty(2 * n + m * m)  # (one scratch allocation: the coupled indices, y and the factor)
    nc = coupled_coordinates(P, buf, True)
    if nc < n and _spd_solve_split(P, q, nc, x, buf):
        return True
    return _spd_solve_full(P, q, x, buf)


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
def clip_twice(x: np.ndarray, lb: np.ndarray, ub: np.ndarray, out: np.ndarray) -> None:
    """x projected onto lb ≤ x ≤ ub, written into both rows of ``out`` (2, n): a step's q̇ and the copy the resolver
    keeps (its warm start and rate-limit reference), in one call."""
    for i in range(x.shape[0]):
        v = min(max(x[i], lb[i]), ub[i])
        out[0, i] = v
        out[1, i] = v


@_jit
def spd_solve(P: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, bool]:
    """x = −P⁻¹ q by Cholesky (:func:`spd_solve_into`); ``ok`` false when P is not numerically SPD."""
    x = np.empty(q.shape[0])
    ok = spd_solve_into(P, q, x)
    return x, ok


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


def first_run_cost() -> dict[str, float]:
    """Seconds each kernel takes on its first call in this process (JIT compile, or loading the on-disk cache).

    Calls every kernel on tiny inputs; later calls are the steady-state cost. Reported by the benchmark.
    """
    out: dict[str, float] = {}
    J = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 0.25]])
    z = np.ones(3)
    t0 = time.perf_counter()
    closed_form(J, np.ones(2), z, True, 1e-2, 5e-2, 1e-10)
    out["closed_form"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    closed_form_batch(J[None], np.ones((1, 2)), z[None], True, 1e-2, 5e-2, 1e-10)
    out["closed_form_batch"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    P = np.eye(3)[None] * 2.0
    spd_solve_batch(P, np.ones((1, 3)), -np.ones((1, 3)), np.ones((1, 3)), 0.0)
    out["spd_solve_batch"] = time.perf_counter() - t0
    return out


@_jit
def limit_box(
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
) -> None:
    """The joint-limit box of :meth:`redundik.resolvers.qp.limits.JointLimits.box` for N configurations q (N, nq).

    ``iq`` (nv,) maps each q̇ coordinate to its q index, ``lo``/``hi`` (nv,) are the position limits (±inf where
    none), ``vmax``/``amax`` (nv,) the velocity and rate limits (inf where none), ``gain`` the position gain g;
    ``dq_prev`` (N, nv) is the previous q̇ (zero rows: no rate window). The rules are those of the limits module's
    docstring (position through dt, velocity, braking with a rate limit, the way back from outside, the rate
    window moved onto the nearest feasible velocity).

    Writes (lb, ub, pos_lo, pos_hi) into ``out`` (4, N, nv).
    """
    N = q.shape[0]
    nv = lo.shape[0]
    lb, ub, pl, pu = out[0], out[1], out[2], out[3]
    g = gain / dt
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
def wqp_free_step(
    P: np.ndarray,
    q: np.ndarray,
    shift: float,
    z: np.ndarray,
    z_scale: float,
    qconf: np.ndarray,
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
) -> bool:
    """The rest of a ``wqp`` step once its task rows are in P and q, in one call: P += shift·I, q −= z_scale·z (the
    null-space objective; ``z`` may be empty), the joint-limit box of :func:`limit_box` at ``qconf`` (nq,) into
    out[0:4] (lb, ub, pos_lo, pos_hi), the unconstrained optimum x = −P⁻¹q by Cholesky into out[4], and — when x
    lies in the box (to 1e-12) — x clipped to it into out[5] and out[6] (q̇ and the copy the resolver keeps).

    Returns:
        True when x is finite and inside the box: it is then the QP's optimum (no constraint active).
    """
    n = q.shape[0]
    for i in range(n):
        P[i, i] += shift
    if z.shape[0] == n and z_scale != 0.0:
        for i in range(n):
            q[i] -= z_scale * z[i]
    nq = qconf.shape[0]
    limit_box(
        qconf.reshape((1, nq)),
        iq,
        lo,
        hi,
        vmax,
        amax,
        position,
        has_rate,
        gain,
        dt,
        dq_prev,
        out[0:4].reshape((4, 1, n)),
    )
    x = out[4]
    if not spd_solve_into(P, q, x) or not in_box(x, out[0], out[1], 1e-12):
        return False
    for i in range(n):
        v = min(max(x[i], out[0, i]), out[1, i])
        out[5, i] = v
        out[6, i] = v
    return True


@_jit
def gram_update(P: np.ndarray, q: np.ndarray, J: np.ndarray, v: np.ndarray, w: float, reset: bool) -> None:
    """P += w JᵀJ and q −= w Jᵀv in place (P (n, n), q (n,), J (m, n), v (m,)): one task's rows of a weighted QP;
    ``reset``: P and q are zeroed first (the first task of a step)."""
    m, n = J.shape
    if reset:
        P[:, :] = 0.0
        q[:] = 0.0
    for a in range(m):
        va = w * v[a]
        for i in range(n):
            ji = w * J[a, i]
            if ji != 0.0:
                q[i] -= J[a, i] * va
                for j in range(n):
                    P[i, j] += ji * J[a, j]


@_jit
def lsq_level(
    A: np.ndarray,
    b: np.ndarray,
    x: np.ndarray,
    Z: np.ndarray,
    projected: bool,
    epsilon: float,
    max_damping: float,
    rcond: float,
    x_out: np.ndarray,
) -> tuple[np.ndarray, float, float, int]:
    """One least-squares level of ``hqp``'s closed-form cascade over q̇ = x + Z u (Z = I when not ``projected``).

    u = (A Z)⁺_λ (b − A x) by the damped SVD of A Z (:func:`damped_svd_factors`), x_out ← x + Z u, and the basis of
    the directions that keep this level at its optimum, Z·null(A Z).

    Returns:
        (the new basis (n, r'), σ_min, damping, rank of A Z).
    """
    M = A @ Z if projected else A
    if M.shape[0] == 0 or M.shape[1] == 0:  # no rows, or no directions left: nothing to solve, the basis stays
        x_out[:] = x
        return (Z.copy() if projected else np.eye(M.shape[1])), np.inf, 0.0, 0
    rhs = b - A @ x
    U, _, Vt, inv, rank, sigma_min, damping = damped_svd_factors(M, epsilon, max_damping, rcond)
    k = inv.shape[0]
    u = np.ascontiguousarray(Vt[:k].T) @ (inv * (U.T @ rhs)) if k else np.zeros(M.shape[1])
    null = np.ascontiguousarray(Vt[rank:].T)
    if projected:
        x_out[:] = x + Z @ u
        return np.ascontiguousarray(Z @ null), sigma_min, damping, rank
    x_out[:] = u
    return null, sigma_min, damping, rank

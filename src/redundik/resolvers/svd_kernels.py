"""Compiled eigen- and singular-value decompositions (numba) of the small matrices of a step: the Jacobi routines
(symmetric eigenproblem, one-sided SVD, the wide SVD through the transpose and a Householder completion) and LAPACK
beyond the sizes where they win. The damping rule built on them is :mod:`redundik.resolvers.damping_kernels`."""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.resolvers.qr_kernels import _complete_rows

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

#: Largest symmetric matrix (m, m) whose eigendecomposition uses the Jacobi routine below, and the largest number of
#: columns of a tall matrix whose SVD does; LAPACK beyond, where its call's overhead no longer outweighs Jacobi's
#: extra sweeps (measured inside compiled code: the Jacobi eigensolver is faster at m = 3, slower at m = 6; the
#: Jacobi SVD faster for a 7×3 matrix, slower for a 6×9).
JACOBI_EIG_MAX = 4
JACOBI_SVD_MAX = 8
#: Widest matrix (m ≤ :data:`JACOBI_SVD_MAX` rows) whose full SVD is the Jacobi SVD of its transpose plus a Householder
#: completion of the null directions (``_svd_wide``); LAPACK beyond. Measured inside compiled code, it is faster
#: than ``np.linalg.svd`` up to this width; the completion's O(r n (n − r)) makes it lose beyond (the thin SVD,
#: without the completion, stays faster at larger widths: ``damped_svd_thin``).
JACOBI_WIDE_MAX = 24
#: Singular values of a wide matrix at or below this fraction of ‖M‖_F are exact zeros in ``_svd_wide`` (their
#: right singular vectors are the completion): far below any rank tolerance (``RCOND`` = 1e-10 of σ_max).
_WIDE_NULL = 1e-14
_JACOBI_TOL = 1e-15
_JACOBI_SWEEPS = 60


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

"""Compiled Householder reflections (numba): the reflectors of a block and the orthonormal completion of a set of
rows, used by the wide SVD of :mod:`redundik.resolvers.svd_kernels` (and ``hqp``'s level assembly)."""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)


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

"""An ``hqp`` level whose rows are some rows of the identity with one weight (a posture on some joints,
``PostureTask(joints=...)``), solved from the few rows it leaves out.

Over the orthonormal basis Z (n, r) of the levels above, such a level's matrix is M = √w S Z: the rows ``cols`` of Z.
Its Gram matrix is MᵀM = w (I − Z_cᵀ Z_c), Z_c the c = n − m rows of Z it leaves out (a floating base's six). So
the right singular vectors of M are those of Z_c (a thin c × r SVD instead of M's m × r one) with σ_i = ‖M v_i‖,
and every direction Z_c does not see has σ = √w. The damped least squares u = Σ v_i (d_i/σ_i) v_iᵀ Mᵀ(rhs), d_i the
damped inverse values of :mod:`redundik.resolvers.linalg` over all r values, then takes O(m r) work. Computed as a
norm, a σ that is zero in exact arithmetic comes out at rounding size, and the rule truncates it as it would the
SVD's.
"""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.resolvers.damping_kernels import damped_inverse_values, damped_svd_thin

_jit = _kernel_cache.jit

__all__ = ["selection_columns", "selection_solve"]

#: The most rows a level may leave out for :func:`selection_solve` (the thin SVD of Z_c is then a Jacobi one).
MAX_LEFT_OUT = 8


@_jit
def selection_columns(A: np.ndarray, w: np.ndarray, s: int, m: int, cols: np.ndarray) -> bool:
    """True when the rows A[s:s + m] are rows of the identity at strictly increasing columns with one weight w[s] > 0,
    leaving out between 1 and :data:`MAX_LEFT_OUT` of the n columns; those columns into cols[:m]."""
    n = A.shape[1]
    w0 = w[s]
    if not (w0 > 0.0) or not (0 < n - m <= MAX_LEFT_OUT) or m == 0:
        return False
    last = -1
    for i in range(m):
        if w[s + i] != w0:
            return False
        c = -1
        for j in range(n):
            a = A[s + i, j]
            if a == 1.0 and c < 0:
                c = j
            elif a != 0.0:
                return False
        if c <= last:  # (no 1.0 in the row, or columns not increasing)
            return False
        cols[i] = c
        last = c
    return True


@_jit
def selection_solve(
    M: np.ndarray, Z: np.ndarray, cols: np.ndarray, rhs: np.ndarray, sqrt_w: float, eps_k: float, lam_k: float,
    rcond: float, u: np.ndarray,
) -> tuple[np.ndarray, int, float, float]:  # fmt: skip
    """``hqp_kernels._svd_solve`` for M = √w Z[cols, :r] (m, r), √w = ``sqrt_w``: M⁺_λ rhs into u (r,) by the damping
    rule, and (null(M) (r, r − rank), rank, σ_min, λ) — from the thin SVD of Z's other rows (module docstring).
    Rank −1, nothing written: M or Z is not finite (the caller's SVD route then says where a NaN came from)."""
    m, r = M.shape
    n = Z.shape[0]
    c = n - m
    for row in range(n):
        for j in range(r):
            if not math.isfinite(Z[row, j]) or (row < m and not math.isfinite(M[row, j])):
                return np.zeros((r, 0)), -1, np.nan, np.nan
    Zc = np.empty((c, r))
    a, i = 0, 0
    for row in range(n):
        if a < m and cols[a] == row:
            a += 1
            continue
        for j in range(r):
            Zc[i, j] = Z[row, j]
        i += 1
    Vc = damped_svd_thin(Zc, 0.0, 0.0, 0.0)[2]  # (k, r): Z_c's right singular vectors (a zero row: none there)
    k = Vc.shape[0]
    g = np.zeros(r)  # Mᵀ rhs
    for row in range(m):
        x = rhs[row]
        if x != 0.0:
            for j in range(r):
                g[j] += M[row, j] * x
    sig = np.zeros(k)
    seen = np.zeros(k, np.bool_)  # a direction of Z_c (a nonzero row of Vc)
    for d in range(k):
        norm2 = 0.0
        for j in range(r):
            norm2 += Vc[d, j] * Vc[d, j]
        if norm2 > 0.5:
            seen[d] = True
            total = 0.0
            for row in range(m):
                y = 0.0
                for j in range(r):
                    y += M[row, j] * Vc[d, j]
                total += y * y
            sig[d] = math.sqrt(total)
    nseen = 0
    for d in range(k):
        nseen += seen[d]
    free = r - nseen  # the directions Z_c does not see: σ = √w
    values = np.empty(r)  # every σ, descending: the free ones, then Z_c's in decreasing σ
    order = np.argsort(-sig, kind="mergesort")
    for p in range(free):
        values[p] = sqrt_w
    p = free
    for d in order:
        if seen[d]:
            values[p] = sig[d]
            p += 1
    inv, rank = damped_inverse_values(values, eps_k, lam_k, rcond)
    proj = np.zeros(k)  # v_dᵀ g
    for d in range(k):
        if seen[d]:
            acc = 0.0
            for j in range(r):
                acc += Vc[d, j] * g[j]
            proj[d] = acc
    coef_free = inv[0] / sqrt_w if free > 0 and sqrt_w > 0.0 else 0.0
    for j in range(r):  # the free part: (g minus its parts on Z_c's directions), scaled by d/σ = d_free/√w
        x = g[j]
        for d in range(k):
            if seen[d]:
                x -= Vc[d, j] * proj[d]
        u[j] = coef_free * x
    N = np.zeros((r, r - rank))
    p, col = free, 0
    for d in order:
        if not seen[d]:
            continue
        if p < rank:  # kept (damped or not): d_p/σ_p along v_d
            f = inv[p] / values[p]
            for j in range(r):
                u[j] += Vc[d, j] * f * proj[d]
        else:  # truncated: a null direction left to the levels below
            for j in range(r):
                N[j, col] = Vc[d, j]
            col += 1
        p += 1
    sigma_min = values[rank - 1] if rank else np.inf
    damping = 0.0
    if rank and sigma_min < eps_k and eps_k > 0.0:  # (the rule's λ at σ_min, as damped_svd_factors gives it)
        damping = math.sqrt(1.0 - (sigma_min / eps_k) ** 2) * lam_k
    return N, rank, sigma_min, damping

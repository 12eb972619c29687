"""Compiled damped inverses (numba): the damping rule of :mod:`redundik.resolvers.linalg` (per-direction
σ/(σ² + λ²), λ² = (1 − (σ/ε)²)·λ_max², truncation below rcond·σ_max) applied to the SVD, the factorisation behind
J⁺ (the fast path Jᵀ(JJᵀ)⁻¹ from the eigendecomposition of JJᵀ when J has full row rank and is well conditioned,
else the damped SVD), J⁺_λ b and (I − V_r V_rᵀ) z from those factors, and one least-squares level of ``hqp``'s
closed-form cascade."""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.resolvers.svd_kernels import (
    _WIDE_NULL,
    JACOBI_SVD_MAX,
    _frobenius2,
    _svd_jacobi,
    svd_full,
    sym_eig,
)

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

#: Smallest λ_min/λ_max of JJᵀ for the eigendecomposition fast path (κ(J) ≤ 1e3).
FAST_PATH_RCOND = 1e-6


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
def _all_finite(M: np.ndarray) -> bool:
    """Whether every entry of the matrix M is finite."""
    m, n = M.shape
    for i in range(m):
        for j in range(n):
            if not math.isfinite(M[i, j]):
                return False
    return True


@_jit
def damped_svd_factors(
    M: np.ndarray, epsilon: float, max_damping: float, rcond: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, float, float]:
    """The damped SVD of M (m, n), m ≥ 1: (U_k (m, k), σ (k,), Vt (n, n), inverse values, rank, σ_min, damping).

    damping = λ at σ_min, √(1 − (σ_min/ε)²)·λ_max, when σ_min < ε (else 0); σ_min = ∞ when M = 0. A non-finite M
    (a NaN row from a task or potential) has no SVD: NaN factors (rank 0, σ_min and damping NaN), so that what is
    solved with them is NaN and the resolver's diagnosed fallback names the row, instead of an exception.
    """
    if not _all_finite(M):
        m, n = M.shape
        k = min(m, n)
        return np.full((m, k), np.nan), np.full(k, np.nan), np.eye(n), np.full(k, np.nan), 0, np.nan, np.nan
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
    (on a wide M of few rows, a fraction of the full SVD's cost). A wide M of at most :data:`JACOBI_SVD_MAX` rows
    takes the Jacobi SVD of Mᵀ (σ ≤ ``_WIDE_NULL``·‖M‖_F an exact zero, its row of Vt zero; measured faster than
    LAPACK's thin SVD at such shapes, up to 6×160), anything else LAPACK's thin SVD."""
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

    The fast path — J of full row rank with λ_min/λ_max of JJᵀ above ``FAST_PATH_RCOND`` (and rcond²), so that
    every direction is kept — takes the eigendecomposition of JJᵀ alone, damped or not: Jᵀuᵢ = σᵢvᵢ, so
    J⁺_λ = Jᵀ U diag(1/(σᵢ² + λᵢ²)) Uᵀ (λᵢ = 0 for σᵢ ≥ ε) and J⁺J = Jᵀ U diag(1/σᵢ²) Uᵀ J. Anything else (a
    rank-deficient or ill-conditioned J, more rows than columns, a non-finite J) takes the damped SVD.

    Returns:
        (fast, U, d, Vt, inv, rank, sigma_min, damping). Fast path: U (m, m) eigenvectors of JJᵀ, d (m,) its
        eigenvalues σᵢ² (ascending), inv = 1/(σᵢ² + λᵢ²), Vt empty. SVD path: U (m, k), d = σ (k,) descending,
        Vt (n, n), inv the damped inverse values σ/(σ² + λ²); damping = λ at σ_min (0 when no direction is
        damped). :func:`null_project_factored` takes d (the projector is undamped), :func:`solve_factored` inv.
    """
    m, n = J.shape
    if m == 0:
        return False, np.zeros((0, 0)), np.zeros(0), np.eye(n), np.zeros(0), 0, np.inf, 0.0
    if m <= n and _all_finite(J):  # (a non-finite J: the NaN factors of damped_svd_factors)
        A = np.empty((m, m))
        for i in range(m):  # JJᵀ (m, m), symmetric by construction
            for j in range(i, m):
                t = 0.0
                for k in range(n):
                    t += J[i, k] * J[j, k]
                A[i, j] = t
                A[j, i] = t
        lam, U = sym_eig(A)
        if lam[m - 1] > 0.0 and lam[0] > max(FAST_PATH_RCOND, rcond * rcond) * lam[m - 1]:  # every direction kept
            if lam[0] >= epsilon * epsilon:  # none damped: Jᵀ(JJᵀ)⁻¹
                return True, np.ascontiguousarray(U), lam, np.zeros((0, n)), 1.0 / lam, m, math.sqrt(lam[0]), 0.0
            # some damped (σ_i < ε): J⁺_λ = V diag(σ/(σ² + λ²)) Uᵀ = Jᵀ U diag(1/(σ² + λ²)) Uᵀ, as Jᵀuᵢ = σᵢvᵢ
            inv = np.empty(m)
            damp = epsilon > 0.0 and max_damping > 0.0
            for i in range(m):
                lam2 = (1.0 - lam[i] / (epsilon * epsilon)) * max_damping * max_damping if damp else 0.0
                inv[i] = 1.0 / (lam[i] + max(lam2, 0.0))
            sigma_min = math.sqrt(lam[0])
            damping = math.sqrt(1.0 - lam[0] / (epsilon * epsilon)) * max_damping if epsilon > 0.0 else 0.0
            return True, np.ascontiguousarray(U), lam, np.zeros((0, n)), inv, m, sigma_min, damping
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
    fast: bool, J: np.ndarray, U: np.ndarray, d: np.ndarray, Vt: np.ndarray, rank: int, z: np.ndarray
) -> np.ndarray:
    """P_n z = (I − V_r V_rᵀ) z from the factors of :func:`factor` (its d: on the fast path the eigenvalues σᵢ² of
    JJᵀ, and V_r V_rᵀ = J⁺J = Jᵀ U diag(1/σᵢ²) Uᵀ J, undamped whatever the damping of the solve)."""
    if fast:
        m, n = J.shape
        Jz = np.zeros(m)
        for i in range(m):
            for j in range(n):
                Jz[i] += J[i, j] * z[j]
        return z - _jt_ainv(J, U, 1.0 / d, Jz)
    if rank == 0:
        return z.copy()
    Vr = np.ascontiguousarray(Vt[:rank])
    return z - Vr.T @ (Vr @ z)


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

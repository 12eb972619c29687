"""The compiled form of the chapter's state-feedback law for the subtask gains (section 5.2, after eq. 5.15; the
formulas are :mod:`redundik.resolvers.feedback`'s): from the main rows J, V, the null-space objective z and the target
subtasks' rows (N, ẏ_d + K(y_d − y)), the gains k and q̇ = J⁺V + P(N k + z), with the damping rules and factors of
``damping_kernels.factor`` and ``damped_svd_factors`` — the kernels the interpreted law calls.
"""

from __future__ import annotations

import numpy as np

from redundik import _kernel_cache
from redundik.resolvers.cholesky_kernels import _chol_solve
from redundik.resolvers.damping_kernels import damped_svd_factors, factor, null_project_factored, solve_factored
from redundik.resolvers.kernels import gram_cholesky
from redundik.resolvers.layouts import (
    FB_D_DAMPING,
    FB_D_EPSILON,
    FB_D_RANK,
    FB_DAMPING,
    FB_DQ,
    FB_EPSILON,
    FB_J_RANK,
    FB_MAX_DAMPING,
    FB_NULL,
    FB_RANK,
    FB_RCOND,
    FB_SIGMA_MIN,
)

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)


@_jit
def feedback_law(
    J: np.ndarray,
    V: np.ndarray,
    z: np.ndarray,
    has_z: bool,
    Nt: np.ndarray,
    rhs: np.ndarray,
    settings: np.ndarray,
    out: np.ndarray,
    gains: np.ndarray,
    report: np.ndarray,
) -> None:
    """k = D⁻¹[ẏ_d + K(y_d − y) − NᵀJ⁺V − NᵀP z] with D = NᵀPN, and q̇ = J⁺V + P(N k + z) (eq. 5.15 and the law
    after it, P = I − J⁺J): J⁺ damped by ``settings`` (ε, λ_max, rcond), D by d_ε·‖N‖_F² (scale-free). A
    well-conditioned J (``kernels.gram_cholesky``: no direction damped) is solved as Jᵀ(JJᵀ)⁻¹ by Cholesky, σ_min
    then reported as NaN (the caller computes it when it is read); otherwise ``factor``'s damped pseudo-inverse.

    Args:
        J, V: The main rows (m, n) and their right-hand side (m,).
        z: The null-space objective (n,), read when ``has_z``.
        Nt: The target subtasks' gradients η_i as rows (r, n); rhs: their ẏ_d + K(y_d − y) (r,).
        settings: ``layouts.FB_EPSILON`` … ``FB_D_EPSILON``.
        out: J⁺V, P(N k + z) and q̇ (``layouts.FB_ROWS``, n), written.
        gains: k (r,), written; report: ``layouts.FB_J_RANK`` … ``FB_D_DAMPING``, written.
    """
    m, n = J.shape
    r = Nt.shape[0]
    eps, lmax, rcond = settings[FB_EPSILON], settings[FB_MAX_DAMPING], settings[FB_RCOND]
    dq_r = out[FB_RANK]
    PN = np.empty((n, r))
    buf = np.empty(2 * m * m + m)
    if 0 < m <= n and gram_cholesky(J, eps, buf):  # well conditioned, undamped: J⁺ = Jᵀ(JJᵀ)⁻¹ by Cholesky
        L, y = buf[0 : m * m].reshape((m, m)), buf[2 * m * m :]
        _chol_solve(L, V, y)
        dq_r[:] = J.T @ y
        Pz = _cholesky_project(J, L, z, y) if has_z else np.zeros(n)
        for i in range(r):
            PN[:, i] = _cholesky_project(J, L, Nt[i], y)
        rank, smin, damping = m, np.nan, 0.0  # (σ_min: the caller computes it when it is read)
    else:
        fast, U, d, Vt, inv, rank, smin, damping = factor(J, eps, lmax, rcond)
        if m == 0:
            dq_r[:] = 0.0
        else:
            dq_r[:] = solve_factored(fast, J, U, inv, Vt, V)
        Pz = null_project_factored(fast, J, U, d, Vt, rank, z) if has_z else np.zeros(n)
        for i in range(r):
            PN[:, i] = null_project_factored(fast, J, U, d, Vt, rank, np.ascontiguousarray(Nt[i]))
    report[FB_J_RANK], report[FB_SIGMA_MIN], report[FB_DAMPING] = rank, smin, damping
    report[FB_D_RANK], report[FB_D_DAMPING] = 0.0, 0.0
    dq_n = out[FB_NULL]
    dq_n[:] = Pz
    if r > 0:
        D = np.ascontiguousarray(Nt @ PN)  # (r, r), symmetric positive semi-definite
        scale = 0.0
        for i in range(r):
            for j in range(n):
                scale += Nt[i, j] * Nt[i, j]
        d_eps = settings[FB_D_EPSILON] * scale
        Ud, s, Vtd, invd, d_rank, _, d_damping = damped_svd_factors(D, d_eps, d_eps, rcond)
        b = rhs - Nt @ dq_r - Nt @ Pz
        k = s.shape[0]
        if k == 0:
            gains[:] = 0.0
        else:
            gains[:] = np.ascontiguousarray(Vtd[:k].T) @ (invd * (Ud.T @ b))
        dq_n += PN @ gains
        report[FB_D_RANK], report[FB_D_DAMPING] = d_rank, d_damping
    out[FB_DQ] = dq_r + dq_n


@_jit
def _cholesky_project(J: np.ndarray, L: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(I − Jᵀ(JJᵀ)⁻¹J) x with L the Cholesky factor of JJᵀ (``y``: scratch of m)."""
    m, n = J.shape
    for i in range(m):
        t = 0.0
        for j in range(n):
            t += J[i, j] * x[j]
        y[i] = t
    _chol_solve(L, y, y)
    out = x.copy()
    for j in range(n):
        for i in range(m):
            out[j] -= J[i, j] * y[i]
    return out

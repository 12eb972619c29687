"""Compiled kernels (numba): the closed form of ``pinv``'s step, and the index of the resolvers' linear algebra.

Why compiled: through NumPy/SciPy, one ``pinv`` step's algebra would be about ten small-array calls (JJᵀ, an
eigendecomposition through LAPACK's wrapper, Jᵀ U Λ⁻¹, two solves), and at these sizes each call's overhead, not its
arithmetic, dominates; so the algebra is one compiled call. The kernels are compiled at first use and cached on disk
(``cache=True``); the first-run cost is reported by :func:`first_run_cost`.

Here: :func:`closed_form` — the chapter's q̇ = J⁺V + (I − J⁺J)z (eq. 5.8) in one call (``pinv``'s step) — and
:func:`closed_form_batch`, the same over N problems (the body of :mod:`redundik.resolvers.batch`). The other kernels
live by concern, one implementation each (nothing else in redundik computes these; the tests hold them to slow
references), and are re-exported here, so that the resolvers reach them all as ``K.<name>``:

* :mod:`redundik.resolvers.qr_kernels` — Householder reflections and the orthonormal completion of rows;
* :mod:`redundik.resolvers.svd_kernels` — the Jacobi eigen- and singular-value decompositions (LAPACK beyond);
* :mod:`redundik.resolvers.damping_kernels` — the damping rule (``damped_inverse_values``), the factorisation
  behind J⁺ (``factor``: the fast path Jᵀ(JJᵀ)⁻¹ when J has full row rank and is well conditioned, else the
  damped SVD), J⁺_λ b and (I − V_r V_rᵀ) z from those factors, one least-squares level of ``hqp``;
* :mod:`redundik.resolvers.cholesky_kernels` — x = −P⁻¹q with only P's coupled block factored, the weighted rows;
* :mod:`redundik.resolvers.box_kernels` — the joint-limit box, the box tests, ``wqp``'s unconstrained optimum in its
  box (one step, N problems), daqp's split of a bounds-only QP.

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
from redundik.kinematics.lie_kernels import batch_log3_small as batch_log3_small
from redundik.kinematics.lie_kernels import frame_error as frame_error
from redundik.kinematics.lie_kernels import frame_error_rp as frame_error_rp
from redundik.kinematics.lie_kernels import frame_jacobian_lwa as frame_jacobian_lwa
from redundik.resolvers.box_kernels import clip_twice as clip_twice
from redundik.resolvers.box_kernels import in_box as in_box
from redundik.resolvers.box_kernels import joint_box as joint_box
from redundik.resolvers.box_kernels import limit_box as limit_box
from redundik.resolvers.box_kernels import scaled_max as scaled_max
from redundik.resolvers.box_kernels import spd_solve_batch as spd_solve_batch
from redundik.resolvers.box_kernels import spd_solve_box as spd_solve_box
from redundik.resolvers.box_kernels import spd_solve_box_into as spd_solve_box_into
from redundik.resolvers.box_kernels import split_separable as split_separable
from redundik.resolvers.box_kernels import squares_below as squares_below
from redundik.resolvers.box_kernels import wqp_free_step as wqp_free_step
from redundik.resolvers.cholesky_kernels import CHOLESKY_LOOPS_MAX as CHOLESKY_LOOPS_MAX
from redundik.resolvers.cholesky_kernels import _chol_in_place, _chol_solve
from redundik.resolvers.cholesky_kernels import coupled_coordinates as coupled_coordinates
from redundik.resolvers.cholesky_kernels import gram_diagonal_matches as gram_diagonal_matches
from redundik.resolvers.cholesky_kernels import gram_update as gram_update
from redundik.resolvers.cholesky_kernels import spd_solve as spd_solve
from redundik.resolvers.cholesky_kernels import spd_solve_into as spd_solve_into
from redundik.resolvers.damping_kernels import FAST_PATH_RCOND
from redundik.resolvers.damping_kernels import damped_inverse_values as damped_inverse_values
from redundik.resolvers.damping_kernels import damped_svd_factors as damped_svd_factors
from redundik.resolvers.damping_kernels import damped_svd_thin as damped_svd_thin
from redundik.resolvers.damping_kernels import factor as factor
from redundik.resolvers.damping_kernels import lsq_level as lsq_level
from redundik.resolvers.damping_kernels import null_project_factored as null_project_factored
from redundik.resolvers.damping_kernels import solve_factored as solve_factored
from redundik.resolvers.qr_kernels import _reflect as _reflect
from redundik.resolvers.qr_kernels import householder_reflectors as householder_reflectors
from redundik.resolvers.svd_kernels import JACOBI_EIG_MAX as JACOBI_EIG_MAX
from redundik.resolvers.svd_kernels import JACOBI_SVD_MAX as JACOBI_SVD_MAX
from redundik.resolvers.svd_kernels import JACOBI_WIDE_MAX as JACOBI_WIDE_MAX
from redundik.resolvers.svd_kernels import svd_full as svd_full
from redundik.resolvers.svd_kernels import sym_eig as sym_eig

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)


@_jit
def gram_cholesky(J: np.ndarray, epsilon: float, buf: np.ndarray) -> bool:
    """The Cholesky factor L of JJᵀ (m, m) into ``buf[0 : m²]`` (lower triangle, row-major), when JJᵀ − sI is
    positive definite with s = max(ε², FAST_PATH_RCOND·tr JJᵀ): then λ_min > ε² (no direction is damped) and
    λ_min/λ_max > FAST_PATH_RCOND, the conditions of ``factor``'s fast path. False otherwise (``buf``, at least
    2m², is then scratch)."""
    m, n = J.shape
    A = buf[0 : m * m].reshape((m, m))
    S = buf[m * m : 2 * m * m].reshape((m, m))
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
    return _chol_in_place(S) and _chol_in_place(A)


@_jit
def _cholesky_solve_rows(
    J: np.ndarray, V: np.ndarray, z: np.ndarray, has_z: bool, epsilon: float, out: np.ndarray
) -> bool:
    """out[0] = Jᵀ(JJᵀ)⁻¹V and out[1] = z − Jᵀ(JJᵀ)⁻¹Jz (eq. 5.7 and the projector of 5.8) by Cholesky, when
    :func:`gram_cholesky` succeeds (``factor``'s fast path, undamped). False (nothing written) otherwise."""
    m, n = J.shape
    buf = np.empty(2 * m * m + m)  # A = JJᵀ, its shifted copy S and a vector of m: one allocation
    A = buf[0 : m * m].reshape((m, m))
    y = buf[2 * m * m :]
    if not gram_cholesky(J, epsilon, buf):
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
    (so ``factor`` would take its fast path too, undamped) is solved as Jᵀ(JJᵀ)⁻¹ by Cholesky, without the
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
    fast, U, d, Vt, inv, rank, sigma_min, damping = factor(J, epsilon, max_damping, rcond)
    if J.shape[0] == 0:
        out[0, :] = 0.0
    else:
        out[0, :] = solve_factored(fast, J, U, inv, Vt, V)
    if has_z:
        out[1, :] = null_project_factored(fast, J, U, d, Vt, rank, z)
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
    J: np.ndarray, V: np.ndarray, z: np.ndarray, has_z: bool, epsilon: float, max_damping: float, rcond: float,
    out: np.ndarray,
) -> None:  # fmt: skip
    """:func:`closed_form_into` for N problems — J (N, m, n), V (N, m), z (N, n) — each solved as the single ``pinv``
    step solves it (``lazy_sigma``: by Cholesky when J is well conditioned and undamped, else through ``factor``):
    ``out[i]`` (3, n) = (q̇_r, q̇_n, q̇) of problem i. The inputs are read, not written."""
    for i in range(J.shape[0]):
        closed_form_into(J[i], V[i], z[i], has_z, epsilon, max_damping, rcond, out[i], True)


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
    closed_form_batch(J[None], np.ones((1, 2)), z[None], True, 1e-2, 5e-2, 1e-10, np.empty((1, 3, 3)))
    out["closed_form_batch"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    P = np.eye(3)[None] * 2.0
    spd_solve_batch(P, np.ones((1, 3)), -np.ones((1, 3)), np.ones((1, 3)), 0.0)
    out["spd_solve_batch"] = time.perf_counter() - t0
    return out

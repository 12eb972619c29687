"""Compiled kernels (numba) of :class:`redundik.resolvers.batch.BatchResolver`: the N problems' frame placements,
base-aligned Jacobians and pose errors from the joint data Pinocchio computed, and ``wqp``'s P, q, unconstrained
optimum and box test, each in one loop over the problems (no whole-array intermediates).

The formulas are the single step's kernels, called per problem: ``lie_kernels.frame_jacobian_lwa`` and
``lie_kernels.frame_error_rp`` (the frame task), ``cholesky_kernels.gram_update`` (P and q of the task rows) and
``box_kernels.spd_solve_box_into`` (``wqp``'s optimum and its box test).
"""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.kinematics.lie_kernels import frame_error_rp, frame_jacobian_lwa
from redundik.resolvers.box_kernels import spd_solve_box_into
from redundik.resolvers.cholesky_kernels import gram_update

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

__all__ = ["WB_COEFS", "all_rigid", "frame_rows_batch", "wqp_box_batch"]

#: Entries of :func:`wqp_box_batch`'s ``coef``: the frame task's gain K [1/s], the posture's level weight ρ, 1.0 when
#: the stack has a posture (else 0.0), λ₀, the Levenberg–Marquardt factor of λ, the box test's tolerance.
WB_GAIN, WB_SCALE, WB_POSTURE, WB_DAMPING, WB_LM, WB_TOL = range(6)
WB_COEFS = 6


@_jit
def all_rigid(T: np.ndarray, gram_tol: float, last_tol: float) -> bool:
    """Whether every transform of T (N, 4, 4), finite, is rigid: R Rᵀ within ``gram_tol`` of I (each entry), det R
    > 0 and a last row within ``last_tol`` of (0, 0, 0, 1) — in one loop over the problems, stopping at the first
    that fails (``BatchResolver._check``'s test; det R by its cofactor expansion: with R Rᵀ that close to I,
    |det R| ≈ 1 and its sign is the LU determinant's)."""
    for k in range(T.shape[0]):
        R = T[k]
        for i in range(3):
            for j in range(i, 3):
                g = R[i, 0] * R[j, 0] + R[i, 1] * R[j, 1] + R[i, 2] * R[j, 2]
                if i == j:
                    g -= 1.0
                if not abs(g) <= gram_tol:
                    return False
        det = (
            R[0, 0] * (R[1, 1] * R[2, 2] - R[1, 2] * R[2, 1])
            - R[0, 1] * (R[1, 0] * R[2, 2] - R[1, 2] * R[2, 0])
            + R[0, 2] * (R[1, 0] * R[2, 1] - R[1, 1] * R[2, 0])
        )
        if not det > 0.0:
            return False
        if not (
            abs(R[3, 0]) <= last_tol and abs(R[3, 1]) <= last_tol and abs(R[3, 2]) <= last_tol
            and abs(R[3, 3] - 1.0) <= last_tol
        ):  # fmt: skip
            return False
    return True


@_jit
def frame_rows_batch(
    JwT: np.ndarray,
    placement: np.ndarray,
    W: np.ndarray,
    targets: np.ndarray,
    columns: np.ndarray,
    rows: np.ndarray,
    rotation: bool,
    J: np.ndarray,
    e: np.ndarray,
    done: np.ndarray,
) -> None:
    """Per problem k: the frame's Jacobian rows and pose error at its configuration, into J[k] and e[k].

    Inputs: JwT (N, nv, 6) the joint Jacobians in the world frame, transposed [m/rad, 1]; placement (N, 12) the
    parent joint's rotation (column-major) and origin [m]; W (12, 12) the map to the frame's (R row-major, p)
    (``batch._placement_map``); targets (N, 4, 4); columns (nv,) the supporting joints' columns; rows (m,) the
    frame-task rows (0–2 position, 3–5 rotation); ``rotation``: some row is a rotation row.

    Outputs: J (N, m, nv) the rows of the base-aligned Jacobian (``frame_jacobian_lwa``) [m/rad, 1]; e (N, m) the
    error (p_d − p [m], log3(R_d Rᵀ) [rad]) (``frame_error_rp``); done[k] False where the rotation error is too
    large for the small-angle log3 (e[k] is then not written: the caller takes Pinocchio's ``log3``).
    """
    N, nv = JwT.shape[0], JwT.shape[1]
    m = rows.shape[0]
    frame = np.empty(12)
    J6 = np.empty((6, nv))
    zero = np.zeros(6)
    v = np.empty(m)
    for k in range(N):
        x = placement[k]
        for c in range(12):
            t = 0.0
            for j in range(12):
                t += x[j] * W[j, c]
            frame[c] = t
        R = frame[0:9].reshape((3, 3))
        p = frame[9:12]
        frame_jacobian_lwa(JwT[k].T, p, columns, J6)
        for a in range(m):
            J[k, a, :] = J6[rows[a]]
        T = targets[k]
        done[k] = frame_error_rp(T[0:3, 3], T[0:3, 0:3], R, p, zero, 0.0, rows, rotation, e[k], v)


@_jit
def wqp_box_batch(
    J: np.ndarray,
    e: np.ndarray,
    z: np.ndarray,
    coef: np.ndarray,
    box: np.ndarray,
    P: np.ndarray,
    qv: np.ndarray,
    dq: np.ndarray,
    inside: np.ndarray,
    err: np.ndarray,
) -> None:
    """Per problem k, ``wqp``'s QP of the frame task (weight 1) over the posture (weight ρ = ``scale``) and its
    unconstrained optimum tested against the box, as the single step forms them.

    Inputs: J (N, m, nv) [m/rad, 1], e (N, m) the frame error [m, rad], z (N, nv) the posture velocity K_p e_p
    [rad/s]; ``coef`` (``WB_COEFS``,): the gain K [1/s] (V = K e [m/s, rad/s]), ρ, 1.0 when there is a posture, λ₀
    and the Levenberg–Marquardt factor (λ = λ₀ + lm·|e|²), the box test's tolerance; ``box`` (2, N, nv) the bounds
    lb, ub [rad/s].

    Outputs: P[k] = JᵀJ + (ρ I if posture) + λ I; qv[k] = −JᵀV − ρ z (if posture); dq[k] = x = −P⁻¹q clipped to
    the box [rad/s]; inside[k] whether the Cholesky solve succeeded and x lies within the box (±tol);
    err[k] = |e[k]| [m and rad mixed].
    """
    N, nv = qv.shape
    m = e.shape[1]
    gain, scale, has_posture = coef[WB_GAIN], coef[WB_SCALE], coef[WB_POSTURE] != 0.0
    lam0, lm_damping, tol = coef[WB_DAMPING], coef[WB_LM], coef[WB_TOL]
    lb, ub = box[0], box[1]
    V = np.empty(m)
    x = np.empty(nv)
    for k in range(N):
        s = 0.0
        for a in range(m):
            s += e[k, a] * e[k, a]
            V[a] = gain * e[k, a]
        err[k] = math.sqrt(s)
        Pk, qk = P[k], qv[k]
        gram_update(Pk, qk, J[k], V, 1.0, True)
        if has_posture:
            for i in range(nv):
                Pk[i, i] += scale
                qk[i] -= scale * z[k, i]
        lam = lam0 + lm_damping * s
        for i in range(nv):
            Pk[i, i] += lam
        _, inside[k] = spd_solve_box_into(Pk, qk, lb[k], ub[k], tol, x)
        for i in range(nv):
            dq[k, i] = min(max(x[i], lb[k, i]), ub[k, i])

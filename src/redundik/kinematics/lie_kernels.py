"""Compiled Lie-group kernels (numba) of a frame's pose: the small-angle log3, a frame task's error and velocity, and
a frame's base-aligned Jacobian from the joint Jacobians.

The one implementation of these formulas: a frame task's evaluation (:mod:`redundik.tasks.frame`), the clearance
potential (:mod:`redundik.tasks.potential_kernels`) and the resolvers' compiled steps all call them. They sit below
the tasks and the resolvers (they need numpy only), so that neither layer imports the other to reach them.
"""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

__all__ = [
    "SMALL_ROTATION_COS",
    "batch_log3_small",
    "frame_error",
    "frame_error_rp",
    "frame_jacobian_lwa",
]

#: cos θ above which :func:`frame_error` takes the rotation error log3(R_d Rᵀ) itself (θ < 0.45 rad: the atan2 form
#: is exact to rounding there); below it the caller uses Pinocchio's ``log3`` (robust up to θ = π).
SMALL_ROTATION_COS = 0.9


@_jit
def _log3_small(M: np.ndarray, out: np.ndarray, o: int) -> bool:
    """log3(M) ∈ so(3) into out[o:o+3] [rad] when θ < acos(:data:`SMALL_ROTATION_COS`), else False, nothing written.

    ω = θ/sin θ · vee(M − Mᵀ)/2 with θ = atan2(sin θ, cos θ), cos θ = (tr M − 1)/2 (exact to rounding in this range,
    θ → 0 included).
    """
    c = 0.5 * (M[0, 0] + M[1, 1] + M[2, 2] - 1.0)
    if not (c > SMALL_ROTATION_COS):
        return False
    wx = 0.5 * (M[2, 1] - M[1, 2])
    wy = 0.5 * (M[0, 2] - M[2, 0])
    wz = 0.5 * (M[1, 0] - M[0, 1])
    s = math.sqrt(wx * wx + wy * wy + wz * wz)
    f = math.atan2(s, min(c, 1.0)) / s if s > 0.0 else 1.0
    out[o], out[o + 1], out[o + 2] = f * wx, f * wy, f * wz
    return True


@_jit
def batch_log3_small(R: np.ndarray, out: np.ndarray, done: np.ndarray) -> None:
    """``_log3_small`` (the frame task's small-angle log3) of each R[k] (N, 3, 3) into out[k] (N, 3); done[k] is
    False where θ is too large (the caller uses Pinocchio's ``log3`` there)."""
    for k in range(R.shape[0]):
        done[k] = _log3_small(R[k], out[k], 0)


@_jit
def frame_error(
    p_d: np.ndarray,
    R_d: np.ndarray,
    T: np.ndarray,
    twist: np.ndarray,
    gain: float,
    rows: np.ndarray,
    rotation: bool,
    e: np.ndarray,
    v: np.ndarray,
) -> bool:
    """A frame task's error e = (p_d − p, log3(R_d Rᵀ))[rows] and velocity v = twist[rows] + K e into ``e``, ``v``.

    T is the frame's 4×4 pose in the world; ``rotation`` false skips the rotation rows (none selected). For a
    rotation error up to θ = acos(:data:`SMALL_ROTATION_COS`) the axis-angle vector is θ/sin θ · vee(M − Mᵀ)/2 with
    M = R_d Rᵀ and θ = atan2(sin θ, cos θ); beyond it nothing is written and False is returned (the caller then
    uses Pinocchio's ``log3``).
    """
    return frame_error_rp(p_d, R_d, T[0:3, 0:3], T[0:3, 3], twist, gain, rows, rotation, e, v)


@_jit
def frame_error_rp(
    p_d: np.ndarray,
    R_d: np.ndarray,
    R: np.ndarray,
    p: np.ndarray,
    twist: np.ndarray,
    gain: float,
    rows: np.ndarray,
    rotation: bool,
    e: np.ndarray,
    v: np.ndarray,
) -> bool:
    """:func:`frame_error` of a pose given as its rotation R (3, 3) and position p (3,)."""
    err = np.zeros(15)  # the error (6,), then M (3, 3): one allocation
    for i in range(3):
        err[i] = p_d[i] - p[i]
    if rotation:
        M = err[6:15].reshape((3, 3))
        for i in range(3):
            for j in range(3):
                M[i, j] = R_d[i, 0] * R[j, 0] + R_d[i, 1] * R[j, 1] + R_d[i, 2] * R[j, 2]
        if not _log3_small(M, err, 3):
            return False
    for k in range(rows.shape[0]):
        e[k] = err[rows[k]]
        v[k] = twist[rows[k]] + gain * e[k]
    return True


@_jit
def frame_jacobian_lwa(Jw: np.ndarray, p: np.ndarray, columns: np.ndarray, out: np.ndarray) -> None:
    """A frame's base-aligned Jacobian (Pinocchio's LOCAL_WORLD_ALIGNED) into ``out`` (6, nv) from the joint
    Jacobians in the world frame ``Jw`` (6, nv; ``data.J`` after ``computeJointJacobians``) and the frame's origin p:
    on the columns of the joints that support the frame (``columns[c]`` ≠ 0), linear rows v + ω × p, angular rows
    ω; zero elsewhere."""
    px, py, pz = p[0], p[1], p[2]
    for c in range(Jw.shape[1]):
        if columns[c]:
            wx, wy, wz = Jw[3, c], Jw[4, c], Jw[5, c]
            out[0, c] = Jw[0, c] + (wy * pz - wz * py)
            out[1, c] = Jw[1, c] + (wz * px - wx * pz)
            out[2, c] = Jw[2, c] + (wx * py - wy * px)
            out[3, c] = wx
            out[4, c] = wy
            out[5, c] = wz
        else:
            for i in range(6):
                out[i, c] = 0.0

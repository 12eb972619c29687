"""Compiled writers of frame targets: a target pose checked and written into a trajectory's parameter row in one call.

A teleoperated frame task receives a new target every control tick (``FrameTask.set_target``). The target is data:
it is checked (finite, bounded, a rotation) and written in place into the parameter row (p0, R0 row-major) that the
task's :class:`~redundik.tasks.trajectory.Hold` and a fused step read, so nothing is re-planned or allocated.

Status codes returned by the writers: ``OK``, ``NOT_FINITE``, ``TOO_FAR`` (a coordinate beyond the
bound), ``NOT_RIGID`` (the rotation is not orthonormal with det +1, or a 4×4 matrix's last row is not
(0, 0, 0, 1)), ``BAD_SHAPE``. Nothing is written unless the status is ``OK``.

``reference_into`` samples a compiled trajectory (``Line``, ``Circle``, ``Hold``) from that row at a time t: the one
implementation that the trajectories' ``reference`` and a fused step both call.
"""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.tasks.layouts import (
    CIRCLE_C,
    CIRCLE_E1,
    CIRCLE_E2,
    CIRCLE_PHASE,
    CIRCLE_W,
    LINE_V,
    P0,
    R0,
    REF,
    REF_P,
    REF_R,
    REF_TWIST,
)
from redundik.tasks.trajectory import CIRCLE, GIVEN, LINE

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

#: The writers' status codes.
OK, NOT_FINITE, TOO_FAR, NOT_RIGID, BAD_SHAPE = 0, 1, 2, 3, 4


@_jit
def _rotation_status(T: np.ndarray, tol: float) -> int:
    """``OK`` when the upper-left 3×3 block of ``T`` is finite, orthonormal to ``tol`` (max |RRᵀ − I|) with
    det > 0."""
    for i in range(3):
        for j in range(3):
            if not math.isfinite(T[i, j]):
                return NOT_FINITE
    for i in range(3):
        for j in range(3):
            s = T[i, 0] * T[j, 0] + T[i, 1] * T[j, 1] + T[i, 2] * T[j, 2]
            if abs(s - (1.0 if i == j else 0.0)) > tol:
                return NOT_RIGID
    det = (
        T[0, 0] * (T[1, 1] * T[2, 2] - T[1, 2] * T[2, 1])
        - T[0, 1] * (T[1, 0] * T[2, 2] - T[1, 2] * T[2, 0])
        + T[0, 2] * (T[1, 0] * T[2, 1] - T[1, 1] * T[2, 0])
    )
    return OK if det > 0.0 else NOT_RIGID


@_jit
def reference_status(p: np.ndarray, R: np.ndarray, tol: float, max_coordinate: float) -> int:
    """The status of a sampled reference — position p (3,) [length], rotation R (3, 3): ``OK``, ``TOO_FAR``,
    ``NOT_RIGID``, or ``NOT_FINITE`` (a NaN the step's fallback reports)."""
    for i in range(3):
        if not math.isfinite(p[i]):
            return NOT_FINITE
        if abs(p[i]) > max_coordinate:
            return TOO_FAR
    return _rotation_status(R, tol)


@_jit
def pose_into(T: np.ndarray, row: np.ndarray, tol: float, max_coordinate: float) -> int:
    """Check the homogeneous matrix ``T`` (4, 4) and write its position [length] at ``P0`` and its rotation
    (row-major) at ``R0`` of ``row`` (``tasks.layouts``); the status (module docstring)."""
    if T.shape[0] != 4 or T.shape[1] != 4:
        return BAD_SHAPE
    for i in range(3):
        x = T[i, 3]
        if not math.isfinite(x):
            return NOT_FINITE
        if abs(x) > max_coordinate:
            return TOO_FAR
    status = _rotation_status(T, tol)
    if status != OK:
        return status
    for j in range(4):
        if not math.isfinite(T[3, j]):
            return NOT_FINITE
        if abs(T[3, j] - (1.0 if j == 3 else 0.0)) > tol:
            return NOT_RIGID
    for i in range(3):
        row[P0 + i] = T[i, 3]
        for j in range(3):
            row[R0 + 3 * i + j] = T[i, j]
    return OK


@_jit
def position_into(p: np.ndarray, row: np.ndarray, max_coordinate: float) -> int:
    """Check the position ``p`` (3,) [length] and write it at ``row[P0]`` (the orientation is kept)."""
    if p.shape[0] != 3:
        return BAD_SHAPE
    for i in range(3):
        if not math.isfinite(p[i]):
            return NOT_FINITE
        if abs(p[i]) > max_coordinate:
            return TOO_FAR
    for i in range(3):
        row[P0 + i] = p[i]
    return OK


@_jit
def reference_into(kind: int, params: np.ndarray, t: float, out: np.ndarray) -> None:
    """The reference (p_d, R_d, twist) of a ``HOLD``, ``LINE`` or ``CIRCLE`` trajectory at t [s] into ``out``
    (``REF``,).

    Line: p = p0 + v t, twist (v, 0). Circle: p = c + cos(ωt + φ) r e1 + sin(ωt + φ) r e2, twist
    (ω (cos a · r e2 − sin a · r e1), 0). Orientation held (R0). ``GIVEN`` writes nothing.
    """
    if kind == GIVEN:
        return
    for i in range(3):
        out[REF_P + i] = params[P0 + i]
    for i in range(9):
        out[REF_R + i] = params[R0 + i]
    for i in range(REF_TWIST, REF):
        out[i] = 0.0
    if kind == LINE:
        for i in range(3):
            out[REF_P + i] = params[P0 + i] + params[LINE_V + i] * t
            out[REF_TWIST + i] = params[LINE_V + i]
    elif kind == CIRCLE:
        w = params[CIRCLE_W]
        a = w * t + params[CIRCLE_PHASE]
        c, s = math.cos(a), math.sin(a)
        for i in range(3):
            a1, b1 = params[CIRCLE_E1 + i], params[CIRCLE_E2 + i]
            out[REF_P + i] = params[CIRCLE_C + i] + c * a1 + s * b1
            out[REF_TWIST + i] = w * (c * b1 - s * a1)

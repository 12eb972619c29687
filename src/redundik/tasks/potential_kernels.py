"""Compiled kernels (numba) of the potentials: the clearance of ``Clearance`` and its gradient, and the compiled
writers (``CompiledGradient``: ``(q, poses, jw, ints, floats, eta) → p``) of the chapter's joint and frame-point
potentials (section 5.2) — each the one implementation that the potential's own evaluation and the resolvers'
compiled steps both call.
"""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.kinematics.lie_kernels import frame_jacobian_lwa

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

__all__ = [
    "FP_AXES",
    "FP_AXES_N",
    "FP_FRAME",
    "clearance_gradient",
    "clearance_into",
    "joint_value_gradient",
    "sine2_gradient",
    "virtual_point_gradient",
    "waypoints_gradient",
]

#: ``ints`` of a joint potential's writer: the joint's index in q, then in q̇.
J_IQ, J_IV = 0, 1
#: ``ints`` of a frame-point potential's writer (``Clearance``, ``VirtualPoint``): the frame's id, the number k of
#: axes that count, then those k axes (indices into x, y, z), then nv flags: nonzero on the velocity columns of the
#: joints that support the frame (``frame_jacobian_lwa``).
FP_FRAME, FP_AXES_N, FP_AXES = 0, 1, 2
#: ``floats`` of a clearance: the obstacle's centre p_o (3) [m], then its radius r [m]; of a virtual point: p_v (3).
FP_POINT, FP_RADIUS = 0, 3


@_jit
def clearance_into(
    Jw: np.ndarray,
    p: np.ndarray,
    columns: np.ndarray,
    rows: np.ndarray,
    center: np.ndarray,
    radius: float,
    J6: np.ndarray,
    lwa: bool,
    out: np.ndarray,
    scale: float,
) -> float:
    """The clearance p = ‖S(p_f − p_o)‖ − r [m] of ``Clearance`` (its one
    implementation), and scale · η into ``out`` (nv,), η = J_vᵀ Sᵀ u with u = S(p_f − p_o)/‖S(p_f − p_o)‖ (zero on the
    obstacle's axis, ‖·‖ < 1e-12, where the distance is not differentiable).

    Args:
        Jw: The joint Jacobians in the world frame (6, nv; ``data.J``), read when ``lwa``.
        p: The frame's origin p_f (3,) [m] (a view on ``data.oMf``'s memory, or a copy).
        columns: Per velocity column, nonzero where a joint that supports the frame acts (``frame_jacobian_lwa``).
        rows: The axes S selects (indices into x, y, z).
        center: The obstacle's centre p_o (3,) [m].
        radius: Its radius r [m].
        J6: (6, nv): with ``lwa`` the frame's base-aligned Jacobian is written here from ``Jw`` and p
            (``frame_jacobian_lwa``, bitwise getFrameJacobian's); without, it holds that Jacobian already.
        lwa: Whether to compute ``J6`` from ``Jw``.
        out: (nv,) written with scale · η.
        scale: 1 for η, −1 for the row −η of a lower bound's damper.
    """
    k = rows.shape[0]
    dist = np.empty(k)
    s = 0.0
    for i in range(k):
        r = rows[i]
        dist[i] = p[r] - center[r]
        s += dist[i] * dist[i]
    n = math.sqrt(s)
    if n < 1e-12:
        for c in range(out.shape[0]):
            out[c] = 0.0
        return n - radius
    if lwa:
        frame_jacobian_lwa(Jw, p, columns, J6)
    for i in range(k):
        dist[i] /= n
    for c in range(out.shape[0]):
        g = 0.0
        for i in range(k):
            g += J6[rows[i], c] * dist[i]
        out[c] = scale * g
    return n - radius


@_jit
def sine2_gradient(
    q: np.ndarray, poses: np.ndarray, jw: np.ndarray, ints: np.ndarray, floats: np.ndarray, eta: np.ndarray
) -> float:
    """``JointSine2``: p = sin²θ_j, η_j = sin 2θ_j (the chapter's p = sin²θ3, sin²θ6); ``ints`` = (idx_q, idx_v)."""
    x = q[ints[J_IQ]]
    eta[ints[J_IV]] = math.sin(2.0 * x)
    s = math.sin(x)
    return s * s


@_jit
def joint_value_gradient(
    q: np.ndarray, poses: np.ndarray, jw: np.ndarray, ints: np.ndarray, floats: np.ndarray, eta: np.ndarray
) -> float:
    """``JointValue``: p = (q_j − c)², η_j = 2 (q_j − c); ``ints`` = (idx_q, idx_v), ``floats`` = (c,)."""
    d = q[ints[J_IQ]] - floats[0]
    eta[ints[J_IV]] = 2.0 * d
    return d * d


@_jit
def clearance_gradient(
    q: np.ndarray, poses: np.ndarray, jw: np.ndarray, ints: np.ndarray, floats: np.ndarray, eta: np.ndarray
) -> float:
    """``Clearance``: p = ‖S(p_f − p_o)‖ − r [m] and η (:func:`clearance_into`), in the frame-point layout."""
    k = ints[FP_AXES_N]
    p = poses[ints[FP_FRAME], 9:12]
    J6 = np.empty((6, eta.shape[0]))
    rows, columns = ints[FP_AXES : FP_AXES + k], ints[FP_AXES + k :]
    return clearance_into(jw, p, columns, rows, floats[FP_POINT : FP_POINT + 3], floats[FP_RADIUS], J6, True, eta, 1.0)


@_jit
def virtual_point_gradient(
    q: np.ndarray, poses: np.ndarray, jw: np.ndarray, ints: np.ndarray, floats: np.ndarray, eta: np.ndarray
) -> float:
    """``VirtualPoint``: p = ½‖S(p_f − p_v)‖², η = J_vᵀ Sᵀ S (p_f − p_v), in the frame-point layout."""
    k = ints[FP_AXES_N]
    p = poses[ints[FP_FRAME], 9:12]
    J6 = np.empty((6, eta.shape[0]))
    frame_jacobian_lwa(jw, p, ints[FP_AXES + k :], J6)
    value = 0.0
    for i in range(k):
        r = ints[FP_AXES + i]
        mu = p[r] - floats[FP_POINT + r]
        value += mu * mu
        for c in range(eta.shape[0]):
            eta[c] += J6[r, c] * mu
    return 0.5 * value


@_jit
def waypoints_gradient(
    q: np.ndarray, poses: np.ndarray, jw: np.ndarray, ints: np.ndarray, floats: np.ndarray, eta: np.ndarray
) -> float:
    """``JointWaypoints``: the active waypoint c_i moves on while |q_j − c_i| < tolerance (not past the last), then
    p = (q_j − c_i)², η_j = 2 (q_j − c_i). ``ints`` = (idx_q, idx_v, active index i, count), the index rewritten in
    place; ``floats`` = (tolerance, c_1, c_2, …)."""
    x = q[ints[J_IQ]]
    k = ints[2]
    while k < ints[3] - 1 and abs(x - floats[1 + k]) < floats[0]:
        k += 1
    ints[2] = k
    d = x - floats[1 + k]
    eta[ints[J_IV]] = 2.0 * d
    return d * d

"""Compiled kernels (numba) of the potentials: the clearance of ``Clearance`` and its gradient, and the compiled
writers (``CompiledGradient``: ``(q, poses, jw, ints, floats, eta) → p``) of the chapter's joint and frame-point
potentials (section 5.2) — each the one implementation that the potential's own evaluation and the resolvers'
compiled steps both call.
"""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.kinematics.layouts import POSE_P
from redundik.kinematics.lie_kernels import frame_jacobian_lwa
from redundik.tasks.layouts import (
    FP_AXES,
    FP_AXES_N,
    FP_FRAME,
    FP_POINT,
    FP_RADIUS,
    J_IQ,
    J_IV,
    JP_FRAMES,
    JP_ROWS,
    JP_ROWS_N,
    JV_CENTER,
    WP_ACTIVE,
    WP_COUNT,
    WP_POINTS,
    WP_TOLERANCE,
)

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

__all__ = [
    "FP_AXES",
    "FP_AXES_N",
    "FP_FRAME",
    "best_posture_gradient",
    "centering_gradient",
    "clearance_gradient",
    "clearance_into",
    "frame_jacobian_hessian",
    "joint_value_gradient",
    "manipulability_gradient",
    "sine2_gradient",
    "virtual_point_gradient",
    "waypoints_gradient",
]


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
    d = q[ints[J_IQ]] - floats[JV_CENTER]
    eta[ints[J_IV]] = 2.0 * d
    return d * d


@_jit
def centering_gradient(
    q: np.ndarray, poses: np.ndarray, jw: np.ndarray, ints: np.ndarray, floats: np.ndarray, eta: np.ndarray
) -> float:
    """``JointCentering`` on vector-space coordinates (5.9, 5.10): p = ½ Σ w_k (q_k − c_k)², η_k = w_k (q_k − c_k);
    ``ints`` = the index in q of each velocity coordinate (not read where w_k = 0), ``floats`` = (w (nv), c at those
    indices (nv))."""
    nv = ints.shape[0]
    p = 0.0
    for k in range(nv):
        w = floats[k]
        if w != 0.0:
            d = q[ints[k]] - floats[nv + k]
            eta[k] = w * d
            p += w * d * d
    return 0.5 * p


@_jit
def clearance_gradient(
    q: np.ndarray, poses: np.ndarray, jw: np.ndarray, ints: np.ndarray, floats: np.ndarray, eta: np.ndarray
) -> float:
    """``Clearance``: p = ‖S(p_f − p_o)‖ − r [m] and η (:func:`clearance_into`), in the frame-point layout."""
    k = ints[FP_AXES_N]
    p = poses[ints[FP_FRAME], POSE_P : POSE_P + 3]
    J6 = np.empty((6, eta.shape[0]))
    rows, columns = ints[FP_AXES : FP_AXES + k], ints[FP_AXES + k :]
    return clearance_into(jw, p, columns, rows, floats[FP_POINT : FP_POINT + 3], floats[FP_RADIUS], J6, True, eta, 1.0)


@_jit
def virtual_point_gradient(
    q: np.ndarray, poses: np.ndarray, jw: np.ndarray, ints: np.ndarray, floats: np.ndarray, eta: np.ndarray
) -> float:
    """``VirtualPoint``: p = ½‖S(p_f − p_v)‖², η = J_vᵀ Sᵀ S (p_f − p_v), in the frame-point layout."""
    k = ints[FP_AXES_N]
    p = poses[ints[FP_FRAME], POSE_P : POSE_P + 3]
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
    k = ints[WP_ACTIVE]
    while k < ints[WP_COUNT] - 1 and abs(x - floats[WP_POINTS + k]) < floats[WP_TOLERANCE]:
        k += 1
    ints[WP_ACTIVE] = k
    d = x - floats[WP_POINTS + k]
    eta[ints[J_IV]] = 2.0 * d
    return d * d


@_jit
def frame_jacobian_hessian(
    jw: np.ndarray, p: np.ndarray, columns: np.ndarray, mask: np.ndarray, J6: np.ndarray, H: np.ndarray
) -> None:
    """∂J/∂q_k of a frame's base-aligned Jacobian J6 (6, nv; written by ``frame_jacobian_lwa``) into H (6, nv, nv),
    ``H[:, j, k] = ∂J_j/∂q_k`` (``RobotModel.frame_jacobian_derivatives``, the same formula): with the world
    columns S_j = (v_j, ω_j) of ``jw``, ∂S_j/∂q_k = ad(S_k) S_j = (ω_k × v_j + v_k × ω_j, ω_k × ω_j) when M[j, k]
    (``mask``), and the origin's ∂p/∂q_k = J6[0:3, k]: ∂J_j/∂q_k = (∂v_j + ∂ω_j × p + ω_j × ∂p/∂q_k, ∂ω_j)."""
    frame_jacobian_lwa(jw, p, columns, J6)
    nv = jw.shape[1]
    for j in range(nv):
        if not columns[j]:
            for r in range(6):
                for k in range(nv):
                    H[r, j, k] = 0.0
            continue
        vx, vy, vz, wx, wy, wz = jw[0, j], jw[1, j], jw[2, j], jw[3, j], jw[4, j], jw[5, j]
        for k in range(nv):
            hvx = hvy = hvz = hwx = hwy = hwz = 0.0
            if mask[j * nv + k] and columns[k]:
                ax, ay, az, bx, by, bz = jw[0, k], jw[1, k], jw[2, k], jw[3, k], jw[4, k], jw[5, k]  # (v_k, ω_k)
                hvx = (by * vz - bz * vy) + (ay * wz - az * wy)
                hvy = (bz * vx - bx * vz) + (az * wx - ax * wz)
                hvz = (bx * vy - by * vx) + (ax * wy - ay * wx)
                hwx, hwy, hwz = by * wz - bz * wy, bz * wx - bx * wz, bx * wy - by * wx
            dpx, dpy, dpz = J6[0, k], J6[1, k], J6[2, k]  # ∂p/∂q_k (zero off the frame's support)
            H[0, j, k] = hvx + (hwy * p[2] - hwz * p[1]) + (wy * dpz - wz * dpy)
            H[1, j, k] = hvy + (hwz * p[0] - hwx * p[2]) + (wz * dpx - wx * dpz)
            H[2, j, k] = hvz + (hwx * p[1] - hwy * p[0]) + (wx * dpy - wy * dpx)
            H[3, j, k] = hwx
            H[4, j, k] = hwy
            H[5, j, k] = hwz


@_jit
def best_posture_gradient(
    q: np.ndarray, poses: np.ndarray, jw: np.ndarray, ints: np.ndarray, floats: np.ndarray, eta: np.ndarray
) -> float:
    """``BestPosture`` (eq. 5.12): p = Σ_f tr(J_f W J_fᵀ) over the rows that count, η_k = 2 Σ_f tr(∂J_f/∂q_k W J_fᵀ).
    Layout ``JP_*``; ``floats`` = w (nv)."""
    nv = eta.shape[0]
    nf, m = ints[JP_FRAMES], ints[JP_ROWS_N]
    fids = JP_ROWS + m
    mask = ints[fids + nf + nf * nv :]
    J6 = np.empty((6, nv))
    H = np.empty((6, nv, nv))
    value = 0.0
    for f in range(nf):
        fid = ints[fids + f]
        columns = ints[fids + nf + f * nv : fids + nf + (f + 1) * nv]
        frame_jacobian_hessian(jw, poses[fid, POSE_P : POSE_P + 3], columns, mask, J6, H)
        for i in range(m):
            r = ints[JP_ROWS + i]
            for j in range(nv):
                jwj = J6[r, j] * floats[j]
                value += J6[r, j] * jwj
                for k in range(nv):
                    eta[k] += 2.0 * jwj * H[r, j, k]
    return value


@_jit
def manipulability_gradient(
    q: np.ndarray, poses: np.ndarray, jw: np.ndarray, ints: np.ndarray, floats: np.ndarray, eta: np.ndarray
) -> float:
    """``Manipulability``: p = √det(J Jᵀ) = Π σ_i of the frame Jacobian's rows that count, and
    η_k = Σ_i (Π_{l≠i} σ_l) u_iᵀ (∂J/∂q_k) v_i from the SVD J = Σ σ_i u_i v_iᵀ (no inverse of JJᵀ: finite at a
    singularity). Layout ``JP_*`` with one frame."""
    nv = eta.shape[0]
    m = ints[JP_ROWS_N]
    fids = JP_ROWS + m
    fid = ints[fids]
    cols = fids + 1  # one frame: its columns, then the support mask
    columns = ints[cols : cols + nv]
    J6 = np.empty((6, nv))
    H = np.empty((6, nv, nv))
    frame_jacobian_hessian(jw, poses[fid, POSE_P : POSE_P + 3], columns, ints[cols + nv :], J6, H)
    J = np.empty((m, nv))
    for i in range(m):
        J[i] = J6[ints[JP_ROWS + i]]
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    kk = s.shape[0]
    value = 1.0
    for i in range(kk):
        value *= s[i]
    for i in range(kk):
        others = 1.0
        for l in range(kk):
            if l != i:
                others *= s[l]
        for a in range(m):
            ua = U[a, i] * others
            if ua == 0.0:
                continue
            r = ints[JP_ROWS + a]
            for n in range(nv):
                c = ua * Vt[i, n]
                if c != 0.0:
                    for k in range(nv):
                        eta[k] += c * H[r, n, k]
    return value

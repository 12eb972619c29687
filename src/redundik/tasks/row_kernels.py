"""Compiled writers (numba) of the built-in tasks that give their rows through ``Task.compiled_rows``
(:class:`redundik.tasks.base.CompiledRows`): joint coupling, the pose of one frame relative to another, the centre of
mass; and of the support polygon's barrier (``Barrier.compiled_barrier``, :class:`redundik.tasks.base.CompiledBarrier`).
Each is the one implementation of its rows: the task's ``evaluate`` (:class:`redundik.tasks.rows.CompiledTask`) or
the bound subtask's rows, and the resolvers' compiled steps, call the same kernel.

The task writers have the protocol's signature ``(q, t, poses, jw, ints, floats, gain, J, e, v)``, the barrier's
``(q, poses, jw, ints, floats, h, H)``; ``poses`` holds the frames' placements (rotation column-major, then the
origin) and ``jw`` the joint Jacobians in the world frame.
"""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.kinematics.layouts import POSE_P, POSE_R
from redundik.kinematics.lie_kernels import frame_jacobian_lwa
from redundik.tasks.layouts import (
    COM_BODIES,
    COM_BODY,
    COM_LEVER,
    COM_MASS,
    COM_NBODIES,
    COM_NROWS,
    COM_ROWS,
    COM_TARGET,
    CPL_IQ_I,
    CPL_IQ_J,
    CPL_IV_I,
    CPL_IV_J,
    CPL_OFFSET,
    REL_FRAME_A,
    REL_FRAME_B,
    REL_NROWS,
    REL_P,
    REL_R,
    REL_ROWS,
    SUP_AX,
    SUP_AY,
    SUP_B,
    SUP_EDGE,
    SUP_EDGES,
    SUP_MARGIN,
)

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

__all__ = ["com_rows", "coupling_rows", "log3", "relative_rows"]


@_jit
def coupling_rows(
    q: np.ndarray,
    t: float,
    poses: np.ndarray,
    jw: np.ndarray,
    ints: np.ndarray,
    floats: np.ndarray,
    gain: float,
    J: np.ndarray,
    e: np.ndarray,
    v: np.ndarray,
) -> None:
    """Joint coupling q_i − q_j = c (section 5.3): J = (e_i − e_j)ᵀ, e = c − (q_i − q_j), v = K e.

    ``ints`` = (idx_q i, idx_v i, idx_q j, idx_v j); ``floats`` = (c,) [rad or m] (``tasks.layouts``' ``CPL_*``)."""
    J[0, ints[CPL_IV_I]] = 1.0
    J[0, ints[CPL_IV_J]] = -1.0
    e[0] = floats[CPL_OFFSET] - (q[ints[CPL_IQ_I]] - q[ints[CPL_IQ_J]])
    v[0] = gain * e[0]


@_jit
def log3(M: np.ndarray, out: np.ndarray) -> None:
    """log3 of a rotation matrix M (3, 3) into ``out`` (3,): the axis-angle vector θ u, θ ∈ [0, π] (Pinocchio's
    ``log3``; near θ = π the axis comes from the diagonal of M)."""
    tr = M[0, 0] + M[1, 1] + M[2, 2]
    c = min(1.0, max(-1.0, 0.5 * (tr - 1.0)))
    wx, wy, wz = M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]
    s = 0.5 * math.sqrt(wx * wx + wy * wy + wz * wz)
    theta = math.atan2(s, c)
    if c > -0.99:  # away from π: θ / (2 sin θ) times the skew part (its series below 1e-8)
        f = 0.5 + theta * theta / 12.0 if theta < 1e-4 else 0.5 * theta / math.sin(theta)
        out[0], out[1], out[2] = f * wx, f * wy, f * wz
        return
    # near π: R ≈ 2 u uᵀ − I + sin θ [u]×, so u_k² = (M_kk − c) / (1 − c); the largest |u_k| takes the sign of the
    # skew part (sin θ u_k = w_k / 2), the others u_i u_k = (M_ik + M_ki) / (2 (1 − c))
    d = 1.0 - c
    u = np.empty(3)
    for i in range(3):
        u[i] = math.sqrt(max(0.0, (M[i, i] - c) / d))
    k = 0
    if u[1] > u[k]:
        k = 1
    if u[2] > u[k]:
        k = 2
    w = (wx, wy, wz)
    sk = 1.0 if w[k] >= 0.0 else -1.0
    for i in range(3):
        if i != k:
            u[i] = sk * math.copysign(u[i], M[i, k] + M[k, i])
    u[k] = sk * u[k]
    n = math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
    for i in range(3):
        out[i] = theta * u[i] / n


@_jit
def relative_rows(
    q: np.ndarray,
    t: float,
    poses: np.ndarray,
    jw: np.ndarray,
    ints: np.ndarray,
    floats: np.ndarray,
    gain: float,
    J: np.ndarray,
    e: np.ndarray,
    v: np.ndarray,
) -> None:
    """The pose of frame A in frame B (:mod:`redundik.tasks.relative`): p_rel = R_Bᵀ (p_A − p_B), R_rel = R_Bᵀ R_A,
    e = (p_d − p_rel, log3(R_d R_relᵀ))[rows], J = diag(R_Bᵀ, R_Bᵀ) [[J_A^v − J_B^v + [p_A − p_B]× J_B^ω],
    [J_A^ω − J_B^ω]][rows], v = K e.

    ``ints`` = (frame A, frame B, r, rows (r), A's supporting columns (nv), B's (nv)); ``floats`` = (p_d (3) [m],
    R_d row-major (9)) (``tasks.layouts``' ``REL_*``)."""
    nv = jw.shape[1]
    fa, fb, r = ints[REL_FRAME_A], ints[REL_FRAME_B], ints[REL_NROWS]
    cols = REL_ROWS + r  # A's supporting columns, then B's
    Ra = poses[fa, POSE_R : POSE_R + 9].reshape(3, 3).T  # (stored column-major)
    Rb = poses[fb, POSE_R : POSE_R + 9].reshape(3, 3).T
    pa, pb = poses[fa, POSE_P : POSE_P + 3], poses[fb, POSE_P : POSE_P + 3]
    d = pa - pb
    ja, jb = np.empty((6, nv)), np.empty((6, nv))
    frame_jacobian_lwa(jw, pa, ints[cols : cols + nv], ja)
    frame_jacobian_lwa(jw, pb, ints[cols + nv : cols + 2 * nv], jb)
    err = np.empty(6)
    M = np.empty((3, 3))
    for i in range(3):  # p_d − R_bᵀ d; and M = R_d R_relᵀ = R_d R_aᵀ R_b
        err[i] = floats[REL_P + i] - (Rb[0, i] * d[0] + Rb[1, i] * d[1] + Rb[2, i] * d[2])
    Rrel = Rb.T @ Ra
    Rd = floats[REL_R : REL_R + 9].reshape(3, 3)
    for i in range(3):
        for j in range(3):
            M[i, j] = Rd[i, 0] * Rrel[j, 0] + Rd[i, 1] * Rrel[j, 1] + Rd[i, 2] * Rrel[j, 2]
    log3(M, err[3:6])
    full = np.empty((6, nv))
    for c in range(nv):
        wbx, wby, wbz = jb[3, c], jb[4, c], jb[5, c]
        lv0 = ja[0, c] - jb[0, c] + (d[1] * wbz - d[2] * wby)  # d × ω_B
        lv1 = ja[1, c] - jb[1, c] + (d[2] * wbx - d[0] * wbz)
        lv2 = ja[2, c] - jb[2, c] + (d[0] * wby - d[1] * wbx)
        aw0, aw1, aw2 = ja[3, c] - wbx, ja[4, c] - wby, ja[5, c] - wbz
        for i in range(3):  # R_bᵀ applied to both blocks
            full[i, c] = Rb[0, i] * lv0 + Rb[1, i] * lv1 + Rb[2, i] * lv2
            full[3 + i, c] = Rb[0, i] * aw0 + Rb[1, i] * aw1 + Rb[2, i] * aw2
    for k in range(r):
        row = ints[REL_ROWS + k]
        e[k] = err[row]
        v[k] = gain * err[row]
        for c in range(nv):
            J[k, c] = full[row, c]


@_jit
def com_into(poses: np.ndarray, jw: np.ndarray, ints: np.ndarray, floats: np.ndarray, Jc: np.ndarray) -> np.ndarray:
    """The centre of mass c (3,) [m] (returned) and its Jacobian into ``Jc`` (3, nv; zeros on entry):
    c = Σ m_i c_i / M with c_i = p_i + R_i l_i the bodies' centres, J_c = Σ (m_i / M) (J_i^v + ω_i × c_i) on the
    columns that support body i (``ints``, ``floats``: the bodies of ``com_rows``' layout)."""
    nv = jw.shape[1]
    b, r = ints[COM_NBODIES], ints[COM_NROWS]
    fids = COM_ROWS + r
    cols = fids + b
    c = np.zeros(3)
    for i in range(b):
        f = ints[fids + i]
        body = COM_BODIES + COM_BODY * i
        w = floats[body + COM_MASS]
        lever = floats[body + COM_LEVER : body + COM_LEVER + 3]
        lx, ly, lz = lever[0], lever[1], lever[2]
        R = poses[f, POSE_R : POSE_R + 9]  # column-major: column j at 3 j
        p = poses[f, POSE_P : POSE_P + 3]
        c0 = p[0] + R[0] * lx + R[3] * ly + R[6] * lz  # p + R l
        c1 = p[1] + R[1] * lx + R[4] * ly + R[7] * lz
        c2 = p[2] + R[2] * lx + R[5] * ly + R[8] * lz
        c[0] += w * c0
        c[1] += w * c1
        c[2] += w * c2
        for col in range(nv):
            if ints[cols + i * nv + col]:
                wx, wy, wz = jw[3, col], jw[4, col], jw[5, col]
                Jc[0, col] += w * (jw[0, col] + wy * c2 - wz * c1)
                Jc[1, col] += w * (jw[1, col] + wz * c0 - wx * c2)
                Jc[2, col] += w * (jw[2, col] + wx * c1 - wy * c0)
    return c


@_jit
def com_rows(
    q: np.ndarray,
    t: float,
    poses: np.ndarray,
    jw: np.ndarray,
    ints: np.ndarray,
    floats: np.ndarray,
    gain: float,
    J: np.ndarray,
    e: np.ndarray,
    v: np.ndarray,
) -> None:
    """The centre of mass (:mod:`redundik.tasks.balance`): c and J_c of :func:`com_into`; e = (c_d − c)[rows],
    v = K e.

    ``ints`` = (bodies b, r, rows (r), per body its joint's frame id (b), per body its supporting columns (b × nv));
    ``floats`` = (c_d (3) [m], per body m_i / M, l_i (3) [m] (b × 4)) (``tasks.layouts``' ``COM_*``)."""
    nv = jw.shape[1]
    Jc = np.zeros((3, nv))
    c = com_into(poses, jw, ints, floats, Jc)
    for k in range(ints[COM_NROWS]):
        row = ints[COM_ROWS + k]
        e[k] = floats[COM_TARGET + row] - c[row]
        v[k] = gain * e[k]
        for col in range(nv):
            J[k, col] = Jc[row, col]


@_jit
def support_rows(
    q: np.ndarray, poses: np.ndarray, jw: np.ndarray, ints: np.ndarray, floats: np.ndarray, h: np.ndarray,
    H: np.ndarray,
) -> None:  # fmt: skip
    """The support polygon's barrier (``SupportPolygon``, a ``CompiledBarrier`` writer): per edge i (outward unit
    normal a_i, offset b_i), h_i = b_i − a_iᵀ S c − m [m] and H_i = −a_iᵀ S J_c, with c, J_c of :func:`com_into` and
    S the x–y selection (``tasks.layouts``' ``SUP_*`` after the bodies)."""
    nv = jw.shape[1]
    Jc = np.zeros((3, nv))
    c = com_into(poses, jw, ints, floats, Jc)
    o = COM_BODIES + COM_BODY * ints[COM_NBODIES]
    margin = floats[o + SUP_MARGIN]
    for i in range(h.shape[0]):
        edge = o + SUP_EDGES + SUP_EDGE * i
        ax, ay = floats[edge + SUP_AX], floats[edge + SUP_AY]
        h[i] = (floats[edge + SUP_B] - (ax * c[0] + ay * c[1])) - margin
        for col in range(nv):
            H[i, col] = -ax * Jc[0, col] + -ay * Jc[1, col]

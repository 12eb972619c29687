"""Compiled kernels (numba) of the potentials: the clearance of ``Clearance`` and its
gradient, the one implementation that the potential's own evaluation and the resolvers' compiled steps both call.
"""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.kinematics.lie_kernels import frame_jacobian_lwa

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

__all__ = ["clearance_into"]


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

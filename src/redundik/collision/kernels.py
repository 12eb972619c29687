"""Compiled kernels (numba) of the collision world: capsule–capsule distances, capsule end-sphere distances and the
exact distance Jacobian rows, each one call over all the pairs of a tick.

Why compiled: per pair, the NumPy route is a dozen small-array operations (≈ 20 µs for an end sphere in Python,
mostly call overhead), so with 20 candidate pairs the collision rows cost several times the rest of a ``wqp`` step;
one compiled call over every pair costs about as much as one of those operations. The formulas are those of
:mod:`redundik.collision.world` (its docstrings carry the derivations); the tests hold the kernels to coal's
distances and to finite differences.

Shapes are described per geometry g by a kind code and four numbers:

* ``CAPSULE`` (a sphere is a capsule of half length 0): ``prm[g] = (R, half length, 0, 0)``, axis local z;
* ``BOX``: ``prm[g] = (half sides x, y, z, 0)``;
* ``HALFSPACE``, the solid {x : nᵀx ≤ d} of the geometry's frame: ``prm[g] = (n_x, n_y, n_z, d)``;
* ``OTHER`` (meshes / convex hulls): left to coal.

Poses are world homogeneous transforms ``T`` (G, 4, 4) (rotation ``T[g, :3, :3]``, translation ``T[g, :3, 3]``).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

CAPSULE, BOX, HALFSPACE, OTHER = 0, 1, 2, 3

_jit = nb.njit(cache=True, nogil=True)


@_jit
def _segment_params(p1: np.ndarray, d1: np.ndarray, p2: np.ndarray, d2: np.ndarray) -> tuple[float, float]:
    """(s, u) ∈ [0, 1]² minimising |(p1 + s d1) − (p2 + u d2)| (Ericson, Real-Time Collision Detection, §5.1.9)."""
    r = p1 - p2
    a = d1 @ d1
    e = d2 @ d2
    f = d2 @ r
    eps = 1e-18
    if a <= eps and e <= eps:
        return 0.0, 0.0
    if a <= eps:
        return 0.0, min(1.0, max(0.0, f / e))
    c = d1 @ r
    if e <= eps:
        return min(1.0, max(0.0, -c / a)), 0.0
    b = d1 @ d2
    den = a * e - b * b
    s = min(1.0, max(0.0, (b * f - c * e) / den)) if den > eps * a * e else 0.0
    u = (b * s + f) / e
    if u < 0.0:
        u = 0.0
        s = min(1.0, max(0.0, -c / a))
    elif u > 1.0:
        u = 1.0
        s = min(1.0, max(0.0, (b - c) / a))
    return s, u


@_jit
def capsule_pairs(
    T: np.ndarray, prm: np.ndarray, ia: np.ndarray, ib: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Signed distances of the capsule pairs (ia[k], ib[k]): (d (k,), p1 (k, 3), p2 (k, 3), n (k, 3), ok (k,)).

    d = |c₂ − c₁| − R₁ − R₂ between the closest axis points c₁, c₂; n = (c₂ − c₁)/|c₂ − c₁|, p₁ = c₁ + R₁n,
    p₂ = c₂ − R₂n, so p₂ − p₁ = d n also when penetrating (coal's convention). ``ok`` is False where the axes meet
    (|c₂ − c₁| < 1e-12: n undefined; the caller asks coal).
    """
    m = ia.shape[0]
    d = np.empty(m)
    p1 = np.zeros((m, 3))
    p2 = np.zeros((m, 3))
    n = np.zeros((m, 3))
    ok = np.ones(m, dtype=np.bool_)
    for k in range(m):
        a, b = ia[k], ib[k]
        ra, ha, rb, hb = prm[a, 0], prm[a, 1], prm[b, 0], prm[b, 1]
        za = T[a, :3, 2] * ha
        zb = T[b, :3, 2] * hb
        sa = T[a, :3, 3] - za
        sb = T[b, :3, 3] - zb
        s, u = _segment_params(sa, 2.0 * za, sb, 2.0 * zb)
        ca = sa + 2.0 * s * za
        cb = sb + 2.0 * u * zb
        diff = cb - ca
        L = math.sqrt(diff @ diff)
        if L < 1e-12:
            ok[k] = False
            d[k] = -ra - rb
            continue
        nk = diff / L
        d[k] = L - ra - rb
        n[k] = nk
        p1[k] = ca + ra * nk
        p2[k] = cb - rb * nk
    return d, p1, p2, n, ok


@_jit
def _ball_to(
    c: np.ndarray, r: float, kind: int, prm: np.ndarray, Ro: np.ndarray, to: np.ndarray
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, bool]:
    """Ball (centre c, radius r) to a shape: (d, point on the ball, point on the shape, unit u ball → shape, ok)."""
    z3 = np.zeros(3)
    if kind == CAPSULE:
        ax = Ro[:, 2] * prm[1]
        a = to - ax
        ab = 2.0 * ax
        L2 = ab @ ab
        s = min(1.0, max(0.0, ((c - a) @ ab) / L2)) if prm[1] > 0.0 else 0.0
        x = a + s * ab
        v = x - c
        L = math.sqrt(v @ v)
        if L <= 1e-12:
            return 0.0, z3, z3, z3, False
        u = v / L
        return L - r - prm[0], c + r * u, x - prm[0] * u, u, True
    if kind == BOX:
        hs = prm[:3]
        cl = Ro.T @ (c - to)
        cb = np.minimum(np.maximum(cl, -hs), hs)
        v = cb - cl
        L = math.sqrt(v @ v)
        if L > 1e-12:  # outside the box
            u = Ro @ (v / L)
            return L - r, c + r * u, to + Ro @ cb, u, True
        depth = hs - np.abs(cl)
        ax = int(np.argmin(depth))
        out = np.zeros(3)
        out[ax] = 1.0 if cl[ax] >= 0.0 else -1.0
        u = -(Ro @ out)  # the distance grows when the centre moves outwards (along −u)
        face = cl.copy()
        face[ax] = out[ax] * hs[ax]
        return -depth[ax] - r, c + r * u, to + Ro @ face, u, True
    if kind == HALFSPACE:
        nw = Ro @ prm[:3]
        h = nw @ (c - to) - prm[3]
        u = -nw
        return h - r, c + r * u, c - h * nw, u, True
    return 0.0, z3, z3, z3, False


@_jit
def end_spheres(
    T: np.ndarray,
    kind: np.ndarray,
    prm: np.ndarray,
    br_pair: np.ndarray,
    br_b: np.ndarray,
    br_o: np.ndarray,
    br_first: np.ndarray,
    br_sign: np.ndarray,
    sel: np.ndarray,
    pair_d: np.ndarray,
    pair_p1: np.ndarray,
    influence: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The end spheres of capsules against their pair's other body, over the branches of the selected pairs.

    Branch r: the ball of radius R at the end ``br_sign[r]`` (±1 along local z) of capsule ``br_b[r]`` against
    ``br_o[r]``, of pair ``br_pair[r]``; ``br_first[r]``: the capsule is body 1 of the pair (else the points and
    normal are swapped so that p₂ − p₁ = d n from body 1 to body 2). Only branches with ``sel[br_pair[r]]`` are
    computed; ``pair_d``/``pair_p1`` (per pair) are the pair's own distance and witness on body 1.

    Returns:
        (branch indices (m,), d (m,), p1 (m, 3), p2 (m, 3), n (m, 3)) of the kept branches: those within
        ``influence``, defined (the end off the other shape's axis/centre; not an ``OTHER`` shape) and not the
        pair's own witness (|d_e − d| < 1e-9 and the same point within 1e-7 m).
    """
    m = br_pair.shape[0]
    idx = np.empty(m, dtype=np.int64)
    d = np.empty(m)
    p1 = np.empty((m, 3))
    p2 = np.empty((m, 3))
    n = np.empty((m, 3))
    c_ = 0
    for r in range(m):
        k = br_pair[r]
        b, o = br_b[r], br_o[r]
        if not sel[k] or kind[o] == OTHER:
            continue
        c = T[b, :3, 3] + br_sign[r] * prm[b, 1] * T[b, :3, 2]
        de, ps, po, u, ok = _ball_to(c, prm[b, 0], kind[o], prm[o], np.ascontiguousarray(T[o, :3, :3]), T[o, :3, 3])
        if not ok or de >= influence:
            continue
        if br_first[r]:
            q1, q2, nr = ps, po, u
        else:
            q1, q2, nr = po, ps, -u
        if abs(de - pair_d[k]) < 1e-9 and np.max(np.abs(q1 - pair_p1[k])) < 1e-7:
            continue  # the pair's own witness
        idx[c_], d[c_], p1[c_], p2[c_], n[c_] = r, de, q1, q2, nr
        c_ += 1
    return idx[:c_], d[:c_], p1[:c_], p2[:c_], n[:c_]


@_jit
def distance_rows(
    Js: np.ndarray,
    mask: np.ndarray,
    ja: np.ndarray,
    jb: np.ndarray,
    n: np.ndarray,
    p1: np.ndarray,
    p2: np.ndarray,
) -> np.ndarray:
    """Rows nᵀ(v_{p₂} − v_{p₁})/q̇, shape (k, nv): for body points p₁ (joint ja[r]) and p₂ (joint jb[r]).

    With the spatial (world) Jacobian J^s (6, nv) and M_j the mask of the velocities supporting joint j,
    nᵀv_p = M_j ⊙ (nᵀJ^s_v + (p × n)ᵀJ^s_ω) (:meth:`redundik.collision.world.CollisionWorld.jacobian`).
    """
    k = n.shape[0]
    nv = Js.shape[1]
    out = np.zeros((k, nv))
    for r in range(k):
        nr = n[r]
        a, b = p1[r], p2[r]
        xa = np.array([a[1] * nr[2] - a[2] * nr[1], a[2] * nr[0] - a[0] * nr[2], a[0] * nr[1] - a[1] * nr[0]])
        xb = np.array([b[1] * nr[2] - b[2] * nr[1], b[2] * nr[0] - b[0] * nr[2], b[0] * nr[1] - b[1] * nr[0]])
        ma, mb = mask[ja[r]], mask[jb[r]]
        for c in range(nv):
            lin = nr[0] * Js[0, c] + nr[1] * Js[1, c] + nr[2] * Js[2, c]
            va = lin + xa[0] * Js[3, c] + xa[1] * Js[4, c] + xa[2] * Js[5, c]
            vb = lin + xb[0] * Js[3, c] + xb[1] * Js[4, c] + xb[2] * Js[5, c]
            out[r, c] = mb[c] * vb - ma[c] * va
    return out

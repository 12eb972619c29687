"""Compiled kernels (numba) of the collision world: capsule–capsule distances, capsule end-sphere distances and the
exact distance Jacobian rows, each one call over all the pairs of a tick.

Why compiled: per pair, the NumPy route would be a dozen small-array operations, mostly call overhead, so with
20 candidate pairs the collision rows would cost several times the rest of a ``wqp`` step; one compiled call over
every pair costs about as much as one of those operations. The formulas are those of
:mod:`redundik.collision.world` (its docstrings carry the derivations); the tests hold the kernels to coal's
distances and to finite differences.

Shapes are described per geometry g by a kind code and four numbers (the layouts of
:mod:`redundik.collision.layouts`, with their units):

* ``CAPSULE`` (a sphere is a capsule of half length 0): ``prm[g]`` the radius R and the half length, axis local z;
* ``BOX``: ``prm[g]`` the half sides along x, y, z;
* ``HALFSPACE``, the solid {x : nᵀx ≤ d} of the geometry's frame: ``prm[g]`` the normal n and d;
* ``OTHER`` (meshes / convex hulls): left to coal.

Poses are world homogeneous transforms ``T`` (G, 4, 4) (rotation ``T[g, :3, :3]``, translation ``T[g, :3, 3]``).

The kernels take their data as records, plain tuples (numba dispatches a tuple of arrays as fast as the arrays),
their slots and columns named in :mod:`redundik.collision.layouts`:

* ``Shapes`` ``(T, kind, prm)``: the geometries' poses, kind codes (G,) and numbers (G, 4);
* ``BranchTable`` ``(br, sign)``: per end-sphere branch r, ``br[r]`` (int, columns ``BR_PAIR``,
  ``BR_CAPSULE``, ``BR_OTHER``, ``BR_FIRST``: the pair, the capsule, the pair's other body, 1 when the
  capsule is body 1 of the pair) and ``sign[r]`` = ±1, the end along the capsule's local z;
* ``PairData`` ``(d, p1, p2, n, rate, near)``: per pair the distance [m] (P,), witness points on body 1 and 2
  and unit normal (P, 3), ∂d/∂t [m/s] (P,), and the indices of the pairs that get rows;
* ``Joints`` ``(mask, pj)``: the joints' support masks (njoints, nv), the pairs' joints (P, 2) (with the spatial
  Jacobian ``Js`` (6, nv) of the tick, a separate argument);
* ``Gains`` ``(reach, influence, safety, gamma, no_cap, ends, qp_cap)``: the damper's numbers
  (``barrier_rows``): reach, d_i, d_s [m], γ, the gain outside d_i [1/s], whether end spheres get rows, the
  QP rate cap [1/s] (0: the rows as h, ∂h/∂q).
"""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.collision.layouts import (
    BOX,
    BOX_HX,
    BOX_HY,
    BOX_HZ,
    BR_CAPSULE,
    BR_FIRST,
    BR_OTHER,
    BR_PAIR,
    CAP_HALF,
    CAP_RADIUS,
    CAPSULE,
    F_DIST,
    F_GAMMA,
    F_H,
    F_JAC,
    F_PAIR,
    F_POINTS,
    GAIN_ENDS,
    GAIN_REACH,
    HALFSPACE,
    HS_D,
    HS_NX,
    HS_NY,
    HS_NZ,
    OTHER,
    PAIR_D,
    PAIR_NEAR,
    PJ_BODY1,
    PJ_BODY2,
    POSES_LIVE,
    POSES_SRC,
    PTS,
    PTS_N,
    PTS_P1,
    PTS_P2,
    TABLE_BR,
)

Shapes = tuple[np.ndarray, np.ndarray, np.ndarray]
BranchTable = tuple[np.ndarray, np.ndarray]
PairData = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
Joints = tuple[np.ndarray, np.ndarray]
Gains = tuple[float, float, float, float, float, bool, float]

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)


@_jit
def load_poses(src: np.ndarray, live: np.ndarray, T: np.ndarray) -> None:
    """T[g] ← the placement ``src[g]`` for g in ``live``: ``src`` (G, 12) per geometry the rotation column-major,
    then the translation (the memory of Pinocchio's ``GeometryData.oMg``, :func:`redundik.collision.world`)."""
    for i in range(live.shape[0]):
        g = live[i]
        for c in range(3):
            for r in range(3):
                T[g, r, c] = src[g, 3 * c + r]
            T[g, c, 3] = src[g, 9 + c]


@_jit
def _dot(a: tuple[float, float, float], b: tuple[float, float, float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@_jit
def _segment_params(
    p1: tuple[float, float, float], d1: tuple[float, float, float], p2: tuple[float, float, float],
    d2: tuple[float, float, float],
) -> tuple[float, float]:  # fmt: skip
    """(s, u) ∈ [0, 1]² minimising |(p1 + s d1) − (p2 + u d2)| (Ericson, Real-Time Collision Detection, §5.1.9)."""
    r = (p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2])
    a = _dot(d1, d1)
    e = _dot(d2, d2)
    f = _dot(d2, r)
    eps = 1e-18
    if a <= eps and e <= eps:
        return 0.0, 0.0
    if a <= eps:
        return 0.0, min(1.0, max(0.0, f / e))
    c = _dot(d1, r)
    if e <= eps:
        return min(1.0, max(0.0, -c / a)), 0.0
    b = _dot(d1, d2)
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
    (|c₂ − c₁| < 1e-12: n undefined; the caller asks coal). Scalar arithmetic only (no temporary arrays).
    """
    m = ia.shape[0]
    d = np.empty(m)
    p1 = np.zeros((m, 3))
    p2 = np.zeros((m, 3))
    n = np.zeros((m, 3))
    ok = np.ones(m, dtype=np.bool_)
    _capsule_pairs_into(T, prm, ia, ib, d, p1, p2, n, ok)
    return d, p1, p2, n, ok


@_jit
def _capsule_pairs_into(
    T: np.ndarray, prm: np.ndarray, ia: np.ndarray, ib: np.ndarray, d: np.ndarray, p1: np.ndarray, p2: np.ndarray,
    n: np.ndarray, ok: np.ndarray,
) -> None:  # fmt: skip
    """:func:`capsule_pairs` into given arrays (p1, p2, n of the pairs whose axes meet: zeros)."""
    for k in range(ia.shape[0]):
        a, b = ia[k], ib[k]
        ra, ha, rb, hb = prm[a, CAP_RADIUS], prm[a, CAP_HALF], prm[b, CAP_RADIUS], prm[b, CAP_HALF]
        za = (T[a, 0, 2] * ha, T[a, 1, 2] * ha, T[a, 2, 2] * ha)
        zb = (T[b, 0, 2] * hb, T[b, 1, 2] * hb, T[b, 2, 2] * hb)
        sa = (T[a, 0, 3] - za[0], T[a, 1, 3] - za[1], T[a, 2, 3] - za[2])
        sb = (T[b, 0, 3] - zb[0], T[b, 1, 3] - zb[1], T[b, 2, 3] - zb[2])
        s, u = _segment_params(sa, (2 * za[0], 2 * za[1], 2 * za[2]), sb, (2 * zb[0], 2 * zb[1], 2 * zb[2]))
        ca = (sa[0] + 2 * s * za[0], sa[1] + 2 * s * za[1], sa[2] + 2 * s * za[2])
        cb = (sb[0] + 2 * u * zb[0], sb[1] + 2 * u * zb[1], sb[2] + 2 * u * zb[2])
        dx, dy, dz = cb[0] - ca[0], cb[1] - ca[1], cb[2] - ca[2]
        L = math.sqrt(dx * dx + dy * dy + dz * dz)
        if L < 1e-12:
            ok[k] = False
            d[k] = -ra - rb
            for i in range(3):
                p1[k, i], p2[k, i], n[k, i] = 0.0, 0.0, 0.0
            continue
        ok[k] = True
        nx, ny, nz = dx / L, dy / L, dz / L
        d[k] = L - ra - rb
        n[k, 0], n[k, 1], n[k, 2] = nx, ny, nz
        p1[k, 0], p1[k, 1], p1[k, 2] = ca[0] + ra * nx, ca[1] + ra * ny, ca[2] + ra * nz
        p2[k, 0], p2[k, 1], p2[k, 2] = cb[0] - rb * nx, cb[1] - rb * ny, cb[2] - rb * nz


@_jit
def _ball_to(
    c: tuple[float, float, float], r: float, kind: int, prm: np.ndarray, T: np.ndarray, o: int
) -> tuple[float, tuple[float, float, float], tuple[float, float, float], tuple[float, float, float], bool]:
    """Ball (centre c, radius r) to shape ``o`` (pose ``T[o]``): (d, point on the ball, point on the shape, unit u
    from the ball to the shape, ok); scalar arithmetic only."""
    z3 = (0.0, 0.0, 0.0)
    if kind == CAPSULE:
        h = prm[CAP_HALF]
        ax = (T[o, 0, 2] * h, T[o, 1, 2] * h, T[o, 2, 2] * h)
        a = (T[o, 0, 3] - ax[0], T[o, 1, 3] - ax[1], T[o, 2, 3] - ax[2])
        s = 0.0
        if h > 0.0:
            L2 = 4.0 * _dot(ax, ax)
            s = min(1.0, max(0.0, 2.0 * ((c[0] - a[0]) * ax[0] + (c[1] - a[1]) * ax[1] + (c[2] - a[2]) * ax[2]) / L2))
        x = (a[0] + 2 * s * ax[0], a[1] + 2 * s * ax[1], a[2] + 2 * s * ax[2])
        v = (x[0] - c[0], x[1] - c[1], x[2] - c[2])
        L = math.sqrt(_dot(v, v))
        if L <= 1e-12:
            return 0.0, z3, z3, z3, False
        u = (v[0] / L, v[1] / L, v[2] / L)
        R0 = prm[CAP_RADIUS]
        pb = (c[0] + r * u[0], c[1] + r * u[1], c[2] + r * u[2])
        ps = (x[0] - R0 * u[0], x[1] - R0 * u[1], x[2] - R0 * u[2])
        return L - r - R0, pb, ps, u, True
    if kind == BOX:
        w = (c[0] - T[o, 0, 3], c[1] - T[o, 1, 3], c[2] - T[o, 2, 3])
        cl0 = T[o, 0, 0] * w[0] + T[o, 1, 0] * w[1] + T[o, 2, 0] * w[2]  # Rᵀ(c − t)
        cl1 = T[o, 0, 1] * w[0] + T[o, 1, 1] * w[1] + T[o, 2, 1] * w[2]
        cl2 = T[o, 0, 2] * w[0] + T[o, 1, 2] * w[1] + T[o, 2, 2] * w[2]
        h0, h1, h2 = prm[BOX_HX], prm[BOX_HY], prm[BOX_HZ]
        b0, b1, b2 = min(max(cl0, -h0), h0), min(max(cl1, -h1), h1), min(max(cl2, -h2), h2)
        v0, v1, v2 = b0 - cl0, b1 - cl1, b2 - cl2
        L = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if L <= 1e-12:  # inside: the nearest face
            d0, d1, d2 = h0 - abs(cl0), h1 - abs(cl1), h2 - abs(cl2)
            if d0 <= d1 and d0 <= d2:
                sg = 1.0 if cl0 >= 0.0 else -1.0
                depth, o0, o1, o2 = d0, sg, 0.0, 0.0
                b0 = sg * h0
            elif d1 <= d2:
                sg = 1.0 if cl1 >= 0.0 else -1.0
                depth, o0, o1, o2 = d1, 0.0, sg, 0.0
                b1 = sg * h1
            else:
                sg = 1.0 if cl2 >= 0.0 else -1.0
                depth, o0, o1, o2 = d2, 0.0, 0.0, sg
                b2 = sg * h2
            # the distance grows when the centre moves outwards (along −u)
            v0, v1, v2, L, dist = -o0, -o1, -o2, 1.0, -depth - r
        else:
            dist = L - r
        ul = (v0 / L, v1 / L, v2 / L)
        u = (
            T[o, 0, 0] * ul[0] + T[o, 0, 1] * ul[1] + T[o, 0, 2] * ul[2],
            T[o, 1, 0] * ul[0] + T[o, 1, 1] * ul[1] + T[o, 1, 2] * ul[2],
            T[o, 2, 0] * ul[0] + T[o, 2, 1] * ul[1] + T[o, 2, 2] * ul[2],
        )
        ps = (
            T[o, 0, 3] + T[o, 0, 0] * b0 + T[o, 0, 1] * b1 + T[o, 0, 2] * b2,
            T[o, 1, 3] + T[o, 1, 0] * b0 + T[o, 1, 1] * b1 + T[o, 1, 2] * b2,
            T[o, 2, 3] + T[o, 2, 0] * b0 + T[o, 2, 1] * b1 + T[o, 2, 2] * b2,
        )
        return dist, (c[0] + r * u[0], c[1] + r * u[1], c[2] + r * u[2]), ps, u, True
    if kind == HALFSPACE:
        nw = (
            T[o, 0, 0] * prm[HS_NX] + T[o, 0, 1] * prm[HS_NY] + T[o, 0, 2] * prm[HS_NZ],
            T[o, 1, 0] * prm[HS_NX] + T[o, 1, 1] * prm[HS_NY] + T[o, 1, 2] * prm[HS_NZ],
            T[o, 2, 0] * prm[HS_NX] + T[o, 2, 1] * prm[HS_NY] + T[o, 2, 2] * prm[HS_NZ],
        )
        h = nw[0] * (c[0] - T[o, 0, 3]) + nw[1] * (c[1] - T[o, 1, 3]) + nw[2] * (c[2] - T[o, 2, 3]) - prm[HS_D]
        u = (-nw[0], -nw[1], -nw[2])
        pb = (c[0] + r * u[0], c[1] + r * u[1], c[2] + r * u[2])
        ps = (c[0] - h * nw[0], c[1] - h * nw[1], c[2] - h * nw[2])
        return h - r, pb, ps, u, True
    return 0.0, z3, z3, z3, False


@_jit
def _end_sphere(
    shapes: Shapes, branches: BranchTable, r: int, pair_d: np.ndarray, pair_p1: np.ndarray, reach: float
) -> tuple[bool, float, tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]:
    """Branch r of ``branches`` (the ball of radius R at one end of a capsule against its pair's other body):
    (kept, d [m], p1, p2, n), p₂ − p₁ = d n from body 1 to body 2 of the pair.

    Kept: within ``reach`` [m], defined (the end off the other shape's axis/centre; not an ``OTHER`` shape) and not
    the pair's own witness (|d_e − d| < 1e-9 with ``pair_d``, the same point within 1e-7 m as ``pair_p1``).
    """
    T, kind, prm = shapes
    br, sign = branches
    z3 = (0.0, 0.0, 0.0)
    k, b, o = br[r, BR_PAIR], br[r, BR_CAPSULE], br[r, BR_OTHER]
    if kind[o] == OTHER:
        return False, 0.0, z3, z3, z3
    e = sign[r] * prm[b, CAP_HALF]
    c = (T[b, 0, 3] + e * T[b, 0, 2], T[b, 1, 3] + e * T[b, 1, 2], T[b, 2, 3] + e * T[b, 2, 2])
    de, ps, po, u, ok = _ball_to(c, prm[b, CAP_RADIUS], kind[o], prm[o], T, o)
    if not ok or de >= reach:
        return False, 0.0, z3, z3, z3
    if br[r, BR_FIRST]:
        q1, q2, nr = ps, po, u
    else:
        q1, q2, nr = po, ps, (-u[0], -u[1], -u[2])
    same = max(abs(q1[0] - pair_p1[k, 0]), abs(q1[1] - pair_p1[k, 1]), abs(q1[2] - pair_p1[k, 2])) < 1e-7
    if abs(de - pair_d[k]) < 1e-9 and same:
        return False, 0.0, z3, z3, z3  # the pair's own witness
    return True, de, q1, q2, nr


@_jit
def end_spheres(
    shapes: Shapes, branches: BranchTable, sel: np.ndarray, pair_d: np.ndarray, pair_p1: np.ndarray, influence: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The end spheres of capsules against their pair's other body, over the branches of the selected pairs.

    Only branches of pairs with ``sel[pair]`` are computed; ``pair_d``/``pair_p1`` (per pair) are the pair's own
    distance and witness on body 1 (:func:`_end_sphere`).

    Returns:
        (branch indices (m,), d (m,), p1 (m, 3), p2 (m, 3), n (m, 3)) of the branches :func:`_end_sphere` keeps with
        reach ``influence`` [m].
    """
    br = branches[TABLE_BR]
    m = br.shape[0]
    idx = np.empty(m, dtype=np.int64)
    d = np.empty(m)
    p1 = np.empty((m, 3))
    p2 = np.empty((m, 3))
    n = np.empty((m, 3))
    c_ = 0
    for r in range(m):
        if not sel[br[r, BR_PAIR]]:
            continue
        kept, de, q1, q2, nr = _end_sphere(shapes, branches, r, pair_d, pair_p1, influence)
        if not kept:
            continue
        idx[c_], d[c_] = r, de
        for i in range(3):
            p1[c_, i], p2[c_, i], n[c_, i] = q1[i], q2[i], nr[i]
        c_ += 1
    return idx[:c_], d[:c_], p1[:c_], p2[:c_], n[:c_]


@_jit
def _row_into(
    out: np.ndarray, r: int, Js: np.ndarray, ma: np.ndarray, mb: np.ndarray,
    nr: tuple[float, float, float], a: tuple[float, float, float], b: tuple[float, float, float],
) -> None:  # fmt: skip
    """out[r] = nᵀ(v_{p₂} − v_{p₁})/q̇ for the body points a (masked by ``ma``) and b (``mb``), unit normal ``nr``."""
    xa0, xa1, xa2 = a[1] * nr[2] - a[2] * nr[1], a[2] * nr[0] - a[0] * nr[2], a[0] * nr[1] - a[1] * nr[0]
    xb0, xb1, xb2 = b[1] * nr[2] - b[2] * nr[1], b[2] * nr[0] - b[0] * nr[2], b[0] * nr[1] - b[1] * nr[0]
    for c in range(Js.shape[1]):
        lin = nr[0] * Js[0, c] + nr[1] * Js[1, c] + nr[2] * Js[2, c]
        va = lin + xa0 * Js[3, c] + xa1 * Js[4, c] + xa2 * Js[5, c]
        vb = lin + xb0 * Js[3, c] + xb1 * Js[4, c] + xb2 * Js[5, c]
        out[r, c] = mb[c] * vb - ma[c] * va


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
    out = np.zeros((k, Js.shape[1]))
    for r in range(k):
        nr = (n[r, 0], n[r, 1], n[r, 2])
        a = (p1[r, 0], p1[r, 1], p1[r, 2])
        b = (p2[r, 0], p2[r, 1], p2[r, 2])
        _row_into(out, r, Js, mask[ja[r]], mask[jb[r]], nr, a, b)
    return out


@_jit
def capsule_distances(
    T: np.ndarray, prm: np.ndarray, ia: np.ndarray, ib: np.ndarray, influence: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`capsule_pairs` over every pair of a world of capsules/spheres only, with the selections of the tick.

    Returns:
        (d (P,), p1 (P, 3), p2 (P, 3), n (P, 3), the pairs whose axes meet (the caller asks coal), the pairs with
        d < ``influence`` [m] (valid when no axes meet)).
    """
    d, p1, p2, n, ok = capsule_pairs(T, prm, ia, ib)
    m = d.shape[0]
    bad = np.empty(m, dtype=np.int64)
    near = np.empty(m, dtype=np.int64)
    nb_, nn_ = 0, 0
    for k in range(m):
        if not ok[k]:
            bad[nb_] = k
            nb_ += 1
        if d[k] < influence:
            near[nn_] = k
            nn_ += 1
    return d, p1, p2, n, bad[:nb_], near[:nn_]


@_jit
def barrier_rows(
    shapes: Shapes, branches: BranchTable, pairs: PairData, joints: Joints, Js: np.ndarray, gains: Gains
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The collision damper's rows in one call: the pairs ``near`` and (``ends``) their capsules' end spheres.

    Rows are the pairs first (in the order of ``near``), then the end-sphere branches of those pairs, kept as in
    :func:`_end_sphere` (within ``reach`` [m]). Per row at distance d: h = d − d_s + rate/γ, gain γ where
    d < ``influence`` [m], else h = d − d_s and gain ``no_cap``; the Jacobian row is :func:`distance_rows`'s. Branch
    rows have no obstacle rate (the caller uses this only without moving obstacles and without ``OTHER`` shapes in a
    branch). The records are those of the module docstring.

    Returns:
        (h (k,) [m], ∂h/∂q (k, nv), γ (k,) [1/s], row ids (k,): the pair index, or P + the branch index); with
        ``qp_cap`` > 0 [1/s] the first two are instead the QP rows C q̇ ≤ d of the damper,
        d = min(γ, ``qp_cap``) h [m/s] and C = −∂h/∂q (:meth:`redundik.tasks.subtasks.BoundSubtask.rows`).
    """
    d, near = pairs[PAIR_D], pairs[PAIR_NEAR]
    br = branches[TABLE_BR]
    P = d.shape[0]
    k0 = near.shape[0]
    m = br.shape[0] if gains[GAIN_ENDS] and k0 else 0
    sel = np.zeros(P, dtype=np.bool_)
    for i in range(k0):
        sel[near[i]] = True
    rows = k0
    for r in range(m):
        if sel[br[r, BR_PAIR]]:
            rows += 1
    H = np.zeros((rows, Js.shape[1]))
    h = np.empty(rows)
    gam = np.empty(rows)
    ids = np.empty(rows, dtype=np.int64)
    c_ = _barrier_rows_into(shapes, branches, pairs, joints, Js, gains, sel, (h, H, gam, ids))
    return h[:c_], H[:c_], gam[:c_], ids[:c_]


@_jit
def _barrier_rows_into(
    shapes: Shapes, branches: BranchTable, pairs: PairData, joints: Joints, Js: np.ndarray, gains: Gains,
    sel: np.ndarray, out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> int:  # fmt: skip
    """``barrier_rows`` into ``out`` = (h, H, γ, row ids) (room for every row; ``sel``: the pairs of ``near``);
    the row count."""
    d, p1, p2, n, rate, near = pairs
    mask, pj = joints
    reach, influence, safety, gamma, no_cap, ends, qp_cap = gains
    h, H, gam, ids = out
    br = branches[TABLE_BR]
    P = d.shape[0]
    k0 = near.shape[0]
    m = br.shape[0] if ends and k0 else 0
    for i in range(k0):
        k = near[i]
        nr = (n[k, 0], n[k, 1], n[k, 2])
        a = (p1[k, 0], p1[k, 1], p1[k, 2])
        b = (p2[k, 0], p2[k, 1], p2[k, 2])
        _row_into(H, i, Js, mask[pj[k, PJ_BODY1]], mask[pj[k, PJ_BODY2]], nr, a, b)
        dk = d[k]
        if dk < influence:
            h[i], gam[i] = dk - safety + rate[k] / gamma, gamma
        else:
            h[i], gam[i] = dk - safety, no_cap
        ids[i] = k
    c_ = k0
    for r in range(m):
        k = br[r, BR_PAIR]
        if not sel[k]:
            continue
        kept, de, q1, q2, nr = _end_sphere(shapes, branches, r, d, p1, reach)
        if not kept:
            continue
        _row_into(H, c_, Js, mask[pj[k, PJ_BODY1]], mask[pj[k, PJ_BODY2]], nr, q1, q2)
        if de < influence:
            h[c_], gam[c_] = de - safety + 0.0 / gamma, gamma
        else:
            h[c_], gam[c_] = de - safety, no_cap
        ids[c_] = P + r
        c_ += 1
    if qp_cap > 0.0:
        for r in range(c_):
            h[r] = min(gam[r], qp_cap) * h[r]
            for col in range(H.shape[1]):
                H[r, col] = -H[r, col]
    return c_


@_jit
def capsule_damper(
    poses: tuple[np.ndarray, np.ndarray], shapes: Shapes, caps: tuple[np.ndarray, np.ndarray],
    branches: BranchTable, joints: Joints, Js: np.ndarray, gains: Gains, F: np.ndarray, I: np.ndarray,
) -> tuple[int, int, int]:  # fmt: skip
    """A static world of capsule/sphere pairs in one call: :func:`load_poses` (``poses`` = (src, live)),
    :func:`capsule_pairs` (every pair, ``caps`` = (ia, ib)), the pairs within ``reach`` [m], then
    ``barrier_rows`` on them (no obstacle rates), written into the caller's fresh arrays (returning arrays costs
    more than the computation):

    * ``F`` (``F_PAIR`` P + (``F_JAC`` + nv) R,): d (P,), p1, p2, n stacked (``PTS``, P, 3), then h (R,), γ (R,),
      ∂h/∂q (R, nv) (the first k entries, rows), with R = P + the number of branches (room for every row; the blocks
      of :mod:`redundik.collision.layouts`);
    * ``I`` (P + R,): the pairs with d < ``reach`` (the first k₀ of P), the row ids (the first k of R).

    Returns:
        (k₀, k, the number of pairs whose axes meet); with axes meeting the rows are left out (k = 0): the caller
        asks coal for those pairs and takes the general route. ``gains`` as in ``barrier_rows``.
    """
    T, _kind, prm = shapes
    ia, ib = caps
    reach = gains[GAIN_REACH]
    P, R, nv = ia.shape[0], branches[TABLE_BR].shape[0] + ia.shape[0], Js.shape[1]
    load_poses(poses[POSES_SRC], poses[POSES_LIVE], T)
    d = F[F_DIST * P : F_POINTS * P]
    pts = F[F_POINTS * P : F_PAIR * P].reshape((PTS, P, 3))
    p1, p2, n = pts[PTS_P1], pts[PTS_P2], pts[PTS_N]
    ok = np.empty(P, dtype=np.bool_)
    _capsule_pairs_into(T, prm, ia, ib, d, p1, p2, n, ok)
    sel = np.zeros(P, dtype=np.bool_)
    bad, k0 = 0, 0
    for k in range(P):
        if not ok[k]:
            bad += 1
        if d[k] < reach:
            I[k0] = k
            sel[k] = True
            k0 += 1
    if bad:
        return k0, 0, bad
    o = F_PAIR * P
    pairs = (d, p1, p2, n, np.zeros(P), I[:k0])
    h, H, gam = (
        F[o + F_H * R : o + F_GAMMA * R],
        F[o + F_JAC * R :].reshape((R, nv)),
        F[o + F_GAMMA * R : o + F_JAC * R],
    )
    k = _barrier_rows_into(shapes, branches, pairs, joints, Js, gains, sel, (h, H, gam, I[P:]))
    return k0, k, 0

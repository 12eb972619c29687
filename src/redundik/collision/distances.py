"""A collision world's distances at one instant (:class:`Distances`, ``Branches``) and the interpreted
reference of the end-sphere distances: per geometry its shape description (``shape_info``) and the kernels'
record of it (``shape_table``), a ball's signed distance to a shape (``sphere_to``, coal for meshes and convex
hulls) and the end-sphere branches whose other body only coal handles (``slow_end_spheres``). The compiled kernels
(:mod:`redundik.collision.kernels`) hold the same formulas; the records' layouts are those of
:mod:`redundik.collision.layouts`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from redundik.collision.layouts import (
    BOX,
    BOX_HALVES,
    BR_CAPSULE,
    BR_FIRST,
    BR_OTHER,
    BR_PAIR,
    CAP_HALF,
    CAP_RADIUS,
    CAPSULE,
    HALFSPACE,
    HS_D,
    HS_NORMAL,
    OTHER,
    SHAPE_PRM,
)


@dataclass
class Distances:
    """Every candidate pair at one instant (pair order of ``CollisionWorld.pair_names``).

    Attributes:
        d: Signed distances [m], shape (P,) (negative: penetration depth).
        p1: Nearest points on body 1, world frame [m], shape (P, 3) (filled for :attr:`near` pairs only).
        p2: Nearest points on body 2 [m], shape (P, 3) (idem).
        n: Unit normals from body 1 to body 2, shape (P, 3) (idem).
        rate: ∂d/∂t from moving obstacles [m/s], shape (P,) (idem).
        near: Indices of the pairs whose witness points were read (d < the influence distance asked for).
    """

    d: np.ndarray
    p1: np.ndarray
    p2: np.ndarray
    n: np.ndarray
    rate: np.ndarray
    near: np.ndarray


@dataclass
class Branches:
    """Sub-shape distances of some pairs (:meth:`redundik.collision.world.CollisionWorld.end_spheres`), one entry per
    branch.

    Attributes:
        pair: The pair index of each branch, shape (m,).
        d: Signed distances [m], shape (m,).
        p1: Nearest points on (the sub-shape of) body 1 [m], shape (m, 3).
        p2: Nearest points on (the sub-shape of) body 2 [m], shape (m, 3).
        n: Unit normals from body 1 to body 2 (p₂ − p₁ = d n), shape (m, 3).
        rate: ∂d/∂t from a moving obstacle (body 2) [m/s], shape (m,).
        names: ``body1|body2@body+`` / ``@body-``: the pair and the end (local +z or −z) of which capsule.
    """

    pair: np.ndarray
    d: np.ndarray
    p1: np.ndarray
    p2: np.ndarray
    n: np.ndarray
    rate: np.ndarray
    names: list[str] = field(default_factory=list)

    @staticmethod
    def empty() -> Branches:
        """No branch."""
        z = np.zeros((0, 3))
        return Branches(np.zeros(0, dtype=int), np.zeros(0), z, z.copy(), z.copy(), np.zeros(0))


def _unit(v: np.ndarray) -> tuple[np.ndarray, float] | None:
    n = math.sqrt(float(v @ v))
    return (v / n, n) if n > 1e-12 else None


_SPHERE_REQ = coal.DistanceRequest()
_SPHERE_REQ.enable_signed_distance = True


def sphere_to(
    c: np.ndarray, r: float, info: tuple[Any, ...], M: pin.SE3
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray] | None:
    """Signed distance [m] of the ball (centre c, radius r) to a shape at pose M: (d, point on the ball, point on the
    shape, unit normal u from the ball to the shape, with p_shape − p_ball = d u), or ``None`` when undefined (the
    centre on a sphere's centre or a capsule's axis)."""
    kind = info[0]
    if kind in ("sphere", "capsule"):
        x = M.translation
        if kind == "capsule":
            ax = M.rotation[:, 2] * info[2]
            a, ab = x - ax, 2 * ax
            s = min(1.0, max(0.0, float((c - a) @ ab) / float(ab @ ab))) if info[2] > 0 else 0.0
            x = a + s * ab
        un = _unit(x - c)
        if un is None:
            return None
        u, L = un
        return L - r - info[1], c + r * u, x - info[1] * u, u
    if kind == "box":
        R, t, hs = M.rotation, M.translation, info[1]
        cl = R.T @ (c - t)
        cb = np.clip(cl, -hs, hs)
        un = _unit(cb - cl)
        if un is not None:  # outside the box
            ul, L = un
            u = R @ ul
            return L - r, c + r * u, t + R @ cb, u
        depth = hs - np.abs(cl)
        a = int(np.argmin(depth))
        out_l = np.zeros(3)
        out_l[a] = 1.0 if cl[a] >= 0 else -1.0
        u = -(R @ out_l)  # the distance grows when the centre moves outwards (along −u)
        face = cl.copy()
        face[a] = out_l[a] * hs[a]
        return -float(depth[a]) - r, c + r * u, t + R @ face, u
    if kind == "halfspace":  # the solid {x : nᵀx ≤ d} of the shape's frame
        nw = M.rotation @ info[1]
        h = float(nw @ (c - M.translation)) - info[2]
        u = -nw
        return h - r, c + r * u, c - h * nw, u
    res = coal.DistanceResult()
    coal.distance(coal.Sphere(r), coal.Transform3s(np.eye(3), c), info[1], coal.Transform3s(M.rotation, M.translation),
                  _SPHERE_REQ, res)  # fmt: skip
    p1, p2 = np.asarray(res.getNearestPoint1()), np.asarray(res.getNearestPoint2())
    d = float(res.min_distance)
    diff = p2 - p1
    nd = math.sqrt(float(diff @ diff))
    u = diff / (nd if d >= 0 else -nd) if nd > 1e-9 else np.asarray(res.normal)
    return d, p1, p2, u


def shape_info(geometry: pin.GeometryModel) -> list[tuple[Any, ...]]:
    """Per geometry: ("capsule", R, half length) | ("sphere", R) | ("box", half sides) | ("halfspace", n, d) |
    ("other", shape) (lengths [m]; the shapes ``sphere_to`` takes)."""
    info: list[tuple[Any, ...]] = []
    for go in geometry.geometryObjects:
        g = go.geometry
        if isinstance(g, coal.Capsule):
            info.append(("capsule", float(g.radius), float(g.halfLength)))
        elif isinstance(g, coal.Sphere):
            info.append(("sphere", float(g.radius)))
        elif isinstance(g, coal.Box):
            info.append(("box", np.asarray(g.halfSide, dtype=float).copy()))
        elif isinstance(g, coal.Halfspace):
            info.append(("halfspace", np.asarray(g.n, dtype=float).copy(), float(g.d)))
        else:
            info.append(("other", g))
    return info


def shape_table(info: list[tuple[Any, ...]]) -> tuple[np.ndarray, np.ndarray]:
    """(kind codes (G,), numbers (G, ``SHAPE_PRM``)) of the geometries described by ``info`` (``shape_info``): the
    kernels' record of the shapes (:mod:`redundik.collision.layouts`; a sphere is a capsule of half length 0)."""
    G = len(info)
    kind = np.full(G, OTHER, dtype=np.int64)
    prm = np.zeros((G, SHAPE_PRM))
    for g, inf in enumerate(info):
        if inf[0] == "capsule":
            kind[g], prm[g, CAP_RADIUS], prm[g, CAP_HALF] = CAPSULE, inf[1], inf[2]
        elif inf[0] == "sphere":
            kind[g], prm[g, CAP_RADIUS], prm[g, CAP_HALF] = CAPSULE, inf[1], 0.0
        elif inf[0] == "box":
            kind[g], prm[g, BOX_HALVES] = BOX, inf[1]
        elif inf[0] == "halfspace":
            kind[g], prm[g, HS_NORMAL], prm[g, HS_D] = HALFSPACE, inf[1], inf[2]
    return kind, prm


def slow_end_spheres(
    info: list[tuple[Any, ...]],
    shapes: tuple[np.ndarray, np.ndarray, np.ndarray],
    table: tuple[np.ndarray, np.ndarray],
    dist: Distances,
    branches: np.ndarray,
    influence: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The end spheres ``branches`` (rows of the branch table ``table``, records of
    :mod:`redundik.collision.kernels`) whose other body only coal handles, one ``sphere_to`` call each:
    (branch indices, d [m], p1, p2, n) of those within ``influence`` [m] that are not the pair's own witness
    (:meth:`redundik.collision.world.CollisionWorld.end_spheres`)."""
    T, _kind, prm = shapes
    br, sign = table
    keep, dd, pp1, pp2, nn = [], [], [], [], []
    for r in branches.tolist():
        k, b, o = int(br[r, BR_PAIR]), int(br[r, BR_CAPSULE]), int(br[r, BR_OTHER])
        c = T[b, :3, 3] + sign[r] * prm[b, CAP_HALF] * T[b, :3, 2]
        hit = sphere_to(c, float(prm[b, CAP_RADIUS]), info[o], pin.SE3(T[o]))
        if hit is None or hit[0] >= influence:
            continue
        d_e, ps, po, u = hit
        q1, q2, nrm = (ps, po, u) if br[r, BR_FIRST] else (po, ps, -u)
        if abs(d_e - dist.d[k]) < 1e-9 and np.abs(q1 - dist.p1[k]).max() < 1e-7:
            continue  # the pair's own witness
        keep.append(r)
        dd.append(d_e)
        pp1.append(q1)
        pp2.append(q2)
        nn.append(nrm)
    z = np.zeros((0, 3))
    if not keep:
        return np.zeros(0, dtype=np.int64), np.zeros(0), z, z, z
    return np.array(keep, dtype=np.int64), np.array(dd), np.array(pp1), np.array(pp2), np.array(nn)

"""Collision geometry: the robot's links from its URDF, approximated by fast primitives, and obstacle shapes.

Raw collision meshes are far too slow for a control tick (all 123 Panda mesh pairs ≈ 23 ms per
``computeDistances``). Each link's collision geometry — every mesh and primitive of the link, in its joint frame —
is replaced by one *enclosing* primitive fitted to its vertices (``approximation``):

* ``capsule`` (default): axis = principal direction of the vertices (PCA), radius R = the largest distance of a
  vertex from that axis, and the segment [a, b] the shortest one such that every vertex lies within R of it
  (a = maxᵢ(tᵢ − √(R² − rᵢ²))... see :func:`fit_capsule`). Enclosing, so a positive capsule distance is a positive
  mesh distance (conservative).
* ``sphere``: the centre of the vertices' bounding box and the largest distance from it (enclosing).
* ``hull``: the convex hull of the vertices (coal ``Convex``; exact for convex links, slower than primitives).
* ``mesh``: the raw meshes (slow; for reference).

Every fitted shape keeps its link's name, parent joint and parent frame, so an SRDF's ``disable_collisions``
(matched by link name) applies to it unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

from redundik.errors import ModelError

#: The approximations :func:`approximate` offers.
APPROXIMATIONS = ("capsule", "sphere", "hull", "mesh")


def shape_points(geometry: object) -> np.ndarray:
    """Points whose hull is the shape (vertices of a mesh, corners of a box, rims of a cylinder), shape (k, 3) [m].

    Raises:
        ModelError: a shape type that cannot be sampled.
    """
    if isinstance(geometry, coal.BVHModelBase):
        return np.asarray(geometry.vertices(), dtype=float).reshape(-1, 3)
    if isinstance(geometry, coal.Box):
        hs = np.asarray(geometry.halfSide, dtype=float)
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        return signs * hs
    if isinstance(geometry, coal.Sphere):
        r = float(geometry.radius)
        return np.vstack([np.eye(3) * r, -np.eye(3) * r])
    if isinstance(geometry, (coal.Cylinder, coal.Capsule)):
        r, hl = float(geometry.radius), float(geometry.halfLength)
        ang = np.linspace(0.0, 2 * np.pi, 16, endpoint=False)
        ring = np.column_stack([r * np.cos(ang), r * np.sin(ang), np.zeros_like(ang)])
        pts = [ring + np.array([0.0, 0.0, hl]), ring - np.array([0.0, 0.0, hl])]
        if isinstance(geometry, coal.Capsule):
            pts.append(np.array([[0, 0, hl + r], [0, 0, -hl - r]]))
        return np.vstack(pts)
    if isinstance(geometry, coal.ConvexBase):
        return np.asarray(geometry.points(), dtype=float).reshape(-1, 3)
    raise ModelError(f"cannot approximate a collision shape of type {type(geometry).__name__}")


@dataclass(frozen=True)
class FittedShape:
    """A primitive fitted to points: the shape and its placement in the points' frame."""

    shape: object
    placement: pin.SE3


def fit_capsule(points: np.ndarray) -> FittedShape:
    """The enclosing capsule of ``points`` (k, 3) [m] about their principal axis.

    With the axis u through the centroid c, each point has an axial coordinate tᵢ and a radial distance rᵢ; the
    radius is R = maxᵢ rᵢ and the segment [a, b] along u must satisfy |tᵢ − clamp(tᵢ, a, b)| ≤ √(R² − rᵢ²), i.e.
    a = maxᵢ... the tightest choice is a = minᵢ(tᵢ + sᵢ), b = maxᵢ(tᵢ − sᵢ), sᵢ = √(R² − rᵢ²) (if a > b the capsule
    degenerates to a sphere-like one at (a + b)/2 with R enlarged to cover every point).
    """
    pts = np.asarray(points, dtype=float)
    c = pts.mean(axis=0)
    X = pts - c
    _, _, vt = np.linalg.svd(X, full_matrices=False)
    u = vt[0]
    t = X @ u
    radial = X - np.outer(t, u)
    r = np.linalg.norm(radial, axis=1)
    R = max(float(r.max()), 1e-4)
    s = np.sqrt(np.maximum(R * R - r * r, 0.0))
    a, b = float(np.min(t + s)), float(np.max(t - s))
    if a > b:
        a = b = 0.5 * (a + b)
    mid = c + 0.5 * (a + b) * u
    # R must cover every point's distance to the segment (exact by construction; guard rounding)
    seg_t = np.clip(t, a, b)
    R = max(R, float(np.max(np.linalg.norm(X - np.outer(seg_t, u), axis=1))) * (1 + 1e-9))
    z = u
    x = np.cross(z, [1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.cross(z, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return FittedShape(coal.Capsule(R, max(b - a, 0.0)), pin.SE3(np.column_stack([x, y, z]), mid))


def fit_sphere(points: np.ndarray) -> FittedShape:
    """The enclosing sphere centred on the bounding box of ``points`` (k, 3) [m]."""
    pts = np.asarray(points, dtype=float)
    c = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    R = max(float(np.max(np.linalg.norm(pts - c, axis=1))), 1e-4)
    return FittedShape(coal.Sphere(R), pin.SE3(np.eye(3), c))


def fit_hull(points: np.ndarray) -> FittedShape:
    """The convex hull of ``points`` (k, 3) [m] as a coal ``Convex``."""
    pts = np.asarray(points, dtype=float)
    bvh = coal.BVHModelOBBRSS()
    bvh.beginModel(0, len(pts))
    bvh.addVertices(pts)
    bvh.endModel()
    bvh.buildConvexHull(True, "Qt")
    return FittedShape(bvh.convex, pin.SE3.Identity())


_FITS = {"capsule": fit_capsule, "sphere": fit_sphere, "hull": fit_hull}


def package_dirs_for(urdf: Path) -> list[str]:
    """Folders where ``package://`` mesh paths of ``urdf`` resolve: the example-robot-data share and the parents."""
    from redundik.kinematics import example_robot_data_dir

    dirs = [str(p) for p in list(urdf.resolve().parents)[:4]]
    try:
        dirs.insert(0, str(example_robot_data_dir().parent.parent))
    except ModelError:
        pass
    return dirs


def load_collision_model(
    model: pin.Model, urdf: str | Path, package_dirs: Sequence[str] | None = None
) -> pin.GeometryModel:
    """The URDF's ``<collision>`` geometry for ``model`` (built from the same URDF).

    Raises:
        ModelError: missing URDF, or a mesh file that is missing or unreadable (names it).
    """
    path = Path(urdf)
    if not path.is_file():
        raise ModelError(f"URDF file '{path}' does not exist")
    dirs = list(package_dirs) if package_dirs is not None else package_dirs_for(path)
    try:
        return pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.COLLISION, package_dirs=dirs)
    except Exception as exc:  # C++ errors (missing mesh, parse error) come as ValueError/RuntimeError
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ModelError(f"could not load the collision geometry of '{path.name}': {msg}") from exc


def approximate(model: pin.Model, geom: pin.GeometryModel, approximation: str = "capsule") -> pin.GeometryModel:
    """One primitive per link (the union of the link's collision shapes), see the module docstring.

    Raises:
        ModelError: unknown approximation (lists the valid ones).
    """
    if approximation not in APPROXIMATIONS:
        raise ModelError(f"unknown collision approximation '{approximation}'; available: {', '.join(APPROXIMATIONS)}")
    out = pin.GeometryModel()
    if approximation == "mesh":
        for go in geom.geometryObjects:
            out.addGeometryObject(
                pin.GeometryObject(go.name, go.parentJoint, go.parentFrame, go.placement, go.geometry)
            )
        return out
    groups: dict[int, list[np.ndarray]] = {}
    joints: dict[int, int] = {}
    for go in geom.geometryObjects:
        pts = shape_points(go.geometry)  # meshes are loaded already scaled
        M = go.placement  # shape frame in the joint frame
        pts_j = pts @ np.asarray(M.rotation).T + np.asarray(M.translation)
        groups.setdefault(int(go.parentFrame), []).append(pts_j)
        joints[int(go.parentFrame)] = int(go.parentJoint)
    fit = _FITS[approximation]
    for fid, chunks in groups.items():
        f = fit(np.vstack(chunks))
        name = model.frames[fid].name
        out.addGeometryObject(pin.GeometryObject(name, joints[fid], fid, f.placement, f.shape))
    return out

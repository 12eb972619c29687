"""The collision world of a replay: obstacles at their poses and sizes, the robot's collision shapes (the fitted
capsules the distances are computed on) and, per drawn sample, the closest pair's witness segment and distance.

Everything is read from a :class:`~redundik.collision.CollisionWorld` (no browser here): obstacle sizes from their
coal shapes, poses from :meth:`~redundik.collision.Obstacle.placement_at` (moving obstacles move), link-shape poses
as ``oMi[joint] · placement`` (Pinocchio's ``updateGeometryPlacements``), distances from
:meth:`~redundik.collision.CollisionWorld.compute` — the numbers of the run's ``min_distance`` series.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import coal
import numpy as np

from redundik.viewer.scene import box_mesh, cylinder_mesh, geometry_mesh, sphere_mesh

#: Colour of obstacles and of the robot's collision shapes [RGB in 0..1].
OBSTACLE_COLOR = (0.85, 0.35, 0.3)
SHAPE_COLOR = (0.2, 0.55, 0.95)


@dataclass
class WorldShape:
    """One drawable collision shape.

    Attributes:
        name: Obstacle or link name (the world's).
        kind: ``box``, ``sphere``, ``capsule``, ``cylinder``, ``plane`` or ``mesh`` (a convex hull).
        size: Its sizes [length unit]: ``radius``, ``length`` (of a capsule's or cylinder's axis, along local z),
            ``size`` (a box's full side lengths).
        vertices: Mesh in the shape frame, shape (V, 3), float32.
        triangles: Vertex indices, shape (T, 3), uint32.
        pose: An obstacle's pose in the world at t = 0 (4×4); ``None`` for a link shape (it moves with its joint).
    """

    name: str
    kind: str
    size: dict[str, Any]
    vertices: np.ndarray
    triangles: np.ndarray
    pose: np.ndarray | None = None


@dataclass
class WorldFrames:
    """The world at a run's drawn samples (F of them).

    Attributes:
        obstacle_poses: 3×4 obstacle → world matrices, row-major, shape (F, K, 12).
        shape_poses: 3×4 link shape → world matrices, shape (F, L, 12).
        distance: The smallest signed distance over every candidate pair [length unit], shape (F,) (< 0: penetration).
        p1: Its witness point on body 1 [length unit], shape (F, 3).
        p2: Its witness point on body 2, shape (F, 3).
        pair: Index of the closest pair into the world's ``pair_names``, shape (F,).
    """

    obstacle_poses: np.ndarray
    shape_poses: np.ndarray
    distance: np.ndarray
    p1: np.ndarray
    p2: np.ndarray
    pair: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))


def capsule_mesh(radius: float, half_length: float) -> tuple[np.ndarray, np.ndarray]:
    """A capsule of ``radius`` [m] around the local z axis from −``half_length`` to +``half_length`` [m]."""
    v1, t1 = cylinder_mesh(radius, -half_length, half_length, sides=16)
    v2, t2 = sphere_mesh(radius, rings=8, sides=16)
    v3 = v2.copy()
    v2[:, 2] -= half_length
    v3[:, 2] += half_length
    v = np.vstack([v1, v2, v3]).astype(np.float32)
    t = np.vstack([t1, t2 + len(v1), t2 + len(v1) + len(v2)]).astype(np.uint32)
    return v, t


def _hull_mesh(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    from scipy.spatial import ConvexHull

    hull = ConvexHull(points)
    return points.astype(np.float32), hull.simplices.astype(np.uint32)


def shape_of(name: str, geom: object, extent: float) -> WorldShape | None:
    """The :class:`WorldShape` of a coal geometry (``None`` for a kind not drawn); ``extent`` [m] sizes a plane."""
    if isinstance(geom, coal.Box):
        half = np.asarray(geom.halfSide, dtype=float)
        v, t = box_mesh(half.tolist())
        return WorldShape(name, "box", {"size": (2 * half).tolist()}, v, t)
    if isinstance(geom, coal.Sphere):
        r = float(geom.radius)
        v, t = sphere_mesh(r, rings=12, sides=24)
        return WorldShape(name, "sphere", {"radius": r}, v, t)
    if isinstance(geom, coal.Capsule):
        r, hl = float(geom.radius), float(geom.halfLength)
        v, t = capsule_mesh(r, hl)
        return WorldShape(name, "capsule", {"radius": r, "length": 2 * hl}, v, t)
    if isinstance(geom, coal.Cylinder):
        r, hl = float(geom.radius), float(geom.halfLength)
        v, t = cylinder_mesh(r, -hl, hl, sides=24)
        return WorldShape(name, "cylinder", {"radius": r, "length": 2 * hl}, v, t)
    if isinstance(geom, coal.Halfspace):  # solid below the plane nᵀx = d: a thin square slab under it
        n = np.asarray(geom.n, dtype=float)
        if not np.allclose(n, [0.0, 0.0, 1.0]):
            return None  # obstacles' planes are z ≤ 0 of their frame (make_shape); others are not drawn
        v, t = box_mesh([extent, extent, 0.005 * extent])
        v = v - np.array([0.0, 0.0, 0.005 * extent - float(geom.d)], dtype=np.float32)
        return WorldShape(name, "plane", {"extent": extent}, v, t)
    points = getattr(geom, "points", None)
    if points is not None and int(getattr(geom, "num_points", 0)) >= 4:  # a convex hull (obstacle mesh, link hull)
        pts = np.asarray([np.asarray(p, dtype=float) for p in points]).reshape(-1, 3)
        v, t = _hull_mesh(pts)
        return WorldShape(name, "mesh", {"points": int(pts.shape[0])}, v, t)
    mesh = geometry_mesh(geom, 2500)  # a link's own mesh (approximation "mesh")
    if mesh is not None:
        return WorldShape(name, "mesh", {"points": int(mesh[0].shape[0])}, *mesh)
    return None


def world_obstacles(world: Any, extent: float = 1.0) -> list[tuple[int, WorldShape]]:
    """(index into ``world.obstacles``, shape) of every drawable obstacle."""
    out = []
    for k, ob in enumerate(world.obstacles):
        shape = shape_of(ob.name, ob.shape, extent)
        if shape is not None:
            shape.pose = np.asarray(ob.placement_at(0.0).homogeneous, dtype=float)
            out.append((k, shape))
    return out


def link_shapes(world: Any) -> list[tuple[int, WorldShape]]:
    """(geometry index, shape) of every robot collision shape of the world (its fitted capsules ...)."""
    out = []
    objs = world.geometry.geometryObjects
    for g in range(world.n_links):
        shape = shape_of(world.link_names[g], objs[g].geometry, 1.0)
        if shape is not None:
            out.append((g, shape))
    return out


def sample_world(
    world: Any,
    robot: Any,
    t: np.ndarray,
    q: np.ndarray,
    obstacles: Sequence[int],
    shapes: Sequence[int],
) -> WorldFrames:
    """Obstacle and link-shape poses and the closest pair at the samples (t [s] (F,), q (F, nq)) of a run.

    Args:
        world: The collision world.
        robot: Its robot.
        t: Sample times [s] (moving obstacles are placed at them).
        q: Configurations.
        obstacles: Indices into ``world.obstacles`` drawn (:func:`world_obstacles`).
        shapes: Geometry indices of the link shapes drawn (:func:`link_shapes`).
    """
    n = q.shape[0]
    ob_poses = np.empty((n, len(obstacles), 12), dtype=np.float32)
    sh_poses = np.empty((n, len(shapes), 12), dtype=np.float32)
    dist = np.full(n, np.inf)
    p1, p2 = np.zeros((n, 3)), np.zeros((n, 3))
    pair = np.full(n, -1, dtype=int)
    objs = world.geometry.geometryObjects
    try:
        for k in range(n):
            robot.update(q[k])
            world.set_time(float(t[k]))
            for i, ob in enumerate(obstacles):
                ob_poses[k, i] = world.obstacles[ob].placement_at(float(t[k])).homogeneous[:3].reshape(-1)
            for i, g in enumerate(shapes):
                M = robot.data.oMi[objs[g].parentJoint] * objs[g].placement
                sh_poses[k, i] = np.asarray(M.homogeneous)[:3].reshape(-1)
            if world.n_pairs:
                d = world.compute(robot)
                j = int(np.argmin(d.d))
                dist[k], p1[k], p2[k], pair[k] = float(d.d[j]), d.p1[j], d.p2[j], j
    finally:
        world.set_time(0.0)
    return WorldFrames(ob_poses, sh_poses, dist, p1, p2, pair)

"""What a replay draws, computed with Pinocchio: decimated link meshes, their world poses per sample, paths.

No browser, meshcat or matplotlib here: only numpy and Pinocchio. A URDF robot contributes its ``<visual>``
geometry (meshes through coal/assimp, boxes, cylinders, spheres), decimated by vertex clustering; a robot without a
URDF (D-H tables) gets one cylinder per drawn segment, whose per-sample transform stretches it between the two frames.
Every part carries a 3×4 affine matrix per sample (rigid for meshes, scaled for segment cylinders).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from redundik.errors import ModelError
from redundik.kinematics.model import RobotModel

#: Default colour of parts whose URDF gives none [RGB in 0..1].
DEFAULT_COLOR = (0.82, 0.84, 0.88)


@dataclass
class MeshPart:
    """One drawable part of the robot.

    Attributes:
        name: Geometry or segment name.
        vertices: Vertex positions in the part frame [m], shape (V, 3), float32.
        triangles: Vertex indices, shape (T, 3), uint32.
        color: RGB in 0..1.
        joint: Index of the Pinocchio joint moving the part (0: the world).
        placement: Part frame in its joint frame, 4×4 (meshes); ``None`` for a segment cylinder.
        segment: (frame, frame) for a segment cylinder, else ``None``.
        radius: Segment cylinder radius [m].
    """

    name: str
    vertices: np.ndarray
    triangles: np.ndarray
    color: tuple[float, float, float] = DEFAULT_COLOR
    joint: int = 0
    placement: np.ndarray | None = None
    segment: tuple[str, str] | None = None
    radius: float = 0.0


@dataclass
class PathSet:
    """Desired and actual positions of one task frame over a run [m], shapes (N, 3)."""

    name: str
    frame: str
    desired: np.ndarray
    actual: np.ndarray


@dataclass
class Obstacle:
    """A round obstacle: a sphere, or with ``vertical`` an infinite post (drawn ``height`` tall) [m]."""

    name: str
    center: np.ndarray
    radius: float
    vertical: bool = False
    height: float = 1.0


@dataclass
class RunFrames:
    """One run, sampled for drawing.

    Attributes:
        name: Run name.
        t: Sample times [s], shape (F,).
        q: Configurations, shape (F, nq).
        poses: Per sample and part, the 3×4 affine part → world matrix, shape (F, P, 12), row-major.
        proximity: Per sample and part, joint-limit proximity of the part's joint in 0..1 (1 at a limit), (F, P).
        paths: Desired/actual paths of the task frames (all samples of the run, not only the drawn ones).
        info: Scalars shown next to the run (resolver, max task error ...).
    """

    name: str
    t: np.ndarray
    q: np.ndarray
    poses: np.ndarray
    proximity: np.ndarray
    paths: list[PathSet] = field(default_factory=list)
    info: dict[str, object] = field(default_factory=dict)


# ---------------------------------------------------------------------------------------------------- primitives
def box_mesh(half: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """A box of half extents ``half`` [m] centred at the origin: (vertices (8, 3), triangles (12, 3))."""
    hx, hy, hz = (float(h) for h in half)
    v = np.array([[sx * hx, sy * hy, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = [(a, b, c) for a, b, c, d in faces] + [(a, c, d) for a, b, c, d in faces]
    return v.astype(np.float32), np.array(tris, dtype=np.uint32)


def cylinder_mesh(radius: float, z0: float, z1: float, sides: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """A closed cylinder of ``radius`` [m] along z from ``z0`` to ``z1`` [m]."""
    a = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
    ring = np.column_stack([radius * np.cos(a), radius * np.sin(a)])
    v = np.vstack(
        [
            np.column_stack([ring, np.full(sides, z0)]),
            np.column_stack([ring, np.full(sides, z1)]),
            [[0, 0, z0]],
            [[0, 0, z1]],
        ]
    )
    tris = []
    c0, c1 = 2 * sides, 2 * sides + 1
    for i in range(sides):
        j = (i + 1) % sides
        tris += [(i, j, sides + j), (i, sides + j, sides + i), (c0, j, i), (c1, sides + i, sides + j)]
    return v.astype(np.float32), np.array(tris, dtype=np.uint32)


def sphere_mesh(radius: float, rings: int = 8, sides: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """A UV sphere of ``radius`` [m] centred at the origin."""
    verts = [[0.0, 0.0, radius]]
    for i in range(1, rings):
        th = np.pi * i / rings
        for k in range(sides):
            ph = 2 * np.pi * k / sides
            verts.append([radius * np.sin(th) * np.cos(ph), radius * np.sin(th) * np.sin(ph), radius * np.cos(th)])
    verts.append([0.0, 0.0, -radius])
    bottom = len(verts) - 1
    tris = [(0, 1 + k, 1 + (k + 1) % sides) for k in range(sides)]
    for i in range(rings - 2):
        a, b = 1 + i * sides, 1 + (i + 1) * sides
        for k in range(sides):
            kk = (k + 1) % sides
            tris += [(a + k, b + k, b + kk), (a + k, b + kk, a + kk)]
    last = 1 + (rings - 2) * sides
    tris += [(bottom, last + (k + 1) % sides, last + k) for k in range(sides)]
    return np.array(verts, dtype=np.float32), np.array(tris, dtype=np.uint32)


def decimate(vertices: np.ndarray, triangles: np.ndarray, max_triangles: int) -> tuple[np.ndarray, np.ndarray]:
    """Reduce a triangle mesh to at most ``max_triangles`` by vertex clustering on a grid.

    Vertices falling into one grid cell merge into their mean; collapsed and duplicate triangles are dropped. The
    cell starts at 1/200 of the bounding-box diagonal and grows by 1.3× until the mesh is small enough.
    """
    v = np.asarray(vertices, dtype=np.float64)
    tri = np.asarray(triangles, dtype=np.int64)
    if tri.shape[0] <= max_triangles or v.shape[0] == 0:
        return v.astype(np.float32), tri.astype(np.uint32)
    lo = v.min(axis=0)
    diag = float(np.linalg.norm(v.max(axis=0) - lo)) or 1.0
    cell = diag / 200.0
    while True:
        keys = np.floor((v - lo) / cell).astype(np.int64)
        _, inverse = np.unique(keys, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        t = inverse[tri]
        keep = (t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])
        t = t[keep]
        if t.shape[0]:
            t = np.unique(t, axis=0)
        if t.shape[0] <= max_triangles or cell > diag:
            break
        cell *= 1.3
    n = int(inverse.max()) + 1
    counts = np.bincount(inverse, minlength=n).astype(np.float64)
    centers = np.column_stack([np.bincount(inverse, weights=v[:, i], minlength=n) for i in range(3)]) / counts[:, None]
    used = np.unique(t)
    remap = np.full(n, -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    return centers[used].astype(np.float32), remap[t].astype(np.uint32)


# ---------------------------------------------------------------------------------------------------- robot parts
def _package_dirs(urdf: Path) -> list[str]:
    dirs = [str(p) for p in urdf.resolve().parents]
    try:
        from redundik.kinematics import example_robot_data_dir

        dirs.insert(0, str(example_robot_data_dir().parent.parent))
    except ModelError:
        pass
    return dirs


def geometry_mesh(geom: object, max_triangles: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Vertices and triangles of a coal geometry, or ``None`` for a kind not drawn."""
    kind = type(geom).__name__
    if kind.startswith("BVHModel") or kind.startswith("Convex"):
        n = int(geom.num_tris)  # type: ignore[attr-defined]
        if n == 0:
            return None
        v = np.asarray(geom.vertices(), dtype=np.float64)  # type: ignore[attr-defined]
        tri_at = geom.tri_indices  # type: ignore[attr-defined]
        t = np.array([[tri_at(i)[0], tri_at(i)[1], tri_at(i)[2]] for i in range(n)], dtype=np.int64)
        return decimate(v, t, max_triangles)
    if kind == "Box":
        return box_mesh(np.asarray(geom.halfSide).tolist())  # type: ignore[attr-defined]
    if kind == "Cylinder":
        h = float(geom.halfLength)  # type: ignore[attr-defined]
        return cylinder_mesh(float(geom.radius), -h, h)  # type: ignore[attr-defined]
    if kind == "Sphere":
        return sphere_mesh(float(geom.radius))  # type: ignore[attr-defined]
    if kind == "Capsule":
        h, r = float(geom.halfLength), float(geom.radius)  # type: ignore[attr-defined]
        v1, t1 = cylinder_mesh(r, -h, h)
        v2, t2 = sphere_mesh(r)
        v3 = v2.copy()
        v2[:, 2] -= h
        v3[:, 2] += h
        v = np.vstack([v1, v2, v3])
        return v, np.vstack([t1, t2 + len(v1), t2 + len(v1) + len(v2)]).astype(np.uint32)
    return None


def visual_parts(robot: RobotModel, urdf: Path, max_triangles: int = 2500) -> list[MeshPart]:
    """The URDF's visual geometry on the redundik model, one decimated part per geometry object.

    Raises:
        ModelError: if Pinocchio cannot read the visual geometry (missing meshes ...).
    """
    try:
        gmodel = pin.buildGeomFromUrdf(
            robot.model, str(urdf), pin.GeometryType.VISUAL, package_dirs=_package_dirs(urdf)
        )
    except Exception as exc:  # pinocchio raises ValueError/RuntimeError from C++
        raise ModelError(f"could not load the visual geometry of '{urdf}': {exc}") from exc
    parts: list[MeshPart] = []
    for g in gmodel.geometryObjects:
        mesh = geometry_mesh(g.geometry, max_triangles)
        if mesh is None:
            continue
        v, t = mesh
        v = (v * np.asarray(g.meshScale, dtype=np.float32)).astype(np.float32)
        color = tuple(float(c) for c in np.asarray(g.meshColor)[:3])
        if np.allclose(color, 0.9) or np.allclose(color, 0.0):  # Pinocchio's default: the DAE colours are lost
            color = DEFAULT_COLOR
        parts.append(MeshPart(g.name, v, t, color, int(g.parentJoint), np.asarray(g.placement.homogeneous)))  # type: ignore[arg-type]
    return parts


def segment_parts(robot: RobotModel, segments: Sequence[tuple[str, str]], radius: float) -> list[MeshPart]:
    """One unit cylinder (z from 0 to 1, radius 1) per (frame, frame) segment; :func:`sample_run` stretches it."""
    v, t = cylinder_mesh(1.0, 0.0, 1.0, sides=12)
    parts = []
    for a, b in segments:
        jid = int(robot.model.frames[robot.frame_id(b)].parentJoint)
        parts.append(MeshPart(f"{a}→{b}", v, t, DEFAULT_COLOR, jid, None, (a, b), radius))
    return parts


def robot_parts(
    robot: RobotModel,
    urdf: Path | None,
    segments: Sequence[tuple[str, str]] = (),
    max_triangles: int = 2500,
) -> list[MeshPart]:
    """Visual meshes when a URDF is known and has any, otherwise segment cylinders sized to the robot."""
    if urdf is not None:
        parts = visual_parts(robot, urdf, max_triangles)
        if parts:
            return parts
    if not segments:
        raise ModelError(f"robot '{robot.name}': no visual geometry and no segments to draw")
    q = robot.neutral()
    robot.update(q)
    lengths = [float(np.linalg.norm(robot.frame_position(b) - robot.frame_position(a))) for a, b in segments]
    scale = max(lengths) if lengths and max(lengths) > 0 else 1.0
    return segment_parts(robot, segments, 0.04 * scale)


def _segment_matrix(pa: np.ndarray, pb: np.ndarray, radius: float) -> np.ndarray:
    """Affine 3×4 mapping the unit cylinder onto the segment pa → pb with ``radius``."""
    d = pb - pa
    length = float(np.linalg.norm(d))
    z = d / length if length > 1e-12 else np.array([0.0, 0.0, 1.0])
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.empty((3, 4))
    m[:, 0], m[:, 1], m[:, 2], m[:, 3] = x * radius, y * radius, z * max(length, 1e-9), pa
    return m


def limit_proximity(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """Per Pinocchio joint (index 0 = world), 1 − distance to the nearer limit / half range, clipped to 0..1."""
    model = robot.model
    out = np.zeros(model.njoints)
    for j in range(1, model.njoints):
        jm = model.joints[j]
        if jm.nq != 1:
            continue
        lo, hi = float(model.lowerPositionLimit[jm.idx_q]), float(model.upperPositionLimit[jm.idx_q])
        if not (np.isfinite(lo) and np.isfinite(hi)) or hi - lo <= 0 or hi - lo > 1e6:
            continue
        half = 0.5 * (hi - lo)
        v = float(q[jm.idx_q])
        out[j] = float(np.clip(1.0 - min(v - lo, hi - v) / half, 0.0, 1.0))
    return out


def sample_run(
    robot: RobotModel,
    parts: Sequence[MeshPart],
    name: str,
    t: np.ndarray,
    q: np.ndarray,
    max_frames: int = 400,
) -> RunFrames:
    """Part poses and limit proximity at (at most ``max_frames``, evenly spaced, last included) samples of a run."""
    n = q.shape[0]
    idx = np.unique(np.linspace(0, n - 1, min(n, max_frames)).round().astype(int))
    poses = np.empty((idx.size, len(parts), 12), dtype=np.float32)
    prox = np.empty((idx.size, len(parts)), dtype=np.float32)
    for k, i in enumerate(idx):
        robot.update(q[i])
        pj = limit_proximity(robot, q[i])
        for p, part in enumerate(parts):
            if part.segment is not None:
                a, b = part.segment
                m = _segment_matrix(robot.frame_position(a), robot.frame_position(b), part.radius)
            else:
                assert part.placement is not None
                m = (robot.data.oMi[part.joint].homogeneous @ part.placement)[:3]
            poses[k, p] = m.reshape(-1)
            prox[k, p] = pj[part.joint]
    return RunFrames(name, np.asarray(t)[idx], np.asarray(q)[idx], poses, prox)


def world_bounds(parts: Sequence[MeshPart], runs: Sequence[RunFrames]) -> tuple[np.ndarray, float]:
    """Centre [m] and radius [m] of a sphere holding every part at every drawn sample, and every path."""
    pts = []
    for run in runs:
        for k in range(0, run.poses.shape[0], max(1, run.poses.shape[0] // 8)):
            for p, part in enumerate(parts):
                m = run.poses[k, p].reshape(3, 4).astype(np.float64)
                lo, hi = part.vertices.min(axis=0), part.vertices.max(axis=0)
                corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
                pts.append(corners @ m[:, :3].T + m[:, 3])
        for path in run.paths:
            pts += [path.desired, path.actual]
    allp = np.vstack(pts) if pts else np.zeros((1, 3))
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    return 0.5 * (lo + hi), max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)

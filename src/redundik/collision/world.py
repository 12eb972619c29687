"""The collision world: the robot's fitted link shapes, obstacles (static or moving), the filtered pair list, and
per-tick distances with witness points and their exact Jacobian.

Distances come from coal (through Pinocchio's ``computeDistances``) on the primitives of
:mod:`redundik.collision.geometry`; for every pair (body 1, body 2) coal gives the signed distance d, the nearest
points p₁, p₂ (world frame) and the unit normal n with p₂ − p₁ = d n (also when penetrating, d < 0). The distance
Jacobian is then exact (Faverjon & Tournassoud 1987; Kanoun, Lamiraux & Wieber 2011, eq. of the collision task):

    ∂d/∂q = nᵀ (J_{p₂} − J_{p₁}),   J_p = J_v(joint) − [p − o_joint]× J_ω(joint)

with the base-aligned (``LOCAL_WORLD_ALIGNED``) joint Jacobian at the joint origin o (rows v, ω): the velocity of
the body point coinciding with p. Where the nearest points are unique (generic for strictly convex primitives)
this is the true derivative; the tests check it against finite differences.

Pair filtering (done once, at construction): pairs on the same joint or on adjacent joints (parent and child), the
SRDF's ``disable_collisions`` (the Panda's and TALOS's ship with example-robot-data; MoveIt's "Adjacent", "Never",
"Default" pairs), user-given pairs, pairs of two bodies that cannot move (both fixed to the world), and — with
:meth:`CollisionWorld.exclude_colliding_at` — self pairs whose enclosing shapes already overlap at a reference
configuration (they would be structural contacts of the approximation, not of the robot).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from redundik.collision import kernels as KC
from redundik.collision.geometry import approximate, load_collision_model
from redundik.errors import ModelError
from redundik.kinematics.memory import se3_vector_view
from redundik.kinematics.model import RobotModel


# ---------------------------------------------------------------------------------------------------- obstacles
@dataclass(frozen=True)
class Motion:
    """A translational obstacle motion: offset(t) = v t + A ⊙ sin(2π f t + φ) [m] added to the obstacle's pose.

    Attributes:
        velocity: v [m/s], shape (3,).
        amplitude: A [m], shape (3,).
        frequency: f [Hz] ≥ 0.
        phase: φ [rad].
    """

    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    amplitude: tuple[float, float, float] = (0.0, 0.0, 0.0)
    frequency: float = 0.0
    phase: float = 0.0

    def __post_init__(self) -> None:
        vals = [*self.velocity, *self.amplitude, self.frequency, self.phase]
        if len(self.velocity) != 3 or len(self.amplitude) != 3 or not all(math.isfinite(float(v)) for v in vals):
            raise ModelError("obstacle motion: velocity and amplitude need 3 finite numbers, frequency/phase finite")
        if self.frequency < 0:
            raise ModelError(f"obstacle motion: frequency must be ≥ 0 [Hz], got {self.frequency}")

    def offset(self, t: float) -> np.ndarray:
        """Displacement at time t [s], shape (3,) [m]."""
        w = 2 * math.pi * self.frequency
        return np.asarray(self.velocity) * t + np.asarray(self.amplitude) * math.sin(w * t + self.phase)

    def rate(self, t: float) -> np.ndarray:
        """Velocity at time t [s], shape (3,) [m/s]."""
        w = 2 * math.pi * self.frequency
        return np.asarray(self.velocity) + np.asarray(self.amplitude) * w * math.cos(w * t + self.phase)


#: Obstacle kinds and their size parameters.
OBSTACLE_KINDS: dict[str, tuple[str, ...]] = {
    "sphere": ("radius",),
    "box": ("size",),
    "capsule": ("radius", "length"),
    "cylinder": ("radius", "length"),
    "plane": (),
    "mesh": ("path",),
}


def _positive(value: float, what: str, allow_zero: bool = False) -> float:
    v = float(value)
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ModelError(f"{what} must be a finite number {'≥' if allow_zero else '>'} 0 [m], got {value}")
    return v


def make_shape(
    kind: str,
    *,
    radius: float | None = None,
    length: float | None = None,
    size: Sequence[float] | None = None,
    path: str | Path | None = None,
    scale: Sequence[float] = (1.0, 1.0, 1.0),
) -> object:
    """A coal shape for an obstacle of ``kind`` (see :data:`OBSTACLE_KINDS`); sizes in [m].

    ``box`` takes full side lengths ``size`` (3,); ``capsule``/``cylinder`` a ``radius`` and the ``length`` of the
    axis (along local z); ``plane`` is the half-space z ≤ 0 of its frame (solid below); ``mesh`` is a mesh file
    (STL, OBJ, DAE) used through its convex hull.

    Raises:
        ModelError: unknown kind (lists them), a missing or non-positive size, a missing or unreadable mesh file.
    """
    if kind == "sphere":
        return coal.Sphere(_positive(radius if radius is not None else -1, "sphere radius"))
    if kind == "box":
        if size is None or len(size) != 3:
            raise ModelError("box: 'size' needs 3 side lengths [m]")
        return coal.Box(*[_positive(s, "box size") for s in size])
    if kind in ("capsule", "cylinder"):
        r = _positive(radius if radius is not None else -1, f"{kind} radius")
        ln = _positive(length if length is not None else -1, f"{kind} length", allow_zero=True)
        return coal.Capsule(r, ln) if kind == "capsule" else coal.Cylinder(r, ln)
    if kind == "plane":
        return coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
    if kind == "mesh":
        if path is None:
            raise ModelError("mesh: 'path' (a mesh file) is required")
        p = Path(path)
        if not p.is_file():
            raise ModelError(f"mesh file '{p}' does not exist")
        sc = np.array([_positive(s, "mesh scale") for s in scale], dtype=float)
        try:
            bvh = coal.MeshLoader().load(str(p), sc)
            if bvh.num_vertices < 4:
                raise ValueError("fewer than 4 vertices")
            bvh.buildConvexHull(True, "Qt")
            return bvh.convex
        except Exception as exc:
            raise ModelError(f"mesh file '{p}' could not be read: {_loader_message(exc)}") from exc
    raise ModelError(f"unknown obstacle type '{kind}'; available: {', '.join(OBSTACLE_KINDS)}")


def _loader_message(exc: Exception) -> str:
    """The reason in a coal loader error, without its C++ source location (one line, ≤ 160 characters)."""
    text = str(exc).strip()
    if "message:" in text:
        text = text.split("message:", 1)[1]
    lines = [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.strip().startswith("Hint:")]
    return " ".join(lines)[:160] or type(exc).__name__


@dataclass
class Obstacle:
    """An environment obstacle fixed to the world, optionally moving (translation only).

    Attributes:
        name: Unique name (also the pair names of diagnostics).
        shape: A coal shape (:func:`make_shape`).
        placement: Pose in the world at t = 0.
        motion: A :class:`Motion`, or ``None`` (static).
    """

    name: str
    shape: object
    placement: pin.SE3 = field(default_factory=pin.SE3.Identity)
    motion: Motion | None = None

    def __post_init__(self) -> None:
        M = self.placement.homogeneous
        if not np.all(np.isfinite(M)):
            raise ModelError(f"obstacle '{self.name}': the pose contains NaN or infinite values")

    def placement_at(self, t: float) -> pin.SE3:
        """Pose at time t [s]."""
        if self.motion is None:
            return self.placement
        return pin.SE3(self.placement.rotation, self.placement.translation + self.motion.offset(t))


# ---------------------------------------------------------------------------------------------------- distances
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
    """Sub-shape distances of some pairs (:meth:`CollisionWorld.end_spheres`), one entry per branch.

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


def _sphere_to(
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


def _placements_view(data: pin.GeometryData) -> np.ndarray | None:
    """A read-only (G, 12) view on the memory of ``data.oMg`` (:func:`redundik.kinematics.memory.se3_vector_view`):
    the placements ``updateGeometryPlacements`` writes there, read by a compiled kernel without a Python call per
    geometry."""
    return se3_vector_view(data.oMg)


def read_srdf_pairs(path: str | Path) -> list[tuple[str, str]]:
    """The ``<disable_collisions link1= link2=>`` pairs of an SRDF file.

    Raises:
        ModelError: a missing or malformed file.
    """
    p = Path(path)
    if not p.is_file():
        raise ModelError(f"SRDF file '{p}' does not exist")
    try:
        root = ET.parse(p).getroot()
    except ET.ParseError as exc:
        raise ModelError(f"SRDF file '{p}' is not valid XML: {exc}") from exc
    return [(e.get("link1", ""), e.get("link2", "")) for e in root.iter("disable_collisions")]


def default_srdf(urdf: str | Path) -> Path | None:
    """The SRDF example-robot-data ships beside a URDF (``../srdf/*.srdf``), or ``None``."""
    folder = Path(urdf).resolve().parent.parent / "srdf"
    if not folder.is_dir():
        return None
    files = sorted(folder.glob("*.srdf"))
    stem = Path(urdf).stem.split("_")[0]
    for f in files:
        if f.stem == stem:
            return f
    return files[0] if files else None


class CollisionWorld:
    """Robot link shapes + obstacles + the filtered candidate pairs, with distances and distance Jacobians.

    Args:
        robot: The robot (its ``pin.Model`` must be the one ``robot_geometry`` was built for).
        robot_geometry: One shape per link (:func:`~redundik.collision.geometry.approximate`).
        obstacles: Environment obstacles.
        self_collision: Include robot–robot pairs.
        disabled: Link-name pairs never checked (an SRDF's, the user's).
        obstacle_links: Links checked against obstacles (``None``: every moving link).
        links: The links kept at all (``None``: every link with collision geometry), e.g. a humanoid's torso and arms.

    Raises:
        ModelError: unknown link names in ``disabled`` / ``obstacle_links`` (lists the links), repeated obstacle
            names.
    """

    def __init__(
        self,
        robot: RobotModel,
        robot_geometry: pin.GeometryModel,
        obstacles: Sequence[Obstacle] = (),
        *,
        self_collision: bool = True,
        disabled: Sequence[tuple[str, str]] = (),
        obstacle_links: Sequence[str] | None = None,
        links: Sequence[str] | None = None,
    ) -> None:
        self.model = robot.model
        self.robot_name = robot.name
        gm = pin.GeometryModel()
        every = [go.name for go in robot_geometry.geometryObjects]
        bad = [n for n in (links or ()) if n not in every]
        if bad:
            raise ModelError(
                f"links: unknown link(s) {', '.join(map(repr, bad))}; links with collision geometry: {', '.join(every)}"
            )
        for go in robot_geometry.geometryObjects:
            if links is not None and go.name not in links:
                continue
            gm.addGeometryObject(pin.GeometryObject(go.name, go.parentJoint, go.parentFrame, go.placement, go.geometry))
        self.n_links = gm.ngeoms
        self.link_names = [go.name for go in gm.geometryObjects]
        names = [o.name for o in obstacles]
        dup = sorted({n for n in names if names.count(n) > 1} | (set(names) & set(self.link_names)))
        if dup:
            raise ModelError(f"obstacle names must be unique and differ from the link names; repeated: {dup}")
        self.obstacles = list(obstacles)
        for ob in self.obstacles:
            gm.addGeometryObject(pin.GeometryObject(ob.name, 0, 0, ob.placement, ob.shape))
        self.geometry = gm
        unknown = sorted({n for pair in disabled for n in pair} - set(every))
        if unknown:
            shown = ", ".join(map(repr, unknown))
            raise ModelError(f"disabled pair: unknown link(s) {shown}; links: {', '.join(every)}")
        if obstacle_links is not None:
            self._check_links(obstacle_links, "obstacle_links")
        off = {frozenset(p) for p in disabled}
        parents = self.model.parents
        pairs: list[tuple[int, int]] = []
        objs = gm.geometryObjects
        if self_collision:
            for i in range(self.n_links):
                for j in range(i + 1, self.n_links):
                    ji, jj = objs[i].parentJoint, objs[j].parentJoint
                    if ji == jj or parents[ji] == jj or parents[jj] == ji or (ji == 0 and jj == 0):
                        continue
                    if frozenset((self.link_names[i], self.link_names[j])) in off:
                        continue
                    pairs.append((i, j))
        allowed = set(obstacle_links) if obstacle_links is not None else None
        for i in range(self.n_links):
            if objs[i].parentJoint == 0 or (allowed is not None and self.link_names[i] not in allowed):
                continue
            for k in range(len(self.obstacles)):
                pairs.append((i, self.n_links + k))
        self._set_pairs(pairs)
        self.time = 0.0
        self.excluded: list[str] = []
        #: The state of the last :meth:`compute`: (robot, time [s], influence [m], the bytes of q).
        self._cache: tuple[RobotModel, float, float, bytes] | None = None
        self._dist: Distances | None = None
        self._pending: tuple[np.ndarray, np.ndarray, int] | None = None  # capsule_damper's (F, I, k₀), unread

    # ------------------------------------------------------------------ construction helpers
    @classmethod
    def from_urdf(
        cls,
        robot: RobotModel,
        urdf: str | Path,
        obstacles: Sequence[Obstacle] = (),
        *,
        approximation: str = "capsule",
        srdf: str | Path | bool | None = True,
        disabled: Sequence[tuple[str, str]] = (),
        package_dirs: Sequence[str] | None = None,
        self_collision: bool = True,
        obstacle_links: Sequence[str] | None = None,
        links: Sequence[str] | None = None,
    ) -> CollisionWorld:
        """Load the URDF's collision geometry, fit ``approximation`` shapes and filter pairs.

        Args:
            srdf: ``True``: the SRDF shipped beside the URDF if any; a path; ``False``/``None``: none.

        Raises:
            ModelError: missing URDF / mesh / SRDF, unknown approximation or link names.
        """
        raw = load_collision_model(robot.model, urdf, package_dirs)
        shapes = approximate(robot.model, raw, approximation)
        off = list(disabled)
        srdf_path = default_srdf(urdf) if srdf is True else (None if srdf in (False, None) else Path(srdf))  # type: ignore[arg-type]
        if srdf_path is not None:
            off += read_srdf_pairs(srdf_path)
        known = {go.name for go in shapes.geometryObjects}
        bad = sorted({n for pair in disabled for n in pair} - known)
        if bad:
            raise ModelError(
                f"disabled pair: unknown link(s) {', '.join(map(repr, bad))}; links with collision geometry: "
                f"{', '.join(sorted(known))}"
            )
        off = [p for p in off if p[0] in known and p[1] in known]
        return cls(
            robot,
            shapes,
            obstacles,
            self_collision=self_collision,
            disabled=off,
            obstacle_links=obstacle_links,
            links=links,
        )

    def _check_links(self, names: Sequence[str], what: str) -> None:
        bad = [n for n in names if n not in self.link_names]
        if bad:
            raise ModelError(
                f"{what}: unknown link(s) {', '.join(repr(b) for b in bad)}; links with collision geometry: "
                f"{', '.join(self.link_names)}"
            )

    def _set_pairs(self, pairs: list[tuple[int, int]]) -> None:
        gm = self.geometry
        gm.removeAllCollisionPairs()
        for i, j in pairs:
            gm.addCollisionPair(pin.CollisionPair(i, j))
        self.pairs = list(pairs)
        objs = gm.geometryObjects
        self.pair_joints = [(int(objs[i].parentJoint), int(objs[j].parentJoint)) for i, j in pairs]
        self.pair_names = [f"{objs[i].name}|{objs[j].name}" for i, j in pairs]
        self._moving = {self.n_links + k for k, ob in enumerate(self.obstacles) if ob.motion is not None}
        self.data = pin.GeometryData(gm)
        for req in self.data.distanceRequests:
            req.enable_signed_distance = True
        self._poses, self._poses_of = _placements_view(self.data), self.data  # the view and the data it reads
        self._cache = None
        self._pending = None
        self._pj: tuple[np.ndarray, np.ndarray] | None = None
        self._tables()

    def _tables(self) -> None:
        """The per-tick kernels' static data: shape codes, capsule pairs (computed by
        :func:`~redundik.collision.kernels.capsule_pairs`, deactivated in coal), coal's pairs, end-sphere branches."""
        info = self._shape_info()
        G = len(info)
        kind = np.full(G, KC.OTHER, dtype=np.int64)
        prm = np.zeros((G, 4))
        for g, inf in enumerate(info):
            if inf[0] == "capsule":
                kind[g], prm[g, :2] = KC.CAPSULE, (inf[1], inf[2])
            elif inf[0] == "sphere":
                kind[g], prm[g, :2] = KC.CAPSULE, (inf[1], 0.0)
            elif inf[0] == "box":
                kind[g], prm[g, :3] = KC.BOX, inf[1]
            elif inf[0] == "halfspace":
                kind[g], prm[g, :3], prm[g, 3] = KC.HALFSPACE, inf[1], inf[2]
        self._kind, self._prm = kind, prm
        pa = np.array([i for i, _ in self.pairs], dtype=np.int64)
        pb = np.array([j for _, j in self.pairs], dtype=np.int64)
        caps = (kind[pa] == KC.CAPSULE) & (kind[pb] == KC.CAPSULE) if self.pairs else np.zeros(0, dtype=bool)
        self._cap = np.flatnonzero(caps)
        self._coal = np.flatnonzero(~caps)
        for k in self._cap.tolist():
            self.data.deactivateCollisionPair(k)
        self._live = sorted({g for pair in self.pairs for g in pair if g < self.n_links})
        self._live_arr = np.array(self._live, dtype=np.int64)
        self._T = np.tile(np.eye(4), (G, 1, 1))  # world poses of the geometries (obstacles: set here and by set_time)
        objs = self.geometry.geometryObjects
        for g in range(self.n_links, G):
            self._T[g] = objs[g].placement.homogeneous
        self._cap_a, self._cap_b = pa[self._cap].copy(), pb[self._cap].copy()
        # end-sphere branches: (pair, capsule geometry, other geometry, capsule is body 1, end ±1)
        rows: list[tuple[int, int, int, bool, float]] = []
        for k, (i, j) in enumerate(self.pairs):
            for b, o, first in ((i, j, True), (j, i, False)):
                if kind[b] == KC.CAPSULE and prm[b, 1] > 0:
                    rows += [(k, b, o, first, 1.0), (k, b, o, first, -1.0)]
        tab = np.array([r[:3] for r in rows], dtype=np.int64).reshape(-1, 3)
        self._br_pair, self._br_b, self._br_o = tab[:, 0].copy(), tab[:, 1].copy(), tab[:, 2].copy()
        self._br_first = np.array([r[3] for r in rows], dtype=np.bool_)
        self._br_sign = np.array([r[4] for r in rows], dtype=float)
        self._br_other = kind[self._br_o] == KC.OTHER
        self._br_any_other = bool(self._br_other.any())
        self._br_tab = np.column_stack([tab, self._br_first.astype(np.int64)]).astype(np.int64)
        names = self._geom_names
        self._br_labels = [f"{self.pair_names[k]}@{names[b]}{'+' if sg > 0 else '-'}" for k, b, _o, _f, sg in rows]
        #: Row labels by row id (``collision.kernels.barrier_rows``): the pairs, then the branches.
        self.row_labels = self.pair_names + self._br_labels
        self._pj2 = np.array(self.pair_joints, dtype=np.int64).reshape(-1, 2)
        #: ``collision.kernels.capsule_damper``'s fixed arguments, for a static world of capsules only
        #: whose placements are read from oMg's memory (else ``None``).
        self._static: tuple[Any, ...] | None = None
        if self._cap.size == len(self.pairs) and not self._moving and self._poses is not None:
            self._static = (
                self._poses, self._live_arr, self._T, prm, self._cap_a, self._cap_b, kind, self._br_tab,
                self._br_sign, self._joint_masks(), self._pj2,
            )  # fmt: skip
        #: (pairs P, rows at most R = P + branches, nv): the sizes of capsule_damper's arrays.
        self._sizes = (len(self.pairs), len(self.pairs) + len(self._br_sign), int(self.model.nv))
        self._pa, self._pb = pa, pb

    def exclude_colliding_at(self, robot: RobotModel, q: np.ndarray, threshold: float = 0.0) -> list[str]:
        """Drop the self pairs closer than ``threshold`` [m] at ``q`` (structural overlaps of the approximation).

        Returns:
            The names of the dropped pairs (also kept in :attr:`excluded`).
        """
        robot.update(q)
        dist = self.compute(robot)
        keep, dropped = [], []
        for k, (i, j) in enumerate(self.pairs):
            if j < self.n_links and dist.d[k] < threshold:
                dropped.append(self.pair_names[k])
            else:
                keep.append((i, j))
        self._set_pairs(keep)
        self.excluded += dropped
        return dropped

    # ------------------------------------------------------------------ time
    def set_time(self, t: float) -> None:
        """Move the moving obstacles to their pose at time t [s] (call before the tick at t)."""
        t = float(t)
        if not math.isfinite(t):
            raise ModelError(f"collision world: time must be finite, got {t}")
        self.time = t
        for k, ob in enumerate(self.obstacles):
            if ob.motion is not None:
                M = ob.placement_at(t)
                self.geometry.geometryObjects[self.n_links + k].placement = M
                self._T[self.n_links + k] = M.homogeneous

    # ------------------------------------------------------------------ distances
    @property
    def n_pairs(self) -> int:
        """Number of candidate pairs."""
        return len(self.pairs)

    def check(self, robot: RobotModel) -> None:
        """Raise :class:`ModelError` unless ``robot`` is the robot this world was built for."""
        if robot.model is not self.model:
            raise ModelError(
                f"collision world was built for robot '{self.robot_name}', not for '{robot.name}' (another model)"
            )

    def compute(self, robot: RobotModel, influence: float = math.inf) -> Distances:
        """Distances of every pair at the robot's current (updated) state; witness points for d < ``influence``.

        The broad phase is coal's own (bounding volumes of the primitives); this method keeps for the narrow data
        (points, normals, Jacobians) only the pairs within ``influence`` [m]. Cached per kinematic update and time.
        """
        key = robot.q.tobytes()  # (a copy of q's 8 nv bytes: cheaper than comparing arrays)
        c = self._cache
        if (
            c is not None
            and c[3] == key
            and c[0] is robot
            and c[1] == self.time
            and c[2] == influence
            and (self._dist is not None or self._pending is not None)
        ):
            return self._distances()
        pin.updateGeometryPlacements(self.model, robot.data, self.geometry, self.data)
        if self._poses is not None and self._poses_of is self.data:  # straight from oMg's memory
            KC.load_poses(self._poses, self._live_arr, self._T)
        elif self._live:
            placements = self.data.oMg.tolist()  # one call (indexing ``oMg`` costs as much per geometry)
            T = self._T
            for g in self._live:
                T[g] = placements[g].homogeneous
        P = len(self.pairs)
        cap = self._cap
        if cap.size == P:  # only capsule/sphere pairs: one compiled call, the kernel's arrays are the pairs'
            d, p1, p2, nrm, bad, near = KC.capsule_distances(
                self._T, self._prm, self._cap_a, self._cap_b, float(influence)
            )
            if bad.size:
                for k in bad.tolist():  # axes meeting: coal's normal
                    self._from_coal(k, pin.computeDistance(self.geometry, self.data, k), d, p1, p2, nrm)
                near = np.flatnonzero(d < influence)
        else:
            d = np.empty(P)
            p1, p2, nrm = np.zeros((P, 3)), np.zeros((P, 3)), np.zeros((P, 3))
            if cap.size:  # capsule/sphere pairs: one compiled call
                dc, a, b, nc, ok = KC.capsule_pairs(self._T, self._prm, self._cap_a, self._cap_b)
                d[cap], p1[cap], p2[cap], nrm[cap] = dc, a, b, nc
                if not ok.all():
                    for k in cap[~ok].tolist():  # axes meeting: coal's normal
                        self._from_coal(k, pin.computeDistance(self.geometry, self.data, k), d, p1, p2, nrm)
            if self._coal.size:
                pin.computeDistances(self.geometry, self.data)  # the capsule pairs are deactivated
                results = self.data.distanceResults
                for k in self._coal.tolist():
                    d[k] = results[k].min_distance
                for k in self._coal[d[self._coal] < influence].tolist():
                    self._from_coal(k, results[k], d, p1, p2, nrm)
            near = np.flatnonzero(d < influence)
        rate = np.zeros(P)
        if self._moving:
            for k in near.tolist():
                ib = self.pairs[k][1]
                if ib in self._moving:
                    motion = self.obstacles[ib - self.n_links].motion
                    if motion is not None:
                        rate[k] = float(nrm[k] @ motion.rate(self.time))
        self._dist, self._pending = Distances(d, p1, p2, nrm, rate, near), None
        self._cache = (robot, self.time, influence, key)
        return self._dist

    def _distances(self) -> Distances:
        """The cached :class:`Distances`, built from :meth:`damper`'s arrays on first use."""
        if self._pending is not None:
            F, I, k0 = self._pending
            P = len(self.pairs)
            pts = F[P : 10 * P].reshape(3, P, 3)
            self._dist, self._pending = Distances(F[:P], pts[0], pts[1], pts[2], np.zeros(P), I[:k0]), None
        assert self._dist is not None
        return self._dist

    @staticmethod
    def _from_coal(k: int, r: Any, d: np.ndarray, p1: np.ndarray, p2: np.ndarray, nrm: np.ndarray) -> None:
        """Pair k's distance, witness points and normal from coal's result ``r``."""
        d[k] = r.min_distance
        a, b = r.getNearestPoint1(), r.getNearestPoint2()
        p1[k], p2[k] = a, b
        diff = b - a
        nd = math.sqrt(float(diff @ diff))
        # p2 − p1 = d n (coal's convention, also when penetrating); coal's own normal where the points coincide
        nrm[k] = diff / (nd if d[k] >= 0 else -nd) if nd > 1e-9 else r.normal

    def jacobian(self, robot: RobotModel, dist: Distances, rows: np.ndarray) -> np.ndarray:
        """∂d/∂q of the pairs ``rows`` (pair indices), shape (k, nv) (module docstring).

        Vectorised on the spatial (WORLD) Jacobian J^s of the last kinematic update: the velocity of the body point
        at p is v_p = M_j ⊙ (J^s_v − [p]× J^s_ω) q̇ with M_j the columns of the joints supporting body j, so
        nᵀ v_p = M_j ⊙ (nᵀJ^s_v + (p × n)ᵀ J^s_ω) — equal to the base-aligned form of the module docstring.
        """
        rows = np.asarray(rows, dtype=np.int64)
        return self.point_jacobian(robot, rows, dist.n[rows], dist.p1[rows], dist.p2[rows])

    def point_jacobian(
        self, robot: RobotModel, pairs: np.ndarray, n: np.ndarray, p1: np.ndarray, p2: np.ndarray
    ) -> np.ndarray:
        """nᵀ(v_{p₂} − v_{p₁}) / q̇ for the body points p₁ (on body 1 of ``pairs[r]``), p₂ (body 2), shape (k, nv).

        :meth:`jacobian` with given points and normals (world frame, shapes (k, 3)): the rate of the gap along n
        between the two body-fixed points, the exact Jacobian of a sub-shape distance (:meth:`end_spheres`).
        """
        pairs = np.asarray(pairs, dtype=np.int64)
        if not pairs.size:
            return np.zeros((0, robot.nv))
        Js = np.asarray(robot.data.J)  # (6, nv), spatial Jacobian in the world frame
        ja, jb = self._pair_joint_arrays()
        mask = self._joint_masks(robot)
        f = np.ascontiguousarray
        return KC.distance_rows(f(Js), mask, ja[pairs], jb[pairs], f(n, float), f(p1, float), f(p2, float))

    def end_spheres(self, dist: Distances, rows: np.ndarray, influence: float) -> Branches:
        """The distances of the end spheres of every capsule of the pairs ``rows`` to the pair's other body.

        A capsule is the set of points within R of a segment [a, b], so its distance to a convex body B is
        d = min_{s∈[0,1]} dist(ball(a + s(b − a), R), B); s ↦ dist(·) is convex, and the minimum is either interior
        (the pair's own witness, smooth there) or at an end, s = 0 or 1: the ball of radius R at a or b. Each
        end-sphere distance d_e ≥ d is a C¹ function of q (point-to-convex distance), so the barrier's rows on the
        pair and on its end spheres bound every branch of d from below to first order: when the capsule's axis is
        nearly parallel to the other body's surface the witness point jumps between the ends within one step, and
        the row of the pair alone (the derivative of the current branch) would not see the other end approach.

        Called after :meth:`compute` at the same state (uses its placements). Ends whose distance is ≥ ``influence``
        [m] or equal to the pair's own witness (same point within 1e-7 m) are left out.
        """
        rows = np.asarray(rows, dtype=np.int64)
        if not rows.size or not self._br_pair.size:
            return Branches.empty()
        sel = np.zeros(len(self.pairs), dtype=np.bool_)
        sel[rows] = True
        parts = [
            KC.end_spheres(
                self._T, self._kind, self._prm, self._br_pair, self._br_b, self._br_o, self._br_first,
                self._br_sign, sel, dist.d, dist.p1, float(influence),
            )
        ]  # fmt: skip
        if self._br_other.any():
            slow = np.flatnonzero(sel[self._br_pair] & self._br_other)
            if slow.size:  # a capsule end against a mesh/convex hull: coal, per branch
                parts.append(self._slow_end_spheres(dist, slow, influence))
        if len(parts) == 1:
            idx, d, p1, p2, nn = parts[0]
        else:
            idx, d = np.concatenate([q[0] for q in parts]), np.concatenate([q[1] for q in parts])
            p1, p2, nn = (np.vstack([q[i] for q in parts]) for i in (2, 3, 4))
        if not idx.size:
            return Branches.empty()
        pair = self._br_pair[idx]
        rate = np.zeros(idx.size)
        if self._moving:
            for r, k in enumerate(pair.tolist()):
                j = self.pairs[k][1]
                mo = self.obstacles[j - self.n_links].motion if j in self._moving else None
                if mo is not None:
                    rate[r] = float(nn[r] @ mo.rate(self.time))
        labels = self._br_labels
        return Branches(pair, d, p1, p2, nn, rate, [labels[r] for r in idx.tolist()])

    def damper(
        self, robot: RobotModel, reach: float, influence: float, safety: float, gamma: float, no_cap: float,
        ends: bool, qp_cap: float = 0.0,
    ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None]:  # fmt: skip
        """(every pair's distance [m], :meth:`damper_rows`) at the robot's current state after :meth:`compute`
        (``influence`` = ``reach``, cached as usual), in one compiled call
        (``collision.kernels.capsule_damper``) where the world is capsules/spheres only and static and
        the distances are not cached yet; the same results as the two calls (``qp_cap`` > 0 [1/s]: the rows as
        (d, C) of C q̇ ≤ d, see :meth:`damper_rows`).
        """
        key = robot.q.tobytes()
        c = self._cache
        static = self._static
        if (
            static is not None
            and self._poses is not None
            and self._poses_of is self.data
            and (c is None or c[3] != key or c[0] is not robot or c[1] != self.time or c[2] != reach)
        ):
            pin.updateGeometryPlacements(self.model, robot.data, self.geometry, self.data)
            P, R, nv = self._sizes
            F, I = np.empty(10 * P + (2 + nv) * R), np.empty(P + R, dtype=np.int64)
            args = (*static, np.asarray(robot.data.J), float(reach), float(influence), float(safety), float(gamma),
                    float(no_cap), bool(ends), float(qp_cap), F, I)  # fmt: skip
            k0, k, bad = KC.capsule_damper(*args)
            if not bad:
                self._dist, self._pending = None, (F, I, k0)  # the Distances built when read (compute)
                self._cache = (robot, self.time, reach, key)
                o = 10 * P
                return F[:P], (
                    F[o : o + k],
                    F[o + 2 * R : o + 2 * R + k * nv].reshape(k, nv),
                    F[o + R : o + R + k],
                    I[P : P + k],
                )
        dist = self.compute(robot, reach)  # (axes meeting: coal's normals)
        return dist.d, self.damper_rows(robot, dist, reach, influence, safety, gamma, no_cap, ends, qp_cap)

    def damper_rows(
        self, robot: RobotModel, dist: Distances, reach: float, influence: float, safety: float, gamma: float,
        no_cap: float, ends: bool, qp_cap: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:  # fmt: skip
        """The collision damper's rows on the pairs ``dist.near`` and (``ends``) their end spheres, in one compiled
        call (``collision.kernels.barrier_rows``): (h [m], ∂h/∂q (k, nv), γ [1/s], row ids, labels in
        ``row_labels``); ``None`` where that call does not apply (moving obstacles, a capsule end against a
        mesh): the caller then uses :meth:`end_spheres` and :meth:`point_jacobian`.

        Args:
            dist: :meth:`compute`'s result at the current state (its placements are used).
            reach: Rows for the end spheres closer than this [m].
            influence: d_i [m]: rows closer than this have h = d − d_s + (∂d/∂t)/γ and gain ``gamma`` [1/s], the
                others h = d − d_s and gain ``no_cap`` [1/s].
            safety: d_s [m].
            qp_cap: > 0 [1/s]: (d, C) of the QP rows C q̇ ≤ d instead of (h, ∂h/∂q) (kernels.barrier_rows).
        """
        if self._moving or (ends and self._br_any_other):
            return None
        return KC.barrier_rows(
            self._T, self._kind, self._prm, self._br_tab, self._br_sign, dist.d, dist.p1, dist.p2, dist.n, dist.rate,
            dist.near, np.asarray(robot.data.J), self._joint_masks(robot), self._pj2, float(reach), float(influence),
            float(safety), float(gamma), float(no_cap), bool(ends), float(qp_cap),
        )  # fmt: skip

    def _slow_end_spheres(
        self, dist: Distances, branches: np.ndarray, influence: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`end_spheres` for the branches whose other body only coal handles: (branch indices, d, p1, p2, n)."""
        info = self._shape_info()
        keep, dd, pp1, pp2, nn = [], [], [], [], []
        for r in branches.tolist():
            k, b, o = int(self._br_pair[r]), int(self._br_b[r]), int(self._br_o[r])
            Mo = pin.SE3(self._T[o])
            c = self._T[b, :3, 3] + self._br_sign[r] * self._prm[b, 1] * self._T[b, :3, 2]
            hit = _sphere_to(c, float(self._prm[b, 0]), info[o], Mo)
            if hit is None or hit[0] >= influence:
                continue
            d_e, ps, po, u = hit
            q1, q2, nrm = (ps, po, u) if self._br_first[r] else (po, ps, -u)
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

    _info: list[tuple[Any, ...]] | None = None

    def _shape_info(self) -> list[tuple[Any, ...]]:
        """Per geometry: ("capsule", R, half length) | ("sphere", R) | ("box", half sides) | ("halfspace", n, d) |
        ("other", shape) (read once: pinocchio copies ``geometryObjects`` on every access)."""
        if self._info is None or len(self._info) != self.geometry.ngeoms:
            info: list[tuple[Any, ...]] = []
            for go in self.geometry.geometryObjects:
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
            self._info = info
            self._geom_names = [go.name for go in self.geometry.geometryObjects]
        return self._info

    def _pair_joint_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        pj: tuple[np.ndarray, np.ndarray] | None = getattr(self, "_pj", None)
        if pj is None or len(pj[0]) != len(self.pair_joints):
            arr = np.array(self.pair_joints, dtype=np.int64).reshape(-1, 2)
            pj = (arr[:, 0].copy(), arr[:, 1].copy())
            self._pj = pj
        return pj

    def _joint_masks(self, robot: RobotModel | None = None) -> np.ndarray:
        """M[j, k] = 1 when velocity k belongs to a joint supporting joint j (M[0] = 0: the world), (njoints, nv)."""
        if getattr(self, "_masks", None) is None:
            m = self.model
            owner = np.empty(m.nv, dtype=int)
            for jid in range(1, m.njoints):
                jm = m.joints[jid]
                owner[jm.idx_v : jm.idx_v + jm.nv] = jid
            masks = np.zeros((m.njoints, m.nv))
            for jid in range(1, m.njoints):
                masks[jid] = np.isin(owner, list(m.supports[jid]))
            self._masks = masks
        return self._masks

    def closest(self, robot: RobotModel) -> tuple[str, float]:
        """(pair name, distance [m]) of the closest pair at the robot's current state (``("", inf)`` if none)."""
        if not self.pairs:
            return "", math.inf
        dist = self.compute(robot, influence=-math.inf)
        k = int(np.argmin(dist.d))
        return self.pair_names[k], float(dist.d[k])

    def __repr__(self) -> str:
        return (
            f"CollisionWorld(robot={self.robot_name!r}, links={self.n_links}, obstacles={len(self.obstacles)}, "
            f"pairs={self.n_pairs})"
        )

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
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from redundik._kernel_cache import KernelNamespace
from redundik.collision import layouts as L
from redundik.collision.distances import Branches, Distances, shape_info, shape_table, slow_end_spheres, sphere_to
from redundik.collision.geometry import approximate, load_collision_model
from redundik.collision.layouts import F_DIST, F_GAMMA, F_H, F_JAC, F_PAIR, F_POINTS, PTS, PTS_N, PTS_P1, PTS_P2
from redundik.collision.obstacles import OBSTACLE_KINDS, Motion, Obstacle, make_shape
from redundik.collision.pairs import candidate_pairs, default_srdf, read_srdf_pairs
from redundik.errors import ModelError
from redundik.kinematics.memory import se3_vector_view
from redundik.kinematics.model import RobotModel

#: The compiled collision kernels, imported on first use (a namespace: a cold start puts their twins here).
KC = KernelNamespace("redundik.collision.kernels")

__all__ = [
    "OBSTACLE_KINDS",
    "Branches",
    "CollisionWorld",
    "Distances",
    "Motion",
    "Obstacle",
    "default_srdf",
    "make_shape",
    "read_srdf_pairs",
]

#: The interpreted ball-to-shape distance (:func:`redundik.collision.distances.sphere_to`), the reference the tests
#: hold the compiled end spheres to.
_sphere_to = sphere_to


def _placements_view(data: pin.GeometryData) -> np.ndarray | None:
    """A read-only (G, 12) view on the memory of ``data.oMg`` (:func:`redundik.kinematics.memory.se3_vector_view`):
    the placements ``updateGeometryPlacements`` writes there, read by a compiled kernel without a Python call per
    geometry."""
    return se3_vector_view(data.oMg)


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
        allowed = set(obstacle_links) if obstacle_links is not None else None
        pairs = candidate_pairs(
            self.model, gm, self.n_links, self_collision=self_collision, disabled={frozenset(p) for p in disabled},
            obstacle_links=allowed,
        )  # fmt: skip
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
        self._new_data()
        self._cache = None
        self._pending = None
        self._pj: tuple[np.ndarray, np.ndarray] | None = None
        self._tables()

    def _new_data(self) -> None:
        """Coal's geometry data for :attr:`geometry` (signed distances) and the view of its placements, taken after
        the placements are set to the identity: a fresh ``GeometryData`` leaves them uninitialised, and a NaN there
        fails the view's check of the values (:func:`~redundik.kinematics.memory.se3_vector_view`), which left the
        world without its one-call damper (``capsule_damper``) for the whole run."""
        self.data = pin.GeometryData(self.geometry)
        for req in self.data.distanceRequests:
            req.enable_signed_distance = True
        placements = self.data.oMg
        for g in range(len(placements)):
            placements[g] = pin.SE3.Identity()
        self._poses, self._poses_of = _placements_view(self.data), self.data  # the view and the data it reads

    def _bind_static(self) -> None:
        """Capsule pairs off in coal's data (the kernels compute them); ``_static``: ``kernels.capsule_damper``'s fixed
        arguments for a static world of capsules read from oMg's memory (else ``None``)."""
        for k in self._cap.tolist():
            self.data.deactivateCollisionPair(k)
        self._static: tuple[Any, ...] | None = None
        if self._cap.size == len(self.pairs) and not self._moving and self._poses is not None:
            poses, caps = (self._poses, self._live_arr), (self._cap_a, self._cap_b)
            self._static = (poses, self._shapes, caps, self._branches, self._joints)

    def __getstate__(self) -> dict[str, Any]:
        """Copied or pickled without coal's data (it does not pickle) and views of it (a copy would read a frozen
        array as its placements): the copy makes its own."""
        dropped = ("data", "_poses", "_poses_of", "_static", "_cache", "_pending", "_dist")
        return {key: value for key, value in self.__dict__.items() if key not in dropped}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._new_data()
        self._bind_static()
        self._cache = self._pending = self._dist = None

    def _tables(self) -> None:
        """The per-tick kernels' static data: shape codes, capsule pairs (computed by
        :func:`~redundik.collision.kernels.capsule_pairs`, deactivated in coal), coal's pairs, end-sphere branches."""
        info = self._shape_info()
        G = len(info)
        kind, prm = shape_table(info)
        self._kind, self._prm = kind, prm
        pa = np.array([i for i, _ in self.pairs], dtype=np.int64)
        pb = np.array([j for _, j in self.pairs], dtype=np.int64)
        caps = (kind[pa] == L.CAPSULE) & (kind[pb] == L.CAPSULE) if self.pairs else np.zeros(0, dtype=bool)
        self._cap = np.flatnonzero(caps)
        self._coal = np.flatnonzero(~caps)
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
                if kind[b] == L.CAPSULE and prm[b, L.CAP_HALF] > 0:
                    rows += [(k, b, o, first, 1.0), (k, b, o, first, -1.0)]
        br = np.zeros((len(rows), L.BR_COLS), dtype=np.int64)
        for r, (k, b, o, first, _sg) in enumerate(rows):
            br[r, L.BR_PAIR], br[r, L.BR_CAPSULE], br[r, L.BR_OTHER], br[r, L.BR_FIRST] = k, b, o, first
        #: The branch table (kernels.BranchTable, layouts ``TABLE_BR``, ``TABLE_SIGN``): the int table, the ends ±1.
        self._branches = (br, np.array([sg for *_, sg in rows], dtype=float))
        self._br_pair = br[:, L.BR_PAIR].copy()
        self._br_other = kind[br[:, L.BR_OTHER]] == L.OTHER
        self._br_any_other = bool(self._br_other.any())
        #: The geometries (kernels.Shapes): world poses, kind codes, numbers.
        self._shapes = (self._T, kind, prm)
        names = self._geom_names
        self._br_labels = [f"{self.pair_names[k]}@{names[b]}{'+' if sg > 0 else '-'}" for k, b, _o, _f, sg in rows]
        #: Row labels by row id (``collision.kernels.barrier_rows``): the pairs, then the branches.
        self.row_labels = self.pair_names + self._br_labels
        self._pj2 = np.array(self.pair_joints, dtype=np.int64).reshape(-1, L.PJ_COLS)
        #: The joints (kernels.Joints): support masks, the pairs' joints.
        self._joints = (self._joint_masks(), self._pj2)
        self._bind_static()
        #: (pairs P, rows at most R = P + branches, nv): the sizes of capsule_damper's arrays.
        self._sizes = (len(self.pairs), len(self.pairs) + len(self._br_pair), int(self.model.nv))
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
            d, pts = F[F_DIST * P : F_POINTS * P], F[F_POINTS * P : F_PAIR * P].reshape(PTS, P, 3)
            self._dist = Distances(d, pts[PTS_P1], pts[PTS_P2], pts[PTS_N], np.zeros(P), I[:k0])
            self._pending = None
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
        parts = [KC.end_spheres(self._shapes, self._branches, sel, dist.d, dist.p1, float(influence))]
        if self._br_any_other:
            slow = np.flatnonzero(sel[self._br_pair] & self._br_other)
            if slow.size:  # a capsule end against a mesh/convex hull: coal, per branch
                info = self._shape_info()
                parts.append(slow_end_spheres(info, self._shapes, self._branches, dist, slow, influence))
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
            F, I = np.empty(F_PAIR * P + (F_JAC + nv) * R), np.empty(P + R, dtype=np.int64)
            gains = (float(reach), float(influence), float(safety), float(gamma), float(no_cap), bool(ends),
                     float(qp_cap))  # fmt: skip
            k0, k, bad = KC.capsule_damper(*static, np.asarray(robot.data.J), gains, F, I)
            if not bad:
                self._dist, self._pending = None, (F, I, k0)  # the Distances built when read (compute)
                self._cache = (robot, self.time, reach, key)
                o = F_PAIR * P
                h, gam, jac = o + F_H * R, o + F_GAMMA * R, o + F_JAC * R
                return F[F_DIST * P : F_POINTS * P], (
                    F[h : h + k],
                    F[jac : jac + k * nv].reshape(k, nv),
                    F[gam : gam + k],
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
        pairs = (dist.d, dist.p1, dist.p2, dist.n, dist.rate, dist.near)
        gains = (float(reach), float(influence), float(safety), float(gamma), float(no_cap), bool(ends), float(qp_cap))
        return KC.barrier_rows(self._shapes, self._branches, pairs, self._joints, np.asarray(robot.data.J), gains)

    _info: list[tuple[Any, ...]] | None = None

    def _shape_info(self) -> list[tuple[Any, ...]]:
        """:func:`~redundik.collision.distances.shape_info` of the geometries, and their names (read once: pinocchio
        copies ``geometryObjects`` on every access)."""
        if self._info is None or len(self._info) != self.geometry.ngeoms:
            self._info = shape_info(self.geometry)
            self._geom_names = [go.name for go in self.geometry.geometryObjects]
        return self._info

    def _pair_joint_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        pj: tuple[np.ndarray, np.ndarray] | None = getattr(self, "_pj", None)
        if pj is None or len(pj[0]) != len(self.pair_joints):
            arr = np.array(self.pair_joints, dtype=np.int64).reshape(-1, L.PJ_COLS)
            pj = (arr[:, L.PJ_BODY1].copy(), arr[:, L.PJ_BODY2].copy())
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

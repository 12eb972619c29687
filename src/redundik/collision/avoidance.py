"""Collision avoidance as a barrier (velocity damper, QP resolvers) and as a repulsive potential (``pinv``,
``feedback``) — one object, two roles.

**Barrier** (``BoundSubtask(CollisionAvoidance(...))`` in ``wqp`` and at any ``hqp`` level): one row per pair
within the influence distance d_i, h = d − d_s ≥ 0 with the exact H = ∂d/∂q (:mod:`redundik.collision.world`) and
the per-row gain γ = ξ/(d_i − d_s), so that the bound subtask's damper ḣ ≥ −γh is the velocity damper of
Faverjon & Tournassoud (1987) as used by Kanoun, Lamiraux & Wieber (2011):

    ḋ ≥ −ξ (d − d_s)/(d_i − d_s)     [m/s],  for d < d_i

(pairs beyond d_i give no row). With a moving obstacle ḋ = H q̇ + ∂d/∂t, and ∂d/∂t = nᵀ v_obstacle is folded into
h (h = d − d_s + (∂d/∂t)/γ), so the rows C q̇ ≤ γh are the damper on the total rate. The bound subtask caps γ at
1/dt; choose ξ ≤ (d_i − d_s)/dt for the exact damper.

**Potential** (``GradientSubtask(..., gain < 0)``): the repulsive penalty, quadratic inside the influence zone,

    p(q) = ½ Σ_{d_j < d_i} ((d_i − d_j)/(d_i − d_s))²,    η = −Σ (d_i − d_j)/(d_i − d_s)² ∂d_j/∂q

(dimensionless; C¹ at d = d_i), descended by a negative gain k in the null space of the main tasks: it pushes
pairs apart but, as any null-space term, cannot override a main task that drives the robot into an obstacle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from redundik.collision.world import CollisionWorld, Distances
from redundik.errors import ModelError, TaskError
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import Barrier, BarrierTerm, Potential, check_name, check_number

#: γ of the look-ahead rows: "infinite", i.e. the bound subtask's cap 1/dt.
_NO_CAP = 1e12


@dataclass
class CollisionReport:
    """Diagnostics of one evaluation.

    Attributes:
        closest_pair: Name ``body1|body2`` of the closest pair.
        distance: Its signed distance [m] (``inf`` without pairs).
        active: Names of the pairs within the influence distance (the barrier's rows).
        candidates: Number of candidate pairs checked.
    """

    closest_pair: str = ""
    distance: float = math.inf
    active: list[str] = field(default_factory=list)
    candidates: int = 0


class CollisionAvoidance(Barrier, Potential):
    """Distance constraints / repulsion between the pairs of a :class:`CollisionWorld` (module docstring).

    Args:
        world: The collision world (robot shapes, obstacles, pairs).
        influence: d_i [m] > d_s: pairs farther away are ignored.
        safety: d_s [m] ≥ 0: the distance kept.
        xi: ξ [m/s] > 0: the damper's approach speed at d = d_i.
        name: Subtask name.

    Raises:
        TaskError: non-finite or out-of-range numbers (d_i ≤ d_s, ξ ≤ 0, d_s < 0).
    """

    #: Collision rows are safety rows: a relaxed QP keeps them (:attr:`~redundik.tasks.base.Barrier.critical`).
    critical = True

    def __init__(
        self,
        world: CollisionWorld,
        *,
        influence: float = 0.1,
        safety: float = 0.01,
        xi: float = 0.2,
        lookahead: float = 0.05,
        end_spheres: bool = True,
        name: str = "collision",
    ) -> None:
        if not isinstance(world, CollisionWorld):
            raise TaskError(f"collision subtask: expected a CollisionWorld, got {type(world).__name__}")
        self.name = check_name(name, "collision subtask")
        self.world = world
        self.safety = check_number(safety, f"subtask '{name}': safety (d_s) [m]", low=0.0)
        self.influence = check_number(influence, f"subtask '{name}': influence (d_i) [m]", low=self.safety, strict=True)
        self.xi = check_number(xi, f"subtask '{name}': xi [m/s]", low=0.0, strict=True)
        self.lookahead = check_number(lookahead, f"subtask '{name}': lookahead [m]", low=0.0)
        self.end_spheres = bool(end_spheres)
        self._report_of: np.ndarray | None = None  # the distances [m] the report is read from (built on demand)
        self._rep = CollisionReport()
        #: Per prefix: (the last compiled rows' ids, the world labels they were read from, their names), and the
        #: world labels with the prefix.
        self._names_cache: dict[str, tuple[bytes, list[str], list[str]]] = {}
        self._prefixed: dict[str, tuple[list[str], list[str]]] = {}

    @property
    def gamma(self) -> float:
        """γ = ξ/(d_i − d_s) [1/s]."""
        return self.xi / (self.influence - self.safety)

    def check(self, robot: RobotModel) -> None:
        try:
            self.world.check(robot)
        except ModelError as exc:
            raise TaskError(f"subtask '{self.name}': {exc}") from None

    def _near(self, robot: RobotModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(indices of the pairs within d_i, their distances, the full distance vector) and the report."""
        dist = self.world.compute(robot, self.influence)
        self._report_of = dist.d
        rows = dist.near
        return rows, dist.d[rows], dist.d

    @property
    def report(self) -> CollisionReport:
        """Diagnostics of the last evaluation (:class:`CollisionReport`), built when first read."""
        if self._report_of is not None:
            self._fill_report(self._report_of)
            self._report_of = None
        return self._rep

    def _fill_report(self, d: np.ndarray) -> None:
        rep = self._rep
        rep.candidates = self.world.n_pairs
        if d.size:
            k = int(np.argmin(d))
            rep.closest_pair, rep.distance = self.world.pair_names[k], float(d[k])
        else:
            rep.closest_pair, rep.distance = "", math.inf
        rep.active = [self.world.pair_names[k] for k in np.flatnonzero(d < self.influence)]

    # ------------------------------------------------------------------ barrier
    def evaluate(self, robot: RobotModel) -> BarrierTerm:
        """The damper rows (module docstring): per pair and per capsule end sphere at distance d (module docstring).

        d < d_i: h = d − d_s + (∂d/∂t)/γ, γ = ξ/(d_i − d_s); d_i ≤ d < d_i + lookahead: h = d − d_s, γ = ∞ (the
        bound subtask caps it at 1/dt, so the row is d + (H q̇) dt ≥ d_s: the robot's own motion does not cross d_s
        within one step; it binds only for approach speeds above (d − d_s)/dt, and an obstacle's motion, which
        needs dt to be folded in, is left to the damper once the pair is within d_i). Rows are the pairs first (pair
        order), then the end-sphere branches (ends within d_i + lookahead; each row by its own distance).
        """
        reach = self.influence + self.lookahead
        g = self.gamma
        self._report_of, fused = self.world.damper(
            robot, reach, self.influence, self.safety, g, _NO_CAP, self.end_spheres
        )
        if fused is not None:
            h, H, gam, ids = fused
            return BarrierTerm(h, H, self._row_names(ids), gam)
        return self._term(robot, self.world.compute(robot, reach), reach)

    def bound_rows(self, robot: RobotModel, rate_cap: float, prefix: str) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """The damper as QP rows C q̇ ≤ d (what :meth:`~redundik.tasks.subtasks.BoundSubtask.rows` makes of
        :meth:`evaluate`: C = −H, d = min(γ, ``rate_cap``) h [m/s], ``rate_cap`` = 1/dt [1/s]; row names
        ``prefix:name``), in the same compiled call as the rows where the world allows it; the same numbers either
        way."""
        reach = self.influence + self.lookahead
        self._report_of, fused = self.world.damper(
            robot, reach, self.influence, self.safety, self.gamma, _NO_CAP, self.end_spheres, rate_cap
        )
        if fused is not None:
            d, C, _, ids = fused
            return C, d, self._row_names(ids, prefix)
        term = self._term(robot, self.world.compute(robot, reach), reach)
        assert term.gamma is not None
        return -term.H, np.minimum(term.gamma, rate_cap) * term.h, [f"{prefix}:{n}" for n in term.names]

    def _term(self, robot: RobotModel, dist: Distances, reach: float) -> BarrierTerm:
        """:meth:`evaluate` row by row (moving obstacles, capsule ends against meshes), from ``dist``."""
        g = self.gamma
        rows = dist.near
        d, rate = dist.d[rows], dist.rate[rows]
        names = [self.world.pair_names[k] for k in rows]
        pairs, n, p1, p2 = rows, dist.n[rows], dist.p1[rows], dist.p2[rows]
        if self.end_spheres and rows.size:
            br = self.world.end_spheres(dist, rows, reach)
            if br.pair.size:
                pairs, n = np.concatenate([pairs, br.pair]), np.vstack([n, br.n])
                p1, p2 = np.vstack([p1, br.p1]), np.vstack([p2, br.p2])
                d, rate = np.concatenate([d, br.d]), np.concatenate([rate, br.rate])
                names += br.names
        H = self.world.point_jacobian(robot, pairs, n, p1, p2)
        inside = d < self.influence
        h = np.where(inside, d - self.safety + rate / g, d - self.safety)
        return BarrierTerm(h, H, names, np.where(inside, g, _NO_CAP))

    def _row_names(self, ids: np.ndarray, prefix: str = "") -> list[str]:
        """The row names (``prefix:name`` with a prefix) of the row ids ``ids`` (:meth:`CollisionWorld.damper_rows`):
        the list of the last call while the rows are the same (the active pairs and end spheres unchanged), else
        built anew from the world's labels (prefixed once per pair set and prefix)."""
        key = ids.tobytes()
        cache = self._names_cache.get(prefix)
        if cache is None or key != cache[0] or cache[1] is not self.world.row_labels:
            labels = self.world.row_labels
            pre = self._prefixed.get(prefix)
            if pre is None or pre[0] is not labels:
                pre = self._prefixed[prefix] = (labels, [f"{prefix}:{n}" for n in labels] if prefix else labels)
            cache = self._names_cache[prefix] = (key, labels, [pre[1][i] for i in ids.tolist()])
        return cache[2]

    # ------------------------------------------------------------------ potential
    def value(self, robot: RobotModel) -> float:
        """p = ½ Σ ((d_i − d)/(d_i − d_s))² over the pairs within d_i (dimensionless)."""
        _, d, _ = self._near(robot)
        s = (self.influence - d) / (self.influence - self.safety)
        return float(0.5 * s @ s)

    def gradient(self, robot: RobotModel) -> np.ndarray:
        """η = −Σ (d_i − d)/(d_i − d_s)² ∂d/∂q, shape (nv,)."""
        rows, d, _ = self._near(robot)
        if not rows.size:
            return np.zeros(robot.nv)
        dist = self.world.compute(robot, self.influence)
        H = self.world.jacobian(robot, dist, rows)
        w = -(self.influence - d) / (self.influence - self.safety) ** 2
        return np.asarray(w @ H)

    def diagnostics(self, robot: RobotModel | None = None) -> CollisionReport:
        """The closest pair, its distance and the active pairs (of the last evaluation, or at ``robot``'s state)."""
        if robot is not None:
            self._near(robot)
        return self.report

    def __repr__(self) -> str:
        return (
            f"CollisionAvoidance(name={self.name!r}, pairs={self.world.n_pairs}, influence={self.influence}, "
            f"safety={self.safety}, xi={self.xi})"
        )

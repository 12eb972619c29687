"""YAML for the robot's world (issue 12): ``collision:`` and ``obstacles:`` of a task file, and the typed entries
built on them, registered in the builders' registries on import.

* ``collision:`` — the robot's collision shapes (``approximation``: capsule | sphere | hull | mesh), the SRDF
  (``srdf: true`` = the one example-robot-data ships beside the URDF, a path, or ``false``), extra ``disable`` link
  pairs, ``self_collision``, ``obstacle_links``, ``exclude_colliding_at_start``.
* ``obstacles:`` — named obstacles ``{type: sphere|box|capsule|cylinder|plane|mesh, ...sizes, xyz, rpy, motion}``
  with ``motion: {velocity: [..], amplitude: [..], frequency: f, phase: φ}`` for a moving one.
* potential ``type: collision`` → :class:`~redundik.collision.CollisionAvoidance` (``kind: bound`` for the
  velocity damper in ``wqp``/``hqp``, a negative ``gain`` for the repulsive potential in ``pinv``/``feedback``);
* potential ``type: support_polygon`` → :class:`~redundik.tasks.balance.SupportPolygon` (``kind: bound``);
* main tasks ``type: com`` (:class:`~redundik.tasks.balance.CoMTask`) and ``type: contact``
  (:class:`~redundik.tasks.balance.ContactTask`).

Every problem is a one-line :class:`~redundik.errors.ConfigError` naming the key path.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import pinocchio as pin
from pydantic import Field

from redundik.collision import CollisionAvoidance, CollisionWorld, Motion, Obstacle, make_shape
from redundik.config import schema as s
from redundik.config.builders import Context, _wrap, check_frame
from redundik.config.registry import As, OptVec3, register
from redundik.config.robot import LoadedRobot, rpy_matrix
from redundik.config.yamlio import join_path, validate
from redundik.errors import ConfigError, RedundikError
from redundik.tasks.balance import CoMTask, ContactTask, SupportPolygon
from redundik.tasks.subtasks import BoundSubtask

Positive = Annotated[float, Field(gt=0)]


class MotionSpec(s.StrictModel):
    """``motion:`` of an obstacle: offset(t) = v t + A sin(2π f t + φ) [m]."""

    velocity: s.Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    amplitude: s.Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    frequency: float = Field(default=0.0, ge=0)
    phase: float = 0.0


class ObstacleSpec(s.StrictModel):
    """One entry of ``obstacles:`` (sizes [m], ``rpy`` in the file's angle unit)."""

    type: Literal["sphere", "box", "capsule", "cylinder", "plane", "mesh"]
    radius: Positive | None = None
    length: Annotated[float, Field(ge=0)] | None = None
    size: Annotated[list[Positive], Field(min_length=3, max_length=3)] | None = None
    path: str | None = None
    scale: Annotated[list[Positive], Field(min_length=3, max_length=3)] = Field(default_factory=lambda: [1.0, 1.0, 1.0])
    xyz: s.Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    rpy: s.Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    motion: MotionSpec | None = None


class CollisionSpec(s.StrictModel):
    """The ``collision:`` section."""

    approximation: Literal["capsule", "sphere", "hull", "mesh"] = "capsule"
    srdf: bool | str = True
    self_collision: bool = True
    disable: list[Annotated[list[s.Name], Field(min_length=2, max_length=2)]] = Field(default_factory=list)
    obstacle_links: list[s.Name] | None = None
    links: list[s.Name] | None = None
    exclude_colliding_at_start: bool = True
    urdf: str | None = None


_NEEDS = {
    "sphere": ("radius",),
    "box": ("size",),
    "capsule": ("radius", "length"),
    "cylinder": ("radius", "length"),
    "mesh": ("path",),
    "plane": (),
}


def build_obstacle(name: str, raw: Any, angle_scale: float, base_dir: Path, path: str) -> Obstacle:
    """An :class:`Obstacle` from its YAML entry.

    Raises:
        ConfigError: at ``path`` (a missing size, a missing or unreadable mesh, NaN poses are refused by the schema).
    """
    spec: ObstacleSpec = validate(ObstacleSpec, raw, path)
    for key in _NEEDS[spec.type]:
        if getattr(spec, key) is None:
            raise ConfigError(f"a {spec.type} obstacle needs '{key}'", path)
    mesh = None
    if spec.path is not None:
        mesh = Path(spec.path) if Path(spec.path).is_absolute() else (base_dir / spec.path)
    try:
        shape = make_shape(
            spec.type, radius=spec.radius, length=spec.length, size=spec.size, path=mesh, scale=spec.scale
        )
    except RedundikError as exc:
        raise ConfigError(str(exc), join_path(path, "path" if spec.type == "mesh" else "type")) from None
    pose = pin.SE3(rpy_matrix(np.asarray(spec.rpy) * angle_scale), np.asarray(spec.xyz, dtype=float))
    motion = None
    if spec.motion is not None:
        m = spec.motion
        motion = Motion(tuple(m.velocity), tuple(m.amplitude), m.frequency, m.phase)  # type: ignore[arg-type]
    return _wrap(path, lambda: Obstacle(name, shape, pose, motion))


def build_world(
    collision: Any, obstacles: dict[str, Any], robot: LoadedRobot, q0: np.ndarray, angle_scale: float, base_dir: Path
) -> CollisionWorld:
    """The task file's :class:`CollisionWorld` (``collision:`` + ``obstacles:``).

    Raises:
        ConfigError: with the key path of the offending entry.
    """
    spec: CollisionSpec = validate(CollisionSpec, collision or {}, "collision")
    if spec.urdf is not None:
        urdf: Path | None = Path(spec.urdf) if Path(spec.urdf).is_absolute() else base_dir / spec.urdf
    else:
        urdf = robot.urdf
    if urdf is None:
        raise ConfigError(
            "collision geometry needs a URDF robot (or 'collision.urdf'); this robot is a D-H table", "collision"
        )
    obs = [
        build_obstacle(name, raw, angle_scale, base_dir, join_path("obstacles", name))
        for name, raw in obstacles.items()
    ]
    srdf: bool | Path = spec.srdf if isinstance(spec.srdf, bool) else (base_dir / spec.srdf)
    try:
        world = CollisionWorld.from_urdf(
            robot.model,
            urdf,
            obs,
            approximation=spec.approximation,
            srdf=srdf,
            disabled=[(a, b) for a, b in spec.disable],
            self_collision=spec.self_collision,
            obstacle_links=spec.obstacle_links,
            links=spec.links,
        )
    except RedundikError as exc:
        msg = str(exc)
        where = "collision"
        if msg.startswith("disabled pair: "):
            where, msg = "collision.disable", msg.removeprefix("disabled pair: ")
        elif msg.startswith("obstacle_links: "):
            where, msg = "collision.obstacle_links", msg.removeprefix("obstacle_links: ")
        elif msg.startswith("links: "):
            where, msg = "collision.links", msg.removeprefix("links: ")
        elif "SRDF" in msg:
            where = "collision.srdf"
        elif "obstacle names" in msg:
            where = "obstacles"
        raise ConfigError(msg, where) from None
    if spec.exclude_colliding_at_start:
        world.exclude_colliding_at(robot.model, q0)
    return world


# ---------------------------------------------------------------------------------------------------- typed entries
# Registered from the constructors (redundik.config.registry): the YAML keys, defaults, bounds and descriptions are
# derived from CollisionAvoidance, SupportPolygon, CoMTask and ContactTask; only what the file adds is written here.
def _world(value: Any, ctx: Context, path: str, spec: Any) -> CollisionWorld:
    world = getattr(ctx, "world", None)
    if world is None:
        raise ConfigError("a collision potential needs a 'collision:' or 'obstacles:' section in the task file", path)
    if spec.influence <= spec.safety:
        raise ConfigError(
            f"influence ({spec.influence}) must be > safety ({spec.safety})", join_path(path, "influence")
        )
    return world


def _feet(value: Any, ctx: Context, path: str, spec: Any) -> list[str]:
    return [check_frame(ctx, f, join_path(path, i)) for i, f in enumerate(value)]


def _distinct_axes(value: Any, ctx: Context, path: str, spec: Any) -> list[str]:
    if len(set(value)) != len(value):
        raise ConfigError(f"expected distinct axes, got {value}", path)
    return list(value)


Positive2 = Annotated[list[Positive], Field(min_length=2, max_length=2)]
register(
    "collision",
    "potential",
    CollisionAvoidance,
    params={"world": As(hidden=True, convert=_world), "influence": As(bounds={"gt": 0}), "xi": As(bounds={"gt": 0})},
)
register(
    "support_polygon",
    "potential",
    SupportPolygon,
    params={
        "feet": As(annotation=Annotated[list[s.Name], Field(min_length=1)], convert=_feet),
        "size": As(annotation=Positive2),
    },
)
register(
    "com",
    "task",
    CoMTask,
    params={
        "target": As(annotation=OptVec3),
        "axes": As(annotation=Annotated[list[s.Axis], Field(min_length=1, max_length=3)], convert=_distinct_axes),
    },
)
register("contact", "task", ContactTask, params={"gain": As(default=10.0, bounds={"ge": 0})})


# ---------------------------------------------------------------------------------------------------- run summary
def world_clock(world: CollisionWorld, dt: float, then: Callable[[int], None] | None) -> Callable[[int], None]:
    """A simulation progress callback that moves the obstacles to t = k·dt after k steps (then calls ``then``)."""

    def cb(k: int) -> None:
        world.set_time(k * dt)
        if then is not None:
            then(k)

    return cb


def world_summary(plan: Any, run: Any, log: Any) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The world numbers of ``summary.json`` for one run, and their per-sample CSV series.

    * ``min_collision_distance`` [m]: the smallest signed distance over every candidate pair and sample (negative:
      penetration), with ``closest_pair``, ``penetrating_samples`` and, per sample, ``min_distance``,
      ``closest_pair_id`` (index into ``collision_pair_names``), ``active_pairs`` (pairs within the run's collision
      influence distance, the barrier's rows) and ``binding_rows`` (damper rows the step's q̇ holds at their bound,
      C q̇ ≥ d − 1e-6: the active constraints; empty on the last sample), with the names of the rows that were
      binding at some step in ``binding_constraints``;
    * ``com_support_margin`` [m]: the smallest signed distance of the CoM projection to the support polygon's
      edges (positive inside; the margin of the barrier not subtracted);
    * ``max_contact_drift`` [m]: the largest ‖p − p₀‖ of a contact task's frame.
    """
    robot = plan.robot.model
    world: CollisionWorld | None = getattr(plan, "world", None)
    sources = [getattr(sub, "source", getattr(sub, "potential", None)) for sub in run.stack.subtasks]
    sources += list(run.watched)
    supports = [p for p in sources if isinstance(p, SupportPolygon)]
    avoid = [p for p in sources if isinstance(p, CollisionAvoidance)]
    contacts = [t for t in run.stack.tasks if isinstance(t, ContactTask)]
    if world is None and not supports and not contacts:
        return {}, {}
    n = log.q.shape[0]
    out: dict[str, Any] = {}
    series: dict[str, np.ndarray] = {}
    dmin = np.full(n, np.inf)
    active = np.zeros(n)
    closest = [""] * n
    margin = np.full(n, np.inf)
    drift = np.zeros(n)
    influence = max((a.influence for a in avoid), default=None)
    closest_id = np.full(n, np.nan)
    binding = np.full(n, np.nan)
    bound_avoid = [
        (sub, sub.source)
        for sub in run.stack.subtasks
        if isinstance(sub, BoundSubtask) and isinstance(sub.source, CollisionAvoidance)
    ]
    binding_names: set[str] = set()
    for k in range(n):
        robot.update(log.q[k])
        if world is not None and world.n_pairs:
            world.set_time(float(log.t[k]))
            dist = world.compute(robot, influence if influence is not None else -np.inf)
            j = int(np.argmin(dist.d))
            dmin[k], closest[k], closest_id[k] = float(dist.d[j]), world.pair_names[j], j
            active[k] = dist.near.size if influence is not None else 0
            if bound_avoid and k < n - 1:
                binding[k] = 0
                for sub, _src in bound_avoid:
                    C, d, names = sub.rows(robot, float(log.t[k + 1] - log.t[k]))
                    hit = np.flatnonzero(C @ log.dq[k] >= d - 1e-6)
                    binding[k] += hit.size
                    binding_names.update(names[i] for i in hit.tolist())
        for sp in supports:
            margin[k] = min(margin[k], sp.value(robot))
        for c in contacts:
            drift[k] = max(drift[k], c.drift(robot))
    if world is not None:
        world.set_time(0.0)
        k = int(np.argmin(dmin))
        out["min_collision_distance"] = float(dmin[k])
        out["closest_pair"] = closest[k]
        out["penetrating_samples"] = int(np.count_nonzero(dmin < 0))
        out["collision_pairs"] = world.n_pairs
        out["collision_pair_names"] = list(world.pair_names)
        series["min_distance"] = dmin
        series["closest_pair_id"] = closest_id
        if influence is not None:
            out["max_active_pairs"] = int(active.max())
            series["active_pairs"] = active
        if bound_avoid:
            out["max_binding_rows"] = int(np.nanmax(binding)) if np.isfinite(binding).any() else 0
            out["binding_constraints"] = sorted(binding_names)
            series["binding_rows"] = binding
    if supports:
        out["com_support_margin"] = float(np.min(margin))
        series["com_support_margin"] = margin
    if contacts:
        out["max_contact_drift"] = float(np.max(drift))
        series["contact_drift"] = drift
    return out, series

"""Random-target stress runs for collision avoidance (used by ``benchmarks/collision_stress.py`` and a fast test).

Each episode draws a target for the hand(s) — inside an obstacle, or across the robot's own body — and runs the
closed loop (q ← q ⊕ q̇ dt) with the collision damper as a hard constraint; every sample's smallest signed
distance over all candidate pairs is recorded. A penetration is a sample with d < 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from redundik.collision.avoidance import CollisionAvoidance
from redundik.collision.world import CollisionWorld, Obstacle, make_shape
from redundik.kinematics import RobotModel, example_robot_data_dir, load_example_robot
from redundik.resolvers import make_resolver
from redundik.tasks import BoundSubtask, FrameTask, PostureTask, TaskStack

PANDA_Q0 = np.array([0.0, -0.785398, 0.0, -2.356194, 0.0, 1.570796, 0.785398, 0.02, 0.02])


@dataclass
class StressResult:
    """Counts of one stress configuration.

    Attributes:
        steps: Control steps run.
        penetrations: Samples with a negative distance.
        min_distance: Smallest signed distance seen [m].
        fallbacks: Steps the resolver reported a fallback.
        closest: Pair of the smallest distance.
        fallback_penetrations: Penetrating samples right after a fallback step (a relaxed QP drops the rows).
        reasons: The fallback notes seen (first 80 characters).
    """

    steps: int = 0
    penetrations: int = 0
    min_distance: float = np.inf
    fallbacks: int = 0
    closest: str = ""
    fallback_penetrations: int = 0
    reasons: set[str] = field(default_factory=set)


def panda_scene() -> tuple[RobotModel, CollisionWorld, list[str]]:
    """The Panda, the panda_shelf obstacles, self-collision; the hand frame."""
    robot = load_example_robot("panda")
    urdf = example_robot_data_dir() / "panda_description/urdf/panda.urdf"

    def at(x: float, y: float, z: float) -> pin.SE3:
        return pin.SE3(np.eye(3), np.array([x, y, z]))

    obstacles = [
        Obstacle("post", make_shape("capsule", radius=0.03, length=1.0), at(0.18, 0.25, 0.5)),
        Obstacle("bay_floor", make_shape("box", size=[0.3, 0.4, 0.03]), at(0.5, 0.4, 0.1)),
        Obstacle("bay_back", make_shape("box", size=[0.03, 0.4, 0.5]), at(0.67, 0.4, 0.35)),
        Obstacle("ball", make_shape("sphere", radius=0.08), at(0.45, -0.25, 0.4)),
    ]
    world = CollisionWorld.from_urdf(robot, urdf, obstacles)
    world.exclude_colliding_at(robot, PANDA_Q0)
    return robot, world, ["panda_hand"]


def talos_scene() -> tuple[RobotModel, CollisionWorld, list[str]]:
    """TALOS (fixed pelvis), self-collision between torso, head, arms and grippers; both grippers as hands."""
    from redundik.kinematics import from_urdf

    urdf = example_robot_data_dir() / "talos_data/robots/talos_reduced.urdf"
    robot = from_urdf(urdf, name="talos")
    links = [
        "base_link", "torso_2_link", "head_2_link",
        "arm_left_3_link", "arm_left_4_link", "arm_left_5_link", "arm_left_7_link", "gripper_left_base_link",
        "arm_right_3_link", "arm_right_4_link", "arm_right_5_link", "arm_right_7_link", "gripper_right_base_link",
    ]  # fmt: skip
    world = CollisionWorld.from_urdf(robot, urdf, links=links)
    world.exclude_colliding_at(robot, talos_q0(robot))
    return robot, world, ["gripper_left_base_link", "gripper_right_base_link"]


def talos_q0(robot: RobotModel) -> np.ndarray:
    """configs/talos.yaml's q0 (half-sitting legs, elbows bent)."""
    q = [0.0, 0.0, -0.411354, 0.859395, -0.448041, -0.001708] * 2 + [0.0, 0.006761]
    q += [-0.3, 0.2, 0.0, -1.6, 0.0, 0.0, 0.1, 0.0, 0.3, -0.2, 0.0, -1.6, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0]
    return np.array(q)


def run_stress(
    scene: str,
    resolver: str,
    backend: str,
    *,
    episodes: int,
    steps: int = 100,
    dt: float = 0.01,
    seed: int = 0,
    lookahead: float = 0.05,
    end_spheres: bool = True,
) -> StressResult:
    """``episodes`` random-target episodes of ``steps`` steps each (module docstring).

    ``lookahead`` and ``end_spheres`` are :class:`CollisionAvoidance`'s (``0.0``, ``False``: the plain damper).
    """
    robot, world, hands = panda_scene() if scene == "panda" else talos_scene()
    q_home = PANDA_Q0 if scene == "panda" else talos_q0(robot)
    rng = np.random.default_rng(seed)
    avoid = CollisionAvoidance(world, influence=0.08, safety=0.01, xi=0.3, lookahead=lookahead, end_spheres=end_spheres)
    tasks = [FrameTask(h, axes="position", gain=8.0) for h in hands]
    bound = BoundSubtask(avoid, priority=0 if resolver == "hqp" else None)
    stack = TaskStack([*tasks, PostureTask(gain=0.5)], [bound])
    options: dict[str, Any] = {"backend": backend}
    if resolver == "hqp":
        options["levels"] = {h: 1 for h in hands}
    res = make_resolver(resolver, **options)
    out = StressResult()
    obstacle_points = [np.asarray(ob.placement.translation) for ob in world.obstacles]
    q = q_home.copy()
    for _ in range(episodes):
        robot.update(q)
        for task in tasks:
            if obstacle_points and rng.random() < 0.6:  # through an obstacle
                p = obstacle_points[rng.integers(len(obstacle_points))] + rng.normal(0, 0.05, 3)
            else:  # across the body: a point near the torso / the other side
                p = (
                    rng.uniform([-0.2, -0.4, -0.1], [0.5, 0.4, 0.8])
                    if scene == "panda"
                    else rng.uniform([-0.1, -0.4, -0.2], [0.5, 0.4, 0.5])
                )
            task.set_target(p)
        res.reset()
        for k in range(steps):
            step = res.step(robot, stack, q, k * dt, dt)
            if step.fallback:
                out.fallbacks += 1
                out.reasons.add(step.fallback[:80])
            q = robot.integrate(q, step.dq, dt)
            robot.update(q)
            name, d = world.closest(robot)
            out.steps += 1
            if d < 0:
                out.penetrations += 1
                out.fallback_penetrations += bool(step.fallback)
            if d < out.min_distance:
                out.min_distance, out.closest = d, name
        if rng.random() < 0.3:
            q = q_home.copy()  # sometimes restart from home, otherwise chain the episodes
    return out

"""The collision part of :func:`redundik.warmup.warm_up`: steps under a resolver a stack with a collision world, so
that the kernels of :mod:`redundik.collision.kernels` a loop reaches are compiled (or loaded) before its first step.

The worlds are built on the warm-up's arm (one capsule per link, self-collision pairs) and differ in what their
obstacles make the world call:

* ``capsules`` — capsule and sphere pairs only, static (a sphere obstacle; a humanoid's self-collision): the damper
  in one compiled call (``capsule_damper``), the distances in one (``capsule_distances``: the potential, a run's
  summary);
* ``boxes`` — a capsule and a box obstacle besides (a shelf; coal computes the box pairs): ``load_poses`` and
  ``capsule_pairs``, then the damper rows (``barrier_rows``);
* ``moving`` — a moving sphere: the damper row by row (``end_spheres``, ``distance_rows``).

A resolver that accepts bound subtasks (``wqp``, ``hqp``) steps the damper on each world (``hqp`` at level 0, as
the shipped task files put it); every resolver steps the repulsive potential as a gradient subtask on the static
worlds (the distances, then ``distance_rows``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import pinocchio as pin

    from redundik.collision import CollisionWorld
    from redundik.kinematics import RobotModel

#: The names of the warm-up's collision subtask (no "runs mixed" warning is logged for it) and of its frame task.
NAME, HAND = "warm_up_collision", "warm_up_hand"


def link_capsules(robot: RobotModel) -> pin.GeometryModel:
    """A ``pin.GeometryModel`` with one capsule (radius 0.04 m, axis 0.2 m) on each link of the warm-up's arm
    (:func:`redundik.from_dh`, a = 0.3 m: link k runs along the x axis of frame k's joint), named ``link<k>``."""
    import coal
    import pinocchio as pin

    model = robot.model
    along_x = pin.SE3(pin.utils.rotate("y", np.pi / 2), np.array([0.15, 0.0, 0.0]))  # (local z along the link)
    geometry = pin.GeometryModel()
    for k in range(1, model.njoints):
        frame = model.getFrameId(model.names[k])
        geometry.addGeometryObject(pin.GeometryObject(f"link{k}", k, frame, along_x, coal.Capsule(0.04, 0.2)))
    return geometry


def worlds(robot: RobotModel, q0: np.ndarray) -> dict[str, CollisionWorld]:
    """The ``capsules``, ``boxes`` and ``moving`` worlds (module docstring), each obstacle 12–15 cm from the axis of
    one link at ``q0`` [rad] (3–6 cm from its capsule)."""
    import pinocchio as pin

    from redundik.collision import CollisionWorld, Motion, Obstacle, make_shape

    robot.update(q0)

    def beside(link: int, kind: str, gap: float, **size: Any) -> Obstacle:
        """An obstacle ``gap`` [m] from the middle of link ``link``'s axis, horizontally and square to the link."""
        a, b = robot.frame_position(str(link - 1)), robot.frame_position(str(link))
        side = np.cross(b - a, [0.0, 0.0, 1.0])
        pose = pin.SE3(np.eye(3), 0.5 * (a + b) + gap * side / np.linalg.norm(side))
        return Obstacle(f"{kind}{link}", make_shape(kind, **size), pose)

    sphere = beside(5, "sphere", 0.12, radius=0.05)
    post, box = beside(6, "capsule", 0.12, radius=0.03, length=0.3), beside(3, "box", 0.15, size=(0.1, 0.1, 0.1))
    moving = beside(4, "sphere", 0.12, radius=0.05)
    moving.motion = Motion(velocity=(0.0, 0.0, -0.01))  # [m/s]
    geometry = link_capsules(robot)
    return {
        "capsules": CollisionWorld(robot, geometry, [sphere]),
        "boxes": CollisionWorld(robot, geometry, [post, box]),
        "moving": CollisionWorld(robot, geometry, [moving]),
    }


def step_collision(rk: Any, robot: RobotModel, name: str, q0: np.ndarray, steps: int = 3) -> None:
    """``steps`` steps of a fresh resolver ``name`` (its compiled step, as a loop's) from ``q0`` [rad] on a frame
    task, a posture and a collision subtask of each kind the resolver accepts, on each of :func:`worlds` (module
    docstring): the damper as a bound (under ``hqp`` at level 0, the frame task at level 1), the repulsive potential
    as a gradient (the static worlds)."""
    from redundik.collision import CollisionAvoidance
    from redundik.resolvers.base import _WARNED_INTERPRETED, _WARNED_MIXED

    res = rk.make_resolver(name, levels={HAND: 1}) if name == "hqp" else rk.make_resolver(name)
    _WARNED_MIXED.add((name, (NAME,)))  # (no "runs mixed" or "runs interpreted" warning for our own)
    _WARNED_INTERPRETED.add((name, (NAME,)))
    subs: list[Any] = []
    for kind, world in worlds(robot, q0).items():
        avoid = CollisionAvoidance(world, influence=0.2, safety=0.01, xi=0.2)
        if "bound" in res.accepts:
            subs.append(rk.BoundSubtask(avoid, priority=0 if name == "hqp" else None, name=NAME))
        if "gradient" in res.accepts and kind != "moving":
            subs.append(rk.GradientSubtask(avoid, gain=-1.0, name=NAME))
    for sub in subs:
        task = rk.FrameTask("7", rk.Circle(0.02, np.pi, plane=("y", "z")), gain=5.0, name=HAND)
        stack = rk.TaskStack([task, rk.PostureTask(gain=1.0)], [sub])
        q = q0.copy()
        robot.update(q)
        stack.reset(robot)
        for k in range(steps):
            q = robot.integrate(q, res.step(robot, stack, q, k * 0.01, 0.01).dq, 0.01)

"""Compile (or load from numba's on-disk cache) the kernels a control loop uses, before the loop starts.

The resolvers' closed forms and their fused steps are numba kernels, compiled at their first call and cached on disk
in the user's cache folder (``redundik._kernel_cache.cache_dir``). On an empty cache a resolver's first steps
run interpreted while a background thread compiles them (``redundik._coldstart``, which calls this function);
:func:`warm_up` pays the compilation ahead instead, in the caller's thread — at start-up, in a container build
(``redundik compile``), or before a real-time loop that must be compiled from its first tick — and says so in a
``logging`` line.
"""

from __future__ import annotations

import logging
import time
from typing import Any

import numpy as np

_LOG = logging.getLogger("redundik")

#: The resolvers :func:`warm_up` steps by default.
RESOLVERS: tuple[str, ...] = ("pinv", "feedback", "wqp", "hqp")


def warm_up(resolvers: tuple[str, ...] | list[str] = RESOLVERS, *, ik: bool = True) -> dict[str, float]:
    """Step each resolver of ``resolvers`` a few times on a small arm (a frame task on a trajectory, a target set
    at run time in each accepted form, a posture, a joint centering and the potentials with compiled writers, joint
    limits; a user's task, a relative pose, target subtasks, the centre of mass, and under ``wqp``/``hqp`` a clearance
    bound that binds and the support polygon), then on collision worlds
    (:func:`redundik.warmup_collision.step_collision`: the damper as a bound, the repulsive potential as a gradient),
    so that the kernels of their compiled and interpreted steps — constrained ones and the collision world's
    included — are compiled or loaded; with ``ik``, also
    :func:`redundik.solve_ik` (a pose and a position target, and the batch form), under the key ``"solve_ik"``;
    returns the seconds each took.

    Raises:
        ResolverError: an unknown resolver name (the message lists the known ones).
    """
    import redundik as rk
    from redundik import _coldstart
    from redundik._kernel_cache import cache_dir
    from redundik.warmup_collision import step_collision

    _coldstart.adopt()  # (numba imported and the deferred kernels decorated: _kernel_cache.defer_numba)

    _LOG.info(
        "redundik: loading the compiled kernels from %s (a first run on an empty cache compiles them: up to a minute)",
        cache_dir(),
    )
    robot = _arm(rk)
    q0 = np.full(robot.nq, 0.3)
    out: dict[str, float] = {}
    for name in resolvers:
        t0 = time.perf_counter()
        resolver = rk.make_resolver(name)
        with _coldstart.compiling():  # this thread's kernel calls compile: none runs interpreted
            _step_both_paths(rk, robot, resolver, q0)
            step_collision(rk, robot, name, q0)
            _speed_cap()
            if name == "wqp":  # (a step whose limit binds solves its box QP through daqp's C entry point)
                from redundik.resolvers.qp.wqp_native import warm_native_box

                warm_native_box()
        _coldstart.HOT.add(name)
        out[name] = time.perf_counter() - t0
    if ik:
        t0 = time.perf_counter()
        robot.update(q0)
        home = robot.frame_pose("7")
        with _coldstart.compiling():
            rk.solve_ik(robot, "7", home, q0, timeout=None, max_restarts=0)
            rk.solve_ik(robot, "7", home.translation + 0.01, q0, timeout=None, max_restarts=0)
            rk.solve_ik_batch(robot, "7", [home, home], q0, timeout=None, max_restarts=0)
        out["solve_ik"] = time.perf_counter() - t0
    _LOG.info("redundik: kernels ready in %.1f s", sum(out.values()))
    return out


def _arm(rk: Any) -> Any:
    """The warm-up's arm: 7 revolute joints of a DH chain (a = 0.3 m, α = ±π/2), a body of 1 kg on each link (its
    centre of mass 0.15 m along the link), so that the centre-of-mass writers run."""
    import pinocchio as pin

    robot = rk.from_dh([rk.DHRow(str(k), a=0.3, alpha=np.pi / 2 if k % 2 else -np.pi / 2) for k in range(1, 8)])
    model = robot.model
    for j in range(1, model.njoints):
        model.inertias[j] = pin.Inertia(1.0, np.array([0.15, 0.0, 0.0]), 0.01 * np.eye(3))
    return robot


def _speed_cap() -> None:
    """The joint-speed cap's test (``SpeedLimiter.binds``: max |q̇_i| / c_i), which a step reaches only when ‖q̇‖
    exceeds the smallest cap: the warm-up's slow steps never do, and a loop's first fast step compiled it."""
    from redundik.resolvers.linalg import K

    K.scaled_max(np.ones(2), np.ones(2))


def _gradients(rk: Any) -> list[Any]:
    """Gradient subtasks on a joint centering and on each potential with a compiled writer (their kernels)."""
    from redundik.tasks.waypoints import JointWaypoints

    return [
        rk.GradientSubtask(rk.JointCentering(), gain=-1.0),
        rk.GradientSubtask(rk.JointSine2("4"), gain=0.01),
        rk.GradientSubtask(rk.JointValue("2", 0.3), gain=-0.01),
        rk.GradientSubtask(rk.VirtualPoint("3", [0.5, 0.5, 0.5]), gain=-0.01),
        rk.GradientSubtask(rk.Clearance("5", [1.0, 1.0, 1.0], 0.1), gain=0.01),
        rk.GradientSubtask(JointWaypoints("1", [0.5, 0.3]), gain=-0.01),
        rk.GradientSubtask(rk.BestPosture("7"), gain=-0.001),
        rk.GradientSubtask(rk.Manipulability("7", axes="position"), gain=0.001),
    ]


def _step_both_paths(rk: Any, robot: Any, resolver: Any, q0: np.ndarray) -> None:
    """Three steps of each of the warm-up's stacks, on the resolver's compiled step and on its per-task path."""
    for fuse in (True, False) if hasattr(resolver, "fuse") else (None,):
        if fuse is not None:
            resolver.fuse = fuse
        for kind in ("trajectory", "teleop", "user", "relative", "targets", "binding", "balance"):
            stack = _stack(rk, robot, resolver.name, kind, q0)
            if stack is None:
                continue
            task = stack.tasks[0]
            q = q0.copy()
            robot.update(q)
            stack.reset(robot)
            home = robot.frame_pose("7")
            for k in range(3):
                if kind == "teleop":  # (each accepted form: an SE3, twice — the hold made, then written in place —
                    _set_target(task, home, k)  # a 4×4 matrix, a position)
                q = robot.integrate(q, resolver.step(robot, stack, q, k * 0.01, 0.01).dq, 0.01)


def _stack(rk: Any, robot: Any, resolver: str, kind: str, q0: np.ndarray) -> Any:
    """The warm-up's stack of ``kind`` for ``resolver`` (``None``: a kind the resolver refuses): a frame task (on a
    trajectory, or re-targeted), then the posture and the gradients; a user's task among them (the mixed step); a
    relative pose (``RelativePoseTask``'s writer); target subtasks (the feedback law, a QP's weighted rows); a bound
    on a clearance that binds from the first step (``wqp``'s rows QP, ``hqp``'s constrained cascade); the centre of
    mass (``CoMTask``'s writer) and, under a QP resolver, the support polygon's barrier (its writer)."""
    from redundik.resolvers.base import _WARNED_MIXED

    teleop = kind == "teleop"
    task = rk.FrameTask("7", None if teleop else rk.Circle(0.02, np.pi, plane=("y", "z")), gain=5.0)
    qp = resolver in ("wqp", "hqp")
    if kind == "user":  # a user's own task among compiled ones: the mixed step's writing of its rows
        _WARNED_MIXED.add((resolver, ("warm_up_height",)))  # (no "runs mixed" warning for our own)
        return rk.TaskStack([task, _user_task(rk), rk.PostureTask(gain=1.0)])
    if kind == "relative":
        return rk.TaskStack([task, rk.RelativePoseTask("7", "4", axes="position"), rk.PostureTask(gain=1.0)])
    if kind == "targets":
        if resolver == "pinv":
            return None
        return rk.TaskStack([task], [rk.TargetSubtask(rk.JointCentering(), target=0.5, rate=1.0)])
    if kind == "balance":  # the centre of mass as a task, and (QP resolvers) the support polygon's barrier
        from redundik.tasks.balance import CoMTask, SupportPolygon

        com = CoMTask(axes=("x", "y"), gain=1.0, weight=0.1)
        support = [rk.BoundSubtask(SupportPolygon(["2"], size=(1.0, 1.0), margin=0.0))] if qp else []
        return rk.TaskStack([task, com, rk.PostureTask(gain=1.0)], support)
    if kind == "binding":
        if not qp:
            return None
        robot.update(q0)
        near = robot.frame_position("6") + np.array([0.05, 0.0, 0.0])  # (5 cm away, kept ≥ 20 cm: it binds)
        bound = rk.BoundSubtask(rk.Clearance("6", near, 0.0), lower=0.2)
        return rk.TaskStack([task, rk.PostureTask(gain=1.0)], [bound])
    subs = _gradients(rk)
    if qp:  # (a bound on a clearance: its compiled damper rows)
        subs.append(rk.BoundSubtask(rk.Clearance("6", [1.0, 1.0, 1.0], 0.1), lower=0.01))
    return rk.TaskStack([task, rk.PostureTask(gain=1.0)], subs)


def _set_target(task: Any, home: Any, k: int) -> None:
    """Step k's re-targeting of the teleop stack's frame task (``home``: the frame's pose at the start): an SE3
    twice at k = 0 (the first makes the task's hold, the second is written into it), its 4×4 matrix at k = 1, a
    position at k = 2."""
    if k == 0:
        task.set_target(home)
        task.set_target(home)
    elif k == 1:
        task.set_target(np.array(home.homogeneous))
    else:
        task.set_target(home.translation + 0.001 * k)


def _user_task(rk: Any) -> Any:
    """A task of the kind a user writes (a Python ``evaluate``: the height of frame "4", one row)."""

    class Height(rk.Task):  # type: ignore[misc]
        def __init__(self) -> None:
            self._init_task("warm_up_height", gain=1.0)

        def evaluate(self, robot: Any, t: float) -> Any:
            e = np.array([0.1 - robot.frame_position("4")[2]])
            return rk.TaskTerm(self.name, robot.frame_jacobian("4")[2:3], self.gain * e, e, self.weight)

        def __repr__(self) -> str:
            return "Height()"

    return Height()

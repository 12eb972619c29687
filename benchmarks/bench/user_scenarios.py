"""What users run (issue 31 item 8), as cases of the main benchmark — public classes only:

* ``panda_teleop``, ``talos_teleop``: the ``panda_circle`` / ``talos`` task sets, but redundik's frame tasks have no
  trajectory: every tick the runner calls ``FrameTask.set_target(T)`` (inside the timed tick) with the reference
  pose of t + dt (a moving target; gain 1/dt, the same dead-beat request as the peers'). The pose is made outside
  the timed tick (the operator's device, not the library); mink, pink and PlaCo get the same pose every tick
  (their ``set_target`` / ``T_world_frame`` inside their timed tick).
* ``panda_user_task``: ``panda_circle`` with the hand task a user's ``class MyFrameTask(FrameTask): pass``
  (:class:`benchmarks.user_cases.MyFrameTask`); the same task set, so its peers are ``panda_circle``'s.
* ``panda_custom_task``: ``panda_circle`` plus a user's 10-line ``Task`` subclass (the elbow's lateral position,
  :class:`benchmarks.user_cases.ElbowSide`, held at q0's: the arm's redundant degree of freedom there); no peer
  runs that task, so it has no peer ratio, only
  the ratio to the built-in case.

Each of these, and ``talos_actuated``, is also compared with its built-in case (:data:`BASELINES`) of the same
method and backend in the same run.
"""

from __future__ import annotations

import time

import numpy as np

from benchmarks.bench.scenarios import PANDA_Q0, Scenario, panda_scenario, talos_scenario
from benchmarks.user_cases import ElbowSide, MyFrameTask
from redundik.kinematics.urdf import load_example_robot
from redundik.tasks.base import Task

#: Each user case's built-in case (same method and backend, same run): the "× built-in" ratio.
BASELINES: dict[str, str] = {
    "panda_teleop": "panda_circle",
    "talos_teleop": "talos",
    "panda_user_task": "panda_circle",
    "panda_custom_task": "panda_circle",
    "talos_actuated": "talos",
}
#: Cases whose peers are another robot's (the identical task set, not run twice); ``None``: no peer ratio.
PEERS_OF: dict[str, str | None] = {
    "panda_user_task": "panda_circle",
    "panda_custom_task": None,
    "talos_actuated": "talos",
}
#: The redundik methods of the user cases that have no peers of their own.
REDUNDIK_METHODS: tuple[str, ...] = ("pinv", "feedback", "wqp", "hqp")


def panda_teleop_scenario() -> Scenario:
    """``panda_circle`` driven by ``set_target`` every tick."""
    sc = panda_scenario()
    sc.key, sc.teleop = "panda_teleop", True
    sc.title = "Panda, hand re-targeted every tick (set_target) along the 5 cm circle, posture, limits"
    return sc


def talos_teleop_scenario() -> Scenario:
    """``talos`` driven by ``set_target`` every tick (both grippers)."""
    sc = talos_scenario()
    sc.key, sc.teleop = "talos_teleop", True
    sc.title = "Talos (free flyer), both grippers re-targeted every tick (set_target), posture, limits"
    return sc


def panda_user_task_scenario() -> Scenario:
    """``panda_circle`` with a user's ``FrameTask`` subclass that changes nothing."""
    sc = panda_scenario()
    sc.key, sc.frame_class = "panda_user_task", MyFrameTask
    sc.title = "Panda circle, hand task = `class MyFrameTask(FrameTask): pass`"
    sc.methods, sc.placo, sc.all_backends = REDUNDIK_METHODS, False, False
    return sc


def panda_custom_task_scenario() -> Scenario:
    """``panda_circle`` plus a user's own 10-line task (the elbow's lateral position held at q0's, gain 5/s,
    weight 1)."""
    robot = load_example_robot("panda")
    robot.update(PANDA_Q0)
    y0 = float(robot.frame_position("panda_link4")[1])

    def extra() -> list[Task]:
        return [ElbowSide(y0, gain=5.0)]

    sc = panda_scenario()
    sc.key, sc.extra_tasks = "panda_custom_task", extra
    sc.title = "Panda circle + a user's 10-line Task subclass (the elbow's lateral position, benchmarks/user_cases.py)"
    sc.methods, sc.placo, sc.all_backends = REDUNDIK_METHODS, False, False
    return sc


def custom_task_evaluate_us(calls: int = 200, blocks: int = 7) -> float:
    """The user's task's own cost: the median over ``blocks`` of the mean time of ``ElbowSide.evaluate`` [µs]
    (on the Panda at q0, kinematics updated once), for issue 31's "a custom task adds its evaluate + 10 %"."""
    robot = load_example_robot("panda")
    robot.update(PANDA_Q0)
    task = ElbowSide(0.0, gain=5.0)
    task.evaluate(robot, 0.0)
    per = []
    for _ in range(blocks):
        t0 = time.perf_counter_ns()
        for _ in range(calls):
            task.evaluate(robot, 0.0)
        per.append((time.perf_counter_ns() - t0) / calls / 1e3)
    return float(np.median(per))


USER_SCENARIOS = {
    "panda_teleop": panda_teleop_scenario,
    "talos_teleop": talos_teleop_scenario,
    "panda_user_task": panda_user_task_scenario,
    "panda_custom_task": panda_custom_task_scenario,
}

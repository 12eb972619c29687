"""Alarms that mean something: ``result.fallback`` (the answer is not what the stack asked) against
``result.relaxed`` (a relaxation the stack is documented to make).

The Panda's hand jumps to a new target every 0.2 s under ``hqp`` with two joint bounds on levels 1 and 2 that ask
more than the velocity limits and each other allow (joint 4 kept out of a band and pushed into it). The bounds are
relaxed on most steps and ``result.relaxed`` names them; ``result.fallback`` stays ``None``: nothing failed. Then
the same stack with a backend that refuses every QP: every step that needs one falls back to the damped closed form,
and ``result.fallback`` says so. An alarm on ``fallback`` fires on the second run only.

Run: ``python examples/alarms.py``; the last line is the check.
"""

from __future__ import annotations

import logging
from collections import Counter

import numpy as np

import redundik as rk
from redundik.errors import SolverError
from redundik.resolvers.qp import Backend, QPProblem, QPSolution

logging.getLogger("redundik").setLevel(logging.ERROR)  # (a note that the bounds run interpreted)
DT = 0.01
STEPS = 200
TIP = "panda_hand_tcp"


class RefusingBackend(Backend):
    """A QP backend that never solves (a stand-in for a solver that crashed)."""

    name = "refusing"

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        raise SolverError(f"refusing: {problem.label} not solved", problem)


def run(backend: str | Backend) -> tuple[int, Counter[str], str | None]:
    """(steps with a fallback, how often each name was relaxed, the first fallback note)."""
    robot = rk.load_example_robot("panda")
    q = np.array([0.0, -0.4, 0.0, -2.2, 0.0, 1.8, 0.8, 0.02, 0.02])
    robot.update(q)
    tip = rk.FrameTask(TIP, axes="position", gain=20.0, name="tip")
    band = rk.JointValue("panda_joint4", -1.6)
    stack = rk.TaskStack(
        [tip, rk.PostureTask(gain=1.0, name="posture")],
        [
            rk.BoundSubtask(band, lower=0.5**2, rate=50.0, name="keep_out"),  # |q4 + 1.6| ≥ 0.5
            rk.BoundSubtask(band, upper=0.2**2, rate=50.0, name="keep_in"),  # |q4 + 1.6| ≤ 0.2: contradicts it
        ],
    )
    stack.reset(robot)
    resolver = rk.make_resolver("hqp", backend=backend, levels={"keep_out": 1, "keep_in": 2})
    rng = np.random.default_rng(4)
    fallbacks, relaxed, first = 0, Counter[str](), None
    for k in range(STEPS):
        if k % 20 == 0:  # the application moves the target
            tip.set_target(np.array([0.5, 0.0, 0.4]) + rng.uniform(-0.2, 0.2, 3))
        result = resolver.step(robot, stack, q, k * DT, DT)
        if result.fallback is not None:  # the alarm
            fallbacks += 1
            first = first or result.fallback
        relaxed.update(result.relaxed)  # a counter, not an alarm
        q = robot.integrate(q, result.dq, DT)
    return fallbacks, relaxed, first


def main() -> int:
    fb, relaxed, _ = run("daqp")
    print(f"daqp:     fallback on {fb} of {STEPS} steps; relaxed {dict(relaxed)}")
    fb_bad, _, note = run(RefusingBackend())
    print(f"refusing: fallback on {fb_bad} of {STEPS} steps; first: {note}")
    ok = fb == 0 and relaxed["keep_in"] > STEPS // 2 and fb_bad > STEPS // 2
    print(f"check: no alarm while the bounds are relaxed, an alarm when the backend fails: {'OK' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

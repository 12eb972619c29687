"""Teleoperation: a scripted operator moves the tool target every tick (jumps included) — targets set at run time.

The Panda's tool frame task has no trajectory: it holds whatever target the operator last set with
``FrameTask.set_target`` (an SE3, a 4×4 matrix, or a position that keeps the current orientation). A posture task
(a regulariser: it lies below the frame task under every resolver) keeps the arm near its start. The operator
drags the target along a slow figure-eight, jumps it 4 cm at t = 1 s, and sends a position-only target at
t = 2 s; ``stack.reset`` in the middle (as a controller restart would) keeps the target that was set.

Run: ``python examples/teleop.py [--resolver pinv|wqp|hqp|feedback]``; the last line is a JSON record.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pinocchio as pin

import redundik as rk

DT = 2e-3  # control period [s]
TICKS = 1500  # 3 s
GAIN = 40.0  # [1/s] on the tool error (K·dt = 0.08)
TOOL = "panda_hand_tcp"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolver", choices=["pinv", "wqp", "hqp", "feedback"], default="hqp")
    args = parser.parse_args(argv)

    robot = rk.load_example_robot("panda")
    q = np.array([0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.02, 0.02])
    tool = rk.FrameTask(TOOL, gain=GAIN)  # no trajectory: holds its target
    stack = rk.TaskStack([tool, rk.PostureTask(gain=1.0)])
    resolver = rk.make_resolver(args.resolver)
    robot.update(q)
    stack.reset(robot)
    home = robot.frame_pose(TOOL).copy()  # frame_pose is a live view on the kinematic data: copy to keep it
    errors = np.empty(TICKS)
    fallbacks = 0
    for k in range(TICKS):
        t = k * DT
        offset = np.array([0.0, 0.05 * np.sin(2.0 * t), 0.03 * np.sin(4.0 * t)])  # a slow figure-eight [m]
        if t >= 1.0:
            offset += np.array([0.04, 0.0, 0.0])  # the operator jumps the target 4 cm
        if t < 2.0:
            tool.set_target(pin.SE3(home.rotation, home.translation + offset))
        else:
            tool.set_target(home.translation + offset)  # position only: the orientation target is kept
        if k == 750:
            stack.reset(robot)  # a controller restart keeps the target that was set
        result = resolver.step(robot, stack, q, t, DT)
        errors[k] = float(np.linalg.norm(result.terms[0].error[:3]))
        fallbacks += result.fallback is not None
        q = robot.integrate(q, result.dq, DT)
    robot.update(q)
    jump = int(1.0 / DT)
    record = {
        "resolver": args.resolver,
        "steps": TICKS,
        "error_before_jump_m": float(np.max(errors[100:jump])),  # tracking the moving target (lag ∝ speed / K)
        "error_at_jump_m": float(errors[jump]),
        "settled_error_m": float(np.max(errors[jump + 150 :])),
        "fallback_steps": fallbacks,
        "limit_violation": float(robot.limit_violation(q).max()),
    }
    print(json.dumps(record))
    ok = record["settled_error_m"] < 5e-3 and record["error_at_jump_m"] > 0.03 and fallbacks == 0
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

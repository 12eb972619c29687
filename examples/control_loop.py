"""redundik inside a control loop: no YAML, no files, no plots — one resolver step per control tick.

A Panda (9 velocity coordinates: 7 arm joints and 2 fingers) keeps its gripper orientation while the tool point
draws a 10 cm circle at 1 kHz; the redundancy (9 − 6 = 3) is used to keep the joints near the middle of their
ranges (p = ½‖q − q_c‖², gain k < 0, a gradient subtask). The same stack runs under every resolver: ``pinv`` and
``feedback`` project the gradient in the null space (eq. 5.8), ``hqp`` puts it on its own lowest level, ``wqp``
weights it ρ = 1e-4 below the frame task (see docs/stack.md). In a real stack ``q`` would come from the joint
encoders and ``dq`` would be sent to the velocity controller; here the loop integrates q ← q ⊕ q̇·dt itself.

Run: ``python examples/control_loop.py [--resolver pinv|wqp|hqp|feedback] [--steps N]``; the last line printed is
one JSON record (resolver, steps, max_position_error_m, fallback_steps, max_abs_dq, moved).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

import redundik as rk

DT = 1e-3  # control period [s]
TURN = 2000  # ticks of one turn of the circle (2 s)
TOOL = "panda_hand_tcp"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolver", choices=["pinv", "wqp", "hqp", "feedback"], default="pinv")
    parser.add_argument("--steps", type=int, default=TURN, help="control ticks (default: one turn, 2000)")
    parser.add_argument("--quiet", action="store_true", help="print only the JSON line")
    args = parser.parse_args(argv)
    if args.steps < 1:
        parser.error("--steps must be ≥ 1")

    # --- the README's snippet -------------------------------------------------------------------------------
    robot = rk.load_example_robot("panda")
    stack = rk.TaskStack(
        [rk.FrameTask(TOOL, rk.Circle(0.1, np.pi, plane=("y", "z")), gain=50.0)],  # feed-forward + 50 /s feedback
        [rk.GradientSubtask(rk.JointCentering(), gain=-2.0)],  # k < 0: descend ½‖q − q_c‖² in the null space (5.8)
    )
    resolver, dt = rk.make_resolver(args.resolver), DT
    q = np.array([0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.02, 0.02])
    robot.update(q)
    stack.reset(robot)
    q0 = q.copy()
    worst, fallbacks, max_dq = 0.0, 0, 0.0
    for tick in range(args.steps + 1):  # one call per control tick
        result = resolver.step(robot, stack, q, tick * dt, dt)  # q̇, residuals, damping / fallback diagnostics
        worst = max(worst, float(np.linalg.norm(result.terms[0].error[:3])))
        if tick == args.steps:
            break
        fallbacks += result.fallback is not None
        max_dq = max(max_dq, float(np.max(np.abs(result.dq))))
        q = robot.integrate(q, result.dq, dt)  # or send result.dq to the robot
        if not args.quiet and tick % 500 == 0:
            print(f"t = {tick * dt:5.2f} s   position error {1e3 * worst:8.4f} mm   fallback: {result.fallback}")
    # ----------------------------------------------------------------------------------------------------------
    moved = bool(np.linalg.norm(robot.difference(q0, q)) > 1e-6)
    record = {
        "resolver": args.resolver,
        "steps": args.steps,
        "max_position_error_m": worst,
        "fallback_steps": fallbacks,
        "max_abs_dq": max_dq,
        "moved": moved,
        "limit_violation": float(robot.limit_violation(q).max()),
    }
    print(json.dumps(record))
    return 0 if worst < 1e-3 and fallbacks == 0 and moved else 1


if __name__ == "__main__":
    raise SystemExit(main())

"""Direction-preserving scaling: a hand that slows down along its path instead of swerving when a limit binds.

An operator drags the Panda's tool target 0.35 m across the workspace in one jump; the tool task's gain turns that
into a commanded velocity V far beyond the joint velocity limits. The same run under ``hqp`` twice: unscaled, the
hand's velocity J q̇ is the closest the limits allow to V and points off V's direction while a limit binds; with
``scaling="direction"`` it is α V exactly (α ∈ [0, 1] the largest the limits allow), and ``result.scale`` /
``result.stuck`` say how much of V was delivered. Both runs end at the target; only one went straight.

Run: ``python examples/direction_scaling.py [--resolver hqp|wqp]``; the last line is a JSON record.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pinocchio as pin

import redundik as rk

DT = 1e-2  # control period [s]
TICKS = 150  # 1.5 s
GAIN = 20.0  # [1/s] on the tool error (K·dt = 0.2)
TOOL = "panda_hand_tcp"
JUMP = np.array([0.15, -0.3, -0.1])  # the operator's jump [m]


def angle(a: np.ndarray, b: np.ndarray) -> float:
    """The angle between two vectors [rad] (0 when either is zero)."""
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    return 0.0 if na == 0.0 or nb == 0.0 else math.acos(min(1.0, max(-1.0, float(a @ b) / (na * nb))))


def run(resolver_name: str, scaling: str) -> dict[str, float]:
    """One run toward the jumped target; the largest angle between J q̇ and V, α's range, the path's straightness."""
    robot = rk.load_example_robot("panda")
    q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
    robot.update(q)
    tool = rk.FrameTask(TOOL, axes="position", gain=GAIN)
    stack = rk.TaskStack([tool, rk.PostureTask(gain=1.0)])
    start = robot.frame_position(TOOL).copy()
    goal = start + JUMP
    tool.set_target(pin.SE3(robot.frame_pose(TOOL).rotation, goal))
    resolver = rk.make_resolver(resolver_name, scaling=scaling)
    worst, alphas, off_line, stuck = 0.0, [], 0.0, 0
    line = JUMP / np.linalg.norm(JUMP)
    for k in range(TICKS):
        res = resolver.step(robot, stack, q, k * DT, DT)
        term = res.terms[0]
        if np.linalg.norm(term.v) > 1e-6:
            worst = max(worst, angle(term.J @ res.dq, term.v))
        alphas.append(res.scale)
        stuck += res.stuck
        q = robot.integrate(q, res.dq, DT)
        robot.update(q)
        rel = robot.frame_position(TOOL) - start
        off_line = max(off_line, float(np.linalg.norm(rel - (rel @ line) * line)))  # distance from the straight line
    return {
        "max_angle_deg": math.degrees(worst),
        "min_alpha": float(min(alphas)),
        "final_alpha": float(alphas[-1]),
        "stuck_steps": stuck,
        "max_off_line_mm": 1e3 * off_line,
        "final_error_mm": 1e3 * float(np.linalg.norm(robot.frame_position(TOOL) - goal)),
        "limit_violation": float(robot.limit_violation(q).max()),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolver", choices=["hqp", "wqp"], default="hqp")
    args = parser.parse_args(argv)
    plain = run(args.resolver, "off")
    scaled = run(args.resolver, "direction")
    for name, rec in (("unscaled", plain), ("direction", scaled)):
        print(
            f"{args.resolver} {name:>9}: J q̇ off V by up to {rec['max_angle_deg']:.2e}°, α from {rec['min_alpha']:.3f} "
            f"to {rec['final_alpha']:.3f}, hand up to {rec['max_off_line_mm']:.1f} mm off the straight line, "
            f"{rec['final_error_mm']:.2f} mm from the target at the end"
        )
    print(json.dumps({"resolver": args.resolver, "unscaled": plain, "direction": scaled}))
    ok = (
        scaled["max_angle_deg"] < 1e-4
        and plain["max_angle_deg"] > 1.0
        and scaled["min_alpha"] < 1.0
        and scaled["limit_violation"] == 0.0
        and scaled["final_error_mm"] < 1.0
    )
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

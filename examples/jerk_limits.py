"""Jerk limits: the same target jumps with no rate limit, an acceleration limit, and acceleration plus jerk limits.

The Panda's hand jumps to a new position target 15 cm away every second (a teleoperator's clicks); ``wqp`` tracks
it under the model's position and velocity limits plus, in turn, nothing more, a_max = 10 rad/s², and a_max =
10 rad/s² with j_max = 200 rad/s³ (``JointLimits(acceleration=..., jerk=...)``, in YAML ``limits: {acceleration: 10,
jerk: 200}``). For each it prints the smoothness metrics of :mod:`redundik.reporting.smoothness` — max |q̈|, max
|jerk| and the chatter (sign changes of q̈ per joint per second) — the steps that reported a relaxation
(``result.relaxed``), and the hand's error at the end of each jump.

Run: ``python examples/jerk_limits.py``; the last line is a JSON record.
"""

from __future__ import annotations

import json

import numpy as np

import redundik as rk
from redundik.reporting import smoothness

DT = 5e-3  # control period [s]
TICKS = 1000  # 5 s
HAND = "panda_hand"
JUMPS = np.array([[0.15, 0.0, 0.0], [0.0, -0.15, 0.0], [0.0, 0.0, -0.15], [-0.15, 0.15, 0.0], [0.0, 0.0, 0.15]])


def run(limits: rk.JointLimits) -> dict[str, object]:
    """Five target jumps under ``wqp`` with ``limits``: the smoothness summary, relaxed steps and errors."""
    robot = rk.load_example_robot("panda")
    q = np.array([0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.02, 0.02])
    hand = rk.FrameTask(HAND, axes="position", gain=5.0)
    stack = rk.TaskStack([hand, rk.PostureTask(q, gain=1.0, weight=1e-3)])
    resolver = rk.make_resolver("wqp", limits=limits)
    robot.update(q)
    stack.reset(robot)
    start = robot.frame_position(HAND).copy()
    dqs, relaxed, errors, target = [], 0, [], start
    for k in range(TICKS):
        if k % 200 == 0:
            if k:
                robot.update(q)
                errors.append(float(np.linalg.norm(robot.frame_position(HAND) - target)))
            target = start + JUMPS[: k // 200 + 1].sum(axis=0)
            hand.set_target(target)
        out = resolver.step(robot, stack, q, k * DT, DT)
        relaxed += bool(out.relaxed)
        dqs.append(np.array(out.dq, dtype=float))
        q = robot.integrate(q, out.dq, DT)
    robot.update(q)
    errors.append(float(np.linalg.norm(robot.frame_position(HAND) - target)))
    summary = smoothness.summary(np.array(dqs), DT, robot.joint_names)
    return {
        "max_abs_ddq": summary["max_abs_ddq"],
        "max_abs_jerk": summary["max_abs_jerk"],
        "chatter_max_per_s": summary["chatter_per_s"]["max"],
        "chatter_mean_per_s": summary["chatter_per_s"]["mean"],
        "relaxed_steps": relaxed,
        "max_error_after_jump_m": max(errors),
    }


def main() -> int:
    cases = {
        "no rate limit": rk.JointLimits(),
        "a_max 10": rk.JointLimits(acceleration=10.0),
        "a_max 10, j_max 200": rk.JointLimits(acceleration=10.0, jerk=200.0),
    }
    results = {name: run(lim) for name, lim in cases.items()}
    print(f"{'limits':22s} {'max |q̈|':>12s} {'max |jerk|':>12s} {'chatter max':>12s} {'mean':>8s} {'relaxed':>8s}")
    print(f"{'':22s} {'[rad/s²]':>12s} {'[rad/s³]':>12s} {'[1/s]':>12s} {'[1/s]':>8s} {'steps':>8s}")
    for name, r in results.items():
        print(
            f"{name:22s} {r['max_abs_ddq']:12.4g} {r['max_abs_jerk']:12.4g} {r['chatter_max_per_s']:12.3g} "
            f"{r['chatter_mean_per_s']:8.3g} {r['relaxed_steps']:8d}"
        )
    limited = results["a_max 10, j_max 200"]
    assert limited["max_abs_jerk"] <= 200.0 * (1 + 1e-9) and limited["max_abs_ddq"] <= 10.0 * (1 + 1e-9)
    print(json.dumps(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""IK to convergence with rk.solve_ik: a Panda pose, a position, two frames at once, and a batch of 100 poses.

Every answer is within the joint limits (even a failed one); tolerances are separate in metres and radians. The
targets are the frames' poses at random in-limit configurations, so each is reachable.

Run: ``python examples/solve_ik.py``; the last line printed is one JSON record (success rates, worst errors,
limit violations).
"""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin

import redundik as rk

TOOL = "panda_hand_tcp"


def pose_at(robot: rk.RobotModel, q: np.ndarray, frame: str) -> pin.SE3:
    """The frame's pose at q (forward kinematics)."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.frame_id(frame)].copy()


def main() -> int:
    robot = rk.load_example_robot("panda")
    rng = np.random.default_rng(2026)  # not 0: solve_ik's restarts are seeded with 0 by default
    target = pose_at(robot, robot.random_configuration(rng), TOOL)

    # one pose: position within 1e-5 m and orientation within 1e-4 rad, 50 ms at most
    res = rk.solve_ik(robot, TOOL, target, position_tolerance=1e-5, orientation_tolerance=1e-4, timeout=0.05)
    print(f"pose:      success={res.success} in {res.iterations} iterations, {res.restarts} restarts")
    print(f"           errors {res.position_error:.1e} m, {res.orientation_error:.1e} rad")

    # a position only (the orientation is free), from a given start
    res_p = rk.solve_ik(robot, TOOL, target.translation, q0=res.q)
    print(f"position:  success={res_p.success}, error {res_p.position_error:.1e} m")

    # two frames at once: the hand's pose and the elbow's position (a mapping frame → target)
    q_true = robot.random_configuration(rng)
    both = {TOOL: pose_at(robot, q_true, TOOL), "panda_link4": pose_at(robot, q_true, "panda_link4").translation}
    res_2 = rk.solve_ik(robot, both, timeout=0.2)
    print(f"two frames: success={res_2.success}, per frame {res_2.frame_errors}")

    # a batch: 100 poses, problem i seeded with (seed, i), the same answers as 100 solve_ik calls
    targets = [pose_at(robot, robot.random_configuration(rng), TOOL) for _ in range(100)]
    batch = rk.solve_ik_batch(robot, TOOL, targets, timeout=0.05)
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    violations = int(np.sum(np.any((batch.q < lo) | (batch.q > hi), axis=1)))
    print(f"batch:     {100 * batch.success_rate:.0f} % solved, median {1e3 * np.median(batch.elapsed):.2f} ms")
    record = {
        "pose_success": res.success,
        "position_success": res_p.success,
        "two_frames_success": res_2.success,
        "batch_success_rate": batch.success_rate,
        "batch_max_position_error_m": float(np.max(batch.position_error[batch.success], initial=0.0)),
        "limit_violations": violations,
    }
    print(json.dumps(record))
    return 0 if res.success and res_p.success and res_2.success and violations == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())

"""Tutorial 3, add your robot from a URDF: load one with ``redundik.from_urdf``, look at what was read, use it.

The URDF is ``configs/arm4.urdf``, shipped with redundik (``redundik.shipped.example_urdf("arm4")`` finds it in a
checkout and in an installed wheel): a 4-joint arm (base yaw, shoulder and elbow pitch, wrist pitch) with a fixed
tool frame and joint limits. Its tool *position* is 3 task rows for 4 joints: one degree of redundancy. The script
loads it (in your project: your robot's URDF path), inspects what redundik read (joints, limits, frames), then moves
the tool to a point under ``hqp`` with the URDF's joint limits enforced.

Run: ``python examples/urdf_robot.py``; the last line checks the reached position and the limits.
"""

from __future__ import annotations

import numpy as np

import redundik as rk
from redundik.shipped import example_urdf


def main() -> int:
    robot = rk.from_urdf(example_urdf("arm4"))  # kinematics only; meshes, if any, are not loaded

    print(f"robot {robot.name!r}: nq = {robot.nq}, nv = {robot.nv}, joints {robot.joint_names}")
    for name, lo, hi, vmax in zip(
        robot.joint_names, robot.lower_limits, robot.upper_limits, robot.velocity_limits, strict=True
    ):
        print(f"  {name:9} [{lo:+.2f}, {hi:+.2f}] rad, |q̇| ≤ {vmax:.1f} rad/s")
    try:
        robot.frame_id("tcp")
    except rk.ModelError as exc:  # a wrong name lists the valid ones
        print(f"  frame 'tcp'? -> {exc}")

    q = np.array([0.0, 0.3, 0.6, 0.2])
    robot.update(q)
    print(f"tool at q = {q}: {np.round(robot.frame_position('tool'), 4)} m")

    # Move the tool to a point: a position task holding a target set at run time, the URDF limits in the QP.
    reach = rk.FrameTask("tool", axes="position", gain=20.0)
    stack = rk.TaskStack([reach], [rk.GradientSubtask(rk.JointCentering(), gain=-1.0)])
    stack.reset(robot)
    goal = np.array([0.35, 0.25, 0.55])
    reach.set_target(goal)
    resolver = rk.make_resolver("hqp", limits=rk.JointLimits())
    dt = 0.01
    for k in range(300):
        result = resolver.step(robot, stack, q, k * dt, dt)
        q = robot.integrate(q, result.dq, dt)
    robot.update(q)
    reached = float(np.linalg.norm(robot.frame_position("tool") - goal))
    violation = float(robot.limit_violation(q).max())
    print(f"after 3 s: q = {np.round(q, 3)}, tool {np.round(robot.frame_position('tool'), 4)} m")
    print(f"active limits on the last step: {result.info.get('active_limits')}, fallback: {result.fallback}")

    ok = reached < 1e-4 and violation == 0.0
    verdict = "OK" if ok else "FAIL"
    print(f"check: tool within {reached:.1e} m of the goal (< 1e-4), limit violation {violation:g}: {verdict}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

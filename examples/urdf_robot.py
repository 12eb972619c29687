"""Tutorial 3, add your robot from a URDF: write a small URDF, load it with ``redundik.from_urdf``, use it.

The URDF below is a 4-joint arm (base yaw, shoulder and elbow pitch, wrist pitch) with a fixed tool frame and
joint limits. Its tool *position* is 3 task rows for 4 joints: one degree of redundancy. The script writes the file
into a temporary folder (in your project it is your robot's URDF), loads it, inspects what redundik read (joints,
limits, frames), then moves the tool to a point under ``hqp`` with the URDF's joint limits enforced.

Run: ``python examples/urdf_robot.py``; the last line checks the reached position and the limits.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

import redundik as rk


def link(name: str, length: float) -> str:
    """A link with a (massless) inertial block; kinematics ignores the visuals, so none are given."""
    return (
        f'  <link name="{name}"><inertial><origin xyz="0 0 {length / 2}"/><mass value="1"/>'
        f'<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>\n'
    )


def joint(name: str, parent: str, child: str, z: float, axis: str, lower: float, upper: float) -> str:
    """A revolute joint ``z`` [m] above its parent's origin, limits [rad] and a 2 rad/s velocity limit."""
    return (
        f'  <joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0 0 {z}"/><axis xyz="{axis}"/>'
        f'<limit lower="{lower}" upper="{upper}" velocity="2.0" effort="10"/></joint>\n'
    )


ARM_URDF = (
    '<?xml version="1.0"?>\n<robot name="arm4">\n'
    + link("base", 0.1)
    + link("l1", 0.3)
    + link("l2", 0.4)
    + link("l3", 0.3)
    + link("l4", 0.1)
    + link("tool", 0.0)
    + joint("yaw", "base", "l1", 0.1, "0 0 1", -2.9, 2.9)
    + joint("shoulder", "l1", "l2", 0.3, "0 1 0", -1.6, 1.6)
    + joint("elbow", "l2", "l3", 0.4, "0 1 0", -2.4, 2.4)
    + joint("wrist", "l3", "l4", 0.3, "0 1 0", -0.5, 0.5)  # a tight range, to see a limit bind
    + '  <joint name="tool_mount" type="fixed"><parent link="l4"/><child link="tool"/>'
    '<origin xyz="0 0 0.1"/></joint>\n'
    "</robot>\n"
)


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "arm4.urdf"
        path.write_text(ARM_URDF)
        robot = rk.from_urdf(path)  # kinematics only; meshes, if any, are not loaded

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

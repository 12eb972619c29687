"""redundik inside a control loop: no YAML, no files, no plots — one resolver step per control tick.

A Panda (9 velocity coordinates: 7 arm joints and 2 fingers) keeps its gripper orientation while the tool point
draws a 10 cm circle at 1 kHz; the redundancy (9 − 6 = 3) is used to keep the joints near the middle of their
ranges (p = ½‖q − q_c‖², gain k < 0). In a real stack, ``q`` would come from the joint encoders and ``dq`` would
be sent to the velocity controller; here the loop integrates q ← q ⊕ q̇·dt itself.

Run: ``python examples/control_loop.py``
"""

from __future__ import annotations

import time

import numpy as np

import redundik as rk

DT = 1e-3  # control period [s]
TICKS = 2000  # 2 s
TOOL = "panda_hand_tcp"


def main() -> int:
    robot = rk.load_example_robot("panda")
    q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
    circle = rk.Circle(radius=0.10, omega=np.pi, plane=("y", "z"))  # one turn in 2 s, centred beside the start
    stack = rk.TaskStack(
        tasks=[rk.FrameTask(TOOL, circle, axes="pose", gain=50.0)],  # feed-forward + 50 /s feedback on the error
        subtasks=[rk.GradientSubtask(rk.JointCentering(), gain=-2.0)],  # k < 0: descend ½‖q − q_c‖² in the null space
    )
    resolver = rk.PinvResolver()

    robot.update(q)
    stack.reset(robot)  # anchors the circle at the current tool pose
    resolver.check(robot, stack)
    start = robot.frame_position(TOOL)
    step_times = []
    worst = 0.0
    print(f"{robot.name}: {robot.nv} joints, tool '{TOOL}' at {np.round(start, 4).tolist()} m")
    print("   t [s]   position error [mm]   orientation error [mrad]   p_centering")
    for tick in range(TICKS + 1):
        t = tick * DT
        t0 = time.perf_counter()
        result = resolver.step(robot, stack, q, t, DT)  # update kinematics at q, solve for q̇
        step_times.append(time.perf_counter() - t0)
        e = result.terms[0].error  # (x, y, z, rx, ry, rz) desired − actual, world frame
        worst = max(worst, float(np.linalg.norm(e[:3])))
        if tick % 400 == 0:
            p = stack.subtasks[0].potential.value(robot)
            print(f"{t:8.2f}   {1e3 * np.linalg.norm(e[:3]):19.4f}   {1e3 * np.linalg.norm(e[3:]):24.4f}   {p:11.4f}")
        q = robot.integrate(q, result.dq, DT)

    robot.update(q)
    violation = float(robot.limit_violation(q).max())
    med = 1e6 * float(np.median(step_times))
    print(f"max position error {1e3 * worst:.4f} mm, joint-limit violation {violation:.2e}, step {med:.0f} µs (median)")
    ok = worst < 1e-3 and violation == 0.0
    print("OK" if ok else "FAILED: tracking error above 1 mm or joint limits violated")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

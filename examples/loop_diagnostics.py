"""Tutorial 4, use it in your control loop: targets set at run time, joint limits, and what a step reports.

A planar 4R arm (unit links, D-H table with joint limits; joint 3 may only bend ±0.6 rad) holds its tip on a target
that the "application" moves every 0.5 s (``FrameTask.set_target``). The minimum-norm motion to some waypoints bends
joint 3 beyond its range: ``pinv`` (no limits) goes through the limit; ``wqp`` and ``hqp`` keep every joint inside,
reach the waypoint with the other joints, and report the binding limit in ``result.info["active_limits"]``. Each
tick reads ``StepResult``: q̇, the main-task error, σ_min, damping, fallback, build and solve times.

Run: ``python examples/loop_diagnostics.py``; the last line is the check.
"""

from __future__ import annotations

import numpy as np

import redundik as rk

DT = 0.005  # control period [s]
HOLD = 100  # ticks per waypoint (0.5 s)
WAYPOINTS = [(2.5, 1.5), (1.0, 2.8), (3.0, -0.8), (0.4, 1.2), (2.5, 1.5)]  # tip targets [m], all reachable


def make_robot() -> rk.RobotModel:
    rows = [rk.DHRow(str(i), a=1.0, lower=-2.8, upper=2.8, velocity=3.0) for i in range(1, 5)]
    rows[2] = rk.DHRow("3", a=1.0, lower=-0.6, upper=0.6, velocity=3.0)
    return rk.from_dh(rows, name="planar4r_limited")


def run(resolver_name: str, verbose: bool) -> dict[str, float]:
    robot = make_robot()
    q = np.array([0.2, 0.4, 0.3, 0.2])
    robot.update(q)
    tip = rk.FrameTask("4", axes="planar", gain=40.0)  # no trajectory: hold a target (set below)
    posture = rk.PostureTask(gain=1.0)  # a regulariser in the null space: take up the redundancy gently
    stack = rk.TaskStack([tip, posture])
    stack.reset(robot)
    # pinv runs without any limit here, not even its default joint-speed cap (the arm's 3 rad/s, which would slow
    # it down on the long jumps: examples/singularity.py shows the cap)
    options = {"max_joint_speed": None} if resolver_name == "pinv" else {}
    resolver = rk.make_resolver(resolver_name, **options)
    worst_violation, fallbacks, errors = 0.0, 0, []
    for k in range(HOLD * len(WAYPOINTS)):
        if k % HOLD == 0:  # the application moves the target: a jump, at run time
            x, y = WAYPOINTS[k // HOLD]
            tip.set_target([x, y, 0.0])
        result = resolver.step(robot, stack, q, k * DT, DT)
        q = robot.integrate(q, result.dq, DT)  # or: send result.dq to the robot's velocity interface
        worst_violation = max(worst_violation, float(robot.limit_violation(q).max()))
        fallbacks += result.fallback is not None
        if k % HOLD == HOLD - 1:  # end of a waypoint: what did the last step report?
            errors.append(result.task_error)
            if verbose:
                limits = result.info.get("active_limits", "n/a (no limits)")
                print(
                    f"  waypoint {k // HOLD}: tip error {result.task_error:8.2e} m  σ_min {result.sigma_min:5.3f}  "
                    f"damped {result.damped!s:5}  active limits {limits}  fallback {result.fallback}  "
                    f"build+solve {1e6 * (result.build_time + result.solve_time):5.0f} µs"
                )
    return {"violation": worst_violation, "fallbacks": fallbacks, "max_error": max(errors)}


def main() -> int:
    results = {}
    for name in ("pinv", "wqp", "hqp"):
        print(f"{name}:")
        results[name] = run(name, verbose=True)
        worst, fallbacks = results[name]["violation"], results[name]["fallbacks"]
        print(f"  worst joint-limit violation {worst:.3f} rad, fallback steps {fallbacks}")
    qp_ok = all(results[n]["violation"] == 0.0 and results[n]["fallbacks"] == 0 for n in ("wqp", "hqp"))
    tracked = all(r["max_error"] < 1e-4 for r in results.values())
    shown = results["pinv"]["violation"] > 0.0  # without limits, joint 3 leaves its range
    ok = qp_ok and tracked and shown
    verdict = "OK" if ok else "FAIL"
    print(f"check: QP resolvers inside the limits, every waypoint within 1e-4 m, pinv over the limit: {verdict}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

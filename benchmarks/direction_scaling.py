"""Direction-preserving scaling (issue 33 item 1): α and the hand's direction on random Panda states, against a
reference LP, with the unscaled modes' swerve for contrast.

States (seeded): configurations drawn within the joint limits (30 % with one joint 1e-4 of its range from a limit),
a tool target 0.1–0.6 m away in a random orientation offset, gain 20 /s, dt = 10 ms, a posture task below: V is far
beyond what the velocity limits allow in one step, so the limits bind. For each state and each resolver (``wqp``,
``hqp``) the step is taken with ``scaling="direction"`` and without:

* α against the reference: max α over the full (q̇, α) with J q̇ = αV and the step's joint-limit box as bounds
  (scipy's HiGHS, no null-space reduction or margins) — the largest |α − α_ref|;
* the angle between J q̇ and V [rad] whenever α > 0 (max), and for the unscaled step (median and max over the
  states where a limit binds, i.e. the unscaled step solved a QP) [deg];
* the step time (median, p99) [ms] of both modes.

Run: ``python benchmarks/direction_scaling.py [--n 1000] [--seed 0] [--reach 0.1,0.6] [--json FILE]``; one line per
resolver. ``--reach 0.005,0.03`` gives nearer targets, where the limits bind on fewer states and bend V less.
"""

from __future__ import annotations

import os

# timed after untimed warm-up steps: the kernels compile in the caller's thread, not in redundik's background one
os.environ.setdefault("REDUNDIK_COLD_START", "wait")

import argparse
import json
import math
import time

import numpy as np
import pinocchio as pin
from scipy.optimize import linprog

import redundik as rk

TOOL = "panda_hand_tcp"
DT = 0.01
GAIN = 20.0


def reference_alpha(J: np.ndarray, V: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> float:
    """max α over (q̇, α): J q̇ = αV, lb ≤ q̇ ≤ ub, 0 ≤ α ≤ 1; NaN when infeasible."""
    n = J.shape[1]
    cost = np.zeros(n + 1)
    cost[-1] = -1.0
    bounds = [(a if math.isfinite(a) else None, b if math.isfinite(b) else None) for a, b in zip(lb, ub, strict=True)]
    bounds.append((0.0, 1.0))
    opts = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}
    res = linprog(
        cost, A_eq=np.hstack([J, -V[:, None]]), b_eq=np.zeros(J.shape[0]), bounds=bounds, method="highs", options=opts
    )
    return float(res.x[-1]) if res.status == 0 else math.nan


def angle(a: np.ndarray, b: np.ndarray) -> float:
    """The angle between two vectors [rad] (0 when either is zero)."""
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    if na == 0.0 or nb == 0.0:
        return 0.0
    return math.acos(min(1.0, max(-1.0, float(a @ b) / (na * nb))))


def states(
    robot: rk.RobotModel, n: int, seed: int, reach: tuple[float, float] = (0.1, 0.6)
) -> list[tuple[np.ndarray, pin.SE3]]:
    """n (q, tool target) pairs (module docstring); ``reach``: the range of the target's distance scale [m]."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.lower_limits, robot.upper_limits
    out = []
    for _ in range(n):
        u = rng.uniform(0.02, 0.98, size=robot.nq)
        if rng.uniform() < 0.3:
            u[rng.integers(0, 7)] = rng.choice([1e-4, 1.0 - 1e-4])
        q = lo + (hi - lo) * u
        robot.update(q)
        pose = robot.frame_pose(TOOL).copy()
        rot = pin.exp3(rng.normal(size=3) * 0.3)
        offset = rng.normal(size=3) * rng.uniform(*reach)
        out.append((q, pin.SE3(rot @ pose.rotation, pose.translation + offset)))
    return out


def run(name: str, robot: rk.RobotModel, cases: list[tuple[np.ndarray, pin.SE3]]) -> dict[str, object]:
    """The figures of one resolver over the cases (module docstring)."""
    tool = rk.FrameTask(TOOL, gain=GAIN)
    stack = rk.TaskStack([tool, rk.PostureTask(gain=1.0)])
    scaled, plain = rk.make_resolver(name, scaling="direction"), rk.make_resolver(name)
    d_alpha, max_angle, swerve, alphas, stuck, unreachable = 0.0, 0.0, [], [], 0, 0
    times: dict[str, list[float]] = {"direction": [], "off": []}
    for q, target in cases:
        tool.set_target(target)
        for key, resolver in (("off", plain), ("direction", scaled)):
            resolver.reset()
            t0 = time.perf_counter()
            res = resolver.step(robot, stack, q, 0.0, DT)
            times[key].append(time.perf_counter() - t0)
            term = res.terms[0]
            if key == "off":
                if res.info["qp"]:
                    swerve.append(angle(term.J @ res.dq, term.v))
                continue
            box = resolver.limits.box(robot, q, DT)  # type: ignore[attr-defined]
            ref = reference_alpha(term.J, term.v, box.lb, box.ub)
            if math.isnan(ref):
                unreachable += 1
                continue
            d_alpha = max(d_alpha, abs(res.scale - ref))
            alphas.append(res.scale)
            stuck += res.stuck
            if res.scale > 0.0:
                max_angle = max(max_angle, angle(term.J @ res.dq, term.v))
    ms = {k: np.asarray(v) * 1e3 for k, v in times.items()}
    return {
        "resolver": name,
        "states": len(cases),
        "binding": len(swerve),
        "max_abs_alpha_minus_reference": d_alpha,
        "max_angle_rad": max_angle,
        "median_alpha": float(np.median(alphas)) if alphas else math.nan,
        "stuck": stuck,
        "unreachable": unreachable,
        "unscaled_median_swerve_deg": math.degrees(float(np.median(swerve))) if swerve else 0.0,
        "unscaled_max_swerve_deg": math.degrees(float(np.max(swerve))) if swerve else 0.0,
        "step_ms_direction_median_p99": [float(np.median(ms["direction"])), float(np.percentile(ms["direction"], 99))],
        "step_ms_off_median_p99": [float(np.median(ms["off"])), float(np.percentile(ms["off"], 99))],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1000, help="random states (default 1000)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--reach", default="0.1,0.6", help="range of the target offsets' scale [m] (default 0.1,0.6)")
    parser.add_argument("--json", default=None, help="write the records to this file")
    args = parser.parse_args(argv)
    robot = rk.load_example_robot("panda")
    lo, hi = (float(x) for x in args.reach.split(","))
    cases = states(robot, args.n, args.seed, (lo, hi))
    records = []
    for name in ("wqp", "hqp"):
        rec = run(name, robot, cases)
        records.append(rec)
        print(
            f"{name}: {rec['states']} states ({rec['binding']} binding unscaled): max |α − α_ref| = "
            f"{rec['max_abs_alpha_minus_reference']:.2e}, max angle(J q̇, V) = {rec['max_angle_rad']:.2e} rad "
            f"(α > 0), median α = {rec['median_alpha']:.3f}, stuck {rec['stuck']}, unreachable {rec['unreachable']}; "
            f"unscaled swerve median {rec['unscaled_median_swerve_deg']:.1f}° "
            f"max {rec['unscaled_max_swerve_deg']:.1f}°; "
            f"step [ms] direction {rec['step_ms_direction_median_p99'][0]:.2f} (p99 "
            f"{rec['step_ms_direction_median_p99'][1]:.2f}), off {rec['step_ms_off_median_p99'][0]:.2f}"
        )
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(records, fh, indent=1)
    ok = all(
        r["max_abs_alpha_minus_reference"] <= 1e-6 and r["max_angle_rad"] <= 1e-6  # type: ignore[operator]
        for r in records
    )
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

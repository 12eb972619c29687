"""The cost of collision constraints in a ``wqp`` step: the Panda, hand + posture + joint limits, without and with
the collision damper over 20 candidate pairs, interleaved step by step at the same configurations.

    python benchmarks/collision_cost.py [--steps 3000] [--pairs 20] [--split]

Prints the medians and 90th percentiles [µs] of both steps, their ratios (guarded / plain) and the median of the
per-step differences (guarded − plain [µs]: what the collision constraint adds, which a faster plain step leaves
unchanged while it raises the ratio). ``--split`` interleaves a third step whose bound subtask is a barrier with
constant rows (the damper's rows at the first configuration, no collision computation), which splits the added time
into the resolver's share (bound rows in the QP, the safety guard) and the collision computation's. The machine is
shared: only numbers from one interleaved run mean anything (``../shared/environment-notes.md``).
"""

from __future__ import annotations

import os

# timed after untimed warm-up steps: the kernels compile in the caller's thread, not in redundik's background one
os.environ.setdefault("REDUNDIK_COLD_START", "wait")

import argparse
import math
import time

import numpy as np

from redundik.collision import CollisionAvoidance, CollisionWorld
from redundik.kinematics import example_robot_data_dir
from redundik.kinematics.model import RobotModel
from redundik.resolvers import make_resolver
from redundik.simulation.collision_stress import PANDA_Q0, panda_scene
from redundik.tasks import BoundSubtask, FrameTask, PostureTask, TaskStack
from redundik.tasks.base import Barrier, BarrierTerm


class _ConstantRows(Barrier):
    """A safety barrier returning fixed rows (the resolver's share of a collision step, ``--split``)."""

    critical = True

    def __init__(self, term: BarrierTerm) -> None:
        self.name, self.term = "constant", term

    def evaluate(self, robot: RobotModel) -> BarrierTerm:
        return self.term


def measure(steps: int = 3000, pairs: int = 20, seed: int = 0, split: bool = False) -> dict[str, float]:
    """Per-step times [µs] (median, p90) without and with the damper, their ratios, the median added time [µs]
    (guarded − plain, per step) and how often a QP ran; with ``split`` also the median added time of the
    constant-rows step (module docstring)."""
    robot, full, _ = panda_scene()
    urdf = example_robot_data_dir() / "panda_description/urdf/panda.urdf"
    links = ["panda_link3", "panda_link4", "panda_link5", "panda_link6", "panda_link7", "panda_hand"]
    world = CollisionWorld.from_urdf(robot, urdf, full.obstacles[:3], obstacle_links=links, self_collision=True)
    world._set_pairs(world.pairs[:pairs])
    avoid = CollisionAvoidance(world, influence=0.1, safety=0.01, xi=0.3)
    hand = FrameTask("panda_hand", gain=5.0)
    hand.set_target(np.array([0.4, 0.2, 0.35]))
    plain = TaskStack([hand, PostureTask(gain=1.0)])
    guarded = TaskStack([hand, PostureTask(gain=1.0)], [BoundSubtask(avoid)])
    r1, r2, r3 = make_resolver("wqp"), make_resolver("wqp"), make_resolver("wqp")
    rng = np.random.default_rng(seed)
    qs = [PANDA_Q0 + rng.normal(0, 0.05, 9) for _ in range(steps)]
    robot.update(qs[0])
    constant = TaskStack([hand, PostureTask(gain=1.0)], [BoundSubtask(_ConstantRows(avoid.evaluate(robot)))])
    for q in qs[:50]:  # warm-up (JIT caches, allocations)
        r1.step(robot, plain, q, 0.0, 0.01)
        r2.step(robot, guarded, q, 0.0, 0.01)
        r3.step(robot, constant, q, 0.0, 0.01)
    t1, t2, t3, qp = np.empty(steps), np.empty(steps), np.empty(steps), 0
    cases = [(r1, plain, t1), (r2, guarded, t2)] + ([(r3, constant, t3)] if split else [])
    for k, q in enumerate(qs):
        order = cases[k % len(cases) :] + cases[: k % len(cases)]
        for res, stack, out in order:
            a = time.perf_counter()
            step = res.step(robot, stack, q, 0.0, 0.01)
            out[k] = time.perf_counter() - a
            if stack is guarded:
                qp += int(step.info["qp"]) > 0  # type: ignore[call-overload]
    m1, m2 = float(np.median(t1)), float(np.median(t2))
    p1, p2 = float(np.percentile(t1, 90)), float(np.percentile(t2, 90))
    return {
        "pairs": float(world.n_pairs),
        "plain_median_us": m1 * 1e6,
        "guarded_median_us": m2 * 1e6,
        "plain_p90_us": p1 * 1e6,
        "guarded_p90_us": p2 * 1e6,
        "median_ratio": m2 / m1,
        "p90_ratio": p2 / p1,
        "median_of_ratios": float(np.median(t2 / t1)),
        "added_median_us": float(np.median(t2 - t1)) * 1e6,
        "constant_added_median_us": float(np.median(t3 - t1)) * 1e6 if split else math.nan,
        "qp_fraction": qp / steps,
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--pairs", type=int, default=20)
    ap.add_argument("--split", action="store_true", help="also time a step with constant bound rows")
    args = ap.parse_args()
    out = measure(args.steps, args.pairs, split=args.split)
    print(
        f"wqp step, {out['pairs']:.0f} candidate pairs: plain {out['plain_median_us']:.0f} µs (p90 "
        f"{out['plain_p90_us']:.0f}), with collision {out['guarded_median_us']:.0f} µs (p90 "
        f"{out['guarded_p90_us']:.0f}); ratio median {out['median_ratio']:.2f}, p90 {out['p90_ratio']:.2f}, "
        f"median of per-step ratios {out['median_of_ratios']:.2f}; added {out['added_median_us']:.0f} µs (median "
        f"of guarded − plain); a QP was solved on {out['qp_fraction']:.0%} of the guarded steps"
    )
    if args.split:
        print(
            f"of the added {out['added_median_us']:.0f} µs: {out['constant_added_median_us']:.0f} µs with constant "
            "bound rows (the resolver's share), the rest the collision computation"
        )


if __name__ == "__main__":
    main()

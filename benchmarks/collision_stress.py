"""Collision avoidance under stress, and the cost of the collision rows in a ``wqp`` step.

    python benchmarks/collision_stress.py [--episodes 25] [--steps 100]

1. Random targets through the obstacles and across the body (redundik.simulation.collision_stress), Panda and TALOS,
   wqp and hqp, every installed backend: penetration counts (samples with d < 0) and the smallest distance.
2. A Panda ``wqp`` step (hand + posture + joint limits) without and with a collision damper over 20 candidate
   pairs, interleaved, medians and their ratio.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from redundik.collision import CollisionAvoidance, CollisionWorld
from redundik.kinematics import example_robot_data_dir
from redundik.resolvers import make_resolver
from redundik.simulation.collision_stress import PANDA_Q0, panda_scene, run_stress
from redundik.tasks import BoundSubtask, FrameTask, PostureTask, TaskStack


def step_ratio(n: int = 2000) -> tuple[float, float, int]:
    """Median wqp step [µs] without / with a collision damper over 20 candidate pairs, and the pair count."""
    robot, full, _ = panda_scene()
    urdf = example_robot_data_dir() / "panda_description/urdf/panda.urdf"
    links = ["panda_link3", "panda_link4", "panda_link5", "panda_link6", "panda_link7", "panda_hand"]
    world = CollisionWorld.from_urdf(robot, urdf, full.obstacles[:3], obstacle_links=links, self_collision=True)
    keep = [(i, j) for (i, j) in world.pairs][:20]
    world._set_pairs(keep)
    avoid = CollisionAvoidance(world, influence=0.1, safety=0.01, xi=0.3)
    hand = FrameTask("panda_hand", gain=5.0)
    hand.set_target(np.array([0.4, 0.2, 0.35]))
    plain = TaskStack([hand, PostureTask(gain=1.0)])
    guarded = TaskStack([hand, PostureTask(gain=1.0)], [BoundSubtask(avoid)])
    r1, r2 = make_resolver("wqp"), make_resolver("wqp")
    rng = np.random.default_rng(0)
    t1, t2 = [], []
    for _ in range(n):
        q = PANDA_Q0 + rng.normal(0, 0.05, 9)
        a = time.perf_counter()
        r1.step(robot, plain, q, 0.0, 0.01)
        b = time.perf_counter()
        r2.step(robot, guarded, q, 0.0, 0.01)
        c = time.perf_counter()
        t1.append(b - a)
        t2.append(c - b)
    return float(np.median(t1) * 1e6), float(np.median(t2) * 1e6), world.n_pairs


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--episodes", type=int, default=25)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--scene", choices=["panda", "talos"], action="append", help="default: both")
    ap.add_argument("--backend", action="append", help="default: every installed one")
    ap.add_argument("--resolver", choices=["wqp", "hqp"], action="append", help="default: both")
    ap.add_argument("--no-ratio", action="store_true", help="skip the step-time ratio")
    args = ap.parse_args()
    backends = []
    for b in args.backend or ("daqp", "quadprog", "proxsuite", "osqp"):
        try:
            make_resolver("wqp", backend=b)
            backends.append(b)
        except Exception:  # not installed
            pass
    total = 0
    for scene in args.scene or ("panda", "talos"):
        for resolver in args.resolver or ("wqp", "hqp"):
            for backend in backends:
                t = time.time()
                out = run_stress(scene, resolver, backend, episodes=args.episodes, steps=args.steps, seed=7)
                total += out.steps
                print(
                    f"{scene:6s} {resolver} {backend:9s} steps {out.steps:6d} penetrations {out.penetrations:5d} "
                    f"min d {out.min_distance * 1e3:7.2f} mm ({out.closest}) fallbacks {out.fallbacks} "
                    f"(penetrating after one: {out.fallback_penetrations}) "
                    f"[{time.time() - t:.1f} s]",
                    flush=True,
                )
    print(f"total steps {total}")
    if args.no_ratio:
        return
    a, b, pairs = step_ratio()
    print(f"wqp step: {a:.0f} µs without, {b:.0f} µs with {pairs} candidate pairs: ratio {b / a:.2f}")


if __name__ == "__main__":
    main()

"""Time per control step of the hyper-redundant snake as n grows (section 5.2): n = 10, 20, 40, 80.

Each step: kinematics update + tip pose task (6 rows) + joint centering + three link clearances (pinv: gradients
in the null space, eq. 5.15; hqp: clearances as inequalities at level 1, centering at level 2). The cases are
interleaved round-robin (the machine is shared and noisy) and medians are reported.

Run: ``/work/venv/bin/python benchmarks/snake_scaling.py [--steps 200] [--rounds 3]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from redundik.kinematics import snake
from redundik.resolvers import make_resolver
from redundik.simulation import simulate
from redundik.tasks import BoundSubtask, Circle, Clearance, FrameTask, GradientSubtask, JointCentering, TaskStack


def build(n: int, resolver: str):
    """The snake, its task stack, a resolver and q0 (a gentle curl) for n joints."""
    robot = snake(n, link=4.0 / n)
    q0 = np.array([np.deg2rad(15 * np.sin(0.35 * i)) if i % 2 == 0 else np.deg2rad(10) for i in range(n)])
    robot.update(q0)
    frames = [str(n // 4), str(n // 2), str(3 * n // 4)]
    obstacles = [robot.frame_position(f) + np.array([0.0, 0.12, 0.0]) for f in frames]
    clear = [Clearance(f, c, 0.06, name=f"clear{f}") for f, c in zip(frames, obstacles, strict=True)]
    if resolver == "pinv":
        subs = [GradientSubtask(JointCentering(), gain=-1.0)] + [GradientSubtask(c, gain=0.3) for c in clear]
    else:
        subs = [BoundSubtask(c, lower=0.03, rate=2.0, priority=1) for c in clear]
        subs.append(GradientSubtask(JointCentering(), gain=-1.0))
    task = FrameTask(str(n), Circle(0.15, 1.2566, ("x", "y")), axes="pose", gain=2.0, name="tip")
    return robot, TaskStack([task], subs), make_resolver(resolver), q0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 40, 80])
    parser.add_argument("--resolvers", nargs="+", default=["pinv", "hqp"])
    args = parser.parse_args()
    samples: dict[tuple[int, str], list[float]] = {}
    for _ in range(args.rounds):
        for n in args.sizes:
            for res in args.resolvers:
                robot, stack, resolver, q0 = build(n, res)
                t0 = time.perf_counter()
                log = simulate(robot, stack, resolver, q0, dt=0.02, steps=args.steps)
                samples.setdefault((n, res), []).extend(log.step_time.tolist())
                _ = time.perf_counter() - t0
    print(f"{'n':>4} {'r':>4} " + " ".join(f"{r + ' [us]':>14}" for r in args.resolvers))
    for n in args.sizes:
        row = [np.median(samples[(n, r)]) * 1e6 for r in args.resolvers]
        print(f"{n:>4} {n - 6:>4} " + " ".join(f"{v:>14.0f}" for v in row))


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Hot-path timing of redundik's resolvers against mink and pink (issue 11 item 1), interleaved, as ratios.

Usage::

    python benchmarks/hot_path.py                       # Panda circle and Talos, pinv/wqp/hqp vs mink/pink (daqp)
    python benchmarks/hot_path.py --robots panda_circle --chunks 20 --chunk 100
    python benchmarks/hot_path.py --profile             # plus the per-stage profile of each redundik case
    python benchmarks/hot_path.py --snake 10 20 40 80 160   # the snake's growth exponent and p90/median (wqp, hqp)

Every case is one runner of the benchmark harness (same robots, task sets and timed region as
``benchmarks/compare_resolvers.py``: the kinematics update, the references, building and solving). The cases advance
by ``--chunk`` steps in turn, the order rotating each round, so that the machine's drift hits them alike; the
medians and 90th percentiles come from one run and each is given as a ratio to the faster peer's median. On a
shared, loaded machine only the ratios carry over between runs.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np


def _harness() -> tuple[Any, Any, Any, Any]:
    """(SCENARIOS, RedundikRunner, MinkRunner, PinkRunner) from wherever the benchmark harness lives."""
    try:
        from redundik.peers.bench.runners import MinkRunner, PinkRunner, RedundikRunner
        from redundik.peers.bench.scenarios import SCENARIOS
    except ImportError:  # the harness moved out of the package: the checkout's benchmarks/bench
        sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1]))
        from benchmarks.bench.peer_runners import MinkRunner, PinkRunner  # type: ignore[no-redef]
        from benchmarks.bench.runners import RedundikRunner  # type: ignore[no-redef]
        from benchmarks.bench.scenarios import SCENARIOS  # type: ignore[no-redef]
    return SCENARIOS, RedundikRunner, MinkRunner, PinkRunner


def run(robots: list[str], methods: list[str], chunks: int, chunk: int, warmup: int, profile: int) -> int:
    """Time the cases, print one line per case (median, p90 [µs], ratios to the faster peer); 0 on success."""
    scenarios, redundik_runner, mink_runner, pink_runner = _harness()
    for key in robots:
        sc = scenarios[key]()
        runners: dict[str, Any] = {}
        for m in methods:
            if m == "mink":
                runners[m] = mink_runner(sc, "daqp")
            elif m == "pink":
                runners[m] = pink_runner(sc, "daqp")
            else:
                runners[m] = redundik_runner(sc, m, None, {})
        for r in runners.values():
            r.run(warmup)
            r.record.step_ns.clear()
            r.record.qp_steps = 0
        order = list(runners.values())
        for k in range(chunks):
            for r in order[k % len(order) :] + order[: k % len(order)]:
                r.run(chunk)
        med = {m: float(np.median(r.record.step_ns)) / 1e3 for m, r in runners.items()}
        p90 = {m: float(np.percentile(r.record.step_ns, 90)) / 1e3 for m, r in runners.items()}
        peers = [med[m] for m in ("mink", "pink") if m in med]
        peer = min(peers) if peers else float("nan")
        print(f"{key}: {chunks * chunk} steps per case, faster peer median {peer:.1f} µs")
        for m, r in runners.items():
            qp = r.record.qp_steps
            print(
                f"  {m:5s} median {med[m]:7.1f} µs  p90 {p90[m]:7.1f} µs  median/peer {med[m] / peer:5.3f}  "
                f"p90/peer {p90[m] / peer:5.3f}  p90/median {p90[m] / med[m]:4.2f}  qp steps {qp}"
            )
        if profile:
            for m, r in runners.items():
                if hasattr(r, "profile"):
                    stages = r.profile(profile)
                    print(f"  profile {m}: " + ", ".join(f"{k} {v:.1f}" for k, v in stages.items()) + " µs")
    return 0


def snake(sizes: list[int], resolvers: list[str], steps: int, rounds: int) -> int:
    """Median and p90 per step of the snake (the benchmark's ``snakeN`` scenarios, which replaced
    ``benchmarks/snake_scaling.py``) as n grows, interleaved, and the growth exponent of the median (least-squares
    slope of log t against log n)."""
    import time

    from redundik.resolvers import make_resolver

    scenarios = _harness()[0]

    def build(n: int, r: str) -> tuple[Any, Any, Any, np.ndarray]:
        sc = scenarios[f"snake{n}"]()
        robot = sc.robot()
        return robot, sc.stack(r, robot), make_resolver(r), sc.q0.copy()

    cases = {(n, r): build(n, r) for n in sizes for r in resolvers}
    samples: dict[tuple[int, str], list[float]] = {key: [] for key in cases}
    qs = {key: case[3].copy() for key, case in cases.items()}
    dt = 0.01  # the scenarios' step (their frame task's gain is 1/dt)
    for rnd in range(rounds + 1):  # round 0 warms up (JIT, caches) and is not kept
        for key, (robot, stack, resolver, q0) in cases.items():
            if rnd == 0:
                robot.update(q0)
                stack.reset(robot)
            q = qs[key]
            for k in range(steps):
                t = (rnd * steps + k) * dt
                t0 = time.perf_counter()
                res = resolver.step(robot, stack, q, t, dt)
                t1 = time.perf_counter()
                q = robot.integrate(q, res.dq, dt)
                if rnd:
                    samples[key].append(t1 - t0)
            qs[key] = q
    for r in resolvers:
        med = np.array([np.median(samples[(n, r)]) for n in sizes])
        p90 = np.array([np.percentile(samples[(n, r)], 90) for n in sizes])
        slope = float(np.polyfit(np.log(sizes), np.log(med), 1)[0])
        rows = ", ".join(
            f"n={n}: {m * 1e6:.0f} µs (p90/median {p / m:.2f})" for n, m, p in zip(sizes, med, p90, strict=True)
        )
        print(f"snake {r}: growth exponent {slope:.2f}; {rows}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments and run."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--robots", nargs="+", default=["panda_circle", "talos"], help="scenario keys (panda_circle talos ...)"
    )
    parser.add_argument("--methods", nargs="+", default=["pinv", "wqp", "hqp", "mink", "pink"])
    parser.add_argument("--chunks", type=int, default=20, help="round-robin turns")
    parser.add_argument("--chunk", type=int, default=50, help="steps per case per turn")
    parser.add_argument("--warmup", type=int, default=100, help="untimed steps per case first (JIT, caches)")
    parser.add_argument("--profile", type=int, nargs="?", const=500, default=0, help="per-stage profile steps")
    parser.add_argument("--snake", type=int, nargs="+", default=None, help="snake sizes n (instead of the robots)")
    args = parser.parse_args(argv)
    if args.snake:
        return snake(args.snake, [m for m in args.methods if m in ("pinv", "wqp", "hqp")], args.chunk, args.chunks)
    return run(args.robots, args.methods, args.chunks, args.chunk, args.warmup, args.profile)


if __name__ == "__main__":
    sys.exit(main())

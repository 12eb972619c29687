#!/usr/bin/env python3
"""Count the alarms of a long stress run: ``result.fallback`` against ``result.relaxed`` (issue 33, item 6).

Usage::

    python benchmarks/alarm_stress.py                      # 2 000 steps per (resolver, backend) pair
    python benchmarks/alarm_stress.py --steps 14000        # ≥ 1e5 steps over wqp/hqp × 4 backends
    python benchmarks/alarm_stress.py --steps 500 --json a.json --backends daqp quadprog

Every (resolver, backend) pair replays the same episodes, half of each kind:

* ``chain``: the episodes of ``benchmarks/stress_resolvers.py`` (a random 7-joint D-H chain or the 3R arm, a start
  inside, at or outside the position limits, rate limits on half of them, random gradient, target and bound
  subtasks);
* ``panda``: the Panda with a tip position task on level 0, a random joint bound on each of levels 1 and 2 (kept
  inside or outside a random radius at a random rate: often beyond what the limits or the level above allow), a
  posture on level 3 in half of them, a random target jump every 10 steps, an acceleration limit.

Counted per pair, with the backend's ``solve`` watched (a ``SolverError`` on a QP whose constraints admit a point —
``redundik.resolvers.qp.problem.infeasible`` says False — is a backend failure; a refused infeasible QP is not):

* ``fallback``: steps with ``result.fallback`` set; ``unexplained``: those of them in which the backend never
  failed (the target: 0);
* ``relaxed``: steps with ``result.relaxed`` non-empty; ``retried``: those counting a backend retry
  (``"… (backend retried)"``); ``failures``: steps in which the backend failed at least once;
* ``silent``: steps with neither field set whose bound rows C q̇ ≤ d are violated beyond 1e-6·max(1, ‖d‖∞) — an
  unreported relaxation (the target: 0).

Prints one line per pair and the totals; ``--json`` writes them.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import logging
import sys
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

import redundik as rk
from redundik.errors import SolverError
from redundik.resolvers.qp import QPProblem, QPSolution, available_backends
from redundik.resolvers.qp.problem import infeasible

logging.getLogger("redundik").setLevel(logging.ERROR)  # (the one-time "runs interpreted" notes)

TIP = "panda_hand_tcp"
DT = 0.01


def _stress_resolvers() -> Any:
    """``benchmarks/stress_resolvers.py`` (its episodes), loaded from this file's directory."""
    spec = importlib.util.spec_from_file_location("stress_resolvers", Path(__file__).with_name("stress_resolvers.py"))
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("stress_resolvers", module)
    spec.loader.exec_module(module)
    return module


@dataclass
class Counts:
    """What one (resolver, backend) pair reported."""

    resolver: str
    backend: str
    steps: int = 0
    fallback: int = 0
    unexplained: int = 0
    relaxed: int = 0
    retried: int = 0
    failures: int = 0
    silent: int = 0
    wall_s: float = 0.0


@dataclass
class Episode:
    """One episode: robot, start, stack, levels and limits, and a random source for its target jumps."""

    kind: str
    robot: rk.RobotModel
    q0: np.ndarray
    stack: rk.TaskStack
    levels: dict[str, int]
    limits: dict[str, Any]
    dt: float
    seed: int


def panda_episode(robot: rk.RobotModel, seed: int) -> Episode:
    """A Panda episode (module docstring), every random choice from ``seed``."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.lower_limits, robot.upper_limits
    arm = robot.joint_names[:7]
    q0 = rng.uniform(lo, hi)
    task = rk.FrameTask(TIP, axes="position", gain=float(rng.uniform(1.0, 50.0)), name="tip")
    subs: list[rk.Subtask] = []
    levels: dict[str, int] = {}
    for k in (1, 2):
        j = str(rng.choice(arm))
        i = robot.joint_names.index(j)
        centre, radius = float(rng.uniform(lo[i], hi[i])), float(rng.uniform(0.05, 0.5) * (hi[i] - lo[i]))
        key = "lower" if rng.random() < 0.5 else "upper"
        pot = rk.JointValue(j, centre)
        subs.append(rk.BoundSubtask(pot, **{key: radius**2}, rate=float(rng.uniform(0.0, 20.0)), name=f"b{k}"))
        levels[f"b{k}"] = k
    tasks: list[rk.Task] = [task]
    if rng.random() < 0.5:
        tasks.append(rk.PostureTask(gain=1.0, name="posture"))
    return Episode("panda", robot, q0, rk.TaskStack(tasks, subs), levels, {"acceleration": 20.0}, DT, seed)


def chain_episode(stress: Any, seed: int, steps: int) -> Episode:
    """An episode of ``stress_resolvers.py`` (its robot, start, stack and limits)."""
    ep = stress.make_episode(seed, steps)
    return Episode("chain", ep.robot, ep.q0, ep.stack(), {}, dict(ep.limit_options), ep.dt, seed)


def _bound_violation(robot: rk.RobotModel, stack: rk.TaskStack, dq: np.ndarray, dt: float) -> float:
    """How far q̇ violates the bound rows C q̇ ≤ d, relative to max(1, ‖d‖∞)."""
    worst = 0.0
    for sub in stack.bound_subtasks:
        C, d, _ = sub.rows(robot, dt)
        if C.shape[0]:
            worst = max(worst, float(np.max(C @ dq - d)) / max(1.0, float(np.max(np.abs(d)))))
    return worst


def run_pair(resolver: str, backend: str, episodes: list[Episode], steps: int) -> Counts:
    """Replay ``episodes`` (``steps`` each) with one (resolver, backend)."""
    out = Counts(resolver, backend)
    t0 = time.perf_counter()
    for ep in episodes:
        robot, stack = ep.robot, ep.stack
        res = rk.make_resolver(resolver, backend=backend, limits=dict(ep.limits))
        if resolver == "hqp" and ep.levels:
            res.levels = ep.levels
        failed = [False]
        solve = res.backend.solve

        def watched(
            problem: QPProblem, warm: np.ndarray | None = None, solve: Any = solve, failed: list[bool] = failed
        ) -> QPSolution:
            try:
                return solve(problem, warm)
            except SolverError:
                failed[0] |= not infeasible(problem)
                raise

        res.backend.solve = watched
        rng = np.random.default_rng(ep.seed + 1)
        q = ep.q0.copy()
        robot.update(q)
        stack.reset(robot)
        if ep.kind == "panda":
            robot.update(rng.uniform(robot.lower_limits, robot.upper_limits))
            stack.tasks[0].set_target(robot.frame_position(TIP))
        for k in range(steps):
            if ep.kind == "panda" and k and k % 10 == 0:  # a target jump
                robot.update(rng.uniform(robot.lower_limits, robot.upper_limits))
                stack.tasks[0].set_target(robot.frame_position(TIP))
            failed[0] = False
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                step = res.step(robot, stack, q, k * ep.dt, ep.dt)
            out.steps += 1
            out.failures += failed[0]
            if step.fallback is not None:
                out.fallback += 1
                out.unexplained += not failed[0]
            if step.relaxed:
                out.relaxed += 1
                out.retried += any(r.endswith("(backend retried)") for r in step.relaxed)
            elif step.fallback is None and _bound_violation(robot, stack, step.dq, ep.dt) > 1e-6:
                out.silent += 1
            q = robot.integrate(q, step.dq, ep.dt)
    out.wall_s = time.perf_counter() - t0
    return out


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments, run every pair, print and write the counts; exit code 1 on an unexplained fallback or
    a silent relaxation."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=2000, help="steps per (resolver, backend) pair")
    parser.add_argument("--episode", type=int, default=50, help="steps per episode")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--backends", nargs="+", default=None)
    parser.add_argument("--resolvers", nargs="+", default=["wqp", "hqp"])
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    stress = _stress_resolvers()
    panda = rk.load_example_robot("panda")
    n_ep = max(1, -(-args.steps // args.episode))
    episodes = [
        panda_episode(panda, args.seed + i) if i % 2 else chain_episode(stress, args.seed + i, args.episode)
        for i in range(n_ep)
    ]
    results = []
    for resolver in args.resolvers:
        for backend in args.backends or available_backends():
            r = run_pair(resolver, backend, episodes, args.episode)
            print(
                f"{resolver:>4}/{backend:<10} steps {r.steps:>7}  fallback {r.fallback:>5} (unexplained "
                f"{r.unexplained})  relaxed {r.relaxed:>6} (backend retried {r.retried})  backend failures "
                f"{r.failures}  silent {r.silent}  ({r.wall_s:.0f} s)",
                flush=True,
            )
            results.append(r)
    total = {key: sum(getattr(r, key) for r in results) for key in ("steps", "fallback", "unexplained", "relaxed",
                                                                    "retried", "failures", "silent")}  # fmt: skip
    print("total " + "  ".join(f"{k} {v}" for k, v in total.items()))
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"pairs": [asdict(r) for r in results], "total": total}, indent=2))
    return int(total["unexplained"] + total["silent"] > 0)


if __name__ == "__main__":
    raise SystemExit(main())

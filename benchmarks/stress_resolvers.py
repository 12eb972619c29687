#!/usr/bin/env python3
"""Stress the QP resolvers: random robots, targets, starts at and outside the limits, rate limits, every backend.

Usage::

    python benchmarks/stress_resolvers.py                         # ≥ 1e5 steps (about 15 000 per resolver/backend)
    python benchmarks/stress_resolvers.py --steps 300 --json s.json  # a small run (the test suite runs one)

Every (resolver, backend) pair replays the same random episodes (same seeds), so the backends are compared on
identical problems. An episode: a random robot (a 7-joint spatial D-H chain with random ranges and velocity limits,
or the 3R arm), a start inside, exactly at, or up to 0.2 rad outside the position limits, a random frame target
(pose, position or planar; a fixed target or a line), one or two random subtasks (gradient, target, bound), a
posture sometimes, rate limits (a_max) on half of the episodes, a random gain with K·dt ∈ (0.05, 1.9).

Counted per step, from a joint-limit box computed independently of the resolver (same settings, same previous
q̇):

* ``violations``: q̇ outside the box (beyond 1e-9), |q̇| above a velocity limit, or a joint that started inside
  its range leaving it (beyond 1e-9 rad), or one that started outside moving further out — must be 0;
* ``nans``: a non-finite q̇ — must be 0 (and a "non-finite" fallback counts here too);
* ``silent``: a step that reports neither a fallback nor a relaxation (``result.relaxed``) while a bound row
  C q̇ ≤ d is violated beyond max(the backend's tolerance, 1e-6) relative to max(1, ‖d‖∞) — a silent wrong answer,
  must be 0;
* ``fallbacks``: the steps that report something, by class:
  - ``infeasible: bound subtasks vs limits``: a relaxation (no fallback) where the bound rows C q̇ ≤ d have no
    solution inside the box (checked by a linear program) — a truly infeasible problem;
  - ``contradicted by a higher level``: hqp only: a relaxation (no fallback) where the bound rows are feasible inside
    the box but not together with the higher levels' optimum — the hierarchy's answer (daqp from the same state
    relaxes them too);
  - ``backend retried``: a relaxation that only counts a QP a documented retry solved (``"… (backend retried)"``);
  - ``backend failure``: anything else — a ``result.fallback`` (a backend failure no retry rescued, a relaxation
    that was not needed) — must be 0.

Prints one line per pair and writes ``--json`` ``{"pairs": [...], "total_steps": N}``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linprog

import redundik as rk
from redundik.kinematics import DHRow
from redundik.resolvers.qp import available_backends
from redundik.resolvers.qp.backends import TOLERANCE
from redundik.resolvers.qp.limits import JointLimits

#: Tolerance of every check [rad/s for q̇, rad or m for q].
TOL = 1e-9
RESOLVERS = ("wqp", "hqp")
INFEASIBLE = "infeasible: bound subtasks vs limits"
CONTRADICTED = "contradicted by a higher level"
FAILURE = "backend failure"
RETRIED = "backend retried"


@dataclass
class Episode:
    """One random episode: robot, start, stack factory and limit settings."""

    robot: rk.RobotModel
    q0: np.ndarray
    dt: float
    steps: int
    limit_options: dict[str, Any]
    seed: int
    start: str

    def stack(self) -> rk.TaskStack:
        """A fresh stack (same random choices for every backend: drawn from the episode's seed)."""
        return _random_stack(self.robot, np.random.default_rng(self.seed + 7), self.dt)


@dataclass
class PairResult:
    """What one (resolver, backend) pair did."""

    resolver: str
    backend: str
    steps: int = 0
    violations: int = 0
    max_violation: float = 0.0
    nans: int = 0
    silent: int = 0
    max_silent: float = 0.0
    fallbacks: Counter = field(default_factory=Counter)
    first: dict[str, str] = field(default_factory=dict)
    qp_steps: int = 0
    wall_s: float = 0.0

    def as_json(self) -> dict[str, Any]:
        """The JSON record."""
        return {
            "resolver": self.resolver,
            "backend": self.backend,
            "steps": self.steps,
            "violations": self.violations,
            "max_violation": self.max_violation,
            "nans": self.nans,
            "silent_bound_violations": self.silent,
            "max_silent_bound_violation": self.max_silent,
            "fallbacks": dict(self.fallbacks),
            "fallback_total": int(sum(self.fallbacks.values())),
            "first_fallback_per_class": self.first,
            "qp_steps": self.qp_steps,
            "wall_s": self.wall_s,
        }


# ---------------------------------------------------------------------------------------------------------- random
def _chain(rng: np.random.Generator) -> rk.RobotModel:
    rows = []
    for i in range(7):
        half = float(rng.uniform(0.3, 2.5))
        mid = float(rng.uniform(-0.5, 0.5))
        rows.append(
            DHRow(
                f"j{i + 1}",
                theta=float(rng.uniform(-np.pi, np.pi)),
                d=float(rng.uniform(-0.3, 0.3)),
                a=float(rng.uniform(0.1, 0.5)),
                alpha=float(rng.choice([-np.pi / 2, 0.0, np.pi / 2]) + rng.uniform(-0.2, 0.2)),
                lower=mid - half,
                upper=mid + half,
                velocity=float(rng.uniform(0.5, 3.0)),
            )
        )
    return rk.from_dh(rows, name="chain7")


def _planar(rng: np.random.Generator) -> rk.RobotModel:
    lim = float(rng.uniform(0.5, 2.5))
    rows = [DHRow(str(i + 1), a=1.0, lower=-lim, upper=lim, velocity=float(rng.uniform(0.5, 3.0))) for i in range(3)]
    return rk.from_dh(rows, name="planar3r")


def make_episode(seed: int, steps: int) -> Episode:
    """Episode ``seed``: every random choice comes from it."""
    rng = np.random.default_rng(seed)
    robot = _chain(rng) if rng.random() < 0.75 else _planar(rng)
    lo, hi = robot.lower_limits, robot.upper_limits
    q0 = rng.uniform(lo, hi)
    start = str(rng.choice(["inside", "at", "outside"]))
    pick = rng.random(robot.nv) < 0.4
    side = rng.random(robot.nv) < 0.5
    if start == "at":
        q0[pick] = np.where(side, hi, lo)[pick]
    elif start == "outside":
        over = rng.uniform(0.001, 0.2, robot.nv)
        q0[pick] = np.where(side, hi + over, lo - over)[pick]
    options: dict[str, Any] = {}
    if rng.random() < 0.5:
        options["acceleration"] = float(rng.uniform(0.5, 50.0))
    if rng.random() < 0.3:
        options["position_gain"] = float(rng.uniform(0.2, 1.0))
    dt = float(rng.choice([0.01, 0.005, 0.002]))
    return Episode(robot, q0, dt, steps, options, seed, start)


def _random_stack(robot: rk.RobotModel, rng: np.random.Generator, dt: float) -> rk.TaskStack:
    tip = robot.joint_names[-1]
    planar = robot.name == "planar3r"
    axes = "planar" if planar else str(rng.choice(["pose", "position"]))
    gain = float(rng.uniform(0.05, 1.9)) / dt
    if rng.random() < 0.5:
        velocity = rng.uniform(-0.3, 0.3, 2 if planar else 3)
        task = rk.FrameTask(tip, rk.Line(velocity.tolist()), axes=axes, gain=gain, name="frame")
    else:
        task = rk.FrameTask(tip, axes=axes, gain=gain, name="frame")
        q_t = rng.uniform(robot.lower_limits, robot.upper_limits)
        robot.update(q_t)
        task.set_target(robot.frame_pose(tip).homogeneous if axes == "pose" else robot.frame_position(tip))
    tasks: list[rk.Task] = [task]
    if rng.random() < 0.4:
        tasks.append(rk.PostureTask(gain=float(rng.uniform(0.1, 5.0))))
    joints = robot.joint_names
    subs: list[rk.Subtask] = []
    for k in range(int(rng.integers(1, 3))):
        j = str(rng.choice(joints))
        kind = rng.choice(["gradient", "target", "bound"])
        if kind == "gradient":
            subs.append(rk.GradientSubtask(rk.JointCentering(), gain=-float(rng.uniform(0.1, 3.0)), name=f"g{k}"))
        elif kind == "target":
            pot = rk.JointSine2(j) if rng.random() < 0.5 else rk.JointValue(j, 0.0)
            subs.append(rk.TargetSubtask(pot, target=float(rng.uniform(0.0, 1.0)), rate=1.0, name=f"t{k}"))
        else:
            i = joints.index(j)
            lo, hi = robot.lower_limits[i], robot.upper_limits[i]
            centre, radius = float(rng.uniform(lo, hi)), float(rng.uniform(0.05, 0.5) * (hi - lo))
            rate = float(rng.uniform(0.0, 20.0))
            key = "lower" if rng.random() < 0.5 else "upper"  # stay away from / stay near the centre (p = (q − c)²)
            pot = rk.JointValue(j, centre)
            subs.append(rk.BoundSubtask(pot, **{key: radius**2}, rate=rate, name=f"b{k}"))
    return rk.TaskStack(tasks, subs)


# ---------------------------------------------------------------------------------------------------------- checks
def _violation(box: Any, dq: np.ndarray, q: np.ndarray, q_next: np.ndarray, lo: np.ndarray, hi: np.ndarray,
               vmax: np.ndarray) -> float:  # fmt: skip
    v = max(float(np.max(box.lb - dq, initial=0.0)), float(np.max(dq - box.ub, initial=0.0)))
    v = max(v, float(np.max(np.abs(dq) - vmax, initial=0.0)))
    inside = (q >= lo) & (q <= hi)
    out_now = np.maximum(lo - q, 0.0) + np.maximum(q - hi, 0.0)
    out_next = np.maximum(lo - q_next, 0.0) + np.maximum(q_next - hi, 0.0)
    v = max(v, float(np.max(np.where(inside, out_next, 0.0), initial=0.0)))
    v = max(v, float(np.max(np.where(~inside, out_next - out_now, 0.0), initial=0.0)))
    return v


def _bound_rows(robot: rk.RobotModel, stack: rk.TaskStack, dt: float) -> tuple[np.ndarray, np.ndarray]:
    Cs, ds = [np.zeros((0, robot.nv))], [np.zeros(0)]
    for sub in stack.bound_subtasks:
        C, d, _ = sub.rows(robot, dt)
        Cs.append(C)
        ds.append(d)
    return np.vstack(Cs), np.concatenate(ds)


def _feasible(C: np.ndarray, d: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> bool:
    if not C.shape[0]:
        return True
    bounds = [
        (None if not np.isfinite(a) else a, None if not np.isfinite(b) else b) for a, b in zip(lb, ub, strict=True)
    ]
    out = linprog(np.zeros(C.shape[1]), A_ub=C, b_ub=d + 1e-9, bounds=bounds, method="highs")
    return bool(out.status == 0)


def _members(relaxed: tuple[str, ...]) -> set[str]:
    """The members a step relaxed (its ``relaxed`` without the QPs a retry solved)."""
    return {r for r in relaxed if not r.endswith("(backend retried)")}


def _classify(fallback: str | None, relaxed: tuple[str, ...], feasible: bool, resolver: str,
              reference: tuple[str, ...] | None) -> str:  # fmt: skip
    if fallback is not None:
        return "non-finite" if "non-finite" in fallback else FAILURE
    if not _members(relaxed):
        return RETRIED
    if not feasible:
        return INFEASIBLE
    if resolver == "hqp" and reference is not None and _members(reference):
        return CONTRADICTED
    return FAILURE


# ---------------------------------------------------------------------------------------------------------- run
def run_pair(resolver: str, backend: str, episodes: list[Episode]) -> PairResult:
    """Replay ``episodes`` with one (resolver, backend); returns the counts."""
    out = PairResult(resolver, backend)
    t0 = time.perf_counter()
    for ep in episodes:
        robot = ep.robot
        res = rk.make_resolver(resolver, backend=backend, limits=dict(ep.limit_options))
        ref = None if backend == "daqp" else rk.make_resolver(resolver, backend="daqp", limits=dict(ep.limit_options))
        lim = JointLimits(**ep.limit_options)
        lim.bind(robot)
        lo, hi, vmax = robot.lower_limits, robot.upper_limits, robot.velocity_limits
        stack = ep.stack()
        q = ep.q0.copy()
        robot.update(q)
        stack.reset(robot)
        dq_prev: np.ndarray | None = None
        for k in range(ep.steps):
            t = k * ep.dt
            box = lim.box(robot, q, ep.dt, dq_prev)
            if ref is not None:
                ref._dq_prev = None if dq_prev is None else dq_prev.copy()  # the same state for the reference
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                step = res.step(robot, stack, q, t, ep.dt)
            out.steps += 1
            out.qp_steps += bool(step.info.get("qp", 0))
            dq = step.dq
            if not np.all(np.isfinite(dq)):
                out.nans += 1
                break
            if step.fallback is None and not _members(step.relaxed) and stack.bound_subtasks:
                # nothing reported: every bound row must hold (within the backend's accuracy), else the step was a
                # silent wrong answer
                C, d = _bound_rows(robot, stack, ep.dt)
                over = float(np.max(C @ dq - d, initial=0.0))
                if over > max(TOLERANCE[backend], 1e-6) * max(1.0, float(np.max(np.abs(d), initial=0.0))):
                    out.silent += 1
                    out.max_silent = max(out.max_silent, over)
                    out.first.setdefault("silent", f"episode {ep.seed} step {k}: bound rows violated by {over:.3g}")
            if step.fallback is not None or step.relaxed:
                C, d = _bound_rows(robot, stack, ep.dt)
                reference = None
                if ref is not None:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        reference = ref.step(robot, stack, q, t, ep.dt).relaxed
                    robot.update(q)
                elif resolver == "hqp":
                    reference = step.relaxed
                feasible = _feasible(C, d, box.lb, box.ub)
                cls = _classify(step.fallback, step.relaxed, feasible, resolver, reference)
                if cls == "non-finite":
                    out.nans += 1
                out.fallbacks[cls] += 1
                what = step.fallback if step.fallback is not None else f"relaxed {step.relaxed}"
                out.first.setdefault(cls, f"episode {ep.seed} step {k}: {what[:300]}")
            q_next = robot.integrate(q, dq, ep.dt)
            v = _violation(box, dq, q, q_next, lo, hi, vmax)
            if v > TOL:
                out.violations += 1
                out.max_violation = max(out.max_violation, v)
            dq_prev = dq.copy()
            q = q_next
    out.wall_s = time.perf_counter() - t0
    return out


def run(steps_per_pair: int, episode_steps: int = 50, backends: list[str] | None = None,
        resolvers: tuple[str, ...] = RESOLVERS, seed: int = 0, log: Any = print) -> list[PairResult]:  # fmt: skip
    """Every (resolver, backend) pair over the same ⌈steps_per_pair / episode_steps⌉ episodes."""
    n_ep = max(1, -(-steps_per_pair // episode_steps))
    episodes = [make_episode(seed + i, episode_steps) for i in range(n_ep)]
    results = []
    for resolver in resolvers:
        for backend in backends or available_backends():
            r = run_pair(resolver, backend, episodes)
            log(
                f"{resolver:>4}/{backend:<10} steps {r.steps:>7}  violations {r.violations}  nans {r.nans}  "
                f"silent {r.silent}  "
                f"fallbacks {dict(r.fallbacks) or 0}  QP steps {r.qp_steps}  ({r.wall_s:.0f} s)"
            )
            results.append(r)
    return results


def main(argv: list[str] | None = None) -> int:
    """Parse arguments, run, print and write the counts; exit code 1 if a violation, NaN or failure occurred."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=15000, help="steps per (resolver, backend) pair")
    parser.add_argument("--episode", type=int, default=50, help="steps per episode")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--backends", nargs="+", default=None)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    results = run(args.steps, args.episode, args.backends, seed=args.seed)
    total = sum(r.steps for r in results)
    bad = sum(r.violations + r.nans + r.silent + r.fallbacks.get(FAILURE, 0) for r in results)
    print(f"total steps {total}; violations + NaNs + silent bound violations + backend failures = {bad}")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"pairs": [r.as_json() for r in results], "total_steps": total}, indent=2))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

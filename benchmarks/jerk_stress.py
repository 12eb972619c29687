#!/usr/bin/env python3
"""Stress the jerk limits: random target jumps on the Panda and TALOS, ``wqp`` and ``hqp``, every QP backend.

Usage::

    python benchmarks/jerk_stress.py                          # ≥ 1e5 steps per robot (split over the pairs)
    python benchmarks/jerk_stress.py --steps 2000 --robots panda   # a short check

An episode: the robot starts at rest at its reference configuration; its hand (both hands on TALOS) gets a new
random position target every 40–120 steps, up to 0.4 m away (often out of reach: the joints then run into their
position limits at speed), with a posture task below; limits: the model's position and velocity limits,
acceleration a_max and jerk j_max on every joint. Counted per step (q̈ and jerk from the returned q̇, the robot at
rest before the first step):

* ``jerk`` / ``acc``: |Δq̈|/dt > j_max or |q̈| > a_max beyond 1e-9 relative on a step that reported no
  relaxation — must be 0;
* ``pos`` / ``vel``: a joint outside its position limits (beyond 1e-9 rad) or |q̇| above its limit (1e-9
  relative) — must be 0;
* ``relaxed``: steps whose result reports a relaxation (``result.relaxed``, module docstring of
  :mod:`redundik.resolvers.qp.limits`); ``fallback``: steps with a fallback.

Prints one line per (robot, resolver, backend); exits 1 when a must-be-0 count is not.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass, field

import numpy as np

import redundik as rk
from redundik.kinematics.urdf import load_example_robot
from redundik.resolvers.qp import available_backends
from redundik.resolvers.qp.limits import JointLimits

#: Relative tolerance of the acceleration, jerk and velocity checks; absolute [rad] of the position check.
TOL = 1e-9
#: Per robot: hand frames, a_max [rad/s²], j_max [rad/s³], dt [s].
ROBOTS: dict[str, tuple[tuple[str, ...], float, float, float]] = {
    "panda": (("panda_hand",), 10.0, 400.0, 0.005),
    "talos": (("gripper_left_base_link", "gripper_right_base_link"), 8.0, 300.0, 0.01),
}


@dataclass
class Counts:
    """Violation and event counts of one (robot, resolver, backend) run."""

    steps: int = 0
    jerk: int = 0
    acc: int = 0
    pos: int = 0
    vel: int = 0
    relaxed: int = 0
    fallback: int = 0
    seconds: float = 0.0
    worst: dict[str, float] = field(default_factory=lambda: {"jerk": 0.0, "acc": 0.0})

    @property
    def bad(self) -> int:
        """The counts that must be 0."""
        return self.pos + self.vel + self.jerk + self.acc

    def line(self, label: str) -> str:
        return (
            f"{label:28s} steps {self.steps:7d}  jerk {self.jerk}  acc {self.acc}  pos {self.pos}  vel {self.vel}  "
            f"relaxed {self.relaxed}  fallback {self.fallback}  max |jerk|/j_max {self.worst['jerk']:.12f}  "
            f"max |q̈|/a_max {self.worst['acc']:.12f}  {1e6 * self.seconds / max(self.steps, 1):.0f} µs/step"
        )


def reference_q(robot: rk.RobotModel) -> np.ndarray:
    """A start inside every limit: TALOS half-sitting, else the middle of each joint's range (neutral where none)."""
    if robot.name == "talos":
        from benchmarks.bench.scenarios import talos_q0

        return talos_q0(robot)
    q = robot.neutral()
    for j in robot.joints:
        if j.idx_q >= 0 and np.isfinite(j.lower) and np.isfinite(j.upper) and abs(j.upper) < 1e10:
            q[j.idx_q] = 0.5 * (j.lower + j.upper)
    return q


def run_episodes(name: str, resolver: str, backend: str, steps: int, seed: int = 0) -> Counts:
    """``steps`` steps of random target jumps on robot ``name`` (episodes of 400 steps from rest)."""
    frames, amax, jmax, dt = ROBOTS[name]
    robot = load_example_robot(name)
    q0 = reference_q(robot)
    rng = np.random.default_rng(seed)
    hands = [rk.FrameTask(f, axes="position", gain=0.5 / dt) for f in frames]
    stack = rk.TaskStack([*hands, rk.PostureTask(q0, gain=1.0, weight=1e-3)])
    limits = JointLimits(acceleration=amax, jerk=jmax)
    res = rk.make_resolver(resolver, backend=backend, limits=limits)
    limits.bind(robot)
    lo, hi = limits.lower_position, limits.upper_position
    vmax = np.array([j.velocity if 0 < j.velocity < 1e10 else np.inf for j in robot.joints])
    iq = np.array([max(j.idx_q, 0) for j in robot.joints])
    counts = Counts()
    t_start = time.perf_counter()
    done = 0
    while done < steps:
        q = q0.copy()
        robot.update(q)
        res.reset()
        stack.reset(robot)
        v1, v2 = np.zeros(robot.nv), np.zeros(robot.nv)
        next_jump = 0
        for k in range(min(400, steps - done)):
            if k == next_jump:
                robot.update(q)
                for h in hands:
                    h.set_target(robot.frame_position(h.frame) + rng.uniform(-0.4, 0.4, 3))
                next_jump = k + int(rng.integers(40, 120))
            out = res.step(robot, stack, q, k * dt, dt)
            dq = np.asarray(out.dq, dtype=float)
            acc = (dq - v1) / dt
            jerk = (dq - 2 * v1 + v2) / (dt * dt)
            counts.worst["jerk"] = max(counts.worst["jerk"], float(np.max(np.abs(jerk))) / jmax)
            counts.worst["acc"] = max(counts.worst["acc"], float(np.max(np.abs(acc))) / amax)
            exempt = bool(out.relaxed)  # a reported relaxation may exceed the relaxed limit, nothing else may
            counts.jerk += not exempt and bool(np.any(np.abs(jerk) > jmax * (1 + TOL)))
            counts.acc += not exempt and bool(np.any(np.abs(acc) > amax * (1 + TOL)))
            counts.vel += bool(np.any(np.abs(dq) > vmax * (1 + TOL)))
            counts.relaxed += bool(out.relaxed)
            counts.fallback += out.fallback is not None
            q = robot.integrate(q, dq, dt)
            qq = q[iq]
            counts.pos += bool(np.any((qq < lo - TOL) | (qq > hi + TOL)))
            v2, v1 = v1, dq.copy()
            counts.steps += 1
        done += min(400, steps - done)
    counts.seconds = time.perf_counter() - t_start
    return counts


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=100_000, help="steps per robot, split over the pairs")
    ap.add_argument("--robots", nargs="+", default=list(ROBOTS), choices=list(ROBOTS))
    ap.add_argument("--backends", nargs="+", default=None, help="default: every installed backend")
    args = ap.parse_args(argv)
    backends = args.backends or available_backends()
    bad = 0
    for name in args.robots:
        pairs = [(r, b) for r in ("wqp", "hqp") for b in backends]
        per_pair = max(args.steps // len(pairs), 1)
        for resolver, backend in pairs:
            c = run_episodes(name, resolver, backend, per_pair)
            print(c.line(f"{name} {resolver} {backend}"), flush=True)
            bad += c.bad
    print("OK: 0 violations" if not bad else f"FAILED: {bad} steps with violations")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

"""What users run (issue 31): a trajectory tick against a teleop tick (``set_target`` every tick, its cost included),
the same tick with the posture's reference moved every tick (``PostureTask.set_target``), a ``FrameTask`` subclass, a
10-line custom task (its ``evaluate``, the same row as a compiled writer of ``rk.CompiledTask``, and the same row as
the library's own ``FrameTask`` on one axis), and TALOS with the library's ``PostureTask``; the custom task's
``evaluate`` alone is also timed in the rotation — public classes only, cases interleaved tick by tick in one process,
medians and p90 per case, ratios against the trajectory tick.

Run: ``python benchmarks/user_cases.py [--steps N] [--json FILE]``; prints a table and the path each case took
(``result.info["path"]``). Ratios from one run; the machine is shared, so report the spread of several runs.
"""

from __future__ import annotations

import os

# timed after untimed warm-up steps: the kernels compile in the caller's thread, not in redundik's background one
os.environ.setdefault("REDUNDIK_COLD_START", "wait")

import argparse
import gc
import json
import time
from typing import Any

import numba
import numpy as np
import pinocchio as pin

import redundik as rk
from redundik.kinematics.layouts import POSE_P

TOOL = "panda_hand_tcp"
Q0 = np.array([0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.02, 0.02])
DT = 1e-3
KINDS = ("trajectory", "teleop", "posture_target", "subclass", "builtin_row", "custom_task", "compiled_task")


class MyFrameTask(rk.FrameTask):
    """A user's subclass that changes nothing about the rows (the issue's ``class MyFrameTask(FrameTask): pass``)."""


class ElbowSide(rk.Task):
    """A user's 10-line task: keep the elbow's lateral position at y_d (one row of its frame Jacobian).

    The Panda's self-motion at ``Q0`` swings the elbow sideways: this row steers the arm's one redundant degree of
    freedom. (Its height would not do: with the hand's pose held, it is stationary under the self-motion at ``Q0``,
    so hand + height is a singular main task there.)"""

    def __init__(self, y_d: float, gain: float = 5.0) -> None:
        self._init_task("elbow_side", gain=gain)
        self.y_d = y_d

    def evaluate(self, robot: rk.RobotModel, t: float) -> rk.TaskTerm:
        J = robot.frame_jacobian("panda_link4")[1:2]
        e = np.array([self.y_d - robot.frame_position("panda_link4")[1]])
        return rk.TaskTerm(self.name, J, self.gain * e, e, self.weight)

    def __repr__(self) -> str:
        return f"ElbowSide(y_d={self.y_d})"


@numba.njit  # (no on-disk cache: numba keys it by the importing name, a script and a module differ)
def _elbow_rows(q, t, poses, jw, ints, floats, gain, J, e, v):  # type: ignore[no-untyped-def]
    """The same row as ``ElbowSide.evaluate``, as a compiled writer (``rk.CompiledRows``)."""
    f = ints[0]  # (ints: the frame, then a flag per column; floats: y_d)
    px, py, pz = poses[f, POSE_P : POSE_P + 3]  # the frame's origin [m]
    for c in range(jw.shape[1]):  # the y row of the frame's base-aligned Jacobian: v_y + (ω × p)_y
        if ints[1 + c]:
            J[0, c] = jw[1, c] + jw[5, c] * px - jw[3, c] * pz
    e[0] = floats[0] - py
    v[0] = gain * e[0]


class ElbowSideCompiled(rk.CompiledTask):
    """``ElbowSide`` with its row as a compiled writer: a user's task of one file on the compiled step."""

    def __init__(self, y_d: float, gain: float = 5.0) -> None:
        self._init_task("elbow_side", gain=gain)
        self.floats = np.array([y_d])
        self.ints = np.zeros(0, dtype=np.int64)

    def compiled_rows(self, robot: rk.RobotModel) -> rk.CompiledRows:
        if self.ints.shape[0] == 0:
            fid = robot.frame_id("panda_link4")
            model = robot.model
            cols = np.zeros(robot.nv, dtype=np.int64)
            for j in model.supports[model.frames[fid].parentJoint]:
                if j > 0:
                    cols[model.joints[j].idx_v] = 1
            self.ints = np.concatenate([[fid], cols]).astype(np.int64)
        return rk.CompiledRows(_elbow_rows, 1, self.ints, self.floats)

    def __repr__(self) -> str:
        return f"ElbowSideCompiled(y_d={self.floats[0]})"


def elbow_y0() -> float:
    """The elbow's (``panda_link4``) lateral position at ``Q0`` [m]: the user task's target."""
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    return float(robot.frame_position("panda_link4")[1])


def _panda_case(kind: str, method: str) -> dict[str, Any]:
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    y0 = float(robot.frame_position("panda_link4")[1])  # the user task holds the elbow's lateral position at Q0
    circle = rk.Circle(0.1, np.pi, plane=("y", "z"))
    if kind == "trajectory":
        tasks: list[rk.Task] = [rk.FrameTask(TOOL, circle, gain=50.0)]
    elif kind == "subclass":
        tasks = [MyFrameTask(TOOL, circle, gain=50.0)]
    elif kind == "custom_task":
        tasks = [rk.FrameTask(TOOL, circle, gain=50.0), ElbowSide(y0, gain=5.0)]
    elif kind == "compiled_task":
        tasks = [rk.FrameTask(TOOL, circle, gain=50.0), ElbowSideCompiled(y0, gain=5.0)]
    elif kind == "builtin_row":  # the same row through the library's own task: what the row costs by itself
        elbow = rk.FrameTask("panda_link4", rk.Hold(), axes=["y"], gain=5.0, name="elbow_side")
        tasks = [rk.FrameTask(TOOL, circle, gain=50.0), elbow]
    elif kind == "posture_target":  # the trajectory case, with the posture's q_ref set every tick
        tasks = [rk.FrameTask(TOOL, circle, gain=50.0)]
    else:  # teleop
        tasks = [rk.FrameTask(TOOL, gain=40.0)]
    stack = rk.TaskStack([*tasks, rk.PostureTask(gain=1.0)])
    robot.update(Q0)
    stack.reset(robot)
    home = robot.frame_pose(TOOL)
    posture = stack.tasks[-1] if kind == "posture_target" else None
    return {
        "robot": robot, "stack": stack, "res": rk.make_resolver(method), "q": Q0.copy(), "k": 0, "home": home,
        "posture": posture,
    }  # fmt: skip


def _talos_case(method: str) -> dict[str, Any]:
    robot = rk.load_example_robot("talos")
    q0 = robot.neutral()
    robot.update(q0)
    hands = [rk.FrameTask(f, rk.Circle(0.05, np.pi, plane=("y", "z")), gain=20.0) for f in ("gripper_left_joint",)]
    stack = rk.TaskStack([*hands, rk.PostureTask(gain=1.0)])
    stack.reset(robot)
    return {"robot": robot, "stack": stack, "res": rk.make_resolver(method), "q": q0.copy(), "k": 0, "home": None,
            "posture": None}  # fmt: skip


def _evaluate_case() -> dict[str, Any]:
    """The custom task's ``evaluate`` alone, timed in the same rotation as the steps (the kinematics updated at a
    moving q first, untimed): its own cost under the same cache conditions as the step that calls it."""
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    return {"robot": robot, "task": ElbowSide(float(robot.frame_position("panda_link4")[1])), "k": 0}


def _evaluate_tick(case: dict[str, Any]) -> float:
    k = case["k"]
    q = Q0.copy()
    q[:7] += 0.2 * np.sin(1e-3 * k + np.arange(7))
    case["robot"].update(q)
    t0 = time.perf_counter()
    case["task"].evaluate(case["robot"], k * DT)
    elapsed = time.perf_counter() - t0
    case["k"] = k + 1
    return elapsed


def _tick(case: dict[str, Any], teleop: bool) -> tuple[float, Any]:
    if "task" in case:  # the custom task's evaluate alone
        return _evaluate_tick(case), None
    k = case["k"]
    t = k * DT
    target = None
    if teleop:  # the operator's new pose (made outside the timed tick: the user's cost, not the library's)
        h = case["home"]
        target = pin.SE3(h.rotation, h.translation + np.array([0.0, 0.05 * np.sin(2 * t), 0.03 * np.sin(4 * t)]))
    posture = case["posture"]
    if posture is not None:  # a moving posture reference (a planner's nominal configuration), made untimed
        ref = Q0.copy()
        ref[:7] += 0.1 * np.sin(2 * t + np.arange(7))
    t0 = time.perf_counter()
    if target is not None:
        case["stack"].tasks[0].set_target(target)  # timed: set_target is part of a teleop tick
    if posture is not None:
        posture.set_target(ref)  # timed, as set_target above
    res = case["res"].step(case["robot"], case["stack"], case["q"], t, DT)
    elapsed = time.perf_counter() - t0
    case["q"] = case["robot"].integrate(case["q"], res.dq, DT)
    case["k"] = k + 1
    return elapsed, res


def run(steps: int) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for method in ("pinv", "wqp", "hqp"):
        cases = {kind: _panda_case(kind, method) for kind in KINDS}
        cases["talos_posture"] = _talos_case(method)
        cases["custom_evaluate"] = _evaluate_case()
        for name, c in cases.items():
            for _ in range(30):
                _tick(c, name == "teleop")
        times: dict[str, list[float]] = {name: [] for name in cases}
        gc.disable()
        try:
            names = list(cases)
            order = np.random.default_rng(0)
            for _ in range(steps):  # a new random order every round: no case always follows the same neighbour
                for i in order.permutation(len(names)):
                    name = names[i]
                    times[name].append(_tick(cases[name], name == "teleop")[0])
        finally:
            gc.enable()
        paths = {
            name: "-" if name == "custom_evaluate" else _tick(c, name == "teleop")[1].info["path"]
            for name, c in cases.items()
        }
        base = float(np.median(times["trajectory"]))
        for name, ts in times.items():
            arr = np.array(ts) * 1e6
            out[f"{method}/{name}"] = {
                "median_us": float(np.median(arr)),
                "p90_us": float(np.percentile(arr, 90)),
                "x_trajectory": float(np.median(arr)) / (base * 1e6),
                "path": paths[name],
            }
    task = rk.FrameTask(TOOL, gain=40.0)
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    rk.TaskStack([task]).reset(robot)
    T = robot.frame_pose(TOOL)
    for _ in range(100):
        task.set_target(T)
    n = 20000
    t0 = time.perf_counter()
    for _ in range(n):
        task.set_target(T)
    out["set_target_us"] = (time.perf_counter() - t0) / n * 1e6
    elbow = ElbowSide(0.0)  # the custom task's own cost: its evaluate alone (the target: a tick adds ≤ this + 10 %)
    for _ in range(100):
        elbow.evaluate(robot, 0.0)
    t0 = time.perf_counter()
    for _ in range(n):
        elbow.evaluate(robot, 0.0)
    out["custom_evaluate_us"] = (time.perf_counter() - t0) / n * 1e6
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    res = run(args.steps)
    print(f"{'case':28s} {'median µs':>10s} {'p90 µs':>8s} {'× traj':>7s}  path")
    for key, v in res.items():
        if isinstance(v, dict):
            print(f"{key:28s} {v['median_us']:10.1f} {v['p90_us']:8.1f} {v['x_trajectory']:7.2f}  {v['path']}")
    print(f"set_target alone: {res['set_target_us']:.2f} µs")
    ev = res["custom_evaluate_us"]
    for method in ("pinv", "wqp", "hqp"):
        rot = res[f"{method}/custom_evaluate"]["median_us"]
        base = res[f"{method}/trajectory"]["median_us"]
        extra = res[f"{method}/custom_task"]["median_us"] - base
        comp = res[f"{method}/compiled_task"]["median_us"] - base
        row = res[f"{method}/builtin_row"]["median_us"] - base
        print(
            f"{method}: the custom task adds {extra:.1f} µs to a tick (its evaluate alone: {ev:.1f} µs in a tight "
            f"loop, {rot:.1f} µs in the rotation); "
            f"as a compiled writer it adds {comp:.1f} µs; the same row as a built-in FrameTask adds {row:.1f} µs"
        )
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(res, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

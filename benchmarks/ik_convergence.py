"""IK to convergence on random reachable poses: rk.solve_ik against TRAC-IK (pytracik) and a pink loop.

Targets: the tool frame's pose at N configurations drawn uniformly within the joint limits (seeded), for the Panda,
the UR5 and the xArm7 (7 dof, from example-robot-data's URDF). Every solver starts from mid-range, has the same
tolerances (1e-5 m; 1e-4 rad for ours, TRAC-IK's epsilon 1e-5 on its twist) and a 5 ms budget per pose; success
is re-checked here by Pinocchio's forward kinematics (1e-5 m / 1e-4 rad), and a limit violation is any returned
coordinate outside the URDF's limits. Times: the solver call only, per pose (median, p99, max) [ms].

TRAC-IK (``pytracik``) runs in its own interpreter (``--peers-python``, default /work/wt/ikpeers/bin/python, or
$IKPEERS_PYTHON) and receives the joint limits explicitly (it reads every Panda range as [0, 0]). The pink loop
(``pink.solve_ik`` with its configuration limits, dt = 1, ≤ 500 iterations) runs only on ``--pink`` (it is slow).
mink is not run: it needs a MuJoCo model of each robot, not set up here. A missing peer is skipped with a note.

Run: ``python benchmarks/ik_convergence.py [--quick | --n N] [--robots panda,ur5,xarm7] [--pink] [--json FILE]``.
"""

from __future__ import annotations

import os

# timed after untimed warm-up steps: the kernels compile in the caller's thread, not in redundik's background one
os.environ.setdefault("REDUNDIK_COLD_START", "wait")

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

import redundik as rk
from redundik.kinematics.urdf import EXAMPLE_ROBOTS, example_robot_data_dir

ROBOTS = {"panda": ("panda_link0", "panda_hand_tcp"), "ur5": ("base_link", "tool0"), "xarm7": ("link_base", "link_eef")}
TOL_P, TOL_R, TIMEOUT = 1e-5, 1e-4, 5e-3

TRACIK_SCRIPT = r"""
import os, sys, time, numpy as np, pytracik
d = np.load(sys.argv[1]); urdf = open(sys.argv[2]).read()
s = pytracik.TRAC_IK(sys.argv[3], sys.argv[4], urdf, float(sys.argv[5]), 1e-5, pytracik.SolveType.Speed)
pytracik.set_joint_limits(s, list(d["lo"]), list(d["hi"]))
out, times = [], []
for p, quat in zip(d["pos"], d["quat"]):
    t = time.perf_counter(); r = pytracik.ik(s, d["q0"], *p, *quat); times.append(time.perf_counter() - t)
    out.append(r)
np.savez(sys.argv[6], res=np.array(out), times=np.array(times))
sys.stdout.flush(); os._exit(0)  # pytracik can corrupt the heap at interpreter shutdown: skip it
"""


def targets(robot: rk.RobotModel, frame: str, n: int, seed: int) -> list[pin.SE3]:
    rng, data, fid = np.random.default_rng(seed), robot.model.createData(), robot.frame_id(frame)
    out = []
    for _ in range(n):
        pin.framesForwardKinematics(robot.model, data, robot.random_configuration(rng))
        out.append(data.oMf[fid].copy())
    return out


def check(robot: rk.RobotModel, frame: str, qs: np.ndarray, Ts: list[pin.SE3]) -> tuple[np.ndarray, int]:
    """(success by FK per pose, number of poses with a coordinate outside the limits)."""
    data, fid = robot.model.createData(), robot.frame_id(frame)
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    ok = np.zeros(len(Ts), dtype=bool)
    viol = 0
    for i, (q, T) in enumerate(zip(qs, Ts, strict=True)):
        if not np.all(np.isfinite(q)):
            continue
        pin.framesForwardKinematics(robot.model, data, q)
        M = data.oMf[fid]
        ep = np.linalg.norm(M.translation - T.translation)
        er = np.linalg.norm(pin.log3(T.rotation @ M.rotation.T))
        ok[i] = ep <= TOL_P * 1.0001 and er <= TOL_R * 1.0001
        viol += bool(np.any(q < lo) or np.any(q > hi))
    return ok, viol


def row(name: str, solver: str, ok: np.ndarray, viol: int, times: np.ndarray) -> dict[str, object]:
    ms = times * 1e3
    return {
        "robot": name, "solver": solver, "n": int(ok.size), "success": float(np.mean(ok)),
        "median_ms": float(np.median(ms)), "p99_ms": float(np.percentile(ms, 99)), "max_ms": float(np.max(ms)),
        "limit_violations": viol,
    }  # fmt: skip


def run_ours(robot: rk.RobotModel, frame: str, Ts: list[pin.SE3]) -> tuple[np.ndarray, np.ndarray]:
    rk.solve_ik(robot, frame, Ts[0], timeout=TIMEOUT)  # compiled kernels loaded before the clock runs
    qs, times = [], []
    for i, T in enumerate(Ts):
        t = time.perf_counter()
        res = rk.solve_ik(robot, frame, T, position_tolerance=TOL_P, orientation_tolerance=TOL_R, timeout=TIMEOUT,
                          seed=(1, i))  # fmt: skip
        times.append(time.perf_counter() - t)
        qs.append(res.q)
    return np.array(qs), np.array(times)


def quaternion(R: np.ndarray) -> np.ndarray:
    q = pin.Quaternion(R)
    return np.array([q.x, q.y, q.z, q.w])


def run_tracik(
    python: str, robot: rk.RobotModel, urdf: Path, base: str, frame: str, Ts: list[pin.SE3], q0: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    with tempfile.TemporaryDirectory() as tmp:
        src, out, script = Path(tmp) / "in.npz", Path(tmp) / "out.npz", Path(tmp) / "tracik.py"
        nj = (
            q0.size
        )  # the chain's joints (the Panda's fingers are not in it): as many limits, or pytracik's heap breaks
        lo, hi = robot.model.lowerPositionLimit[:nj], robot.model.upperPositionLimit[:nj]
        np.savez(src, pos=np.array([T.translation for T in Ts]), quat=np.array([quaternion(T.rotation) for T in Ts]),
                 q0=q0, lo=lo, hi=hi)  # fmt: skip
        script.write_text(TRACIK_SCRIPT)
        proc = subprocess.run([python, str(script), str(src), str(urdf), base, frame, str(TIMEOUT), str(out)],
                              capture_output=True, text=True)  # fmt: skip
        if proc.returncode != 0 or not out.exists():
            print(f"  TRAC-IK failed to run: {proc.stderr.strip()[-300:]}")
            return None
        d = np.load(out)
        res = d["res"]
        qs = np.where(res[:, :1] > 0, res[:, 1:], np.nan)  # status column: > 0 solved
        return qs, d["times"]


def run_pink(robot: rk.RobotModel, frame: str, Ts: list[pin.SE3], q0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    import pink

    qs, times = [], []
    for T in Ts:
        t = time.perf_counter()
        conf = pink.Configuration(robot.model, robot.model.createData(), q0.copy())
        task = pink.tasks.FrameTask(frame, position_cost=1.0, orientation_cost=1.0)
        task.set_target(T)
        for _ in range(500):
            M = conf.get_transform_frame_to_world(frame)
            if (np.linalg.norm(M.translation - T.translation) <= TOL_P
                    and np.linalg.norm(pin.log3(T.rotation @ M.rotation.T)) <= TOL_R):  # fmt: skip
                break
            v = pink.solve_ik(conf, [task], 1.0, solver="daqp", damping=1e-12)
            conf.integrate_inplace(v, 1.0)
        times.append(time.perf_counter() - t)
        qs.append(conf.q.copy())
    return np.array(qs), np.array(times)


def run_robot(name: str, n: int, seed: int, peers_python: str, pink: bool = False) -> list[dict[str, object]]:
    """The rows of one robot (:data:`ROBOTS`): rk.solve_ik, TRAC-IK when ``peers_python`` exists, pink on ``pink``."""
    base, frame = ROBOTS[name]
    robot = rk.load_example_robot(name)
    Ts = targets(robot, frame, n, seed)
    q_mid = robot.model.lowerPositionLimit * 0.5 + robot.model.upperPositionLimit * 0.5
    qs, times = run_ours(robot, frame, Ts)
    rows = [row(name, "redundik solve_ik", *check(robot, frame, qs, Ts), times)]
    if Path(peers_python).exists():
        urdf = example_robot_data_dir() / EXAMPLE_ROBOTS[name][0]
        got = run_tracik(peers_python, robot, urdf, base, frame, Ts, q_mid[: 7 if name == "panda" else robot.nq])
        if got is not None:
            qt, tt = got
            if qt.shape[1] != robot.nq:  # the chain ends before the fingers: pad them at mid-range
                qt = np.hstack([qt, np.broadcast_to(q_mid[qt.shape[1] :], (n, robot.nq - qt.shape[1]))])
            rows.append(row(name, "TRAC-IK (pytracik, 5 ms)", *check(robot, frame, qt, Ts), tt))
    else:
        print(f"  note: TRAC-IK skipped ({peers_python} not found; set --peers-python)")
    if pink:
        try:
            qp, tp = run_pink(robot, frame, Ts, q_mid)
            rows.append(row(name, "pink loop (dt 1, ≤ 500 it)", *check(robot, frame, qp, Ts), tp))
        except ImportError:
            print("  note: pink skipped (not installed)")
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000, help="poses per robot (default 10 000)")
    ap.add_argument("--quick", action="store_true", help="500 poses per robot")
    ap.add_argument("--robots", default="panda,ur5,xarm7")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--pink", action="store_true", help="also run the pink loop (slow)")
    ap.add_argument("--peers-python", default=os.environ.get("IKPEERS_PYTHON", "/work/wt/ikpeers/bin/python"))
    ap.add_argument("--json", type=Path, help="write the rows to this file")
    args = ap.parse_args(argv)
    n = 500 if args.quick else args.n
    if n < 1:
        ap.error("--n must be ≥ 1")
    rows = []
    for name in args.robots.split(","):
        if name not in ROBOTS:
            ap.error(f"unknown robot {name!r}; known: {sorted(ROBOTS)}")
        got = run_robot(name, n, args.seed, args.peers_python, pink=args.pink)
        rows += got
        for r in got:
            print(json.dumps(r))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""PlaCo worker of the benchmark: runs in PlaCo's own interpreter (numpy + placo only, no redundik, any pin).

PlaCo 0.10 pins ``pin==3.8.0`` (its own libpinocchio), so it cannot share the benchmark's environment; the
benchmark starts this script with a PlaCo interpreter and drives it over stdin/stdout, one JSON document per line,
chunk by chunk, so PlaCo's chunks interleave with the in-process cases of the same run.

Protocol (each request one line of JSON on stdin, each answer one line on stdout):

* ``{"cmd": "init", "urdf": PATH, "frames": [NAME, ...], "free_flyer": BOOL, "dt": S, "joints": [NAME, ...],
  "q0": [values of joints], "base": [x, y, z, qx, qy, qz, qw] | null, "frame_weights": [w_pos, w_rot],
  "posture_weight": W, "posture_gain": K_p}`` → ``{"ok": true, "placo": VERSION}``.
  The URDF must have no ``<visual>``/``<collision>`` (PlaCo opens their meshes even with ``ignore_collisions``).
* ``{"cmd": "run", "targets": [[16 × len(frames) floats, row-major 4×4 per frame], ...]}`` (one entry per step,
  the reference poses at t + dt) → ``{"ok": true, "ns": [per-step ns], "q": [[base (7) if free flyer, then the
  joints in the order of "joints"], ...]}`` (the configuration after each step).
* ``{"cmd": "quit"}`` → exits.

An error answers ``{"ok": false, "error": "..."}``. The timed region of a step is what a PlaCo control loop pays:
``task.T_world_frame = T`` per frame, ``robot.update_kinematics()``, ``solver.solve(True)`` (which also integrates).
The posture's target is moved each tick to q + K_p·dt·(q0 − q) (PlaCo's joints task is position-level, like its
frame task: matched to the benchmark's K_p); that update is Python and is kept *outside* the timed region, which
favours PlaCo.
"""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import numpy as np


class Worker:
    def __init__(self, msg: dict[str, Any]) -> None:
        import placo

        self.placo = placo
        self.robot = placo.RobotWrapper(msg["urdf"], placo.Flags.ignore_collisions)
        self.free_flyer = bool(msg["free_flyer"])
        self.joints = list(msg["joints"])
        self.q0 = np.asarray(msg["q0"], dtype=float)
        self.gain_dt = float(msg["posture_gain"]) * float(msg["dt"])
        for name, value in zip(self.joints, self.q0, strict=True):
            self.robot.set_joint(name, float(value))
        if msg.get("base") is not None:
            q = np.array(self.robot.state.q, dtype=float)
            q[:7] = np.asarray(msg["base"], dtype=float)
            self.robot.state.q = q
        else:
            self.robot.set_T_world_fbase(np.eye(4))
        self.robot.update_kinematics()
        solver = placo.KinematicsSolver(self.robot)
        solver.mask_fbase(not self.free_flyer)
        solver.enable_joint_limits(True)
        solver.enable_velocity_limits(True)
        solver.dt = float(msg["dt"])
        w_pos, w_rot = (float(w) for w in msg["frame_weights"])
        self.tasks = []
        for frame in msg["frames"]:
            task = solver.add_frame_task(frame, self.robot.get_T_world_frame(frame))
            task.configure(frame, "soft", w_pos, w_rot)
            self.tasks.append(task)
        self.posture = solver.add_joints_task()
        self.posture.set_joints({n: float(v) for n, v in zip(self.joints, self.q0, strict=True)})
        self.posture.configure("posture", "soft", float(msg["posture_weight"]))
        self.solver = solver
        self._offsets = [self.robot.get_joint_offset(n) for n in self.joints]

    def _joints(self) -> np.ndarray:
        return np.asarray(self.robot.state.q)[self._offsets]

    def run(self, targets: list[list[float]]) -> dict[str, Any]:
        ns, qs = [], []
        clock = time.perf_counter_ns
        n = len(self.tasks)
        for flat in targets:
            T = np.asarray(flat, dtype=float).reshape(n, 4, 4)
            qj = self._joints()  # the posture target: q + K_p dt (q0 − q), untimed (see the module docstring)
            self.posture.set_joints(dict(zip(self.joints, (qj + self.gain_dt * (self.q0 - qj)).tolist(), strict=True)))
            t0 = clock()
            for task, Ti in zip(self.tasks, T, strict=True):
                task.T_world_frame = Ti
            self.robot.update_kinematics()
            self.solver.solve(True)
            t1 = clock()
            ns.append(t1 - t0)
            q = np.asarray(self.robot.state.q)
            qs.append((q[:7].tolist() if self.free_flyer else []) + q[self._offsets].tolist())
        return {"ok": True, "ns": ns, "q": qs}


def main() -> int:
    worker: Worker | None = None
    for line in sys.stdin:
        if not line.strip():
            continue
        try:
            msg = json.loads(line)
            cmd = msg.get("cmd")
            if cmd == "quit":
                return 0
            if cmd == "init":
                worker = Worker(msg)
                import placo  # noqa: F401 - version below

                try:
                    from importlib.metadata import version

                    ver = version("placo")
                except Exception:
                    ver = "?"
                out: dict[str, Any] = {"ok": True, "placo": ver}
            elif cmd == "run":
                if worker is None:
                    raise RuntimeError("run before init")
                out = worker.run(msg["targets"])
            else:
                raise RuntimeError(f"unknown command {cmd!r}")
        except Exception as exc:  # every error goes back to the benchmark, which reports it
            out = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
        sys.stdout.write(json.dumps(out) + "\n")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())

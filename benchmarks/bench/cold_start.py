"""The ``cold_start`` case (issue 31 item 8): what the first step costs a user, in fresh processes.

Per method (``pinv``, ``wqp``, ``hqp``), a fresh ``python`` runs :data:`SCRIPT` — ``import redundik``, load the
Panda, make the ``panda_circle`` stack from public classes, ``resolver.step`` twice — with ``NUMBA_CACHE_DIR`` and
``XDG_CACHE_HOME`` pointing at a new empty folder (``cold``: nothing compiled yet, as after ``pip install``), then
once more on the same folder (``warm``: the kernels load from the cache the first run wrote; that run calls
``rk.warm_up`` after its timings, so the cache is complete). It reports the import,
the set-up, the first and the second step [s], the first step's ``result.info["path"]``, and the wall time of the
process (the interpreter's own start included). ``first_dq_s`` = import + set-up + first step: how long until the
first q̇. Whatever the library does on its first step (compile, load, run interpreted meanwhile) is what is timed.

mink and pink (when installed) run the same task set once each in a fresh process (import, set-up, first
``solve_ik``): they compile nothing, so one run is their cold and warm start.

These are one-shot figures: they run after the interleaved cases, one process at a time. The processes run in the
user's environment (:func:`_user_env`), with redundik's bytecode written first as ``pip install`` writes it.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

#: Per-process limit [s] (an empty cache on a loaded machine compiled for up to ~60 s per method).
TIMEOUT = 900

SCRIPT = r"""
import json, sys, time
t0 = time.perf_counter()
import numpy as np
import redundik as rk
t1 = time.perf_counter()
method = sys.argv[1]
robot = rk.load_example_robot("panda")
q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
robot.update(q)
hand = rk.FrameTask("panda_hand", rk.Circle(0.05, 2 * np.pi / 4, ("y", "z")), gain=100.0)
stack = rk.TaskStack([hand, rk.PostureTask(q, gain=1.0, weight=0.01, priority=0)])
stack.reset(robot)
resolver = rk.make_resolver(method)
t2 = time.perf_counter()
res = resolver.step(robot, stack, q, 0.0, 0.01)
t3 = time.perf_counter()
q = robot.integrate(q, res.dq, 0.01)
resolver.step(robot, stack, q, 0.01, 0.01)
t4 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "setup_s": t2 - t1, "first_step_s": t3 - t2, "second_step_s": t4 - t3,
                  "path": str(res.info.get("path", "?")), "interpreted": list(res.info.get("interpreted", ()))}),
      flush=True)
rk.warm_up([method])  # (the cache completed, as `redundik compile` does: the warm run loads every kernel from it)
"""

PEER_SCRIPT = r"""
import json, sys, time
t0 = time.perf_counter()
import numpy as np
peer, path = sys.argv[1], sys.argv[2]
if peer == "pink":
    import pink, pinocchio as pin
else:
    import mink, mujoco
t1 = time.perf_counter()
q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
if peer == "pink":
    model = pin.buildModelFromUrdf(path)
    conf = pink.Configuration(model, model.createData(), q)
    hand = pink.tasks.FrameTask("panda_hand", position_cost=1.0, orientation_cost=1.0)
    posture = pink.tasks.PostureTask(cost=0.1, gain=0.01)
    hand.set_target_from_configuration(conf)
    posture.set_target(q)
    solve = lambda: pink.solve_ik(conf, [hand, posture], 0.01, solver="daqp", safety_break=False)
else:
    model = mujoco.MjModel.from_binary_path(path)
    conf = mink.Configuration(model)
    conf.update(q)
    hand = mink.FrameTask("panda_hand", "site", position_cost=1.0, orientation_cost=1.0)
    hand.set_target_from_configuration(conf)
    posture = mink.PostureTask(model, cost=0.1, gain=0.01)
    posture.set_target(q)
    solve = lambda: mink.solve_ik(conf, [hand, posture], 0.01, "daqp", limits=[mink.ConfigurationLimit(model)])
t2 = time.perf_counter()
solve()
t3 = time.perf_counter()
solve()
t4 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "setup_s": t2 - t1, "first_step_s": t3 - t2, "second_step_s": t4 - t3}))
"""


def _peer_model(peer: str, folder: Path) -> str:
    """What the peer's process loads (made here, so it imports nothing of redundik): pink the Panda URDF, mink a
    compiled MuJoCo model of it (``.mjb``, with the ``panda_hand`` site) written to ``folder``."""
    from redundik.kinematics.urdf import EXAMPLE_ROBOTS, example_robot_data_dir, load_example_robot

    urdf = example_robot_data_dir() / EXAMPLE_ROBOTS["panda"][0]
    if peer == "pink":
        return str(urdf)
    import mujoco

    from redundik.simulation.mujoco_model import mujoco_from_urdf

    path = folder / "panda.mjb"
    mujoco.mj_saveModel(mujoco_from_urdf(str(urdf), load_example_robot("panda"), ["panda_hand"]), str(path), None)
    return str(path)


def _user_env() -> dict[str, str]:
    """This process's environment as a user's shell has it: without ``REDUNDIK_COLD_START`` (benchmarks/__init__
    sets ``wait`` here; a user has the default) and without ``PYTHONDONTWRITEBYTECODE`` (set on this machine: every
    import of redundik then compiled its sources to bytecode again, some 0.1 s, which a ``pip install`` — it writes
    the bytecode — or an interpreter that may write it never pays after its first import)."""
    env = dict(os.environ)
    env.pop("REDUNDIK_COLD_START", None)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def compile_bytecode() -> None:
    """Write redundik's bytecode as ``pip install`` does (``compileall`` of the package), before the first run."""
    import redundik

    folder = str(Path(redundik.__file__).parent)
    command = [sys.executable, "-m", "compileall", "-q", folder]
    subprocess.run(command, env=_user_env(), capture_output=True, check=False)


def _run(script: str, arg: str, cache: Path | None, *extra: str) -> dict[str, Any]:
    """One fresh process: its JSON line plus ``process_s``; ``error`` instead when it failed."""
    env = _user_env()
    if cache is not None:
        env["NUMBA_CACHE_DIR"] = str(cache / "numba")
        env["XDG_CACHE_HOME"] = str(cache / "xdg")
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            [sys.executable, "-c", script, arg, *extra], capture_output=True, text=True, timeout=TIMEOUT, env=env
        )
    except subprocess.TimeoutExpired:
        return {"error": f"no answer within {TIMEOUT} s"}
    wall = time.perf_counter() - t0
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    if proc.returncode != 0 or not lines:
        return {"error": f"exit {proc.returncode}: {proc.stderr.strip()[-300:]}"}
    out: dict[str, Any] = json.loads(lines[-1])
    out["process_s"] = wall
    out["first_dq_s"] = out["import_s"] + out["setup_s"] + out["first_step_s"]
    return out


def _record(method: str, runs: dict[str, dict[str, Any]]) -> dict[str, Any]:
    rec: dict[str, Any] = {"robot": "cold_start", "method": method, "status": "ok"}
    errors = [f"{kind}: {r['error']}" for kind, r in runs.items() if "error" in r]
    if errors:
        rec["status"] = "failed: " + "; ".join(errors)
    for kind, r in runs.items():
        for key, value in r.items():
            if key != "error":
                rec[f"{kind}_{key}"] = value
    return rec


def run_cold_start(
    methods: Sequence[str], mode: str = "cold", peers: Sequence[str] = ("mink", "pink")
) -> list[dict[str, Any]]:
    """The ``cold_start`` records: per redundik method (``cold`` then ``warm`` on the same new cache folder, or
    ``warm`` only on the user's own cache when ``mode == "warm"``), then each installed peer once."""
    from redundik.peers._deps import available

    out: list[dict[str, Any]] = []
    compile_bytecode()
    for method in methods:
        if mode == "cold":
            with tempfile.TemporaryDirectory(prefix="redundik-cold-") as tmp:
                cold = _run(SCRIPT, method, Path(tmp))
                warm = _run(SCRIPT, method, Path(tmp))
            out.append(_record(method, {"cold": cold, "warm": warm}))
        else:
            out.append(_record(method, {"warm": _run(SCRIPT, method, None)}))
    for peer in peers:
        if available(peer) and (peer != "mink" or available("mujoco")):
            with tempfile.TemporaryDirectory(prefix="redundik-peer-") as tmp:
                run = _run(PEER_SCRIPT, peer, None, _peer_model(peer, Path(tmp)))
            rec = _record(peer, {"cold": run})
            if "error" not in run:  # nothing to compile: its only run is its cold and its warm start
                for key in ("first_dq_s", "first_step_s"):
                    rec[f"warm_{key}"] = run[key]
            out.append(rec)
    return out

"""The first q̇ of a fresh install and of a warm one, per resolver (issue 31: ≤ 3 s cold, ≤ 0.3 s warm).

Each measurement is a fresh interpreter: ``import redundik``, a 7-joint arm, a frame task on a circle with a posture
and a joint centering, and one step; "first q̇" is from the interpreter's first line to the step's q̇, "its step"
the ``step`` call alone, with the path it took. ``cold``: an empty kernel cache (``REDUNDIK_CACHE_DIR`` a new
temporary folder; the default background compilation). ``warm``: the same folder once a run has compiled it
(``redundik compile``'s job). ``wait``: the cold case with ``REDUNDIK_COLD_START=wait`` (the first step compiles in
the caller's thread: what a cold start cost before).

    python benchmarks/cold_start.py [--resolvers pinv wqp hqp] [--no-wait]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

_CODE = """
import time
t0 = time.perf_counter()
import json, numpy as np, redundik as rk
robot = rk.from_dh([rk.DHRow(str(k), a=0.3, alpha=np.pi / 2 if k % 2 else -np.pi / 2) for k in range(1, 8)])
q = np.full(robot.nq, 0.3)
task = rk.FrameTask("7", rk.Circle(0.02, np.pi, plane=("y", "z")), gain=5.0)
stack = rk.TaskStack([task, rk.PostureTask(gain=1.0)], [rk.GradientSubtask(rk.JointCentering(), gain=-1.0)])
robot.update(q)
stack.reset(robot)
res = rk.make_resolver(NAME)
t1 = time.perf_counter()
r = res.step(robot, stack, q, 0.0, 0.01)
first = time.perf_counter() - t0
step = time.perf_counter() - t1
ok = bool(np.isfinite(r.dq).all())
print(json.dumps({"first": first, "step": step, "path": r.info["path"], "finite": ok}))
if COMPILE:
    rk.warm_up([NAME])
"""


def first_step(name: str, cache: str, mode: str, compile_after: bool) -> dict[str, object]:
    """One fresh interpreter's first step of ``name`` with the kernel cache ``cache``."""
    env = {**os.environ, "REDUNDIK_CACHE_DIR": cache, "REDUNDIK_COLD_START": mode}
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # (a user's interpreter keeps redundik's bytecode: see main)
    code = _CODE.replace("NAME", repr(name)).replace("COMPILE", repr(compile_after))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--resolvers", nargs="+", default=["pinv", "wqp", "hqp"])
    ap.add_argument("--no-wait", action="store_true", help="skip the blocking (pre-issue) cold measurement")
    args = ap.parse_args()
    # redundik's bytecode written first, as ``pip install`` writes it (this machine sets PYTHONDONTWRITEBYTECODE:
    # otherwise every fresh interpreter compiles redundik's sources again, some 0.1 s a user does not pay)
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    package = os.path.dirname(__import__("redundik").__file__)
    subprocess.run([sys.executable, "-m", "compileall", "-q", package], env=env, capture_output=True, check=False)
    print(f"{'resolver':8s} {'case':6s} {'first q̇ [s]':>12s} {'its step [s]':>12s}  path")
    for name in args.resolvers:
        with tempfile.TemporaryDirectory() as cache:
            cold = first_step(name, cache, "background", True)  # then compiles, in the same process: warm next
            warm = first_step(name, cache, "background", False)
        rows = [("cold", cold), ("warm", warm)]
        if not args.no_wait:
            with tempfile.TemporaryDirectory() as cache:
                rows.append(("wait", first_step(name, cache, "wait", False)))
        for case, got in rows:
            flag = "" if got["finite"] else "  NON-FINITE"
            print(f"{name:8s} {case:6s} {got['first']:12.3f} {got['step']:12.3f}  {got['path']}{flag}", flush=True)


if __name__ == "__main__":
    main()

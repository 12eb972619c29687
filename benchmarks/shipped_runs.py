"""Every run of the shipped task files (``tasks/*.yaml``) as a user runs it (issue 31 item 3): the path its steps take
(``result.info["path"]``, the members written from Python) and the cost of a step on that path against the same run
with the compiled step switched off (``resolver.fuse = False``: every member's Python ``evaluate`` / ``gradient``,
then the solve) — two copies of each run stepped in the same process, chunk by chunk in turn, on the compiled copy's
configurations. Medians and p90 per run; ``ratio`` = compiled median / interpreted median.

Run: ``python benchmarks/shipped_runs.py [--steps N] [--json FILE] [--only NAME ...]``. One run's ratios; the machine
is shared: report the spread of several runs.
"""

from __future__ import annotations

import os

os.environ.setdefault("REDUNDIK_COLD_START", "wait")  # (timed after untimed warm-up steps)

import argparse
import gc
import json
import logging
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from redundik.config.loader import load_task

TASKS = Path(__file__).resolve().parents[1] / "tasks"
CHUNK = 25  # steps per copy before the other copy's turn


def _copies(path: Path, run: str) -> list[Any]:
    """Two fresh loads of ``run`` (robot, stack, resolver): the compiled one, then the one with ``fuse = False``."""
    out = []
    for fuse in (True, False):
        plan = load_task(path)
        item = plan.runs[run]
        if hasattr(item.resolver, "fuse"):
            item.resolver.fuse = fuse
        robot = plan.robot.model
        item.stack.reset(robot)
        out.append((robot, item.stack, item.resolver, item.q0.copy()))
    return out


def time_run(path: Path, run: str, steps: int, dt: float = 0.01) -> dict[str, Any]:
    """Median and p90 [µs] of a step of ``run`` on each path, and what the compiled copy's last step reported."""
    copies = _copies(path, run)
    if not hasattr(copies[0][2], "fuse"):
        return {"file": path.name, "run": run, "resolver": copies[0][2].name, "skipped": "no compiled step"}
    q = copies[0][3]
    times: list[list[float]] = [[], []]
    info: dict[str, Any] = {}
    k = 0
    gc.disable()
    try:
        while k < steps + 20:
            for c, (robot, stack, resolver, _) in enumerate(copies):
                qc = q.copy()
                for j in range(CHUNK):
                    t = (k + j) * dt
                    t0 = time.perf_counter()
                    res = resolver.step(robot, stack, qc, t, dt)
                    t1 = time.perf_counter()
                    if k + j >= 20:  # (the first steps plan and warm up)
                        times[c].append(t1 - t0)
                    qc = robot.integrate(qc, res.dq, dt)
                    if c == 0:
                        info = {"path": str(res.info["path"]), "interpreted": list(res.info["interpreted"])}
                if c == 0:
                    q_next = qc
            q = q_next
            k += CHUNK
    finally:
        gc.enable()
    med = [float(np.median(x)) * 1e6 for x in times]
    p90 = [float(np.percentile(x, 90)) * 1e6 for x in times]
    return {
        "file": path.name,
        "run": run,
        "resolver": copies[0][2].name,
        **info,
        "compiled_median_us": med[0],
        "compiled_p90_us": p90[0],
        "interpreted_median_us": med[1],
        "interpreted_p90_us": p90[1],
        "ratio": med[0] / med[1],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=300, help="timed steps per copy")
    parser.add_argument("--json", type=Path, help="write the rows as JSON here")
    parser.add_argument("--only", nargs="*", help="file stems to run (default: every tasks/*.yaml)")
    args = parser.parse_args()
    logging.disable(logging.WARNING)  # (the one-time "runs mixed" lines: the table says it)
    warnings.simplefilter("ignore")
    rows = []
    head = f"{'file':24s} {'run':26s} {'resolver':8s} {'path':9s}"
    print(f"{head} {'compiled µs':>12s} {'interp. µs':>11s} {'ratio':>6s}")
    for path in sorted(TASKS.glob("*.yaml")):
        if args.only and path.stem not in args.only:
            continue
        for run in load_task(path).runs:
            row = time_run(path, run, args.steps)
            rows.append(row)
            if "skipped" in row:
                print(f"{path.name:24s} {run:26s} {row['resolver']:8s} ({row['skipped']})")
                continue
            names = f"  Python: {', '.join(row['interpreted'])}" if row["interpreted"] else ""
            print(
                f"{path.name:24s} {run:26s} {row['resolver']:8s} {row['path']:9s} "
                f"{row['compiled_median_us']:12.1f} {row['interpreted_median_us']:11.1f} {row['ratio']:6.2f}{names}"
            )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()

"""A 2-D GIF of one planar run: computer project 1, the RPR arm in a corner (``tasks/rpr_corner.yaml``).

The run is simulated by the YAML layer (``redundik.config``); the drawing takes only the simulation log's frame
origins and plain options (links, walls, the traced frame): :func:`redundik.reporting.animate.animate_planar`.

Run: ``python examples/animate_planar.py [--task FILE] [--run NAME] [--out FILE.gif] [--wall x=-0.6 ...]``
(the ``cli`` extra). Without ``--out`` the GIF goes to a temporary folder and only its size is printed.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from redundik.config import load_task
from redundik.config.runner import run_task
from redundik.reporting.animate import animate_planar
from redundik.shipped import find_example

AXIS = {"x": 0, "y": 1, "z": 2}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="2-D GIF of a planar task run")
    parser.add_argument("--task", default=None, help="task file (default: the shipped rpr_corner)")
    parser.add_argument("--run", default="avoid_hqp")
    parser.add_argument("--out", default=None, help="output .gif (default: a temporary file)")
    parser.add_argument("--every", type=int, default=8, help="samples between two images")
    parser.add_argument("--wall", action="append", default=None, help="x=VALUE or y=VALUE (repeatable)")
    args = parser.parse_args(argv)
    task = Path(args.task) if args.task else find_example("rpr_corner")
    if task is None:
        raise SystemExit("the shipped task rpr_corner is missing: reinstall redundik")
    walls = []
    for w in args.wall if args.wall is not None else (["x=-0.6", "y=-0.4"] if args.task is None else []):
        axis, _, value = w.partition("=")
        walls.append((axis.strip(), float(value)))
    plan = load_task(task)
    log = run_task(plan, [args.run])[args.run].log
    axes = plan.draw.plane or ("x", "y")
    with tempfile.TemporaryDirectory() as tmp:
        out = animate_planar(
            log.frame_positions,
            plan.draw.segments,
            args.out or Path(tmp) / f"{plan.name}.gif",
            plane=(AXIS[axes[0]], AXIS[axes[1]]),
            every=args.every,
            walls=walls,
            trace=plan.draw.path_frame,
            title=f"{plan.name}: {args.run}",
        )
        size = out.stat().st_size
    print(f"{plan.name}/{args.run}: {log.t.shape[0]} samples, GIF of {size} bytes" + (f" in {out}" if args.out else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

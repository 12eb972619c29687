"""2-D animation (GIF) of a planar task run, e.g. computer project 1 (``tasks/rpr_corner.yaml``).

A plotting module: matplotlib (Agg) and Pillow are imported inside the functions. Usage::

    python -m redundik.robots.animate tasks/rpr_corner.yaml --run avoid_hqp --out rpr.gif --wall x=-0.6 --wall y=-0.4
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from redundik.errors import ConfigError


def animate_planar(
    frames: dict[str, np.ndarray],
    segments: Sequence[tuple[str, str]],
    path: str | Path,
    *,
    plane: tuple[int, int] = (0, 1),
    every: int = 5,
    fps: int = 20,
    walls: Sequence[tuple[str, float]] = (),
    trace: str | None = None,
    title: str = "",
) -> Path:
    """Write a GIF of the logged frame origins, one image every ``every`` samples.

    Args:
        frames: Frame name → origins, shape (N, 3) (``SimulationLog.frame_positions``).
        segments: Links to draw as (frame, frame) pairs.
        path: Output ``.gif``.
        plane: Indices of the two world axes drawn.
        every: Samples between two images (≥ 1).
        fps: Images per second.
        walls: Lines to draw, as ("x", value) for x = value or ("y", value).
        trace: Frame whose path is drawn as it goes (e.g. the tip).
        title: Figure title.

    Returns:
        The path written.

    Raises:
        ConfigError: unknown frame in ``segments``/``trace`` or ``every`` < 1.
    """
    from redundik._extras import require

    matplotlib = require("matplotlib", "plotting")

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    if every < 1:
        raise ConfigError(f"every must be ≥ 1, got {every}")
    for name in [f for s in segments for f in s] + ([trace] if trace else []):
        if name not in frames:
            raise ConfigError(f"frame '{name}' was not logged; logged: {sorted(frames)}")
    i, j = plane
    pts = np.concatenate([frames[f][:, [i, j]] for f in frames])
    lo, hi = pts.min(axis=0) - 0.2, pts.max(axis=0) + 0.2
    fig, ax = plt.subplots(figsize=(4, 4), dpi=72)
    ax.set_aspect("equal")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_title(title, fontsize=9)
    for axis, value in walls:
        if axis == "x":
            ax.axvline(value, color="0.3", lw=3)
        else:
            ax.axhline(value, color="0.3", lw=3)
    lines = [ax.plot([], [], "o-", lw=2, ms=3)[0] for _ in segments]
    path_line = ax.plot([], [], "-", lw=1, color="tab:red")[0]
    n = next(iter(frames.values())).shape[0]
    samples = list(range(0, n, every))

    def draw(k: int) -> list[Any]:
        for line, (a, b) in zip(lines, segments, strict=True):
            line.set_data([frames[a][k, i], frames[b][k, i]], [frames[a][k, j], frames[b][k, j]])
        if trace:
            path_line.set_data(frames[trace][: k + 1, i], frames[trace][: k + 1, j])
        return [*lines, path_line]

    from redundik.reporting.paths import safe_path

    anim = FuncAnimation(fig, draw, frames=samples, blit=True)
    out = safe_path(Path(path).parent, Path(path).name)
    anim.save(out, writer=PillowWriter(fps=fps))
    plt.close(fig)
    return out


def main(argv: list[str] | None = None) -> int:
    """Command line: run one run of a planar task file and animate it."""
    from redundik.config import load_task
    from redundik.config.runner import run_task

    parser = argparse.ArgumentParser(description="2-D GIF of a planar task run")
    parser.add_argument("task")
    parser.add_argument("--run", required=True)
    parser.add_argument("--out", default="animation.gif")
    parser.add_argument("--every", type=int, default=8)
    parser.add_argument("--wall", action="append", default=[], help="x=VALUE or y=VALUE (repeatable)")
    args = parser.parse_args(argv)
    plan = load_task(args.task)
    result = run_task(plan, [args.run])[args.run]
    walls = []
    for w in args.wall:
        axis, _, value = w.partition("=")
        walls.append((axis.strip(), float(value)))
    axes = plan.draw.plane or ("x", "y")
    idx = {"x": 0, "y": 1, "z": 2}
    animate_planar(
        result.log.frame_positions,
        plan.draw.segments,
        args.out,
        plane=(idx[axes[0]], idx[axes[1]]),
        every=args.every,
        walls=walls,
        trace=plan.draw.path_frame,
        title=f"{plan.name}: {args.run}",
    )
    print(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""2-D animation (GIF) of one planar run from its logged frame origins, e.g. computer project 1 (``rpr_corner``).

A plotting module: matplotlib (Agg) and Pillow are imported inside the function. It takes the simulation log's
``frame_positions`` and plain options (links, walls, traced frame), not a task file; ``examples/animate_planar.py``
runs ``tasks/rpr_corner.yaml`` and animates it. ``redundik run FILE --gif`` animates every run of a file side by side
(:mod:`redundik.reporting.gif`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from redundik.errors import ConfigError
from redundik.reporting.paths import safe_path


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

    anim = FuncAnimation(fig, draw, frames=samples, blit=True)
    out = safe_path(Path(path).parent, Path(path).name)
    anim.save(out, writer=PillowWriter(fps=fps))
    plt.close(fig)
    return out

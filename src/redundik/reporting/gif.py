"""``TASK.gif`` of ``redundik run FILE --gif``: every run's stick figure animated side by side (matplotlib + Pillow).

Like the PNG figures (:mod:`redundik.reporting.plots`) it takes the runs' simulation logs and plain options.

Planar robots are drawn in their plane, spatial ones in 3-D. Frame origins come from forward kinematics of the
logged configurations (so every segment of the drawing plan is available, logged or not); the desired paths of
the frame tasks are drawn dashed, the travelled path of each frame task grows as the run plays.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.reporting.plots import _AXIS, FigureOptions, Runs, _grid, _plane, _plt, frame_task_paths, logged_runs


def _origins(robot: RobotModel, q: np.ndarray, frames: list[str]) -> dict[str, np.ndarray]:
    out = {f: np.empty((q.shape[0], 3)) for f in frames}
    for k in range(q.shape[0]):
        robot.update(q[k])
        for f in frames:
            out[f][k] = robot.frame_position(f)
    return out


def write_gif(
    runs: Runs,
    robot: RobotModel,
    path: Path,
    options: FigureOptions | None = None,
    frames: int = 60,
    fps: int = 15,
) -> Path:
    """Write the animation of the logged runs to ``path`` (``frames`` images at ``fps``); returns it.

    Args:
        runs: The runs by name (:class:`~redundik.reporting.plots.LoggedRun` records or bare simulation logs).
        robot: The robot they ran (frame origins by forward kinematics of the logged q).
        path: Output ``.gif``.
        options: Title, links (``segments``) and plane, as for the PNG figures.
        frames: Number of images.
        fps: Images per second.
    """
    plt = _plt()
    from matplotlib.animation import FuncAnimation, PillowWriter

    results, options = logged_runs(runs), options or FigureOptions()
    segments = options.segments
    names = list(dict.fromkeys(f for s in segments for f in s))
    n = min(r.log.q.shape[0] for r in results.values())
    idx = np.unique(np.linspace(0, n - 1, min(frames, n)).round().astype(int))
    data = {name: _origins(robot, r.log.q[idx], names) for name, r in results.items()}
    paths = {name: frame_task_paths(robot, r) for name, r in results.items()}
    plane = _plane(options, results)
    ids = [0, 1, 2] if plane is None else [_AXIS[plane[0]], _AXIS[plane[1]]]
    rows, cols = _grid(len(results), 3)
    kw: dict[str, Any] = {} if plane is not None else {"subplot_kw": {"projection": "3d"}}
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 3.6 * rows), squeeze=False, **kw)
    pts = np.vstack([xyz for d in data.values() for xyz in d.values()])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    mid, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2, 1e-3) * 1.1
    unit = robot.length_unit
    artists: list[tuple[Any, list[Any], list[Any]]] = []
    for ax, name in zip(axes.flat, results, strict=False):
        for _, desired, _actual in paths[name]:
            ax.plot(*[desired[:, i] for i in ids], color="tab:green", ls="--", lw=1.0)
        links = [ax.plot(*([[0, 0]] * len(ids)), color="tab:blue", lw=2.5)[0] for _ in segments]
        trails = [ax.plot(*([[0]] * len(ids)), color="tab:orange", lw=1.5)[0] for _ in paths[name]]
        artists.append((ax, links, trails))
        label = results[name].label
        ax.set_title(f"{name} ({label})" if label else name, fontsize=10)
        for i, lim in zip(ids, ("set_xlim", "set_ylim", "set_zlim"), strict=False):
            getattr(ax, lim)(mid[i] - half, mid[i] + half)
        labels = plane if plane is not None else ("x", "y", "z")
        for lab, setter in zip(labels, ("set_xlabel", "set_ylabel", "set_zlabel"), strict=False):
            getattr(ax, setter)(f"{lab} [{unit}]", fontsize=8)
        if plane is not None:
            ax.set_aspect("equal")
            ax.grid(alpha=0.3)
    for ax in axes.flat[len(results) :]:
        ax.set_visible(False)
    title = fig.suptitle("", fontsize=11)
    t_all = next(iter(results.values())).log.t[idx]

    def draw(k: int) -> list[Any]:
        out: list[Any] = [title]
        for (_, links, trails), name in zip(artists, results, strict=True):
            d = data[name]
            for line, (a, b) in zip(links, segments, strict=True):
                xyz = np.vstack([d[a][k], d[b][k]])
                line.set_data(xyz[:, ids[0]], xyz[:, ids[1]])
                if plane is None:
                    line.set_3d_properties(xyz[:, 2])
                out.append(line)
            for line, (_, _, actual) in zip(trails, paths[name], strict=True):
                upto = actual[: 1 + (math.floor(idx[k] * (actual.shape[0] - 1) / max(n - 1, 1)))]
                line.set_data(upto[:, ids[0]], upto[:, ids[1]])
                if plane is None:
                    line.set_3d_properties(upto[:, 2])
                out.append(line)
        title.set_text(f"{options.title}   t = {t_all[k]:.2f} s")
        return out

    fig.tight_layout(rect=(0, 0, 1, 0.94))
    anim = FuncAnimation(fig, draw, frames=len(idx), blit=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    anim.save(str(path), writer=PillowWriter(fps=fps), dpi=72)
    plt.close(fig)
    return path

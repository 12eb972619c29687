"""Figures of parallel mechanisms (matplotlib with the Agg backend, imported only inside these functions).

They take the mechanism objects of :mod:`redundik.parallel` and their results; ``redundik parallel ...`` writes them.

* :func:`draw_stewart` — 3-D drawing of a Stewart pose (base, top disc, legs).
* :func:`animate_stewart` — GIF of a sequence of poses (PillowWriter).
* :func:`plot_joint_profiles` — the six joint profiles of computer project 2, book vs exact scheme.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from redundik.parallel import PathResult, StewartPlatform

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _pyplot() -> Any:
    from redundik._extras import require

    matplotlib = require("matplotlib", "plotting")

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _polygon(points: np.ndarray) -> np.ndarray:
    """Close a planar polygon, ordering the points by angle about their centroid."""
    c = points.mean(axis=0)
    order = np.argsort(np.arctan2(points[:, 1] - c[1], points[:, 0] - c[0]))
    return np.vstack([points[order], points[order][:1]])


def _stewart_artists(ax: Any, platform: StewartPlatform, p: ArrayLike, R: ArrayLike) -> None:
    legs = platform.inverse_kinematics(p, R)
    base = _polygon(platform.base_points)
    top = _polygon(platform.top_points @ np.asarray(R).T + np.asarray(p))
    ax.plot(base[:, 0], base[:, 1], base[:, 2], "k-", lw=2, label="base")
    ax.plot(top[:, 0], top[:, 1], top[:, 2], "b-", lw=2, label="top disc")
    for i, (b, t) in enumerate(zip(platform.leg_base, legs.top_world, strict=True)):
        ax.plot([b[0], t[0]], [b[1], t[1]], [b[2], t[2]], "r-", lw=1.5)
        mid = (b + t) / 2
        ax.text(mid[0], mid[1], mid[2], str(i + 1), fontsize=8)
    axis = np.asarray(R)[:, 2] * 0.3
    ax.quiver(*np.asarray(p), *axis, color="g", label="z6")


def _limits(ax: Any, points: np.ndarray) -> None:
    centre = (points.max(axis=0) + points.min(axis=0)) / 2
    half = float((points.max(axis=0) - points.min(axis=0)).max()) / 2 * 1.1 + 1e-9
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(min(0.0, centre[2] - half), centre[2] + half)


def draw_stewart(platform: StewartPlatform, p: ArrayLike, R: ArrayLike, out: str | Path | None = None) -> Figure:
    """3-D drawing of the platform at pose (p [length unit], R); saved to ``out`` (PNG) if given."""
    plt = _pyplot()
    fig = plt.figure(figsize=(6, 6))
    ax = fig.add_subplot(projection="3d")
    _stewart_artists(ax, platform, p, R)
    legs = platform.inverse_kinematics(p, R)
    _limits(ax, np.vstack([platform.base_points, legs.top_world]))
    ax.set_xlabel(f"x0 [{platform.unit}]")
    ax.set_ylabel(f"y0 [{platform.unit}]")
    ax.set_zlabel(f"z0 [{platform.unit}]")
    ax.set_title(f"{platform.kind} Stewart platform, legs " + ", ".join(f"{q:.3f}" for q in legs.lengths))
    ax.legend(loc="upper left", fontsize=8)
    if out is not None:
        fig.savefig(out, dpi=100)
    return fig


def animate_stewart(
    platform: StewartPlatform, poses: Sequence[tuple[ArrayLike, ArrayLike]], out: str | Path, fps: int = 10
) -> Path:
    """Write a GIF of the platform moving through ``poses`` [(p, R), ...] with matplotlib's PillowWriter."""
    plt = _pyplot()
    from matplotlib.animation import FuncAnimation, PillowWriter

    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")
    everything = np.vstack([platform.base_points] + [platform.inverse_kinematics(p, R).top_world for p, R in poses])

    def frame(k: int) -> list[Any]:
        ax.cla()
        _stewart_artists(ax, platform, *poses[k])
        _limits(ax, everything)
        ax.set_title(f"frame {k + 1}/{len(poses)}")
        return []

    anim = FuncAnimation(fig, frame, frames=len(poses), blit=False)
    out = Path(out)
    anim.save(out, writer=PillowWriter(fps=fps))
    plt.close(fig)
    return out


def plot_joint_profiles(result: PathResult, out: str | Path | None = None) -> Figure:
    """Six joint profiles (l1, l2, l3 [length unit]; θ4, θ5, θ6 [deg]) vs time, book lagged vs exact I-K."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 3, figsize=(12, 6), sharex=True)
    names = ["l1", "l2", "l3", "θ4 [deg]", "θ5 [deg]", "θ6 [deg]"]
    for k, ax in enumerate(axes.ravel()):
        scale = 1.0 if k < 3 else 180.0 / np.pi
        ax.plot(result.t, result.joints_book[:, k] * scale, "r--", label="book (lagged θ6)")
        ax.plot(result.t, result.joints_exact[:, k] * scale, "b-", label="exact (self-consistent)")
        ax.set_title(names[k])
        ax.grid(True, alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("3+3 hybrid arm, computer project 2: joint profiles")
    fig.tight_layout()
    if out is not None:
        fig.savefig(out, dpi=100)
    return fig

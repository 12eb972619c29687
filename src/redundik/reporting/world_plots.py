"""The collision world of a task run as PNG figures (``world.png``, ``arm_world.png``; matplotlib, Agg backend).

Left: the smallest signed distance over every candidate pair against time, one curve per run, with d = 0
(penetration below) and the runs' safety distances d_s. Right: a 3-D view of the obstacles at t = 0 (boxes,
spheres, capsules, cylinders, convex meshes as their vertices; planes as a patch), each run's logged frame path,
the closest pair's segment p₁ → p₂ every few samples (thin) and at the run's closest sample (thick, labelled with
the pair and its distance). Witness points are recomputed from the logged configurations with the
:class:`~redundik.collision.CollisionWorld` of the runs' collision subtasks (:func:`run_world`; at most
:data:`MAX_SAMPLES` samples per run). The safety distance's label sits beside the axes, not on the curves.

``arm_world.png``: per run, the arm (sticks between the joint origins) at the start, the end, the closest sample
and one more, among the obstacles, with each instant's closest pair p₁ → p₂ (dashed) and the closest one (thick).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import coal
import numpy as np

from redundik.collision import CollisionAvoidance, CollisionWorld
from redundik.kinematics.model import RobotModel
from redundik.reporting.plots import (
    FigureOptions,
    LoggedRun,
    Runs,
    _colors,
    _finish,
    _plt,
    frame_task_paths,
    logged_runs,
)
from redundik.reporting.styles import outside_right, run_style, same_as, with_note
from redundik.tasks.subtasks import BoundSubtask

#: Samples per run at which the witness points are recomputed.
MAX_SAMPLES = 300


def closest_segments(
    world: CollisionWorld, robot: Any, t: np.ndarray, q: np.ndarray, max_samples: int = MAX_SAMPLES
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """(sample indices, d [m], p₁, p₂ [m] (k, 3), pair names) of the closest pair at up to ``max_samples``
    samples of a logged run (every sample's distances are in the run's ``min_distance`` CSV series)."""
    n = q.shape[0]
    idx = np.unique(np.linspace(0, n - 1, min(n, max_samples)).round().astype(int))
    d, p1, p2, names = np.empty(idx.size), np.empty((idx.size, 3)), np.empty((idx.size, 3)), []
    for r, k in enumerate(idx.tolist()):
        robot.update(q[k])
        world.set_time(float(t[k]))
        dist = world.compute(robot)
        j = int(np.argmin(dist.d))
        d[r], p1[r], p2[r] = dist.d[j], dist.p1[j], dist.p2[j]
        names.append(world.pair_names[j])
    world.set_time(0.0)
    return idx, d, p1, p2, names


def _box_edges(half: np.ndarray, M: np.ndarray) -> list[np.ndarray]:
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    world = corners @ M[:3, :3].T + M[:3, 3]
    edges = []
    for a in range(8):
        for b in range(a + 1, 8):
            if bin(a ^ b).count("1") == 1:
                edges.append(world[[a, b]])
    return edges


def draw_obstacles(ax: Any, world: CollisionWorld) -> None:
    """Wireframes of ``world``'s obstacles at their current poses on a 3-D axis."""
    a = np.linspace(0, 2 * np.pi, 40)
    first = True
    for k, ob in enumerate(world.obstacles):
        M = world.geometry.geometryObjects[world.n_links + k].placement.homogeneous
        R, c = M[:3, :3], M[:3, 3]
        g = ob.shape
        style: dict[str, Any] = {"color": "tab:red", "alpha": 0.55, "lw": 0.8}
        label = {"label": "obstacles"} if first else {}
        first = False
        if isinstance(g, coal.Box):
            for i, e in enumerate(_box_edges(np.asarray(g.halfSide), M)):
                ax.plot(e[:, 0], e[:, 1], e[:, 2], **style, **(label if i == 0 else {}))
        elif isinstance(g, coal.Sphere):
            u, v = np.meshgrid(a[::3], np.linspace(0, np.pi, 8))
            r = float(g.radius)
            ax.plot_wireframe(
                c[0] + r * np.cos(u) * np.sin(v),
                c[1] + r * np.sin(u) * np.sin(v),
                c[2] + r * np.cos(v),
                **style,
                **label,
            )
        elif isinstance(g, (coal.Capsule, coal.Cylinder)):
            r, hl = float(g.radius), float(g.halfLength)
            ring = np.stack([r * np.cos(a), r * np.sin(a), np.zeros_like(a)], axis=1)
            for z in (-hl, hl):
                pts = (ring + np.array([0.0, 0.0, z])) @ R.T + c
                ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], **style)
            for ang in np.linspace(0, 2 * np.pi, 4, endpoint=False):
                side = np.array([[r * np.cos(ang), r * np.sin(ang), -hl], [r * np.cos(ang), r * np.sin(ang), hl]])
                side = side @ R.T + c
                ax.plot(side[:, 0], side[:, 1], side[:, 2], **style, **(label if ang == 0 else {}))
        elif isinstance(g, coal.Halfspace):
            s = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]]) * 0.4
            pts = np.column_stack([s, np.zeros(5)]) @ R.T + c
            ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], **style, **label)
        else:  # a convex mesh: its vertices
            pts = np.asarray(getattr(g, "points", np.zeros((0, 3))), dtype=float).reshape(-1, 3)
            if pts.size:
                pts = pts @ R.T + c
                ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=2, color="tab:red", alpha=0.4, **label)


def _avoidance(r: LoggedRun) -> list[CollisionAvoidance]:
    subs = list(r.stack.subtasks) if r.stack is not None else []
    sources = [getattr(sub, "source", getattr(sub, "potential", None)) for sub in subs] + list(r.watched)
    return [p for p in sources if isinstance(p, CollisionAvoidance)]


def run_world(runs: dict[str, LoggedRun]) -> CollisionWorld | None:
    """The collision world of the runs' collision subtasks or watched collision potentials (the first), or ``None``."""
    for r in runs.values():
        for avoid in _avoidance(r):
            return avoid.world
    return None


def plot_world(runs: Runs, robot: RobotModel, path: Path, options: FigureOptions | None = None) -> Path | None:
    """Write ``world.png`` (module docstring); ``None`` without a collision world or a run."""
    fig = world_figure(runs, robot, options)
    if fig is None:
        return None
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    fig.savefig(path, dpi=110)
    _plt().close(fig)
    return path


def world_figure(runs: Runs, robot: RobotModel, options: FigureOptions | None = None) -> Any:
    """The figure of :func:`plot_world` (``None`` without a collision world or a run)."""
    results, options = logged_runs(runs), options or FigureOptions()
    world = run_world(results)
    if world is None or not world.n_pairs or not results:
        return None
    plt = _plt()
    fig = plt.figure(figsize=(14, 6))
    ax_d = fig.add_subplot(1, 2, 1)
    ax_3 = fig.add_subplot(1, 2, 2, projection="3d")
    world.set_time(0.0)
    draw_obstacles(ax_3, world)
    colors = _colors(len(results))
    safeties: set[float] = set()
    segments = {
        name: closest_segments(world, robot, np.asarray(r.log.t), np.asarray(r.log.q)) for name, r in results.items()
    }
    curves = []
    for name, r in results.items():
        t, dmin = np.asarray(r.log.t), r.series.get("min_distance")
        if dmin is not None and len(dmin) == len(t):
            curves.append((name, t, np.asarray(dmin)))
        else:
            idx, d = segments[name][0], segments[name][1]
            curves.append((name, t[idx], d))
    same = same_as(curves)
    for i, (name, r) in enumerate(results.items()):
        col = colors[i]
        t = np.asarray(r.log.t)
        idx, d, p1, p2, pairs = segments[name]
        _, tc, dc = curves[i]
        ax_d.plot(tc, dc, color=col, lw=1.6, label=with_note(name, name, same), **run_style(i, len(results), tc.size))
        for sub in r.stack.subtasks if r.stack is not None else []:
            src = getattr(sub, "source", None)
            if isinstance(src, CollisionAvoidance) and isinstance(sub, BoundSubtask):
                safeties.add(src.safety)
        for _frame, _desired, actual in frame_task_paths(robot, r):
            ax_3.plot(actual[:, 0], actual[:, 1], actual[:, 2], color=col, lw=1.2, alpha=0.8)
        for k in range(0, idx.size, max(1, idx.size // 25)):
            ax_3.plot(*np.stack([p1[k], p2[k]], axis=1), color=col, lw=0.6, alpha=0.35)
        k = int(np.argmin(d))
        ax_3.plot(
            *np.stack([p1[k], p2[k]], axis=1),
            color=col,
            lw=3,
            marker="o",
            ms=4,
            label=f"{name}: {pairs[k]} {d[k] * 1e3:.1f} mm at t = {t[idx[k]]:.2f} s",
        )
        ax_d.plot(t[idx[k]], d[k], "o", color=col, ms=5)
    unit = robot.length_unit
    ax_d.axhline(0.0, color="k", lw=0.8)
    outside_right(ax_d, 0.0, "d = 0", color="k")
    for ds in sorted(safeties):
        ax_d.axhline(ds, color="grey", lw=0.8, ls="--", label=f"safety distance d_s = {ds:g} {unit}")
        outside_right(ax_d, ds, f"d_s = {ds:g} {unit}")  # beside the axes, not on the curves
    ax_d.set_xlabel("t [s]")
    ax_d.set_ylabel(f"smallest signed distance [{unit}] (< 0: penetration)")
    ax_d.set_title("closest pair's distance over time")
    ax_d.grid(alpha=0.3)
    ax_d.legend(fontsize=8)
    spans = [np.ptp(lim) for lim in (ax_3.get_xlim(), ax_3.get_ylim(), ax_3.get_zlim())]
    ax_3.set_box_aspect(spans)  # metres alike on the three axes
    ax_3.set_xlabel(f"x [{unit}]")
    ax_3.set_ylabel(f"y [{unit}]")
    ax_3.set_zlabel(f"z [{unit}]")
    ax_3.set_title("obstacles, frame paths, closest-pair segments (thick: closest sample)")
    ax_3.legend(fontsize=7, loc="upper left")
    fig.suptitle(f"{options.title}: collision world", fontsize=12)
    return fig


# ---------------------------------------------------------------------------------------------------- the arm
def arm_points(robot: RobotModel, q: np.ndarray) -> list[np.ndarray]:
    """The arm as sticks at q: per joint, the segment from its parent joint's origin to its own [length unit] (2, 3)."""
    robot.update(q)
    model, data = robot.model, robot.data
    return [
        np.stack([data.oMi[int(model.parents[j])].translation, data.oMi[j].translation])
        for j in range(1, model.njoints)
    ]


def _instants(n: int, closest: int, count: int = 4) -> list[int]:
    """Up to ``count`` sample indices: the start, the end, the closest sample and evenly spread others."""
    picked = {0, n - 1, closest}
    for k in np.linspace(0, n - 1, count).round().astype(int).tolist():
        if len(picked) >= count:
            break
        if all(abs(k - p) > n // (2 * count) for p in picked):
            picked.add(int(k))
    return sorted(picked)


def plot_arm_world(runs: Runs, robot: RobotModel, path: Path, options: FigureOptions | None = None) -> Path | None:
    """Write ``arm_world.png``: per run the arm at a few instants among the obstacles, with each instant's closest
    pair (p₁ → p₂) and the closest one's distance; ``None`` without a collision world."""
    fig = arm_world_figure(runs, robot, options)
    return None if fig is None else _finish(fig, path)


def arm_world_figure(runs: Runs, robot: RobotModel, options: FigureOptions | None = None) -> Any:
    """The figure of :func:`plot_arm_world` (``None`` without a collision world or a run)."""
    results, options = logged_runs(runs), options or FigureOptions()
    world = run_world(results)
    if world is None or not world.n_pairs or not results:
        return None
    plt = _plt()
    n = len(results)
    cols = min(n, 2)
    rows = -(-n // cols)
    fig = plt.figure(figsize=(6.2 * cols, 5.6 * rows))
    unit = robot.length_unit
    cmap = plt.get_cmap("viridis")
    for i, (name, r) in enumerate(results.items()):
        ax = fig.add_subplot(rows, cols, i + 1, projection="3d")
        t, q = np.asarray(r.log.t), np.asarray(r.log.q)
        idx, d, p1, p2, pairs = closest_segments(world, robot, t, q)
        worst = int(np.argmin(d))
        samples = _instants(t.size, int(idx[worst]))
        world.set_time(float(t[idx[worst]]))
        draw_obstacles(ax, world)  # at the closest instant (moving obstacles)
        world.set_time(0.0)
        for j, k in enumerate(samples):
            col = cmap(0.9 * j / max(len(samples) - 1, 1))
            for m, seg in enumerate(arm_points(robot, q[k])):
                ax.plot(*seg.T, color=col, lw=2.2, marker="o", ms=3, label=f"t = {t[k]:.2f} s" if m == 0 else None)
            s = int(np.argmin(np.abs(idx - k)))
            ax.plot(*np.stack([p1[s], p2[s]], axis=1), color=col, lw=1.0, ls="--", marker=".", ms=5)
        ax.plot(
            *np.stack([p1[worst], p2[worst]], axis=1),
            color="k",
            lw=2.5,
            marker="o",
            ms=5,
            label=f"closest: {pairs[worst]} {d[worst]:.3g} {unit} (t = {t[idx[worst]]:.2f} s)",
        )
        spans = [max(np.ptp(lim), 1e-9) for lim in (ax.get_xlim(), ax.get_ylim(), ax.get_zlim())]
        ax.set_box_aspect(spans)
        ax.set_xlabel(f"x [{unit}]")
        ax.set_ylabel(f"y [{unit}]")
        ax.set_zlabel(f"z [{unit}]")
        ax.set_title(f"{name} ({r.label})" if r.label else name, fontsize=10)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(
        f"{options.title}: the arm among the obstacles (dashed: each instant's closest pair p₁ → p₂)", fontsize=12
    )
    return fig

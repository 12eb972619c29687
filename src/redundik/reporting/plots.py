"""PNG figures of a task run (matplotlib, Agg backend; imported only when figures are written).

* ``joints.png``: joint profiles q(t), one panel per joint, the runs overlaid;
* ``task_error.png``: main-task error norms (log scale), one panel per task;
* ``potentials.png``: subtask / watched potential / monitor values over time, with targets;
* ``world.png`` (tasks with a collision world, :mod:`redundik.reporting.world_plots`): obstacles, closest-pair
  segments and the smallest distance over time;
* ``arm_world.png`` (idem): the arm at a few instants among the obstacles, with each instant's closest pair;
* ``configurations.png``: the arm drawn every k samples with the tip path, one panel per run — the chapter's
  Figs. 5.7 and 5.8 for a planar arm (a 3-D stick drawing for spatial robots).

Every figure takes the runs as :class:`LoggedRun` records (a :class:`~redundik.simulation.SimulationLog` and the
task stack it ran; a bare log is accepted too), the robot and plain :class:`FigureOptions` — not a task file: a
control loop written in Python draws its logs the same way ``redundik run`` does.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.reporting.paths import safe_path
from redundik.reporting.styles import potential_unit, run_style, same_as, with_note
from redundik.simulation.loop import SimulationLog
from redundik.tasks.base import Potential
from redundik.tasks.stack import TaskStack
from redundik.tasks.subtasks import BoundSubtask, TargetSubtask

_AXIS = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class LoggedRun:
    """One run as the figures see it: its simulation log and the library objects it ran with.

    Attributes:
        log: The simulation log (t, q, task errors, potentials, frame origins).
        stack: The task stack it ran: its frame tasks give the desired paths and the split pose errors, its
            subtasks the kind, target and bounds drawn with each potential; ``None``: the log alone.
        label: Shown after the run's name in panel titles (e.g. the resolver name).
        watched: Potentials logged but not controlled (watched and monitors; clearances are drawn as obstacles).
        monitors: Names of the logged potentials that are monitors.
        torque_monitors: Names of the torque monitors τ = JᵀF whose ``m.NAME.max|mean|min`` are in ``series``.
        series: Extra per-sample series by name, shape (N,).
    """

    log: SimulationLog
    stack: TaskStack | None = None
    label: str = ""
    watched: Sequence[Potential] = ()
    monitors: frozenset[str] = frozenset()
    torque_monitors: Sequence[str] = ()
    series: Mapping[str, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True)
class FigureOptions:
    """Plain options of the figures (a task file's ``name`` and ``draw:`` entry, and its potentials' types).

    Attributes:
        title: Figure title prefix (the task name).
        segments: Links drawn in ``configurations.png``, as (frame, frame) pairs of logged frames; none: no drawing.
        plane: The two world axes of a planar drawing (``("x", "y")``); ``None``: found from the logged motion.
        every: Samples between two drawn configurations; ``None``: about 20 drawings.
        path_frame: Frame whose path is drawn (besides the frame tasks' paths).
        kinds: Type of each potential by name, shown in the panel titles (``"clearance"``).
    """

    title: str = "run"
    segments: Sequence[tuple[str, str]] = ()
    plane: tuple[str, str] | None = None
    every: int | None = None
    path_frame: str | None = None
    kinds: Mapping[str, str] = field(default_factory=dict)


#: Runs by name: :class:`LoggedRun` records or bare simulation logs.
Runs = Mapping[str, LoggedRun | SimulationLog]


def logged_runs(runs: Runs) -> dict[str, LoggedRun]:
    """The runs as :class:`LoggedRun` records (a bare log becomes one without a stack), in order."""
    return {name: r if isinstance(r, LoggedRun) else LoggedRun(r) for name, r in runs.items()}


def _subtasks(r: LoggedRun) -> list[Any]:
    return list(r.stack.subtasks) if r.stack is not None else []


def _plt() -> Any:
    from redundik._extras import require

    matplotlib = require("matplotlib", "plotting")

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _colors(n: int) -> list[Any]:
    plt = _plt()
    cmap = plt.get_cmap("tab10")
    return [cmap(i % 10) for i in range(n)]


def _lw(i: int, n: int) -> float:
    """Line width of run i of n: earlier runs thicker, so runs with identical curves all stay visible."""
    return 1.4 + 2.0 * (n - 1 - i) / max(n - 1, 1)


def _grid(n: int, max_cols: int = 3) -> tuple[int, int]:
    cols = min(n, max_cols)
    return math.ceil(n / cols), cols


def _finish(fig: Any, path: Path) -> Path:
    fig.tight_layout(rect=(0, 0, 1, 0.95))  # leave the suptitle its own band
    fig.savefig(path, dpi=110)
    _plt().close(fig)
    return path


def plot_joints(runs: Runs, robot: RobotModel, path: Path, options: FigureOptions | None = None) -> Path:
    """Joint profiles: q_j(t) in degrees (revolute) or the length unit (prismatic), runs overlaid."""
    return _finish(joints_figure(runs, robot, options), path)


def joints_figure(runs: Runs, robot: RobotModel, options: FigureOptions | None = None) -> Any:
    """The figure of :func:`plot_joints` (a matplotlib ``Figure``): each run its colour and marker, a run equal to
    an earlier one says so in the legend; limits near the motion are lines, limits far off are named in the title."""
    plt = _plt()
    results, options = logged_runs(runs), options or FigureOptions()
    joints = [j for j in robot.joints if j.idx_q >= 0]
    colors = _colors(len(results))
    shown = joints[:12]
    rows, cols = _grid(len(shown), 3 if len(shown) > 4 else len(shown))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 2.9 * rows), squeeze=False, sharex=True)
    n_runs = len(results)
    for ax, j in zip(axes.flat, shown, strict=False):
        revolute = j.kind == "revolute"
        lo, hi = np.inf, -np.inf
        curves = [(name, r.log.t, r.log.q[:, j.idx_q]) for name, r in results.items()]
        same = same_as(curves)
        for i, ((name, t, y), c) in enumerate(zip(curves, colors, strict=True)):
            y = np.degrees(y) if revolute else y
            lo, hi = min(lo, float(np.min(y))), max(hi, float(np.max(y)))
            ax.plot(t, y, color=c, label=with_note(name, name, same), lw=_lw(i, n_runs), **run_style(i, n_runs, t.size))
        pad = max(0.08 * (hi - lo), 1.0 if revolute else 1e-3)
        span = max(hi - lo, 10.0 if revolute else 0.05)
        far: list[str] = []
        unit = "deg" if revolute else robot.length_unit
        for lim, side in ((j.lower, "min"), (j.upper, "max")):
            if not (np.isfinite(lim) and abs(lim) < 1e9):
                continue
            v = float(np.degrees(lim)) if revolute else float(lim)
            if lo - span <= v <= hi + span:  # near the motion: draw the limit line, widening the axis to it
                first = not any(ln.get_label() == "joint limit" for ln in ax.get_lines())
                ax.axhline(v, color="tab:red", ls="--", lw=1.2, label="joint limit" if first else None)
                lo, hi = min(lo, v), max(hi, v)
            else:  # far away: drawing it would flatten the motion, so name it
                far.append(f"{side} {v:.4g}")
        ax.set_ylim(lo - pad, hi + pad)
        far_text = f"\nlimits off the axis: {', '.join(far)} {unit}" if far else ""  # in the title, not on the data
        ax.set_title(f"joint {j.name}{far_text}", fontsize=10 if not far else 9)
        ax.set_ylabel(f"{'θ' if revolute else 'd'} [{unit}]")
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(shown) :]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    axes.flat[0].legend(fontsize=8)
    more = f" (first 12 of {len(joints)})" if len(joints) > 12 else ""
    fig.suptitle(f"{options.title}: joint profiles{more}", fontsize=12)
    return fig


def plot_task_errors(runs: Runs, robot: RobotModel, path: Path, options: FigureOptions | None = None) -> Path:
    """Main-task errors on a log scale, runs overlaid: one panel per task and unit (a pose task gets a position
    panel [length unit] and an orientation panel [rad], recomputed from the logged q), so no axis mixes units."""
    return _finish(task_errors_figure(runs, robot, options), path)


def task_errors_figure(runs: Runs, robot: RobotModel, options: FigureOptions | None = None) -> Any:
    """The figure of :func:`plot_task_errors`; runs as in :func:`joints_figure`."""
    plt = _plt()
    results, options = logged_runs(runs), options or FigureOptions()
    unit = robot.length_unit
    panels: dict[str, tuple[str, str]] = {}  # key → (title, y label)
    curves: dict[str, list[tuple[str, np.ndarray, np.ndarray]]] = {}
    for name, r in results.items():
        split = split_task_errors(robot, r)
        for tname, e in r.log.task_errors.items():
            parts = split.get(tname)
            if parts is None:
                key = tname
                panels.setdefault(key, (f"task '{tname}': ‖e‖", "‖e‖"))
                curves.setdefault(key, []).append((name, r.log.t, e))
                continue
            pos, rot = parts
            if pos is not None:
                key = f"{tname}/position"
                panels.setdefault(key, (f"task '{tname}': position error ‖p_d − p‖", f"‖e_p‖ [{unit}]"))
                curves.setdefault(key, []).append((name, r.log.t, pos))
            if rot is not None:
                key = f"{tname}/orientation"
                panels.setdefault(key, (f"task '{tname}': orientation error ‖log(R_d Rᵀ)‖", "‖e_R‖ [rad]"))
                curves.setdefault(key, []).append((name, r.log.t, rot))
    if not panels:
        panels["(none)"] = ("no main task", "‖e‖")
        curves["(none)"] = []
    colors = dict(zip(results, _colors(len(results)), strict=True))
    index = {name: i for i, name in enumerate(results)}
    rows, cols = _grid(len(panels), 2)
    fig, axes = plt.subplots(rows, cols, figsize=(6.0 * cols, 3.4 * rows), squeeze=False)
    for ax, (key, (title, ylabel)) in zip(axes.flat, panels.items(), strict=False):
        same = same_as(curves[key])
        for i, (name, t, e) in enumerate(curves[key]):
            y = np.array(e, dtype=float)
            y[y <= 0] = np.nan  # log scale: exact zeros (t = 0) are not drawn
            label = with_note(f"{name} (max {np.nanmax(e) if np.any(np.isfinite(y)) else 0.0:.2g})", name, same)
            style = run_style(index[name], len(results), t.size)
            ax.semilogy(t, y, color=colors[name], label=label, lw=_lw(i, len(results)), **style)
        peak = max((float(np.nanmax(e)) for _, _, e in curves[key] if np.any(np.asarray(e) > 0)), default=0.0)
        if peak > 0:  # the exact start (e ≈ 1e-16) would stretch the log axis over 12 decades
            ax.set_ylim(bottom=peak * 1e-5)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("t [s]")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3, which="both")
        if curves[key]:
            ax.legend(fontsize=8)
    for ax in axes.flat[len(panels) :]:
        ax.set_visible(False)
    fig.suptitle(f"{options.title}: main-task error", fontsize=12)
    return fig


def split_task_errors(
    robot: RobotModel, r: LoggedRun | SimulationLog
) -> dict[str, tuple[np.ndarray | None, np.ndarray | None]]:
    """Per frame task that mixes position and orientation rows: (position error norm, orientation error norm)
    at every sample, recomputed from the logged q and the task's reference; other tasks are left out."""
    from redundik.tasks.frame import FrameTask

    r = r if isinstance(r, LoggedRun) else LoggedRun(r)
    tasks = [t for t in (r.stack.tasks if r.stack is not None else []) if isinstance(t, FrameTask)]
    tasks = [t for t in tasks if any(a.startswith("r") for a in t.axes) and any(not a.startswith("r") for a in t.axes)]
    if not tasks:
        return {}
    import pinocchio as pin

    out: dict[str, tuple[np.ndarray | None, np.ndarray | None]] = {}
    model = robot
    model.update(r.log.q[0])
    for t in tasks:
        t.reset(model)
    pos = {t.name: np.empty(r.log.t.shape[0]) for t in tasks}
    rot = {t.name: np.empty(r.log.t.shape[0]) for t in tasks}
    for k, tk in enumerate(r.log.t):
        model.update(r.log.q[k])
        for t in tasks:
            pose = model.frame_pose(t.frame)
            p_d, R_d, _ = t.trajectory.reference(float(tk))
            e = np.concatenate([p_d - pose.translation, pin.log3(R_d @ pose.rotation.T)])
            rows_p = [i for i in t.rows if i < 3]
            rows_r = [i for i in t.rows if i >= 3]
            pos[t.name][k] = float(np.linalg.norm(e[rows_p]))
            rot[t.name][k] = float(np.linalg.norm(e[rows_r]))
    for t in tasks:
        out[t.name] = (pos[t.name], rot[t.name])
    return out


def plot_potentials(
    runs: Runs, path: Path, options: FigureOptions | None = None, robot: RobotModel | None = None
) -> Path | None:
    """Potential and monitor values over time, runs overlaid; controlled subtasks solid, watched ones dashed.

    ``robot`` gives the length unit and joint kinds of the values' units (metres and both joint kinds without it).
    """
    fig = potentials_figure(runs, options, robot)
    return None if fig is None else _finish(fig, path)


def _potential_of(results: Mapping[str, LoggedRun], pname: str) -> Any:
    """The potential object logged as ``pname`` (a subtask's, a watched one or a monitor), or ``None``."""
    for r in results.values():
        for sub in _subtasks(r):
            if sub.name == pname:
                return getattr(sub, "potential", getattr(sub, "source", None))
        for pot in r.watched:
            if getattr(pot, "name", None) == pname:
                return pot
    return None


def _bounds(ax: Any, sub: Any, name: str, color: Any, unit: str) -> None:
    """A target or bound subtask's target / bounds as labelled dotted lines (in the legend, off the curves)."""
    if isinstance(sub, TargetSubtask):
        ax.axhline(sub.target, color=color, ls=":", lw=1.2, label=f"{name}: target p_d = {sub.target:g} {unit}")
    if isinstance(sub, BoundSubtask):
        safety = getattr(sub.source, "safety", None)  # a collision damper bounds each pair's distance, not p
        if sub.lower is None and sub.upper is None and safety is not None:
            ax.plot([], [], " ", label=f"{name}: bound d ≥ d_s = {safety:g} on each pair (world.png)")
        for bound, side in ((sub.lower, "lower"), (sub.upper, "upper")):
            if bound is not None:
                ax.axhline(bound, color=color, ls=(0, (1, 1.5)), lw=1.4, label=f"{name}: {side} bound {bound:g} {unit}")


def potentials_figure(runs: Runs, options: FigureOptions | None = None, robot: RobotModel | None = None) -> Any:
    """The figure of :func:`plot_potentials` (``None`` without a potential): y axes in the potential's unit,
    targets and bounds drawn and in the legend, each run its colour and marker, equal runs noted."""
    plt = _plt()
    results, options = logged_runs(runs), options or FigureOptions()
    series: list[str] = []
    for r in results.values():
        series += [k for k in r.log.potentials if k not in series]
    torque_names: list[str] = []
    for r in results.values():
        torque_names += [m for m in r.torque_monitors if m not in torque_names]
    panels = series + torque_names
    if not panels:
        return None
    colors = _colors(len(results))
    rows, cols = _grid(len(panels), 2)
    fig, axes = plt.subplots(rows, cols, figsize=(6.4 * cols, 3.6 * rows), squeeze=False)
    n = len(results)
    for ax, pname in zip(axes.flat, panels, strict=False):
        kind = options.kinds.get(pname, "")
        monitor = any(pname in r.monitors for r in results.values())
        unit = potential_unit(_potential_of(results, pname), robot)
        same = same_as(
            [(name, r.log.t, r.log.potentials[pname]) for name, r in results.items() if pname in r.log.potentials]
        )
        for i, ((name, r), c) in enumerate(zip(results.items(), colors, strict=True)):
            if pname in r.log.potentials:
                sub = next((s for s in _subtasks(r) if s.name == pname), None)
                style = "-" if sub is not None or monitor else "--"
                label = name if monitor else f"{name} (not controlled)" if sub is None else f"{name} ({sub.kind})"
                t, p = r.log.t, r.log.potentials[pname]
                marks = run_style(i, n, t.size)
                ax.plot(t, p, color=c, ls=style, label=with_note(label, name, same), lw=_lw(i, n), **marks)
                if isinstance(sub, TargetSubtask):
                    ideal = sub.target + (p[0] - sub.target) * np.exp(-sub.rate * (t - t[0]))
                    ax.plot(
                        t, ideal, color="k", ls=":", lw=1.2, label=f"{name}: p_d + (p₀ − p_d)e^(−Kt), K = {sub.rate:g}"
                    )
                _bounds(ax, sub, name, c, unit)
            elif pname in torque_names and f"m.{pname}.max" in r.series:
                for stat, ls in (("max", "-"), ("mean", "--"), ("min", ":")):
                    ax.plot(r.log.t, r.series[f"m.{pname}.{stat}"], color=c, ls=ls, label=f"{name}: {stat} |τ|")
        role = "monitor" if monitor else "potential"
        ylabel = f"p [{unit}]"
        if pname in torque_names:
            role, kind, ylabel = "monitor", "torques τ = JᵀF", "|τ| [N·m; N for prismatic joints]"
        ax.set_title(f"{role} '{pname}' ({kind})", fontsize=10)
        ax.set_xlabel("t [s]")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for ax in axes.flat[len(panels) :]:
        ax.set_visible(False)
    fig.suptitle(f"{options.title}: subtask potentials and monitors", fontsize=12)
    return fig


def _desired_path(r: LoggedRun, frame: str | None) -> np.ndarray | None:
    if frame is None or r.stack is None:
        return None
    for task in r.stack.tasks:
        traj = getattr(task, "trajectory", None)
        if getattr(task, "frame", None) == frame and traj is not None:
            try:
                return np.array([traj.sample(float(t))[0].translation for t in r.log.t])
            except Exception:  # a trajectory that was never started: no reference to draw
                return None
    return None


def _plane(options: FigureOptions, results: Mapping[str, LoggedRun]) -> tuple[str, str] | None:
    if options.plane is not None:
        return options.plane
    pts = [xyz for r in results.values() for xyz in r.log.frame_positions.values()]
    if not pts:
        return None
    allp = np.vstack(pts)
    span = allp.max(axis=0) - allp.min(axis=0)
    scale = max(float(span.max()), 1e-9)
    flat = [a for a in "xyz" if span[_AXIS[a]] < 1e-9 * scale]
    if not flat:
        return None
    rest = [a for a in "xyz" if a != flat[-1]]
    return rest[0], rest[1]


def frame_task_paths(robot: RobotModel, r: LoggedRun) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(frame, desired positions, actual positions) of every frame task of a run, from the logged q (≤ 1500 points)."""
    from redundik.viewer.html import stack_paths

    if r.stack is None:
        return []
    return [(p.frame, p.desired, p.actual) for p in stack_paths(robot, r.stack, r.log.t, r.log.q)]


def _draw_obstacles(ax: Any, r: LoggedRun, ids: list[int], spatial: bool, zspan: tuple[float, float]) -> None:
    """Round obstacles of the run's clearance potentials: circles (posts) in a plane, wire spheres / posts in 3-D
    (a post over ``zspan`` [length unit], the drawing's height: its distance ignores z)."""
    from redundik.viewer.html import clearance_obstacles

    potentials = [getattr(s, "potential", None) for s in _subtasks(r)] + list(r.watched)
    for k, ob in enumerate(clearance_obstacles(potentials)):
        label = "obstacle" if k == 0 else None
        c = ob.center
        a = np.linspace(0, 2 * np.pi, 60)
        if not spatial:
            ax.fill(
                c[ids[0]] + ob.radius * np.cos(a),
                c[ids[1]] + ob.radius * np.sin(a),
                color="tab:red",
                alpha=0.3,
                label=label,
            )
            continue
        if ob.vertical:
            for z in zspan:
                ax.plot(c[0] + ob.radius * np.cos(a), c[1] + ob.radius * np.sin(a), z, color="tab:red", alpha=0.5)
            ax.plot(
                [c[0], c[0]],
                [c[1], c[1]],
                list(zspan),
                color="tab:red",
                lw=3,
                alpha=0.5,
                label=label,
            )
        else:
            u, v = np.meshgrid(a[::4], np.linspace(0, np.pi, 8))
            ax.plot_wireframe(
                c[0] + ob.radius * np.cos(u) * np.sin(v),
                c[1] + ob.radius * np.sin(u) * np.sin(v),
                c[2] + ob.radius * np.cos(v),
                color="tab:red",
                alpha=0.4,
                lw=0.6,
                label=label,
            )


def plot_configurations(runs: Runs, robot: RobotModel, path: Path, options: FigureOptions | None = None) -> Path | None:
    """The arm every k samples (links between logged frame origins), the tip path and the desired path.

    One panel per run. Planar robots (or ``options.plane``) are drawn in that plane, others as 3-D sticks.
    """
    results, options = logged_runs(runs), options or FigureOptions()
    segments = options.segments
    if not segments:
        return None
    plt = _plt()
    plane = _plane(options, results)
    n_runs = len(results)
    rows, cols = _grid(n_runs, 2 if n_runs == 4 else 3)
    size = 5.0 if plane is not None else 5.5
    kw: dict[str, Any] = {} if plane is not None else {"subplot_kw": {"projection": "3d"}}
    fig, axes = plt.subplots(rows, cols, figsize=(size * cols, size * rows), squeeze=False, **kw)
    unit = robot.length_unit
    all_pts = np.vstack([xyz for r in results.values() for xyz in r.log.frame_positions.values()])
    lo, hi = all_pts.min(axis=0), all_pts.max(axis=0)
    for ax, (name, r) in zip(axes.flat, results.items(), strict=False):
        fp = r.log.frame_positions
        n = r.log.t.shape[0]
        every = options.every or max(1, math.ceil((n - 1) / 20))
        dt = float(r.log.t[1] - r.log.t[0]) if n > 1 else 0.0
        idx = list(range(0, n, every))
        if idx[-1] != n - 1:
            idx.append(n - 1)
        ids = [0, 1, 2] if plane is None else [_AXIS[plane[0]], _AXIS[plane[1]]]
        for k_i, k in enumerate(idx):
            first, last = k_i == 0, k == n - 1
            color = "tab:blue" if first else "tab:red" if last else "0.55"
            lw = 2.4 if first or last else 1.0
            alpha = 1.0 if first or last else 0.35 + 0.5 * k / max(n - 1, 1)
            for a, b in segments:
                pa, pb = fp[a][k], fp[b][k]
                coords = [[pa[i], pb[i]] for i in ids]
                ax.plot(*coords, color=color, lw=lw, alpha=alpha, solid_capstyle="round")
            joints = np.array([fp[f][k] for f in dict.fromkeys([s for seg in segments for s in seg])])
            ax.plot(*[joints[:, i] for i in ids], "o", color=color, ms=3.5 if (first or last) else 2, alpha=alpha)
        tip = options.path_frame
        task_paths = frame_task_paths(robot, r)
        drawn = {frame for frame, _, _ in task_paths}
        if tip is not None and tip in fp and tip not in drawn:
            ax.plot(*[fp[tip][:, i] for i in ids], color="tab:orange", lw=2.0, label=f"path of frame {tip}")
            ref = _desired_path(r, tip)
            if ref is not None:
                ax.plot(*[ref[:, i] for i in ids], color="k", ls="--", lw=1.0, label="desired path")
        for j, (frame, desired, actual) in enumerate(task_paths):
            first = j == 0
            ax.plot(*[actual[:, i] for i in ids], color="tab:orange", lw=2.0, label="actual paths" if first else None)
            ax.plot(*[desired[:, i] for i in ids], color="k", ls="--", lw=1.0, label="desired paths" if first else None)
            del frame
        _draw_obstacles(ax, r, ids, plane is None, (float(min(lo[2], 0.0)), float(hi[2])))
        ax.plot([], [], color="tab:blue", lw=2.4, label="t = 0")
        ax.plot([], [], color="tab:red", lw=2.4, label=f"t = {r.log.t[-1]:.3g} s")
        ax.plot([], [], color="0.55", lw=1.0, label=f"every {every * dt:.3g} s")
        ax.set_title(f"{name} ({r.label})" if r.label else name, fontsize=10)
        if plane is not None:
            ax.set_xlabel(f"{plane[0]} [{unit}]")
            ax.set_ylabel(f"{plane[1]} [{unit}]")
            ax.set_aspect("equal", adjustable="datalim")
            ax.grid(alpha=0.3)
        else:
            ax.set_xlabel(f"x [{unit}]")
            ax.set_ylabel(f"y [{unit}]")
            ax.set_zlabel(f"z [{unit}]")
            mid, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2, 1e-3)
            ax.set_xlim(mid[0] - half, mid[0] + half)
            ax.set_ylim(mid[1] - half, mid[1] + half)
            ax.set_zlim(mid[2] - half, mid[2] + half)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 4), fontsize=9, frameon=False)
    for ax in axes.flat[n_runs:]:
        ax.set_visible(False)
    fig.suptitle(f"{options.title}: configurations over time", fontsize=12)
    fig.tight_layout(rect=(0, 0.07, 1, 0.95))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_figures(runs: Runs, robot: RobotModel, out_dir: Path, options: FigureOptions | None = None) -> list[Path]:
    """Write every figure into ``out_dir``; returns the files written."""
    written = [
        plot_joints(runs, robot, safe_path(out_dir, "joints.png"), options),
        plot_task_errors(runs, robot, safe_path(out_dir, "task_error.png"), options),
        plot_potentials(runs, safe_path(out_dir, "potentials.png"), options, robot),
        plot_configurations(runs, robot, safe_path(out_dir, "configurations.png"), options),
    ]
    from redundik.reporting.world_plots import plot_arm_world, plot_world  # obstacles, closest pairs, the arm

    written.append(plot_world(runs, robot, safe_path(out_dir, "world.png"), options))
    written.append(plot_arm_world(runs, robot, safe_path(out_dir, "arm_world.png"), options))
    return [p for p in written if p is not None]

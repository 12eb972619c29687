"""Offline HTML replay of task runs: one self-contained file (data and a small WebGL renderer inline, no network).

The page embeds, as JSON, the robot's decimated visual meshes, each part's world pose at up to ``max_frames``
samples per run (computed here with Pinocchio), joint-limit proximity per part (drawn orange → red near a limit),
the desired and actual paths of every frame task, task-frame and target triads, round obstacles (clearance
potentials; a post stands from the floor to the top of the scene) and a task file's collision world
(:mod:`redundik.viewer.world`: its obstacles at their poses and sizes, the robot's collision shapes — shown with the
``capsules`` button — and per drawn sample the closest pair's witness segment and signed distance). It plays with a
time slider; several runs of one task file are switchable. URL parameters (query or hash): ``run=NAME``,
``t=SECONDS`` (that instant, paused), ``play=1``, ``speed=X``, ``az``/``el`` [deg], ``robot=0``, ``paths=0``,
``capsules=1``.
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Iterable, Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.viewer.scene import (
    MeshPart,
    Obstacle,
    PathSet,
    RunFrames,
    cylinder_mesh,
    robot_parts,
    sample_run,
    sphere_mesh,
    world_bounds,
)
from redundik.viewer.world import (
    OBSTACLE_COLOR,
    SHAPE_COLOR,
    WorldFrames,
    WorldShape,
    link_shapes,
    sample_world,
    world_obstacles,
)

if TYPE_CHECKING:
    from redundik.config.loader import RunPlan, TaskPlan
    from redundik.config.runner import RunResult
    from redundik.tasks.stack import TaskStack

_PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{title}</title>
<style>
html,body{{margin:0;height:100%;font:13px system-ui,sans-serif;color:#223;background:#f6f7f9}}
#bar{{position:absolute;left:0;right:0;top:0;height:34px;display:flex;gap:8px;align-items:center;padding:0 8px;
background:#fff;border-bottom:1px solid #dde}}
#slider{{flex:1}} #time{{white-space:nowrap}} #info{{color:#556;white-space:nowrap;overflow:hidden}}
#view{{position:absolute;top:35px;left:0;width:100%;height:calc(100% - 35px);display:block}}
#legend{{position:absolute;right:8px;bottom:8px;background:#ffffffd0;padding:4px 8px;border-radius:4px}}
.sw{{display:inline-block;width:18px;height:3px;vertical-align:middle;margin:0 4px 0 10px}}
</style></head>
<body data-status="loading">
<div id="bar"><b>{title}</b><select id="run" title="run"></select><button id="play">play</button>
<button id="capsules" title="show the robot's collision shapes" hidden>capsules</button>
<input type="range" id="slider" min="0" max="0" value="0"><span id="time"></span><span id="info"></span></div>
<canvas id="view"></canvas>
<div id="legend"><span class="sw" style="background:#1a9940"></span>desired path / target
<span class="sw" style="background:#2659e6"></span>actual path
<span class="sw" style="background:#f59a1f"></span><span class="sw" style="background:#e61f1a;margin-left:0"></span>
near a joint limit<span id="legend-world" hidden><span class="sw" style="background:#d9594d"></span>obstacles
<span class="sw" style="background:#c21fc2"></span>closest pair</span></div>
<script id="replay-data" type="application/json">{data}</script>
<script>{script}</script>
</body></html>
"""


def _b64(a: np.ndarray, dtype: str = "<f4") -> str:
    return base64.b64encode(np.ascontiguousarray(a, dtype=dtype).tobytes()).decode("ascii")


def _mesh_json(v: np.ndarray, t: np.ndarray) -> dict[str, Any]:
    wide = v.shape[0] >= 65536
    return {
        "vertices": _b64(v.reshape(-1)),
        "triangles": _b64(t.reshape(-1), "<u4" if wide else "<u2"),
        "index_type": "uint32" if wide else "uint16",
    }


def post_span(ob: Obstacle, low: float, high: float) -> tuple[float, float]:
    """The drawn z range [length unit] of a round obstacle: a post (distance in x–y only, its centre's z ignored by
    the clearance) stands from ``low`` (the floor) to ``high`` (the top of the scene); a sphere is its own."""
    if ob.vertical:
        return low, max(high, low + ob.height)
    z = float(ob.center[2])
    return z - ob.radius, z + ob.radius


def _obstacle_json(ob: Obstacle, low: float, high: float) -> dict[str, Any]:
    if ob.vertical:
        z0, z1 = post_span(ob, low, high)
        v, t = cylinder_mesh(ob.radius, z0, z1, sides=24)
        center = np.array([ob.center[0], ob.center[1], 0.0])
    else:
        v, t = sphere_mesh(ob.radius, rings=12, sides=24)
        center = np.asarray(ob.center, dtype=float)
    pose = np.hstack([np.eye(3), center.reshape(3, 1)])
    return {"name": ob.name, "color": list(OBSTACLE_COLOR), "pose": _b64(pose.reshape(-1)), **_mesh_json(v, t)}


def _shape_json(shape: WorldShape, color: tuple[float, float, float]) -> dict[str, Any]:
    pose = {} if shape.pose is None else {"pose": _b64(shape.pose[:3].reshape(-1))}
    return {
        "name": shape.name,
        "kind": shape.kind,
        "size": shape.size,
        "color": list(color),
        **pose,
        **_mesh_json(shape.vertices, shape.triangles),
    }


def _world_run_json(wf: WorldFrames) -> dict[str, Any]:
    finite = np.isfinite(wf.distance)
    return {
        "obstacle_poses": _b64(wf.obstacle_poses.reshape(-1)),
        "shape_poses": _b64(wf.shape_poses.reshape(-1)),
        "distance": [round(float(d), 9) if f else None for d, f in zip(wf.distance, finite, strict=True)],
        "p1": _b64(wf.p1.reshape(-1)),
        "p2": _b64(wf.p2.reshape(-1)),
        "pair": [int(k) for k in wf.pair],
    }


def _frame_matrices(robot: RobotModel, frame: str, q: np.ndarray) -> np.ndarray:
    out = np.empty((q.shape[0], 12))
    for k in range(q.shape[0]):
        robot.update(q[k])
        out[k] = robot.frame_pose(frame).homogeneous[:3].reshape(-1)
    return out


def replay_data(
    robot: RobotModel,
    parts: Sequence[MeshPart],
    runs: Sequence[RunFrames],
    *,
    title: str,
    obstacles: Sequence[Obstacle] = (),
    task_frames: Mapping[str, Sequence[tuple[str, np.ndarray, np.ndarray]]] | None = None,
    path_times: Mapping[str, np.ndarray] | None = None,
    world: tuple[Sequence[WorldShape], Sequence[WorldShape], Sequence[str]] | None = None,
    world_frames: Mapping[str, WorldFrames] | None = None,
) -> dict[str, Any]:
    """The JSON document the page plays.

    Args:
        robot: The robot (for frame poses).
        parts: Drawable parts (see :func:`redundik.viewer.scene.robot_parts`).
        runs: Sampled runs (see :func:`redundik.viewer.scene.sample_run`), with their paths filled in.
        title: Page title.
        obstacles: Round obstacles to draw.
        task_frames: Per run, (frame name, actual 3×4 poses (F, 12), desired 3×4 poses (F, 12)) at the drawn samples.
        path_times: Per run, the times [s] of the path samples, shape (N,).
        world: The collision world drawn: (obstacles, robot collision shapes, pair names), see
            :mod:`redundik.viewer.world`.
        world_frames: Per run, the world at the drawn samples (:func:`redundik.viewer.world.sample_world`).
    """
    center, radius = world_bounds(parts, runs)
    lows = [float(np.min(r.poses.reshape(*r.poses.shape[:2], 3, 4)[:, :, 2, 3])) for r in runs]  # (3×4: z of t)
    floor = min(0.0, *lows) if lows else 0.0
    step = float(10 ** np.floor(np.log10(radius / 2))) if radius > 0 else 0.1
    top = float(center[2]) + radius
    doc: dict[str, Any] = {
        "title": title,
        "length_unit": robot.length_unit,
        "view": {"center": [float(c) for c in center], "radius": radius, "floor": floor, "grid": step},
        "parts": [{"name": p.name, "color": list(p.color), **_mesh_json(p.vertices, p.triangles)} for p in parts],
        "obstacles": [_obstacle_json(o, floor, top) for o in obstacles],
        "world": None,
        "runs": [],
    }
    if world is not None:
        obs, shapes, pair_names = world
        doc["world"] = {
            "obstacles": [_shape_json(o, OBSTACLE_COLOR) for o in obs],
            "shapes": [_shape_json(sh, SHAPE_COLOR) for sh in shapes],
            "pair_names": list(pair_names),
        }
    for r in runs:
        frames = (task_frames or {}).get(r.name, [])
        pt = (path_times or {}).get(r.name, r.t)
        doc["runs"].append(
            {
                "name": r.name,
                "t": [round(float(x), 6) for x in r.t],
                "info": r.info,
                "poses": _b64(r.poses.reshape(-1)),
                "proximity": _b64(r.proximity.reshape(-1)),
                "path_t": [round(float(x), 6) for x in pt],
                "paths": [
                    {"name": p.name, "desired": _b64(p.desired.reshape(-1)), "actual": _b64(p.actual.reshape(-1))}
                    for p in r.paths
                ],
                "task_frames": [
                    {"name": n, "actual": _b64(a.reshape(-1)), "desired": _b64(d.reshape(-1))} for n, a, d in frames
                ],
                "world": _world_run_json(world_frames[r.name]) if world_frames and r.name in world_frames else None,
            }
        )
    return doc


def render_page(doc: Mapping[str, Any]) -> str:
    """The HTML text of a replay document (script and data inline)."""
    script = resources.files("redundik.viewer").joinpath("replay.js").read_text(encoding="utf-8")
    data = json.dumps(doc, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    return _PAGE.format(title=html.escape(str(doc.get("title", "redundik replay"))), data=data, script=script)


# ---------------------------------------------------------------------------------------------------- task runs
def _frame_tasks(stack: TaskStack) -> list[Any]:
    from redundik.tasks.frame import FrameTask

    return [t for t in stack.tasks if isinstance(t, FrameTask)]


def run_obstacles(run: RunPlan, length_scale: float = 1.0) -> list[Obstacle]:
    """Round obstacles of a run's clearance potentials (controlled, watched or monitored)."""
    pots = [getattr(s, "potential", None) for s in run.stack.subtasks] + list(run.watched) + list(run.monitors)
    return clearance_obstacles(pots, length_scale)


def clearance_obstacles(potentials: Iterable[Any], length_scale: float = 1.0) -> list[Obstacle]:
    """Round obstacles of the clearance potentials among ``potentials`` (others and ``None`` skipped), once each."""
    from redundik.tasks.potentials import Clearance

    out: list[Obstacle] = []
    for p in potentials:
        if not isinstance(p, Clearance) or p.name in {o.name for o in out}:
            continue
        vertical = set(p.axes) == {"x", "y"}  # distance in x-y only: an infinite post along z
        center = np.array(p.center, dtype=float)
        ob = Obstacle(p.name, center, max(p.radius, 0.01 * length_scale), vertical, 2.0 * length_scale)
        if not any(_same_place(ob, o) for o in out):  # a potential and its monitor on one post: drawn once
            out.append(ob)
    return out


def _same_place(a: Obstacle, b: Obstacle) -> bool:
    """Two round obstacles drawn alike (a post's centre z does not count)."""
    axes = slice(0, 2) if a.vertical else slice(0, 3)
    return a.vertical == b.vertical and a.radius == b.radius and bool(np.allclose(a.center[axes], b.center[axes]))


def run_paths(robot: RobotModel, run: RunPlan, t: np.ndarray, q: np.ndarray, max_points: int = 1500) -> list[PathSet]:
    """Desired (from the task's trajectory, anchored at q[0]) and actual positions of each frame task's frame."""
    return stack_paths(robot, run.stack, t, q, max_points)


def stack_paths(
    robot: RobotModel, stack: TaskStack, t: np.ndarray, q: np.ndarray, max_points: int = 1500
) -> list[PathSet]:
    """:func:`run_paths` of a task stack: the paths of its frame tasks over a logged run (≤ ``max_points`` each)."""
    tasks = _frame_tasks(stack)
    if not tasks:
        return []
    robot.update(q[0])
    for task in tasks:
        task.reset(robot)
    idx = np.unique(np.linspace(0, t.shape[0] - 1, min(t.shape[0], max_points)).round().astype(int))
    out = []
    for task in tasks:
        desired = np.array([task.trajectory.reference(float(t[i]))[0] for i in idx])
        actual = np.empty_like(desired)
        for k, i in enumerate(idx):
            robot.update(q[i])
            actual[k] = robot.frame_position(task.frame)
        out.append(PathSet(task.name, task.frame, desired, actual))
    return out


def _desired_matrices(run: RunPlan, t: np.ndarray) -> list[np.ndarray]:
    out = []
    for task in _frame_tasks(run.stack):
        mats = np.empty((t.shape[0], 12))
        for k, tk in enumerate(t):
            p, R, _ = task.trajectory.reference(float(tk))
            mats[k] = np.hstack([np.asarray(R), np.asarray(p).reshape(3, 1)]).reshape(-1)
        out.append(mats)
    return out


def build_task_replay(
    plan: TaskPlan,
    runs: Mapping[str, tuple[np.ndarray, np.ndarray, dict[str, Any]]],
    *,
    max_frames: int = 200,
    max_triangles: int = 2500,
) -> dict[str, Any]:
    """The replay document of several runs of one task file.

    Args:
        plan: The loaded task file.
        runs: By run name: (t [s] (N,), q (N, nq), info shown in the page).
        max_frames: Drawn samples per run (the paths keep up to 1500 points).
        max_triangles: Triangle budget per visual mesh.
    """
    robot = plan.robot.model
    parts = robot_parts(robot, plan.robot.urdf, plan.draw.segments, max_triangles)
    frames_list: list[RunFrames] = []
    task_frames: dict[str, list[tuple[str, np.ndarray, np.ndarray]]] = {}
    path_times: dict[str, np.ndarray] = {}
    obstacles: list[Obstacle] = []
    for name, (t, q, info) in runs.items():
        rp = plan.runs[name]
        rf = sample_run(robot, parts, name, t, q, max_frames)
        rf.paths = run_paths(robot, rp, t, q)
        rf.info = dict(info)
        n = t.shape[0]
        path_times[name] = t[np.unique(np.linspace(0, n - 1, min(n, 1500)).round().astype(int))]
        tasks = _frame_tasks(rp.stack)
        desired = _desired_matrices(rp, rf.t)
        task_frames[name] = [
            (tk.name, _frame_matrices(robot, tk.frame, rf.q), d) for tk, d in zip(tasks, desired, strict=True)
        ]
        for ob in run_obstacles(rp):
            if ob.name not in {o.name for o in obstacles} and not any(_same_place(ob, o) for o in obstacles):
                obstacles.append(ob)
        frames_list.append(rf)
    world, world_frames = _task_world(plan, frames_list, parts)
    return replay_data(
        robot,
        parts,
        frames_list,
        title=f"{plan.name} — {plan.robot.model.name}",
        obstacles=obstacles,
        task_frames=task_frames,
        path_times=path_times,
        world=world,
        world_frames=world_frames,
    )


def _task_world(
    plan: TaskPlan, runs: Sequence[RunFrames], parts: Sequence[MeshPart]
) -> tuple[tuple[list[WorldShape], list[WorldShape], list[str]] | None, dict[str, WorldFrames]]:
    """The task file's collision world for :func:`replay_data`, and its state at each run's drawn samples."""
    world = getattr(plan, "world", None)
    if world is None:
        return None, {}
    _, radius = world_bounds(parts, runs)
    obs = world_obstacles(world, extent=radius)
    shapes = link_shapes(world)
    robot = plan.robot.model
    frames = {r.name: sample_world(world, robot, r.t, r.q, [k for k, _ in obs], [g for g, _ in shapes]) for r in runs}
    return ([o for _, o in obs], [s for _, s in shapes], list(world.pair_names)), frames


def write_html(
    path: str | Path,
    plan: TaskPlan,
    results: Mapping[str, RunResult],
    *,
    max_frames: int = 200,
    max_triangles: int = 2500,
) -> Path:
    """Write the offline replay of a task file's runs to ``path`` (one self-contained HTML file); returns it.

    Args:
        path: Output file (``.html``); its folder is created.
        plan: The loaded task file.
        results: From :func:`redundik.config.runner.run_task`.
        max_frames: Drawn samples per run.
        max_triangles: Triangle budget per visual mesh.
    """
    runs = {
        name: (
            r.log.t,
            r.log.q,
            {
                "resolver": r.plan.resolver_name,
                "max task error": float(r.summary.get("max_task_error", r.log.max_task_error)),
                **({"plant": r.summary["plant"]} if "plant" in r.summary else {}),
            },
        )
        for name, r in results.items()
    }
    doc = build_task_replay(plan, runs, max_frames=max_frames, max_triangles=max_triangles)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(render_page(doc), encoding="utf-8")
    return out

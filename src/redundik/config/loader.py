"""Task files → a :class:`TaskPlan`: the robot, and for every run a ready task stack and resolver.

The whole file is checked before anything runs: shape (pydantic), then names and sizes against the robot, then
each run is assembled and its resolver's ``check`` called at q0. Any problem is a one-line
:class:`~redundik.errors.ConfigError` with the YAML key path.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from redundik import _coldstart
from redundik.config import world_types  # registers collision / balance YAML types (issue 12)
from redundik.config.builders import (
    MONITORS,
    POTENTIALS,
    TASKS,
    Context,
    TorqueMonitor,
    build_typed,
    check_frame,
    task_name,
)
from redundik.config.options import check_resolver_options
from redundik.config.robot import LoadedRobot, angle_scale, configuration_from_file, load_robot
from redundik.config.schema import MAX_STEPS, RunSpec, SubtaskSpec, TaskFileSpec
from redundik.config.yamlio import join_path, read_yaml, validate
from redundik.errors import ConfigError, RedundikError
from redundik.resolvers import RESOLVERS, Resolver, make_resolver
from redundik.resolvers.base import check_gains
from redundik.simulation.plant import PlantOptions
from redundik.tasks import BoundSubtask, GradientSubtask, Potential, Subtask, TargetSubtask, Task, TaskStack
from redundik.tasks.base import check_name


@dataclass
class RunPlan:
    """One run, ready to simulate.

    Attributes:
        name: Run name.
        description: Free text from the file.
        resolver_name: Registry name of the resolver.
        resolver: The resolver.
        stack: Main tasks and controlled subtasks.
        q0: Initial configuration [rad, length unit].
        watched: The file's other potentials, logged but not controlled in this run.
        monitors: Potentials under ``monitors:`` (logged only).
        torque_monitors: ``type: torques`` monitors.
        plant: The simulated robot driven by the run (``plant:`` of the run or the file), ``None``: kinematic.
    """

    name: str
    description: str
    resolver_name: str
    resolver: Resolver
    stack: TaskStack
    q0: np.ndarray
    watched: list[Potential] = field(default_factory=list)
    monitors: list[Potential] = field(default_factory=list)
    torque_monitors: list[TorqueMonitor] = field(default_factory=list)
    plant: PlantOptions | None = None
    integrator: str = "euler"
    rtol: float = 1e-10
    atol: float = 1e-12


#: Memory the logs of all runs of a file may need [bytes]: Σ (steps + 1) × columns × 8 (see docs/task-files.md).
MAX_LOG_BYTES = 512 * 1024 * 1024


@dataclass
class DrawPlan:
    """What the configuration figure draws.

    Attributes:
        segments: Links as (frame, frame) pairs.
        plane: Two world axes for a planar drawing, or ``None`` (decide from the data).
        every: Samples between drawn configurations, or ``None`` (about 12 per run).
        path_frame: Frame whose path is drawn (the first frame task's frame), or ``None``.
    """

    segments: list[tuple[str, str]]
    plane: tuple[str, str] | None = None
    every: int | None = None
    path_frame: str | None = None

    @property
    def frames(self) -> list[str]:
        """Every frame the drawing needs, in order of first appearance."""
        out: list[str] = []
        for a, b in self.segments:
            for f in (a, b):
                if f not in out:
                    out.append(f)
        if self.path_frame is not None and self.path_frame not in out:
            out.append(self.path_frame)
        return out


@dataclass
class TaskPlan:
    """A validated task file.

    Attributes:
        name: Task name (also the default output folder).
        description: Free text.
        path: The file, or ``None`` for an in-memory mapping.
        robot: The robot and what its config added.
        angle_unit: Unit of angle-valued entries of the task file.
        dt: Time step [s].
        steps: Number of steps.
        q0: Default initial configuration [rad, length unit].
        runs: The runs by name, in file order.
        potential_types: ``type`` of every potential and monitor by name.
        draw: The drawing plan.
        log_frames: Frames whose origins are logged at every sample.
    """

    name: str
    description: str
    path: Path | None
    robot: LoadedRobot
    angle_unit: str
    dt: float
    steps: int
    q0: np.ndarray
    runs: dict[str, RunPlan]
    potential_types: dict[str, str]
    draw: DrawPlan
    log_frames: list[str]
    world: Any = None  # the collision world (redundik.collision.CollisionWorld) of 'collision:'/'obstacles:'


def _refuse_other_kinds(data: dict[str, Any], path: Path) -> None:
    """A sweep file, robot config or mechanism config given where a task file is expected: say which it is."""
    from redundik.config.anyfile import detect_kind

    kind = detect_kind(data)
    if kind == "task":
        return
    command = {
        "sweep": f"run it with `redundik sweep {path}`",
        "robot": "a task file names it under 'robot:'",
        "mechanism": "use the `redundik stewart`, `hybrid33`, `delta` or `mobility` commands",
    }[kind]
    raise ConfigError(f"{path.name} is a {kind} file, not a task file: {command} (`redundik validate` checks any)")


def load_task(source: str | Path | dict[str, Any], base_dir: Path | None = None) -> TaskPlan:
    """Read, validate and assemble a task file (every run) without running it.

    Args:
        source: Path of a YAML task file, or its content as a mapping.
        base_dir: Folder relative paths are resolved from (the file's folder by default; cwd for a mapping).

    Raises:
        ConfigError: the first problem found, with its YAML key path.
    """
    with _coldstart.loading():  # (cold: the kernels' twins, nothing compiled in the caller's thread)
        return _load_task(source, base_dir)


def _load_task(source: str | Path | dict[str, Any], base_dir: Path | None) -> TaskPlan:
    """:func:`load_task`'s work."""
    if isinstance(source, dict):
        data, path = source, None
        base = base_dir or Path.cwd()
    else:
        path = Path(source)
        data = read_yaml(path, "task file")
        base = base_dir or path.resolve().parent
        _refuse_other_kinds(data, path)
    spec: TaskFileSpec = validate(TaskFileSpec, data)
    steps = _check_steps(spec)
    robot = load_robot(spec.robot, base, "robot")
    _check_integrators(spec, robot.model.nq, robot.model.nv)

    if spec.q0 is not None:
        q0 = configuration_from_file(spec.q0, robot.model, spec.angle_unit, "q0")
    elif robot.q0 is not None:
        q0 = robot.q0
    else:
        q0 = robot.model.neutral()
    world = None
    if spec.collision is not None or spec.obstacles:
        world = world_types.build_world(spec.collision, spec.obstacles, robot, q0, angle_scale(spec.angle_unit), base)
    ctx = Context(robot.model, spec.angle_unit, world)

    # every potential and monitor once, for names/sizes (runs build their own fresh objects)
    types: dict[str, str] = {}
    for name, raw in spec.potentials.items():
        _check_label(name, "potential", join_path("potentials", name))
        build_typed(POTENTIALS, raw, name, ctx, join_path("potentials", name), "potential")
        types[name] = str(raw["type"])
    for name, raw in spec.monitors.items():
        where = join_path("monitors", name)
        _check_label(name, "monitor", where)
        if name in spec.potentials:
            raise ConfigError(f"'{name}' is already a potential; give the monitor another name", where)
        _build_monitor(raw, name, ctx, where)
        types[name] = str(raw["type"])
    for i, f in enumerate(spec.log_frames):
        check_frame(ctx, f, join_path("log_frames", i))

    runs = {name: _build_run(spec, ctx, name, run, q0) for name, run in spec.runs.items()}
    _set_integrators(spec, runs)
    draw = _draw_plan(spec, robot, ctx, runs)
    log_frames = list(dict.fromkeys([*draw.frames, *spec.log_frames]))
    size_key = "steps" if spec.steps is not None else "duration"
    _check_log_memory(runs, steps, robot.model.nq, robot.model.nv, len(log_frames), size_key)
    return TaskPlan(
        name=spec.name,
        description=spec.description,
        path=path,
        robot=robot,
        angle_unit=spec.angle_unit,
        dt=spec.dt,
        steps=steps,
        q0=q0,
        runs=runs,
        potential_types=types,
        draw=draw,
        log_frames=log_frames,
        world=world,
    )


def _check_steps(spec: TaskFileSpec) -> int:
    """The number of steps, bounded by :data:`MAX_STEPS` (``duration / dt`` too)."""
    n = spec.n_steps
    if n > MAX_STEPS:
        raise ConfigError(
            f"duration / dt = {spec.duration:g} / {spec.dt:g} gives {n} steps; at most {MAX_STEPS} are allowed",
            "duration",
        )
    return n


def _check_integrators(spec: TaskFileSpec, nq: int, nv: int) -> None:
    """Runge-Kutta integrators need a vector-space configuration (nq = nv)."""
    for name, run in spec.runs.items():
        integrator = run.integrator or spec.integrator
        if integrator != "euler" and nq != nv:
            where = join_path("runs", name, "integrator") if run.integrator else "integrator"
            raise ConfigError(
                f"{integrator} needs a robot whose configuration is a vector space (nq = nv); this one has "
                f"nq = {nq}, nv = {nv} (a free-flyer base or continuous joints): use euler",
                where,
            )


def _set_integrators(spec: TaskFileSpec, runs: dict[str, RunPlan]) -> None:
    """Each run's integrator and tolerances: its own keys, else the file's."""
    for name, plan in runs.items():
        run = spec.runs[name]
        plan.integrator = run.integrator or spec.integrator
        plan.rtol = spec.rtol if run.rtol is None else run.rtol
        plan.atol = spec.atol if run.atol is None else run.atol


def _check_log_memory(runs: dict[str, RunPlan], steps: int, nq: int, nv: int, n_frames: int, key: str) -> None:
    """Refuse a file whose logs would need more than :data:`MAX_LOG_BYTES` (estimate: samples × columns × 8)."""
    total = 0
    for plan in runs.values():
        n_pot = len(plan.stack.subtasks) + len(plan.watched) + len(plan.monitors) + 3 * len(plan.torque_monitors)
        columns = 1 + nq + nv + len(plan.stack.tasks) + n_pot + 3 * n_frames + 16  # 16: per-step diagnostics
        total += (steps + 1) * columns * 8
    if total > MAX_LOG_BYTES:
        raise ConfigError(
            f"{steps} steps would need about {total / 2**20:.0f} MiB of logs for {len(runs)} run(s) "
            f"(at most {MAX_LOG_BYTES // 2**20} MiB): use fewer steps, a larger dt or fewer runs",
            key,
        )


def _build_monitor(raw: Any, name: str, ctx: Context, path: str) -> Potential | TorqueMonitor:
    kind = raw.get("type") if isinstance(raw, dict) else None
    if isinstance(kind, str) and kind in MONITORS:
        return build_typed(MONITORS, raw, name, ctx, path, "monitor")
    registry: dict[str, Any] = {**POTENTIALS, **MONITORS}
    return build_typed(registry, raw, name, ctx, path, "monitor")


def _build_tasks(raws: list[dict[str, Any]], ctx: Context, path: str, offset: int = 0) -> list[Task]:
    out = []
    for i, raw in enumerate(raws):
        name = task_name(raw, i + offset)
        out.append(build_typed(TASKS, raw, name, ctx, join_path(path, i), "main task"))
    return out


_KINDS = {"gradient": "gradient", "target": "target", "bound": "bound", "bounds": "bound"}


def _subtask(pot: Potential, sub: SubtaskSpec, path: str) -> Subtask:
    """A typed subtask from its YAML entry: ``kind`` (or the old ``mode``) if given, else inferred from the keys."""
    kind = sub.kind or (None if sub.mode is None else _KINDS[sub.mode])
    if kind is None:
        if sub.target is not None:
            kind = "target"
        elif sub.lower is not None or sub.upper is not None:
            kind = "bound"
        else:
            kind = "gradient"
    allowed = {
        "gradient": ("gain",),
        "target": ("target", "rate", "target_rate", "weight", "priority"),
        "bound": ("lower", "upper", "rate", "priority"),
    }[kind]
    given = [
        k
        for k in ("gain", "target", "rate", "target_rate", "lower", "upper", "weight", "priority")
        if getattr(sub, k) is not None
    ]
    extra = [k for k in given if k not in allowed]
    if extra:
        why = ""
        if kind == "gradient":
            why = (
                " (a gradient subtask z = kη has no weight or level of its own: its gain k sets its strength and it "
                "always lies in the null space of everything above, see docs/stack.md; remove the key)"
            )
        raise ConfigError(f"a {kind} subtask takes {', '.join(allowed)}; remove {', '.join(extra)}{why}", path)
    kwargs: dict[str, Any] = {k: getattr(sub, k) for k in given}
    try:
        if kind == "gradient":
            return GradientSubtask(pot, **kwargs)
        if kind == "target":
            if "target" not in kwargs:
                raise ConfigError("a target subtask needs 'target'", path)
            return TargetSubtask(pot, **kwargs)
        return BoundSubtask(pot, **kwargs)
    except RedundikError as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(str(exc).removeprefix(f"subtask '{pot.name}': "), path) from None


#: Most physics steps of a plant per control tick, and in one run: a tiny ``sim_dt`` would run for hours.
MAX_SUBSTEPS, MAX_PHYSICS_STEPS = 1000, 50_000_000


def _check_plant_rate(spec: TaskFileSpec, sim_dt: float, where: str) -> None:
    """``sim_dt`` must divide ``dt`` (checked here, at validation, as the plant checks it when built) and keep the
    physics steps bounded."""
    ratio = spec.dt / sim_dt
    substeps = round(ratio)
    at = join_path(where, "sim_dt")
    if substeps < 1 or abs(ratio - substeps) > 1e-6 * ratio:
        raise ConfigError(f"sim_dt = {sim_dt:g} s must divide the control dt = {spec.dt:g} s", at)
    if substeps > MAX_SUBSTEPS:
        raise ConfigError(
            f"sim_dt = {sim_dt:g} s gives {substeps} physics steps per control tick of {spec.dt:g} s; at most "
            f"{MAX_SUBSTEPS} are allowed",
            at,
        )
    total = substeps * spec.n_steps
    if total > MAX_PHYSICS_STEPS:
        raise ConfigError(
            f"{spec.n_steps} ticks × {substeps} physics steps = {total} MuJoCo steps; at most {MAX_PHYSICS_STEPS} "
            "are allowed (raise sim_dt or shorten the run)",
            at,
        )


def _check_label(name: str, what: str, path: str) -> None:
    """A potential or monitor name: it becomes a CSV column (``p.NAME``, ``m.NAME``), a key of summary.json and a
    subtask name, so it follows the library's name rule (:data:`redundik.tasks.base.NAME_PATTERN`)."""
    try:
        check_name(name, what)
    except RedundikError as exc:
        raise ConfigError(str(exc).removeprefix(f"{what}: "), path) from None


def _build_run(spec: TaskFileSpec, ctx: Context, name: str, run: RunSpec, q0_file: np.ndarray) -> RunPlan:
    path = join_path("runs", name)
    robot = ctx.robot
    # main tasks: the file's (or this run's replacement) plus extra ones
    if run.main is not None:
        tasks = _build_tasks(run.main, ctx, join_path(path, "main"))
    else:
        tasks = _build_tasks(spec.main, ctx, "main")
    tasks += _build_tasks(run.extra_main, ctx, join_path(path, "extra_main"), offset=len(tasks))
    names = [t.name for t in tasks]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ConfigError(f"main task names must be unique; repeated: {', '.join(dup)} (give each a 'name')", path)
    for key, overrides in (("gains", run.gains), ("weights", run.weights)):
        for tname, value in overrides.items():
            where = join_path(path, key, tname)
            if tname not in names:
                raise ConfigError(f"no main task named '{tname}'; main tasks: {', '.join(names) or '(none)'}", where)
            task = tasks[names.index(tname)]
            if key == "gains":
                if value < 0:
                    raise ConfigError(f"must be ≥ 0, got {value}", where)
                task.gain = float(value)
            else:
                if value <= 0:
                    raise ConfigError(f"must be > 0, got {value}", where)
                task.weight = float(value)
    # subtasks: named potentials of the file
    subtasks: list[Subtask] = []
    for pname, sub in run.subtasks.items():
        where = join_path(path, "subtasks", pname)
        if pname not in spec.potentials:
            defined = ", ".join(spec.potentials) or "(none)"
            raise ConfigError(f"no potential named '{pname}' under 'potentials'; defined: {defined}", where)
        pot = build_typed(POTENTIALS, spec.potentials[pname], pname, ctx, join_path("potentials", pname), "potential")
        subtasks.append(_subtask(pot, sub or SubtaskSpec(), where))
        if subtasks[-1].name in names:
            raise ConfigError(
                f"potential '{pname}' has the name of a main task: tasks and subtasks of a run need distinct names "
                "(rename the potential or give the task a 'name')",
                where,
            )
    controlled = {s.name for s in subtasks}
    watched = [
        build_typed(POTENTIALS, raw, pname, ctx, join_path("potentials", pname), "potential")
        for pname, raw in spec.potentials.items()
        if pname not in controlled
    ]
    monitors: list[Potential] = []
    torques: list[TorqueMonitor] = []
    for mname, raw in spec.monitors.items():
        mon = _build_monitor(raw, mname, ctx, join_path("monitors", mname))
        (torques if isinstance(mon, TorqueMonitor) else monitors).append(mon)  # type: ignore[arg-type]
    # resolver from the registry (QP resolvers register themselves there)
    if run.resolver not in RESOLVERS:
        raise ConfigError(
            f"unknown resolver '{run.resolver}'; available: {', '.join(sorted(RESOLVERS))}",
            join_path(path, "resolver"),
        )
    check_resolver_options(run.resolver, run.options, join_path(path, "options"))
    try:
        resolver = make_resolver(run.resolver, **run.options)
    except RedundikError as exc:
        raise ConfigError(str(exc), join_path(path, "options")) from None
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"resolver '{run.resolver}': bad options: {exc}", join_path(path, "options")) from None
    q0 = q0_file if run.q0 is None else configuration_from_file(run.q0, robot, ctx.angle_unit, join_path(path, "q0"))
    # assemble at q0 exactly as the simulation will, so that a run that cannot start fails now
    try:
        stack = TaskStack(tasks, subtasks)
        robot.update(q0)
        stack.reset(robot)
        for pot in [*watched, *monitors]:
            pot.check(robot)
        resolver.reset()
        resolver.check(robot, stack)
        check_gains(stack, spec.dt, resolver.name)  # what Resolver.step refuses at the first step (K·dt > 2)
        stack.evaluate(robot, 0.0)
    except RedundikError as exc:
        raise ConfigError(str(exc), path) from None
    given = run.plant if run.plant is not None else spec.plant
    if given is not None:
        _check_plant_rate(spec, given.sim_dt, join_path(path, "plant") if run.plant is not None else "plant")
    plant = given.options() if given is not None else None
    return RunPlan(name, run.description, run.resolver, resolver, stack, q0, watched, monitors, torques, plant)


def _draw_plan(spec: TaskFileSpec, robot: LoadedRobot, ctx: Context, runs: dict[str, RunPlan]) -> DrawPlan:
    path_frame = None
    for run in runs.values():
        for t in run.stack.tasks:
            frame = getattr(t, "frame", None)
            if isinstance(frame, str):
                path_frame = frame
                break
        if path_frame:
            break
    draw = spec.draw
    if draw is None or draw.frames is None:
        segments = list(robot.segments)
    else:
        raw = draw.frames
        single = all(isinstance(f, (str, int)) and not isinstance(f, bool) for f in raw)
        chains = [raw] if single else raw
        segments = []
        for ci, chain in enumerate(chains):
            cpath = "draw.frames" if single else join_path("draw.frames", ci)
            if not isinstance(chain, list) or len(chain) < 2:
                raise ConfigError("expected a list of at least two frame names, or a list of such lists", cpath)
            names = [str(f) for f in chain]
            for i, f in enumerate(names):
                check_frame(ctx, f, join_path(cpath, i))
            segments += list(itertools.pairwise(names))
    if draw is not None and draw.path is not None:
        path_frame = check_frame(ctx, draw.path, "draw.path")
    plane = None if draw is None or draw.plane is None else (draw.plane[0], draw.plane[1])
    if plane is not None and plane[0] == plane[1]:
        raise ConfigError(f"expected two different axes, got {list(plane)}", "draw.plane")
    return DrawPlan(segments, plane, None if draw is None else draw.every, path_frame)

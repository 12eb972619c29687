"""``redundik validate`` for any YAML file of the project: task files, robot configs, parallel-mechanism configs.

The kind of file is told from its top-level keys: ``kind`` → a parallel-mechanism config
(:mod:`redundik.config.parallel`); ``dh`` or ``urdf`` without ``runs`` / ``robot`` → a robot config
(:mod:`redundik.config.robot`); ``targets`` or ``convergence`` without ``runs`` → a sweep file
(:mod:`redundik.sweep.plan`); anything else is checked as a task file (:mod:`redundik.config.loader`).
Each is checked as fully as the commands that use it would check it at load time.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from redundik.config.yamlio import read_yaml

FileKind = Literal["task", "robot", "mechanism", "sweep"]


def detect_kind(data: dict[str, Any]) -> FileKind:
    """What a parsed YAML mapping is, from its top-level keys."""
    if "runs" not in data and ("targets" in data or "convergence" in data):
        return "sweep"
    if "runs" in data or "robot" in data:
        return "task"
    if "kind" in data:
        return "mechanism"
    if "dh" in data or "urdf" in data:
        return "robot"
    return "task"


def validate_file(path: str | Path) -> str:
    """Check one file completely; returns a one-line description of what it is.

    The shape of the file (keys, types, bounds) is checked first, with nothing heavier than pydantic imported, so
    a malformed file is refused in milliseconds; only a well-formed one builds its robot (Pinocchio) and runs.

    Raises:
        ConfigError: the first problem, with its key path (one line).
    """
    from redundik.config.schema import RobotSpec, TaskFileSpec
    from redundik.config.yamlio import validate

    path = Path(path)
    data = read_yaml(path, "file")
    kind = detect_kind(data)
    if kind == "mechanism":
        from redundik.config.parallel import parse_config

        cfg = parse_config(data, str(path))
        cfg.build()
        return f"{cfg.kind} mechanism config '{cfg.name}'"
    if kind == "sweep":
        from redundik.sweep.plan import load_sweep

        sweep = load_sweep(path)
        return (
            f"sweep '{sweep.name}', robot '{sweep.robot.model.name}': {sweep.n_problems} problems "
            f"({sweep.n_targets} targets × {sweep.n_starts} starts), {sweep.spec.resolver.name}"
        )
    if kind == "robot":
        prefix = f"{path.name}: "
        spec = validate(RobotSpec, data, prefix)
        from redundik.config.robot import build_robot

        robot = build_robot(spec, path.resolve().parent, prefix, str(path)).model
        return f"robot config '{robot.name}' ({robot.nv} joints)"
    validate(TaskFileSpec, data)  # the shape, before the loader's imports (Pinocchio, the task types)
    from redundik.config.loader import load_task

    plan = load_task(path)
    runs = ", ".join(f"{n} ({r.resolver_name}, {r.integrator})" for n, r in plan.runs.items())
    return (
        f"task '{plan.name}', robot '{plan.robot.model.name}' ({plan.robot.model.nv} joints), "
        f"dt = {plan.dt} s, {plan.steps} steps, runs: {runs}"
    )

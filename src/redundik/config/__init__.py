"""YAML task runs: robot configs and task files → robots, task stacks and resolvers; running them.

Library use does not need this package (build robots, tasks and resolvers directly); it is what
``redundik run`` / ``redundik validate`` use, and what tests and tools use to run a task file::

    from redundik.config import load_task, run_task
    plan = load_task("tasks/planar3r_line.yaml")     # validates every run, raises ConfigError
    results = run_task(plan)                          # {run name: RunResult(log, summary, ...)}

Its names are imported on first use, so ``redundik.config.yamlio`` / ``schema`` (the shape checks of
``redundik validate``) load without Pinocchio.
"""

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from redundik.config.loader import DrawPlan, RunPlan, TaskPlan, load_task
    from redundik.config.robot import LoadedRobot, load_robot
    from redundik.config.runner import run_task

_LAZY = {
    "DrawPlan": "redundik.config.loader",
    "RunPlan": "redundik.config.loader",
    "TaskPlan": "redundik.config.loader",
    "load_task": "redundik.config.loader",
    "LoadedRobot": "redundik.config.robot",
    "load_robot": "redundik.config.robot",
    "run_task": "redundik.config.runner",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'redundik.config' has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(module), name)


__all__ = ["DrawPlan", "LoadedRobot", "RunPlan", "TaskPlan", "load_robot", "load_task", "run_task"]

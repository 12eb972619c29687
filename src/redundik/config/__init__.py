"""YAML task runs: robot configs and task files → robots, task stacks and resolvers; running them.

Library use does not need this package (build robots, tasks and resolvers directly); it is what
``redundik run`` / ``redundik validate`` use, and what tests and tools use to run a task file::

    from redundik.config import load_task, run_task
    plan = load_task("tasks/planar3r_line.yaml")     # validates every run, raises ConfigError
    results = run_task(plan)                          # {run name: RunResult(log, summary, ...)}
"""

from redundik.config.loader import DrawPlan, RunPlan, TaskPlan, load_task
from redundik.config.robot import LoadedRobot, load_robot

__all__ = ["DrawPlan", "LoadedRobot", "RunPlan", "TaskPlan", "load_robot", "load_task"]

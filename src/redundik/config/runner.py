"""Run the runs of a :class:`~redundik.config.TaskPlan` and summarise them (the numbers of ``summary.json``)."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from redundik.config.loader import RunPlan, TaskPlan
from redundik.config.world_types import world_clock, world_summary
from redundik.errors import ConfigError, SimulationError
from redundik.reporting import smoothness
from redundik.simulation import SimulationLog, simulate
from redundik.simulation.plant import Plant
from redundik.tasks.subtasks import TargetSubtask
from redundik.tasks.waypoints import JointWaypoints


@dataclass
class RunResult:
    """One simulated run.

    Attributes:
        name: Run name.
        plan: What was run.
        log: The simulation log (q, q̇, task errors, potentials incl. watched ones and monitors, frame origins).
        series: Extra per-sample series by CSV column name (torque monitors: ``m.NAME.max`` ...), shape (N,).
        limit_violation: Largest joint-limit violation per sample [rad or length], shape (N,).
        summary: The run's entry of ``summary.json``.
    """

    name: str
    plan: RunPlan
    log: SimulationLog
    series: dict[str, np.ndarray] = field(default_factory=dict)
    limit_violation: np.ndarray = field(default_factory=lambda: np.zeros(0))
    summary: dict[str, Any] = field(default_factory=dict)


def select_runs(plan: TaskPlan, names: Iterable[str] | None) -> list[str]:
    """The runs to execute, in file order.

    Raises:
        ConfigError: an unknown run name (lists the file's runs).
    """
    if names is None:
        return list(plan.runs)
    wanted = [n.strip() for n in names if n.strip()]
    if not wanted:
        raise ConfigError(f"--runs: no run name given; runs in the file: {', '.join(plan.runs)}")
    bad = [n for n in wanted if n not in plan.runs]
    if bad:
        raise ConfigError(f"no run named {', '.join(repr(b) for b in bad)}; runs in the file: {', '.join(plan.runs)}")
    return [n for n in plan.runs if n in wanted]


def run_task(
    plan: TaskPlan,
    runs: Iterable[str] | None = None,
    progress: Callable[[str, int], None] | None = None,
) -> dict[str, RunResult]:
    """Simulate the selected runs of a task plan (all by default).

    Args:
        plan: From :func:`redundik.config.load_task`.
        runs: Names of the runs to execute.
        progress: Called as ``progress(run_name, steps_done)``.

    Returns:
        Results by run name, in file order.
    """
    out: dict[str, RunResult] = {}
    for name in select_runs(plan, runs):
        out[name] = run_one(plan, plan.runs[name], progress)
    return out


def run_one(plan: TaskPlan, run: RunPlan, progress: Callable[[str, int], None] | None = None) -> RunResult:
    """Simulate one run and summarise it."""
    robot = plan.robot.model
    cb = None if progress is None else (lambda k: progress(run.name, k))
    world = getattr(plan, "world", None)
    if world is not None:  # moving obstacles: the clock follows the steps (the next tick is at k·dt)
        world.set_time(0.0)
        cb = world_clock(world, plan.dt, cb)
    plant = None
    if run.plant is not None:
        from redundik.simulation.plant import make_plant

        where = f"runs.{run.name}.plant"
        plant = make_plant(run.plant, robot, plan.robot.urdf, control_dt=plan.dt, where=where)
    log = simulate(
        robot,
        run.stack,
        run.resolver,
        run.q0,
        dt=plan.dt,
        steps=plan.steps,
        log_frames=tuple(plan.log_frames),
        extra_potentials=tuple(run.watched + run.monitors),
        progress=cb,
        plant=plant,
        integrator=run.integrator,
        rtol=run.rtol,
        atol=run.atol,
    )
    n = log.q.shape[0]
    violation = np.array([float(np.max(robot.limit_violation(log.q[k]), initial=0.0)) for k in range(n)])
    series: dict[str, np.ndarray] = {}
    if run.torque_monitors:
        tau = {m.name: np.empty((n, robot.nv)) for m in run.torque_monitors}
        with np.errstate(over="ignore", invalid="ignore"):  # overflow is reported below, in one line
            for k in range(n):
                robot.update(log.q[k])
                for m in run.torque_monitors:
                    tau[m.name][k] = m.torques(robot)
            for m in run.torque_monitors:
                a = np.abs(tau[m.name])
                series[f"m.{m.name}.max"] = a.max(axis=1)
                series[f"m.{m.name}.min"] = a.min(axis=1)
                series[f"m.{m.name}.mean"] = a.mean(axis=1)
    for key, values in series.items():
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            t = float(log.t[bad[0]])
            raise SimulationError(
                f"run '{run.name}' diverged at t = {t:.6g} s: monitor {key} is not finite (overflow?)"
            )
    world_stats, world_series = world_summary(plan, run, log)
    series.update(world_series)
    if plant is not None:
        series.update(plant.series())
    result = RunResult(run.name, run, log, series, violation)
    result.summary = summarise(plan, result) | world_stats
    if plant is not None:
        result.summary.update(plant_summary(plan, run, plant, log))
    return result


def plant_summary(plan: TaskPlan, run: RunPlan, plant: Plant, log: SimulationLog) -> dict[str, Any]:
    """The plant's entries of a run's ``summary.json``: ``plant``, the error under the plant and, when
    ``kinematic_reference`` is on, the same run's error with the perfect integrator (``kinematic_max_task_error``)."""
    out: dict[str, Any] = {"plant": plant.name, **plant.summary()}
    out["plant_max_task_error"] = log.max_task_error
    options = run.plant
    if options is not None and options.kinematic_reference:
        ref = simulate(plan.robot.model, run.stack, run.resolver, run.q0, dt=plan.dt, steps=plan.steps)
        out["kinematic_max_task_error"] = ref.max_task_error
        out["error_ratio_plant_vs_kinematic"] = log.max_task_error / max(ref.max_task_error, 1e-15)
        out["max_q_deviation_from_kinematic"] = float(np.max(np.abs(log.q - ref.q)))
    return out


def _stats(x: np.ndarray) -> dict[str, float]:
    return {"initial": float(x[0]), "final": float(x[-1]), "min": float(np.min(x)), "max": float(np.max(x))}


def summarise(plan: TaskPlan, result: RunResult) -> dict[str, Any]:
    """The ``summary.json`` entry of one run (lengths in the model's unit, angles in rad)."""
    run, log = result.plan, result.log
    err = log.stacked_error
    st_us = log.step_time * 1e6
    summary: dict[str, Any] = {
        "resolver": run.resolver_name,
        "description": run.description,
        "final_q": [float(v) for v in log.q[-1]],
        "max_task_error": float(np.max(err)),
        "final_task_error": float(err[-1]),
        "task_errors": {k: {"max": float(np.max(v)), "final": float(v[-1])} for k, v in log.task_errors.items()},
        "subtasks": {
            s.name: {
                "kind": s.kind,
                **(
                    {"initial": float(log.potentials[s.name][0]), "final": float(log.potentials[s.name][-1])}
                    if s.name in log.potentials
                    else {}
                ),
                **({"target": float(s.target)} if isinstance(s, TargetSubtask) else {}),
            }
            for s in run.stack.subtasks
        },
        "potentials": {k: _stats(v) for k, v in log.potentials.items() if k not in {m.name for m in run.monitors}},
        "step_time_us": {
            "median": float(np.median(st_us)) if st_us.size else 0.0,
            "p90": float(np.percentile(st_us, 90)) if st_us.size else 0.0,
        },
        "limit_violations": int(np.count_nonzero(result.limit_violation > 0)),
        "max_limit_violation": float(np.max(result.limit_violation, initial=0.0)),
        "damped_steps": int(np.count_nonzero(log.damped)),
        "fallbacks": len(log.fallbacks),
        "relaxed_steps": len(log.relaxed),
        "smoothness": smoothness.summary(log.dq[:-1], plan.dt, plan.robot.model.joint_names),
    }
    for s in run.stack.subtasks:  # a waypoint round trip that stalled short of a waypoint says so
        pot = getattr(s, "potential", None)
        if isinstance(pot, JointWaypoints):
            summary["subtasks"][s.name]["waypoints"] = {
                "values": [float(v) for v in pot.values],
                "tolerance": pot.tolerance,
                "reached": pot.reached(log.q),
            }
    if log.fallbacks:
        summary["fallback_reasons"] = sorted({reason for _, reason in log.fallbacks})
    if log.relaxed:
        summary["relaxed_members"] = sorted({name for _, names in log.relaxed for name in names})
    if "sigma_min" in log.extras:
        summary["min_sigma_min"] = float(np.nanmin(log.extras["sigma_min"]))
    if "speed_scale" in log.extras:  # steps the joint-speed cap scaled (resolvers/singularity.py): NaN elsewhere
        summary["capped_steps"] = int(np.isfinite(log.extras["speed_scale"]).sum())
    if "singularity_state" in log.extras:  # the singularity guard's state per step (2: halted)
        summary["halted_steps"] = int((log.extras["singularity_state"] == 2).sum())
        summary["max_condition"] = float(np.nanmax(log.extras["condition"]))
    monitors: dict[str, Any] = {m.name: _stats(log.potentials[m.name]) for m in run.monitors}
    for m in run.torque_monitors:
        monitors[m.name] = {stat: _stats(result.series[f"m.{m.name}.{stat}"]) for stat in ("max", "min", "mean")}
    if monitors:
        summary["monitors"] = monitors
    clearances = [log.potentials[m.name] for m in run.monitors if plan.potential_types.get(m.name) == "clearance"]
    if clearances:
        summary["min_clearance"] = float(min(np.min(c) for c in clearances))
    postures = [m.name for m in run.monitors if plan.potential_types.get(m.name) == "best_posture"]
    if "trace_JWJT" in {m.name for m in run.monitors}:
        postures = ["trace_JWJT"]
    if postures:
        x = log.potentials[postures[0]]
        summary["trace_JWJT"] = {"initial": float(x[0]), "final": float(x[-1]), "min": float(np.min(x))}
    return summary


def task_summary(plan: TaskPlan, results: dict[str, RunResult]) -> dict[str, Any]:
    """The whole ``summary.json``."""
    robot = plan.robot.model
    return {
        "task": plan.name,
        "description": plan.description,
        "robot": robot.name,
        "robot_source": plan.robot.source,
        "task_file": str(plan.path.resolve()) if plan.path is not None else None,
        "length_unit": robot.length_unit,
        "joints": robot.joint_names,
        "dt": plan.dt,
        "steps": plan.steps,
        "runs": {name: r.summary for name, r in results.items()},
    }

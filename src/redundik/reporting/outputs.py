"""Files a task run writes: ``summary.json`` and one ``RUN.csv`` per run.

Every path goes through :func:`safe_path` (re-exported from :mod:`redundik.reporting.paths`): use it for any new
writer too.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from redundik.config.loader import TaskPlan
from redundik.config.runner import RunResult, task_summary
from redundik.kinematics import RobotModel
from redundik.reporting import smoothness
from redundik.reporting.paths import safe_path

__all__ = ["q_labels", "run_table", "safe_path", "write_csv", "write_outputs"]


def q_labels(robot: RobotModel) -> list[str]:
    """Column labels of the configuration vector, ``q.<joint>`` (``q[i]`` for entries of multi-dof joints)."""
    labels = [f"q[{i}]" for i in range(robot.nq)]
    for j in robot.joints:
        if j.idx_q >= 0 and robot.nq == robot.nv:
            labels[j.idx_q] = f"q.{j.name}"
        elif j.idx_q >= 0 and robot.model.joints[robot.model.getJointId(j.name)].nq == 1:
            labels[j.idx_q] = f"q.{j.name}"
    return labels


def run_table(plan: TaskPlan, result: RunResult) -> tuple[list[str], np.ndarray]:
    """The columns and rows of ``RUN.csv``: one row per sample.

    Columns: ``t`` [s]; ``q.<joint>`` [rad or length]; ``dq.<joint>`` (q̇ applied after the sample); ``e.<task>``
    (task error norm); ``p.<potential>`` (every potential of the file, controlled or watched); ``m.<monitor>``;
    ``limit_violation``; per-step diagnostics (``step_time_us``, ``damped``, ``fallback`` (1 when the step fell
    back), ``relaxed`` (the number of members it relaxed as documented), the smoothness columns ``max_abs_ddq``,
    ``max_abs_jerk``, ``ddq_sign_changes`` of :mod:`redundik.reporting.smoothness`, ``sigma_min``, ... — empty on
    the last sample, which has no step); ``x.<frame>``, ``y.<frame>``, ``z.<frame>`` of the logged frame origins.
    """
    robot = plan.robot.model
    log = result.log
    n = log.t.shape[0]
    monitor_names = {m.name for m in result.plan.monitors}
    cols: list[tuple[str, np.ndarray]] = [("t", log.t)]
    cols += [(lab, log.q[:, i]) for i, lab in enumerate(q_labels(robot))]
    cols += [(f"dq.{name}", log.dq[:, i]) for i, name in enumerate(robot.joint_names)]
    cols += [(f"e.{k}", v) for k, v in log.task_errors.items()]
    cols += [(f"p.{k}", v) for k, v in log.potentials.items() if k not in monitor_names]
    cols += [(f"m.{k}", v) for k, v in log.potentials.items() if k in monitor_names]
    cols += list(result.series.items())
    cols.append(("limit_violation", result.limit_violation))

    def per_step(x: np.ndarray) -> np.ndarray:
        out = np.full(n, np.nan)
        out[: x.shape[0]] = x
        return out

    cols.append(("step_time_us", per_step(log.step_time * 1e6)))
    cols.append(("damped", per_step(log.damped.astype(float))))
    flags = np.zeros((2, log.step_time.shape[0]))  # per step: fell back (1/0), members relaxed (their number)
    for k, _ in log.fallbacks:
        flags[0, k] = 1.0
    for k, names in log.relaxed:
        flags[1, k] = len(names)
    cols += [("fallback", per_step(flags[0])), ("relaxed", per_step(flags[1]))]
    cols += smoothness.columns(log.dq[:-1], plan.dt, n)
    cols += [(k, per_step(v)) for k, v in log.extras.items()]
    for f, xyz in log.frame_positions.items():
        cols += [(f"{a}.{f}", xyz[:, i]) for i, a in enumerate("xyz")]
    return [c for c, _ in cols], np.column_stack([v for _, v in cols])


def _fmt(v: float) -> str:
    if math.isnan(v):
        return ""
    return f"{v:.10g}"


def write_csv(path: Path, header: list[str], rows: np.ndarray) -> None:
    """Write a numeric table (NaN as an empty cell)."""
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for row in rows:
            w.writerow([_fmt(float(v)) for v in row])


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def write_outputs(plan: TaskPlan, results: dict[str, RunResult], out_dir: Path) -> dict[str, Any]:
    """Write ``summary.json`` and the CSV of every run into ``out_dir`` (created); returns the summary."""
    summary = _jsonable(task_summary(plan, results))
    text = json.dumps(summary, indent=2, ensure_ascii=False) + "\n"
    tables = {name: run_table(plan, result) for name, result in results.items()}
    paths = {name: safe_path(out_dir, f"{name}.csv") for name in results}  # every path checked before any write
    safe_path(out_dir, "summary.json").write_text(text, encoding="utf-8")
    for name, (header, rows) in tables.items():
        write_csv(paths[name], header, rows)
    return summary

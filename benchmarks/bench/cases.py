"""One case's summary: :class:`CaseResult` from a runner's records (:func:`summarise`), its honest status
(:func:`case_status`), and the versions of what ran."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from benchmarks.bench import batch as batch_case
from benchmarks.bench.peer_runners import MinkShelfRunner
from benchmarks.bench.runners import Runner

#: Largest fraction of steps that may fall back (or raise) or leave the robot frozen before a case is FAILED.
MAX_BAD_FRACTION = 0.01
#: Largest joint-limit violation a case may reach [rad or m] (numerical round-off of the peers' integrators).
LIMIT_TOLERANCE = 1e-5


@dataclass
class CaseResult:
    """The summary of one case (robot, method, backend)."""

    robot: str
    method: str
    backend: str
    median_us: float
    p90_us: float
    max_task_error: float
    mean_task_error: float
    limit_violations: int
    max_violation: float
    subtask_final: float
    subtask_mean: float
    subtask_label: str
    failures: int
    steps: int
    default_backend: bool = False
    qp_fraction: float | None = None
    first_failure: str | None = None
    stages_us: dict[str, float] | None = None
    fallback_steps: int = 0
    first_fallback: str | None = None
    frozen_steps: int = 0
    error_tolerance: float = 1e-3
    status: str = "ok"
    problems_per_s: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """True when the case tracks, moves, keeps the limits and rarely falls back (:func:`case_status`)."""
        return self.status == "ok"

    def as_json(self) -> dict[str, Any]:
        """The JSON record (keys ``robot``, ``method``, ``backend``, ``median_us``, ``p90_us``,
        ``max_task_error``, ``limit_violations``, ``status`` first — other tools read them — then the extras)."""
        return {
            "robot": self.robot,
            "method": self.method,
            "backend": self.backend,
            "median_us": self.median_us,
            "p90_us": self.p90_us,
            "max_task_error": self.max_task_error,
            "limit_violations": self.limit_violations,
            "status": self.status,
            **({} if self.problems_per_s is None else {"problems_per_s": self.problems_per_s}),
            "error_tolerance": self.error_tolerance,
            "fallback_steps": self.fallback_steps,
            "first_fallback": self.first_fallback,
            "frozen_steps": self.frozen_steps,
            "mean_task_error": self.mean_task_error,
            "max_violation": self.max_violation,
            "subtask": self.subtask_label,
            "subtask_final": self.subtask_final,
            "subtask_mean": self.subtask_mean,
            "failures": self.failures,
            "first_failure": self.first_failure,
            "steps": self.steps,
            "default_backend": self.default_backend,
            "qp_fraction": self.qp_fraction,
            "stages_us": self.stages_us,
            **self.extra,
        }


def summarise_case(r: Any, warmup: int, defaults: dict[str, str]) -> CaseResult:
    if isinstance(r, batch_case.BatchRunner):
        return _summarise_batch(r, warmup, defaults)
    rec = r.record
    times = np.asarray(rec.step_ns[warmup:], dtype=float) / 1e3
    ok = times[times > 0] if np.any(times > 0) else times
    viol = np.asarray(rec.violation)
    err = np.asarray(rec.task_error)
    mon = np.asarray(rec.monitor)
    backend = r.backend
    sc = r.scenario
    case = CaseResult(
        robot=sc.key,
        method=r.method,
        backend=backend,
        median_us=float(np.median(ok)) if ok.size else float("nan"),
        p90_us=float(np.percentile(ok, 90)) if ok.size else float("nan"),
        max_task_error=float(np.max(err)) if err.size else 0.0,
        mean_task_error=float(np.mean(err)) if err.size else 0.0,
        limit_violations=int(np.sum(viol > 0.0)),
        max_violation=float(np.max(viol, initial=0.0)),
        subtask_final=float(mon[-1]) if mon.size else 0.0,
        subtask_mean=float(np.mean(mon)) if mon.size else 0.0,
        subtask_label=sc.monitor_label,
        failures=rec.failures,
        steps=len(rec.step_ns),
        default_backend=defaults.get(f"{sc.key}/{r.method}") == backend,
        first_failure=rec.first_failure,
        qp_fraction=rec.qp_steps / max(len(rec.step_ns), 1) if r.method in ("wqp", "hqp") else None,
        fallback_steps=rec.fallbacks,
        first_fallback=rec.first_fallback,
        frozen_steps=rec.frozen,
        error_tolerance=sc.error_tolerance,
    )
    if rec.paths:  # which path redundik's steps took (result.info["path"]) and the members it ran interpreted
        case.extra["path"] = _path_label(rec.paths)
        case.extra["paths"] = dict(rec.paths)
        case.extra["interpreted"] = sorted(rec.interpreted)
    if rec.step_ns:  # the first step of the process: the kernels' JIT compile or their load from numba's disk cache
        case.extra["first_step_s"] = rec.step_ns[0] / 1e9
    flags = np.asarray(rec.qp_flags[warmup:], dtype=bool)
    if r.method in ("wqp", "hqp") and flags.shape == times.shape and flags.any():
        qp_t, free_t = times[flags], times[~flags]  # the two kinds of step: a bimodal time per step
        case.extra["qp_step_median_us"] = float(np.median(qp_t))
        case.extra["free_step_median_us"] = float(np.median(free_t)) if free_t.size else None
        case.qp_fraction = float(flags.mean())
    if sc.final_tolerance is not None and sc.episode is not None and err.size:
        ends = np.arange(sc.episode - 1, err.size, sc.episode)
        case.extra["final_task_error"] = float(np.max(err[ends])) if ends.size else None
        case.extra["final_tolerance"] = sc.final_tolerance
    if sc.key == "panda_shelf" and mon.size:
        case.extra["min_collision_distance"] = float(np.min(mon))
        case.extra["collision_pairs"] = int(getattr(sc, "pairs", 0)) or None
    if isinstance(r, MinkShelfRunner):
        case.extra["collision_pairs"] = r.pairs_used  # mink drops pairs of welded / parent-child bodies
    if r.method == "placo":
        case.extra["placo_version"] = getattr(r, "version", None)
        case.extra["out_of_process"] = True
    case.status = case_status(case)
    return case


def _path_label(paths: dict[str, int]) -> str:
    """``"compiled"`` when every step took one path, else each path with its count of steps."""
    if len(paths) == 1:
        return next(iter(paths))
    return ", ".join(f"{p} {n}" for p, n in sorted(paths.items(), key=lambda kv: -kv[1]))


def _summarise_batch(r: batch_case.BatchRunner, warmup: int, defaults: dict[str, str]) -> CaseResult:
    times = np.asarray(r.step_ns[warmup:], dtype=float) / 1e3
    ok = times[times > 0] if np.any(times > 0) else times
    m = r.measure()
    median = float(np.median(ok)) if ok.size else float("nan")
    case = CaseResult(
        robot=batch_case.ROBOT_KEY,
        method=r.method,
        backend=r.backend,
        median_us=median,
        p90_us=float(np.percentile(ok, 90)) if ok.size else float("nan"),
        max_task_error=m["max_task_error"],
        mean_task_error=m.get("mean_task_error", float("nan")),
        limit_violations=m["limit_violations"],
        max_violation=m["max_violation"],
        subtask_final=0.0,
        subtask_mean=0.0,
        subtask_label="–",
        failures=r.failures,
        steps=len(r.step_ns) * r.q.shape[0],
        default_backend=True,
        first_failure=r.first_failure,
        qp_fraction=m.get("qp_fraction"),
        fallback_steps=m["fallbacks"],
        first_fallback=m.get("first_fallback"),
        error_tolerance=1e-3,
        problems_per_s=r.q.shape[0] / (median * 1e-6) if median > 0 else None,
    )
    if r.paths:
        case.extra["path"] = _path_label(r.paths)
    case.extra["problems"] = int(r.q.shape[0])
    case.extra["calls"] = len(r.step_ns)
    if "loop_agreement" in m:
        case.extra["loop_agreement"] = m["loop_agreement"]
    case.status = case_status(case)
    return case


def summarise(r: Runner, warmup: int = 0, defaults: dict[str, str] | None = None) -> CaseResult:
    """The :class:`CaseResult` of a runner that has run (timings after ``warmup`` steps), with its status."""
    return summarise_case(r, warmup, defaults or {})


def case_status(c: CaseResult) -> str:
    """``"ok"``, or ``"failed: "`` and every reason, for a case whose numbers cannot be compared honestly:

    * its stacked frame-task error exceeds the scenario's tolerance (``error_tolerance``, 1 mm / 1 mrad);
    * its robot does not move on more than 1 % of the steps (q unchanged to 1e-12; every reference moves);
    * it falls back (``StepResult.fallback``) or raises on more than 1 % of the steps;
    * it breaks the joint limits by more than 1e-5 rad (the limits are part of every scenario's task);
    * ``panda_shelf``: its final error exceeds the scenario's ``final_tolerance`` or a pair penetrates;
    * a batch case: its q̇ differs from the one-by-one loop's by more than 1e-9.

    A failed case keeps its row in the reports but is left out of the ratios and the targets.
    """
    reasons = []
    n = max(c.steps, 1)
    if not c.max_task_error <= c.error_tolerance:  # NaN fails too
        reasons.append(f"tracking error {c.max_task_error:.2e} > tolerance {c.error_tolerance:g}")
    if c.frozen_steps > MAX_BAD_FRACTION * n:
        reasons.append(f"robot does not move on {c.frozen_steps} of {c.steps} steps")
    bad = c.fallback_steps + c.failures
    if bad > MAX_BAD_FRACTION * n:
        first = c.first_failure or c.first_fallback or ""
        reasons.append(f"falls back or raises on {bad} of {c.steps} steps" + (f" ({first[:120]})" if first else ""))
    if c.max_violation > LIMIT_TOLERANCE:
        reasons.append(f"breaks the joint limits on {c.limit_violations} steps (by up to {c.max_violation:.1e})")
    final, final_tol = c.extra.get("final_task_error"), c.extra.get("final_tolerance")
    if final is not None and final_tol is not None and not final <= final_tol:
        reasons.append(f"final task error {final:.2e} > tolerance {final_tol:g}")
    dmin = c.extra.get("min_collision_distance")
    if dmin is not None and not dmin >= 0.0:
        reasons.append(f"penetrates (min collision distance {dmin:.2e} m)")
    agree = c.extra.get("loop_agreement")
    if agree is not None and not agree <= batch_case.AGREEMENT:
        reasons.append(f"differs from the one-by-one loop by {agree:.1e} > {batch_case.AGREEMENT:g}")
    return "ok" if not reasons else "failed: " + "; ".join(reasons)


def versions(runners: Sequence[Any] = ()) -> dict[str, str]:
    from importlib import metadata

    out = {}
    for dist in ("redundik", "pin", "numpy", "qpsolvers", "osqp", "proxsuite", "daqp", "quadprog", "mink", "mujoco"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            continue
    try:
        out["pin-pink"] = metadata.version("pin-pink")
    except metadata.PackageNotFoundError:
        pass
    for r in runners:
        if getattr(r, "method", "") == "placo":
            out["placo"] = f"{getattr(r, 'version', '?')} (own interpreter {getattr(r, 'python', '?')})"
    return out


#: The ``ik_convergence`` case: rk.solve_ik against TRAC-IK on random reachable poses (benchmarks/ik_convergence.py).
IK_CONVERGENCE = "ik_convergence"
#: Its poses per robot: full run, and ``--quick``.
IK_POSES, IK_POSES_QUICK = 10_000, 200


def ik_convergence_case(n: int, robots: Sequence[str] = ("panda", "ur5", "xarm7")) -> dict[str, Any]:
    """The ``ik_convergence`` record: per robot and solver, success, median / p99 / max time [ms] and limit
    violations on n reachable poses (5 ms budget; TRAC-IK only where its interpreter is installed)."""
    import os

    from benchmarks import ik_convergence as ikc

    peers = os.environ.get("IKPEERS_PYTHON", "/work/wt/ikpeers/bin/python")
    rows = [r for name in robots for r in ikc.run_robot(name, n, 0, peers)]
    return {"case": IK_CONVERGENCE, "poses": n, "timeout_s": ikc.TIMEOUT, "rows": rows}

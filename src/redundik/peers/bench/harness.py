"""Run the comparison: build the cases from a method list, step them round-robin in chunks, summarise.

The machine is noisy (shared cores), so cases are never run one after the other: every case advances by a chunk
of steps in turn (the order rotating each round), so slow drifts of the machine hit all cases alike, and the
medians, p90 and ratios all come from one run.
"""

from __future__ import annotations

import platform
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from redundik.errors import ConfigError, RedundikError
from redundik.peers._deps import available
from redundik.peers.bench.runners import MinkRunner, PinkRunner, RedundikRunner, Runner
from redundik.peers.bench.scenarios import SCENARIOS
from redundik.resolvers.registry import RESOLVERS

#: Methods in report order; ``method`` values of the JSON.
METHODS: tuple[str, ...] = ("pinv", "feedback", "wqp", "hqp", "mink", "pink")
#: QP backends tried for wqp/hqp (each one that the resolver accepts and is installed becomes a case).
QP_BACKENDS: tuple[str, ...] = ("osqp", "proxsuite", "daqp", "quadprog")
#: Backends tried for the peers (their fastest is used in the ratios).
PEER_BACKENDS: tuple[str, ...] = ("daqp", "quadprog")
#: Largest fraction of steps that may fall back (or raise) or leave the robot frozen before a case is FAILED.
MAX_BAD_FRACTION = 0.01
#: Largest joint-limit violation a case may reach [rad or m] (numerical round-off of the peers' integrators).
LIMIT_TOLERANCE = 1e-5


@dataclass
class BenchConfig:
    """What to run.

    Attributes:
        robots: Scenario keys (``planar3r``, ``panda``, ``panda_tight``, ``talos``).
        methods: Methods among :data:`METHODS`.
        steps: Timed steps per case after warm-up (≥ 2000 for the reported numbers).
        warmup: Steps run before timing starts.
        chunk: Steps per case per round-robin turn.
        qp_backends: Backends for wqp/hqp; ``None`` = every one of :data:`QP_BACKENDS` that works.
        peer_backends: Backends for mink/pink.
        profile_steps: Steps of the per-stage profile of redundik's methods (0 = off).
        resolver_options: Extra options per redundik method (e.g. tolerances).
    """

    robots: Sequence[str] = ("planar3r", "panda", "panda_tight", "talos")
    methods: Sequence[str] = METHODS
    steps: int = 2000
    warmup: int = 200
    chunk: int = 50
    qp_backends: Sequence[str] | None = None
    peer_backends: Sequence[str] = PEER_BACKENDS
    profile_steps: int = 400
    resolver_options: dict[str, dict[str, Any]] = field(default_factory=dict)

    @classmethod
    def quick(cls, steps: int = 300) -> BenchConfig:
        """A run that finishes within a minute: fewer steps, every QP backend, the peers on daqp only."""
        return cls(steps=steps, warmup=30, chunk=50, peer_backends=("daqp",), profile_steps=100)

    def check(self) -> None:
        """Raise :class:`ConfigError` on unknown robots/methods or non-positive counts."""
        bad = [r for r in self.robots if r not in SCENARIOS]
        if bad:
            raise ConfigError(f"unknown robots {bad}; available: {sorted(SCENARIOS)}", "robots")
        bad = [m for m in self.methods if m not in METHODS]
        if bad:
            raise ConfigError(f"unknown methods {bad}; available: {list(METHODS)}", "methods")
        for key in ("steps", "chunk"):
            if getattr(self, key) < 1:
                raise ConfigError(f"must be ≥ 1, got {getattr(self, key)}", key)
        if self.warmup < 0 or self.profile_steps < 0:
            raise ConfigError("must be ≥ 0", "warmup/profile_steps")


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
        }


@dataclass
class BenchResult:
    """Everything one run produced."""

    cases: list[CaseResult]
    skipped: list[str]
    meta: dict[str, Any]

    def find(self, robot: str, method: str, backend: str | None = None) -> list[CaseResult]:
        """Cases of a robot and method (and backend)."""
        return [
            c
            for c in self.cases
            if c.robot == robot and c.method == method and (backend is None or c.backend == backend)
        ]

    def fastest(self, robot: str, method: str) -> CaseResult | None:
        """The case of ``method`` on ``robot`` with the lowest median (its fastest backend) among the cases that did
        not fail (:func:`case_status`), if any."""
        found = [c for c in self.find(robot, method) if c.ok]
        return min(found, key=lambda c: c.median_us) if found else None

    def default(self, robot: str, method: str) -> CaseResult | None:
        """The case of ``method`` with its default backend (or the only one)."""
        found = self.find(robot, method)
        for c in found:
            if c.default_backend:
                return c
        return found[0] if len(found) == 1 else None

    def faster_peer(self, robot: str) -> CaseResult | None:
        """The faster of mink and pink (each with its fastest backend) on ``robot``."""
        peers = [c for c in (self.fastest(robot, "mink"), self.fastest(robot, "pink")) if c is not None]
        return min(peers, key=lambda c: c.median_us) if peers else None

    def ratios(self) -> list[dict[str, Any]]:
        """Median of every redundik case that did not fail over the faster (non-failed) peer's median, per robot."""
        out = []
        for c in self.cases:
            if c.method in ("mink", "pink") or not c.ok:
                continue
            peer = self.faster_peer(c.robot)
            if peer is None or peer.median_us <= 0:
                continue
            out.append(
                {
                    "robot": c.robot,
                    "method": c.method,
                    "backend": c.backend,
                    "peer": f"{peer.method}/{peer.backend}",
                    "ratio": c.median_us / peer.median_us,
                }
            )
        return out

    def targets(self) -> list[dict[str, Any]]:
        """The issue's performance targets, each with the measured value and whether it is met."""
        out: list[dict[str, Any]] = []

        def add(name: str, value: float | None, limit: float | None, unit: str, detail: str) -> None:
            met = None if value is None or limit is None else bool(value <= limit)
            out.append({"target": name, "value": value, "limit": limit, "unit": unit, "met": met, "detail": detail})

        peer = self.faster_peer("panda")
        wqp = _ok(self.default("panda", "wqp"))
        add(
            "panda: wqp (default backend) ≤ ¼ faster peer",
            None if wqp is None or peer is None else wqp.median_us / peer.median_us,
            0.25,
            "ratio",
            _detail(wqp, peer),
        )
        pinv = _ok(self.default("panda", "pinv"))
        add("panda: pinv with null-space subtask < 25 µs", None if pinv is None else pinv.median_us, 25.0, "µs", "")
        hqp = _ok(self.default("panda", "hqp"))
        add(
            "panda: 3-level hqp ≤ one weighted QP step of the faster peer",
            None if hqp is None or peer is None else hqp.median_us / peer.median_us,
            1.0,
            "ratio",
            _detail(hqp, peer),
        )
        pink = self.fastest("talos", "pink")
        wqp_h = _ok(self.default("talos", "wqp"))
        add(
            "humanoid: wqp ≤ ⅓ pink",
            None if wqp_h is None or pink is None else wqp_h.median_us / pink.median_us,
            1.0 / 3.0,
            "ratio",
            _detail(wqp_h, pink),
        )
        return out


def _ok(c: CaseResult | None) -> CaseResult | None:
    return c if c is not None and c.ok else None


def _detail(a: CaseResult | None, b: CaseResult | None) -> str:
    if a is None or b is None:
        return "not measured (or FAILED)"
    return f"{a.method}/{a.backend} {a.median_us:.1f} µs vs {b.method}/{b.backend} {b.median_us:.1f} µs"


# ---------------------------------------------------------------------------------------------------------- building
def build_cases(config: BenchConfig, log: Callable[[str], None] = print) -> tuple[list[Runner], list[str], dict]:
    """One runner per (robot, method, backend) that can run here; the rest is listed as skipped with why."""
    runners: list[Runner] = []
    skipped: list[str] = []
    defaults: dict[tuple[str, str], str] = {}
    for key in config.robots:
        sc = SCENARIOS[key]()
        for method in config.methods:
            opts = dict(config.resolver_options.get(method, {}))
            if method in ("pinv", "feedback"):
                runners.append(RedundikRunner(sc, method, None, opts))
            elif method in ("wqp", "hqp"):
                if method not in RESOLVERS:
                    skipped.append(f"{key}/{method}: resolver '{method}' is not registered (QP resolvers missing)")
                    continue
                try:
                    default = RedundikRunner(sc, method, None, opts)
                except RedundikError as exc:
                    skipped.append(f"{key}/{method}: {exc}")
                    continue
                defaults[(key, method)] = default.backend
                for b in config.qp_backends if config.qp_backends is not None else QP_BACKENDS:
                    if b == default.backend:
                        runners.append(default)
                        continue
                    try:
                        runners.append(RedundikRunner(sc, method, b, opts))
                    except RedundikError as exc:
                        skipped.append(f"{key}/{method}/{b}: {exc}")
                if not any(r is default for r in runners) and config.qp_backends is None:
                    runners.append(default)
            else:
                if not (available(method) and (method != "mink" or available("mujoco"))):
                    skipped.append(f"{key}/{method}: not installed (install redundik[peers])")
                    continue
                import qpsolvers

                for b in config.peer_backends:
                    if b not in qpsolvers.available_solvers:
                        skipped.append(f"{key}/{method}/{b}: qpsolvers backend not installed")
                        continue
                    try:
                        runners.append(MinkRunner(sc, b) if method == "mink" else PinkRunner(sc, b))
                    except Exception as exc:  # a peer that cannot be set up is reported, not fatal
                        skipped.append(f"{key}/{method}/{b}: {type(exc).__name__}: {exc}")
        log(f"  {key}: {sum(r.scenario.key == key for r in runners)} cases")
    return runners, skipped, {f"{k[0]}/{k[1]}": v for k, v in defaults.items()}


# ---------------------------------------------------------------------------------------------------------- running
def run_benchmark(config: BenchConfig, log: Callable[[str], None] = print) -> BenchResult:
    """Build every case, run warm-up and timed steps round-robin, profile redundik's methods, summarise.

    Raises:
        ConfigError: a bad configuration.
    """
    config.check()
    t_start = time.perf_counter()
    log(f"building cases for {list(config.robots)} × {list(config.methods)}")
    runners, skipped, defaults = build_cases(config, log)
    total = config.warmup + config.steps
    done = 0
    rnd = 0
    log(f"running {len(runners)} cases × {total} steps round-robin in chunks of {config.chunk}")
    while done < total:
        n = min(config.chunk, total - done)
        order = runners[rnd % len(runners) :] + runners[: rnd % len(runners)] if runners else []
        for r in order:
            r.run(n)
        done += n
        rnd += 1
    cases: list[CaseResult] = []
    for r in runners:
        cases.append(_summarise(r, config.warmup, defaults))
    if config.profile_steps > 0:
        log(f"profiling redundik's methods ({config.profile_steps} steps each, round-robin)")
        prof_runners = [r for r in runners if isinstance(r, RedundikRunner)]
        stages: dict[int, dict[str, list[float]]] = {id(r): {} for r in prof_runners}
        per = max(config.profile_steps // 5, 1)
        for _ in range(5):
            for r in prof_runners:
                try:
                    for key, val in r.profile(per).items():
                        stages[id(r)].setdefault(key, []).append(val)
                except Exception as exc:  # profiling must not kill the report
                    log(f"  profile of {r.label} failed: {exc}")
        for r, c in zip(runners, cases, strict=True):
            if id(r) in stages and stages[id(r)]:
                c.stages_us = {k: float(np.median(v)) for k, v in stages[id(r)].items()}
    meta = {
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "steps": config.steps,
        "warmup": config.warmup,
        "chunk": config.chunk,
        "robots": list(config.robots),
        "methods": list(config.methods),
        "default_backends": defaults,
        "wall_time_s": time.perf_counter() - t_start,
        "versions": _versions(),
    }
    return BenchResult(cases, skipped, meta)


def _summarise(r: Runner, warmup: int, defaults: dict[str, str]) -> CaseResult:
    rec = r.record
    times = np.asarray(rec.step_ns[warmup:], dtype=float) / 1e3
    ok = times[times > 0] if np.any(times > 0) else times
    viol = np.asarray(rec.violation)
    err = np.asarray(rec.task_error)
    mon = np.asarray(rec.monitor)
    backend = r.backend
    case = CaseResult(
        robot=r.scenario.key,
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
        subtask_label=r.scenario.monitor_label,
        failures=rec.failures,
        steps=len(rec.step_ns),
        default_backend=defaults.get(f"{r.scenario.key}/{r.method}") == backend,
        first_failure=rec.first_failure,
        qp_fraction=rec.qp_steps / max(len(rec.step_ns), 1) if r.method in ("wqp", "hqp") else None,
        fallback_steps=rec.fallbacks,
        first_fallback=rec.first_fallback,
        frozen_steps=rec.frozen,
        error_tolerance=r.scenario.error_tolerance,
    )
    case.status = case_status(case)
    return case


def summarise(r: Runner, warmup: int = 0, defaults: dict[str, str] | None = None) -> CaseResult:
    """The :class:`CaseResult` of a runner that has run (timings after ``warmup`` steps), with its status."""
    return _summarise(r, warmup, defaults or {})


def case_status(c: CaseResult) -> str:
    """``"ok"``, or ``"failed: "`` and every reason, for a case whose numbers cannot be compared honestly:

    * its stacked frame-task error exceeds the scenario's tolerance (``error_tolerance``, 1 mm / 1 mrad);
    * its robot does not move on more than 1 % of the steps (q unchanged to 1e-12; every reference moves);
    * it falls back (``StepResult.fallback``) or raises on more than 1 % of the steps;
    * it breaks the joint limits by more than 1e-5 rad (the limits are part of every scenario's task).

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
    return "ok" if not reasons else "failed: " + "; ".join(reasons)


def _versions() -> dict[str, str]:
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
    return out

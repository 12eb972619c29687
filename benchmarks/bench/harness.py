"""Run the comparison: build the cases from a robot and method list, step them round-robin in chunks, summarise.

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

from benchmarks.bench import batch as batch_case
from benchmarks.bench.cases import CaseResult, case_status, summarise, summarise_case, versions
from benchmarks.bench.cold_start import run_cold_start
from benchmarks.bench.peer_runners import MinkRunner, MinkShelfRunner, PinkRunner, PinkShelfRunner
from benchmarks.bench.placo_peer import PlacoRunner, find_placo_python
from benchmarks.bench.runners import RedundikRunner
from benchmarks.bench.scenarios import SCENARIOS as BUILTIN_SCENARIOS
from benchmarks.bench.scenarios import SNAKE_SIZES
from benchmarks.bench.user_scenarios import BASELINES, PEERS_OF, USER_SCENARIOS, custom_task_evaluate_us
from redundik.errors import ConfigError, RedundikError
from redundik.peers._deps import available
from redundik.resolvers.registry import RESOLVERS

#: Methods in report order; ``method`` values of the JSON.
METHODS: tuple[str, ...] = (
    "pinv", "feedback", "wqp", "hqp", "mink", "pink", "placo",
    "wqp_batch", "wqp_steps", "wqp_loop", "pinv_batch", "pinv_steps", "pinv_loop",
)  # fmt: skip
#: Methods of the batch case (only there): the batch, a loop of ordinary steps, the contract's reset loop.
BATCH_METHODS: tuple[str, ...] = batch_case.METHODS
#: Every scenario: the built-in ones and the user cases (:mod:`benchmarks.bench.user_scenarios`).
SCENARIOS = {**BUILTIN_SCENARIOS, **USER_SCENARIOS}
#: The cold-start case (subprocesses on an empty kernel cache; :mod:`benchmarks.bench.cold_start`).
COLD_START = "cold_start"
#: Robots (``robot`` values of the JSON) in report order: every case of a full run.
ROBOTS: tuple[str, ...] = (
    "panda_circle", "panda_teleop", "panda_user_task", "panda_custom_task", "panda_tight", "talos", "talos_teleop",
    "talos_actuated", *(f"snake{n}" for n in SNAKE_SIZES), batch_case.ROBOT_KEY, "panda_shelf", COLD_START,
)  # fmt: skip
#: The robots of ``--quick``.
QUICK_ROBOTS: tuple[str, ...] = (
    "panda_circle", "panda_teleop", "panda_user_task", "panda_custom_task", "talos", "talos_teleop", "snake10",
    "snake80", batch_case.ROBOT_KEY, COLD_START,
)  # fmt: skip
#: Every robot the harness knows (``planar3r``, the chapter's 3R arm, only on request).
KNOWN_ROBOTS: tuple[str, ...] = (*ROBOTS, "planar3r")
#: Steps (calls of 1000 problems) of the batch case, warm-up excluded, and its warm-up.
BATCH_STEPS, BATCH_WARMUP = 20, 2
#: The peers (not redundik's methods).
PEERS: tuple[str, ...] = ("mink", "pink", "placo")
#: QP backends tried for wqp/hqp (each one that the resolver accepts and is installed becomes a case).
QP_BACKENDS: tuple[str, ...] = ("osqp", "proxsuite", "daqp", "quadprog")
#: Backends tried for the peers (their fastest is used in the ratios).
PEER_BACKENDS: tuple[str, ...] = ("daqp", "quadprog")


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
        placo_python: PlaCo's interpreter (``None``: ``$REDUNDIK_PLACO_PYTHON`` or the checkout's ``.venv-placo``).
        batch_steps: Timed calls of the batch case (each resolving 1000 problems).
        batch_problems: Problems of the batch case.
    """

    robots: Sequence[str] = ROBOTS
    methods: Sequence[str] = METHODS
    steps: int = 2000
    warmup: int = 200
    chunk: int = 50
    qp_backends: Sequence[str] | None = None
    peer_backends: Sequence[str] = PEER_BACKENDS
    profile_steps: int = 400
    resolver_options: dict[str, dict[str, Any]] = field(default_factory=dict)
    placo_python: str | None = None
    batch_steps: int = BATCH_STEPS
    batch_problems: int = batch_case.N_PROBLEMS
    #: ``cold_start``: the methods whose first step is timed in fresh subprocesses.
    cold_start_methods: Sequence[str] = ("pinv", "wqp", "hqp")
    #: ``cold_start``: ``"cold"`` (an empty cache, then warm), ``"warm"`` (the user's cache only) or ``"off"``.
    cold_start: str = "cold"

    @classmethod
    def quick(cls, steps: int = 300) -> BenchConfig:
        """A short run (a few minutes, much of it the cold start's compile on an empty cache): the quick robots,
        fewer steps, the default QP backend, the peers on daqp only, the cold start of ``wqp`` only."""
        return cls(
            robots=QUICK_ROBOTS, steps=steps, warmup=30, chunk=50, qp_backends=("daqp",), peer_backends=("daqp",),
            profile_steps=100, batch_steps=4, cold_start_methods=("wqp",),
        )  # fmt: skip

    def check(self) -> None:
        """Raise :class:`ConfigError` on unknown robots/methods or non-positive counts."""
        bad = [r for r in self.robots if r not in KNOWN_ROBOTS]
        if bad:
            raise ConfigError(f"unknown robots {bad}; available: {list(KNOWN_ROBOTS)}", "robots")
        bad = [m for m in self.methods if m not in METHODS]
        if bad:
            raise ConfigError(f"unknown methods {bad}; available: {list(METHODS)}", "methods")
        for key in ("steps", "chunk", "batch_steps", "batch_problems"):
            if getattr(self, key) < 1:
                raise ConfigError(f"must be ≥ 1, got {getattr(self, key)}", key)
        if self.warmup < 0 or self.profile_steps < 0:
            raise ConfigError("must be ≥ 0", "warmup/profile_steps")
        if self.cold_start not in ("cold", "warm", "off"):
            raise ConfigError(f"must be 'cold', 'warm' or 'off', got {self.cold_start!r}", "cold_start")


@dataclass
class BenchResult:
    """Everything one run produced."""

    cases: list[CaseResult]
    skipped: list[str]
    meta: dict[str, Any]
    #: The ``cold_start`` records (:func:`benchmarks.bench.cold_start.run_cold_start`).
    cold_start: list[dict[str, Any]] = field(default_factory=list)

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
        """The faster of mink and pink (each with its fastest backend) on ``robot`` (on the robot whose identical
        task set they ran, :data:`PEERS_OF`; ``None`` where no peer runs the task set)."""
        robot = PEERS_OF.get(robot, robot)  # type: ignore[assignment]
        if robot is None:
            return None
        peers = [c for c in (self.fastest(robot, "mink"), self.fastest(robot, "pink")) if c is not None]
        return min(peers, key=lambda c: c.median_us) if peers else None

    def ratios(self) -> list[dict[str, Any]]:
        """Median of every redundik case that did not fail over the faster (non-failed) of mink and pink, per robot,
        and over PlaCo's where it ran (``ratio_placo``); a user case also over its built-in case (``ratio_builtin``,
        :data:`BASELINES`); ``path`` is the case's ``result.info["path"]``."""
        out = []
        for c in self.cases:
            if c.method in PEERS or not c.ok or c.method in BATCH_METHODS:
                continue
            peer = self.faster_peer(c.robot)
            placo = self.placo(c.robot)
            base = self.builtin(c)
            if (peer is None or peer.median_us <= 0) and placo is None and base is None:
                continue
            out.append(
                {
                    "robot": c.robot,
                    "method": c.method,
                    "backend": c.backend,
                    "peer": None if peer is None else f"{peer.method}/{peer.backend}",
                    "ratio": None if peer is None else c.median_us / peer.median_us,
                    "ratio_placo": None if placo is None else c.median_us / placo.median_us,
                    "builtin": None if base is None else base.robot,
                    "ratio_builtin": None if base is None else c.median_us / base.median_us,
                    "path": c.extra.get("path"),
                }
            )
        return out

    def placo(self, robot: str) -> CaseResult | None:
        """PlaCo's case for ``robot``'s task set (:data:`PEERS_OF`), if it ran and did not fail."""
        peer_robot = PEERS_OF.get(robot, robot)
        return None if peer_robot is None else self.fastest(peer_robot, "placo")

    def builtin(self, c: CaseResult) -> CaseResult | None:
        """A user case's built-in case (:data:`BASELINES`): same method and backend, same run, not failed."""
        robot = BASELINES.get(c.robot)
        if robot is None:
            return None
        found = [b for b in self.find(robot, c.method, c.backend) if b.ok and b.median_us > 0]
        return found[0] if found else None

    def snake_fit(self, method: str) -> dict[str, Any]:
        """Growth exponent b of median ∝ n^b (least squares in log–log over the snake cases that did not fail) and
        p90/median at every n."""
        pts = []
        for n in SNAKE_SIZES:
            c = _ok(self.default(f"snake{n}", method))
            if c is not None and c.median_us > 0:
                pts.append((n, c.median_us, c.p90_us, c.qp_fraction))
        out: dict[str, Any] = {"method": method, "n": [p[0] for p in pts], "median_us": [p[1] for p in pts]}
        out["p90_us"] = [p[2] for p in pts]
        out["p90_over_median"] = [p[2] / p[1] for p in pts]
        out["qp_fraction"] = [p[3] for p in pts]
        logn = np.log([p[0] for p in pts])
        out["exponent"] = float(np.polyfit(logn, np.log(out["median_us"]), 1)[0]) if len(pts) >= 2 else None
        out["exponent_p90"] = float(np.polyfit(logn, np.log(out["p90_us"]), 1)[0]) if len(pts) >= 2 else None
        return out

    def targets(self) -> list[dict[str, Any]]:
        """The issue's performance targets (issue 11), each with the value measured in this run and whether it is met
        (``None``: not measured here, or a case it needs failed)."""
        out: list[dict[str, Any]] = []

        def add(name: str, value: float | None, limit: float, unit: str, detail: str, kind: str = "max") -> None:
            met = None if value is None else bool(value <= limit if kind == "max" else value >= limit)
            out.append(
                {"target": name, "value": value, "limit": limit, "unit": unit, "kind": kind, "met": met,
                 "detail": detail}
            )  # fmt: skip

        def ratio(a: CaseResult | None, b: CaseResult | None) -> float | None:
            return None if a is None or b is None or b.median_us <= 0 else a.median_us / b.median_us

        peer = self.faster_peer("panda_circle")
        placo = self.fastest("panda_circle", "placo")
        wqp = _ok(self.default("panda_circle", "wqp"))
        add("panda_circle: wqp ≤ 0.20 × faster of mink/pink", ratio(wqp, peer), 0.20, "ratio", _detail(wqp, peer))
        add("panda_circle: wqp ≤ 2 × PlaCo", ratio(wqp, placo), 2.0, "ratio", _detail(wqp, placo))
        pinv = _ok(self.default("panda_circle", "pinv"))
        add(
            "panda_circle: pinv (null-space subtask) ≤ 0.12 × faster of mink/pink",
            ratio(pinv, peer), 0.12, "ratio", _detail(pinv, peer),
        )  # fmt: skip
        hqp = _ok(self.default("panda_circle", "hqp"))
        add(
            "panda_circle: 3-level hqp, inequality inactive ≤ 0.30 × faster of mink/pink",
            ratio(hqp, peer), 0.30, "ratio", _detail(hqp, peer),
        )  # fmt: skip
        peer_t = self.faster_peer("panda_tight")
        hqp_t = _ok(self.default("panda_tight", "hqp"))
        add(
            "panda_tight: 3-level hqp, a limit active ≤ 0.60 × faster of mink/pink",
            ratio(hqp_t, peer_t), 0.60, "ratio", _detail(hqp_t, peer_t),
        )  # fmt: skip
        wqp_h = _ok(self.default("talos", "wqp"))
        placo_h = self.fastest("talos", "placo")
        add("talos: wqp ≤ 1 × PlaCo", ratio(wqp_h, placo_h), 1.0, "ratio", _detail(wqp_h, placo_h))
        for method in ("wqp", "hqp"):
            fit = self.snake_fit(method)
            sizes = ", ".join(f"n={n}: {m:.0f} µs" for n, m in zip(fit["n"], fit["median_us"], strict=True))
            if fit["exponent_p90"] is not None:
                sizes += f" (p90 grows as n^{fit['exponent_p90']:.2f})"
            add(f"snake: {method} growth exponent ≤ 1.3", fit["exponent"], 1.3, "exponent", sizes or "not measured")
        for method in ("pinv", "wqp", "hqp"):
            fit = self.snake_fit(method)
            worst = max(fit["p90_over_median"]) if fit["p90_over_median"] else None
            each = ", ".join(f"{n}: {r:.2f}" for n, r in zip(fit["n"], fit["p90_over_median"], strict=True))
            add(f"snake: {method} p90/median ≤ 2.5 at every n", worst, 2.5, "ratio", each or "not measured")
        for res in ("wqp", "pinv"):
            b = _ok(self.fastest(batch_case.ROBOT_KEY, f"{res}_batch"))
            lo = _ok(self.fastest(batch_case.ROBOT_KEY, f"{res}_steps"))
            speed = None if b is None or lo is None or not lo.problems_per_s else b.problems_per_s / lo.problems_per_s  # type: ignore[operator]
            detail = (
                "not measured (or FAILED)" if speed is None
                else f"{b.problems_per_s:.0f} vs {lo.problems_per_s:.0f} problems/s"  # type: ignore[union-attr]
            )  # fmt: skip
            add(
                f"{batch_case.ROBOT_KEY}: {res} batch ≥ 10 × a loop of ordinary steps' problems/s",
                speed, 10.0, "ratio", detail, "min",
            )  # fmt: skip
        self._user_targets(add, ratio)
        return out

    def _user_targets(self, add: Callable[..., None], ratio: Callable[..., float | None]) -> None:
        """Issue 31's targets: teleop and a user's subclass against the built-in case, PlaCo, the cold start."""
        for robot, limit in (("panda_teleop", 1.15), ("panda_user_task", 1.05)):
            for method in ("pinv", "wqp", "hqp"):
                c = _ok(self.default(robot, method))
                b = None if c is None else self.builtin(c)
                what = "the trajectory tick" if robot.endswith("teleop") else "the built-in FrameTask"
                add(f"{robot}: {method} ≤ {limit} × {what} (issue 31)", ratio(c, b), limit, "ratio", _detail(c, b))
        own = self.meta.get("custom_task_evaluate_us")
        for method in ("pinv", "wqp", "hqp") if own is not None else ():
            c = _ok(self.default("panda_custom_task", method))
            b = None if c is None else self.builtin(c)
            value = None if c is None or b is None else (c.median_us - b.median_us) / (own + 0.1 * b.median_us)
            detail = "not measured (or FAILED)" if c is None or b is None else (
                f"{c.median_us:.1f} − {b.median_us:.1f} µs added, its evaluate {own:.1f} µs + 10 % of the built-in"
            )  # fmt: skip
            add(f"panda_custom_task: {method} adds ≤ its evaluate + 10 % (issue 31)", value, 1.0, "ratio", detail)
        for robot in ("panda_circle", "panda_teleop"):
            for method, limit in (("pinv", 1.2), ("wqp", 1.5), ("hqp", 2.0)):
                c, p = _ok(self.default(robot, method)), self.placo(robot)
                add(f"{robot}: {method} ≤ {limit} × PlaCo (issue 31)", ratio(c, p), limit, "ratio", _detail(c, p))
        for rec in self.cold_start:
            if rec.get("method") != "wqp" or rec.get("status") != "ok":
                continue
            for key, limit in (("cold_first_dq_s", 3.0), ("warm_first_dq_s", 0.3)):
                value = rec.get(key)
                what = "empty cache" if key.startswith("cold") else "warm cache"
                add(f"cold_start: wqp first q̇ ({what}) ≤ {limit} s (issue 31)", value, limit, "s",
                    "fresh subprocess: import + set-up + first step")  # fmt: skip


def _ok(c: CaseResult | None) -> CaseResult | None:
    return c if c is not None and c.ok else None


def _detail(a: CaseResult | None, b: CaseResult | None) -> str:
    if a is None or b is None:
        return "not measured (or FAILED)"
    return f"{a.method}/{a.backend} {a.median_us:.1f} µs vs {b.method}/{b.backend} {b.median_us:.1f} µs"


# ---------------------------------------------------------------------------------------------------------- building
AnyRunner = Any  # a Runner, or a batch_case.BatchRunner (duck-typed: run, close, label, method, backend)


def build_cases(
    config: BenchConfig, log: Callable[[str], None] = print
) -> tuple[list[AnyRunner], list[str], dict[str, Any]]:
    """One runner per (robot, method, backend) that can run here; the rest is listed as skipped with why."""
    runners: list[AnyRunner] = []
    skipped: list[str] = []
    defaults: dict[tuple[str, str], str] = {}
    placo_python: str | None = None
    placo_why = ""
    if "placo" in config.methods:
        placo_python, placo_why = find_placo_python(config.placo_python)
        if placo_python is not None:
            log(f"  PlaCo interpreter: {placo_python} ({placo_why})")
    for key in config.robots:
        n_before = len(runners)
        if key == COLD_START:
            continue  # run after the interleaved cases, in subprocesses (run_benchmark)
        if key == batch_case.ROBOT_KEY:
            for method in BATCH_METHODS:
                if method in config.methods:
                    runners.append(batch_case.BatchRunner(method, config.batch_problems))
                    defaults[(key, method)] = runners[-1].backend
            log(f"  {key}: {len(runners) - n_before} cases")
            continue
        sc = SCENARIOS[key]()
        for method in config.methods:
            if method in BATCH_METHODS or (sc.methods is not None and method not in sc.methods):
                continue
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
                backends = config.qp_backends if config.qp_backends is not None else QP_BACKENDS
                if not sc.all_backends:
                    backends = (default.backend,)
                for b in backends:
                    if b == default.backend:
                        runners.append(default)
                        continue
                    try:
                        runners.append(RedundikRunner(sc, method, b, opts))
                    except RedundikError as exc:
                        skipped.append(f"{key}/{method}/{b}: {exc}")
                if not any(r is default for r in runners):
                    runners.append(default)
            elif method == "placo":
                if not sc.placo:
                    continue
                if placo_python is None:
                    skipped.append(f"{key}/placo: {placo_why}")
                    continue
                try:
                    runners.append(PlacoRunner(sc, placo_python))
                except Exception as exc:  # a peer that cannot be set up is reported, not fatal
                    skipped.append(f"{key}/placo: {type(exc).__name__}: {exc}")
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
        if key == "panda_shelf":  # the peers on the same collision geometry (runners.PinkShelfRunner/MinkShelfRunner)
            import qpsolvers

            for method, cls in (("mink", MinkShelfRunner), ("pink", PinkShelfRunner)):
                if method not in config.methods:
                    continue
                if not (available(method) and (method != "mink" or available("mujoco"))):
                    skipped.append(f"{key}/{method}: not installed (install redundik[peers])")
                    continue
                for b in config.peer_backends:
                    if b not in qpsolvers.available_solvers:
                        continue
                    try:
                        runners.append(cls(sc, b))
                    except Exception as exc:  # a peer that cannot be set up is reported, not fatal
                        skipped.append(f"{key}/{method}/{b}: {type(exc).__name__}: {exc}")
        log(f"  {key}: {len(runners) - n_before} cases")
    return runners, skipped, {f"{k[0]}/{k[1]}": v for k, v in defaults.items()}


def _plan(r: AnyRunner, config: BenchConfig) -> tuple[int, int]:
    """(warm-up, timed) steps of a runner: the batch case's own counts, the scenario's step factor otherwise."""
    if isinstance(r, batch_case.BatchRunner):
        return BATCH_WARMUP, config.batch_steps
    f = r.scenario.step_factor
    return max(round(config.warmup * f), 1 if config.warmup else 0), max(round(config.steps * f), 1)


# ---------------------------------------------------------------------------------------------------------- running
def run_benchmark(config: BenchConfig, log: Callable[[str], None] = print) -> BenchResult:
    """Build every case, run warm-up and timed steps round-robin, profile redundik's methods, summarise.

    Every case advances by its chunk in turn (the order rotating each round); a case with fewer steps (the slow
    snakes, the batch calls) gets a proportionally smaller chunk, so all cases run over the same rounds.

    Raises:
        ConfigError: a bad configuration.
    """
    config.check()
    t_start = time.perf_counter()
    log(f"building cases for {list(config.robots)} × {list(config.methods)}")
    runners, skipped, defaults = build_cases(config, log)
    try:
        plans = [_plan(r, config) for r in runners]
        totals = [w + s for w, s in plans]
        rounds = max(-(-(config.warmup + config.steps) // config.chunk), 1)
        chunks = [max(-(-t // rounds), 1) for t in totals]
        done = [0] * len(runners)
        log(f"running {len(runners)} cases round-robin over {rounds} rounds (chunk {config.chunk} steps)")
        rnd = 0
        while any(d < t for d, t in zip(done, totals, strict=True)):
            k = rnd % len(runners)
            for i in list(range(k, len(runners))) + list(range(k)):
                n = min(chunks[i], totals[i] - done[i])
                if n > 0:
                    runners[i].run(n)
                    done[i] += n
            rnd += 1
        cases = [summarise_case(r, w, defaults) for r, (w, _) in zip(runners, plans, strict=True)]
        if config.profile_steps > 0:
            _profile(runners, cases, config, log)
    finally:
        for r in runners:
            r.close()
    extra: dict[str, Any] = {}
    if "panda_custom_task" in config.robots:  # the user task's own evaluate, for its target (a tight loop)
        extra["custom_task_evaluate_us"] = custom_task_evaluate_us()
    cold: list[dict[str, Any]] = []
    if COLD_START in config.robots and config.cold_start != "off":
        log(f"cold start of {list(config.cold_start_methods)} ({config.cold_start}), one fresh process at a time")
        peers = tuple(p for p in ("mink", "pink") if p in config.methods)
        cold = run_cold_start(config.cold_start_methods, config.cold_start, peers)
    meta = {
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "steps": config.steps,
        "warmup": config.warmup,
        "chunk": config.chunk,
        "batch_steps": config.batch_steps,
        "robots": list(config.robots),
        "methods": list(config.methods),
        "default_backends": defaults,
        "wall_time_s": time.perf_counter() - t_start,
        "versions": versions(runners),
        **extra,
    }
    return BenchResult(cases, skipped, meta, cold)


def _profile(
    runners: list[AnyRunner], cases: list[CaseResult], config: BenchConfig, log: Callable[[str], None]
) -> None:
    """The per-stage profile of redundik's methods (separate probed steps, round-robin) into ``stages_us``."""
    log(f"profiling redundik's methods ({config.profile_steps} steps each, round-robin)")
    prof = [(r, c) for r, c in zip(runners, cases, strict=True) if isinstance(r, RedundikRunner)]
    stages: dict[int, dict[str, list[float]]] = {id(r): {} for r, _ in prof}
    for _ in range(5):
        for r, _ in prof:
            per = max(int(config.profile_steps * r.scenario.step_factor) // 5, 1)
            try:
                for key, val in r.profile(per).items():
                    stages[id(r)].setdefault(key, []).append(val)
            except Exception as exc:  # profiling must not kill the report
                log(f"  profile of {r.label} failed: {exc}")
    for r, c in prof:
        if stages[id(r)]:
            c.stages_us = {k: float(np.median(v)) for k, v in stages[id(r)].items()}


__all__ = [  # (CaseResult, case_status and summarise live in benchmarks.bench.cases; re-exported here)
    "BATCH_METHODS", "KNOWN_ROBOTS", "METHODS", "QUICK_ROBOTS", "ROBOTS", "BenchConfig", "BenchResult", "CaseResult",
    "case_status", "run_benchmark", "summarise",
]  # fmt: skip

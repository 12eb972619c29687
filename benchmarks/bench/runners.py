"""One benchmark case = one runner: a method (redundik resolver or peer) stepping one scenario, timed per step.

The timed region of a step is what a control loop pays per tick, the same for every method: the kinematics update
at q, sampling the references, building and solving the problem — never the integration q ⊕ q̇·dt nor the
metrics. Metrics (tracking error, subtask value, limit violations) are computed afterwards on a separate redundik
model with the same frame tasks, so every method is measured by the same ruler.
"""

from __future__ import annotations

import copy
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from benchmarks.bench.scenarios import Scenario
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import Resolver
from redundik.resolvers.fused import plan_of
from redundik.resolvers.registry import make_resolver
from redundik.resolvers.result import StepResult
from redundik.tasks.base import Barrier, Potential, Task, TaskTerm
from redundik.tasks.stack import TaskStack
from redundik.tasks.subtasks import Subtask

_ns = time.perf_counter_ns

#: A step that changes no coordinate of q by more than this counts as "the robot did not move" [rad or m].
FROZEN_STEP = 1e-12


@dataclass
class Record:
    """Per-step records of a runner (appended as it runs)."""

    step_ns: list[int] = field(default_factory=list)
    task_error: list[float] = field(default_factory=list)
    monitor: list[float] = field(default_factory=list)
    violation: list[float] = field(default_factory=list)
    failures: int = 0
    qp_steps: int = 0
    #: Per step, whether the resolver called its QP backend (False for the peers and the closed forms).
    qp_flags: list[bool] = field(default_factory=list)
    first_failure: str | None = None
    fallbacks: int = 0
    first_fallback: str | None = None
    frozen: int = 0
    stages: dict[str, list[int]] = field(default_factory=dict)
    #: redundik's steps per ``result.info["path"]`` and the union of their ``info["interpreted"]`` names.
    paths: dict[str, int] = field(default_factory=dict)
    interpreted: set[str] = field(default_factory=set)


class Metrics:
    """The common ruler: frame-task errors, the monitored potential and limit violations, on its own model."""

    def __init__(self, scenario: Scenario) -> None:
        self.robot = scenario.robot()
        self.tasks = scenario.frame_tasks(gain=0.0)
        self.monitor = scenario.monitor()
        self.reset(scenario.q0)

    def reset(self, q0: np.ndarray) -> None:
        """Anchor the references at q0 (start of an episode)."""
        self.robot.update(q0)
        for task in self.tasks:
            task.reset(self.robot)
        self.monitor.check(self.robot)

    def task_error(self, q: np.ndarray, t: float) -> float:
        """Norm of the stacked frame-task errors at (q, t)."""
        self.robot.update(q)
        return float(np.sqrt(sum(task.evaluate(self.robot, t).error_norm ** 2 for task in self.tasks)))

    def after_step(self, q: np.ndarray) -> tuple[float, float]:
        """(monitored potential, largest limit violation) at the configuration reached by a step."""
        self.robot.update(q)
        return float(self.monitor.value(self.robot)), float(np.max(self.robot.limit_violation(q), initial=0.0))


class Runner(ABC):
    """Steps one scenario with one method; :meth:`run` advances it by a chunk of steps."""

    method: str
    backend: str

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self.metrics = Metrics(scenario)
        self.record = Record()
        self._qp_now = False  # the step being recorded called a QP backend
        self.k = 0  # step within the episode
        self.q = scenario.q0.copy()

    @property
    def label(self) -> str:
        """``robot/method/backend``."""
        return f"{self.scenario.key}/{self.method}/{self.backend}"

    def restart(self) -> None:
        """Start a new episode at q0."""
        self.k = 0
        self.q = self.scenario.q0.copy()
        self.metrics.reset(self.q)
        self._restart()

    def run(self, steps: int) -> None:
        """Advance by ``steps`` control ticks (restarting episodes as the scenario says). The chunk's steps are
        scored by the common ruler after the chunk, as PlaCo's worker chunks are: nothing but the method's own
        work runs between two timed steps of one runner."""
        sc, rec = self.scenario, self.record
        taken: list[tuple[float, np.ndarray, np.ndarray]] = []
        for _ in range(steps):
            if sc.episode is not None and self.k >= sc.episode:
                self._score(taken)  # (the ruler is anchored per episode)
                self.restart()
            t = self.k * sc.dt
            try:
                elapsed, q_next = self._step(t)
            except Exception as exc:  # a method that raises is counted, never stops the benchmark
                rec.failures += 1
                if rec.first_failure is None:
                    rec.first_failure = f"{type(exc).__name__}: {exc}"
                elapsed, q_next = 0, self.q
            rec.step_ns.append(elapsed)
            rec.qp_flags.append(self._qp_now)
            self._qp_now = False
            taken.append((t, self.q, q_next))
            self.q = q_next
            self.k += 1
        self._score(taken)

    def _score(self, taken: list[tuple[float, np.ndarray, np.ndarray]]) -> None:
        """The common ruler on the steps ``taken`` (t, q before, q after), in order; ``taken`` is emptied."""
        rec, metrics = self.record, self.metrics
        for t, q, q_next in taken:
            if float(np.max(np.abs(q_next - q), initial=0.0)) <= FROZEN_STEP:
                rec.frozen += 1  # the robot did not move this step (every scenario's references move)
            rec.task_error.append(metrics.task_error(q, t))
            value, viol = metrics.after_step(q_next)
            rec.monitor.append(value)
            rec.violation.append(viol)
        taken.clear()

    def record_step(self, t: float, elapsed: int, q_next: np.ndarray) -> None:
        """Record one step taken at time t from self.q to ``q_next`` in ``elapsed`` ns and score it (a runner whose
        chunk ran elsewhere: PlaCo's worker)."""
        rec = self.record
        rec.step_ns.append(elapsed)
        rec.qp_flags.append(self._qp_now)
        self._qp_now = False
        self._score([(t, self.q, q_next)])
        self.q = q_next
        self.k += 1

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release what the runner holds (a worker process)."""

    @abstractmethod
    def _step(self, t: float) -> tuple[int, np.ndarray]:
        """One timed step at time t from self.q: (elapsed [ns], next configuration in redundik coordinates)."""

    def _restart(self) -> None:  # noqa: B027 - optional hook
        """Method-specific reset at the start of an episode."""


# ---------------------------------------------------------------------------------------------------------- redundik
class RedundikRunner(Runner):
    """A redundik resolver from the registry: ``resolver.step(robot, stack, q, t, dt)`` is the timed region."""

    def __init__(self, scenario: Scenario, method: str, backend: str | None, options: dict[str, Any]) -> None:
        super().__init__(scenario)
        self.method = method
        self.options = dict(options)
        if backend is not None:
            self.options["backend"] = backend
        self.resolver: Resolver = make_resolver(method, **self.options)
        self.last_result: StepResult | None = None  # the last step's result, held as a control loop holds it
        used = getattr(self.resolver, "backend", None)
        self.backend = backend or str(getattr(used, "name", used) or "-")
        self.robot = scenario.robot() if scenario.runner_robot is None else scenario.runner_robot()
        self.stack = scenario.stack(method, self.robot)
        self._restart()

    def _restart(self) -> None:
        self.robot.update(self.q)
        self.stack = self.scenario.stack(self.method, self.robot)
        self.stack.reset(self.robot)
        self.resolver.reset()
        self.resolver.check(self.robot, self.stack)

    def _step(self, t: float) -> tuple[int, np.ndarray]:
        dt = self.scenario.dt
        poses = teleop_poses(self.metrics.tasks, t + dt) if self.scenario.teleop else None  # the operator's
        t0 = _ns()
        if poses is not None:  # teleop: set_target every tick, inside the timed tick
            for task, pose in zip(self.stack.tasks, poses, strict=False):
                task.set_target(pose)  # type: ignore[attr-defined]  # the scenario's frame tasks come first
        res = self.resolver.step(self.robot, self.stack, self.q, t, dt)
        t1 = _ns()
        self.last_result = res  # (a user's loop ``res = step(...)`` holds its last result while it steps)
        info = res.info
        path = str(info.get("path", "?"))
        self.record.paths[path] = self.record.paths.get(path, 0) + 1
        self.record.interpreted.update(info.get("interpreted", ()))
        if info.get("qp", 0):  # wqp/hqp: a backend was called (0 = closed-form shortcut, no active constraint)
            self.record.qp_steps += 1
            self._qp_now = True
        if res.fallback is not None:
            self.record.fallbacks += 1
            if self.record.first_fallback is None:
                self.record.first_fallback = f"t = {t:.3f} s: {res.fallback}"
        return t1 - t0, self.robot.integrate(self.q, res.dq, dt)

    def _retarget(self, t: float) -> None:
        """Teleop cases, in the profile's probed steps: the targets of t + dt set before the probes start."""
        if self.scenario.teleop:
            for task, pose in zip(
                self.stack.tasks, teleop_poses(self.metrics.tasks, t + self.scenario.dt), strict=False
            ):
                task.set_target(pose)  # type: ignore[attr-defined]

    def profile(self, steps: int) -> dict[str, float]:
        """Median time per stage [µs] over ``steps`` extra steps with timing probes (not the timed run; a teleop
        case's ``set_target`` is left out of them).

        Stages: ``kinematics`` (RobotModel.update), ``tasks`` (task terms, potential values and gradients),
        ``build`` (the resolver's build time minus the task evaluation inside it), ``solve`` (its solve time),
        ``other`` (the rest of the step: results, diagnostics, Python glue).
        """
        if plan_of(self.resolver) is not None:
            return self._profile_fused(steps)
        probe = _Probe()

        def timed_stack() -> TaskStack:
            return TaskStack(
                [_TimedTask(task, probe) for task in self.stack.tasks],
                [_timed_subtask(sub, probe) for sub in self.stack.subtasks],
            )

        timed = timed_stack()
        out: dict[str, list[float]] = {k: [] for k in ("kinematics", "tasks", "build", "solve", "other", "total")}
        dt = self.scenario.dt
        for _ in range(steps):
            if self.scenario.episode is not None and self.k >= self.scenario.episode:
                self.restart()
                timed = timed_stack()
            t = self.k * dt
            self._retarget(t)
            probe.ns = 0
            t0 = _ns()
            self.robot.update(self.q)
            t1 = _ns()
            res = self.resolver.solve(self.robot, timed, t, dt)
            t2 = _ns()
            build_ns = res.build_time * 1e9
            solve_ns = res.solve_time * 1e9
            out["kinematics"].append(t1 - t0)
            out["tasks"].append(probe.ns)
            out["build"].append(max(build_ns - probe.ns, 0.0))
            out["solve"].append(solve_ns)
            out["other"].append(max((t2 - t1) - build_ns - solve_ns, 0.0))
            out["total"].append(t2 - t0)
            self.q = self.robot.integrate(self.q, res.dq, dt)
            self.k += 1
        return {k: float(np.median(v)) / 1e3 for k, v in out.items() if v}

    def _profile_fused(self, steps: int) -> dict[str, float]:
        """:meth:`profile` of a fused step (``redundik.resolvers.fused``): the tasks are evaluated inside its one
        compiled call, so ``tasks`` is 0 and ``build`` is that call (evaluation, accumulation and the closed-form
        solve, up to the box test); ``solve`` is what follows (the QP when a limit binds, the result)."""
        out: dict[str, list[float]] = {k: [] for k in ("kinematics", "tasks", "build", "solve", "other", "total")}
        dt = self.scenario.dt
        for _ in range(steps):
            if self.scenario.episode is not None and self.k >= self.scenario.episode:
                self.restart()
            t = self.k * dt
            self._retarget(t)
            t0 = _ns()
            self.robot.update(self.q)
            t1 = _ns()
            res = self.resolver.step(self.robot, self.stack, self.q, t, dt)  # updates again: its own kinematics
            t2 = _ns()
            build_ns, solve_ns = res.build_time * 1e9, res.solve_time * 1e9
            kin = t1 - t0
            out["kinematics"].append(kin)
            out["tasks"].append(0.0)
            out["build"].append(build_ns)
            out["solve"].append(solve_ns)
            out["other"].append(max((t2 - t1) - kin - build_ns - solve_ns, 0.0))
            out["total"].append(t2 - t1)
            self.q = self.robot.integrate(self.q, res.dq, dt)
            self.k += 1
        return {k: float(np.median(v)) / 1e3 for k, v in out.items() if v}


def teleop_poses(refs: list[Any], t: float) -> list[Any]:
    """The reference poses at t of the frame tasks ``refs`` (an operator's targets; made outside the timed tick)."""
    return [ref.trajectory.sample(t)[0] for ref in refs]


class _Probe:
    ns: int = 0


def _timed_subtask(sub: Subtask, probe: _Probe) -> Subtask:
    """A shallow copy of ``sub`` whose potential is timed (barriers are left as they are)."""
    out = copy.copy(sub)
    if hasattr(out, "source"):
        if isinstance(out.source, Potential) and not isinstance(out.source, Barrier):  # a barrier stays as it is
            out.source = _TimedPotential(out.source, probe)
    elif getattr(out, "potential", None) is not None:
        out.potential = _TimedPotential(out.potential, probe)  # type: ignore[attr-defined]
    return out


class _TimedTask(Task):
    def __init__(self, inner: Task, probe: _Probe) -> None:
        self.inner, self.probe = inner, probe
        self._init_task(inner.name, weight=inner.weight, gain=inner.gain, priority=inner.priority)
        self.identity_jacobian = inner.identity_jacobian  # type: ignore[misc]  # mirror the declarations
        self.regularization = inner.regularization  # type: ignore[misc]

    def reset(self, robot: RobotModel) -> None:
        self.inner.reset(robot)

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        t0 = _ns()
        term = self.inner.evaluate(robot, t)
        self.probe.ns += _ns() - t0
        return term

    def __repr__(self) -> str:
        return repr(self.inner)


class _TimedPotential(Potential):
    def __init__(self, inner: Potential, probe: _Probe) -> None:
        self.inner, self.probe, self.name = inner, probe, inner.name

    def check(self, robot: RobotModel) -> None:
        self.inner.check(robot)

    def value(self, robot: RobotModel) -> float:
        t0 = _ns()
        v = self.inner.value(robot)
        self.probe.ns += _ns() - t0
        return v

    def gradient(self, robot: RobotModel) -> np.ndarray:
        t0 = _ns()
        g = self.inner.gradient(robot)
        self.probe.ns += _ns() - t0
        return g

    def value_and_gradient(self, robot: RobotModel) -> tuple[float, np.ndarray]:
        t0 = _ns()
        vg = self.inner.value_and_gradient(robot)  # the inner potential's own fused path, as an untimed step takes
        self.probe.ns += _ns() - t0
        return vg

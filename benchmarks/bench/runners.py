"""One benchmark case = one runner: a method (redundik resolver or peer) stepping one scenario, timed per step.

The timed region of a step is what a control loop pays per tick, the same for every method: the kinematics update
at q, sampling the references, building and solving the problem — never the integration q ⊕ q̇·dt nor the
metrics. Metrics (tracking error, subtask value, limit violations) are computed afterwards on a separate redundik
model with the same frame tasks, so every method is measured by the same ruler.
"""

from __future__ import annotations

import copy
import logging
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from benchmarks.bench.scenarios import POSTURE_GAIN, POSTURE_WEIGHT, Scenario, urdf_path
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import Resolver
from redundik.resolvers.fused import plan_of
from redundik.resolvers.registry import make_resolver
from redundik.tasks.base import Barrier, Potential, Task, TaskTerm
from redundik.tasks.frame import FrameTask
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
        """Advance by ``steps`` control ticks (restarting episodes as the scenario says)."""
        sc, rec = self.scenario, self.record
        for _ in range(steps):
            if sc.episode is not None and self.k >= sc.episode:
                self.restart()
            t = self.k * sc.dt
            try:
                elapsed, q_next = self._step(t)
            except Exception as exc:  # a method that raises is counted, never stops the benchmark
                rec.failures += 1
                if rec.first_failure is None:
                    rec.first_failure = f"{type(exc).__name__}: {exc}"
                elapsed, q_next = 0, self.q
            self.record_step(t, elapsed, q_next)

    def record_step(self, t: float, elapsed: int, q_next: np.ndarray) -> None:
        """Record one step taken at time t from self.q to ``q_next`` in ``elapsed`` ns (the common ruler)."""
        rec = self.record
        rec.step_ns.append(elapsed)
        rec.qp_flags.append(self._qp_now)
        self._qp_now = False
        if float(np.max(np.abs(q_next - self.q), initial=0.0)) <= FROZEN_STEP:
            rec.frozen += 1  # the robot did not move this step (every scenario's references move)
        rec.task_error.append(self.metrics.task_error(self.q, t))
        value, viol = self.metrics.after_step(q_next)
        rec.monitor.append(value)
        rec.violation.append(viol)
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


# ---------------------------------------------------------------------------------------------------------- peers
class _PeerRunner(Runner):
    """Shared by mink and pink: frame tasks to the next reference pose (gain 1), posture, limits."""

    def __init__(self, scenario: Scenario, backend: str) -> None:
        super().__init__(scenario)
        self.backend = backend
        self.robot = scenario.robot()  # helper model for the adapters' gradients
        # the references, sampled at t + dt
        self.refs = [t for t in scenario.frame_tasks(gain=0.0) if isinstance(t, FrameTask)]
        self._build()
        self._restart()

    def _restart(self) -> None:
        self.robot.update(self.q)
        for ref in self.refs:
            ref.reset(self.robot)
        self._reset_peer()

    @abstractmethod
    def _build(self) -> None: ...

    def _reset_peer(self) -> None:
        """mink and pink: the peer's configuration from q, its posture target from q0 (other peers override)."""
        self.conf.update(self.jmap.to_peer_q(self.q))
        if self.scenario.posture:
            self.posture.set_target(self.jmap.to_peer_q(self.scenario.q0))


class MinkRunner(_PeerRunner):
    """mink on a MuJoCo model of the same robot (from the URDF, or built from the D-H model)."""

    method = "mink"

    def _build(self) -> None:
        from redundik.peers._deps import require
        from redundik.peers.joint_map import JointMap
        from redundik.simulation.mujoco_model import mujoco_from_robot, mujoco_from_urdf

        mink = require("mink")
        self.mink = mink
        sc = self.scenario
        frames = [f.frame for f in sc.frames]
        if sc.urdf is None:
            self.model = mujoco_from_robot(self.robot, frames)
        else:
            self.model = mujoco_from_urdf(urdf_path(sc), self.robot, frames, free_flyer=sc.urdf[1])
        self.jmap = JointMap.from_mujoco(self.robot, self.model)
        self.conf = mink.Configuration(self.model)
        self.frame_tasks = []
        for spec in sc.frames:
            pos, ori = (1.0, 1.0) if spec.axes == "pose" else (np.array([1.0, 1.0, 0.0]), 0.0)
            self.frame_tasks.append(mink.FrameTask(spec.frame, "site", position_cost=pos, orientation_cost=ori))
        self.tasks: list[Any] = list(self.frame_tasks)
        if sc.posture:
            self.posture = mink.PostureTask(self.model, cost=np.sqrt(POSTURE_WEIGHT), gain=POSTURE_GAIN * sc.dt)
            self.tasks.append(self.posture)
        if sc.peer_potential is not None:
            from redundik.peers.mink_tasks import MinkPotentialTask

            factory, kw = sc.peer_potential
            self.tasks.append(MinkPotentialTask(factory(), sc.robot(), dt=sc.dt, joint_map=self.jmap, **kw))
        self.limits: list[Any] = [mink.ConfigurationLimit(self.model)]
        vel = {j.name: j.velocity for j in self.robot.joints if j.idx_q >= 0 and np.isfinite(j.velocity)}
        if vel:
            self.limits.append(mink.VelocityLimit(self.model, vel))
        self.SE3, self.SO3 = mink.SE3, mink.SO3

    def _step(self, t: float) -> tuple[int, np.ndarray]:
        dt = self.scenario.dt
        q_peer = self.jmap.to_peer_q(self.q)
        poses = teleop_poses(self.refs, t + dt) if self.scenario.teleop else None  # untimed, as for redundik
        t0 = _ns()
        self.conf.update(q_peer)
        for i, (task, ref) in enumerate(zip(self.frame_tasks, self.refs, strict=True)):
            pose = poses[i] if poses is not None else ref.trajectory.sample(t + dt)[0]
            task.set_target(
                self.SE3.from_rotation_and_translation(self.SO3.from_matrix(pose.rotation), pose.translation)
            )
        v = self.mink.solve_ik(self.conf, self.tasks, dt, self.backend, damping=1e-12, limits=self.limits)
        t1 = _ns()
        q_next_peer = self.conf.integrate(v, dt)
        return t1 - t0, self.jmap.to_robot_q(q_next_peer)


class PinkRunner(_PeerRunner):
    """pink on a Pinocchio model of the same robot (a copy of redundik's, so pink's attributes stay off ours)."""

    method = "pink"

    def _build(self) -> None:
        import pinocchio as pin

        from redundik.peers._deps import require
        from redundik.peers.joint_map import JointMap

        pink = require("pink")
        self.pink = pink
        sc = self.scenario
        self.model = pin.Model(self.robot.model)
        self.data = self.model.createData()
        self.jmap = JointMap.from_pinocchio(self.robot, self.model)
        self.frame_tasks = []
        for spec in sc.frames:
            pos, ori = (1.0, 1.0) if spec.axes == "pose" else ([1.0, 1.0, 0.0], 0.0)
            self.frame_tasks.append(pink.tasks.FrameTask(spec.frame, position_cost=pos, orientation_cost=ori))
        self.tasks: list[Any] = list(self.frame_tasks)
        if sc.posture:
            self.posture = pink.tasks.PostureTask(cost=float(np.sqrt(POSTURE_WEIGHT)), gain=POSTURE_GAIN * sc.dt)
            self.tasks.append(self.posture)
        if sc.peer_potential is not None:
            from redundik.peers.pink_tasks import PinkPotentialTask

            factory, kw = sc.peer_potential
            self.tasks.append(PinkPotentialTask(factory(), sc.robot(), dt=sc.dt, joint_map=self.jmap, **kw))
        self.conf = pink.Configuration(self.model, self.data, self.jmap.to_peer_q(self.q))
        self.limits: list[Any] = [self.model.configuration_limit]
        if np.any(np.isfinite(self.robot.velocity_limits) & (self.robot.velocity_limits < 1e9)):
            self.limits.append(self.model.velocity_limit)
        logging.getLogger().setLevel(logging.ERROR)  # pink logs each out-of-limit step (counted here instead)

    def _step(self, t: float) -> tuple[int, np.ndarray]:
        dt = self.scenario.dt
        q_peer = self.jmap.to_peer_q(self.q)
        poses = teleop_poses(self.refs, t + dt) if self.scenario.teleop else None  # untimed, as for redundik
        t0 = _ns()
        self.conf.update(q_peer)
        for i, (task, ref) in enumerate(zip(self.frame_tasks, self.refs, strict=True)):
            task.set_target(poses[i] if poses is not None else ref.trajectory.sample(t + dt)[0])
        # safety_break=False: pink would raise on 1e-5 rad excursions (environment notes); violations are counted
        # by the common ruler instead, for every method alike.
        v = self.pink.solve_ik(
            self.conf, self.tasks, dt, solver=self.backend, damping=1e-12, limits=self.limits, safety_break=False
        )
        t1 = _ns()
        return t1 - t0, self.jmap.to_robot_q(self.conf.integrate(v, dt))


class PinkShelfRunner(_PeerRunner):
    """pink on ``panda_shelf``: the same collision geometry as redundik's world (its fitted capsules, the four
    obstacles and its 60 candidate pairs, as a Pinocchio ``GeometryModel``) under pink's ``SelfCollisionBarrier``.

    What is matched and what is pink's own:

    * geometry and pairs: identical (a copy of :attr:`CollisionWorld.geometry` with the world's pairs);
    * the barrier: pink's control-barrier function ḣ ≥ −γ h on h = d − d_min, with γ = ξ/(d_i − d_s) and
      d_min = d_s, is redundik's velocity damper ḋ ≥ −ξ (d − d_s)/(d_i − d_s) written the other way round; pink
      applies it to every pair at every step (redundik only within d_i plus a look-ahead, where it binds), and its
      "safe displacement" cost is off (``safe_displacement_gain=0``: an extra regularisation towards a backup
      motion that redundik's stack does not have, and with it pink's hand stalls 1.8 cm short of the target);
    * the hand: pink's dead-beat ``FrameTask`` (gain 1) towards T_eff = the pose our K = 5/s + feed-forward task
      asks for one step ahead (position p + Δp_d + K·dt·(p_d − p), rotation likewise), computed outside the timed
      region (which favours pink);
    * posture: ``PostureTask`` to the task file's centre with α = K_p·dt, cost √ρ (ρ = wqp's level ratio);
    * limits: configuration and velocity limits.
    """

    method = "pink"

    def _build(self) -> None:
        import pinocchio as pin

        from redundik.peers._deps import require
        from redundik.peers.joint_map import JointMap

        pink = require("pink")
        self.pink, self.pin = pink, pin
        sc = self.scenario
        world = sc.world  # type: ignore[attr-defined]
        self.model = pin.Model(sc.runner_robot().model)  # type: ignore[misc]
        self.data = self.model.createData()
        self.jmap = JointMap.from_pinocchio(self.robot, self.model)
        gm = world.geometry.copy()
        for i, j in world.pairs:
            gm.addCollisionPair(pin.CollisionPair(int(i), int(j)))
        self.geometry = gm
        self.geometry_data = pin.GeometryData(gm)
        avoid = sc.avoid  # type: ignore[attr-defined]
        self.barrier = pink.barriers.SelfCollisionBarrier(
            n_collision_pairs=len(world.pairs), gain=avoid.gamma, safe_displacement_gain=0.0, d_min=avoid.safety
        )
        self.hand = pink.tasks.FrameTask(sc.frames[0].frame, position_cost=1.0, orientation_cost=1.0, gain=1.0)
        self.posture = pink.tasks.PostureTask(cost=float(np.sqrt(sc.level_ratio)), gain=sc.posture_gain * sc.dt)  # type: ignore[attr-defined]
        self.tasks: list[Any] = [self.hand, self.posture]
        self.conf = pink.Configuration(
            self.model, self.data, self.jmap.to_peer_q(self.q), collision_model=gm, collision_data=self.geometry_data
        )
        self.limits: list[Any] = [self.model.configuration_limit, self.model.velocity_limit]
        self.gain = float(sc.frame_gain or 1.0 / sc.dt)
        logging.getLogger().setLevel(logging.ERROR)

    def _reset_peer(self) -> None:
        self.conf.update(self.jmap.to_peer_q(self.q))
        self.posture.set_target(self.jmap.to_peer_q(self.scenario.posture_center))  # type: ignore[attr-defined]

    def _target(self, t: float) -> Any:
        """T_eff: the pose one step ahead that redundik's feed-forward + K task asks for (module docstring)."""
        pin, dt, k = self.pin, self.scenario.dt, self.gain
        ref = self.refs[0].trajectory
        now, _ = ref.sample(t)
        nxt, _ = ref.sample(t + dt)
        self.robot.update(self.q)
        cur = self.robot.frame_pose(self.scenario.frames[0].frame)
        p = cur.translation + (nxt.translation - now.translation) + k * dt * (now.translation - cur.translation)
        R_err = pin.exp3(k * dt * pin.log3(now.rotation @ cur.rotation.T))
        R = (nxt.rotation @ now.rotation.T) @ R_err @ cur.rotation
        return pin.SE3(R, p)

    def _step(self, t: float) -> tuple[int, np.ndarray]:
        dt = self.scenario.dt
        target = self._target(t)  # untimed: the reference re-expressed as pink's dead-beat target
        q_peer = self.jmap.to_peer_q(self.q)
        t0 = _ns()
        self.conf.update(q_peer)
        self.hand.set_target(target)
        v = self.pink.solve_ik(
            self.conf, self.tasks, dt, solver=self.backend, damping=1e-12, limits=self.limits,
            barriers=[self.barrier], safety_break=False,
        )  # fmt: skip
        t1 = _ns()
        return t1 - t0, self.jmap.to_robot_q(self.conf.integrate(v, dt))


class MinkShelfRunner(PinkShelfRunner):
    """mink on ``panda_shelf``: MuJoCo model of the same URDF with redundik's collision shapes added as geoms (each
    capsule on the body carrying its link, the obstacles in the world body) and ``CollisionAvoidanceLimit`` on the
    world's 60 pairs. mink's limit, −ḋ ≤ g·(d − d_min)/dt within the detection distance, is our damper with
    g = γ·dt, d_min = d_s and detection distance d_i. Hand and posture as in :class:`PinkShelfRunner`."""

    method = "mink"

    def _build(self) -> None:
        import coal
        import pinocchio as pin

        from redundik.peers._deps import require
        from redundik.peers.joint_map import JointMap
        from redundik.simulation.mujoco_model import _compile, _host_body, _wxyz, add_frame_sites, strip_urdf

        mink = require("mink")
        mujoco = require("mujoco")
        self.mink, self.pin = mink, pin
        sc = self.scenario
        world, avoid = sc.world, sc.avoid  # type: ignore[attr-defined]
        spec = mujoco.MjSpec.from_string(strip_urdf(sc.urdf_file))  # type: ignore[attr-defined]
        spec.compiler.discardvisual = False  # keep every added geom
        add_frame_sites(spec, self.robot, [f.frame for f in sc.frames])
        bodies = {b.name for b in spec.bodies}
        robot = self.robot
        robot.update(robot.neutral())
        data = robot.data
        names = []
        for go in world.geometry.geometryObjects:
            g = go.geometry
            if isinstance(g, coal.Capsule):
                kind, size = mujoco.mjtGeom.mjGEOM_CAPSULE, [g.radius, g.halfLength, 0.0]
            elif isinstance(g, coal.Box):
                kind, size = mujoco.mjtGeom.mjGEOM_BOX, list(np.asarray(g.halfSide))
            elif isinstance(g, coal.Sphere):
                kind, size = mujoco.mjtGeom.mjGEOM_SPHERE, [g.radius, 0.0, 0.0]
            else:
                raise RuntimeError(f"geometry {go.name}: {type(g).__name__} has no MuJoCo twin here")
            name = f"rk_{go.name}"
            if go.parentJoint == 0:
                body, rel = spec.worldbody, go.placement
            else:
                host = _host_body(robot, go.parentFrame, bodies)
                body = spec.body(robot.model.frames[host].name)
                rel = robot.frame_pose(host).actInv(data.oMi[go.parentJoint] * go.placement)
            body.add_geom(
                name=name, type=kind, size=size, pos=np.asarray(rel.translation), quat=_wxyz(rel.rotation),
                contype=1, conaffinity=1,  # mink keeps only pairs that pass this check (no simulation here)
            )  # fmt: skip
            names.append(name)
        self.model = _compile(spec, sc.urdf_file)  # type: ignore[attr-defined]
        self.jmap = JointMap.from_mujoco(self.robot, self.model)
        self.conf = mink.Configuration(self.model)
        pairs = [([names[i]], [names[j]]) for i, j in world.pairs]
        self.collision = mink.CollisionAvoidanceLimit(
            self.model, pairs, gain=avoid.gamma * sc.dt, minimum_distance_from_collisions=avoid.safety,
            collision_detection_distance=avoid.influence,
        )  # fmt: skip
        self.limits: list[Any] = [mink.ConfigurationLimit(self.model), self.collision]
        vel = {j.name: j.velocity for j in self.robot.joints if j.idx_q >= 0 and np.isfinite(j.velocity)}
        if vel:
            self.limits.append(mink.VelocityLimit(self.model, vel))
        self.hand = mink.FrameTask(sc.frames[0].frame, "site", position_cost=1.0, orientation_cost=1.0, gain=1.0)
        self.posture = mink.PostureTask(self.model, cost=float(np.sqrt(sc.level_ratio)), gain=sc.posture_gain * sc.dt)  # type: ignore[attr-defined]
        self.tasks = [self.hand, self.posture]
        self.gain = float(sc.frame_gain or 1.0 / sc.dt)
        self.pairs_used = int(self.collision.max_num_contacts)

    def _step(self, t: float) -> tuple[int, np.ndarray]:
        dt = self.scenario.dt
        target = self._target(t)  # untimed, as for pink
        q_peer = self.jmap.to_peer_q(self.q)
        t0 = _ns()
        self.conf.update(q_peer)
        self.hand.set_target(self.mink.SE3.from_matrix(target.homogeneous))
        v = self.mink.solve_ik(self.conf, self.tasks, dt, self.backend, damping=1e-12, limits=self.limits)
        t1 = _ns()
        return t1 - t0, self.jmap.to_robot_q(self.conf.integrate(v, dt))

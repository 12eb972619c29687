"""The peers' runners (mink, pink, and their shelf variants): the same timed region and ruler as
:class:`benchmarks.bench.runners.RedundikRunner` (the module docstring there), each peer given the frame tasks
to the next reference pose, the posture and the limits of its scenario."""

import logging
import time
from abc import abstractmethod
from typing import Any

import numpy as np

from benchmarks.bench.runners import Runner, teleop_poses
from benchmarks.bench.scenarios import POSTURE_GAIN, POSTURE_WEIGHT, Scenario, urdf_path
from redundik.tasks.frame import FrameTask

_ns = time.perf_counter_ns


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

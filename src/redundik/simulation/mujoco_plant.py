"""A MuJoCo plant: the robot's URDF in MuJoCo with joint actuators, gravity and rigid-body dynamics.

The model comes from the same URDF as the redundik robot (visuals stripped: MuJoCo cannot open ``package://``
meshes; the URDF's masses and inertias are kept). Every 1-dof joint gets an actuator:

* ``position``: τ = kp·(q_ref − q) − kv·q̇, with q_ref the integral of the commanded q̇ (ramped linearly over the
  substeps of each control period);
* ``velocity``: τ = kv·(q̇_cmd − q̇).

Options: gravity on/off, gravity compensation (MuJoCo's body ``gravcomp`` routed through the actuators, as a
torque-controlled arm's own compensation: it counts in the effort and the limits), the URDF effort limits as
actuator force limits, and an armature (reflected rotor inertia). MuJoCo steps at ``sim_dt``; redundik reads
``qpos`` once per control period.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from redundik._optional import require_extra
from redundik.errors import ConfigError, ModelError
from redundik.kinematics.model import RobotModel

if TYPE_CHECKING:
    from redundik.simulation.plant import PlantOptions


def _per_joint(value: float | Mapping[str, float], names: list[str], key: str, where: str) -> np.ndarray:
    if isinstance(value, Mapping):
        bad = [n for n in value if n not in names]
        if bad:
            raise ConfigError(f"unknown joint '{bad[0]}'; joints: {', '.join(names)}", f"{where}.{key}.{bad[0]}")
        default = 0.0
        out = np.array([float(value.get(n, default)) for n in names])
        missing = [n for n in names if n not in value]
        if missing:
            raise ConfigError(f"no gain for joint '{missing[0]}' (give every joint, or one number)", f"{where}.{key}")
        return out
    return np.full(len(names), float(value))


class MujocoPlant:
    """The robot simulated by MuJoCo under joint position or velocity servos (see the module docstring).

    Args:
        robot: The redundik model of the URDF (joints matched by name).
        urdf: The URDF file.
        spec: The plant's options (a task file's ``plant:`` entry).
        control_dt: The control period [s]; a multiple of ``spec.sim_dt``.
        where: Key path for errors.

    Raises:
        ExtraImportError: MuJoCo is not installed (``pip install 'redundik[sim]'``).
        ConfigError: rates that do not divide, a gain for an unknown joint, a non-positive gain.
        ModelError: a joint MuJoCo lacks, or a multi-dof joint (free flyer: not supported).
    """

    name = "mujoco"

    def __init__(
        self,
        robot: RobotModel,
        urdf: str | os.PathLike[str],
        spec: PlantOptions,
        *,
        control_dt: float,
        where: str = "plant",
    ) -> None:
        mujoco = require_extra("mujoco", "sim")
        from redundik.simulation.mujoco_model import strip_urdf

        self._mj = mujoco
        self.robot = robot
        self.spec = spec
        ratio = control_dt / spec.sim_dt
        self.substeps = round(ratio)
        if self.substeps < 1 or abs(ratio - self.substeps) > 1e-6 * ratio:
            msg = f"sim_dt = {spec.sim_dt} s must divide the control dt = {control_dt} s"
            raise ConfigError(msg, f"{where}.sim_dt")
        if robot.nq != robot.nv or any(robot.model.joints[j].nq != 1 for j in range(1, robot.model.njoints)):
            raise ModelError(f"robot '{robot.name}': the MuJoCo plant supports fixed-base robots of 1-dof joints only")
        names = robot.joint_names
        kp = _per_joint(spec.kp, names, "kp", where)
        kv = _per_joint(spec.kv, names, "kv", where)
        if np.any(kv <= 0) or (spec.actuator == "position" and np.any(kp <= 0)):
            raise ConfigError("actuator gains must be > 0", f"{where}.{'kp' if np.any(kp <= 0) else 'kv'}")
        try:
            mspec = mujoco.MjSpec.from_string(strip_urdf(Path(urdf)))
        except Exception as exc:  # MuJoCo's parser raises ValueError
            raise ModelError(f"MuJoCo could not load URDF '{urdf}': {exc}") from exc
        mspec.option.timestep = spec.sim_dt
        if not spec.gravity:
            mspec.option.gravity = [0.0, 0.0, 0.0]
        if spec.gravity_compensation:
            for body in mspec.bodies:
                if body.name != "world":
                    body.gravcomp = 1.0
        joints = {j.name: j for j in mspec.joints}
        missing = [n for n in names if n not in joints]
        if missing:
            raise ModelError(f"MuJoCo model of '{urdf}' has no joint '{missing[0]}'")
        effort = np.asarray(robot.model.effortLimit, dtype=float)
        for i, n in enumerate(names):
            j = joints[n]
            j.armature = spec.armature
            j.actgravcomp = bool(spec.gravity_compensation)
            if spec.effort_limits and np.isfinite(effort[i]) and effort[i] > 0:
                j.actfrclimited = mujoco.mjtLimited.mjLIMITED_TRUE
                j.actfrcrange = [-effort[i], effort[i]]
            act = mspec.add_actuator(name=f"act_{n}", target=n, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            if spec.actuator == "position":
                act.set_to_position(kp=float(kp[i]), kv=float(kv[i]))
            else:
                act.set_to_velocity(kv=float(kv[i]))
        try:
            self.model = mspec.compile()
        except Exception as exc:
            raise ModelError(f"MuJoCo could not compile the plant of '{urdf}': {exc}") from exc
        self.data = mujoco.MjData(self.model)
        jid = [mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in names]
        self._qadr = np.array([self.model.jnt_qposadr[j] for j in jid])
        self._vadr = np.array([self.model.jnt_dofadr[j] for j in jid])
        self._aid = np.array([mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"act_{n}") for n in names])
        self._q_ref = np.zeros(robot.nq)
        self._effort: list[np.ndarray] = []

    def _measure(self) -> np.ndarray:
        return np.array(self.data.qpos[self._qadr])

    def _torque(self) -> np.ndarray:
        return np.array(self.data.qfrc_actuator[self._vadr])

    def reset(self, q0: np.ndarray) -> np.ndarray:
        """Start at rest at ``q0``; the position reference starts there too."""
        self._mj.mj_resetData(self.model, self.data)
        self.data.qpos[self._qadr] = q0
        self.data.qvel[:] = 0.0
        self._q_ref = np.asarray(q0, dtype=float).copy()
        self.data.ctrl[self._aid] = self._q_ref if self.spec.actuator == "position" else 0.0
        self._mj.mj_forward(self.model, self.data)
        self._effort = [self._torque()]
        return self._measure()

    def step(self, dq: np.ndarray, dt: float) -> np.ndarray:
        """Run ``substeps`` MuJoCo steps with the command q̇ (position reference ramped, or velocity setpoint)."""
        mj, n = self._mj, self.substeps
        if self.spec.actuator == "position":
            start = self._q_ref
            self._q_ref = start + np.asarray(dq) * dt
            for s in range(n):
                self.data.ctrl[self._aid] = start + (s + 1) / n * (self._q_ref - start)
                mj.mj_step(self.model, self.data)
        else:
            self.data.ctrl[self._aid] = dq
            for _ in range(n):
                mj.mj_step(self.model, self.data)
        self._effort.append(self._torque())
        return self._measure()

    def series(self) -> dict[str, np.ndarray]:
        """``u.<joint>``: the actuators' joint torque [N·m or N] at each sample (gravity compensation included)."""
        u = np.array(self._effort)
        return {f"u.{n}": u[:, i] for i, n in enumerate(self.robot.joint_names)}

    def summary(self) -> dict[str, Any]:
        """Actuator effort: max |τ| and RMS τ per joint [N·m or N], and the settings used."""
        u = np.array(self._effort)
        names = self.robot.joint_names
        return {
            "actuator": self.spec.actuator,
            "sim_dt": self.spec.sim_dt,
            "substeps": self.substeps,
            "actuator_effort": {
                "max_abs": {n: float(np.max(np.abs(u[:, i]))) for i, n in enumerate(names)},
                "rms": {n: float(np.sqrt(np.mean(u[:, i] ** 2))) for i, n in enumerate(names)},
            },
        }

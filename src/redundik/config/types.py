"""Every public task, trajectory, potential and monitor type of redundik, registered once for YAML.

Each line names a YAML ``type:`` and the library constructor that builds it; the YAML model (keys, types,
defaults, bounds, descriptions) is derived from the constructor (:mod:`redundik.config.registry`). Overrides are
only where the file format deliberately differs from the Python call (a rotation given as ``rpy`` angles, the
open-loop default gain of a frame task in a task file, a length check the constructor leaves to NumPy).
Subtasks are not ``type:`` entries: a run's ``subtasks:`` maps each named potential to a
:class:`~redundik.tasks.GradientSubtask`, :class:`~redundik.tasks.TargetSubtask` or
:class:`~redundik.tasks.BoundSubtask` (``kind:``); joint limits are the QP resolvers' ``options: {limits: ...}``
(:class:`~redundik.resolvers.JointLimits`).
"""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
from pydantic import Field

from redundik.config import schema as s
from redundik.config.builders import Context, TorqueMonitor, check_axes, frame_list
from redundik.config.registry import POSITIVE, As, OptVec3, configuration, joint_unit, per_joint, register
from redundik.config.robot import rpy_matrix
from redundik.errors import ConfigError, TaskError
from redundik.kinematics import AXES
from redundik.tasks import (
    BestPosture,
    Circle,
    Clearance,
    FrameTask,
    Hold,
    JointCentering,
    JointCoupling,
    JointSine2,
    JointValue,
    JointWaypoints,
    Line,
    Manipulability,
    PoseInterpolation,
    PostureTask,
    PotentialTask,
    RelativePoseTask,
    VirtualPoint,
)
from redundik.tasks.joint_selection import check_joint_selection, selected_coordinates


def _rpy(value: Any, ctx: Context, path: str, spec: Any) -> np.ndarray:
    return rpy_matrix(np.asarray(value) * ctx.scale)


def _plane(value: Any, ctx: Context, path: str, spec: Any) -> tuple[str, str]:
    if value[0] == value[1]:
        raise ConfigError(f"expected two different axes, got {value}", path)
    return (value[0], value[1])


def _posture_joints(value: Any, ctx: Context, path: str, spec: Any) -> Any:
    """A posture's ``joints`` (``actuated`` or joint names), checked against the robot here, with the key path."""
    if value is None:
        return None
    try:
        joints = check_joint_selection(value, "posture")
        selected_coordinates(ctx.robot, joints, "posture")
    except TaskError as exc:
        raise ConfigError(str(exc).removeprefix("posture: "), path) from None
    return joints


def _relative_target(value: Any, ctx: Context, path: str, spec: Any) -> np.ndarray | None:
    if spec.xyz is None and spec.rpy is None:
        return None
    target = np.eye(4)
    if spec.rpy is not None:
        target[:3, :3] = rpy_matrix(np.asarray(spec.rpy) * ctx.scale)
    if spec.xyz is not None:
        target[:3, 3] = spec.xyz
    return target


def torques(
    frames: str | list[str], force: list[float], axes: str | list[str] = "pose", *, name: str = "torques"
) -> TorqueMonitor:
    """τ = JᵀF of the stacked frame Jacobians (the chapter's statics), logged as max/min/mean |τ|.

    Args:
        frames: One frame name or several (their Jacobians are stacked).
        force: F, len(axes) numbers per frame [N, N·m].
        axes: Jacobian rows used.
        name: Monitor name.
    """
    return TorqueMonitor(name, list(frames), np.array([AXES[a] for a in axes]), np.asarray(force, dtype=float))


def _torque_frames(value: Any, ctx: Context, path: str, spec: Any) -> list[str]:
    return frame_list(value, ctx, path)


def _torque_force(value: Any, ctx: Context, path: str, spec: Any) -> list[float]:
    n_frames = 1 if isinstance(spec.frames, str) else len(spec.frames)
    n_axes = len(check_axes(spec.axes, path.rsplit(".", 1)[0] + ".axes"))
    if len(value) != n_frames * n_axes:
        raise ConfigError(
            f"expected {n_frames * n_axes} values ({n_axes} axes × {n_frames} frames), got {len(value)}", path
        )
    return list(value)


# ---------------------------------------------------------------------------------------------------- trajectories
register("hold", "trajectory", Hold, exclude=("pose",))
register(
    "line",
    "trajectory",
    Line,
    params={"velocity": As(annotation=Annotated[list[float], Field(min_length=2, max_length=3)])},
)
register(
    "circle",
    "trajectory",
    Circle,
    params={
        "radius": As(bounds=POSITIVE),
        "plane": As(annotation=Annotated[list[s.Axis], Field(min_length=2, max_length=2)], convert=_plane),
    },
)
register(
    "pose",
    "trajectory",
    PoseInterpolation,
    params={
        "duration": As(bounds={"ge": s.DT_MIN, "le": s.MAX_DURATION}),  # [s]; shorter: a speed beyond any scale
        "rotation": As(key="rpy", annotation=OptVec3, convert=_rpy),
    },
)

# ---------------------------------------------------------------------------------------------------- main tasks
register("frame", "task", FrameTask, params={"gain": As(default=0.0, bounds={"ge": 0})})
register(
    "posture",
    "task",
    PostureTask,
    params={
        "target": As(convert=configuration("nq")),
        "joints": As(annotation=s.Name | list[s.Name] | None, convert=_posture_joints),
    },
)
register("joint_coupling", "task", JointCoupling, params={"offset": As(convert=joint_unit("joint_i"))})
register("potential", "task", PotentialTask)
register(
    "relative_pose",
    "task",
    RelativePoseTask,
    params={
        "frame_a": As(key="frame"),
        "frame_b": As(key="relative_to"),
        "target": As(hidden=True, convert=_relative_target),
    },
    extra={"xyz": (OptVec3, None), "rpy": (OptVec3, None)},
)

# ---------------------------------------------------------------------------------------------------- potentials
register("sin2", "potential", JointSine2)
register("joint_value", "potential", JointValue, params={"value": As(convert=joint_unit("joint"))})
register(
    "joint_centering",
    "potential",
    JointCentering,
    params={"center": As(annotation=list[float] | None, convert=configuration("nq")), "weights": As(convert=per_joint)},
)
register("virtual_point", "potential", VirtualPoint)
register("clearance", "potential", Clearance, params={"radius": As(bounds={"ge": 0})})
register("manipulability", "potential", Manipulability)
register("best_posture", "potential", BestPosture, params={"weights": As(convert=per_joint)})
register(
    "joint_waypoints",
    "potential",
    JointWaypoints,
    params={
        "values": As(annotation=Annotated[list[float], Field(min_length=1)], convert=joint_unit("joint")),
        "tolerance": As(bounds=POSITIVE, convert=joint_unit("joint")),
    },
)

# ---------------------------------------------------------------------------------------------------- monitors
register(
    "torques", "monitor", torques, params={"frames": As(convert=_torque_frames), "force": As(convert=_torque_force)}
)

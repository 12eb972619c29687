"""YAML types for the chapter's robots (issue 4), registered in the builders' registries on import.

* main task ``type: relative_pose`` → :class:`redundik.robots.RelativePoseTask` (two hands holding one object);
* potential ``type: joint_waypoints`` → :class:`redundik.robots.JointWaypoints` (the (6+1) robot's round trip).
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import Field

from redundik.config import schema as s
from redundik.config.builders import (
    Context,
    _wrap,
    check_axes,
    check_frame,
    check_joint,
    register_potential,
    register_task,
)
from redundik.config.robot import rpy_matrix
from redundik.config.yamlio import join_path
from redundik.robots.potentials import JointWaypoints
from redundik.robots.relative import RelativePoseTask
from redundik.tasks import Potential, Task


class RelativePoseSpec(s.StrictModel):
    """Main task ``type: relative_pose``: pose of ``frame`` in ``relative_to`` held (captured at t = 0) or given."""

    type: Literal["relative_pose"]
    name: s.Name | None = None
    frame: s.Name
    relative_to: s.Name
    axes: Any = "pose"
    gain: float = Field(default=1.0, ge=0)
    weight: float = Field(default=1.0, gt=0)
    xyz: s.Vec3 | None = None
    rpy: s.Vec3 | None = None


class JointWaypointsSpec(s.StrictModel):
    """Potential ``type: joint_waypoints``: p = (q_j − c_i)², c_i switching once reached (values in angle unit)."""

    type: Literal["joint_waypoints"]
    joint: s.Name
    values: list[float] = Field(min_length=1)
    tolerance: float = Field(default=0.05, gt=0)


def _task_relative_pose(spec: RelativePoseSpec, name: str, ctx: Context, path: str) -> Task:
    frame = check_frame(ctx, spec.frame, join_path(path, "frame"))
    ref = check_frame(ctx, spec.relative_to, join_path(path, "relative_to"))
    axes = check_axes(spec.axes, join_path(path, "axes"))
    target = None
    if spec.xyz is not None or spec.rpy is not None:
        target = np.eye(4)
        if spec.rpy is not None:
            target[:3, :3] = rpy_matrix(np.asarray(spec.rpy) * ctx.scale)
        if spec.xyz is not None:
            target[:3, 3] = spec.xyz
    return _wrap(
        path,
        lambda: RelativePoseTask(
            frame, ref, axes=axes, gain=spec.gain, weight=spec.weight, target=target, name=spec.name or name
        ),
    )


def _pot_waypoints(spec: JointWaypointsSpec, name: str, ctx: Context, path: str) -> Potential:
    joint = check_joint(ctx, spec.joint, join_path(path, "joint"))
    scale = ctx.scale if ctx.robot.joint(joint).kind == "revolute" else 1.0
    values = [v * scale for v in spec.values]
    return _wrap(path, lambda: JointWaypoints(joint, values, spec.tolerance * scale, name=name))


register_task("relative_pose", RelativePoseSpec, _task_relative_pose)
register_potential("joint_waypoints", JointWaypointsSpec, _pot_waypoints)

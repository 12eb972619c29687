"""Which velocity coordinates a joint-space task covers: ``None`` (all), ``"actuated"`` (all but a floating base's)
or a list of joint names — checked where given, resolved per robot into the index array ``sel`` of
:meth:`~redundik.tasks.base.Task.joint_form` (J = I[sel])."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from redundik._names import did_you_mean
from redundik.errors import TaskError, short_repr
from redundik.kinematics.model import RobotModel

__all__ = ["ACTUATED", "JointSelection", "check_joint_selection", "selected_coordinates"]

#: Every coordinate but those of a floating root joint (a free flyer or a planar joint attached to the world), as
#: pink's and mink's posture tasks leave the base out.
ACTUATED = "actuated"

#: ``None`` (every coordinate), :data:`ACTUATED`, or a tuple of joint names.
JointSelection = str | tuple[str, ...] | None

_FLOATING_ROOTS = ("JointModelFreeFlyer", "JointModelPlanar")


def check_joint_selection(joints: object, what: str) -> JointSelection:
    """``joints`` as a selection (``what`` names the task in the messages).

    Raises:
        TaskError: not ``None``, ``"actuated"`` or a non-empty sequence of distinct joint names.
    """
    if joints is None:
        return None
    if isinstance(joints, str):
        if joints == ACTUATED:
            return ACTUATED
        raise TaskError(
            f"{what}: joints must be None (every coordinate), 'actuated' (all but a floating base) or a list of "
            f"joint names, got the string {short_repr(joints)} (one joint: joints=[{joints!r}])"
        )
    if not isinstance(joints, Sequence | np.ndarray):
        raise TaskError(
            f"{what}: joints must be None (every coordinate), 'actuated' (all but a floating base) or a list of "
            f"joint names, got {type(joints).__name__} {short_repr(joints)}"
        )
    names = list(joints)
    if not names:
        raise TaskError(f"{what}: joints is empty; give at least one joint name (or None for every coordinate)")
    for name in names:
        if not isinstance(name, str):
            raise TaskError(f"{what}: joints must be joint names (str), got {short_repr(name)} in {short_repr(joints)}")
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise TaskError(f"{what}: joints lists {repeated} more than once")
    return tuple(str(n) for n in names)


def selected_coordinates(robot: RobotModel, joints: JointSelection, what: str) -> np.ndarray:
    """The velocity coordinates (sorted int64 indices) that ``joints`` covers on ``robot``.

    Raises:
        TaskError: a joint the robot does not have (close names suggested), or a selection that covers no
            coordinate (``"actuated"`` on a robot with a floating base and nothing else).
    """
    if joints is None:
        return np.arange(robot.nv, dtype=np.int64)
    model = robot.model
    if joints == ACTUATED:  # (a str here: a tuple of names otherwise)
        skip = -1
        if model.njoints > 1 and model.parents[1] == 0 and model.joints[1].shortname() in _FLOATING_ROOTS:
            skip = 1
        cols = [
            c
            for j in range(1, model.njoints)
            if j != skip
            for c in range(model.joints[j].idx_v, model.joints[j].idx_v + model.joints[j].nv)
        ]
    else:
        by_joint = {model.names[j]: range(model.joints[j].idx_v, model.joints[j].idx_v + model.joints[j].nv)
                    for j in range(1, model.njoints)}  # fmt: skip
        by_coordinate = {info.name: [c] for c, info in enumerate(robot.joints)}  # (a multi-dof joint's "name.k")
        cols = []
        for name in joints:
            found = by_joint.get(name, by_coordinate.get(name))
            if found is None:
                known = sorted(set(by_joint) | set(by_coordinate))
                raise TaskError(
                    f"{what}: joint '{name}' does not exist in robot '{robot.name}'; "
                    f"{did_you_mean(name, known)}available: {known}"
                )
            cols += list(found)
    if not cols:
        raise TaskError(f"{what}: joints={joints!r} covers no velocity coordinate of robot '{robot.name}'")
    return np.array(sorted(set(cols)), dtype=np.int64)

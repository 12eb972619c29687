"""One-shot evaluations at one configuration: task rows, rank and general solutions, null check, statics.

The chapter's exercises 1–3 (section 5.5.2) ask, besides the motions the task runs ``tasks/exercise{1,2,3}_*.yaml``
simulate, for answers that are a single evaluation: a minimum-norm velocity (5.7), the general solution with a
subtask gradient (5.8), a null-solution check, the joint torques τ = JᵀF of a static force. These are those small
functions; ``python examples/exercises.py`` prints them for the three exercises (geometry chosen in
``configs/prrp_beam.yaml``, ``configs/rrp_bowl.yaml``, ``configs/rpr_lamp.yaml``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from redundik.errors import MechanismError, TaskError
from redundik.kinematics.model import AXES, RobotModel


def _rows(axes: Sequence[str]) -> list[int]:
    bad = [a for a in axes if a not in AXES]
    if bad:
        raise TaskError(f"axes {bad} unknown; expected a subset of {list(AXES)}")
    return [AXES[a] for a in axes]


def task_jacobian(robot: RobotModel, frame: str, axes: Sequence[str]) -> np.ndarray:
    """Rows ``axes`` of the base-aligned frame Jacobian at the last update, shape (len(axes), nv)."""
    return robot.frame_jacobian(frame)[_rows(axes)]


def min_norm_velocity(J: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rank (minimum-norm) solution q̇ = J⁺v of J q̇ = v, eq. (5.7).

    Raises:
        MechanismError: J is rank deficient (v may not be reachable; J⁺v would not solve J q̇ = v).
    """
    J = np.asarray(J, dtype=float)
    v = np.asarray(v, dtype=float)
    if v.shape != (J.shape[0],):
        raise TaskError(f"v has shape {v.shape}, expected ({J.shape[0]},) for a {J.shape[0]}×{J.shape[1]} Jacobian")
    if np.linalg.matrix_rank(J) < J.shape[0]:
        raise MechanismError(f"Jacobian of rank {np.linalg.matrix_rank(J)} < {J.shape[0]} rows: singular point")
    return np.linalg.pinv(J) @ v


def general_velocity(J: np.ndarray, v: np.ndarray, eta: np.ndarray, k: float) -> np.ndarray:
    """General solution q̇ = J⁺v + (I − J⁺J) k η with a subtask gradient η, eq. (5.8)."""
    J = np.asarray(J, dtype=float)
    Jp = np.linalg.pinv(J)
    return min_norm_velocity(J, v) + (np.eye(J.shape[1]) - Jp @ J) @ (k * np.asarray(eta, dtype=float))


def null_check(J: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Is ``qd`` a null solution (J q̇ = 0)?

    Returns:
        (J q̇ [task units/s], its null-space projection (I − J⁺J) q̇, the angle between q̇ and the null space
        [rad]: 0 for an exact null solution).
    """
    J = np.asarray(J, dtype=float)
    qd = np.asarray(qd, dtype=float)
    qn = (np.eye(J.shape[1]) - np.linalg.pinv(J) @ J) @ qd
    cos = np.clip(np.linalg.norm(qn) / np.linalg.norm(qd), 0.0, 1.0)
    return J @ qd, qn, float(np.arccos(cos))


def frame_axis(robot: RobotModel, frame: str, axis: str) -> np.ndarray:
    """Direction of the frame's local ``x``, ``y`` or ``z`` axis in the world frame at the last update."""
    if axis not in ("x", "y", "z"):
        raise TaskError(f"axis must be x, y or z, got {axis!r}")
    return np.array(robot.frame_pose(frame).rotation[:, AXES[axis]])


def static_torques(robot: RobotModel, frame: str, force: np.ndarray, axes: Sequence[str] = ("x", "y")) -> np.ndarray:
    """Joint torques/forces τ = JᵀF holding a static force F at a frame (the chapter's statics, as in (5.12)).

    Args:
        robot: Updated model.
        frame: Where the force acts (its origin).
        force: F exerted BY the robot on the environment, in the world frame, one entry per axis [N].
        axes: Components of F.

    Returns:
        τ, shape (nv,) [N·m for revolute, N for prismatic joints].
    """
    F = np.asarray(force, dtype=float)
    if F.shape != (len(axes),):
        raise TaskError(f"force has shape {F.shape}, expected ({len(axes)},) for axes {list(axes)}")
    return task_jacobian(robot, frame, axes).T @ F

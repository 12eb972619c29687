"""One-shot answers of the chapter's exercises 1–3 (section 5.5.2): velocities, null check, statics.

The task runs ``tasks/exercise{1,2,3}_*.yaml`` simulate the motions; the answers that are a single evaluation at
one configuration (a minimum-norm velocity, a null-solution check, the joint torques τ = JᵀF of a static force)
are these small functions. ``python -m redundik.robots.exercises`` prints them for the three exercises (geometry
chosen in ``configs/prrp_beam.yaml``, ``configs/rrp_bowl.yaml``, ``configs/rpr_lamp.yaml``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from redundik.errors import MechanismError, TaskError
from redundik.kinematics import AXES, RobotModel

GRAVITY = 9.81  # [m/s²]


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


def answers(root: Path | None = None) -> dict[str, dict[str, np.ndarray | float]]:
    """The one-shot answers of exercises 1–3 at the configurations of their task files.

    Exercise 2's contact configuration is the final sample of its ``avoid_hqp`` run (w at (0.8, 0)).
    """
    from redundik.config import load_task  # lazy: keep the YAML layer out of the import path
    from redundik.config.runner import run_task

    root = root or Path(__file__).resolve().parents[3]
    out: dict[str, dict[str, np.ndarray | float]] = {}

    p1 = load_task(root / "tasks/exercise1_prrp.yaml")
    r1 = p1.robot.model
    r1.update(p1.runs["min_norm"].q0)
    J1 = task_jacobian(r1, "4", ("x", "y", "z"))
    v1 = np.array([0.0, 1.0, 0.0])
    theta3 = float(p1.runs["min_norm"].q0[2])
    eta = np.zeros(r1.nv)
    eta[2] = np.sin(2 * theta3)
    out["exercise1"] = {
        "J": J1,
        "qdot_min_norm": min_norm_velocity(J1, v1),
        "qdot_sing_avoid_k1": general_velocity(J1, v1, eta, 1.0),
        "det_3col": float(np.linalg.det(J1[:, :3])),
    }

    p2 = load_task(root / "tasks/exercise2_rrp_bowl.yaml")
    res2 = run_task(p2, ["avoid_hqp"])["avoid_hqp"]
    r2 = p2.robot.model
    q2 = res2.log.q[-1]
    r2.update(q2)
    z3 = frame_axis(r2, "3", "z")
    out["exercise2"] = {
        "q_contact": q2,
        "w_contact": r2.frame_position("3")[:2],
        "tau_press_12N": static_torques(r2, "3", 12.0 * z3[:2]),
    }

    p3 = load_task(root / "tasks/exercise3_rpr_lamp.yaml")
    r3 = p3.robot.model
    q3 = p3.runs["rank_only"].q0
    r3.update(q3)
    J3 = task_jacobian(r3, "3", ("x", "y"))
    residual, _, angle = null_check(J3, np.array([-np.sqrt(3.0), 1.6, -1.5]))
    elbow = r3.frame_position("2")[:2]
    out["exercise3"] = {
        "q0": q3,
        "elbow": elbow,
        "elbow_lamp_distance": float(np.linalg.norm(elbow - [0.4, 1.4])),
        "J": J3,
        "J_qdot_given": residual,
        "angle_to_null_space_deg": float(np.degrees(angle)),
        "tau_2kg": static_torques(r3, "3", np.array([0.0, 2.0 * GRAVITY])),
    }
    return out


def main() -> None:
    """Print :func:`answers`."""
    np.set_printoptions(precision=4, suppress=True)
    for name, values in answers().items():
        print(name)
        for key, value in values.items():
            print(f"  {key}: {value}")


if __name__ == "__main__":
    main()

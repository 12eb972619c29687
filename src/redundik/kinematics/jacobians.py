"""The chapter's Jacobians of tree-shaped D-H robots, built from the A matrices (eqs. 4.14, 4.15, 5.17).

These functions compute, from the D-H rows alone (no Pinocchio), what the chapter computes by hand: the one-step
A matrices, their products A_0^i along each branch, and for an end-effector frame e the Jacobian

    J_(e) = ( p_e^{i−1} × r_e^{i−1} ;  r_e^{i−1} )   (revolute joint i),    ( r_e^{i−1} ; 0 )   (prismatic joint i),

with p_e^{i−1}, r_e^{i−1} the 4th and 3rd columns of A_e^{i−1} (eq. 4.14), projected on the base by
diag(R_0^e, R_0^e) (eq. 4.15). Stacking the end-effectors of a tree gives the augmented Jacobian (5.17) of the
dual arm: 12×17, with the torso columns shared and zero blocks where an arm does not move a hand. A coupled row
(θ3r = θ3l + β, ``DHRow.joint``) contributes to the column of the joint it shares.

They are independent of :class:`~redundik.kinematics.RobotModel` on purpose: tests compare them with the model's
frame Jacobians. :func:`degree_of_redundancy` works on the model.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from redundik.errors import ModelError
from redundik.kinematics.dh import DHRow
from redundik.kinematics.model import RobotModel


def joint_variables(rows: Sequence[DHRow]) -> list[str]:
    """Names of the joint variables of a D-H table, in order (coupled and fixed rows add none)."""
    return [r.name for r in rows if r.kind != "fixed" and r.joint is None]


def dh_forward(
    rows: Sequence[DHRow], values: Mapping[str, float], base: np.ndarray | None = None, base_frame: str = "0"
) -> dict[str, np.ndarray]:
    """A_b^i of every frame of a (tree-shaped) D-H table: the products of the one-step A matrices.

    Args:
        rows: D-H rows (``parent`` for branches, ``joint`` for coupled rows).
        values: Joint variable by name [rad or length unit] (see :func:`joint_variables`).
        base: A_b^0 (eq. 5.13); identity if ``None``.
        base_frame: Name of frame 0.

    Returns:
        Frame name → 4×4 homogeneous transform in the world base frame.

    Raises:
        ModelError: a missing joint value or an unknown parent.
    """
    frames = {base_frame: np.eye(4) if base is None else np.asarray(base, dtype=float)}
    previous = base_frame
    for row in rows:
        parent = row.parent if row.parent is not None else previous
        if parent not in frames:
            raise ModelError(f"row '{row.name}': parent frame '{parent}' is not defined before it")
        var = row.joint if row.joint is not None else row.name
        if row.kind == "fixed":
            value = 0.0
        elif var in values:
            value = float(values[var])
        else:
            raise ModelError(f"row '{row.name}': no value for joint '{var}'; given: {sorted(values)}")
        frames[row.name] = frames[parent] @ row.transform(value)
        previous = row.name
    return frames


def _chain(rows: Sequence[DHRow], frame: str, base_frame: str) -> list[tuple[DHRow, str]]:
    """The rows from the base to ``frame``, each with the name of its frame i−1."""
    by_name: dict[str, tuple[DHRow, str]] = {}
    previous = base_frame
    for row in rows:
        parent = row.parent if row.parent is not None else previous
        by_name[row.name] = (row, parent)
        previous = row.name
    if frame not in by_name:
        raise ModelError(f"frame '{frame}' is not a row of the D-H table; rows: {list(by_name)}")
    out = []
    name = frame
    while name != base_frame:
        row, parent = by_name[name]
        out.append((row, parent))
        name = parent
    return out[::-1]


def chain_jacobian(
    rows: Sequence[DHRow],
    values: Mapping[str, float],
    frame: str,
    *,
    base: np.ndarray | None = None,
    base_frame: str = "0",
    projected: str = "base",
) -> np.ndarray:
    """The 6×n Jacobian of one frame by eq. (4.14), columns ordered as :func:`joint_variables`.

    Args:
        rows: D-H rows.
        values: Joint variables by name.
        frame: End-effector frame e.
        base: A_b^0.
        base_frame: Name of frame 0.
        projected: ``"base"`` (J_b, eq. 4.15, rows v, ω in the world frame) or ``"end"`` (J_(e), in frame e).

    Raises:
        ModelError: unknown frame or ``projected`` value.
    """
    if projected not in ("base", "end"):
        raise ModelError(f"projected must be 'base' or 'end', got {projected!r}")
    names = joint_variables(rows)
    A = dh_forward(rows, values, base, base_frame)
    ae = A[frame]
    ae_inv = np.linalg.inv(ae)
    J = np.zeros((6, len(names)))
    for row, parent in _chain(rows, frame, base_frame):
        if row.kind == "fixed":
            continue
        col = names.index(row.joint if row.joint is not None else row.name)
        a_e_prev = ae_inv @ A[parent]  # A_e^{i-1}
        r, p = a_e_prev[:3, 2], a_e_prev[:3, 3]
        if row.kind == "revolute":
            J[:3, col] += np.cross(p, r)
            J[3:, col] += r
        else:
            J[:3, col] += r
    if projected == "base":
        R = ae[:3, :3]
        J = np.vstack([R @ J[:3], R @ J[3:]])
    return J


def augmented_jacobian(
    rows: Sequence[DHRow],
    values: Mapping[str, float],
    frames: Sequence[str],
    *,
    base: np.ndarray | None = None,
    base_frame: str = "0",
    projected: str = "base",
) -> np.ndarray:
    """The augmented Jacobian of several end-effectors (eq. 5.17): their chain Jacobians stacked, 6k×n.

    With ``projected="end"`` each 6-row block is in its own end-effector frame (J_end of 5.17); with ``"base"`` it is
    J_0 = diag(R_0^{10}, R_0^{10}, R_0^{17}, R_0^{17}) J_end.
    """
    return np.vstack(
        [chain_jacobian(rows, values, f, base=base, base_frame=base_frame, projected=projected) for f in frames]
    )


def numeric_rank(matrix: np.ndarray, rtol: float = 1e-9) -> int:
    """Rank of a matrix: singular values above ``rtol`` times the largest."""
    s = np.linalg.svd(matrix, compute_uv=False)
    return int(np.sum(s > rtol * max(s[0], 1e-300))) if s.size else 0


def degree_of_redundancy(
    robot: RobotModel,
    frames: Sequence[str],
    task_dim: int,
    *,
    samples: int = 20,
    rng: np.random.Generator | None = None,
) -> tuple[int, int]:
    """Degree of redundancy r = n_eff − m, with n_eff the number of independent joint axes.

    n_eff is the generic rank of the stacked base-aligned Jacobians of ``frames`` (the largest rank over random
    configurations within the limits). With the frames of every moving link of an arm, n_eff counts the joint axes
    that move those links independently: a cart yaw coaxial with the arm's waist gives two identical columns in
    every such Jacobian, so the mobile Stanford arm of Fig. 5.12 has n_eff = 8 (r = 2); tilting the arm on the cart
    separates them (n_eff = 9, r = 3).

    Args:
        robot: The robot.
        frames: Frames whose Jacobians are stacked (e.g. every D-H frame of the arm).
        task_dim: m, the dimension of the main task (6 for a full pose).
        samples: Number of random configurations.
        rng: Random generator.

    Returns:
        (r, n_eff).

    Raises:
        ModelError: ``samples`` < 1 or an unknown frame.
    """
    if samples < 1:
        raise ModelError(f"degree_of_redundancy: samples must be ≥ 1, got {samples}")
    rng = rng if rng is not None else np.random.default_rng(0)
    best = 0
    for _ in range(samples):
        robot.update(robot.random_configuration(rng))
        J = np.vstack([robot.frame_jacobian(f) for f in frames])
        best = max(best, numeric_rank(J))
    return best - task_dim, best

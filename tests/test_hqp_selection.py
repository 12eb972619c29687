"""``hqp``'s least squares of a level made of some rows of the identity (a posture on some joints), solved from the
rows it leaves out (``hqp_selection``), against the damped SVD of the level's matrix (``hqp_kernels._svd_solve``):
the same solution, null space, rank, σ_min and damping — and a TALOS hierarchy whose last level is such a posture,
against the strict hierarchy solved here with NumPy."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.resolvers.hqp_kernels import _svd_solve
from redundik.resolvers.hqp_selection import selection_columns, selection_solve

EPS, MAX_DAMPING, RCOND = 1e-2, 5e-2, 1e-10


def _level(seed: int, n: int, r: int, cols: np.ndarray, w: float, rank_of_z: int | None = None) -> np.ndarray:
    """M = √w Z[cols, :r] for an orthonormal Z (n, r); ``rank_of_z``: Z's columns built so that the rows left out
    see only that many directions (the others are exact zeros of M when that leaves fewer than r − m)."""
    rng = np.random.default_rng(seed)
    Z = np.linalg.qr(rng.standard_normal((n, r)))[0]
    if rank_of_z is not None:  # some basis directions lie wholly on the left-out rows: σ = 0 exactly there
        left = np.setdiff1d(np.arange(n), cols)
        Z[:, :rank_of_z] = 0.0
        Z[left[:rank_of_z], np.arange(rank_of_z)] = 1.0
        Z[:, rank_of_z:] -= Z[:, :rank_of_z] @ (Z[:, :rank_of_z].T @ Z[:, rank_of_z:])
        Z[:, rank_of_z:] = np.linalg.qr(Z[:, rank_of_z:])[0]
    return Z, np.sqrt(w) * Z[cols, :r]


CASES = [  # (n, r, the columns, weight, directions wholly on the left-out rows)
    (38, 26, np.arange(6, 38), 1e-2, None),
    (38, 26, np.arange(6, 38), 1.0, 3),
    (12, 9, np.array([0, 2, 3, 5, 6, 7, 8, 10, 11]), 4.0, None),
    (12, 10, np.array([1, 4, 5, 9]), 1.0, None),  # m < r: at least r − m zeros
    (10, 7, np.arange(3, 10), 1e-6, None),  # every σ under ε: damped
]


@pytest.mark.parametrize("case", range(len(CASES)))
def test_the_level_from_its_left_out_rows_is_solved_as_by_its_svd(case: int) -> None:
    n, r, cols, w, zeros = CASES[case]
    Z, M = _level(case, n, r, cols, w, zeros)
    rhs = np.random.default_rng(100 + case).standard_normal(M.shape[0])
    u, u0 = np.zeros(r), np.zeros(r)
    N, rank, smin, damping = selection_solve(M, Z, cols.astype(np.int64), rhs, np.sqrt(w), EPS, MAX_DAMPING, RCOND, u)
    N0, rank0, smin0, damping0 = _svd_solve(np.ascontiguousarray(M), rhs, EPS, MAX_DAMPING, RCOND, u0)
    assert rank == rank0 and N.shape == N0.shape
    np.testing.assert_allclose([smin, damping], [smin0, damping0], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(u, u0, rtol=0, atol=1e-11 * max(1.0, np.abs(u0).max()))
    np.testing.assert_allclose(N.T @ N, np.eye(r - rank), rtol=0, atol=1e-13)  # an orthonormal basis of the same space
    np.testing.assert_allclose(N @ N.T, N0 @ N0.T, rtol=0, atol=1e-12)
    if zeros:
        assert r - rank == zeros  # (exact zeros computed as norms at rounding size, and truncated)


def test_a_level_that_is_not_finite_is_left_to_the_svd() -> None:
    Z, M = _level(0, 12, 9, np.arange(3, 12), 1.0)
    M[2, 3] = np.nan
    _, rank, _, _ = selection_solve(M, Z, np.arange(3, 12), np.ones(9), 1.0, EPS, MAX_DAMPING, RCOND, np.zeros(9))
    assert rank == -1


def test_only_distinct_unit_rows_of_one_weight_are_a_selection() -> None:
    A = np.eye(6)[[1, 3, 4]]
    cols = np.empty(3, np.int64)
    assert selection_columns(A, np.full(3, 2.0), 0, 3, cols) and list(cols) == [1, 3, 4]
    assert not selection_columns(A, np.array([2.0, 2.0, 1.0]), 0, 3, cols)  # two weights
    assert not selection_columns(A[[1, 0, 2]], np.full(3, 2.0), 0, 3, cols)  # columns not increasing
    B = A.copy()
    B[1, 5] = 1e-300
    assert not selection_columns(B, np.full(3, 2.0), 0, 3, cols)  # one more entry
    assert not selection_columns(2.0 * A, np.full(3, 2.0), 0, 3, cols)  # not unit rows
    assert not selection_columns(np.eye(6), np.ones(6), 0, 6, cols[:0].repeat(6))  # the whole identity: not a part


def test_a_talos_hierarchy_ending_in_a_posture_on_the_actuated_joints_is_the_strict_one() -> None:
    """Gripper poses (level 0), the posture on the actuated joints (level 1): q̇ = x₁ + N₁ (S N₁)⁺ (v₂ − S x₁)."""
    robot = rk.load_example_robot("talos")
    rng = np.random.default_rng(7)
    q = robot.neutral()
    q[7:] += rng.uniform(-0.2, 0.2, robot.nq - 7)
    q[3:7] = pin.Quaternion(pin.exp3(rng.uniform(-0.2, 0.2, 3))).coeffs()
    ref = robot.neutral()
    robot.update(q)
    hands = [rk.FrameTask(f, gain=10.0) for f in ("gripper_left_base_link", "gripper_right_base_link")]
    posture = rk.PostureTask(ref, joints="actuated", gain=2.0, priority=1, weight=3.0)
    stack = rk.TaskStack([*hands, posture])
    stack.reset(robot)
    for task, dz in zip(hands, (0.03, -0.02), strict=True):
        goal = robot.frame_pose(task.frame).copy()
        goal.translation[2] += dz
        task.set_target(goal)
    resolver = rk.make_resolver("hqp", max_joint_speed=None, limits=rk.JointLimits(position=False, velocity=False))
    res = resolver.step(robot, stack, q, 0.0, 0.01)
    assert res.fallback is None and res.info["path"] == "compiled", (res.fallback, res.info)
    terms = {t.name: t for t in res.terms}
    J1 = np.vstack([terms[h.name].J for h in hands])
    v1 = np.concatenate([terms[h.name].v for h in hands])
    J1p = np.linalg.pinv(J1)
    x1 = J1p @ v1
    N1 = np.eye(robot.nv) - J1p @ J1
    S, v2 = terms[posture.name].J, terms[posture.name].v
    expected = x1 + N1 @ np.linalg.pinv(S @ N1, rcond=1e-10) @ (v2 - S @ x1)
    assert np.abs(res.dq - expected).max() <= 1e-9 * np.abs(expected).max()


def test_with_limits_binding_the_posture_as_one_selection_or_as_two_is_the_same_hierarchy() -> None:
    """The benchmark's ``talos_actuated`` stack under ``hqp`` (a joint limit binds on a third of the steps), its
    posture as one ``PostureTask(joints="actuated")`` — rows of I at increasing columns, one weight: the closed
    cascade solves it from the left-out rows — or as two postures splitting those joints at the same level and
    weight (the same rows, not in order: the QR or SVD route). The same q̇ over 150 steps, the steps the limits bind
    included (the constrained cascade takes the SVD for both)."""
    from benchmarks.bench.harness import SCENARIOS

    sc = SCENARIOS["talos_actuated"]()
    runs = []
    for split in (False, True):
        robot = sc.robot()
        q = sc.q0.copy()
        robot.update(q)
        stack = sc.stack("hqp", robot)
        posture = stack.tasks[-1]
        assert isinstance(posture, rk.PostureTask) and posture.joints == "actuated"
        if split:
            names = [j.name for j in robot.joints if j.idx_q >= 7]
            halves = [names[len(names) // 2 :], names[: len(names) // 2]]  # (the second half's rows first)
            parts = [
                rk.PostureTask(sc.q0, joints=h, gain=posture.gain, weight=posture.weight, priority=posture.priority,
                               name=f"posture{i}")
                for i, h in enumerate(halves)
            ]  # fmt: skip
            stack = rk.TaskStack([*stack.tasks[:-1], *parts], stack.subtasks)
        stack.reset(robot)
        resolver = rk.make_resolver("hqp", backend="daqp")
        dqs, qp = [], 0
        for k in range(150):
            res = resolver.step(robot, stack, q, k * sc.dt, sc.dt)
            dqs.append(res.dq.copy())
            qp += res.info.get("qp", 0) > 0
            q = robot.integrate(q, res.dq, sc.dt)
        runs.append((np.array(dqs), qp))
    assert runs[0][1] >= 20 and runs[1][1] == runs[0][1]  # (the constrained cascade ran, as often in both)
    np.testing.assert_allclose(runs[0][0], runs[1][0], rtol=0, atol=1e-9 * np.abs(runs[1][0]).max())

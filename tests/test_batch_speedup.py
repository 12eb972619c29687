"""The batch's fast paths equal the one-by-one loop: the kinematics read through views of Pinocchio's Data (and
without them), ``pinv``'s problems each solved by the single step's kernel, row subsets, no posture, a floating
base, and the whole-array input checks (no timing here)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.resolvers.batch import BatchResolver, _all_rigid
from redundik.resolvers.linalg import K
from redundik.resolvers.registry import make_resolver

Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])


def _targets(robot: rk.RobotModel, Q: np.ndarray, frame: str, rng: np.random.Generator) -> np.ndarray:
    """The frame's pose at each row of Q moved by up to 0.05 rad per velocity coordinate: reachable targets."""
    T = np.empty((Q.shape[0], 4, 4))
    for i, q in enumerate(Q):
        robot.update(pin.integrate(robot.model, q, rng.uniform(-0.05, 0.05, robot.nv)))
        T[i] = robot.frame_pose(frame).homogeneous
    return T


@pytest.fixture(scope="module")
def panda_mixed() -> tuple[rk.RobotModel, np.ndarray, np.ndarray]:
    """36 Panda problems: 28 regular ones (3 at a joint limit: wqp's QP binds) and 8 near a singularity
    (σ_min(J) < 0.01, pinv's ε), whose J fails the Cholesky test of ``pinv``'s fast path (damped)."""
    robot = rk.load_example_robot("panda")
    rng = np.random.default_rng(17)
    lo, hi = robot.lower_limits, robot.upper_limits
    fid = robot.frame_id("panda_hand")
    regular, singular = [], []
    while len(regular) < 28 or len(singular) < 8:
        q = rng.uniform(lo + 0.02, hi - 0.02)
        robot.update(q)
        smin = np.linalg.svd(robot.frame_jacobian(fid), compute_uv=False)[-1]
        (singular if smin < 0.01 else regular).append(q)
    Q = np.array(regular[:28] + singular[:8])
    Q[:3, 3] = hi[3] - 1e-5
    return robot, Q, _targets(robot, Q, "panda_hand", rng)


@pytest.mark.parametrize("method", ["pinv", "wqp"])
@pytest.mark.parametrize(("axes", "posture_gain"), [("pose", 1.0), ("position", 1.0), ("pose", 0.0)])
def test_batch_equals_the_loop_near_singularities(
    method: str, axes: str, posture_gain: float, panda_mixed: tuple
) -> None:
    robot, Q, T = panda_mixed
    batch = BatchResolver(
        make_resolver(method), robot, "panda_hand", axes=axes, gain=20.0, posture_gain=posture_gain, posture_target=Q0
    )
    got = batch.solve(Q, T, 0.01)
    ref = batch.solve_loop(Q, T, 0.01)
    np.testing.assert_allclose(got.dq, ref.dq, atol=1e-9, rtol=0)
    np.testing.assert_allclose(got.task_error, ref.task_error, atol=1e-9)
    np.testing.assert_array_equal(got.qp, ref.qp)
    np.testing.assert_array_equal(got.capped, ref.capped)


def test_pinv_solves_each_problem_with_the_single_steps_kernel(panda_mixed: tuple) -> None:
    """Every problem — the regular ones (Cholesky) and the 8 damped ones (the damped factorisation) — is solved by
    the single step's ``closed_form_into`` (lazy σ_min, as ``pinv``'s step calls it): bit for bit on the batch's own
    rows, and to rounding against the loop of steps."""
    robot, Q, T = panda_mixed
    batch = BatchResolver(make_resolver("pinv"), robot, "panda_hand", gain=20.0, posture_target=Q0)
    got = batch.solve(Q, T, 0.01)
    q, targets = batch._check(Q, T, 0.01)
    J, e, ep = batch._kinematics(q, targets)
    r = batch.resolver
    routes = []
    for i in range(Q.shape[0]):
        out = np.empty((3, robot.nv))
        _, smin, _ = K.closed_form_into(
            J[i].copy(), batch.gain * e[i], batch.posture_gain * ep[i], True, r.epsilon, r.max_damping, 1e-10, out,
            True,
        )  # fmt: skip
        routes.append(np.isnan(smin))  # NaN: the Cholesky route (σ_min left for a read)
        if got.capped[i]:  # the joint-speed cap scaled the row, as it scales a step's q̇
            scale = float(np.linalg.norm(got.dq[i]) / np.linalg.norm(out[2]))
            assert 0.0 < scale < 1.0
            np.testing.assert_allclose(got.dq[i], scale * out[2], rtol=1e-12, atol=1e-12)
        else:
            np.testing.assert_array_equal(got.dq[i], out[2])
    assert sum(routes) == 28 and not got.capped.all()  # the regular problems by Cholesky, the near-singular damped
    np.testing.assert_allclose(got.dq, batch.solve_loop(Q, T, 0.01).dq, atol=1e-9, rtol=0)


@pytest.mark.parametrize("method", ["pinv", "wqp"])
def test_kinematics_without_views_equal_the_views(method: str, panda_mixed: tuple) -> None:
    """Bindings that returned copies of Data's arrays would take the per-object route: the same numbers."""
    robot, Q, T = panda_mixed
    batch = BatchResolver(make_resolver(method), robot, "panda_hand", gain=20.0, posture_target=Q0)
    assert batch._views is not None  # (the bindings here give views on Data's memory)
    with_views = batch.solve(Q, T, 0.01)
    batch._views = None
    without = batch.solve(Q, T, 0.01)
    np.testing.assert_array_equal(with_views.dq, without.dq)
    np.testing.assert_array_equal(with_views.task_error, without.task_error)


def test_the_batch_jacobian_and_error_are_pinocchios(panda_mixed: tuple) -> None:
    """J from the joint Jacobians and the parent's placement equals ``getFrameJacobian`` (LOCAL_WORLD_ALIGNED)
    after ``RobotModel.update``, and the error (p_d − p, log(R_d Rᵀ)) that of the frame's placement."""
    robot, Q, T = panda_mixed
    batch = BatchResolver(make_resolver("pinv"), robot, "panda_hand")
    J, e, _ = batch._kinematics(Q, T)
    fid = robot.frame_id("panda_hand")
    for i in range(Q.shape[0]):
        robot.update(Q[i])
        np.testing.assert_allclose(J[i], robot.frame_jacobian(fid), atol=1e-14)
        M = robot.frame_pose(fid)
        np.testing.assert_allclose(e[i, :3], T[i, :3, 3] - M.translation, atol=1e-14)
        np.testing.assert_allclose(e[i, 3:], pin.log3(T[i, :3, :3] @ M.rotation.T), atol=1e-12)


@pytest.mark.parametrize("method", ["pinv", "wqp"])
@pytest.mark.parametrize("axes", ["pose", ("x", "rz", "y")])
def test_large_rotation_errors_take_pinocchios_log3_and_equal_the_loop(
    method: str, axes: object, panda_mixed: tuple
) -> None:
    """Targets turned 0.6–2.5 rad (beyond ``frame_rows_batch``'s small-angle log3) among small ones, with all rows
    and a reordered subset: the compiled kernels' fallback rows equal the loop."""
    robot, Q, T = panda_mixed
    rng = np.random.default_rng(23)
    T = T.copy()
    for i in range(0, Q.shape[0], 3):
        axis = rng.normal(size=3)
        turn = pin.exp3(rng.uniform(0.6, 2.5) * axis / np.linalg.norm(axis))
        T[i, :3, :3] = turn @ T[i, :3, :3]
    batch = BatchResolver(make_resolver(method), robot, "panda_hand", axes=axes, gain=5.0, posture_target=Q0)
    got, ref = batch.solve(Q, T, 0.01), batch.solve_loop(Q, T, 0.01)
    assert not batch._done.all()  # (the fallback ran)
    np.testing.assert_allclose(got.dq, ref.dq, atol=1e-9, rtol=0)
    np.testing.assert_allclose(got.task_error, ref.task_error, atol=1e-9)
    np.testing.assert_array_equal(got.qp, ref.qp)


@pytest.mark.parametrize("method", ["pinv", "wqp"])
def test_a_floating_base_batch_equals_the_loop(method: str) -> None:
    """nq ≠ nv (a free-flyer's quaternion): the posture error by Pinocchio's difference, the Jacobian's base
    columns included."""
    from redundik.kinematics.urdf import EXAMPLE_ROBOTS, example_robot_data_dir

    robot = rk.from_urdf(example_robot_data_dir() / EXAMPLE_ROBOTS["panda"][0], free_flyer=True)
    rng = np.random.default_rng(4)
    base = np.array([0.1, -0.2, 0.3, 0.0, 0.0, 0.0, 1.0])
    Q = np.empty((12, robot.nq))
    for i in range(12):
        q = pin.integrate(robot.model, np.concatenate([base, Q0]), rng.uniform(-0.3, 0.3, robot.nv))
        Q[i] = q
    ref_q = np.concatenate([base, Q0])
    batch = BatchResolver(make_resolver(method), robot, "panda_hand", gain=10.0, posture_target=ref_q)
    T = _targets(robot, Q, "panda_hand", rng)
    got, ref = batch.solve(Q, T, 0.01), batch.solve_loop(Q, T, 0.01)
    np.testing.assert_allclose(got.dq, ref.dq, atol=1e-9, rtol=0)
    np.testing.assert_allclose(got.task_error, ref.task_error, atol=1e-9)


def test_the_whole_array_rigidity_test_agrees_with_the_per_problem_test() -> None:
    """``_all_rigid`` says True exactly when no problem fails the per-problem test (R Rᵀ within 1e-6 of I,
    det R > 0, last row (0, 0, 0, 1) within 1e-12)."""
    rng = np.random.default_rng(8)
    good = np.stack([pin.SE3.Random().homogeneous for _ in range(20)])
    assert _all_rigid(good)
    for spoil in range(5):
        T = good.copy()
        k = int(rng.integers(20))
        if spoil == 0:
            T[k, :3, :3] *= 1.0 + 1e-5  # not orthonormal
        elif spoil == 1:
            T[k, :3, 0] *= -1.0  # a reflection: det −1
        elif spoil == 2:
            T[k, 3, 0] = 1e-11  # last row
        elif spoil == 3:
            T[k, 3, 3] = 1.0 + 1e-11
        else:
            T[k, :3, :3] *= 1.0 + 4e-7  # within the tolerance: still rigid
        R = T[:, :3, :3]
        per_problem = (
            np.all(np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)) <= 1e-6, axis=(1, 2))
            & (np.linalg.det(R) > 0)
            & np.all(np.abs(T[:, 3] - (0.0, 0.0, 0.0, 1.0)) <= 1e-12, axis=1)
        )
        assert _all_rigid(T) == bool(per_problem.all()) == (spoil == 4)


def test_a_bad_target_among_many_is_named(panda_mixed: tuple) -> None:
    robot, Q, T = panda_mixed
    batch = BatchResolver(make_resolver("pinv"), robot, "panda_hand")
    bad = T.copy()
    bad[7, :3, 0] *= -1.0
    with pytest.raises(rk.ResolverError, match=r"targets of problems \[7\] are not rigid"):
        batch.solve(Q, bad, 0.01)
    qbad = Q.copy()
    qbad[3, 2] = np.inf
    with pytest.raises(rk.ResolverError, match=r"q of problems \[3\] contain NaN or infinite"):
        batch.solve(qbad, T, 0.01)
    qbad[3, 2], qbad[5, 0] = 2e9, -1e200  # finite, but no configuration: refused as a step refuses it
    with pytest.raises(rk.ResolverError, match=r"q of problems \[3, 5\] have entries beyond ±1e\+09"):
        batch.solve(qbad, T, 0.01)


@pytest.mark.parametrize("method", ["pinv", "wqp"])
@pytest.mark.parametrize("count", [1, 2, 36])
def test_a_results_arrays_are_its_own_after_the_next_call(method: str, count: int, panda_mixed: tuple) -> None:
    """A batch reuses its scratch from call to call: the arrays of a result it returned (one problem or many) are
    unchanged by the next call on other problems, and equal those of a batch that made only the first call."""
    robot, Q, T = panda_mixed
    batch = BatchResolver(make_resolver(method), robot, "panda_hand")
    first = batch.solve(Q[:count], T[:count], 0.01)
    kept = first.dq.copy(), first.task_error.copy()
    batch.solve(Q[::-1][:count], T[::-1][:count], 0.01)
    np.testing.assert_array_equal(first.dq, kept[0])
    np.testing.assert_array_equal(first.task_error, kept[1])
    alone = BatchResolver(make_resolver(method), robot, "panda_hand").solve(Q[:count], T[:count], 0.01)
    np.testing.assert_array_equal(first.dq, alone.dq)


@pytest.mark.parametrize("method", ["pinv", "wqp"])
@pytest.mark.parametrize("how", ["pickle", "deepcopy"])
def test_a_copied_batch_reads_its_own_kinematics(method: str, how: str, panda_mixed: tuple) -> None:
    """A pickled or deep-copied batch (a worker's copy) solves as a fresh batch does, on other problems than the
    original last solved, and the original is unaffected: each reads the Pinocchio data of its own (a view copied
    with it read the original's memory, or a frozen copy: silently wrong q̇)."""
    import copy
    import pickle

    robot, Q, T = panda_mixed
    batch = BatchResolver(make_resolver(method), robot, "panda_hand")
    batch.solve(Q[:20], T[:20], 0.01)
    twin = pickle.loads(pickle.dumps(batch)) if how == "pickle" else copy.deepcopy(batch)
    fresh = BatchResolver(make_resolver(method), robot, "panda_hand")
    got = twin.solve(Q[16:], T[16:], 0.01)
    np.testing.assert_array_equal(got.dq, fresh.solve(Q[16:], T[16:], 0.01).dq)
    np.testing.assert_array_equal(batch.solve(Q[16:], T[16:], 0.01).dq, got.dq)

"""Batches equal the one-by-one loop; the compiled kernels equal slow NumPy references (no timing here)."""

from __future__ import annotations

import numpy as np
import pytest

import redundik as rk
from redundik.resolvers import kernels
from redundik.resolvers.base import LazyStepResult
from redundik.resolvers.batch import BatchResolver, batch_log3, solve_batch
from redundik.resolvers.registry import make_resolver

Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])


@pytest.fixture(scope="module")
def panda_problems() -> tuple[rk.RobotModel, np.ndarray, np.ndarray]:
    robot = rk.load_example_robot("panda")
    rng = np.random.default_rng(3)
    lo, hi = robot.lower_limits, robot.upper_limits
    N = 60
    Q = np.clip(Q0 + rng.uniform(-0.4, 0.4, (N, 9)), lo + 1e-4, hi - 1e-4)
    Q[:5, 3] = hi[3] - 1e-5  # five problems start at a joint limit: their QP binds
    T = np.empty((N, 4, 4))
    for i in range(N):
        robot.update(np.clip(Q0 + rng.uniform(-0.4, 0.4, 9), lo, hi))
        T[i] = robot.frame_pose("panda_hand").homogeneous
    return robot, Q, T


@pytest.mark.parametrize("method", ["pinv", "wqp"])
def test_batch_equals_the_loop(method: str, panda_problems: tuple) -> None:
    robot, Q, T = panda_problems
    batch = BatchResolver(make_resolver(method), robot, "panda_hand", gain=5.0, posture_gain=1.0, posture_target=Q0)
    got = batch.solve(Q, T, 0.01)
    ref = batch.solve_loop(Q, T, 0.01)
    np.testing.assert_allclose(got.dq, ref.dq, atol=1e-9, rtol=0)
    np.testing.assert_allclose(got.task_error, ref.task_error, atol=1e-9)
    np.testing.assert_array_equal(got.qp, ref.qp)
    if method == "wqp":
        assert 0 < got.qp.sum() < len(Q)  # some problems needed the backend, most did not


@pytest.mark.parametrize("backend", ["daqp", "quadprog", "proxsuite"])
def test_limit_bound_problems_go_straight_to_the_backend(
    backend: str, panda_problems: tuple, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The batch's QP for a problem whose limits bind is the single step's, handed to the backend as rows of the
    batch's arrays; only a problem the backend refuses may take the single-problem step."""
    robot, Q, T = panda_problems
    batch = BatchResolver(make_resolver("wqp", backend=backend), robot, "panda_hand", gain=5.0, posture_gain=1.0)

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("a limit-bound problem went through the single-problem step")

    monkeypatch.setattr(batch, "solve_loop", refuse)
    got = batch.solve(Q, T, 0.01)
    assert got.qp.sum() >= 5


def test_binding_problems_take_daqps_c_entry_with_the_wrappers_answer(
    panda_problems: tuple, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Under daqp the binding problems' box QPs are solved in one compiled loop through daqp's C entry point, not
    one ``backend.solve`` each, with the answer of the Python wrapper bit for bit (the same C call on the same
    arrays); with the native call off they go through ``backend.solve`` as before."""
    from redundik.resolvers.qp import daqp_native

    if daqp_native.entry() == 0:
        pytest.fail(f"daqp's native call is off here: {daqp_native.status()}")
    robot, Q, T = panda_problems
    resolver = make_resolver("wqp")
    batch = BatchResolver(resolver, robot, "panda_hand", gain=5.0, posture_gain=1.0, posture_target=Q0)
    calls = []
    solve = type(resolver.backend).solve
    monkeypatch.setattr(type(resolver.backend), "solve", lambda self, *a, **k: calls.append(1) or solve(self, *a, **k))
    native = batch.solve(Q, T, 0.01)
    assert native.qp.sum() >= 5 and not calls  # every binding problem solved natively
    monkeypatch.setattr(daqp_native, "enabled", False)
    wrapped = batch.solve(Q, T, 0.01)
    assert len(calls) == native.qp.sum()  # now one backend.solve per binding problem
    np.testing.assert_array_equal(native.dq, wrapped.dq)
    np.testing.assert_array_equal(native.qp, wrapped.qp)


def test_box_qps_native_leaves_an_infeasible_box_to_the_caller() -> None:
    """A box QP daqp does not solve (lb > ub: infeasible) is flagged unsolved and its row of dq left untouched; the
    others are solved and clipped to their box."""
    from redundik.resolvers.qp import daqp_native
    from redundik.resolvers.qp.backends import DaqpBackend

    if daqp_native.entry() == 0:
        pytest.fail(f"daqp's native call is off here: {daqp_native.status()}")
    rng = np.random.default_rng(5)
    N, n = 4, 5
    B = rng.standard_normal((N, n, n))
    P = B @ B.transpose(0, 2, 1) + 0.5 * np.eye(n)
    q = 3.0 * rng.standard_normal((N, n))
    lb, ub = np.full((N, n), -0.2), np.full((N, n), 0.2)
    lb[2, 1], ub[2, 1] = 0.5, 0.1  # problem 2 cannot be solved
    native = daqp_native.NativeDaqp.for_backend(DaqpBackend(), n, 0, None)
    assert native is not None
    dq = np.full((N, n), 7.0)
    solved = np.zeros(N, dtype=np.bool_)
    daqp_native.HK.box_qps_native(native.ctl, native.x, np.empty(n * n + 3 * n), P, q, lb, ub, np.arange(N), dq, solved)
    assert solved.tolist() == [True, True, False, True]
    np.testing.assert_array_equal(dq[2], 7.0)
    for i in (0, 1, 3):  # the KKT conditions of the box QP: a gradient that only pushes against active bounds
        g = P[i] @ dq[i] + q[i]
        at_lb, at_ub = np.isclose(dq[i], lb[i], atol=1e-9), np.isclose(dq[i], ub[i], atol=1e-9)
        assert np.all((np.abs(g) < 1e-8) | (at_lb & (g > -1e-8)) | (at_ub & (g < 1e-8)))
        assert at_lb.any() or at_ub.any()  # the box binds (q was scaled so that it does)


def test_solve_batch_refuses_other_resolvers(panda_problems: tuple) -> None:
    robot, Q, T = panda_problems
    with pytest.raises(rk.ResolverError, match="batches take 'pinv'"):
        solve_batch(make_resolver("hqp"), robot, "panda_hand", Q, T, 0.01)


def test_batch_log3_matches_pinocchio() -> None:
    import pinocchio as pin

    rng = np.random.default_rng(0)
    w = rng.normal(size=(40, 3))
    w[:5] *= 1e-6
    w[5] = [np.pi - 1e-9, 0, 0]
    w[6:16] *= 0.44 / np.linalg.norm(w[6:16], axis=1, keepdims=True) * np.linspace(0.05, 1.0, 10)[:, None]
    R = np.stack([pin.exp3(v) for v in w])
    ref = np.stack([pin.log3(r) for r in R])
    np.testing.assert_allclose(batch_log3(R), ref, atol=1e-9)


def _reference_pinv(J: np.ndarray, eps: float, lmax: float, rcond: float) -> tuple[np.ndarray, np.ndarray]:
    """Slow reference: full SVD, the damping rule written out, J⁺_λ and I − V_r V_rᵀ formed."""
    U, s, Vt = np.linalg.svd(J)
    r = int(np.sum(s > rcond * s[0])) if s.size and s[0] > 0 else 0
    inv = np.zeros_like(s)
    for i in range(r):
        inv[i] = 1 / s[i] if s[i] >= eps else s[i] / (s[i] ** 2 + (1 - (s[i] / eps) ** 2) * lmax**2)
    k = s.size
    return (Vt[:k].T * inv) @ U[:, :k].T, np.eye(J.shape[1]) - Vt[:r].T @ Vt[:r]


@pytest.mark.parametrize("case", ["well", "near_singular", "rank_deficient", "wide"])
def test_closed_form_kernel_matches_the_reference(case: str) -> None:
    rng = np.random.default_rng(7)
    J = rng.normal(size=(6, 9))
    if case == "near_singular":
        J[5] = J[4] + 1e-4 * rng.normal(size=9)
    elif case == "rank_deficient":
        J[5] = J[4]
    elif case == "wide":
        J = rng.normal(size=(3, 12))
    V, z = rng.normal(size=J.shape[0]), rng.normal(size=J.shape[1])
    dq_r, dq_n, rank, _smin, _damping = kernels.closed_form(J, V, z, True, 1e-2, 5e-2, 1e-10)
    pinv, null = _reference_pinv(J, 1e-2, 5e-2, 1e-10)
    np.testing.assert_allclose(dq_r, pinv @ V, atol=1e-9)
    np.testing.assert_allclose(dq_n, null @ z, atol=1e-9)
    assert rank == np.linalg.matrix_rank(J)
    single, batch = np.empty((3, J.shape[1])), np.empty((1, 3, J.shape[1]))
    kernels.closed_form_into(J, V, z, True, 1e-2, 5e-2, 1e-10, single, True)  # (as pinv's step calls it)
    np.testing.assert_allclose(single, [pinv @ V, null @ z, pinv @ V + null @ z], atol=1e-9)
    kernels.closed_form_batch(J[None], V[None], z[None], True, 1e-2, 5e-2, 1e-10, batch)
    np.testing.assert_array_equal(batch[0], single)  # the batch is the same kernel, problem by problem


@pytest.mark.parametrize("n", [5, 40])
def test_spd_kernel_matches_numpy(n: int) -> None:
    rng = np.random.default_rng(n)
    A = rng.normal(size=(n, n))
    P, q = A @ A.T + 1e-3 * np.eye(n), rng.normal(size=n)
    x, ok, inside = kernels.spd_solve_box(P, q, np.full(n, -np.inf), np.full(n, np.inf), 0.0)
    assert ok and inside
    np.testing.assert_allclose(x, np.linalg.solve(P, -q), rtol=1e-9, atol=1e-9)
    _, ok, _ = kernels.spd_solve_box(-P, q, np.zeros(n), np.zeros(n), 0.0)
    assert not ok


def test_first_run_cost_is_reported() -> None:
    cost = kernels.first_run_cost()
    assert set(cost) == {"closed_form", "closed_form_batch", "spd_solve_batch"} and all(v >= 0 for v in cost.values())


def test_qp_diagnostics_are_computed_on_first_read(panda_problems: tuple) -> None:
    robot, _Q, _T = panda_problems
    task = rk.FrameTask("panda_hand", gain=5.0)
    stack = rk.TaskStack([task, rk.PostureTask(Q0)])
    robot.update(Q0)
    stack.reset(robot)
    res = make_resolver("wqp").step(robot, stack, Q0.copy(), 0.0, 0.01)
    assert isinstance(res, LazyStepResult) and res.pending is not None
    assert res.info["qp"] == 0 and res.pending is not None  # eager keys do not trigger the diagnostics
    assert "residual_L0" in res.info and res.pending is None
    assert np.isfinite(res.sigma_min) and res.sigma_min > 0

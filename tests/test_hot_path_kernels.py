"""The hot path's compiled kernels equal slow references (no timing here): the joint-limit box, the Jacobi
eigen/SVD routines, the Gram update of ``wqp``, the frame-task error and one ``hqp`` level."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.resolvers import kernels
from redundik.resolvers.qp.limits import JointLimits


def _reference_box(
    lim: JointLimits, q: np.ndarray, dt: float, dq_prev: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The rules of the limits module's docstring, written out joint by joint (slow)."""
    lo, hi, vmax, amax = lim._lo, lim._hi, lim._vmax, lim._amax
    nv = lo.shape[0]
    lb, ub, pl, pu = (np.empty(nv) for _ in range(4))
    g = lim.position_gain / dt
    for i in range(nv):
        vm, a = vmax[i], amax[i]
        if lim.position:
            qv = q[lim._iq[i]]
            lpos, upos = (lo[i] - qv) * g, (hi[i] - qv) * g
            if np.isfinite(a):
                adt = a * dt
                if hi[i] >= qv:
                    upos = min(upos, -adt + np.sqrt(adt**2 + 2 * a * max(hi[i] - qv, 0.0)))
                if lo[i] <= qv:
                    lpos = max(lpos, adt - np.sqrt(adt**2 + 2 * a * max(qv - lo[i], 0.0)))
            lpos, upos = min(lpos, vm), max(upos, -vm)
            low, up = max(lpos, -vm), min(upos, vm)
            if lim._has_rate and low > up:
                if qv > hi[i]:
                    low = lpos = up
                elif qv < lo[i]:
                    up = upos = low
        else:
            lpos, upos, low, up = -np.inf, np.inf, -vm, vm
        if lim._has_rate and dq_prev is not None:
            step = a * dt
            low, up = min(max(dq_prev[i] - step, low), up), min(max(dq_prev[i] + step, low), up)
        lb[i], ub[i], pl[i], pu[i] = low, up, lpos, upos
    return lb, ub, pl, pu


@pytest.mark.parametrize(
    "options",
    [{}, {"acceleration": 5.0}, {"acceleration": 0.5, "position_gain": 0.5}, {"position": False, "acceleration": 2.0}],
)
def test_limit_box_equals_the_rules(options: dict) -> None:
    robot = rk.load_example_robot("panda")
    lim = JointLimits(**options)
    rng = np.random.default_rng(1)
    for k in range(60):
        q = robot.random_configuration(rng) + rng.normal(0.0, 0.05, robot.nq) * (k % 3 == 0)  # some start outside
        dt = (0.01, 0.001, 0.1)[k % 3]
        prev = rng.uniform(-3.0, 3.0, robot.nv) if k % 2 else None
        box = lim.box(robot, q, dt, prev)
        for got, want in zip((box.lb, box.ub, box.pos_lo, box.pos_hi), _reference_box(lim, q, dt, prev), strict=True):
            np.testing.assert_allclose(got, want, rtol=1e-15, atol=0)
        assert np.all(box.lb <= box.ub)
    Q = np.stack([robot.random_configuration(rng) for _ in range(4)])
    batch = lim.box(robot, Q, 0.01)
    for i in range(4):
        np.testing.assert_array_equal(batch.lb[i], lim.box(robot, Q[i], 0.01).lb)


def test_jacobi_eigen_and_svd_match_lapack() -> None:
    rng = np.random.default_rng(2)
    for trial in range(400):
        m, n = int(rng.integers(1, 10)), int(rng.integers(1, 12))
        M = rng.normal(size=(m, n))
        if trial % 4 == 1 and m > 1:
            M[-1] = M[0]  # a duplicated row: rank deficient
        elif trial % 4 == 2:
            M[:, 0] *= 1e-6
        elif trial % 4 == 3:
            M[0] = 0.0
        U, s, Vt = kernels.svd_full(M)
        k = min(m, n)
        np.testing.assert_allclose(s, np.linalg.svd(M, compute_uv=False), atol=1e-13 * max(1.0, s[0]))
        np.testing.assert_allclose(Vt @ Vt.T, np.eye(n), atol=1e-13)
        np.testing.assert_allclose((U * s) @ Vt[:k], M, atol=1e-12)
        A = M @ M.T
        w, V = kernels.sym_eig(A)
        np.testing.assert_allclose(w, np.linalg.eigvalsh(A), atol=1e-12 * max(1.0, abs(w).max()))
        np.testing.assert_allclose(V @ np.diag(w) @ V.T, A, atol=1e-12 * max(1.0, abs(w).max()))


def test_wide_svd_routes_match_lapack() -> None:
    """The Jacobi SVD of Mᵀ for a wide M of few rows (full: Householder-completed null directions; thin), on
    random, rank-deficient, scaled and zero matrices up to and beyond the widths where LAPACK takes over."""
    rng = np.random.default_rng(12)
    for trial in range(300):
        m = int(rng.integers(1, kernels.JACOBI_SVD_MAX + 2))
        n = m + int(rng.integers(1, 40))
        M = rng.normal(size=(m, n)) * 10.0 ** rng.uniform(-6, 6)
        if trial % 5 == 1 and m > 1:
            M[-1] = M[0]
        elif trial % 5 == 2:
            M[0] = 0.0
        elif trial % 5 == 3 and m > 2:
            M[2] = M[0] + 1e-9 * M[1]  # nearly rank deficient
        elif trial % 5 == 4:
            M[:] = 0.0 if trial % 10 == 4 else M
        scale = max(1.0, float(np.abs(M).max()))
        want = np.linalg.svd(M, compute_uv=False)
        U, s, Vt = kernels.svd_full(M)
        np.testing.assert_allclose(s, want, atol=1e-13 * scale * n)
        np.testing.assert_allclose(Vt @ Vt.T, np.eye(n), atol=1e-13)
        np.testing.assert_allclose((U * s) @ Vt[:m], M, atol=1e-12 * scale)
        assert np.all(np.abs(M @ Vt[m:].T) <= 1e-12 * scale)  # the null directions: M v = 0
        Ut, st, Vtt, _, rank, _, _ = kernels.damped_svd_thin(M, 1e-2, 5e-2, 1e-10)
        np.testing.assert_allclose(st, want, atol=1e-13 * scale * n)
        assert Vtt.shape == (m, n)
        assert rank == (int(np.sum(want > 1e-10 * want[0])) if want[0] > 0 else 0)
        np.testing.assert_allclose(Vtt[:rank] @ Vtt[:rank].T, np.eye(rank), atol=1e-13)
        np.testing.assert_allclose((Ut[:, :rank] * st[:rank]) @ Vtt[:rank], M, atol=1e-12 * scale)
    bad = np.ones((3, 10))
    bad[1, 2] = np.nan
    with pytest.raises(np.linalg.LinAlgError):  # not finite: LAPACK's refusal, as before the Jacobi route
        kernels.svd_full(bad)


def test_gram_update_equals_numpy() -> None:
    rng = np.random.default_rng(3)
    P, q = rng.normal(size=(9, 9)), rng.normal(size=9)
    J, v = rng.normal(size=(6, 9)), rng.normal(size=6)
    P0, q0 = P.copy(), q.copy()
    kernels.gram_update(P, q, np.asfortranarray(J), v, 0.3, False)  # a column-major Jacobian too
    np.testing.assert_allclose(P, P0 + 0.3 * J.T @ J, atol=1e-13)
    np.testing.assert_allclose(q, q0 - 0.3 * J.T @ v, atol=1e-13)
    kernels.gram_update(P, q, J, v, 0.3, True)  # reset: the first task of a step overwrites what was there
    np.testing.assert_allclose(P, 0.3 * J.T @ J, atol=1e-13)
    np.testing.assert_allclose(q, -0.3 * J.T @ v, atol=1e-13)


def test_frame_error_equals_pinocchio_log3() -> None:
    rng = np.random.default_rng(4)
    rows = np.arange(6)
    taken = 0
    for k in range(2000):
        angle = (1e-12, 1e-7, 1e-3, 0.1, 0.44, 0.5, 2.0, np.pi - 1e-6)[k % 8]
        axis = rng.normal(size=3)
        R = pin.exp3(rng.normal(size=3))
        R_d = pin.exp3(axis / np.linalg.norm(axis) * angle) @ R
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, rng.normal(size=3)
        p_d, twist = rng.normal(size=3), rng.normal(size=6)
        e, v = np.empty(6), np.empty(6)
        if kernels.frame_error(p_d, R_d, T, twist, 3.0, rows, True, e, v):
            taken += 1
            ref = np.concatenate((p_d - T[:3, 3], pin.log3(R_d @ R.T)))
            np.testing.assert_allclose(e, ref, atol=1e-14)
            np.testing.assert_allclose(v, twist + 3.0 * ref, atol=1e-13)
        else:
            assert angle > 0.45  # only large rotations are left to Pinocchio's log3
    assert taken >= 1000
    sel = np.array([0, 1, 5])
    e, v = np.empty(3), np.empty(3)
    assert kernels.frame_error(p_d, R, T, twist, 2.0, sel, True, e, v)
    np.testing.assert_allclose(e[:2], (p_d - T[:3, 3])[:2], atol=1e-15)


def test_lsq_level_equals_the_damped_pseudo_inverse() -> None:
    rng = np.random.default_rng(5)
    A, b, x = rng.normal(size=(6, 9)), rng.normal(size=6), rng.normal(size=9)
    out = np.empty(9)
    Z, smin, damping, rank = kernels.lsq_level(A, b, x, np.zeros((0, 0)), False, 1e-2, 5e-2, 1e-10, out)
    np.testing.assert_allclose(out, np.linalg.pinv(A) @ (b - A @ x), atol=1e-12)
    assert rank == 6 and damping == 0.0 and Z.shape == (9, 3)
    np.testing.assert_allclose(A @ Z, 0.0, atol=1e-12)
    np.testing.assert_allclose(smin, np.linalg.svd(A, compute_uv=False)[-1], rtol=1e-12)
    A2, b2 = rng.normal(size=(7, 9)), rng.normal(size=7)
    out2 = np.empty(9)
    Z2, *_ = kernels.lsq_level(A2, b2, out, Z, True, 1e-2, 5e-2, 1e-10, out2)
    u = np.linalg.pinv(A2 @ Z) @ (b2 - A2 @ out)
    np.testing.assert_allclose(out2, out + Z @ u, atol=1e-11)
    assert Z2.shape == (9, 0)


def test_cholesky_closed_form_equals_the_svd_pseudo_inverse() -> None:
    """``pinv``'s Cholesky route (well-conditioned J, σ_min left for later) gives the damped-SVD answer of
    eqs. (5.7)/(5.8), and declines exactly where a direction would be damped or the conditioning is poor."""
    rng = np.random.default_rng(11)
    eps, lam_max = 1e-2, 5e-2
    taken = declined = 0
    for trial in range(300):
        m, n = int(rng.integers(1, 7)), 7
        J = rng.normal(size=(m, n))
        if trial % 3 == 1:  # near-singular: one direction squeezed around ε
            U, s, Vt = np.linalg.svd(J, full_matrices=False)
            s[-1] = eps * rng.uniform(0.3, 3.0)
            J = (U * s) @ Vt
        V, z = rng.normal(size=m), rng.normal(size=n)
        lazy, eager = np.empty((3, n)), np.empty((3, n))
        r1, s1, d1 = kernels.closed_form_into(J, V, z, True, eps, lam_max, 1e-10, lazy, True)
        r0, s0, d0 = kernels.closed_form_into(J, V, z, True, eps, lam_max, 1e-10, eager, False)
        np.testing.assert_allclose(lazy, eager, atol=1e-10 * max(1.0, float(np.abs(eager).max())))
        sv = np.linalg.svd(J, compute_uv=False)
        if np.isnan(s1):
            taken += 1
            assert sv[-1] > eps and d1 == 0.0 and r1 == m  # never a damped direction on this route
            Jp = np.linalg.pinv(J)
            np.testing.assert_allclose(lazy[0], Jp @ V, atol=1e-9)
            np.testing.assert_allclose(lazy[1], z - Jp @ (J @ z), atol=1e-9)
        else:
            declined += 1
            assert (s1, d1, r1) == (s0, d0, r0)
    assert taken > 50 and declined > 20


def test_damped_eigen_route_equals_the_damped_svd_of_numpy() -> None:
    """``factor``'s eigen route with damped directions (J of full row rank, κ ≤ 1e3, σ_min < ε): J⁺_λ b, the
    undamped null projection (I − J⁺J) z, σ_min, λ at σ_min and the rank, each against NumPy's SVD with the damping
    rule σ/(σ² + λ²), λ² = (1 − (σ/ε)²) λ_max² (eq. 5.7's damped least squares)."""
    rng = np.random.default_rng(23)
    eps, lam_max = 5e-2, 1e-1
    taken = 0
    for _ in range(400):
        m = int(rng.integers(1, 7))
        n = int(rng.integers(m, 12))
        U, _ = np.linalg.qr(rng.normal(size=(m, m)))
        W, _ = np.linalg.qr(rng.normal(size=(n, n)))
        s = np.sort(10.0 ** rng.uniform(-2.9, 0.4, m))[::-1]
        J = (U * s) @ W[:m]
        b, z = rng.normal(size=m), rng.normal(size=n)
        fast, Uf, d, Vt, inv, rank, smin, damping = kernels.factor(J, eps, lam_max, 1e-10)
        if not (fast and damping > 0.0):
            continue
        taken += 1
        u, sv, vt = np.linalg.svd(J, full_matrices=False)
        lam2 = np.where(sv < eps, (1.0 - (sv / eps) ** 2) * lam_max**2, 0.0)
        x_ref = vt.T @ (sv / (sv**2 + lam2) * (u.T @ b))
        x = kernels.solve_factored(fast, J, Uf, inv, Vt, b)
        np.testing.assert_allclose(x, x_ref, rtol=0, atol=1e-11 * np.linalg.norm(x_ref))
        p = kernels.null_project_factored(fast, J, Uf, d, Vt, rank, z)
        np.testing.assert_allclose(p, z - vt.T @ (vt @ z), rtol=0, atol=1e-9 * np.linalg.norm(z))
        np.testing.assert_allclose(J @ p, 0.0, atol=1e-9 * np.linalg.norm(z))  # undamped: exactly in null(J)
        out = np.empty((3, n))  # pinv's closed form (eq. 5.8) on the same factors
        kernels.closed_form_into(J, b, z, True, eps, lam_max, 1e-10, out, True)
        np.testing.assert_allclose(out[0], x_ref, rtol=0, atol=1e-11 * np.linalg.norm(x_ref))
        np.testing.assert_allclose(out[1], p, rtol=0, atol=1e-15 * np.linalg.norm(z))
        assert rank == m
        assert smin == pytest.approx(sv[-1], rel=1e-9)
        assert damping == pytest.approx(np.sqrt(1.0 - (sv[-1] / eps) ** 2) * lam_max, rel=1e-9)
    assert taken > 100


def test_pinv_sigma_min_on_request_equals_the_singular_value() -> None:
    robot = rk.load_example_robot("panda")
    q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])  # away from singularities
    robot.update(q)
    stack = rk.TaskStack([rk.FrameTask("panda_hand", gain=1.0)])
    stack.reset(robot)
    res = rk.make_resolver("pinv").step(robot, stack, q, 0.0, 0.01)
    J = robot.frame_jacobian("panda_hand")
    smin = float(np.linalg.svd(J, compute_uv=False)[-1])
    assert res.sigma_min == pytest.approx(smin, rel=1e-9)
    assert res.info["sigma_min"] == pytest.approx(smin, rel=1e-9)
    assert not res.damped and res.info["rank"] == 6


def test_gram_diagonal_matches_is_allclose_of_the_gram_diagonal() -> None:
    """``wqp``'s test of its lifted factor: diag(FᵀF) + δ against P's diagonal, NumPy's allclose rule."""
    rng = np.random.default_rng(21)
    for trial in range(400):
        m, n = int(rng.integers(1, 12)), int(rng.integers(1, 50))
        F = rng.normal(size=(m, n)) * 10.0 ** rng.uniform(-4, 4)
        shift = float(10.0 ** rng.uniform(-9, 1))
        want = np.einsum("ij,ij->j", F, F) + shift
        diag = want.copy()
        if trial % 3 == 1:
            diag[int(rng.integers(n))] *= 1.0 + float(10.0 ** rng.uniform(-12, -6))  # around the 1e-9 tolerance
        elif trial % 3 == 2:
            diag[int(rng.integers(n))] = np.nan
        expected = np.allclose(want, diag, rtol=1e-9, atol=1e-12 * float(np.max(np.abs(want), initial=1.0)))
        strided = np.zeros((n, n))
        strided.reshape(-1)[:: n + 1] = diag
        view = strided.reshape(-1)[:: n + 1]  # the Hessian's diagonal, as wqp passes it
        assert kernels.gram_diagonal_matches(F, shift, view, 1e-9) == expected, trial
    assert not kernels.gram_diagonal_matches(np.ones((2, 3)), 0.0, np.ones(4), 1e-9)


def test_squares_below_is_the_steps_check_of_q() -> None:
    """``squares_below`` (``Resolver.step``'s check of q on every tick) is qᵀq < bound for finite q, False for a NaN,
    an infinite entry or an entry whose square overflows, on strided q too, and raises no floating-point warning."""
    import warnings

    rng = np.random.default_rng(11)
    bound2 = 1e18
    cases = [rng.uniform(-3, 3, n) for n in (1, 3, 9, 33, 160)]
    cases += [np.array([1e9 - 1.0, 0.0]), np.array([1e9, 0.0]), np.array([7e8, 7.2e8])]
    cases += [np.array([np.nan, 0.0]), np.array([0.0, np.inf]), np.array([-np.inf]), np.array([1e200, 1.0])]
    cases += [np.arange(20.0)[::3], np.zeros(0)]
    with warnings.catch_warnings(), np.errstate(all="raise"):
        warnings.simplefilter("error")
        for q in cases:
            with np.errstate(all="ignore"):
                expected = bool(np.isfinite(q).all() and float(np.sum(q.astype(np.longdouble) ** 2)) < bound2)
            assert kernels.squares_below(q, bound2) is expected, q


@pytest.mark.parametrize(("K", "m", "n"), [(0, 0, 1), (1, 6, 9), (2, 13, 38), (3, 7, 4)])
def test_wqp_work_views_sliced_in_python_are_the_compiled_ones(K: int, m: int, n: int) -> None:
    """``wqp_fused.work_views`` (the step's Python slicing) names the same parts of ``work`` as the kernels'
    ``wqp_work_views``: the same offsets, shapes and memory."""
    from redundik.resolvers.linalg import FK
    from redundik.resolvers.qp.wqp_fused import work_views

    work = np.arange(float(FK.wqp_work_size(K, m, n, 0)))
    for ours, theirs in zip(work_views(work, K, m, n), FK.wqp_work_views(work, K, m, n), strict=True):
        assert ours.shape == theirs.shape
        np.testing.assert_array_equal(ours, theirs)
        assert ours.size == 0 or np.shares_memory(ours, work)

"""hqp's lean step against the previous general path: the same q̇ and diagnostics to 1e-10.

The lean step solves the unconstrained cascade in one compiled call (``hqp_kernels.closed_cascade``, a certified QR
where no direction is damped), builds its Level records and σ_min/rank-loss diagnostics only when they are read, and
keeps a level QP's unconstrained optimum when it satisfies the level's rows. The reference here is the path it
replaced: the cascade level by level in Python through ``kernels.lsq_level`` on stacked Level records, every level of
the constrained cascade that the shortcut does not settle solved by the backend.
"""

from __future__ import annotations

import numpy as np
import pytest

import redundik as rk
from redundik.kinematics import DHRow
from redundik.resolvers.qp.hqp import HK, HierarchicalQPResolver
from tests.hqp_reference import _compare, _PythonCascade, _Reference, _same_optima, _stack
from tests.test_qp_helpers import prepared, random_robot, tip


@pytest.mark.parametrize("seed", range(40))
def test_lean_step_equals_the_general_path_on_random_robots(seed: int) -> None:
    """Closed-form steps to 1e-10 with every diagnostic; steps that call the backend to the same optimum of every
    level (1e-6). The two paths pose the same level QPs in different but equivalent forms (the buffer's stacked form
    and ``QPProblem``'s), and where the optimum sits on several nearly tied limits the solver ends at different points
    of its tolerance: over 600 seeds of this construction, 3 steps differed by up to 2.6e-8 in q̇ with LAPACK's null
    bases, 5 by up to 9.5e-7 with the Jacobi ones (seed 18: level 0's residual 4e-7 apart relative, the other path's
    the nearer in one case, this one's in another; quadprog on both paths: 1e-7 in q̇, 1e-15 in the residuals)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 9))
    tight = seed % 3 == 0  # tight velocity limits: the QP path, level by level
    robot = random_robot(rng, n, velocity=float(rng.uniform(0.2, 0.6)) if tight else np.inf)
    q = robot.random_configuration(rng)
    if seed % 4 == 1:  # near a singularity: the tip frame's joints almost aligned
        q = q * 1e-4
    stack = _stack(robot, rng, depth=int(rng.integers(1, 5)), bound=bool(seed % 2))
    if seed % 5 == 2:  # a rate limit: the window of the previous q̇ in the box (three steps)
        _compare(
            robot, stack, q, steps=3, qp_tol=1e-6, limits=rk.JointLimits(acceleration=float(rng.uniform(2.0, 20.0)))
        )
    else:
        _compare(robot, stack, q, qp_tol=1e-6)


@pytest.mark.parametrize("seed", range(12))
def test_lean_step_equals_the_general_path_with_pinned_joints(seed: int) -> None:
    """A joint whose limits are one value (its q̇ pinned to 0): the constrained cascade with the joint fixed — with
    the reference's SVD at every level to 1e-10, and with the certified QR (other null bases of the same spaces) to
    the same optimum of every level: their q̇ may differ by the level QPs' conditioning (seed 11: 1.5e-6 with daqp,
    2.5e-7 with quadprog, the residuals 1e-9 apart, the QR's level 0 the lower).

    Seed 11's ‖q̇‖ is held to 3e-6, not 1e-6: moving q by 1e-15 rad (random, 20 draws) moves the two paths' ‖q̇‖
    apart by up to 1.9e-6 relative on pin 4.1 and on pin 3.8 alike (8.5e-7 and 1.1e-6 unperturbed), while every
    level's residual stays within 1.3e-8: the level QPs' conditioning, not the QR, and not a Pinocchio version."""
    qp_tol = 3e-6 if seed == 11 else 1e-6
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(5, 9))
    robot = random_robot(rng, n, velocity=float(rng.uniform(0.3, 2.0)))
    q = robot.random_configuration(rng)
    j = int(rng.integers(n))
    name = robot.joint_names[j]
    limits = rk.JointLimits(lower={name: float(q[j])}, upper={name: float(q[j])})
    stack = _stack(robot, rng, depth=int(rng.integers(1, 5)), bound=bool(seed % 2))
    assert _compare(robot, stack, q, shortcut=False, certified_qr=False, limits=limits) == "qp"
    assert _compare(robot, stack, q, shortcut=False, qp_tol=qp_tol, limits=limits) == "qp"
    # (the cascade may settle every level itself)
    assert _compare(robot, stack, q, certified_qr=False, limits=limits) in ("qp", "closed")
    assert _compare(robot, stack, q, qp_tol=qp_tol, limits=limits) in ("qp", "closed")


def _complement_case(seed: int) -> tuple[rk.RobotModel, rk.TaskStack, np.ndarray, dict[str, object], bool]:
    """A random robot, stack and start for the complement mode's tests: pinned joints, rate windows, bound
    subtasks (often contradicted: a joint pushed past its bound) and the null-space objective; with or without the
    level shortcut."""
    rng = np.random.default_rng(300 + seed)
    n = int(rng.integers(5, 10))
    robot = random_robot(rng, n, velocity=float(rng.uniform(0.2, 0.8)))
    q = robot.random_configuration(rng)
    kw: dict[str, object] = {}
    if seed % 3 == 1:
        j = int(rng.integers(n))
        name = robot.joint_names[j]
        kw["limits"] = rk.JointLimits(lower={name: float(q[j])}, upper={name: float(q[j])})
    elif seed % 3 == 2:
        kw["limits"] = rk.JointLimits(acceleration=float(rng.uniform(2.0, 20.0)))
    stack = _stack(robot, rng, depth=int(rng.integers(1, 5)), bound=bool(seed % 2))
    return robot, stack, q, kw, bool(seed % 4 < 2)


@pytest.mark.parametrize("seed", range(24))
def test_lean_step_in_the_complement_mode_equals_the_general_path(seed: int) -> None:
    """The level QPs posed in joint space (the limits as bounds, the fixed directions as equalities: ``hqp_kernels.
    level_qp_joint_into``) have the optimum of the general path's, with every diagnostic. The regulariser is 1e-4
    here, so that the directions it alone decides are decided to the solver's accuracy (see the next test)."""
    robot, stack, q, kw, shortcut = _complement_case(seed)
    _compare(robot, stack, q, tol=1e-8, steps=3, shortcut=shortcut, complement=True, regularization=1e-4, **kw)


@pytest.mark.parametrize("seed", range(24))
def test_complement_mode_at_the_default_regularization_keeps_every_level_optimum(seed: int) -> None:
    """At the default regulariser (1e-9) the directions that no level's rows decide are set by ε‖q̇‖² alone, which
    daqp resolves to ~1e-7 in either form (~1e-5 beside a level contradicted by a slack of 50: the slack's ½‖w‖²
    outweighs ε‖q̇‖² by 1e12): there the two forms differ, neither nearer the minimum norm. What the levels decide
    is the same: the residual of every level and the slack of every contradicted one, to 1e-8, the QP count, and
    the norm of q̇ to 1e-6."""
    robot, stack, q, kw, shortcut = _complement_case(seed)
    lean, ref = HierarchicalQPResolver(**kw), _Reference(**kw)  # type: ignore[arg-type]
    lean.complement_min_n, lean.complement_fraction = 0, 0.0
    for res in (lean, ref):
        res.level_shortcut = shortcut
        prepared(res, robot, stack, q)
    for k in range(3):
        a = lean.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
        b = ref.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
        residuals = [key for key in b.info if key.startswith("residual_L")]
        for key in residuals:
            assert a.info[key] == pytest.approx(b.info[key], rel=1e-8, abs=1e-8), key
        contradicted_a = a.info.get("contradicted_levels", {})
        contradicted_b = b.info.get("contradicted_levels", {})
        assert isinstance(contradicted_a, dict) and isinstance(contradicted_b, dict)
        assert contradicted_a.keys() == contradicted_b.keys()
        for level, slack in contradicted_b.items():
            assert contradicted_a[level] == pytest.approx(slack, rel=1e-8), level
        assert (a.info["qp"], a.fallback is None) == (b.info["qp"], b.fallback is None)
        assert np.linalg.norm(a.dq) == pytest.approx(np.linalg.norm(b.dq), rel=1e-6)
        np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=1e-4)
        q = robot.integrate(q, b.dq, 0.01)


@pytest.mark.parametrize("theta", [0.0, 1e-9, 1e-6, 1e-4, 1e-3, 5e-3, 2e-2])
def test_lean_step_equals_the_general_path_near_the_straight_arm(theta: float) -> None:
    """The chapter's 3R arm stretched (θ2 = θ3 ≈ 0): σ_min → 0, damped directions, rank truncated at θ = 0."""
    robot = rk.from_dh([DHRow(str(i + 1), a=1.0) for i in range(3)], name="planar3r")
    q = np.array([0.3, theta, -theta])
    for sub in (
        [rk.GradientSubtask(rk.JointSine2("3"), gain=1.0)],
        [rk.TargetSubtask(rk.JointValue("2", 0.5), target=0.0, rate=2.0)],
        [],
    ):
        stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")], sub)
        _compare(robot, stack, q, limits=False)


def test_lean_diagnostics_are_computed_only_when_read(monkeypatch: pytest.MonkeyPatch) -> None:
    """No Level record and no SVD of a level on a step whose diagnostics are not read; exact values once read."""
    from redundik.resolvers.qp import terms

    built = []
    level = terms.StepRows._level
    monkeypatch.setattr(terms.StepRows, "_level", lambda self, k: built.append(k) or level(self, k))
    robot = random_robot(np.random.default_rng(5), 7)
    q = robot.random_configuration(np.random.default_rng(6))
    stack = _stack(robot, np.random.default_rng(7), depth=4, bound=False)
    res = HierarchicalQPResolver(limits=False)
    prepared(res, robot, stack, q)
    out = res.step(robot, stack, q, 0.0, 0.01)
    assert out.__dict__["pending"] is not None and not built and out.info["qp"] == 0
    J = robot.frame_jacobian(tip(robot))[:3]
    assert out.info["sigma_min_L0"] == pytest.approx(np.linalg.svd(J, compute_uv=False)[-1], rel=1e-10)
    assert built  # the Level records, built on the first read


def test_hqp_kernels_report_their_first_run_cost() -> None:
    from redundik.resolvers import hqp_kernels

    cost = hqp_kernels.first_run_cost()
    assert set(cost) == {"closed_cascade", "level_rows_ok", "level_qp_arrays", "clearance_into", "qp_cascade_run"}
    assert all(v >= 0.0 for v in cost.values())


def test_level_shortcut_is_the_exact_optimum_of_the_level_qp(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every least-squares level the constrained cascade settles without the backend (the top level included)
    gets the exact optimum of its level QP, argmin ½‖M u − rhs‖² + ½ε‖u‖² (an augmented least squares, no squared
    condition number), to 1e-12 — over random robots whose cascade a bound at level 1 or tight velocity limits
    send there. The reference cascade in Python is spied on; the compiled one (hqp's own) agrees with it at
    every step (to the backend's conditioning) when it factors every level by its SVD, as the reference does (its
    certified QR gives other null bases of the same spaces: :func:`test_certified_qr_levels_keep_the_svd_optima`)."""
    seen: list[tuple[bool, np.ndarray, np.ndarray, float, np.ndarray]] = []
    level_qp = _PythonCascade._level_qp

    def spy(self, lv, x, Z, r, box, fixed, diag, pinned, selection, shortcut=False):  # type: ignore[no-untyped-def]
        before = diag.qp
        u, lsq = level_qp(self, lv, x, Z, r, box, fixed, diag, pinned, selection, shortcut)
        if lsq is not None and lv.m and not lv.pure_null_objective and not lv.p:
            M, rhs = self._project(lv, x, Z)
            seen.append((diag.qp == before, M, rhs, max(self.regularization, lsq.damping**2), u))
        return u, lsq

    monkeypatch.setattr(_PythonCascade, "_level_qp", spy)
    for seed in range(24):
        rng = np.random.default_rng(300 + seed)
        n = int(rng.integers(5, 9))
        robot = random_robot(rng, n, velocity=float(rng.uniform(0.2, 0.6)) if seed % 3 == 0 else np.inf)
        q = robot.random_configuration(rng)
        stack = _stack(robot, rng, depth=int(rng.integers(1, 5)), bound=True)
        res, lean = _Reference(), HierarchicalQPResolver()
        lean.certified_qr = False
        prepared(res, robot, stack, q)
        prepared(lean, robot, stack, q)
        for k in range(6):
            out = res.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
            # to 1e-6: a level the backend solves on MᵀM + εI (ε = 1e-9) carries its condition number, and inputs
            # equal to rounding (numba's sums against NumPy's) give optima 2e-7 apart on seed 6's level 2
            got = lean.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
            np.testing.assert_allclose(got.dq, out.dq, rtol=0, atol=1e-6 * max(1.0, float(np.abs(out.dq).max())))
            assert (got.fallback is None) == (out.fallback is None)
            q = robot.integrate(q, out.dq, 0.01)
    settled = [(M, rhs, eps, u) for ok, M, rhs, eps, u in seen if ok]
    assert len(settled) >= 10, len(settled)  # (the backend's optima, with active rows, are not the ridge: skipped)
    for M, rhs, eps, u in settled:
        r = M.shape[1]
        exact = np.linalg.lstsq(np.vstack([M, np.sqrt(eps) * np.eye(r)]), np.concatenate([rhs, np.zeros(r)]))[0]
        scale = max(1.0, float(np.abs(exact).max()))
        np.testing.assert_allclose(u, exact, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("seed", range(8))
def test_certified_qr_factors_a_level_as_its_svd(seed: int) -> None:
    """``_certified_null`` on M (m, r), m ≤ r: when it certifies, N's first r − m columns are an orthonormal basis
    of null(M), the next m complete it to an orthogonal Q, R's singular values are M's, and ``_ridge_triangular``'s
    t gives Q₁t = argmin ‖Mu − rhs‖² + ε‖u‖² (the augmented least squares) to 1e-12; a level with σ_min < ε (what
    the SVD would damp) is refused."""
    rng = np.random.default_rng(seed)
    r = int(rng.integers(2, 12))
    m = int(rng.integers(1, r + 1))
    U, _ = np.linalg.qr(rng.standard_normal((m, m)))
    V, _ = np.linalg.qr(rng.standard_normal((r, r)))
    sigma = np.sort(10.0 ** rng.uniform(-1.5, 0.5, m))[::-1]
    M = U @ np.diag(sigma) @ V[:, :m].T
    N, rrow = np.full((r + 2, r + 2), np.nan), np.full(m * m + 3, np.nan)
    assert HK._certified_null(M, 1e-3, 1e-10, N, rrow)
    Q = N[:r, :r]
    np.testing.assert_allclose(Q.T @ Q, np.eye(r), rtol=0, atol=1e-13)
    np.testing.assert_allclose(M @ Q[:, : r - m], 0.0, rtol=0, atol=1e-13 * sigma[0])
    R = rrow[: m * m].reshape(m, m)
    np.testing.assert_allclose(np.linalg.svd(R, compute_uv=False), sigma, rtol=1e-12)
    rhs = rng.standard_normal(m)
    for eps in (0.0, 1e-9, 1e-3, 0.5):
        u = Q[:, r - m :] @ HK._ridge_triangular(rrow, m, rhs, eps)
        exact = np.linalg.lstsq(np.vstack([M, np.sqrt(eps) * np.eye(r)]), np.concatenate([rhs, np.zeros(r)]))[0]
        np.testing.assert_allclose(u, exact, rtol=0, atol=1e-12 * max(1.0, float(np.abs(exact).max())))
    # the complement mode's thin form: Q₁ᵀ in N's first m rows, an orthonormal basis of M's row space, the same R
    rows, rrow2 = np.full((m + 1, r + 2), np.nan), np.full(m * m + 3, np.nan)
    assert HK._certified_rows(M, 1e-3, 1e-10, rows, rrow2)
    Q1t = rows[:m, :r]
    np.testing.assert_allclose(Q1t @ Q1t.T, np.eye(m), rtol=0, atol=1e-13)
    np.testing.assert_allclose(M - M @ Q1t.T @ Q1t, 0.0, rtol=0, atol=1e-13 * sigma[0])
    np.testing.assert_allclose(rrow2[: m * m], rrow[: m * m], rtol=0, atol=1e-13 * sigma[0])
    np.testing.assert_allclose(np.abs(Q1t), np.abs(Q[:, r - m :].T), rtol=0, atol=1e-13)  # (the same reflections)
    weak = M.copy()
    weak -= sigma[-1] * np.outer(U[:, -1], V[:, m - 1]) * (1.0 - 1e-4 / sigma[-1])  # σ_min → 1e-4 < ε = 1e-3
    assert not HK._certified_null(weak, 1e-3, 1e-10, N, rrow)
    assert not HK._certified_rows(weak, 1e-3, 1e-10, rows, rrow2)


@pytest.mark.parametrize("complement", [False, True])
def test_certified_qr_levels_keep_the_svd_optima(monkeypatch: pytest.MonkeyPatch, complement: bool) -> None:
    """The constrained cascade with the certified QR against the same cascade with the SVD at every level, over
    random robots whose bound at level 1 or tight velocity limits send it there: the same optimum of every level
    (residuals, contradicted slacks, ‖q̇‖; q̇ to the level QPs' conditioning, :func:`_same_optima`), and the same
    σ_min per level in the diagnostics (from R's singular values, to 1e-10) — on steps where the QR did factor;
    in the basis mode and in the complement mode (joint-space level QPs, whatever the robot's size)."""
    factored = [0]
    diagnose = HierarchicalQPResolver._diagnose

    def spy(self, built, dq, diag):  # type: ignore[no-untyped-def]
        if built.qp_stats is not None:
            factored[0] += int(np.isnan(built.qp_stats[:, HK.QS_SIGMA]).sum())
        return diagnose(self, built, dq, diag)

    monkeypatch.setattr(HierarchicalQPResolver, "_diagnose", spy)
    steps = 0
    for seed in range(16):
        rng = np.random.default_rng(500 + seed)
        n = int(rng.integers(5, 9))
        robot = random_robot(rng, n, velocity=float(rng.uniform(0.2, 0.6)) if seed % 2 == 0 else np.inf)
        q = robot.random_configuration(rng)
        stack = _stack(robot, rng, depth=int(rng.integers(1, 5)), bound=True)
        qr, svd = HierarchicalQPResolver(), HierarchicalQPResolver()
        svd.certified_qr = False
        for res in (qr, svd):
            if complement:
                res.complement_min_n, res.complement_fraction = 0, 0.0
            prepared(res, robot, stack, q)
        for k in range(4):
            a = qr.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
            b = svd.step(robot, stack, q, 0.05 + 0.01 * k, 0.01)
            if b.info["qp"]:
                steps += 1
                _same_optima(a, b, 1e-6)
                sig = [key for key in b.info if key.startswith("sigma_min")]
                assert sig and set(sig) <= set(a.info)
                for key in sig:
                    assert a.info[key] == pytest.approx(b.info[key], rel=1e-10), key
            q = robot.integrate(q, b.dq, 0.01)
    assert steps >= 20 and factored[0] >= 20, (steps, factored[0])

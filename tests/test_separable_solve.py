"""``wqp``'s unconstrained optimum x = −P⁻¹q with P's separable coordinates in closed form and only the coupled
block factored (:func:`redundik.resolvers.kernels.spd_solve_into`): the separable test equals a slow reference, and
x, the success flag and every failure are those of the full factorisation (no timing here)."""

from __future__ import annotations

import numpy as np
import pytest

from redundik.resolvers import kernels


def reference_coupled(P: np.ndarray, lower: bool) -> list[int]:
    """The coordinates with P_ii ≯ 0 or a non-zero (NaN included) off the diagonal in their row or column (with
    ``lower``, only P_ij for j < i and P_ki for k > i)."""
    n = P.shape[0]
    nz = P != 0.0  # (NaN != 0 is True)
    np.fill_diagonal(nz, False)
    if lower:
        nz = np.tril(nz)
    linked = nz.any(axis=1) | nz.any(axis=0)
    return [i for i in range(n) if linked[i] or not P[i, i] > 0.0]


def reference_full(P: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, bool]:
    """The full Cholesky route, written out in the kernel's order of operations (slow): x = −P⁻¹q from the lower
    triangle of P, x zero when a pivot is not positive, ok false when x is not finite."""
    n = q.shape[0]
    L = np.zeros((n, n))
    with np.errstate(all="ignore"):
        for j in range(n):
            s = P[j, j]
            for k in range(j):
                s -= L[j, k] * L[j, k]
            if not s > 0.0:
                return np.zeros(n), False
            L[j, j] = np.sqrt(s)
            for i in range(j + 1, n):
                t = P[i, j]
                for k in range(j):
                    t -= L[i, k] * L[j, k]
                L[i, j] = t / L[j, j]
        y = np.empty(n)
        for i in range(n):
            t = -q[i]
            for k in range(i):
                t -= L[i, k] * y[k]
            y[i] = t / L[i, i]
        x = np.empty(n)
        for i in range(n - 1, -1, -1):
            t = y[i]
            for k in range(i + 1, n):
                t -= L[k, i] * x[k]
            x[i] = t / L[i, i]
    return x, bool(np.isfinite(x).all())


def structured(rng: np.random.Generator, n: int, nc: int, blocks: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """An SPD P whose nc coupled coordinates (in ``blocks`` independent groups) are scattered among n, and a q."""
    perm = rng.permutation(n)
    P = np.zeros((n, n))
    for group in np.array_split(perm[:nc], blocks):
        m = group.shape[0]
        B = rng.standard_normal((m + 2, m))
        P[np.ix_(group, group)] = B.T @ B + 1e-2 * np.eye(m)
    S = perm[nc:]
    P[S, S] = rng.uniform(0.05, 5.0, n - nc)
    return P, 3.0 * rng.standard_normal(n)


def coupled(P: np.ndarray, lower: bool) -> list[int]:
    idx = np.empty(P.shape[0], dtype=np.int64)
    nc = kernels.coupled_coordinates(P, idx, lower)
    return [int(i) for i in idx[:nc]]


@pytest.mark.parametrize("seed", range(3))
def test_the_separable_test_equals_the_reference(seed: int) -> None:
    """Random sparsity patterns (symmetric and not, NaN entries, zero/negative/NaN diagonals), both modes."""
    rng = np.random.default_rng(seed)
    for _ in range(200):
        n = int(rng.integers(1, 30))
        P = np.diag(rng.uniform(0.1, 2.0, n))
        for _ in range(int(rng.integers(0, 4))):
            i, j = rng.integers(n, size=2)
            P[i, j] = rng.choice([1.0, -1e-300, np.nan, np.inf, -0.0])
            if rng.random() < 0.5:
                P[j, i] = P[i, j]
        if rng.random() < 0.3:
            P[rng.integers(n), rng.integers(n)] = rng.choice([0.0, -1.0, np.nan])
        for lower in (True, False):
            assert coupled(P, lower) == reference_coupled(P, lower)


def test_the_separable_test_on_dense_and_diagonal_matrices() -> None:
    """A dense SPD P has no separable coordinate, a positive diagonal one no coupled coordinate."""
    rng = np.random.default_rng(5)
    A = rng.standard_normal((12, 12))
    assert coupled(A @ A.T + np.eye(12), True) == list(range(12))
    assert coupled(np.diag(rng.uniform(0.5, 1.0, 12)), False) == []


@pytest.mark.parametrize("seed", range(4))
def test_the_split_solve_is_the_full_factorisation_bit_for_bit(seed: int) -> None:
    """n ≤ 48 (the unblocked loops): x is the full factorisation's, bit for bit, over random structures — one or
    two coupled groups, no coupled coordinate, all coupled — and within κ(P)·1e-14 (relative) of LAPACK's solve."""
    rng = np.random.default_rng(10 + seed)
    for _ in range(60):
        n = int(rng.integers(2, 49))
        nc = int(rng.choice([0, n, int(rng.integers(1, n + 1))]))
        P, q = structured(rng, n, nc, blocks=int(rng.integers(1, 3)))
        x = np.empty(n)
        ok = kernels.spd_solve_into(P, q, x)
        ref, ref_ok = reference_full(P, q)
        assert ok and ref_ok
        np.testing.assert_array_equal(x, ref)
        exact = -np.linalg.solve(P, q)
        assert np.max(np.abs(x - exact)) <= 1e-14 * np.linalg.cond(P) * np.max(np.abs(exact))


@pytest.mark.parametrize(("n", "nc"), [(60, 30), (60, 55), (70, 70), (64, 0)])
def test_large_problems_match_lapack(n: int, nc: int) -> None:
    """Beyond 48 coordinates: the coupled block by the loops (n_c ≤ 48) or LAPACK, the whole of P by LAPACK."""
    rng = np.random.default_rng(n + nc)
    P, q = structured(rng, n, nc)
    x = np.empty(n)
    assert kernels.spd_solve_into(P, q, x)
    exact = -np.linalg.solve(P, q)
    np.testing.assert_allclose(x, exact, rtol=1e-10, atol=1e-12 * np.max(np.abs(exact)))


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal arrays, NaN equal to NaN."""
    return bool(np.array_equal(a, b, equal_nan=True))


@pytest.mark.parametrize(
    "defect",
    [
        "coupled not SPD",
        "separable pivot negative",
        "separable pivot zero",
        "nan q separable",
        "inf q separable",
        "nan q coupled",
        "nan P coupled",
        "inf P coupled diagonal",
        "inf P off-diagonal",
        "tiny separable pivot",
    ],
)
def test_failures_are_the_full_factorisations(defect: str) -> None:
    """Non-finite data or a P that is not SPD: the same flag and the same x (zeros when a pivot fails, the full
    route's non-finite x otherwise) as the full factorisation."""
    rng = np.random.default_rng(7)
    n, nc = 20, 9
    P, q = structured(rng, n, nc)
    C = reference_coupled(P, True)
    S = [i for i in range(n) if i not in C]
    if defect == "coupled not SPD":
        P[C[2], C[2]] = -50.0
    elif defect == "separable pivot negative":
        P[S[0], S[0]] = -1.0
    elif defect == "separable pivot zero":
        P[S[1], S[1]] = 0.0
    elif defect == "nan q separable":
        q[S[2]] = np.nan
    elif defect == "inf q separable":
        q[S[3]] = np.inf
    elif defect == "nan q coupled":
        q[C[0]] = np.nan
    elif defect == "nan P coupled":
        P[C[3], C[1]] = P[C[1], C[3]] = np.nan
    elif defect == "inf P coupled diagonal":
        P[C[4], C[4]] = np.inf
    elif defect == "inf P off-diagonal":
        P[S[0], C[0]] = P[C[0], S[0]] = np.inf
    else:
        P[S[4], S[4]] = 1e-310
        q[S[4]] = 1.0
    x = np.full(n, 123.0)
    with np.errstate(all="ignore"):
        ok = kernels.spd_solve_into(P, q, x)
    ref, ref_ok = reference_full(P, q)
    assert ok == ref_ok
    assert _same(x, ref) or (not ok and not np.isfinite(ref).all() and not np.isfinite(x).all())


def test_the_box_step_and_batch_use_the_same_solve() -> None:
    """``spd_solve_box`` and ``spd_solve_batch`` (the batch resolver's kernel) give the split solve's x and box
    flags on a Talos-like P (16 of 38 coordinates separable)."""
    rng = np.random.default_rng(11)
    Ps, qs = zip(*(structured(rng, 38, 22) for _ in range(5)), strict=True)
    P, q = np.array(Ps), np.array(qs)
    lb, ub = np.full((5, 38), -2.0), np.full((5, 38), 2.0)
    x, ok, inside = kernels.spd_solve_batch(P, q, lb, ub, 1e-12)
    for k in range(5):
        ref, ref_ok = reference_full(P[k], q[k])
        np.testing.assert_array_equal(x[k], ref)
        assert ok[k] == ref_ok and inside[k] == bool(((ref >= -2.0 - 1e-12) & (ref <= 2.0 + 1e-12)).all())
        xs, oks, ins = kernels.spd_solve_box(P[k], q[k], lb[k], ub[k], 1e-12)
        np.testing.assert_array_equal(xs, ref)
        assert (oks, ins) == (ok[k], inside[k])


def test_daqps_split_uses_the_same_test_on_both_triangles() -> None:
    """The backend's split is the kernels' one implementation; it reads both triangles, so a coordinate whose only
    off-diagonal entry is above the diagonal is coupled there (and separable for the Cholesky, which reads only the
    lower triangle)."""
    from redundik.resolvers.qp.backends import split_kernel

    assert split_kernel() is kernels.split_separable
    P = np.diag(np.arange(1.0, 31.0))
    P[3, 7] = 0.5  # (upper triangle only)
    P[10, 12] = P[12, 10] = 0.25
    q, lb, ub = np.ones(30), -np.ones(30), np.ones(30)
    work, idx = np.empty((34, 30)), np.empty(30, dtype=np.int64)
    nc, _ = kernels.split_separable(P, q, lb, ub, 0, work, idx)
    assert nc == 4 and list(idx[:4]) == [3, 7, 10, 12]
    assert coupled(P, True) == [10, 12]


def test_talos_wqp_steps_solve_as_the_full_factorisation() -> None:
    """The benchmark's Talos ``wqp`` QPs (two gripper tasks, posture, limits): 16 of 38 coordinates separable, and
    x on each step the full factorisation's, bit for bit."""
    bench = pytest.importorskip("benchmarks.bench.scenarios")
    from redundik.resolvers.registry import make_resolver

    sc = bench.SCENARIOS["talos"]()
    robot = sc.robot()
    stack = sc.stack("wqp", robot)
    res = make_resolver("wqp")
    res.fuse = False  # (the per-task path keeps its P and q, shifted, in res._P and res._q)
    q = sc.q0.copy()
    robot.update(q)
    stack.reset(robot)
    res.reset()
    res.check(robot, stack)
    for k in range(30):
        out = res.step(robot, stack, q, k * sc.dt, sc.dt)
        q = robot.integrate(q, out.dq, sc.dt)
        if k % 5:
            continue
        P, qv = res._P.copy(), res._q.copy()
        assert len(coupled(P, True)) == 22
        x = np.empty(38)
        assert kernels.spd_solve_into(P, qv, x)
        np.testing.assert_array_equal(x, reference_full(P, qv)[0])

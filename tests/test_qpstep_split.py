"""daqp's bounds-only QPs split into separable variables (closed form) and the coupled rest (daqp): the same answers,
iteration counts and failures as the whole problem solved by daqp, and the same ``wqp`` steps on Talos."""

from __future__ import annotations

import numpy as np
import pytest

from redundik.errors import SolverError
from redundik.resolvers.qp.backends import SPLIT_MIN_SAVING, DaqpBackend, finite, split_kernel
from redundik.resolvers.qp.problem import QPProblem

pytest.importorskip("daqp")

split_separable = split_kernel()  # the compiled kernel


def whole() -> DaqpBackend:
    """daqp on the whole problem (the split never made)."""
    be = DaqpBackend()
    be._split_min_n = 10**9
    return be


def boxed(P: np.ndarray, q: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> QPProblem:
    n = q.shape[0]
    return QPProblem(P, q, np.zeros((0, n)), np.zeros(0), np.zeros((0, n)), np.zeros(0), lb, ub, "box")


def separable_problem(rng: np.random.Generator, n: int, nc: int) -> QPProblem:
    """A bounds-only QP whose nc coupled variables are scattered among n, many bounds binding."""
    perm = rng.permutation(n)
    C, S = perm[:nc], perm[nc:]
    P = np.zeros((n, n))
    B = rng.standard_normal((nc + 2, nc))
    P[np.ix_(C, C)] = B.T @ B + 1e-3 * np.eye(nc)
    P[S, S] = rng.uniform(0.1, 3.0, n - nc)
    lb, ub = -rng.uniform(0.05, 1.5, n), rng.uniform(0.05, 1.5, n)
    lb[rng.integers(n)] = -np.inf
    return boxed(P, 2.0 * rng.standard_normal(n), lb, ub)


def work(n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.empty((4 + n, n)), np.empty(n, dtype=np.int64)


@pytest.mark.parametrize("seed", range(4))
def test_the_split_gives_the_whole_problems_answer_and_iterations(seed: int) -> None:
    """Over random problems (22 … 44 variables, 3 … n − 3 coupled, separable bounds often binding): x to 1e-12 and
    the same iteration count as daqp on the whole problem (one per separable variable clipped, plus daqp's own on
    the coupled ones)."""
    rng = np.random.default_rng(seed)
    split, plain = DaqpBackend(), whole()
    made = clipped_any = 0
    for _ in range(150):
        n = int(rng.integers(22, 45))
        prob = separable_problem(rng, n, int(rng.integers(3, n - 2)))
        nc, clipped = split_separable(prob.P, prob.q, prob.lb, prob.ub, SPLIT_MIN_SAVING, *work(n))
        made += nc > 0
        clipped_any += clipped > 0
        a, b = split.solve(prob), plain.solve(prob)
        np.testing.assert_allclose(a.x, b.x, rtol=0.0, atol=1e-12)
        assert a.iterations == b.iterations
        assert a.backend == b.backend == "daqp"
    assert made > 100 and clipped_any > 50  # the split was exercised, with separable bounds binding


def test_the_kernel_declines_what_it_must_not_split() -> None:
    """No split (n_c = −1) without a separable variable, with only separable ones (a diagonal P), below the saving,
    or when a separable variable's data is NaN/infinite or its interval empty (daqp then reports it)."""
    rng = np.random.default_rng(1)
    prob = separable_problem(rng, 30, 10)
    P, q, lb, ub = prob.P, prob.q, prob.lb, prob.ub
    assert split_separable(P, q, lb, ub, SPLIT_MIN_SAVING, *work(30))[0] == 10
    dense = rng.standard_normal((30, 30))
    assert split_separable(dense @ dense.T + np.eye(30), q, lb, ub, 0, *work(30))[0] == -1
    assert split_separable(np.diag(np.diag(P) + 1.0), q, lb, ub, 0, *work(30))[0] == -1
    assert split_separable(P, q, lb, ub, 30**3, *work(30))[0] == -1
    s = int(np.flatnonzero((P != 0).sum(axis=1) == 1)[0])  # a separable variable
    for key, value in (("q", np.nan), ("q", np.inf), ("lb", np.nan), ("lb", 2.0)):
        arrays = {"q": q.copy(), "lb": lb.copy()}
        arrays[key][s] = value
        if key == "lb" and value == 2.0:
            ub2 = ub.copy()
            ub2[s] = 1.0
            assert split_separable(P, arrays["q"], arrays["lb"], ub2, 0, *work(30))[0] == -1
        else:
            assert split_separable(P, arrays["q"], arrays["lb"], ub, 0, *work(30))[0] == -1


@pytest.mark.parametrize("defect", ["empty interval", "nan cost", "infeasible coupled"])
def test_failures_are_the_whole_problems(defect: str) -> None:
    """A QP that the split declines or whose coupled part daqp does not solve goes to the whole problem's solve:
    the same SolverError (message and all) as without the split."""
    rng = np.random.default_rng(3)
    prob = separable_problem(rng, 32, 12)
    coupled = np.flatnonzero((prob.P != 0).sum(axis=1) > 1)
    sep = np.flatnonzero((prob.P != 0).sum(axis=1) == 1)
    lb, ub, q = prob.lb.copy(), prob.ub.copy(), prob.q.copy()
    if defect == "empty interval":
        lb[sep[0]], ub[sep[0]] = 1.0, 0.5
    elif defect == "nan cost":
        q[sep[1]] = np.nan
    else:
        lb[coupled[0]], ub[coupled[0]] = 1.0, 0.5
    bad = boxed(prob.P, q, lb, ub)
    messages = []
    for be in (DaqpBackend(), whole()):
        try:
            sol = be.solve(bad)
            messages.append(("solved", bool(finite(sol.x))))
        except SolverError as exc:
            messages.append(("raised", str(exc)))
    assert messages[0] == messages[1]


def test_finite_is_the_element_wise_test() -> None:
    """``finite``'s dot-product shortcut decides only when xᵀx is finite; overflowing squares fall back."""
    cases = [np.zeros(0), np.ones(5), np.array([1.0, np.nan]), np.array([np.inf, 1.0]), np.array([-np.inf, np.inf])]
    cases += [np.full(4, 1e200), np.array([1e300, -1e300, np.nan]), np.ones((2, 3)), np.array([[1.0, np.inf]])]
    with np.errstate(over="ignore"):  # (the squares of 1e200 overflow)
        for x in cases:
            assert finite(x) == bool(np.isfinite(x).all())
    with np.errstate(over="raise"):
        assert finite(np.full(3, 1e200)) and not finite(np.array([1e200, np.nan]))


def test_daqp_reads_strided_bounds_as_their_values() -> None:
    """Bounds given as strided views (every other entry of a longer array) are copied before daqp reads them from
    their first element on: the answer is the contiguous problem's."""
    rng = np.random.default_rng(4)
    n = 6
    M = rng.normal(size=(n, n))
    P, q = M @ M.T + np.eye(n), 10.0 * rng.normal(size=n)
    lb2, ub2 = np.repeat(-0.1 * np.arange(1, n + 1), 2), np.repeat(0.1 * np.arange(1, n + 1), 2)
    strided = boxed(P, q, lb2[::2], ub2[::2])
    assert not strided.lb.flags.c_contiguous
    contiguous = boxed(P, q, lb2[::2].copy(), ub2[::2].copy())
    np.testing.assert_allclose(DaqpBackend().solve(strided).x, DaqpBackend().solve(contiguous).x, atol=1e-14)


def test_talos_wqp_steps_are_those_of_the_whole_problem() -> None:
    """The benchmark's Talos ``wqp`` case (two gripper pose tasks, posture, limits: 16 of its 38 variables
    separable), stepped with and without the split: the same q̇ to 1e-10 and the same diagnostics and fallbacks,
    with the backend called on a good share of the steps."""
    bench = pytest.importorskip("benchmarks.bench.scenarios")
    from redundik.resolvers.registry import make_resolver

    sc = bench.SCENARIOS["talos"]()
    runs = []
    for backend in (DaqpBackend(), whole()):
        robot = sc.robot()
        stack = sc.stack("wqp", robot)
        res = make_resolver("wqp", backend=backend)
        q = sc.q0.copy()
        robot.update(q)
        stack.reset(robot)
        res.reset()
        res.check(robot, stack)
        steps = []
        for k in range(250):
            out = res.step(robot, stack, q, k * sc.dt, sc.dt)
            info = dict(out.info)
            steps.append((out.dq.copy(), info, out.fallback, out.sigma_min))
            q = robot.integrate(q, out.dq, sc.dt)
        runs.append(steps)
    qp = 0
    for (dq_a, info_a, fb_a, s_a), (dq_b, info_b, fb_b, s_b) in zip(*runs, strict=True):
        np.testing.assert_allclose(dq_a, dq_b, rtol=0.0, atol=1e-10)
        assert fb_a == fb_b
        assert s_a == pytest.approx(s_b, rel=1e-9)
        assert info_a.keys() == info_b.keys()
        for key in info_a:
            if isinstance(info_a[key], float):
                assert info_a[key] == pytest.approx(info_b[key], rel=1e-8, abs=1e-12), key
            else:
                assert info_a[key] == info_b[key], key
        qp += int(info_a["qp"])
    assert qp > 40


def test_the_template_still_checks_a_subclass_of_the_daqp_backend() -> None:
    """Only the daqp backend itself is trusted to have checked its answer: a subclass that returns NaN (or the wrong
    size) is caught by the template as any user backend is."""
    from redundik.resolvers.qp.problem import QPSolution
    from redundik.resolvers.qp.wqp import WeightedQPResolver

    class Broken(DaqpBackend):
        def __init__(self, x: np.ndarray) -> None:
            super().__init__()
            self.x = x

        def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
            return QPSolution(self.x, 1, "daqp")

    prob = separable_problem(np.random.default_rng(6), 24, 8)
    for x in (np.full(24, np.nan), np.zeros(23)):
        with pytest.raises(SolverError, match="no finite solution of size 24"):
            WeightedQPResolver(backend=Broken(x))._solve_qp(prob)
    assert WeightedQPResolver()._solve_qp(prob).x.shape == (24,)


def test_the_split_of_read_only_and_strided_data_is_the_whole_problems() -> None:
    """A batch's problems come in read-only rows of broadcast arrays, others in strided views: the split copies them
    as daqp would need them and gives the whole problem's answer and iterations."""
    rng = np.random.default_rng(7)
    prob = separable_problem(rng, 30, 9)
    P = prob.P.copy()
    P.setflags(write=False)
    lb2, ub2 = np.repeat(prob.lb, 2), np.repeat(prob.ub, 2)
    odd = QPProblem(P, prob.q, prob.G, prob.h, prob.A, prob.b, lb2[::2], ub2[::2], "views")
    a, b = DaqpBackend().solve(odd), whole().solve(prob)
    np.testing.assert_allclose(a.x, b.x, rtol=0.0, atol=1e-12)
    assert a.iterations == b.iterations

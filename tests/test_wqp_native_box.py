"""``wqp``'s box QP through daqp's C entry point (:mod:`redundik.resolvers.qp.wqp_native`) is the template's answer:
on steps where a joint limit binds, a resolver with the native call and one without it (``daqp_native.enabled``
off: the backend's Python wrapper, through the template) give the same q̇, bit for bit, the same kept q̇ (the next
step's rate window), info, diagnostics, relaxations and fallbacks — fused or per-task, with and without a rate
window — and the lane is taken on those steps (counted), never with another backend."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import redundik as rk
from redundik.resolvers.qp import daqp_native, wqp
from redundik.resolvers.registry import make_resolver

Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
DT = 0.01


def _stack() -> rk.TaskStack:
    """The hand on a fast 20 cm circle: the velocity limits bind on many steps; a posture below it."""
    hand = rk.FrameTask("panda_hand_tcp", rk.Circle(0.2, 6.0, plane=("x", "z")), gain=30.0)
    return rk.TaskStack([hand, rk.PostureTask(gain=1.0)])


def _count_native_steps(native: bool, monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Switch daqp's native call on or off and count the steps the native box QP answers (a one-entry list)."""
    monkeypatch.setattr(daqp_native, "enabled", native)
    taken = [0]
    original = wqp.native_box_step

    def counting(*args: object, **kwargs: object) -> object:
        res = original(*args, **kwargs)  # type: ignore[arg-type]
        taken[0] += res is not None
        return res

    monkeypatch.setattr(wqp, "native_box_step", counting)
    return taken


def _run(native: bool, fuse: bool, limits: dict[str, float], backend: str, monkeypatch: pytest.MonkeyPatch,
         steps: int = 120) -> tuple[list[tuple[object, ...]], int]:  # fmt: skip
    taken = _count_native_steps(native, monkeypatch)
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    stack = _stack()
    stack.reset(robot)
    res = make_resolver("wqp", backend=backend, limits=limits)
    res.fuse = fuse  # type: ignore[attr-defined]
    q, out = Q0.copy(), []
    for k in range(steps):
        step = res.step(robot, stack, q, k * DT, DT)
        info = dict(step.info)
        out.append((step.dq.copy(), res._dq_prev.copy(), info, step.relaxed, step.fallback, step.sigma_min,
                    step.damped, [t.v.copy() for t in step.terms]))  # fmt: skip
        q = robot.integrate(q, step.dq, DT)
    return out, taken[0]


@pytest.mark.parametrize("fuse", [True, False])
@pytest.mark.parametrize("limits", [{}, {"acceleration": 40.0}], ids=["box", "rate_window"])
def test_the_native_box_qp_is_the_templates_answer(fuse: bool, limits: dict[str, float],
                                                    monkeypatch: pytest.MonkeyPatch) -> None:  # fmt: skip
    if not daqp_native.entry():
        pytest.skip(f"daqp's native call is off here: {daqp_native.status()}")  # (CI installs daqp 0.11.0)
    native, taken = _run(True, fuse, limits, "daqp", monkeypatch)
    template, taken_off = _run(False, fuse, limits, "daqp", monkeypatch)
    qp_steps = sum(1 for step in native if step[2]["qp"])
    assert qp_steps >= 20, f"a limit bound on {qp_steps} of 120 steps only"  # (the test could fail)
    assert taken == qp_steps and taken_off == 0
    for k, (a, b) in enumerate(zip(native, template, strict=True)):
        np.testing.assert_array_equal(a[0], b[0], err_msg=f"q̇, step {k}")
        np.testing.assert_array_equal(a[1], b[1], err_msg=f"kept q̇, step {k}")
        assert a[2] == b[2], f"info, step {k}"
        assert a[3:7] == b[3:7], f"relaxed, fallback, σ_min, damped, step {k}"
        for va, vb in zip(a[7], b[7], strict=True):
            np.testing.assert_array_equal(va, vb)


def test_another_backend_never_takes_the_native_box(monkeypatch: pytest.MonkeyPatch) -> None:
    out, taken = _run(True, True, {}, "quadprog", monkeypatch, steps=60)
    assert taken == 0 and any(step[2]["qp"] for step in out)
    assert {step[2]["backend"] for step in out if step[2]["qp"]} == {"quadprog"}


def test_warm_up_compiles_the_native_box_kernel(tmp_path: Path) -> None:
    """On an empty kernel cache, after ``warm_up(["wqp"])`` (what the cold start's background thread runs), fast
    steps whose limits bind take the native box QP — and the 40-joint snake's steps whose clearance rows bind, its
    lifted QP with rows — without compiling anything in the caller's thread (numba's
    compile events, by thread): its kernel, and the joint-speed cap's test, are among those the warm-up compiles
    (the cap's compiled at the loop's first fast step before), not a stall in a control loop."""
    import json
    import os
    import subprocess
    import sys
    import textwrap

    from redundik import _kernel_cache as kc
    from tests.compile_events import LISTENER

    code = textwrap.dedent(
        """
        import json
        import numpy as np
        import redundik as rk
        from redundik.resolvers.qp import wqp
        from redundik.warmup import warm_up

        warm_up(["wqp"], ik=False)
        taken = [0]
        original = wqp.native_box_step

        def counting(*args):
            res = original(*args)
            taken[0] += res is not None
            return res

        wqp.native_box_step = counting
        exec(LISTENER)  # found: the kernels numba compiles in this (the caller's) thread from now on
        robot = rk.load_example_robot("panda")
        q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
        robot.update(q)
        hand = rk.FrameTask("panda_hand_tcp", rk.Circle(0.2, 6.0, plane=("x", "z")), gain=30.0)
        stack = rk.TaskStack([hand, rk.PostureTask(gain=1.0)])
        stack.reset(robot)
        res, qp = rk.make_resolver("wqp"), 0
        for k in range(60):
            step = res.step(robot, stack, q, 0.01 * k, 0.01)
            qp += step.info["qp"]
            q = robot.integrate(q, step.dq, 0.01)
        panda = {"found": sorted(set(found)), "taken": taken[0], "qp": qp}
        # the 40-joint snake with three clearance bounds: their compiled rows, the lifted QP with rows
        from benchmarks.bench.scenarios import snake_scenario

        found.clear()
        taken[0] = qp = 0
        sc = snake_scenario(40)
        robot, q = sc.robot(), sc.q0.copy()
        robot.update(q)
        stack = sc.stacks["wqp"](robot)
        stack.reset(robot)
        res = rk.make_resolver("wqp")
        for k in range(150):
            step = res.step(robot, stack, q, k * sc.dt, sc.dt)
            qp += step.info["qp"]
            q = robot.integrate(q, step.dq, sc.dt)
        snake = {"found": sorted(set(found)), "taken": taken[0], "qp": qp}
        print(json.dumps({"panda": panda, "snake": snake}))
        """
    )
    root = str(kc.PACKAGE_ROOT.parents[1])  # (the checkout: the benchmark's snake)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(kc.PACKAGE_ROOT.parent), root]),
           "REDUNDIK_COLD_START": "wait", "REDUNDIK_CACHE_DIR": str(tmp_path)}  # fmt: skip
    probe = f"LISTENER = {LISTENER!r}\n" + code
    out = subprocess.run(
        [sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=900, check=False
    )
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    for case in ("panda", "snake"):
        assert got[case]["qp"] >= 10 and got[case]["taken"] == got[case]["qp"], got
        assert got[case]["found"] == [], got


def _talos_run(native: bool, monkeypatch: pytest.MonkeyPatch, steps: int = 150) -> tuple[list[tuple[object, ...]], int]:
    from benchmarks.bench.runners import RedundikRunner
    from benchmarks.bench.scenarios import SCENARIOS

    taken = _count_native_steps(native, monkeypatch)
    runner = RedundikRunner(SCENARIOS["talos"](), "wqp", None, {})
    dt, out = runner.scenario.dt, []
    for k in range(steps):
        step = runner.resolver.step(runner.robot, runner.stack, runner.q, k * dt, dt)
        out.append((step.dq.copy(), dict(step.info), step.relaxed, step.fallback, step.sigma_min))
        runner.q = runner.robot.integrate(runner.q, step.dq, dt)
    return out, taken[0]


def test_the_split_native_box_qp_is_the_templates_answer(monkeypatch: pytest.MonkeyPatch) -> None:
    """Talos (nv = 38, above daqp's split size 22): the separable variables in closed form and daqp on the coupled
    ones, as ``DaqpBackend`` splits the QP — the same q̇, info and diagnostics as through the template."""
    if not daqp_native.entry():
        pytest.skip(f"daqp's native call is off here: {daqp_native.status()}")
    native, taken = _talos_run(True, monkeypatch)
    template, taken_off = _talos_run(False, monkeypatch)
    qp_steps = sum(1 for step in native if step[1]["qp"])
    assert qp_steps >= 20 and taken == qp_steps and taken_off == 0, (qp_steps, taken)
    for k, (a, b) in enumerate(zip(native, template, strict=True)):
        np.testing.assert_array_equal(a[0], b[0], err_msg=f"q̇, step {k}")
        assert a[1:] == b[1:], f"info, relaxed, fallback, σ_min, step {k}"


@pytest.mark.parametrize("n", [5, 9, 24, 38])
def test_the_native_box_kernels_are_daqp_backends_solve(n: int) -> None:
    """On random box QPs — a coupled block and separable variables, some of them clipped onto a bound, some bounds
    binding on the coupled ones — the native kernels (whole below the split size, split from it on) give
    ``DaqpBackend.solve``'s x clipped to the box and its iteration count, bit for bit (whenever daqp solves at
    once); the split's clipped variables are counted as the backend counts them."""
    from redundik.resolvers.layouts import OUT_DQ, OUT_KEPT, OUT_LB, OUT_ROWS, OUT_UB
    from redundik.resolvers.qp.daqp_backend import SPLIT_MIN_SAVING, DaqpBackend
    from redundik.resolvers.qp.daqp_native import HK, NativeDaqp
    from redundik.resolvers.qp.problem import QPProblem

    if not daqp_native.entry():
        pytest.skip(f"daqp's native call is off here: {daqp_native.status()}")
    backend = DaqpBackend()
    native = NativeDaqp.for_backend(backend, n, 0, None)
    assert native is not None
    qbuf, work, idx = np.empty(n * n + 3 * n), np.empty((4 + n, n)), np.empty(n, dtype=np.int64)
    rng = np.random.default_rng(n)
    clipped_seen = 0
    for trial in range(40):
        nc = max(2, n // 2)
        F = rng.normal(size=(nc + 2, nc))
        P = np.diag(rng.uniform(0.5, 2.0, n))
        coupled = rng.permutation(n)[:nc]
        P[np.ix_(coupled, coupled)] += F.T @ F
        q = rng.normal(scale=3.0, size=n)
        lb, ub = -rng.uniform(0.1, 1.0, n), rng.uniform(0.1, 1.0, n)
        x_sep = -q / np.diag(P)
        clipped_seen += int(np.sum(((x_sep < lb) | (x_sep > ub))[np.setdiff1d(np.arange(n), coupled)]))
        out = np.zeros((OUT_ROWS, n))
        out[OUT_LB], out[OUT_UB] = lb, ub
        if n < backend._split_min_n:
            flag, iterations = HK.box_qp_native_into(native.ctl, native.x, qbuf, P, q, out)
        else:
            flag, iterations, parts = HK.box_qp_native_split_into(
                native.ctl, native.x, qbuf, P, q, out, SPLIT_MIN_SAVING, work, idx
            )
            assert parts == nc, "the split finds the coupled block"
        empty = np.zeros((0, n))
        sol = backend.solve(QPProblem(P.copy(), q.copy(), empty, np.zeros(0), empty, np.zeros(0), lb, ub))
        assert flag in (1, 2), f"trial {trial}: daqp's exit flag {flag}"
        np.testing.assert_array_equal(out[OUT_DQ], np.clip(sol.x, lb, ub), err_msg=f"trial {trial}")
        np.testing.assert_array_equal(out[OUT_KEPT], out[OUT_DQ])
        assert iterations == sol.iterations, f"trial {trial}"
    if n >= 22:
        assert clipped_seen > 20  # (the split's clipped count was exercised)

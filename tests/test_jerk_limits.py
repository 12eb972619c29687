"""Jerk limits (issue 33, item 2): the jerk window on the last two q̇, the braking-viability bound, the relaxation
order reported in ``result.relaxed``, the YAML key, and random target jumps on the Panda and TALOS under ``wqp`` and
``hqp`` with 0 violations."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

import redundik as rk
from redundik.errors import RedundikError, ResolverError
from redundik.resolvers.qp import DEFAULT_BACKEND
from redundik.resolvers.qp.limits import ACCELERATION_RELAXED, JERK_RELAXED, JointLimits
from tests.test_qp_helpers import case2_robot, case2_stack, prepared

ROOT = Path(__file__).resolve().parents[1]


def _stress_module():
    spec = importlib.util.spec_from_file_location("jerk_stress", ROOT / "benchmarks" / "jerk_stress.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["jerk_stress"] = module
    spec.loader.exec_module(module)
    return module


# ---------------------------------------------------------------------------------------------- the box
def test_from_rest_the_first_step_is_one_jerk_step() -> None:
    robot = case2_robot(lower=-1.0, upper=1.0, velocity=2.0)
    lim = JointLimits(acceleration=10.0, jerk=200.0)
    box = lim.box(robot, np.zeros(3), 0.01)
    np.testing.assert_allclose(box.ub, 200.0 * 0.01**2)  # q̇ ≤ j_max·dt² from rest
    np.testing.assert_allclose(box.lb, -200.0 * 0.01**2)
    assert box.relaxed == ()
    assert box.active(box.ub, lim.joint_names) == ["1:upper_jerk", "2:upper_jerk", "3:upper_jerk"]


def test_the_window_follows_the_last_acceleration() -> None:
    robot = case2_robot(lower=-10.0, upper=10.0, velocity=5.0)
    lim = JointLimits(acceleration=10.0, jerk=100.0)
    dt = 0.01
    v2, v1 = np.full(3, 0.2), np.full(3, 0.25)  # q̈ = 5 rad/s²; one step may change it by ±1 rad/s²
    box = lim.box(robot, np.zeros(3), dt, v1, v2)
    np.testing.assert_allclose(box.lb, 0.25 + 0.04, rtol=1e-12)  # q̇₁ + d₁ − j_max·dt²
    np.testing.assert_allclose(box.ub, 0.25 + 0.06, rtol=1e-12)


def _walk(lim: JointLimits, robot: rk.RobotModel, dt: float, steps: int, seed: int) -> tuple[np.ndarray, int, int]:
    """A random walk through the boxes (q̇ drawn anywhere, pushed to the bounds half the time): the q̇ history
    (from rest), the steps with a relaxation, and the position breaches."""
    rng = np.random.default_rng(seed)
    lo, hi = lim.lower_position, lim.upper_position
    q, v1, v2 = np.zeros(3), np.zeros(3), np.zeros(3)
    hist, relaxed, out = [np.zeros(3), np.zeros(3)], 0, 0
    for k in range(steps):
        box = lim.box(robot, q, dt, v1, v2)
        assert np.all(box.lb <= box.ub)
        relaxed += bool(box.relaxed)
        v = box.clip(rng.choice([-50.0, 50.0], 3) if (k // 30) % 2 else rng.uniform(-50.0, 50.0, 3))
        q = q + v * dt
        out += bool(np.any((q < lo - 1e-12) | (q > hi + 1e-12)))
        v2, v1 = v1, v
        hist.append(v)
    return np.array(hist), relaxed, out


@pytest.mark.parametrize(("amax", "jmax", "dt"), [(5.0, 50.0, 0.01), (20.0, 100.0, 0.002), (10.0, 1e5, 0.01)])
def test_a_random_walk_through_the_boxes_never_needs_a_relaxation(amax: float, jmax: float, dt: float) -> None:
    """Whatever the QP picks inside the box, the next box is not empty (recursive feasibility) and q̈, jerk,
    q̇ and q stay within their limits."""
    robot = case2_robot(lower=-0.5, upper=0.5, velocity=1.0)
    lim = JointLimits(acceleration=amax, jerk=jmax)
    lim.bind(robot)
    hist, relaxed, out = _walk(lim, robot, dt, 3000, seed=int(jmax))
    acc = np.diff(hist, axis=0) / dt
    jerk = np.diff(acc, axis=0) / dt
    assert relaxed == 0 and out == 0
    assert np.max(np.abs(hist)) <= 1.0
    assert np.max(np.abs(acc)) <= amax * (1 + 1e-9)
    assert np.max(np.abs(jerk)) <= jmax * (1 + 1e-9)
    assert np.max(np.abs(jerk)) >= 0.99 * min(jmax, 2 * amax / dt)  # the jerk bound is reached: it binds


def test_the_viability_bound_is_tight() -> None:
    """Near the upper limit the box's upper end is the fastest q̇ that can still stop: a little more breaks the
    limit under the hardest braking (checked by a roll-out written here), the end itself does not."""
    robot = case2_robot(lower=-0.5, upper=0.5, velocity=1.0)
    amax, jmax, dt = 5.0, 50.0, 0.01
    lim = JointLimits(acceleration=amax, jerk=jmax)
    lim.bind(robot)
    alpha, beta = amax * dt, jmax * dt * dt

    def peak(q: float, v: float, d: float) -> float:
        x = q
        while v > 0 or d > 0:
            x += v * dt
            d = max(d - beta, -alpha)
            v += d
        return x

    q = np.array([0.45, 0.0, 0.0])
    v1 = v2 = np.array([0.5, 0.0, 0.0])  # 0.5 rad/s, 5 cm before the limit
    box = lim.box(robot, q, dt, v1, v2)
    ub = float(box.ub[0])
    assert box.relaxed == () and ub < 0.5 + beta  # the braking bound cuts the window
    assert peak(q[0], ub, ub - v1[0]) <= 0.5 + 1e-12
    assert peak(q[0], ub + 1e-6, ub + 1e-6 - v1[0]) > 0.5
    assert box.active(np.array([ub, 0.0, 0.0]), lim.joint_names) == ["1:upper_position"]


# ---------------------------------------------------------------------------------------------- relaxation order
def test_a_start_outside_a_limit_relaxes_the_jerk_first() -> None:
    robot = case2_robot(lower=-0.5, upper=0.5, velocity=1.0)
    lim = JointLimits(acceleration=5.0, jerk=50.0)
    box = lim.box(robot, np.array([0.5003, 0.0, 0.0]), 0.01)  # 0.3 mrad out: back in one step needs −0.03 rad/s
    assert box.relaxed == (JERK_RELAXED,)
    # the acceleration-limited box is [−0.05, −0.03]; its point closest to the jerk window [−0.005, 0.005]
    assert box.lb[0] == box.ub[0] == pytest.approx(-0.03)
    np.testing.assert_allclose(box.ub[1:], 50.0 * 1e-4)  # the other joints keep their jerk window
    box = lim.box(robot, np.array([0.6, 0.0, 0.0]), 0.01)  # 0.1 rad out: back at the velocity limit (hard)
    assert box.relaxed == (JERK_RELAXED, ACCELERATION_RELAXED)
    assert box.lb[0] == box.ub[0] == -1.0


def test_an_acceleration_beyond_the_limit_relaxes_the_jerk_then_the_acceleration() -> None:
    robot = case2_robot(lower=-10.0, upper=10.0, velocity=1.0)
    lim = JointLimits(acceleration=5.0, jerk=50.0)
    dt = 0.01
    # joint 1: last q̈ = 100 rad/s² (beyond a_max: the jerk window misses the acceleration window)
    box = lim.box(robot, np.zeros(3), dt, np.array([0.5, 0, 0]), np.array([-0.5, 0, 0]))
    assert box.relaxed == (JERK_RELAXED,)
    assert 0.5 - 5.0 * dt - 1e-15 <= box.lb[0] <= box.ub[0] <= 0.5 + 5.0 * dt + 1e-15
    # joint 1 at 3 rad/s with v_max = 1 (a limit tightened mid-run): no acceleration step reaches the box
    box = lim.box(robot, np.zeros(3), dt, np.array([3.0, 0, 0]), np.array([3.0, 0, 0]))
    assert box.relaxed == (JERK_RELAXED, ACCELERATION_RELAXED)
    assert box.ub[0] == pytest.approx(1.0)  # velocity: hard


@pytest.mark.parametrize("resolver", ["wqp", "hqp"])
def test_the_resolver_reports_the_relaxation_and_comes_back_inside(resolver: str) -> None:
    robot = case2_robot(lower=-0.6, upper=0.6, velocity=1.0)
    q = np.array([0.65, -0.2, 0.1])
    res = rk.make_resolver(resolver, limits={"acceleration": 5.0, "jerk": 100.0})
    stack = case2_stack()
    prepared(res, robot, stack, q)
    first = res.step(robot, stack, q, 0.0, 0.01)
    assert JERK_RELAXED in first.relaxed and first.fallback is None
    q = robot.integrate(q, first.dq, 0.01)
    for k in range(1, 200):
        out = res.step(robot, stack, q, k * 0.01, 0.01)
        assert out.fallback is None
        q = robot.integrate(q, out.dq, 0.01)
    assert q[0] <= 0.6 + 1e-12 and out.relaxed == ()


def test_a_jerk_limit_set_between_steps_applies_at_once() -> None:
    robot = case2_robot(lower=-3.0, upper=3.0, velocity=2.0)
    lim = JointLimits(acceleration=20.0)
    res = rk.make_resolver("wqp", limits=lim)
    stack = case2_stack()
    q = np.array([0.3, -0.4, 0.5])
    prepared(res, robot, stack, q)
    dqs = []
    for k in range(30):
        if k == 10:
            lim.jerk = 300.0
        out = res.step(robot, stack, q, k * 0.01, 0.01)
        dqs.append(np.asarray(out.dq).copy())
        q = robot.integrate(q, out.dq, 0.01)
    jerk = np.diff(np.array(dqs), n=2, axis=0) / 1e-4
    assert np.max(np.abs(jerk[11:])) <= 300.0 * (1 + 1e-9)  # from the second step with the limit: two q̇ known


def test_bad_jerk_values_are_refused_with_their_joint() -> None:
    with pytest.raises(ResolverError, match=r"jerk\['2'\] must be a number > 0 \[rad/s³\], got -1"):
        JointLimits(jerk={"2": -1.0})
    with pytest.raises(ResolverError, match="jerk must be a number > 0"):
        JointLimits(jerk=0.0)
    lim = JointLimits(jerk={"9": 10.0})
    with pytest.raises(ResolverError, match=r"jerk: unknown joint\(s\) \['9'\]"):
        lim.bind(case2_robot())
    with pytest.raises(ResolverError, match="no batches"):
        JointLimits(jerk=10.0).box(case2_robot(), np.zeros((2, 3)), 0.01)


def test_the_yaml_key_is_checked_with_its_path(tmp_path: Path) -> None:
    from redundik.config import load_task
    from tests.hostile import TASK

    def load(options: str) -> object:
        path = tmp_path / "t.yaml"
        path.write_text(TASK.replace("    resolver: wqp\n", f"    resolver: wqp\n    options: {options}\n", 1))
        return load_task(path)

    with pytest.raises(RedundikError, match=r"runs\.wqp\.options\.limits\.jerk\.2: expected a number > 0, got -1"):
        load("{limits: {jerk: {'2': -1}}}")
    with pytest.raises(RedundikError, match=r"runs\.wqp\.options\.limits\.jerk: expected a number > 0"):
        load("{limits: {jerk: fast}}")
    plan = load("{limits: {acceleration: 5, jerk: {'1': 100, '2': 200}}}")
    lim = plan.runs["wqp"].resolver.limits  # type: ignore[attr-defined]
    assert dict(lim.jerk) == {"1": 100.0, "2": 200.0} and lim.has_jerk


# ---------------------------------------------------------------------------------------------- robots
@pytest.mark.parametrize(("robot", "steps"), [("panda", 3000), ("talos", 1500)])
@pytest.mark.parametrize("resolver", ["wqp", "hqp"])
def test_random_target_jumps_keep_every_limit(robot: str, steps: int, resolver: str) -> None:
    """The benchmark's episodes (``benchmarks/jerk_stress.py``), shorter: 0 jerk, acceleration, position and
    velocity violations, no relaxation and no fallback with the default backend."""
    stress = _stress_module()
    c = stress.run_episodes(robot, resolver, DEFAULT_BACKEND, steps, seed=7)
    assert c.steps == steps
    assert (c.jerk, c.acc, c.pos, c.vel, c.relaxed, c.fallback) == (0, 0, 0, 0, 0, 0), c.line(robot)
    assert c.worst["jerk"] > 0.999  # the jerk limit is reached


@pytest.mark.parametrize("resolver", ["wqp", "hqp"])
def test_the_second_step_after_a_reset_knows_the_first_came_from_rest(resolver: str) -> None:
    """The TALOS stress found it: after ``reset`` the second step took the first step's acceleration as zero (as
    for an unknown history) instead of q̇₀/dt from rest, so a command reversing at once got a jerk of 2·j_max."""
    robot = case2_robot(lower=-3.0, upper=3.0, velocity=2.0)
    res = rk.make_resolver(resolver, limits={"acceleration": 10.0, "jerk": 100.0})
    posture = rk.PostureTask(np.zeros(3), gain=1.0)
    stack = rk.TaskStack([posture])
    q = np.zeros(3)
    prepared(res, robot, stack, q)
    for _ in range(2):  # the second time after a reset
        res.reset()
        posture.target = np.full(3, 1.0)  # far ahead: the first step goes as fast as the jerk allows
        dq0 = np.asarray(res.step(robot, stack, q, 0.0, 0.01).dq).copy()
        posture.target = np.full(3, -1.0)  # reversed: the second step brakes as hard as the jerk allows
        dq1 = np.asarray(res.step(robot, stack, q, 0.01, 0.01).dq).copy()
        jerk = (dq1 - 2 * dq0) / 1e-4  # the robot at rest before dq0
        assert dq0[0] == pytest.approx(100.0 * 1e-4)  # j_max·dt² from rest
        assert dq1[0] == pytest.approx(dq0[0])  # the hardest braking the jerk allows: q̈ back to 0 (it was 0 before)
        assert np.max(np.abs(jerk)) <= 100.0 * (1 + 1e-9)


@pytest.mark.parametrize("method", ["wqp", "hqp"])
def test_a_jerk_limit_switched_on_mid_run_reads_the_last_two_steps_on_either_path(method: str) -> None:
    """The compiled steps keep the last two q̇ as the per-task steps do: a jerk limit set between steps (which
    turns the compiled step off) starts from the same acceleration on a resolver that ran compiled as on one that
    ran the per-task steps (the compiled one took it as zero)."""
    q0 = np.array([0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.02, 0.02])
    runs = []
    for fuse in (True, False):
        robot = rk.load_example_robot("panda")
        subs: list[rk.Subtask] = [rk.GradientSubtask(rk.JointCentering(), gain=-1.0)]
        if method == "wqp":  # (with a bound subtask its per-task step is the template's)
            subs.append(rk.BoundSubtask(rk.JointValue("panda_joint1", 0.0), lower=-2.0, upper=2.0))
        frame = rk.FrameTask("panda_hand_tcp", rk.Circle(0.1, 3.0, plane=("y", "z")), gain=20.0)
        stack = rk.TaskStack([frame], subs)
        resolver = rk.make_resolver(method)
        resolver.fuse = fuse
        robot.update(q0)
        stack.reset(robot)
        q, out = q0.copy(), []
        for k in range(8):
            if k == 5:
                resolver.limits.jerk = 50.0
            res = resolver.step(robot, stack, q, k * 0.01, 0.01)
            out.append((res.dq.copy(), str(res.info["path"])))
            q = robot.integrate(q, res.dq, 0.01)
        runs.append(out)
    assert [p for _, p in runs[0][:5]] == ["compiled"] * 5
    for (a, _), (b, _) in zip(*runs, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


def test_a_jerk_limit_switched_on_mid_run_after_binding_limits_on_hqp() -> None:
    """The same on ``tasks/rpr_corner.yaml`` under ``hqp``, whose joint limits bind before the jerk limit is set (the
    constrained steps keep the q̇ history too): the first jerk-limited steps agree on both paths."""
    from redundik.config import load_task

    runs = []
    for fuse in (True, False):
        plan = load_task(ROOT / "tasks" / "rpr_corner.yaml")
        run = plan.runs["rank_only"]
        robot, stack = plan.robot.model, run.stack
        resolver = rk.make_resolver("hqp")
        resolver.fuse = fuse
        q = np.array(run.q0, dtype=float)
        robot.update(q)
        stack.reset(robot)
        out = []
        for k in range(8):
            if k == 4:
                stack.tasks[0].trajectory.omega = -2.27  # (a turn that drives the joints into their limits)
            if k == 5:
                resolver.limits.jerk = 404.0
            res = resolver.step(robot, stack, q, k * plan.dt, plan.dt)
            out.append(res.dq.copy())
            q = robot.integrate(q, res.dq, plan.dt)
        runs.append(out)
    for k, (a, b) in enumerate(zip(*runs, strict=True)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12, err_msg=f"step {k}")

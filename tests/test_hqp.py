"""hqp: equals the chapter's closed form when nothing is active, keeps higher levels' optimum, any depth."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import redundik as rk
from tests.test_qp_helpers import (
    BACKENDS,
    CASE2_Q0,
    case2_robot,
    case2_stack,
    prepared,
    qp_tolerance,
    random_robot,
    tip,
)


def test_case2_one_step_equals_pinv_and_the_hand_formula() -> None:
    robot = case2_robot()
    stack = case2_stack()
    hqp, pinv = rk.HierarchicalQPResolver(), rk.PinvResolver()
    prepared(hqp, robot, stack, CASE2_Q0)
    dq = hqp.step(robot, stack, CASE2_Q0, 0.0, 0.01).dq
    # J⁺V + (I − J⁺J)kη from numpy's own pinv, independent of redundik's linear algebra
    J = robot.frame_jacobian("3")[:2]
    Jp = np.linalg.pinv(J)
    eta = np.array([0.0, 0.0, np.sin(2 * CASE2_Q0[2])])
    expected = Jp @ np.array([0.2, -0.4]) + (np.eye(3) - Jp @ J) @ eta
    np.testing.assert_allclose(dq, expected, atol=1e-12)
    np.testing.assert_allclose(dq, pinv.step(robot, stack, CASE2_Q0, 0.0, 0.01).dq, atol=1e-12)


def test_case2_run_ends_where_the_pinv_run_ends() -> None:
    robot = case2_robot()
    logs = {}
    for name in ("pinv", "hqp"):
        logs[name] = rk.simulate(robot, case2_stack(), rk.make_resolver(name), CASE2_Q0, dt=0.01, steps=200)
    np.testing.assert_allclose(logs["hqp"].q, logs["pinv"].q, atol=1e-6)
    np.testing.assert_allclose(logs["hqp"].dq, logs["pinv"].dq, atol=1e-6)
    assert logs["hqp"].q[-1, 2] < np.radians(-60)  # θ3 heads for −90° (the chapter's case 2)
    assert not logs["hqp"].fallbacks


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(4, 8), axes=st.sampled_from(["position", "pose", "planar"]))
def test_hqp_main_plus_gradient_equals_pinv_on_random_robots(seed: int, n: int, axes: str) -> None:
    rng = np.random.default_rng(seed)
    robot = random_robot(rng, n)
    q = robot.random_configuration(rng)
    joint = robot.joint_names[int(rng.integers(n))]
    subs = [
        rk.GradientSubtask(rk.JointValue(joint, float(rng.uniform(-1, 1))), gain=float(rng.uniform(-2, 2))),
        rk.GradientSubtask(rk.JointCentering(), gain=float(rng.uniform(-2, 2))),
    ]
    stack = rk.TaskStack([rk.FrameTask(tip(robot), rk.Line(rng.uniform(-0.3, 0.3, 3)), axes=axes, gain=1.0)], subs)
    hqp, pinv = rk.HierarchicalQPResolver(limits=False), rk.PinvResolver()
    prepared(hqp, robot, stack, q)
    a = hqp.step(robot, stack, q, 0.1, 0.01)
    b = pinv.step(robot, stack, q, 0.1, 0.01)
    np.testing.assert_allclose(a.dq, b.dq, atol=1e-6)
    assert a.fallback is None


def _levels_stack(robot: rk.RobotModel, rng: np.random.Generator, depth: int) -> rk.TaskStack:
    """Up to 4 levels: tip position (0), tip orientation (1), a joint target as a 1-row task (2), gradient (3)."""
    names = robot.joint_names
    tasks: list[rk.Task] = [rk.FrameTask(tip(robot), rk.Line(rng.uniform(-0.5, 0.5, 3)), axes="position", gain=1.0)]
    if depth > 1:
        ori = rk.FrameTask(tip(robot), rk.Hold(), axes="orientation", gain=1.0, name="orientation")
        ori.priority = 1  # type: ignore[attr-defined]
        tasks.append(ori)
    if depth > 2:
        tasks.append(rk.PotentialTask(rk.JointValue(names[1], 0.0), target=0.0, rate=5.0, priority=2, name="j2"))
    subs = []
    if depth > 3:
        subs.append(rk.GradientSubtask(rk.JointValue(names[0], 1.0), gain=-3.0))
    return rk.TaskStack(tasks, subs)


@pytest.mark.parametrize("backend", BACKENDS)
@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_lower_levels_never_change_higher_levels_residuals(backend: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    robot = random_robot(rng, 7, velocity=float(rng.uniform(0.3, 1.0)))  # tight velocity limits: QP path
    q = robot.random_configuration(rng)
    tol = max(qp_tolerance(backend), 1e-6)  # the per-backend table, at least hqp's slack margin (1e-7) × levels
    residuals = {}
    for depth in (1, 2, 3, 4):
        stack = _levels_stack(robot, np.random.default_rng(seed), depth)
        res = rk.HierarchicalQPResolver(backend=backend)
        prepared(res, robot, stack, q)
        out = res.step(robot, stack, q, 0.0, 0.01)
        assert np.all(np.isfinite(out.dq))
        assert np.all(np.abs(out.dq) <= robot.velocity_limits + 1e-12)
        for lv in range(depth):
            residuals.setdefault(lv, []).append(out.info[f"residual_L{lv}"])
    for lv, values in residuals.items():
        assert max(values) - min(values) <= tol * (1 + min(values)), (lv, values)


def test_every_backend_gives_the_same_hierarchy_with_active_limits() -> None:
    robot = case2_robot(velocity=0.3)
    out = {}
    for backend in BACKENDS:
        res = rk.HierarchicalQPResolver(backend=backend)
        stack = case2_stack()
        prepared(res, robot, stack, CASE2_Q0)
        r = res.step(robot, stack, CASE2_Q0, 0.0, 0.01)
        assert r.info["qp"] >= 1 and r.info["backend"] == res.backend.name
        assert "3:lower_velocity" in r.info["active_limits"]
        out[backend] = r.dq
    ref = out["quadprog"] if "quadprog" in out else out[BACKENDS[0]]
    for backend, dq in out.items():
        np.testing.assert_allclose(dq, ref, atol=max(qp_tolerance(backend, ref), 1e-7), err_msg=backend)
    # with joint 3 stopped at −0.3 rad/s, the tip task is still met exactly by joints 1 and 2 (level 0 keeps priority)
    J = robot.frame_jacobian("3")[:2]
    np.testing.assert_allclose(J @ ref, [0.2, -0.4], atol=1e-7)


def test_three_levels_with_an_inequality_in_the_middle() -> None:
    """Level 0 tip line, level 1 keep θ2 ≥ −0.75 rad (inequality), level 2 drive θ2 down (gradient): the bound wins."""
    robot = case2_robot()
    stack = rk.TaskStack(
        [rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")],
        [
            rk.BoundSubtask(rk.JointValue("2", 0.0, name="th2"), upper=0.75**2, rate=10.0, priority=1),
            rk.GradientSubtask(rk.JointValue("2", -3.0, name="down"), gain=-5.0),
        ],
    )
    log = rk.simulate(robot, stack, rk.HierarchicalQPResolver(), CASE2_Q0, dt=0.01, steps=150)
    assert log.potentials["th2"].max() <= 0.75**2 + 1e-3
    free = rk.simulate(
        robot, rk.TaskStack(stack.tasks, stack.subtasks[1:]), rk.PinvResolver(), CASE2_Q0, dt=0.01, steps=150
    )
    assert free.potentials["down"][-1] < log.potentials["down"][-1]  # without the bound θ2 goes further
    assert log.max_task_error < 1e-6 + free.max_task_error


def test_clearance_inequality_subtask_is_respected() -> None:
    """Elbow (frame 2) keeps ≥ 0.08 m from a post placed 0.03 m beside its free path; the tip line is still tracked."""
    robot = case2_robot()
    free_stack = case2_stack()
    free = rk.simulate(robot, free_stack, rk.HierarchicalQPResolver(), CASE2_Q0, dt=0.01, steps=150, log_frames=("2",))
    path = free.frame_positions["2"]
    k = 140
    tangent = path[k + 1] - path[k - 1]
    normal = np.array([-tangent[1], tangent[0], 0.0]) / np.linalg.norm(tangent[:2])
    post = path[k] + 0.03 * normal  # 0.03 m beside the free elbow path
    margin = 0.08
    clearance = rk.Clearance("2", post, radius=0.0, axes="planar", name="clear")
    stack = rk.TaskStack(
        [rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")],
        [
            rk.BoundSubtask(clearance, lower=margin, rate=20.0, priority=1),
            rk.GradientSubtask(rk.JointSine2("3"), gain=1.0),
        ],
    )
    kept = rk.simulate(robot, stack, rk.HierarchicalQPResolver(), CASE2_Q0, dt=0.01, steps=150)
    free_clear = np.linalg.norm(path[:, :2] - post[:2], axis=1)
    assert free_clear[0] > margin + 0.02  # starts clear
    assert free_clear.min() < margin - 0.04  # the test can fail: the free motion does pass closer
    assert kept.potentials["clear"].min() >= margin - 1e-3
    assert kept.max_task_error < free.max_task_error + 1e-3  # open-loop Euler drift only, as in the free run
    assert not kept.fallbacks


def test_rank_loss_is_reported_for_an_algorithmic_singularity() -> None:
    robot = case2_robot()
    q = CASE2_Q0
    a = rk.PotentialTask(rk.JointValue("1", 0.0, name="p1"), target=0.0, priority=0, name="first")
    b = rk.PotentialTask(rk.JointValue("1", 0.0, name="p1b"), target=1.0, priority=1, name="conflict")
    stack = rk.TaskStack([a, b])
    res = rk.HierarchicalQPResolver(limits=False)
    prepared(res, robot, stack, q)
    out = res.step(robot, stack, q, 0.0, 0.01)
    assert out.info["rank_loss"] == 1 and out.info["rank_loss_levels"] == [1]
    ok = rk.TaskStack([a, rk.PotentialTask(rk.JointValue("2", 0.0), target=0.0, priority=1)])
    prepared(res, robot, ok, q)
    assert res.step(robot, ok, q, 0.0, 0.01).info["rank_loss"] == 0


def test_levels_option_reorders_the_hierarchy() -> None:
    robot = case2_robot()
    q = CASE2_Q0
    tip = rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")
    push = rk.TargetSubtask(rk.JointValue("1", 3.0, name="push"), target=0.0, rate=5.0)  # wants q̇1 far from J⁺V
    push2 = rk.TargetSubtask(rk.JointValue("2", 3.0, name="push2"), target=0.0, rate=5.0)
    stack = rk.TaskStack([tip], [push, push2])  # 2 + 2 rows on 3 joints: whichever level is lower loses

    def residuals(resolver: rk.HierarchicalQPResolver) -> tuple[float, float]:
        prepared(resolver, robot, stack, q)
        info = resolver.step(robot, stack, q, 0.0, 0.01).info
        return float(info["residual_L0"]), float(info["residual_L1"])

    # default: the tip at level 0 (exact), the target subtask one below (what is left of it)
    top, below = residuals(rk.HierarchicalQPResolver(limits=False))
    assert top < 1e-12 and below > 1e-3
    # flipped: the 1-row subtask on top is met exactly, the tip task gets only what remains
    for levels in ({"push": 0, "push2": 0, "3": 1}, [["push", "push2"], ["3"]]):
        top, below = residuals(rk.HierarchicalQPResolver(limits=False, levels=levels))
        assert top < 1e-12 and below > 1e-3
    with pytest.raises(rk.ResolverError, match=r"'nope': no such task or subtask; tasks and subtasks with a level"):
        prepared(rk.HierarchicalQPResolver(levels={"nope": 1}), robot, stack, q)
    grad = rk.TaskStack([tip], [rk.GradientSubtask(rk.JointSine2("3"))])
    with pytest.raises(rk.ResolverError, match=r"'sin2_3': a gradient subtask belongs to the null-space objective"):
        prepared(rk.HierarchicalQPResolver(levels={"sin2_3": 0}), robot, grad, q)


def test_joint_coupling_at_level_0_holds_the_offset() -> None:
    robot = random_robot(np.random.default_rng(3), 6)
    q0 = robot.random_configuration(np.random.default_rng(4))
    names = robot.joint_names
    stack = rk.TaskStack(
        [
            rk.JointCoupling(names[1], names[2], offset=0.3, gain=10.0),
            rk.FrameTask(tip(robot), rk.Line([0.05, 0.0, 0.02]), axes="position", gain=1.0),
        ],
    )
    stack.tasks[1].priority = 1  # type: ignore[attr-defined]
    # (no joint-speed cap either: the first steps ask 30 rad/s of this limitless robot, which the cap would scale)
    hqp = rk.HierarchicalQPResolver(limits=False, max_joint_speed=None)
    log = rk.simulate(robot, stack, hqp, q0, dt=0.01, steps=200)
    c = log.q[:, 1] - log.q[:, 2]
    err0 = abs(0.3 - c[0])
    assert abs(0.3 - c[-1]) < 1e-6 + err0 * np.exp(-10 * 2.0) * 2 + 1e-9
    # the first coupling error decays like exp(−K t) with Euler steps: (1 − K dt)^k
    np.testing.assert_allclose(np.abs(0.3 - c[:20]), err0 * (1 - 0.1) ** np.arange(20), rtol=1e-6, atol=1e-12)

"""Joint limits as bounds on q̇: formulas, long random runs with 0 violations, starts at and outside the limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

import redundik as rk
from redundik.errors import ResolverError
from redundik.resolvers.qp.limits import POSITION, RATE, VELOCITY, JointLimits
from tests.test_qp_helpers import case2_robot, prepared, random_robot, tip


def test_box_follows_the_documented_formulas() -> None:
    robot = case2_robot(lower=-1.0, upper=1.0, velocity=2.0)
    lim = JointLimits()
    dt = 0.1
    q = np.array([0.0, 0.95, 1.3])  # inside, near the upper limit, outside above it
    box = lim.box(robot, q, dt)
    np.testing.assert_allclose(box.lb, [-2.0, -2.0, -2.0])
    np.testing.assert_allclose(box.ub, [2.0, 0.05 / dt, -2.0])  # joint 3 may only move back, at the velocity limit
    assert box.upper_src.tolist() == [VELOCITY, POSITION, POSITION]
    robot2 = case2_robot(lower=-1.0, upper=1.0)  # no velocity limit: back inside in one step
    box2 = JointLimits(position_gain=0.5).box(robot2, q, dt)
    np.testing.assert_allclose(box2.ub, [0.5 * 1.0 / dt, 0.5 * 0.05 / dt, 0.5 * (1.0 - 1.3) / dt])
    np.testing.assert_allclose(box2.lb, [0.5 * -1.0 / dt, 0.5 * -1.95 / dt, 0.5 * -2.3 / dt])


def test_rate_limit_window_is_relaxed_onto_the_feasible_box() -> None:
    robot = case2_robot(lower=-1.0, upper=1.0, velocity=2.0)
    lim = JointLimits(acceleration=10.0)
    dt = 0.01
    q = np.array([0.0, 0.0, 0.999])
    box = lim.box(robot, q, dt, dq_prev=np.array([1.0, -5.0, 1.0]))
    # joint 3 is 0.001 rad from its limit: braking bound B(δ) = −a·dt + √((a·dt)² + 2aδ) < δ/dt
    brake = -10.0 * dt + math.sqrt((10.0 * dt) ** 2 + 2 * 10.0 * 0.001)
    assert brake < 0.001 / dt
    np.testing.assert_allclose(box.lb, [0.9, -2.0, brake])
    np.testing.assert_allclose(box.ub, [1.1, -2.0, brake])  # joint 2's and 3's windows moved onto the box
    assert box.lower_src[0] == RATE and box.upper_src[0] == RATE
    assert box.lb[2] <= box.ub[2]


def test_overrides_and_errors_name_the_joint() -> None:
    robot = case2_robot(lower=-1.0, upper=1.0, velocity=2.0)
    lim = JointLimits(lower={"2": -0.5}, velocity_limits={"3": 0.1}, acceleration={"1": 3.0})
    lim.bind(robot)
    assert lim.lower_position.tolist() == [-1.0, -0.5, -1.0]
    box = lim.box(robot, np.zeros(3), 0.01, np.zeros(3))
    assert box.ub[2] == pytest.approx(0.1) and box.ub[0] == pytest.approx(0.03)
    with pytest.raises(ResolverError, match=r"unknown joint\(s\) \['elbow'\].*available: \['1', '2', '3'\]"):
        JointLimits(upper={"elbow": 1.0}).bind(robot)
    with pytest.raises(ResolverError, match=r"joint '2': lower 2\.0 > upper 1\.0"):
        JointLimits(lower={"2": 2.0}).bind(robot)
    with pytest.raises(ResolverError, match="position_gain"):
        JointLimits(position_gain=1.5)
    with pytest.raises(ResolverError, match="velocity_limits"):
        JointLimits(velocity_limits={"1": 0.0})
    # the switches take True/False only: velocity=0.3 read as "on" kept the model's limits instead of 0.3 rad/s
    with pytest.raises(ResolverError, match=r"velocity switches .* got 0\.3; a velocity limit for every joint is "
                                            r"velocity_limits="):  # fmt: skip
        JointLimits(velocity=0.3)  # type: ignore[arg-type]
    with pytest.raises(ResolverError, match=r"position switches .* got 'no'"):
        JointLimits(position="no")  # type: ignore[arg-type]
    assert not JointLimits(position=np.bool_(False)).position


def test_free_flyer_coordinates_carry_no_position_limits() -> None:
    from redundik.kinematics.urdf import EXAMPLE_ROBOTS, example_robot_data_dir

    path = example_robot_data_dir() / EXAMPLE_ROBOTS["panda"][0]  # example-robot-data: in the test extra
    robot = rk.from_urdf(path, free_flyer=True)
    lim = JointLimits()
    lim.bind(robot)
    lo, hi = lim.lower_position, lim.upper_position
    assert robot.nv == 6 + 9
    assert np.all(np.isinf(lo[:6])) and np.all(np.isinf(hi[:6]))
    assert np.all(np.isfinite(lo[6:13])) and np.all(np.isfinite(hi[6:13]))  # the arm's 7 joints keep theirs
    q = robot.neutral()
    q[:3] = [1e3, -1e3, 50.0]  # far away base: no position bound on it
    box = lim.box(robot, q, 0.01)
    assert not np.any(box.upper_src[:6] == POSITION) and not np.any(box.lower_src[:6] == POSITION)


def _wild_stack(robot: rk.RobotModel, rng: np.random.Generator) -> rk.TaskStack:
    """Tasks that pull the joints out of their ranges: a far tip target, joints driven past their limits."""
    names = robot.joint_names
    far = rk.Line(rng.uniform(-1.0, 1.0, 3))
    subs = [
        rk.GradientSubtask(rk.JointValue(names[k], float(rng.choice([-5.0, 5.0]))), gain=-4.0)
        for k in rng.choice(len(names), 3, replace=False)
    ]
    return rk.TaskStack([rk.FrameTask(tip(robot), far, axes="position", gain=2.0)], subs)


@pytest.mark.parametrize("resolver", ["wqp", "hqp"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_zero_violations_over_long_random_runs(resolver: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    robot = random_robot(rng, 6, velocity=1.5, limit=1.0)
    acc = 20.0 if seed == 2 else None
    res = rk.make_resolver(resolver, limits={"acceleration": acc})
    q0 = robot.random_configuration(rng)
    dt = 0.01
    log = rk.simulate(robot, _wild_stack(robot, rng), res, q0, dt=dt, steps=600)
    viol = np.array([robot.limit_violation(q) for q in log.q])
    assert viol.max() == 0.0
    assert np.abs(log.dq).max() <= 1.5 + 1e-12
    if acc is not None:
        assert np.abs(np.diff(log.dq[:-1], axis=0)).max() <= acc * dt + 1e-9
    touched = np.isclose(np.abs(log.q), 1.0, atol=1e-6).any()
    assert touched  # the test can fail: the tasks do drive joints onto their limits
    assert np.all(np.isfinite(log.dq))


@pytest.mark.parametrize("resolver", ["wqp", "hqp", "wqp-proxsuite"])
def test_starts_at_and_slightly_outside_the_limits(resolver: str) -> None:
    name, _, backend = resolver.partition("-")
    rng = np.random.default_rng(7)
    robot = random_robot(rng, 6, velocity=0.5, limit=1.0)
    q0 = np.array([1.0, -1.0, 1.02, -1.05, 0.3, 1.0])  # two on a limit, two outside it by 0.02 and 0.05 rad
    dt = 0.01
    opts = {"backend": backend} if backend else {}
    log = rk.simulate(robot, _wild_stack(robot, rng), rk.make_resolver(name, **opts), q0, dt=dt, steps=400)
    outside = np.array([robot.limit_violation(q) for q in log.q])  # (N, 6)
    # never further out; back inside after ⌈excess / (v_max dt)⌉ steps; then 0 violations
    assert np.all(np.diff(outside, axis=0) <= 1e-12)
    back = math.ceil(0.05 / (0.5 * dt))
    assert outside[back:].max() == 0.0
    assert outside[:back].max() > 0  # it did start outside
    assert np.all(np.isfinite(log.dq)) and np.abs(log.dq).max() <= 0.5 + 1e-12


def test_limits_false_removes_them_and_hqp_then_tracks_beyond() -> None:
    robot = case2_robot(lower=-0.1, upper=0.1)
    stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")])
    q0 = np.radians([110.0, -40.0, -30.0])  # outside ±0.1 rad everywhere
    res = rk.HierarchicalQPResolver(limits=False)
    prepared(res, robot, stack, q0)
    free = rk.simulate(robot, stack, res, q0, dt=0.01, steps=20)
    assert free.max_task_error < 1e-3  # open-loop Euler drift only
    held = rk.simulate(robot, stack, rk.HierarchicalQPResolver(), q0, dt=0.01, steps=20)
    assert np.all(np.abs(held.q[-1]) <= 0.1 + 1e-12)  # with the limits it goes back inside at once (no v_max)

"""rk.solve_ik: convergence on reachable poses, hard joint limits (even on failure), several frames, the batch form,
determinism, and clear errors on bad input."""

from __future__ import annotations

import functools

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.errors import ModelError, ResolverError, TaskError
from redundik.ik import kernels as K

TOOL = {"panda": "panda_hand_tcp", "ur5": "tool0"}


@functools.cache
def robot(name: str) -> rk.RobotModel:
    return rk.load_example_robot(name)


def reachable(r: rk.RobotModel, frame: str, n: int, seed: int) -> list[pin.SE3]:
    """Poses of ``frame`` at n random in-limit configurations."""
    rng = np.random.default_rng(seed)
    data = r.model.createData()
    fid = r.model.getFrameId(frame)
    out = []
    for _ in range(n):
        pin.framesForwardKinematics(r.model, data, r.random_configuration(rng))
        out.append(data.oMf[fid].copy())
    return out


def fk(r: rk.RobotModel, q: np.ndarray, frame: str) -> pin.SE3:
    data = r.model.createData()
    pin.framesForwardKinematics(r.model, data, q)
    return data.oMf[r.model.getFrameId(frame)]


def within_limits(r: rk.RobotModel, q: np.ndarray) -> bool:
    return bool(np.all(q >= r.model.lowerPositionLimit) and np.all(q <= r.model.upperPositionLimit))


@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_reachable_poses_are_solved_within_limits(name: str) -> None:
    r, frame = robot(name), TOOL[name]
    targets = reachable(r, frame, 200, seed=7)
    batch = rk.solve_ik_batch(r, frame, targets, timeout=None, max_restarts=100)
    assert batch.success_rate >= 0.99, batch.reason
    for i, T in enumerate(targets):
        q = batch.q[i]
        assert within_limits(r, q)
        if batch.success[i]:
            M = fk(r, q, frame)  # checked independently of the solver's own errors
            assert np.linalg.norm(M.translation - T.translation) <= 1e-5
            assert np.linalg.norm(pin.log3(T.rotation @ M.rotation.T)) <= 1e-4
            assert batch.position_error[i] <= 1e-5 and batch.orientation_error[i] <= 1e-4


@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_few_restarts_and_iterations_per_pose(name: str) -> None:
    """The error-proportional damping and the position weight (kernels docstring): on 200 reachable poses from
    mid-range, at most one restart and 30 iterations per pose on average (before them the UR5 needed 1.5 restarts and
    48 iterations)."""
    r, frame = robot(name), TOOL[name]
    batch = rk.solve_ik_batch(r, frame, reachable(r, frame, 200, seed=0), seed=1, timeout=None, max_restarts=100)
    assert batch.success_rate == 1.0
    assert batch.restarts.mean() <= 1.0, batch.restarts.mean()
    assert batch.iterations.mean() <= 30.0, batch.iterations.mean()


def test_no_kernel_takes_more_than_ten_parameters() -> None:
    import inspect

    for name, fn in vars(K).items():
        if hasattr(fn, "py_func"):
            assert len(inspect.signature(fn.py_func).parameters) <= 10, name


def test_robots_with_the_same_frames_keep_their_own_limits() -> None:
    """Problems are cached per thread and robot: a second robot with the same frames but narrower limits is solved
    within its own limits, and the first one still within its own."""
    wide = robot("panda")
    model = wide.model.copy()
    mid = 0.5 * (model.lowerPositionLimit[:7] + model.upperPositionLimit[:7])
    model.upperPositionLimit[:7] = np.minimum(model.upperPositionLimit[:7], mid)
    narrow = rk.RobotModel(model, name="narrow panda")
    q_in = 0.5 * (model.lowerPositionLimit + model.upperPositionLimit)
    T = fk(narrow, q_in, "panda_hand_tcp").copy()
    for r in (wide, narrow, wide, narrow):
        res = rk.solve_ik(r, "panda_hand_tcp", T, timeout=None, max_restarts=200)
        assert res.success and within_limits(r, res.q)
    assert not within_limits(narrow, rk.solve_ik(wide, "panda_hand_tcp", T, q0=wide.model.upperPositionLimit,
                                                 timeout=None, max_restarts=0).q)  # fmt: skip


def test_a_position_target_after_a_pose_target_is_solved_as_on_its_own() -> None:
    """Each frame keeps six rows in the stacked residual; a position target's rotation rows must be zero, not what
    the previous pose target of the same (cached) problem left there."""
    r = rk.load_example_robot("panda")  # a robot of its own: nothing solved on it yet
    p = np.array([0.0, 0.1, 0.0])
    alone = rk.solve_ik(r, "panda_hand_tcp", p, timeout=None, max_restarts=5)
    rk.solve_ik(r, "panda_hand_tcp", reachable(r, "panda_hand_tcp", 1, seed=2)[0], timeout=None, max_restarts=5)
    after = rk.solve_ik(r, "panda_hand_tcp", p, timeout=None, max_restarts=5)
    assert np.array_equal(after.q, alone.q) and after.iterations == alone.iterations
    mixed = rk.solve_ik_batch(r, "panda_hand_tcp", [reachable(r, "panda_hand_tcp", 1, seed=2)[0], p], seed=3,
                              timeout=None, max_restarts=5)  # fmt: skip
    assert np.array_equal(mixed.q[1], rk.solve_ik(r, "panda_hand_tcp", p, seed=(3, 1), timeout=None, max_restarts=5).q)


def test_threads_get_the_answers_of_serial_calls() -> None:
    from concurrent.futures import ThreadPoolExecutor

    r = robot("ur5")
    targets = reachable(r, "tool0", 16, seed=5)

    def one(i: int) -> np.ndarray:
        return rk.solve_ik(r, "tool0", targets[i], seed=(2, i), timeout=None, max_restarts=50).q

    serial = [one(i) for i in range(16)]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(one, range(16)))
    for a, b in zip(serial, threaded, strict=True):
        assert np.array_equal(a, b)


def test_a_target_se3_that_is_not_rigid_is_refused() -> None:
    bad = pin.SE3(np.diag([1.0, 1.0, 1.01]), np.array([0.4, 0.0, 0.4]))
    with pytest.raises(TaskError, match="rigid transform"):
        rk.solve_ik(robot("panda"), "panda_hand_tcp", bad)


def test_failure_still_returns_a_configuration_within_limits() -> None:
    r = robot("panda")
    res = rk.solve_ik(r, "panda_hand_tcp", np.array([3.0, 0.0, 0.5]), timeout=None, max_restarts=3)
    assert not res.success and res.reason == "max_restarts" and res.restarts == 3
    assert within_limits(r, res.q) and np.all(np.isfinite(res.q))
    assert res.position_error > 1.5  # the Panda reaches ≈ 0.9 m: its best is still far
    res = rk.solve_ik(r, "panda_hand_tcp", np.array([3.0, 0.0, 0.5]), timeout=0.01)
    assert not res.success and res.reason == "timeout" and within_limits(r, res.q)


def test_a_start_outside_the_limits_is_clipped_into_them() -> None:
    r = robot("panda")
    T = reachable(r, "panda_hand_tcp", 1, seed=3)[0]
    res = rk.solve_ik(r, "panda_hand_tcp", T, q0=np.full(9, 10.0), timeout=None, max_restarts=50)
    assert res.success and within_limits(r, res.q)


def test_position_only_target() -> None:
    r = robot("panda")
    p = reachable(r, "panda_hand_tcp", 1, seed=11)[0].translation
    res = rk.solve_ik(r, "panda_hand_tcp", p, timeout=None, max_restarts=50)
    assert res.success and res.orientation_error == 0.0
    assert np.linalg.norm(fk(r, res.q, "panda_hand_tcp").translation - p) <= 1e-5


def test_several_frames_at_once_list_and_mapping() -> None:
    r = robot("panda")
    q_true = r.random_configuration(np.random.default_rng(5))
    hand, elbow = fk(r, q_true, "panda_hand_tcp").copy(), fk(r, q_true, "panda_link4").translation.copy()
    res = rk.solve_ik(r, ["panda_hand_tcp", "panda_link4"], [hand, elbow], timeout=None, max_restarts=100)
    assert res.success and set(res.frame_errors) == {"panda_hand_tcp", "panda_link4"}
    assert np.linalg.norm(fk(r, res.q, "panda_link4").translation - elbow) <= 1e-5
    assert np.linalg.norm(fk(r, res.q, "panda_hand_tcp").translation - hand.translation) <= 1e-5
    again = rk.solve_ik(r, {"panda_hand_tcp": hand, "panda_link4": elbow}, timeout=None, max_restarts=100)
    assert np.array_equal(again.q, res.q)


def test_batch_equals_one_by_one_and_is_deterministic() -> None:
    r = robot("ur5")
    targets = reachable(r, "tool0", 12, seed=21)
    batch = rk.solve_ik_batch(r, "tool0", targets, seed=4, timeout=None, max_restarts=40)
    for i, T in enumerate(targets):
        one = rk.solve_ik(r, "tool0", T, seed=(4, i), timeout=None, max_restarts=40)
        assert np.array_equal(one.q, batch.q[i]) and one.success == batch.success[i]
        assert one.iterations == batch.iterations[i] and one.restarts == batch.restarts[i]
    again = rk.solve_ik_batch(r, "tool0", np.array([T.homogeneous for T in targets]), seed=4, timeout=None,
                              max_restarts=40)  # fmt: skip
    assert np.array_equal(again.q, batch.q)
    other = rk.solve_ik_batch(r, "tool0", targets, seed=5, timeout=None, max_restarts=40)
    assert other.success_rate == 1.0


def test_free_flyer_model_integrates_on_the_manifold() -> None:
    r = robot("talos") if "talos" in rk.kinematics.EXAMPLE_ROBOTS else pytest.skip("no talos")
    frame = "gripper_left_joint" if r.model.existFrame("gripper_left_joint") else r.frame_names[-1]
    target = fk(r, r.neutral(), frame).translation + np.array([0.1, 0.05, -0.1])
    res = rk.solve_ik(r, frame, target, timeout=None, max_restarts=5)
    assert res.success
    assert abs(np.linalg.norm(res.q[3:7]) - 1.0) < 1e-9  # the base quaternion stays a unit quaternion
    lo, hi = r.model.lowerPositionLimit[7:], r.model.upperPositionLimit[7:]
    assert np.all(res.q[7:] >= lo) and np.all(res.q[7:] <= hi)


def test_log3_and_the_rotation_jacobian_against_pinocchio_and_finite_differences() -> None:
    rng = np.random.default_rng(0)
    out = np.empty(3)
    for theta in [0.0, 1e-7, 0.3, 2.0, np.pi - 1e-4, np.pi - 1e-9]:
        axis = rng.normal(size=3)
        w = theta * axis / np.linalg.norm(axis)
        K.log3(pin.exp3(w), out)
        assert np.allclose(pin.exp3(out), pin.exp3(w), atol=1e-9)
        if theta < np.pi - 1e-3:
            assert np.allclose(out, pin.log3(pin.exp3(w)), atol=1e-9)
    Ji = np.empty((3, 3))
    for theta in [1e-6, 0.5, 2.5, 3.1]:
        axis = rng.normal(size=3)
        w = theta * axis / np.linalg.norm(axis)
        K.jr_inv(w, Ji)
        E, h = pin.exp3(w), 1e-6
        num = np.column_stack([(pin.log3(E @ pin.exp3(h * e)) - pin.log3(E @ pin.exp3(-h * e))) / (2 * h)
                               for e in np.eye(3)])  # fmt: skip
        assert np.allclose(Ji, num, atol=1e-6)


@pytest.mark.parametrize(
    ("kwargs", "error", "text"),
    [
        ({"frame": "no_such_frame"}, ModelError, "does not exist"),
        ({"target": np.array([np.nan, 0.0, 0.0])}, TaskError, "NaN"),
        ({"target": np.ones((4, 4))}, TaskError, "rigid transform"),
        ({"target": np.ones(5)}, TaskError, "position (3,)"),
        ({"target": "up"}, TaskError, "expected"),
        ({"position_tolerance": 0.0}, ResolverError, "position_tolerance"),
        ({"orientation_tolerance": -1.0}, ResolverError, "orientation_tolerance"),
        ({"timeout": float("nan")}, ResolverError, "timeout"),
        ({"timeout": None, "max_restarts": None}, ResolverError, "forever"),
        ({"max_restarts": -1}, ResolverError, "max_restarts"),
        ({"max_iterations": 0}, ResolverError, "max_iterations"),
        ({"q0": np.zeros(3)}, ModelError, "expected 9 values"),
        ({"q0": np.full(9, np.inf)}, ModelError, "NaN or infinite"),
        ({"seed": "abc"}, ResolverError, "seed"),
        ({"frame": ["panda_hand_tcp", "panda_link4"]}, TaskError, "2 frames need a list of 2 targets"),
        ({"frame": "universe"}, ModelError, "fixed to the world"),
    ],
)
def test_hostile_inputs_get_clear_errors(kwargs: dict[str, object], error: type[Exception], text: str) -> None:
    args: dict[str, object] = {"frame": "panda_hand_tcp", "target": np.array([0.4, 0.0, 0.4])}
    args.update(kwargs)
    with pytest.raises(error, match=None) as info:
        rk.solve_ik(robot("panda"), **args)  # type: ignore[arg-type]
    assert text in str(info.value)


def test_batch_hostile_inputs() -> None:
    r = robot("panda")
    with pytest.raises(ResolverError, match="q0 has 3 rows for 2 targets"):
        rk.solve_ik_batch(r, "panda_hand_tcp", np.zeros((2, 3)) + 0.3, q0=np.zeros((3, 9)))
    with pytest.raises(TaskError, match="NaN"):
        rk.solve_ik_batch(r, "panda_hand_tcp", np.array([[0.3, 0.0, 0.4], [np.nan, 0.0, 0.0]]))
    with pytest.raises(ResolverError, match="seed"):
        rk.solve_ik_batch(r, "panda_hand_tcp", np.zeros((1, 3)) + 0.3, seed=-1)
    with pytest.raises(ModelError, match="RobotModel"):
        rk.solve_ik(r.model, "panda_hand_tcp", np.zeros(3))  # type: ignore[arg-type]

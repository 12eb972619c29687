"""The clearance potential's compiled path (``hqp_kernels.clearance_into`` on views of Pinocchio's memory) against
the NumPy formula it replaced, p = ‖S(p_f − p_o)‖ − r and η = J_vᵀ Sᵀ u, kept here as the slow reference."""

from __future__ import annotations

import numpy as np
import pytest

import redundik as rk
from redundik.errors import ModelError
from redundik.tasks.potentials import Clearance


def _reference(c: Clearance, robot: rk.RobotModel) -> tuple[float, np.ndarray]:
    fid = robot.frame_id(c.frame)
    d = (robot.frame_position(fid) - c.center)[c.rows]
    n = float(np.linalg.norm(d))
    if n < 1e-12:
        return n - c.radius, np.zeros(robot.nv)
    return n - c.radius, robot.frame_jacobian(fid)[c.rows].T @ (d / n)


@pytest.mark.parametrize("name", ["panda", "talos"])
def test_clearance_equals_the_numpy_formula(name: str) -> None:
    """Value and gradient to 1e-14 on frames along the chains (a floating base on Talos), for every axis set,
    through value_and_gradient, value, gradient and value_and_gradient_into (scale ±1), over random states."""
    robot = rk.load_example_robot(name)
    rng = np.random.default_rng(5)
    moved = [f for f in robot.frame_names if robot.model.frames[robot.frame_id(f)].parentJoint > 0]  # (a joint moves)
    frames = moved[::7][:12]
    for fr in frames:
        for axes in ("position", ("x", "y"), ("z",), ("x", "z")):
            c = Clearance(fr, rng.normal(scale=0.5, size=3), radius=0.05, axes=axes)
            for _ in range(3):
                robot.update(robot.random_configuration(rng))
                p0, g0 = _reference(c, robot)
                p1, g1 = c.value_and_gradient(robot)
                assert abs(p1 - p0) <= 1e-14 and np.abs(g1 - g0).max() <= 1e-14
                assert c.value(robot) == p1
                np.testing.assert_array_equal(c.gradient(robot), g1)
                out = np.full(robot.nv, np.nan)
                assert c.value_and_gradient_into(robot, out, -1.0) == p1
                np.testing.assert_array_equal(out, -g1)


@pytest.mark.parametrize("potential", ["Clearance", "VirtualPoint", "Manipulability"])
def test_a_frame_potential_on_a_frame_fixed_to_the_world_is_refused(potential: str) -> None:
    """A frame no joint moves has a constant potential and a zero gradient: a subtask on it would silently do
    nothing (``FrameTask`` refuses such a frame too)."""
    from redundik.errors import TaskError

    robot = rk.load_example_robot("panda")
    make = {
        "Clearance": lambda: Clearance("panda_link0", [0.3, 0.0, 0.5], radius=0.05),
        "VirtualPoint": lambda: rk.VirtualPoint("panda_link0", [0.3, 0.0, 0.5]),
        "Manipulability": lambda: rk.Manipulability("panda_link0"),
    }[potential]
    stack = rk.TaskStack([rk.FrameTask("panda_hand")], [rk.GradientSubtask(make(), gain=0.1)])
    robot.update(robot.neutral())
    with pytest.raises(TaskError, match="'panda_link0' is fixed to the world"):
        stack.reset(robot)


def test_clearance_follows_moved_centres_radii_and_robots() -> None:
    """An assigned centre and radius are used at the next call (the centre is read-only: an edit in place is
    refused, as a fused step packs it), and a second robot's data gets its own views."""
    a, b = rk.load_example_robot("panda"), rk.load_example_robot("panda")
    rng = np.random.default_rng(2)
    c = Clearance("panda_link4", [0.3, 0.1, 0.4], radius=0.05, axes=("x", "y"))
    for robot in (a, b, a):
        robot.update(robot.random_configuration(rng))
        with pytest.raises(ValueError, match="read-only"):
            c.center[1] += 0.01
        c.center = c.center + np.array([0.0, 0.01, 0.0])
        c.radius += 0.01
        p0, g0 = _reference(c, robot)
        p1, g1 = c.value_and_gradient(robot)
        assert abs(p1 - p0) <= 1e-14 and np.abs(g1 - g0).max() <= 1e-14
    c.center = np.array([0.0, 0.0, 0.0])
    p0, g0 = _reference(c, a)
    p1, g1 = c.value_and_gradient(a)
    assert abs(p1 - p0) <= 1e-14 and np.abs(g1 - g0).max() <= 1e-14


def test_clearance_without_verified_views_takes_the_copies(monkeypatch: pytest.MonkeyPatch) -> None:
    """When Pinocchio's memory cannot be verified the same kernel runs on the bindings' copies: same values."""
    import redundik.kinematics.memory as memory

    monkeypatch.setattr(memory, "se3_vector_view", lambda placements: None)
    robot = rk.load_example_robot("panda")
    rng = np.random.default_rng(8)
    c = Clearance("panda_link6", [0.2, -0.3, 0.5], radius=0.02)
    for _ in range(3):
        robot.update(robot.random_configuration(rng))
        p0, g0 = _reference(c, robot)
        p1, g1 = c.value_and_gradient(robot)
        assert c._views is not None and c._views[2] is None
        assert abs(p1 - p0) <= 1e-14 and np.abs(g1 - g0).max() <= 1e-14


def test_clearance_on_the_obstacle_axis_and_before_update() -> None:
    """On the obstacle's axis the gradient is zero (no direction picked), p = −r; before any update it raises."""
    robot = rk.load_example_robot("panda")
    c = Clearance("panda_link4", [0.0, 0.0, 0.0], radius=0.1, axes=("x", "y"))
    with pytest.raises(ModelError):
        c.value_and_gradient(robot)
    robot.update(robot.neutral())
    c.center = robot.frame_position("panda_link4") + np.array([0.0, 0.0, 0.3])
    p, g = c.value_and_gradient(robot)
    assert p == -0.1
    np.testing.assert_array_equal(g, np.zeros(robot.nv))


def test_clearance_pickles_and_copies_without_its_views() -> None:
    """A pickled or deep-copied clearance leaves its views behind and rebuilds them for the robot it meets."""
    import copy
    import pickle

    robot = rk.load_example_robot("panda")
    robot.update(robot.random_configuration(np.random.default_rng(1)))
    c = Clearance("panda_link4", [0.3, 0.1, 0.4], radius=0.05, axes=("x", "y"))
    p0, g0 = c.value_and_gradient(robot)
    for other in (pickle.loads(pickle.dumps(c)), copy.deepcopy(c)):
        assert other._views is None
        p1, g1 = other.value_and_gradient(robot)
        assert p1 == p0
        np.testing.assert_array_equal(g1, g0)

"""CoM task, contact tasks, the support polygon, and the humanoid_balance run (TALOS with a floating base)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from redundik.config import load_task
from redundik.config.runner import run_task
from redundik.errors import ConfigError, TaskError
from redundik.kinematics import load_example_robot
from redundik.tasks.balance import CoMTask, ContactTask, SupportPolygon, center_of_mass, convex_hull_2d

TASKS = Path(__file__).resolve().parents[1] / "tasks"


def test_com_jacobian_matches_finite_differences() -> None:
    robot = load_example_robot("talos")
    rng = np.random.default_rng(1)
    q = robot.neutral()
    q[7:] += rng.uniform(-0.3, 0.3, robot.nq - 7)
    robot.update(q)
    c, Jc = center_of_mass(robot)
    eps = 1e-6
    for k in rng.choice(robot.nv, 8, replace=False):
        dq = np.zeros(robot.nv)
        dq[k] = eps
        robot.update(pin.integrate(robot.model, q, dq))
        cp = center_of_mass(robot)[0]
        robot.update(pin.integrate(robot.model, q, -dq))
        cm = center_of_mass(robot)[0]
        np.testing.assert_allclose(Jc[:, k], (cp - cm) / (2 * eps), atol=1e-7)
    robot.update(q)
    task = CoMTask(axes=["x", "y"])
    task.reset(robot)
    term = task.evaluate(robot, 0.0)
    assert term.J.shape == (2, robot.nv) and np.allclose(term.error, 0)
    task.set_target(c + np.array([0.01, 0.0, 0.0]))
    assert task.evaluate(robot, 0.0).error == pytest.approx([0.01, 0.0])


def test_support_polygon_is_the_hull_of_both_soles() -> None:
    robot = load_example_robot("talos")
    robot.update(robot.neutral())
    sp = SupportPolygon(["left_sole_link", "right_sole_link"], size=(0.2, 0.1), margin=0.01)
    sp.check(robot)
    assert len(sp.vertices) == 4  # two aligned rectangles: their hull is one rectangle
    c = center_of_mass(robot)[0]
    # distance to the nearest edge: the soles are at x = −0.02, y = ±0.085, so the front edge is at x = 0.08
    expected = min(0.08 - c[0], c[0] + 0.12, 0.135 - c[1], c[1] + 0.135)
    assert sp.value(robot) == pytest.approx(expected)
    assert np.min(sp.evaluate(robot).h) == pytest.approx(expected - 0.01)
    hull = convex_hull_2d(np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]]))
    assert len(hull) == 4
    with pytest.raises(TaskError, match="frame 'left_foot' does not exist"):
        SupportPolygon(["left_foot"]).check(robot)
    with pytest.raises(TaskError, match="size"):
        SupportPolygon(["left_sole_link"], size=(0.2, -0.1))


def test_contact_task_reports_drift() -> None:
    robot = load_example_robot("talos")
    q = robot.neutral()
    robot.update(q)
    foot = ContactTask("left_sole_link")
    foot.reset(robot)
    assert foot.drift(robot) == 0.0
    q2 = q.copy()
    q2[0] += 0.003  # the base moves 3 mm: the foot with it
    robot.update(q2)
    assert foot.drift(robot) == pytest.approx(0.003)
    assert foot.evaluate(robot, 0.0).error[:3] == pytest.approx([-0.003, 0, 0])


def test_humanoid_balance_run() -> None:
    plan = load_task(TASKS / "humanoid_balance.yaml")
    assert plan.robot.model.nv == plan.robot.model.nq - 1 == 38  # the floating base is an unknown
    res = run_task(plan)
    for name, r in res.items():
        s = r.summary
        assert s["com_support_margin"] >= 0.01, name
        assert np.all(r.series["com_support_margin"] >= 0.01)
        assert s["max_contact_drift"] <= 1e-4, name
        assert s["min_collision_distance"] >= 0.0, name
        for hand in ("left_hand", "right_hand"):
            assert s["task_errors"][hand]["final"] < 1e-3, (name, hand)
        # the torso leans: the base moves back to keep the CoM over the feet
        q0, qf = r.log.q[0], r.log.q[-1]
        assert qf[0] < q0[0] - 0.01, name
        assert s["fallbacks"] == 0


def test_bad_balance_input_names_the_key() -> None:
    import yaml

    data = yaml.safe_load((TASKS / "humanoid_balance.yaml").read_text())
    data["robot"] = str(TASKS.parent / "configs/talos_floating.yaml")
    data["potentials"]["support"]["feet"] = ["left_sole_link", "left_toe"]
    with pytest.raises(ConfigError, match=r"potentials\.support\.feet\[1\]: frame 'left_toe' does not exist"):
        load_task(data)
    data = yaml.safe_load((TASKS / "humanoid_balance.yaml").read_text())
    data["robot"] = str(TASKS.parent / "configs/talos_floating.yaml")
    data["collision"]["links"] = ["torso_2_link", "left_arm"]
    with pytest.raises(ConfigError, match=r"collision\.links: unknown link\(s\) 'left_arm'"):
        load_task(data)

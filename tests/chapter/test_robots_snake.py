"""Hyper-redundant snake (section 5.2): the generator, the committed 40-joint config, r = 34, and the task runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from redundik.config import load_robot, load_task
from redundik.config.runner import run_task
from redundik.errors import ModelError
from redundik.kinematics import dh_matrix, numeric_rank, snake, snake_config, snake_rows

ROOT = Path(__file__).resolve().parents[2]


def test_committed_snake40_is_the_generator_output() -> None:
    committed = yaml.safe_load((ROOT / "configs/snake40.yaml").read_text())
    assert committed == yaml.safe_load(yaml.safe_dump(snake_config(40)))


def test_snake_forward_kinematics_is_the_product_of_a_matrices() -> None:
    robot = snake(12, link=0.2)
    q = np.random.default_rng(1).uniform(-1, 1, 12)
    robot.update(q)
    a = np.eye(4)
    for i in range(12):
        a = a @ dh_matrix(q[i], 0.0, 0.2, np.pi / 2 if i % 2 == 0 else -np.pi / 2)
    np.testing.assert_allclose(robot.frame_pose("12").homogeneous, a, atol=1e-12)


@pytest.mark.parametrize("n", [10, 40, 80])
def test_snake_degree_of_redundancy_is_n_minus_6(n: int) -> None:
    robot = snake(n)
    rng = np.random.default_rng(n)
    robot.update(robot.random_configuration(rng))
    assert n - numeric_rank(robot.frame_jacobian(str(n))) == n - 6


def test_snake_generator_rejects_bad_parameters() -> None:
    with pytest.raises(ModelError, match="needs 2 to 256 joints, got 1"):
        snake_rows(1)
    with pytest.raises(ModelError, match="must be > 0"):
        snake_rows(5, link=0.0)


@pytest.fixture(scope="module")
def runs():
    plan = load_task(ROOT / "tasks/snake40.yaml")
    return run_task(plan)


def test_snake_tip_tracks_and_subtasks_fill_the_null_space(runs) -> None:
    robot = load_robot("configs/snake40.yaml", ROOT).model
    assert robot.nv == 40
    for r in runs.values():
        assert r.summary["max_task_error"] < 5e-3
        assert r.summary["limit_violations"] == 0
    assert runs["rank_only"].summary["min_clearance"] < 0.0  # the rank solution drags link 10 into its obstacle
    assert runs["subtasks_pinv"].summary["min_clearance"] > 0.02
    assert runs["hqp"].summary["min_clearance"] > 0.025  # bound 0.03 m, up to the Euler step
    # the hierarchy also centres the joints (level 2) while holding the clearances
    cent = runs["hqp"].log.potentials["centering"]
    assert cent[-1] < 0.7 * cent[0]
    # independently of the logs' potentials: clearance of link 10 from the logged frame origins
    p10 = runs["rank_only"].log.q  # configurations
    robot.update(p10[-1])
    d = np.linalg.norm(robot.frame_position("10") - np.array([0.771, 0.473, 0.377])) - 0.06
    assert d == pytest.approx(runs["rank_only"].log.potentials["obstacle10"][-1], abs=1e-12)

"""Two cooperating robots (block-diagonal Jacobian + coordination constraint, section 5.3) and the mobile
Stanford arm (degree of redundancy r = 2 coaxial / r = 3 tilted, Fig. 5.12)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from redundik.config import load_robot, load_task
from redundik.config.runner import run_task
from redundik.kinematics import degree_of_redundancy, numeric_rank
from redundik.tasks import RelativePoseTask

ROOT = Path(__file__).resolve().parents[2]
RNG = np.random.default_rng(5)
ARM = ["1", "2", "3", "4", "5", "6"]


def test_two_robots_jacobian_is_block_diagonal_and_coordination_leaves_the_object_dofs() -> None:
    robot = load_robot("configs/two_robots.yaml", ROOT).model
    for _ in range(3):
        robot.update(robot.random_configuration(RNG))
        J = np.vstack([robot.frame_jacobian("a6"), robot.frame_jacobian("b6")])
        assert np.all(J[:6, 6:] == 0) and np.all(J[6:, :6] == 0)
        assert numeric_rank(J) == 12  # 12×12, not redundant by itself
        grasp = RelativePoseTask("b6", "a6")
        grasp.reset(robot)
        # the coordination constraint removes 6 dofs: 6 left for the carried object (hand A's pose)
        jrel = grasp.jacobian(robot)
        assert numeric_rank(jrel) == 6
        assert 12 - numeric_rank(np.vstack([jrel, J[:3]])) == 3  # object position only: r = 3


def test_two_robots_carry_the_object_rigidly() -> None:
    plan = load_task(ROOT / "tasks/two_robots.yaml")
    plan.steps = 200
    res = run_task(plan)
    model = load_robot("configs/two_robots.yaml", ROOT).model

    def rel(q: np.ndarray) -> pin.SE3:
        model.update(q)
        return model.frame_pose("a6").actInv(model.frame_pose("b6"))

    for r in res.values():
        assert r.summary["max_task_error"] < 2e-3
        rel0 = rel(r.log.q[0])
        for k in (100, 200):
            d = rel(r.log.q[k])
            assert np.linalg.norm(d.translation - rel0.translation) < 1e-3
            assert np.linalg.norm(pin.log3(d.rotation @ rel0.rotation.T)) < 1e-3
        # hand A is on its circle of radius 0.1 m in the y–z plane
        a = r.log.frame_positions["a6"]
        assert np.ptp(a[:, 0]) < 1e-3
        assert np.ptp(a[:, 1]) > 0.09
    c = {n: res[n].log.potentials["centering"][-1] for n in res}
    assert c["carry_position_centering"] < c["carry"]


@pytest.mark.parametrize(("config", "expected"), [("mobile_stanford", 2), ("mobile_stanford_tilted", 3)])
def test_mobile_stanford_degree_of_redundancy(config: str, expected: int) -> None:
    robot = load_robot(f"configs/{config}.yaml", ROOT).model
    r, n_eff = degree_of_redundancy(robot, ARM, 6, samples=10, rng=RNG)
    assert (r, n_eff) == (expected, 6 + expected)
    # independently: the yaw and waist columns coincide in every arm frame Jacobian iff they are coaxial
    robot.update(robot.random_configuration(RNG))
    iy, i1 = robot.joint("yaw").idx_v, robot.joint("1").idx_v
    J = robot.frame_jacobian("6")
    same = np.allclose(J[:, iy], J[:, i1], atol=1e-12)
    assert same == (expected == 2)
    # the naive count n − m = 3 holds for the hand Jacobian alone in both cases
    assert robot.nv - numeric_rank(J) == 3


def test_degree_of_redundancy_rejects_bad_samples() -> None:
    from redundik.errors import ModelError

    robot = load_robot("configs/mobile_stanford.yaml", ROOT).model
    with pytest.raises(ModelError, match="samples"):
        degree_of_redundancy(robot, ARM, 6, samples=0)


def test_mobile_stanford_cart_travels_while_the_arm_keeps_its_posture() -> None:
    res = run_task(load_task(ROOT / "tasks/mobile_stanford.yaml"))
    for r in res.values():
        hand = r.log.frame_positions["6"]
        np.testing.assert_allclose(hand[-1] - hand[0], [1.0, 0.5, 0.0], atol=2e-3)  # 10 s at (0.1, 0.05, 0) m/s
        assert r.summary["limit_violations"] == 0
    arm = slice(3, 9)
    q0 = res["arm_home"].log.q[0]
    drift_home = np.abs(res["arm_home"].log.q[:, arm] - q0[arm]).max()
    drift_rank = np.abs(res["rank_only"].log.q[:, arm] - q0[arm]).max()
    assert drift_home < 0.5 * drift_rank
    cart_home = np.hypot(*res["arm_home"].log.q[-1, :2])
    assert cart_home > 0.9  # the cart did most of the 1.12 m

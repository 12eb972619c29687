"""Free-flyer base quaternions: a near-unit one is normalised (within QUATERNION_TOLERANCE), a zero, tiny or far
from unit one is refused naming the joint, at the API (check_configuration, update, Resolver.step) and in YAML."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import redundik as rk
from redundik.kinematics.model import QUATERNION_TOLERANCE

CHAIN = (
    "<robot name='c'><link name='l0'/><link name='l1'/><joint name='j1' type='revolute'><parent link='l0'/>"
    "<child link='l1'/><origin xyz='0.5 0 0'/><axis xyz='0 0 1'/><limit lower='-2' upper='2' effort='1' "
    "velocity='2'/></joint></robot>"
)


@pytest.fixture
def floating(tmp_path: Path) -> rk.RobotModel:
    path = tmp_path / "c.urdf"
    path.write_text(CHAIN)
    return rk.from_urdf(path, free_flyer=True)


def _q(quat: list[float]) -> np.ndarray:
    return np.array([0.1, 0.2, 0.3, *quat, 0.4])


@pytest.mark.parametrize("quat", [[0, 0, 0, 0], [0, 0, 0, 1e-9], [0, 0, 0, 0.5], [0, 0, 0, 3.0]])
def test_a_degenerate_base_quaternion_is_refused_naming_the_joint(floating: rk.RobotModel, quat: list[float]) -> None:
    q = _q(quat)
    with pytest.raises(rk.ModelError, match=r"root_joint.*quaternion"):
        floating.check_configuration(q)
    with pytest.raises(rk.ModelError, match=r"root_joint.*quaternion"):
        floating.update(q)
    stack = rk.TaskStack([rk.FrameTask("l1", rk.Hold(), axes="position")])
    for method in ("pinv", "wqp"):
        with pytest.raises(rk.RedundikError, match=r"root_joint.*quaternion"):
            rk.make_resolver(method).step(floating, stack, q, 0.0, 0.01)


def test_a_near_unit_quaternion_is_normalised(floating: rk.RobotModel) -> None:
    s = 1.0 + 0.5 * QUATERNION_TOLERANCE
    q = _q([0.0, 0.0, 0.6 * s, 0.8 * s])
    out = floating.check_configuration(q)
    np.testing.assert_allclose(out[3:7], [0.0, 0.0, 0.6, 0.8], atol=1e-15)
    assert q[6] == 0.8 * s  # the caller's array is left alone
    floating.update(q)
    np.testing.assert_allclose(np.linalg.det(floating.frame_pose("l1").rotation), 1.0, atol=1e-12)
    stack = rk.TaskStack([rk.FrameTask("l1", rk.Line([0.0, 0.1, 0.0]), axes="position")])
    stack.reset(floating)
    dq = rk.make_resolver("wqp").step(floating, stack, q, 0.0, 0.01).dq
    assert np.isfinite(dq).all() and np.linalg.norm(dq) < 10.0


def test_a_degenerate_quaternion_in_a_task_file_is_refused_with_its_key_path(
    tmp_path: Path, cli: Callable[..., tuple[int, str, str]]
) -> None:
    (tmp_path / "c.urdf").write_text(CHAIN)
    (tmp_path / "robot.yaml").write_text("name: c\nurdf: c.urdf\nfree_flyer: true\nangle_unit: rad\n")
    (tmp_path / "task.yaml").write_text(
        "name: t\nrobot: robot.yaml\nangle_unit: rad\nq0: [0, 0, 0, 0, 0, 0, 0, 0.1]\ndt: 0.01\nsteps: 3\n"
        "main:\n  - {name: tip, type: frame, frame: l1, axes: position, trajectory: {type: hold}}\n"
        "runs:\n  a: {resolver: pinv}\n"
    )
    code, out, err = cli("validate", tmp_path / "task.yaml")
    assert code != 0
    assert "q0" in out + err and "quaternion" in out + err and "root_joint" in out + err

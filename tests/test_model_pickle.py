"""A robot model survives a pickle and a deep copy on every Pinocchio the project declares (pin>=3.3.1, 3.8, 4).

Pinocchio before 4 pickles a ``pin.Model`` through a Boost text archive, which writes an infinite limit as ``inf`` and
cannot read it back (``RuntimeError: input stream error``). redundik's own builders leave the effort limit (and,
without limits, the position and velocity limits) infinite, so every resolver that had stepped — and holds its robot —
failed to pickle on pin 3.8. These tests run in the lowest-versions CI job (``.ci/run``) as well as the default one.
"""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.kinematics.snake import snake


def _unlimited_dh() -> rk.RobotModel:
    """Three revolute rows without limits: infinite position, velocity and effort limits."""
    return rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", a=1.0), rk.DHRow("3", a=0.5)])


def _vector_fields(model: pin.Model) -> dict[str, np.ndarray]:
    """The model's float vectors (limits, armature, ...) by name, as this Pinocchio names them."""
    fields = {}
    for name in dir(model):
        if not name.startswith("_"):
            value = getattr(model, name)
            if isinstance(value, np.ndarray) and value.dtype.kind == "f":
                fields[name] = np.array(value)
    return fields


@pytest.mark.parametrize("build", [_unlimited_dh, lambda: snake(6)], ids=["dh_unlimited", "snake6"])
def test_a_robot_with_infinite_limits_pickles_and_copies(build: object) -> None:
    robot = build()  # type: ignore[operator]
    assert not np.isfinite(robot.model.effortLimit).all()  # the case Pinocchio 3's text archive cannot read back
    q = np.linspace(0.1, 0.4, robot.nq)
    robot.update(q)
    frame = robot.frame_names[-1]
    for twin in (pickle.loads(pickle.dumps(robot)), copy.deepcopy(robot)):
        before, after = _vector_fields(robot.model), _vector_fields(twin.model)
        assert before.keys() == after.keys()
        for name, value in before.items():
            np.testing.assert_array_equal(after[name], value, err_msg=name)  # the infinities come back as infinities
        assert twin.joints == robot.joints and twin.name == robot.name
        twin.update(q)
        np.testing.assert_array_equal(twin.frame_position(frame), robot.frame_position(frame))
        np.testing.assert_array_equal(twin.frame_jacobian(frame), robot.frame_jacobian(frame))
    # the original's model is left as it was (the pickle masks a copy, not the model in use)
    assert not np.isfinite(robot.model.effortLimit).all()

"""A typo in a name gets the close matches first, then the full list (issue 32, item 13: pink/mink habits)."""

from __future__ import annotations

import re

import numpy as np
import pytest

import redundik as rk
from redundik._names import close_matches, did_you_mean
from redundik.errors import ModelError, ResolverError, SolverError
from redundik.resolvers.qp.backends import make_backend
from redundik.shipped import example_urdf


@pytest.fixture(scope="module")
def arm() -> rk.RobotModel:
    return rk.from_urdf(example_urdf("arm4"))


def _hint(message: str) -> str:
    """The part of a message before the full listing."""
    found = re.search(r"did you mean (.*?)\?", message)
    assert found, message
    return found.group(1)


def test_close_matches() -> None:
    assert close_matches("panda_hand_tc", ["panda_hand", "panda_hand_tcp", "panda_link7"])[0] == "panda_hand_tcp"
    assert close_matches("TOOL", ["tool", "base"]) == ["tool"]  # case does not hide a match
    assert close_matches("zzz", ["tool", "base"]) == [] and did_you_mean("zzz", ["tool"]) == ""
    assert close_matches(None, ["tool"]) == [] and close_matches("", ["tool"]) == []
    assert did_you_mean("tol", ["tool", "tools"]) == "did you mean 'tool' or 'tools'? "


def test_a_frame_typo_says_did_you_mean(arm: rk.RobotModel) -> None:
    with pytest.raises(ModelError) as info:
        arm.frame_id("tol")
    message = str(info.value)
    assert "'tool'" in _hint(message) and "available: base, yaw" in message  # the hint, then the full list
    with pytest.raises(ModelError) as info:
        arm.frame_id("qqqqqq")
    assert "did you mean" not in str(info.value) and "available:" in str(info.value)


def test_a_frame_typo_in_a_task_says_did_you_mean(arm: rk.RobotModel) -> None:
    stack = rk.TaskStack([rk.FrameTask("toool", axes="position")])
    arm.update(np.zeros(4))
    with pytest.raises(rk.RedundikError) as info:
        stack.reset(arm)
    assert "'tool'" in _hint(str(info.value))


def test_a_joint_typo_says_did_you_mean(arm: rk.RobotModel) -> None:
    with pytest.raises(ModelError) as info:
        arm.joint("elbw")
    assert _hint(str(info.value)) == "'elbow'" and "available:" in str(info.value)


def test_a_resolver_typo_says_did_you_mean() -> None:
    with pytest.raises(ResolverError) as info:
        rk.make_resolver("wpq")
    assert "'wqp'" in _hint(str(info.value)) and "available:" in str(info.value)


def test_a_backend_typo_says_did_you_mean() -> None:
    with pytest.raises(SolverError) as info:
        make_backend("dqap")
    assert _hint(str(info.value)) == "'daqp'" and "installed:" in str(info.value)

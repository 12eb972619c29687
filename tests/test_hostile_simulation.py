"""Hostile arguments to ``simulate``: a bad time grid refused before the logs are allocated, the wrong kind of
robot, stack or resolver named."""

from __future__ import annotations

import numpy as np
import pytest

import redundik as rk
from tests.hostile import _planar


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({"dt": 0.0, "steps": 3}, "dt must be finite and > 0"),
        ({"dt": True, "steps": 3}, "dt must be a number"),
        ({"dt": 0.01, "steps": -1}, "steps must be ≥ 0"),
        ({"dt": 0.01, "steps": 2.5}, "steps must be a whole number"),
        ({"dt": 0.01, "steps": 10**12}, "GiB"),
    ],
)
def test_simulate_refuses_a_bad_time_grid_before_allocating(kwargs: dict[str, object], expected: str) -> None:
    from redundik.errors import SimulationError

    robot, stack, q = _planar()
    with pytest.raises(SimulationError) as info:
        rk.simulate(robot, stack, rk.make_resolver("pinv"), q, **kwargs)  # type: ignore[arg-type]
    assert expected in str(info.value)
    log = rk.simulate(robot, stack, rk.make_resolver("pinv"), q, dt=0.01, steps=2)
    assert log.q.shape == (3, 3) and np.isfinite(log.q).all()


def test_simulate_with_the_wrong_kind_of_argument_says_so() -> None:
    from redundik.errors import SimulationError

    robot, stack, q = _planar()
    with pytest.raises(SimulationError, match="stack must be a TaskStack, got list"):
        rk.simulate(robot, list(stack.tasks), rk.make_resolver("pinv"), q, dt=0.01, steps=2)  # type: ignore[arg-type]
    with pytest.raises(SimulationError, match="resolver must be a Resolver"):
        rk.simulate(robot, stack, "pinv", q, dt=0.01, steps=2)  # type: ignore[arg-type]

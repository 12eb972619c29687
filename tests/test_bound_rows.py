"""``BoundSubtask.rows_into``, the one implementation of a potential's velocity-damper rows C q̇ ≤ d (lower:
C = −η, d = γ(p − lower); upper: C = η, d = γ(upper − p); γ = min(K or 1/dt, 1/dt)), against that formula written
out from the potential's (p, η), and what ``rows`` and ``values`` give through it."""

from __future__ import annotations

import numpy as np
import pytest

import redundik as rk
from redundik.errors import TaskError
from redundik.tasks.potentials import Clearance


def _potentials(robot: rk.RobotModel) -> list[rk.Potential]:
    names = robot.joint_names
    return [
        rk.JointValue(names[2], 0.3, name="jv"),
        rk.JointCentering(name="centre"),
        Clearance("panda_link4", [0.2, 0.3, 0.4], radius=0.05, axes=("x", "y"), name="post"),
    ]


@pytest.mark.parametrize("bounds", [(0.01, None), (None, 0.5), (-0.2, 0.6)])
@pytest.mark.parametrize("rate", [0.0, 10.0, 500.0])
def test_rows_into_is_the_damper_formula(bounds: tuple[float | None, float | None], rate: float) -> None:
    """Bitwise the formula from (p, η), written at an offset into larger buffers without touching the other rows;
    ``rows()`` gives the same arrays with the names ``name:lower`` / ``name:upper``; ``values()`` gives h and H."""
    lower, upper = bounds
    robot = rk.load_example_robot("panda")
    rng = np.random.default_rng(4)
    dt = 0.01
    cap = 1.0 / dt
    gamma = cap if rate == 0 else min(rate, cap)
    for pot in _potentials(robot):
        sub = rk.BoundSubtask(pot, lower=lower, upper=upper, rate=rate)
        sub.check(robot)
        k = (lower is not None) + (upper is not None)
        assert sub.fixed_rows == k
        for _ in range(3):
            robot.update(robot.random_configuration(rng))
            p, eta = pot.value_and_gradient(robot)
            C_ref, d_ref = [], []
            if lower is not None:
                C_ref.append(-eta)
                d_ref.append(gamma * (p - lower))
            if upper is not None:
                C_ref.append(eta)
                d_ref.append(gamma * (upper - p))
            C = np.full((k + 3, robot.nv), 7.0)
            d = np.full(k + 3, 7.0)
            assert sub.rows_into(robot, dt, C, d, 2) == k
            np.testing.assert_array_equal(C[2 : 2 + k], np.array(C_ref))
            np.testing.assert_array_equal(d[2 : 2 + k], np.array(d_ref))
            assert (C[:2] == 7.0).all() and (C[2 + k :] == 7.0).all() and (d[:2] == 7.0).all()
            Cr, dr, names = sub.rows(robot, dt)
            np.testing.assert_array_equal(Cr, np.array(C_ref))
            np.testing.assert_array_equal(dr, np.array(d_ref))
            assert names == [f"{pot.name}:{s}" for s, b in (("lower", lower), ("upper", upper)) if b is not None]
            h, H, vnames, g = sub.values(robot)
            np.testing.assert_array_equal(H, -np.array(C_ref))
            assert vnames == names and g is None
            if lower is not None:
                assert h[0] == p - lower
            if upper is not None:
                assert h[-1] == upper - p


def test_row_names_follow_renames_and_bounds() -> None:
    """The cached names follow a new name and bounds set after construction; callers get copies from rows()."""
    robot = rk.load_example_robot("panda")
    robot.update(robot.neutral())
    sub = rk.BoundSubtask(rk.JointValue(robot.joint_names[0], 0.0, name="a"), lower=-1.0)
    _, _, names = sub.rows(robot, 0.01)
    assert names == ["a:lower"]
    names.append("junk")
    assert sub.row_names == ["a:lower"]
    sub.name = "b"
    sub.upper = 1.0
    assert sub.fixed_rows == 2
    C, d, names = sub.rows(robot, 0.01)
    assert names == ["b:lower", "b:upper"] and C.shape == (2, robot.nv) and d.shape == (2,)


class _Wall(rk.Barrier):
    name = "wall"

    def evaluate(self, robot: rk.RobotModel) -> rk.BarrierTerm:
        H = np.zeros((1, robot.nv))
        H[0, 0] = 1.0
        return rk.BarrierTerm(np.array([0.5 + robot.q[0]]), H, ["w"])


def test_a_barrier_keeps_its_own_rows() -> None:
    """A barrier has no fixed row count and no rows_into (rows() evaluates it)."""
    robot = rk.load_example_robot("panda")
    robot.update(robot.neutral())
    sub = rk.BoundSubtask(_Wall(), rate=5.0)
    assert sub.fixed_rows is None
    with pytest.raises(TaskError, match="rows\\(\\)"):
        sub.rows_into(robot, 0.01, np.zeros((1, robot.nv)), np.zeros(1), 0)
    C, d, names = sub.rows(robot, 0.01)
    assert names == ["wall:w"] and C[0, 0] == -1.0 and d[0] == 5.0 * (0.5 + robot.q[0])

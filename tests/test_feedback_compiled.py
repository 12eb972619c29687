"""The ``feedback`` resolver's compiled step (issue 31 item 3: every shipped stack on the compiled path): the main
rows and z as ``pinv``'s fused step writes them, the target subtasks' rows from their potentials' compiled writers
(or their Python ``row``: a mixed step), the law (after eq. 5.15) in one compiled call — the same q̇, gains and
report as the per-task path (``fuse = False``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import redundik as rk
from redundik.config.loader import load_task

TASKS = Path(__file__).resolve().parents[1] / "tasks"
DT = 0.01


def _agree(a: rk.StepResult, b: rk.StepResult) -> None:
    scale = max(1.0, float(np.abs(b.dq).max()))
    assert np.abs(a.dq - b.dq).max() <= 1e-12 * scale
    assert a.gains is not None and b.gains is not None
    assert np.allclose(a.gains, b.gains, rtol=1e-10, atol=1e-12)
    assert a.dq_rank is not None and b.dq_rank is not None
    assert np.abs(a.dq_rank - b.dq_rank).max() <= 1e-12 * scale
    for key in ("rank", "D_rank", "D_damped"):
        assert a.info[key] == b.info[key], key
    assert a.info["sigma_min"] == pytest.approx(b.info["sigma_min"], rel=1e-9)
    assert a.damped == b.damped
    assert [t.name for t in a.terms] == [t.name for t in b.terms]
    for ta, tb in zip(a.terms, b.terms, strict=True):
        assert np.allclose(ta.J, tb.J, atol=1e-12) and np.allclose(ta.v, tb.v, atol=1e-12)


def _run_both(robot: rk.RobotModel, stacks: list[rk.TaskStack], q0: np.ndarray, steps: int) -> list[str]:
    """Step the compiled and the per-task copy on the compiled copy's configurations; the paths it reported."""
    resolvers = [rk.make_resolver("feedback"), rk.make_resolver("feedback")]
    resolvers[1].fuse = False  # type: ignore[attr-defined]
    q, paths = q0.copy(), []
    for k in range(steps):
        a = resolvers[0].step(robot, stacks[0], q, k * DT, DT)
        b = resolvers[1].step(robot, stacks[1], q, k * DT, DT)
        assert b.info["path"] == "interpreted"
        _agree(a, b)
        paths.append(str(a.info["path"]))
        q = robot.integrate(q, a.dq, DT)
    return paths


@pytest.mark.parametrize(
    ("file", "run", "path", "python"),
    [
        ("planar3r_line.yaml", "feedback", "compiled", ()),
        ("dualarm17.yaml", "independent_feedback", "compiled", ()),
    ],
)
def test_shipped_feedback_runs_take_the_compiled_step(file: str, run: str, path: str, python: tuple[str, ...]) -> None:
    items = [load_task(TASKS / file) for _ in range(2)]
    robot = items[0].robot.model
    stacks = [item.runs[run].stack for item in items]
    for stack in stacks:
        stack.reset(robot)
    resolvers = [item.runs[run].resolver for item in items]
    resolvers[1].fuse = False  # type: ignore[attr-defined]
    q = items[0].runs[run].q0.copy()
    for k in range(60):
        a = resolvers[0].step(robot, stacks[0], q, k * DT, DT)
        b = resolvers[1].step(robot, stacks[1], q, k * DT, DT)
        _agree(a, b)
        assert a.info["path"] == path and tuple(a.info["interpreted"]) == python
        q = robot.integrate(q, a.dq, DT)


class Height(rk.Potential):
    """A user's Python potential (no compiled writer): the height of a frame [m]."""

    def __init__(self, frame: str) -> None:
        self.frame = frame
        self.name = f"height_{frame}"

    def value(self, robot: rk.RobotModel) -> float:
        return float(robot.frame_position(self.frame)[2])

    def gradient(self, robot: rk.RobotModel) -> np.ndarray:
        return np.array(robot.frame_jacobian(self.frame)[2])


def _arm() -> tuple[rk.RobotModel, np.ndarray]:
    robot = rk.from_dh([rk.DHRow(str(k), a=0.3, alpha=np.pi / 2 if k % 2 else -np.pi / 2) for k in range(1, 8)])
    return robot, np.full(robot.nq, 0.3)


def _stack(robot: rk.RobotModel, q: np.ndarray, python_target: bool, second: bool = True) -> rk.TaskStack:
    subs: list[rk.Subtask] = [
        rk.TargetSubtask(rk.JointSine2("4"), target=0.6, rate=2.0),
        rk.GradientSubtask(rk.JointValue("2", 0.9), gain=-2.0),  # (a centering has no range to centre here: z = 0)
    ]
    if second:
        subs.insert(1, rk.TargetSubtask(Height("5") if python_target else rk.JointSine2("6"), target=0.4, rate=1.0))
    stack = rk.TaskStack([rk.FrameTask("7", rk.Circle(0.05, np.pi, plane=("y", "z")), axes="position", gain=5.0)], subs)
    robot.update(q)
    stack.reset(robot)
    return stack


@pytest.mark.parametrize("python_target", [False, True])
def test_compiled_law_matches_the_per_task_path(python_target: bool) -> None:
    robot, q0 = _arm()
    paths = _run_both(robot, [_stack(robot, q0, python_target) for _ in range(2)], q0, 80)
    assert set(paths) == {"mixed" if python_target else "compiled"}


def test_a_rank_deficient_D_is_damped_alike() -> None:
    """Two target subtasks on the same potential: D = NᵀPN has rank 1 (its zero direction truncated, k finite)."""
    robot, q0 = _arm()
    stacks = []
    for _ in range(2):
        stack = _stack(robot, q0, False, second=False)
        stack.subtasks.insert(1, rk.TargetSubtask(rk.JointSine2("4"), target=0.5, rate=1.0, name="twin"))
        robot.update(q0)
        stack.reset(robot)
        stacks.append(stack)
    resolver = rk.make_resolver("feedback")
    res = resolver.step(robot, stacks[0], q0, 0.0, DT)
    assert res.info["path"] == "compiled" and res.info["D_rank"] == 1
    assert res.gains is not None and np.isfinite(res.gains).all()
    _run_both(robot, stacks, q0, 20)


def test_targets_and_rates_are_data_and_membership_replans() -> None:
    robot, q0 = _arm()
    stacks = [_stack(robot, q0, False) for _ in range(2)]
    resolvers = [rk.make_resolver("feedback"), rk.make_resolver("feedback")]
    resolvers[1].fuse = False  # type: ignore[attr-defined]
    q = q0.copy()
    for k in range(30):
        if k == 10:
            for s in stacks:
                s.subtasks[0].set_target(0.2, target_rate=0.1)  # type: ignore[attr-defined]
                s.subtasks[1].rate = 3.0  # type: ignore[attr-defined]
        if k == 20:
            for s in stacks:
                del s.subtasks[1]
        a, b = (r.step(robot, s, q, k * DT, DT) for r, s in zip(resolvers, stacks, strict=True))
        _agree(a, b)
        assert a.gains is not None and a.gains.shape == ((2,) if k < 20 else (1,))
        q = robot.integrate(q, a.dq, DT)


class BrokenHeight(Height):
    def gradient(self, robot: rk.RobotModel) -> np.ndarray:
        g = super().gradient(robot)
        g[0] = np.nan
        return g


def test_a_non_finite_target_row_is_diagnosed_as_on_the_per_task_path() -> None:
    robot, q0 = _arm()
    results = []
    for fuse in (True, False):
        stack = _stack(robot, q0, True)
        stack.subtasks[1].potential = BrokenHeight("5")  # type: ignore[attr-defined]
        resolver = rk.make_resolver("feedback")
        resolver.fuse = fuse  # type: ignore[attr-defined]
        try:
            results.append(resolver.step(robot, stack, q0, 0.0, DT))
        except rk.RedundikError as exc:
            results.append(str(exc))  # type: ignore[arg-type]
    a, b = results
    if isinstance(b, str):
        assert a == b
    else:
        assert isinstance(a, rk.StepResult)
        assert a.fallback == b.fallback and np.array_equal(a.dq, b.dq)
        assert np.isfinite(a.dq).all()

"""Which path the shipped task files take (issue 31 item 3): every run of ``tasks/*.yaml`` under a resolver with a
compiled step is compiled, but for the members whose class has no compiled form yet — named here, so that a member
that loses its compiled form (or a new file that needs one) fails this test."""

from __future__ import annotations

from pathlib import Path

import pytest

from redundik.config.loader import load_task

TASKS = Path(__file__).resolve().parents[1] / "tasks"
#: Classes without a compiled form: their rows come from Python (a mixed step names them): coal's distances of the
#: collision barrier.
NOT_COMPILED = {"CollisionAvoidance"}


def _source_class(member: object) -> str:
    inner = getattr(member, "potential", None) or getattr(member, "source", None) or member
    return type(inner).__name__


@pytest.mark.parametrize("path", sorted(TASKS.glob("*.yaml")), ids=lambda p: p.stem)
def test_shipped_runs_are_compiled_but_for_the_named_classes(path: Path) -> None:
    plan = load_task(path)
    robot = plan.robot.model
    for name, run in plan.runs.items():
        members = {m.name: m for m in [*run.stack.tasks, *run.stack.subtasks]}
        allowed = {n for n, m in members.items() if _source_class(m) in NOT_COMPILED}
        q = run.q0.copy()
        run.stack.reset(robot)
        for k in range(3):
            res = run.resolver.step(robot, run.stack, q, k * 0.01, 0.01)
            q = robot.integrate(q, res.dq, 0.01)
        interpreted = set(res.info["interpreted"])
        assert interpreted <= allowed, f"{path.name} run '{name}': {sorted(interpreted - allowed)} not compiled"
        if not interpreted:
            assert res.info["path"] == "compiled", f"{path.name} run '{name}'"

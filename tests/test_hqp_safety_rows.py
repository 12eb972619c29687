"""hqp's fused step with safety rows (a critical barrier: the collision damper): its answer is kept only when it
holds them; otherwise the step is the template's (solved, relaxed and guarded as without the fused step).

The shipped ``panda_shelf`` hqp run (the damper at level 0, above the hand) is stepped on both paths from the same
configurations: the same q̇ to the backends' tolerance, every step fused, and — with the fused answer refused at
every step — every step the template's, equal to the per-task path exactly.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from redundik.resolvers.qp.base import SAFETY_TOLERANCE, QPResolverBase
from redundik.resolvers.qp.hqp import HierarchicalQPResolver
from redundik.resolvers.qp.hqp_plan import _Plan
from tests.conftest import TASKS


def _copies() -> list[tuple[Any, Any, Any, np.ndarray, float]]:
    from redundik.config import load_task

    out = []
    for fuse in (True, False):
        plan = load_task(Path(TASKS / "panda_shelf.yaml"))
        item = plan.runs["hqp"]
        item.resolver.fuse = fuse
        robot = plan.robot.model
        item.stack.reset(robot)
        out.append((robot, item.stack, item.resolver, item.q0.copy(), float(plan.dt)))
    return out


def _lockstep(steps: int, monkeypatch: pytest.MonkeyPatch | None = None) -> tuple[np.ndarray, dict[str, int]]:
    """Both copies stepped on the fused copy's configurations: the largest |q̇ difference| per step, and how the
    fused copy's steps went (fused answers kept, template steps)."""
    count = {"fused": 0, "template": 0}
    solve_fused, template = HierarchicalQPResolver._fused_solve, QPResolverBase.solve

    def fused(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        res = solve_fused(self, *args, **kwargs)
        count["fused"] += res is not None and self.fuse
        return res

    def tpl(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        count["template"] += bool(self.fuse)
        return template(self, *args, **kwargs)

    assert monkeypatch is not None
    monkeypatch.setattr(HierarchicalQPResolver, "_fused_solve", fused)
    monkeypatch.setattr(QPResolverBase, "solve", tpl)
    (ra, sa, a, q, dt), (rb, sb, b, _, _) = _copies()
    diffs = []
    for k in range(steps):
        x = a.step(ra, sa, q, k * dt, dt)
        y = b.step(rb, sb, q, k * dt, dt)
        assert x.fallback is None and y.fallback is None, (x.fallback, y.fallback)
        diffs.append(float(np.abs(x.dq - y.dq).max()))
        q = ra.integrate(q, x.dq, dt)
    return np.array(diffs), count


def test_the_fused_step_keeps_the_safety_rows_and_the_per_task_answer(monkeypatch: pytest.MonkeyPatch) -> None:
    diffs, count = _lockstep(300, monkeypatch)
    assert count == {"fused": 300, "template": 0}, count
    assert diffs.max() < 1e-6, diffs.max()  # (the same cascade; QP levels to daqp's tolerance)


def test_a_fused_answer_that_breaks_a_safety_row_is_the_templates_step(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_Plan, "keeps_safety_rows", lambda self, dq: False)
    diffs, count = _lockstep(60, monkeypatch)
    assert count == {"fused": 0, "template": 60}, count
    assert diffs.max() == 0.0  # the template's step is the per-task path's, to the bit


def test_keeps_safety_rows_reads_the_rows_the_step_wrote() -> None:
    (robot, stack, res, q, dt), _ = _copies()
    for k in range(150):  # until the forearm is near the post: the damper has rows
        q = robot.integrate(q, res.step(robot, stack, q, k * dt, dt).dq, dt)
    plan = res._plan
    assert plan.critical and plan.safety_rows
    a, e = plan.safety_rows[0]
    assert e > a
    C, d = plan.C[a:e], plan.d[a:e]
    dq = np.zeros(robot.nv)
    assert plan.keeps_safety_rows(dq) == bool((d >= -SAFETY_TOLERANCE).all())
    row = int(np.argmax(np.linalg.norm(C, axis=1)))
    push = C[row] / float(C[row] @ C[row]) * (max(float(d[row]), 0.0) + 1e-3)  # breaks that row by 1e-3
    assert not plan.keeps_safety_rows(push)
    assert plan.keeps_safety_rows(0.5 * push) == bool((C @ (0.5 * push) <= d + SAFETY_TOLERANCE).all())

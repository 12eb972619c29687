"""The live meshcat viewer: cheap per-tick calls, and headless Chromium sees the Panda move on its page."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from redundik.viewer.live import LiveViewer, tick_cost
from tests.conftest import TASKS
from tests.viewer.browser import changed, chromium, screenshot

SIZE = (800, 600)


@pytest.fixture(scope="module")
def viewer() -> Iterator[tuple[LiveViewer, np.ndarray]]:
    from redundik.config import load_task

    plan = load_task(TASKS / "panda_circle.yaml")
    v = LiveViewer(plan.robot.model, plan.robot.urdf, rate_hz=30.0, frames=["panda_hand_tcp"])
    try:
        yield v, plan.q0
    finally:
        v.close()


def test_update_costs_the_loop_little(viewer: tuple[LiveViewer, np.ndarray]) -> None:
    v, q0 = viewer
    cost = tick_cost(v, q0, ticks=300, dt=0.005)  # 1.5 s of a 200 Hz loop
    assert cost["mean_us"] < 500, cost  # the push (ms) happens on the viewer's thread
    assert 15 <= cost["pushes"] <= 60, cost  # ≈ 30 Hz, not one push per tick


def test_chromium_sees_the_robot_move_on_the_live_page(viewer: tuple[LiveViewer, np.ndarray], tmp_path: Path) -> None:
    chromium()
    v, q0 = viewer
    v.update(q0, force=True)
    at0 = screenshot(v.url, tmp_path / "q0.png", SIZE)
    q1 = q0.copy()
    q1[0] += 1.0
    q1[3] += 0.8
    v.update(q1, force=True)
    at1 = screenshot(v.url, tmp_path / "q1.png", SIZE)
    v.set_visible(False)
    empty = screenshot(v.url, tmp_path / "empty.png", SIZE)
    v.set_visible(True)
    h, w, _ = at0.shape
    view = (slice(int(0.05 * h), h), slice(0, w))
    robot = changed(at0, empty)[view]
    assert robot.mean() > 0.015, f"robot covers only {robot.mean():.1%} of the page"
    moved = changed(at0, at1)[view]
    assert moved.sum() > 500, f"only {moved.sum()} pixels changed between two configurations"

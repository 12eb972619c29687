"""The live meshcat viewer: per-tick calls that never push on the loop's thread, and headless Chromium sees the
Panda move on its page."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from redundik.viewer.live import LiveViewer
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


def test_update_hands_q_to_the_viewer_thread_and_the_latest_wins(
    viewer: tuple[LiveViewer, np.ndarray], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The control loop's call never pushes (no ZMQ round trip on its thread), updates coalesce (at most one push
    per period of the viewer's thread), and the last q given is the one shown. Structural, not timed: speed is
    measured by ``tick_cost`` / benchmarks, never asserted in a test."""
    v, q0 = viewer
    v.flush()
    pushed: list[tuple[str, np.ndarray]] = []
    real_push = v._push

    def spy(q: np.ndarray) -> None:
        pushed.append((threading.current_thread().name, q.copy()))
        real_push(q)

    monkeypatch.setattr(v, "_push", spy)
    updates = 300
    start = time.perf_counter()
    for k in range(updates):
        v.update(q0 + 1e-3 * k)
    elapsed = time.perf_counter() - start
    v.flush()
    last = q0 + 1e-3 * (updates - 1)
    deadline = time.perf_counter() + 10.0  # a hang guard: the worker's last push completes
    while not (pushed and np.array_equal(pushed[-1][1], last)) and time.perf_counter() < deadline:
        time.sleep(v.period)
    waited = time.perf_counter() - start - elapsed
    assert pushed, "nothing was pushed"
    assert all(name == "redundik-meshcat" for name, _ in pushed), {name for name, _ in pushed}
    # each push is followed by a sleep of the rest of its period: pushes ≤ 1 + (the time they had) / period
    assert len(pushed) <= 2 + (elapsed + waited) / v.period
    assert len(pushed) < updates
    np.testing.assert_array_equal(pushed[-1][1], last)


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


def test_update_refuses_a_bad_q_and_reports_a_failed_push(
    viewer: tuple[LiveViewer, np.ndarray], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A NaN or a wrong-sized q is refused in the caller's thread (the background thread used to die on it, and the
    viewer froze silently); a push that fails on the viewer's thread is reported by the next update."""
    from redundik.errors import ModelError

    v, q0 = viewer
    with pytest.raises(ModelError, match=r"live viewer: update\(q\): contains NaN"):
        v.update(np.full_like(q0, np.nan))
    with pytest.raises(ModelError, match=r"live viewer: update\(q\): expected 9 values"):
        v.update(q0[:3])

    def broken(q: np.ndarray) -> None:
        raise RuntimeError("meshcat went away")

    monkeypatch.setattr(v, "_push", broken)
    v.update(q0)
    deadline = time.perf_counter() + 10.0  # a hang guard for the worker's push
    while v._failed is None and time.perf_counter() < deadline:
        time.sleep(0.01)
    with pytest.raises(ModelError, match="could not show a configuration: RuntimeError: meshcat went away"):
        v.update(q0)
    monkeypatch.undo()
    v.update(q0, force=True)  # the viewer goes on

"""Computer project 1 (section 5.5.1): the RPR arm near a wall–floor corner, checked with hand formulas."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from redundik.config import load_task
from redundik.config.runner import run_task
from redundik.reporting.animate import animate_planar

ROOT = Path(__file__).resolve().parents[2]
A3, L2, WALL, FLOOR = 0.8, 1.8, -0.6, -0.4


def _hand(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tip and back end B by hand: tip = d2 u1 + a3 u13, B = (d2 − L2) u1."""
    u1 = np.array([np.cos(q[0]), np.sin(q[0])])
    u13 = np.array([np.cos(q[0] + q[2]), np.sin(q[0] + q[2])])
    return q[1] * u1 + A3 * u13, (q[1] - L2) * u1


@pytest.fixture(scope="module")
def runs():
    plan = load_task(ROOT / "tasks/rpr_corner.yaml")
    return plan, run_task(plan)


def test_model_matches_the_hand_formulas_and_starts_on_the_circle(runs) -> None:
    _, res = runs
    r = res["rank_only"]
    tip0, _ = _hand(r.log.q[0])
    np.testing.assert_allclose(tip0, [1.8, 1.0], atol=1e-3)
    for k in (0, 200, 400):
        tip, back = _hand(r.log.q[k])
        np.testing.assert_allclose(r.log.frame_positions["3"][k, :2], tip, atol=1e-12)
        np.testing.assert_allclose(r.log.frame_positions["B"][k, :2], back, atol=1e-12)
        assert r.log.potentials["wall_clearance"][k] == pytest.approx(back[0] - WALL, abs=1e-9)
        assert r.log.potentials["floor_clearance"][k] == pytest.approx(back[1] - FLOOR, abs=1e-9)


def test_every_run_draws_the_circle_ccw_at_half_a_radian_per_second(runs) -> None:
    _, res = runs
    t = res["rank_only"].log.t
    expected = np.c_[1.2 + 0.6 * np.cos(0.5 * t), 1.0 + 0.6 * np.sin(0.5 * t)]
    for r in res.values():
        tips = np.array([_hand(q)[0] for q in r.log.q])
        assert np.abs(tips - expected).max() < 1e-2


def test_back_end_hits_the_corner_without_the_subtask_and_not_with_it(runs) -> None:
    _, res = runs
    assert res["rank_only"].summary["min_clearance"] < -0.5
    for name in ("avoid_wqp", "avoid_hqp"):
        assert res[name].summary["min_clearance"] > 0.04, name  # bound 0.05 m
        assert res[name].summary["limit_violations"] == 0, name
    # the closed form with gradients keeps B off the wall and floor, but ignores the slider range (d2 ≤ 1.8)
    pinv = res["avoid_pinv"]
    assert pinv.summary["min_clearance"] > 0.0
    assert pinv.log.q[:, 1].max() > L2


def test_animation_writes_a_small_gif(runs, tmp_path: Path) -> None:
    plan, res = runs
    out = animate_planar(
        res["avoid_hqp"].log.frame_positions,
        plan.draw.segments,
        tmp_path / "rpr.gif",
        every=60,
        walls=[("x", WALL), ("y", FLOOR)],
        trace="3",
    )
    data = out.read_bytes()
    assert data[:6] in (b"GIF87a", b"GIF89a") and len(data) < 150_000

"""The QP runs of the task files: planar3r_line's wqp/hqp, and the Panda circle (pinv, wqp, hqp) — numerically."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml

from redundik.config import load_task
from redundik.config.runner import RunResult, run_task
from tests.conftest import PLANAR_TASK, TASKS, load_yaml

PANDA_TASK = TASKS / "panda_circle.yaml"


@pytest.fixture(scope="module")
def planar() -> dict[str, RunResult]:
    return run_task(load_task(PLANAR_TASK), runs=["rank_null", "wqp", "hqp"])


def test_planar_hqp_ends_where_rank_null_ends(planar: dict[str, RunResult]) -> None:
    a, b = planar["hqp"].log, planar["rank_null"].log
    np.testing.assert_allclose(a.q, b.q, atol=1e-6)  # the whole path, not only the end
    assert not a.fallbacks
    assert a.q[-1, 2] < np.radians(-80)  # θ3 → −90° (the chapter's case 2)
    assert np.nanmax(a.extras["residual_L0"]) < 1e-9  # level 0 met exactly at every step


def test_planar_wqp_is_close_to_the_hierarchy(planar: dict[str, RunResult]) -> None:
    a, b = planar["wqp"].log, planar["hqp"].log
    assert np.abs(a.q - b.q).max() < 5e-3  # ω = 1e-3: O(ω/σ²) of the tip velocity leaks into the null motion
    assert np.abs(a.q - b.q).max() > 1e-7  # ... it is a weighted sum, not the hierarchy
    assert a.max_task_error < 2 * b.max_task_error + 1e-3
    assert "residual_L0" in a.extras and "residual_L1" in b.extras


@pytest.fixture(scope="module")
def panda(tmp_path_factory: pytest.TempPathFactory) -> dict[str, RunResult]:
    data = load_yaml(PANDA_TASK)
    data["robot"] = str((PANDA_TASK.parent / data["robot"]).resolve())
    data["duration"] = 1.0  # half a circle: the joint-1 stop is reached after ~0.3 s
    path = tmp_path_factory.mktemp("panda") / "panda_short.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), encoding="utf-8")
    return run_task(load_task(path))  # the Panda URDF: example-robot-data, in the test extra


def _circle_error(r: RunResult, radius: float) -> float:
    """Largest distance of the TCP to the circle it should be on at each sample [m] (independent of the task code)."""
    p = r.log.frame_positions["panda_hand_tcp"]
    t = r.log.t
    # every sample must lie in the plane x = x0 and at `radius` from one centre (fitted by least squares)
    off = p - p[0]
    assert np.abs(off[:, 0]).max() < 1e-3
    # the centre is equidistant from all points: least squares on |p − c|² = R²
    A = np.column_stack([2 * p[:, 1], 2 * p[:, 2], np.ones(len(t))])
    b = p[:, 1] ** 2 + p[:, 2] ** 2
    cy, cz, _ = np.linalg.lstsq(A, b, rcond=None)[0]
    dist = np.hypot(p[:, 1] - cy, p[:, 2] - cz)
    return float(np.abs(dist - radius).max())


def test_panda_circle_all_runs_track_and_the_qp_runs_keep_the_limits(panda: dict[str, RunResult]) -> None:
    assert list(panda) == ["pinv", "wqp", "hqp"]
    for name, r in panda.items():
        assert np.all(np.isfinite(r.log.q)), name
        assert r.log.max_task_error < 1e-3, (name, r.log.max_task_error)  # pose error < 1 mm / 1 mrad
        assert _circle_error(r, 0.05) < 1e-3, name
        assert r.limit_violation.max() == 0.0, name  # the URDF limits
        assert not r.log.fallbacks, (name, r.log.fallbacks[:3])
    q1 = {name: r.log.q[:, 0] for name, r in panda.items()}
    assert q1["pinv"].min() < -0.04  # the free motion passes the joint-1 stop at −0.03 rad (the test can fail)
    for name in ("wqp", "hqp"):
        assert q1[name].min() >= -0.03 - 1e-12, name  # the QP runs stop at it ...
        assert np.nanmax(panda[name].log.extras["n_active"]) >= 1, name  # ... and say so
    # with 7 arm joints for 6 task rows the hierarchy keeps the pose as well as the closed form does
    assert panda["hqp"].log.max_task_error < 1.5 * panda["pinv"].log.max_task_error + 1e-5


def test_panda_hqp_without_the_stop_equals_pinv(write_yaml: Callable[..., Path]) -> None:
    data = load_yaml(PANDA_TASK)
    data["robot"] = str((PANDA_TASK.parent / data["robot"]).resolve())
    data["duration"] = 0.25
    data["runs"] = {"pinv": data["runs"]["pinv"], "hqp": {"resolver": "hqp", "subtasks": {"posture": {"gain": -1.0}}}}
    res = run_task(load_task(write_yaml(data)))
    np.testing.assert_allclose(res["hqp"].log.q, res["pinv"].log.q, atol=1e-6)

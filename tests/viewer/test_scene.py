"""Replay geometry: mesh decimation, primitives, part poses from Pinocchio, and `redundik view DIR --html`."""

from __future__ import annotations

import numpy as np
import pytest

from redundik.viewer.scene import decimate, limit_proximity, robot_parts, sample_run, sphere_mesh
from tests.conftest import PLANAR_TASK, TASKS


def test_decimate_respects_the_budget_and_keeps_the_shape() -> None:
    v, t = sphere_mesh(0.1, rings=60, sides=120)
    assert t.shape[0] > 10_000
    dv, dt = decimate(v, t, 800)
    assert 100 < dt.shape[0] <= 800
    assert dt.max() < dv.shape[0]
    assert np.all(np.abs(np.linalg.norm(dv, axis=1) - 0.1) < 0.01)  # still on the sphere, within 1 cm
    assert len({tuple(sorted(tr)) for tr in dt.tolist()}) == dt.shape[0]  # no duplicate, no degenerate one
    assert np.all((dt[:, 0] != dt[:, 1]) & (dt[:, 1] != dt[:, 2]) & (dt[:, 0] != dt[:, 2]))


def test_panda_parts_follow_pinocchio_and_limits_colour() -> None:
    from redundik.config import load_task

    plan = load_task(TASKS / "panda_circle.yaml")
    robot = plan.robot.model
    parts = robot_parts(robot, plan.robot.urdf, max_triangles=500)
    assert all(p.triangles.shape[0] <= 500 for p in parts)
    q = np.vstack([plan.q0, robot.random_configuration(np.random.default_rng(1))])
    frames = sample_run(robot, parts, "r", np.array([0.0, 1.0]), q)
    hand = next(i for i, p in enumerate(parts) if p.name.startswith("panda_hand"))
    robot.update(q[1])
    expected = robot.data.oMi[parts[hand].joint].homogeneous @ parts[hand].placement
    assert np.allclose(frames.poses[1, hand].reshape(3, 4), expected[:3], atol=1e-6)
    at_limit = plan.q0.copy()
    at_limit[3] = robot.lower_limits[3]
    prox = limit_proximity(robot, at_limit)
    assert prox[robot.model.getJointId("panda_joint4")] == pytest.approx(1.0)
    assert prox[robot.model.getJointId("panda_joint1")] == pytest.approx(0.0)  # q0 = 0 is mid-range


def test_dh_robot_falls_back_to_segment_cylinders() -> None:
    from redundik.config import load_task

    plan = load_task(PLANAR_TASK)
    robot = plan.robot.model
    parts = robot_parts(robot, plan.robot.urdf, plan.draw.segments)
    assert len(parts) == len(plan.draw.segments) and plan.robot.urdf is None
    frames = sample_run(robot, parts, "r", np.zeros(1), plan.q0[None, :])
    a, b = parts[-1].segment  # type: ignore[misc]
    robot.update(plan.q0)
    m = frames.poses[0, -1].reshape(3, 4)
    assert np.allclose(m[:, 3], robot.frame_position(a), atol=1e-6)  # unit cylinder base on the first frame
    assert np.allclose(m[:, 3] + m[:, 2], robot.frame_position(b), atol=1e-6)  # its top on the second


def test_view_writes_html_from_an_output_folder(tmp_path) -> None:
    from redundik.cli.main import main

    out = tmp_path / "out"
    assert main(["run", str(PLANAR_TASK), "--out", str(out), "--no-figures", "--quiet"]) == 0
    page = tmp_path / "replay.html"
    assert main(["view", str(out), "--html", str(page)]) == 0
    text = page.read_text(encoding="utf-8")
    assert "replay-data" in text and "planar3r_line" in text
    assert main(["view", str(tmp_path)]) == 3  # no summary.json: a one-line error


def test_gif_and_split_error_figure(tmp_path) -> None:
    from PIL import Image

    from redundik.cli.main import main

    out = tmp_path / "rpr"
    assert (
        main(["run", str(TASKS / "rpr_corner.yaml"), "--gif", "--out", str(out), "--quiet", "--runs", "avoid_hqp"]) == 0
    )
    gif = Image.open(out / "rpr_corner.gif")
    assert gif.n_frames >= 30
    first = np.asarray(gif.convert("RGB"))
    gif.seek(gif.n_frames - 1)
    assert np.abs(first.astype(int) - np.asarray(gif.convert("RGB")).astype(int)).sum() > 0  # it moves
    assert (out / "task_error.png").is_file() and (out / "configurations.png").is_file()

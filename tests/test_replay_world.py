"""The HTML replay's collision world, checked on its data (no browser): obstacles at the world's poses and sizes, the
robot's collision shapes at Pinocchio's placements, and per drawn sample the closest pair and its distance as the
collision module computes them; a clearance post stands where the arm meets it (issue 32, item 9)."""

from __future__ import annotations

import base64
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import yaml

from tests.conftest import TASKS

FRAMES = 40


def _arr(b64: str, *shape: int) -> np.ndarray:
    return np.frombuffer(base64.b64decode(b64), dtype="<f4").astype(float).reshape(*shape)


def _mesh(entry: dict[str, Any]) -> np.ndarray:
    return _arr(entry["vertices"], -1, 3)


@pytest.fixture(scope="module")
def shelf() -> tuple[Any, dict[str, Any], dict[str, Any]]:
    """(plan, results, replay document) of panda_shelf's no_avoidance and wqp runs."""
    from redundik.config import load_task
    from redundik.config.runner import run_task
    from redundik.viewer.html import build_task_replay

    plan = load_task(TASKS / "panda_shelf.yaml")
    results = run_task(plan, ["no_avoidance", "wqp"])
    doc = build_task_replay(plan, {n: (r.log.t, r.log.q, {}) for n, r in results.items()}, max_frames=FRAMES)
    return plan, results, doc


def test_obstacles_have_the_worlds_poses_and_sizes(shelf: tuple[Any, dict[str, Any], dict[str, Any]]) -> None:
    plan, _, doc = shelf
    world = plan.world
    spec = yaml.safe_load((TASKS / "panda_shelf.yaml").read_text(encoding="utf-8"))["obstacles"]
    drawn = doc["world"]["obstacles"]
    assert [o["name"] for o in drawn] == [o.name for o in world.obstacles] == list(spec)
    for entry, ob in zip(drawn, world.obstacles, strict=True):
        y = spec[ob.name]
        assert entry["kind"] == y["type"]
        pose = _arr(entry["pose"], 3, 4)
        assert np.allclose(pose, ob.placement.homogeneous[:3], atol=1e-6)
        assert np.allclose(pose[:, 3], y["xyz"], atol=1e-6)
        v = _mesh(entry) @ pose[:, :3].T + pose[:, 3]  # the drawn mesh, in the world
        lo, hi = v.min(axis=0), v.max(axis=0)
        if y["type"] == "box":
            assert entry["size"]["size"] == pytest.approx(y["size"])
            assert np.allclose(lo, np.subtract(y["xyz"], np.divide(y["size"], 2)), atol=1e-6)
            assert np.allclose(hi, np.add(y["xyz"], np.divide(y["size"], 2)), atol=1e-6)
        else:  # the post: a capsule of radius 3 cm, axis 1 m along z, centred at 0.5 m
            assert entry["size"] == pytest.approx({"radius": y["radius"], "length": y["length"]})
            r, half = y["radius"], y["length"] / 2
            assert hi[2] - lo[2] == pytest.approx(2 * (half + r), abs=1e-6)
            assert np.allclose((lo + hi) / 2, y["xyz"], atol=1e-3)
            assert hi[0] - lo[0] == pytest.approx(2 * r, abs=2e-3)
    # every drawn sample has the obstacles at their (static) pose
    run = doc["runs"][0]
    F = len(run["t"])
    poses = _arr(run["world"]["obstacle_poses"], F, len(drawn), 3, 4)
    for k, ob in enumerate(world.obstacles):
        assert np.allclose(poses[:, k], ob.placement.homogeneous[:3], atol=1e-6)


def test_collision_shapes_follow_the_geometry_placements(shelf: tuple[Any, dict[str, Any], dict[str, Any]]) -> None:
    plan, results, doc = shelf
    world, robot = plan.world, plan.robot.model
    shapes = doc["world"]["shapes"]
    assert [s["name"] for s in shapes] == world.link_names
    objs = world.geometry.geometryObjects
    for s, go in zip(shapes, list(objs)[: world.n_links], strict=True):
        assert s["kind"] == "capsule"
        assert s["size"]["radius"] == pytest.approx(go.geometry.radius)
        assert s["size"]["length"] == pytest.approx(2 * go.geometry.halfLength)
    run = doc["runs"][1]
    F, L = len(run["t"]), len(shapes)
    poses = _arr(run["world"]["shape_poses"], F, L, 3, 4)
    log = results[run["name"]].log
    gdata = pin.GeometryData(world.geometry)
    for f in (0, F // 2, F - 1):
        k = int(np.argmin(np.abs(log.t - run["t"][f])))
        robot.update(log.q[k])
        pin.updateGeometryPlacements(robot.model, robot.data, world.geometry, gdata)
        for g in range(L):
            assert np.allclose(poses[f, g], gdata.oMg[g].homogeneous[:3], atol=1e-5), (f, shapes[g]["name"])


def test_closest_pair_per_frame_is_the_collision_modules(shelf: tuple[Any, dict[str, Any], dict[str, Any]]) -> None:
    plan, results, doc = shelf
    world, robot = plan.world, plan.robot.model
    names = doc["world"]["pair_names"]
    assert names == world.pair_names
    for run in doc["runs"]:
        log, series = results[run["name"]].log, results[run["name"]].series
        w, F = run["world"], len(run["t"])
        p1, p2 = _arr(w["p1"], F, 3), _arr(w["p2"], F, 3)
        for f in range(F):
            k = int(np.argmin(np.abs(log.t - run["t"][f])))
            assert series["min_distance"][k] == pytest.approx(w["distance"][f], abs=1e-8)  # the CSV's series
            robot.update(log.q[k])
            dist = world.compute(robot)
            j = int(np.argmin(dist.d))
            assert names[w["pair"][f]] == world.pair_names[j]
            assert w["distance"][f] == pytest.approx(dist.d[j], abs=1e-8)
            assert np.allclose(p1[f], dist.p1[j], atol=1e-6) and np.allclose(p2[f], dist.p2[j], atol=1e-6)
            assert np.linalg.norm(p2[f] - p1[f]) == pytest.approx(abs(w["distance"][f]), abs=1e-5)
    base = doc["runs"][0]["world"]
    worst = int(np.argmin(base["distance"]))
    assert base["distance"][worst] < -0.05 and names[base["pair"][worst]] == "panda_link5|post"  # shown inside
    assert min(doc["runs"][1]["world"]["distance"]) > 0.005  # wqp keeps clear


def test_a_task_without_a_world_has_none() -> None:
    from redundik.config import load_task
    from redundik.viewer.html import build_task_replay

    plan = load_task(TASKS / "planar3r_line.yaml")
    q = np.vstack([plan.q0, plan.q0])
    doc = build_task_replay(plan, {"rank_only": (np.array([0.0, 0.1]), q, {})})
    assert doc["world"] is None and doc["runs"][0]["world"] is None


def test_track7_post_stands_where_the_elbow_meets_it() -> None:
    """The post (clearance potential and monitor, distance in x–y only) is drawn once, as tall as the scene: from
    the floor past the elbow (frame 3, at z ≈ 13 dm), not as a 2-unit stub around z = 0."""
    from redundik.config import load_task
    from redundik.config.runner import run_task
    from redundik.viewer.html import build_task_replay

    plan = load_task(TASKS / "track7_post.yaml")
    plan.steps = 40
    res = run_task(plan, ["rank_only"])
    log = res["rank_only"].log
    doc = build_task_replay(plan, {"rank_only": (log.t, log.q, {})}, max_frames=10)
    assert [o["name"] for o in doc["obstacles"]] == ["post"]  # post_clearance is the same post
    post = doc["obstacles"][0]
    pose = _arr(post["pose"], 3, 4)
    v = _mesh(post) + pose[:, 3]
    assert np.allclose((v[:, :2].min(axis=0) + v[:, :2].max(axis=0)) / 2, [7.0, 7.5], atol=1e-6)
    assert np.ptp(v[:, 0]) == pytest.approx(0.6, abs=1e-3)  # radius 0.3 dm
    robot = plan.robot.model
    elbow_z = []
    for q in log.q:
        robot.update(q)
        elbow_z.append(robot.frame_position("3")[2])
    assert v[:, 2].min() <= doc["view"]["floor"] + 1e-9
    assert v[:, 2].max() > max(elbow_z) > 12.0

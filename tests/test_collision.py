"""Collision geometry, distances and their exact Jacobian, the damper in the QP resolvers, and the panda_shelf run."""

from __future__ import annotations

import copy
from functools import lru_cache
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest

from redundik.collision import (
    CollisionAvoidance,
    CollisionWorld,
    Motion,
    Obstacle,
    fit_capsule,
    make_shape,
)
from redundik.config import load_task
from redundik.config.runner import run_task
from redundik.errors import ConfigError, ModelError, TaskError
from redundik.kinematics import example_robot_data_dir, load_example_robot
from redundik.resolvers import make_resolver
from redundik.tasks import BoundSubtask, FrameTask, GradientSubtask, PostureTask, TaskStack

TASKS = Path(__file__).resolve().parents[1] / "tasks"
PANDA_Q0 = np.array([0.0, -0.785398, 0.0, -2.356194, 0.0, 1.570796, 0.785398, 0.02, 0.02])


@lru_cache(maxsize=1)
def panda_world() -> tuple[object, CollisionWorld]:
    robot = load_example_robot("panda")
    urdf = example_robot_data_dir() / "panda_description/urdf/panda.urdf"
    obstacles = [
        Obstacle("post", make_shape("capsule", radius=0.03, length=1.0), pin.SE3(np.eye(3), np.array([0.3, 0.3, 0.5]))),
        Obstacle("ball", make_shape("sphere", radius=0.05), pin.SE3(np.eye(3), np.array([0.45, -0.2, 0.4]))),
    ]
    return robot, CollisionWorld.from_urdf(robot, urdf, obstacles)


def test_fitted_capsule_encloses_the_points() -> None:
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(200, 3)) * [0.02, 0.03, 0.1] + [0.1, -0.2, 0.3]
    fit = fit_capsule(pts)
    cap = fit.shape
    assert isinstance(cap, coal.Capsule)
    local = (pts - fit.placement.translation) @ np.asarray(fit.placement.rotation)
    z = np.clip(local[:, 2], -cap.halfLength, cap.halfLength)
    dist = np.linalg.norm(local - np.column_stack([0 * z, 0 * z, z]), axis=1)
    assert np.all(dist <= cap.radius + 1e-9)
    assert cap.radius < 0.12  # tight along the short axes, not a bounding sphere of the cloud


def test_panda_pairs_are_filtered_by_adjacency_and_srdf() -> None:
    _robot, world = panda_world()
    names = set(world.pair_names)
    assert "panda_link3|panda_link4" not in names  # adjacent
    assert "panda_link3|panda_hand" not in names and "panda_hand|panda_link3" not in names  # SRDF "Never"
    assert "panda_link1|panda_link5" in names
    assert "panda_link0|post" not in names  # a fixed link and a static obstacle cannot meet
    assert "panda_hand|post" in names
    assert 20 <= world.n_pairs <= 60


@pytest.mark.parametrize("seed", range(4))
def test_distance_jacobian_matches_finite_differences(seed: int) -> None:
    robot, world = panda_world()
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng)
    robot.update(q)
    dist = world.compute(robot, np.inf)
    rows = np.arange(world.n_pairs)
    H = world.jacobian(robot, dist, rows)
    eps = 1e-6
    fd = np.zeros_like(H)
    for i in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[i] = eps
        robot.update(pin.integrate(robot.model, q, dq))
        dp = world.compute(robot, -np.inf).d.copy()
        robot.update(pin.integrate(robot.model, q, -dq))
        dm = world.compute(robot, -np.inf).d.copy()
        fd[:, i] = (dp - dm) / (2 * eps)
    np.testing.assert_allclose(H, fd, atol=1e-6)


def test_barrier_rows_are_the_velocity_damper() -> None:
    robot, world = panda_world()
    # the plain damper: one row per pair within d_i (no look-ahead rows, no capsule end-sphere branches)
    avoid = CollisionAvoidance(world, influence=0.3, safety=0.02, xi=0.5, lookahead=0.0, end_spheres=False)
    robot.update(PANDA_Q0)
    term = avoid.evaluate(robot)
    dist = world.compute(robot, np.inf)
    assert term.h.size == np.count_nonzero(dist.d < 0.3) > 0
    np.testing.assert_allclose(term.gamma, 0.5 / (0.3 - 0.02))
    C, d, _names = BoundSubtask(avoid).rows(robot, 0.01)
    np.testing.assert_allclose(C, -term.H)
    np.testing.assert_allclose(d, term.gamma * term.h)  # ḋ ≥ −ξ (d − d_s)/(d_i − d_s)
    rep = avoid.diagnostics()
    assert rep.closest_pair in world.pair_names and rep.distance == pytest.approx(float(dist.d.min()))
    assert len(rep.active) == term.h.size


def test_lookahead_and_end_sphere_rows() -> None:
    """Pairs in [d_i, d_i + lookahead) get h = d − d_s at γ = 1/dt; capsule end spheres get their own exact rows."""
    robot, world = panda_world()
    world.set_time(0.0)
    di, ds, la = 0.15, 0.02, 0.1
    avoid = CollisionAvoidance(world, influence=di, safety=ds, xi=0.5, lookahead=la)
    q = PANDA_Q0 + np.array([0.3, 0.2, -0.1, 0.2, 0.1, -0.2, 0.3, 0.0, 0.0])
    robot.update(q)
    term = avoid.evaluate(robot)
    dist = world.compute(robot, np.inf)
    pairs = [n for n in term.names if "@" not in n]
    assert pairs == [world.pair_names[k] for k in np.flatnonzero(dist.d < di + la)]
    ends = [n for n in term.names if "@" in n]
    assert ends and len(set(term.names)) == len(term.names)
    _, d, _ = BoundSubtask(avoid).rows(robot, 0.01)
    for r, name in enumerate(term.names):
        dr = term.h[r] + ds  # the row's own distance (a static world)
        if dr < di:
            assert term.gamma[r] == pytest.approx(avoid.gamma) and d[r] == pytest.approx(avoid.gamma * term.h[r])
        else:
            assert d[r] == pytest.approx(term.h[r] / 0.01)  # γ capped at 1/dt: no crossing of d_s within one step
        if "@" not in name:
            assert dr == pytest.approx(dist.d[world.pair_names.index(name)])
        else:  # an end sphere is a part of the capsule: never closer than the pair
            assert dr >= dist.d[world.pair_names.index(name.split("@")[0])] - 1e-12
    # the end-sphere rows' Jacobians against finite differences of their distances
    eps = 1e-6

    def branch_d(qq: np.ndarray) -> dict[str, float]:
        robot.update(qq)
        t = avoid.evaluate(robot)
        return {n: t.h[i] for i, n in enumerate(t.names) if "@" in n}

    robot.update(q)
    base = dict(zip(term.names, term.H, strict=True))
    for i in range(7):
        dq = np.zeros(robot.nv)
        dq[i] = eps
        hp, hm = branch_d(pin.integrate(robot.model, q, dq)), branch_d(pin.integrate(robot.model, q, -dq))
        for n in ends:
            if n in hp and n in hm:
                assert (hp[n] - hm[n]) / (2 * eps) == pytest.approx(base[n][i], abs=1e-6)


def test_moving_obstacle_rate_is_folded_into_h() -> None:
    robot = load_example_robot("panda")
    urdf = example_robot_data_dir() / "panda_description/urdf/panda.urdf"
    ball = Obstacle(
        "ball",
        make_shape("sphere", radius=0.05),
        pin.SE3(np.eye(3), np.array([0.5, 0.0, 0.6])),
        Motion(velocity=(-0.1, 0.0, 0.0)),
    )
    world = CollisionWorld.from_urdf(robot, urdf, [ball], self_collision=False)
    avoid = CollisionAvoidance(world, influence=0.5, safety=0.0, xi=1.0, lookahead=0.0, end_spheres=False)
    robot.update(PANDA_Q0)
    world.set_time(0.0)
    d0 = world.compute(robot, np.inf).d.copy()
    world.set_time(1e-4)
    d1 = world.compute(robot, np.inf).d.copy()
    world.set_time(0.0)
    term = avoid.evaluate(robot)
    k = [world.pair_names.index(n) for n in term.names]
    rate = (d1 - d0)[k] / 1e-4
    np.testing.assert_allclose(term.h, d0[k] + rate / avoid.gamma, atol=1e-5)
    assert np.all(rate[rate != 0] < 0)  # the ball approaches
    # the capsules' end-sphere branches carry their own exact ∂d/∂t
    dist = world.compute(robot, 0.5)
    b0 = world.end_spheres(dist, dist.near, 0.5)
    world.set_time(1e-4)
    dist = world.compute(robot, 0.5)
    b1 = world.end_spheres(dist, dist.near, 0.5)
    world.set_time(0.0)
    assert b0.names and b0.names == b1.names
    np.testing.assert_allclose((b1.d - b0.d) / 1e-4, b0.rate, atol=1e-5)
    assert np.all(b0.rate[b0.rate != 0] < 0)


@pytest.mark.parametrize("resolver", ["wqp", "hqp"])
def test_qp_keeps_a_hand_driven_into_an_obstacle_outside(resolver: str) -> None:
    robot, world = panda_world()
    world.set_time(0.0)
    avoid = CollisionAvoidance(world, influence=0.1, safety=0.01, xi=0.3)
    hand = FrameTask("panda_hand", axes="position", gain=5.0)
    hand.set_target([0.45, -0.2, 0.4])  # the centre of the ball
    bound = BoundSubtask(avoid, priority=0 if resolver == "hqp" else None)
    stack = TaskStack([hand, PostureTask(gain=1.0)], [bound])
    res = make_resolver(resolver, **({"levels": {"panda_hand": 1}} if resolver == "hqp" else {}))
    q = PANDA_Q0.copy()
    dmin = np.inf
    for k in range(150):
        step = res.step(robot, stack, q, k * 0.01, 0.01)
        q = robot.integrate(q, step.dq, 0.01)
        robot.update(q)
        dmin = min(dmin, world.closest(robot)[1])
    assert dmin >= 0.0
    assert dmin < 0.03  # it did go and press against the ball
    assert world.closest(robot)[0] in {"panda_hand|ball", "panda_leftfinger|ball", "panda_rightfinger|ball"}


def test_pinv_refuses_the_barrier_but_takes_the_repulsive_potential() -> None:
    robot, world = panda_world()
    avoid = CollisionAvoidance(world)
    stack = TaskStack([FrameTask("panda_hand")], [BoundSubtask(avoid)])
    with pytest.raises(Exception, match="bound subtask"):
        make_resolver("pinv").step(robot, stack, PANDA_Q0, 0.0, 0.01)
    stack = TaskStack([FrameTask("panda_hand")], [GradientSubtask(avoid, gain=-1.0)])
    assert np.isfinite(make_resolver("pinv").step(robot, stack, PANDA_Q0, 0.0, 0.01).dq).all()


def test_bad_parameters_raise() -> None:
    _robot, world = panda_world()
    with pytest.raises(TaskError, match="influence"):
        CollisionAvoidance(world, influence=0.01, safety=0.02)
    with pytest.raises(ModelError, match="radius must be a finite number > 0"):
        make_shape("sphere", radius=-0.1)
    with pytest.raises(ModelError, match="unknown obstacle type 'cone'; available"):
        make_shape("cone")
    with pytest.raises(ModelError, match=r"mesh file .* does not exist"):
        make_shape("mesh", path="/nonexistent/x.stl")
    with pytest.raises(ModelError, match="NaN"):
        Obstacle("o", make_shape("sphere", radius=0.1), pin.SE3(np.eye(3), np.array([np.nan, 0, 0])))
    other = load_example_robot("panda")
    with pytest.raises(TaskError, match="built for robot"):
        CollisionAvoidance(world).check(other)


def _shelf(tmp_path: Path, **edit: object) -> dict:
    import yaml

    data = yaml.safe_load((TASKS / "panda_shelf.yaml").read_text())
    data["robot"] = str(TASKS.parent / "configs/panda.yaml")
    for key, value in edit.items():
        node = data
        *head, last = key.split("/")
        for h in head:
            node = node[h]
        node[last] = value
    return data


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        ({"obstacles/post/radius": -0.03}, r"obstacles\.post\.radius: must be > 0"),
        ({"obstacles/post/xyz": [0.1, float("nan"), 0.2]}, r"obstacles\.post\.xyz\[1\]"),
        ({"obstacles/post": {"type": "mesh", "path": "missing.stl"}}, r"obstacles\.post\.path: mesh file"),
        ({"obstacles/post": {"type": "box"}}, r"obstacles\.post: a box obstacle needs 'size'"),
        ({"collision": {"disable": [["panda_link3", "panda_elbow"]]}}, r"collision\.disable: .*'panda_elbow'"),
        ({"collision": {"obstacle_links": ["hand"]}}, r"collision\.obstacle_links: unknown link"),
        ({"collision": {"approximation": "voxels"}}, r"collision\.approximation"),
        ({"potentials/avoid": {"type": "collision", "influence": 0.01, "safety": 0.02}}, r"potentials\.avoid"),
        (
            {"obstacles/post": {"type": "mesh", "path": "garbage.stl"}},
            r"obstacles\.post\.path: mesh file '.*garbage\.stl' could not be read: Could not load resource",
        ),
        ({"obstacles/bay_floor/size": [0.3, -0.4, 0.03]}, r"obstacles\.bay_floor\.size\[1\]: must be > 0"),
        ({"obstacles/bay_floor/rpy": [0.0, float("nan"), 0.0]}, r"obstacles\.bay_floor\.rpy\[1\]: expected a finite"),
        ({"obstacles/post/motion": {"velocity": [0.0, float("nan"), 0.0]}}, r"obstacles\.post\.motion\.velocity\[1\]"),
        ({"obstacles/post/motion": {"amplitude": [0.1, 0, 0], "frequency": -1}}, r"obstacles\.post\.motion\.frequency"),
        ({"obstacles/post/motion": {"velocity": [0.0, 1.0]}}, r"obstacles\.post\.motion\.velocity: expected 3 values"),
        ({"obstacles/post/motion": {"speed": 1.0}}, r"obstacles\.post\.motion\.speed: unknown key 'speed'"),
        (
            {"collision": {"links": ["panda_link3", "panda_wrist"]}},
            r"collision\.links: unknown link\(s\) 'panda_wrist'",
        ),
    ],
)
def test_bad_world_input_is_a_one_line_config_error(tmp_path: Path, edit: dict, match: str) -> None:
    (tmp_path / "garbage.stl").write_bytes(b"not a mesh\x00\x01" * 4)  # exists, unreadable
    with pytest.raises(ConfigError, match=match) as info:
        load_task(_shelf(tmp_path, **edit), base_dir=tmp_path)
    assert "\n" not in str(info.value) and "Traceback" not in str(info.value)


def test_panda_shelf_run(tmp_path: Path) -> None:
    from redundik.reporting.world_plots import closest_segments, plot_world

    plan = load_task(TASKS / "panda_shelf.yaml")
    res = run_task(plan)
    s = {name: r.summary for name, r in res.items()}
    # the figure: obstacles, closest-pair segments, distance over time; its witness points are the summary's
    from redundik.cli.view_cmds import figure_inputs

    runs, options = figure_inputs(plan, {"no_avoidance": res["no_avoidance"], "wqp": res["wqp"]})
    png = plot_world(runs, plan.robot.model, tmp_path / "world.png", options)
    assert png is not None and png.stat().st_size > 20_000
    log = res["no_avoidance"].log
    idx, d, p1, p2, pairs = closest_segments(plan.world, plan.robot.model, log.t, log.q, max_samples=60)
    assert np.allclose(np.linalg.norm(p2 - p1, axis=1), np.abs(d), atol=1e-9)
    assert np.allclose(d, res["no_avoidance"].series["min_distance"][idx], atol=1e-12)
    assert "panda_link5|post" in pairs
    assert s["no_avoidance"]["min_collision_distance"] < -0.03  # the forearm goes through the post
    assert s["no_avoidance"]["closest_pair"] == "panda_link5|post"
    for name in ("pinv_repulsive", "wqp", "hqp"):
        assert s[name]["min_collision_distance"] >= 0.0, name
        assert s[name]["penetrating_samples"] == 0
        assert s[name]["final_task_error"] < 1e-3, name  # the hand reaches the target in the bay
    for name in ("wqp", "hqp"):
        assert s[name]["min_collision_distance"] >= 0.005  # the damper keeps d ≥ d_s (1 cm) to first order
        assert s[name]["max_active_pairs"] >= 1
    assert "min_distance" in res["wqp"].series
    # per-step diagnostics reach the CSV: closest pair (an index into summary's names), rows present, rows binding
    from redundik.reporting.outputs import write_outputs

    write_outputs(plan, res, tmp_path)
    header = (tmp_path / "wqp.csv").read_text().splitlines()[0].split(",")
    for col in ("min_distance", "closest_pair_id", "active_pairs", "binding_rows"):
        assert col in header, col
    w = s["wqp"]
    ids = res["wqp"].series["closest_pair_id"].astype(int)
    assert w["collision_pair_names"][ids[int(np.argmin(res["wqp"].series["min_distance"]))]] == w["closest_pair"]
    assert w["max_binding_rows"] >= 1 and "avoid:panda_link5|post" in w["binding_constraints"]


@pytest.mark.parametrize("backend", ["daqp", "quadprog"])
def test_stress_random_targets_do_not_penetrate(backend: str) -> None:
    """300 steps of random targets through the obstacles and across the body (seed 3): the plain damper (one row
    per pair) penetrates, the capsule witness jumping between the ends of a capsule nearly parallel to the other
    body; with the end-sphere and look-ahead rows d stays ≥ 0 (and near d_s = 1 cm)."""
    from redundik.simulation.collision_stress import run_stress

    out = run_stress("panda", "wqp", backend, episodes=3, steps=100, seed=3)
    assert out.steps == 300 and out.fallbacks == 0
    assert out.penetrations == 0 and out.min_distance > 0.005
    if backend == "daqp":
        plain = run_stress("panda", "wqp", backend, episodes=3, steps=100, seed=3, lookahead=0.0, end_spheres=False)
        assert plain.penetrations > 0


def _press_against_the_ball(
    resolver: object, extra: list, relaxed: list[tuple[str, ...]] | None = None
) -> tuple[float, list[str]]:
    """150 steps of the hand driven into the ball's centre with the collision damper (and ``extra`` bounds):
    (smallest distance, fallback notes); each step's ``relaxed`` appended to ``relaxed`` when given."""
    robot, world = panda_world()
    world.set_time(0.0)
    avoid = CollisionAvoidance(world, influence=0.1, safety=0.01, xi=0.3)
    hand = FrameTask("panda_hand", axes="position", gain=5.0)
    hand.set_target([0.45, -0.2, 0.4])
    stack = TaskStack([hand, PostureTask(gain=1.0)], [BoundSubtask(avoid, priority=0), *extra])
    q, dmin, notes = PANDA_Q0.copy(), np.inf, []
    for k in range(150):
        step = resolver.step(robot, stack, q, k * 0.01, 0.01)  # type: ignore[attr-defined]
        if step.fallback:
            notes.append(step.fallback)
        if relaxed is not None:
            relaxed.append(step.relaxed)
        q = robot.integrate(q, step.dq, 0.01)
        robot.update(q)
        dmin = min(dmin, world.closest(robot)[1])
    return dmin, notes


def test_wqp_relaxed_step_keeps_the_collision_rows() -> None:
    """An infeasible bound (joint 1 to ≥ 3 rad away within one step, γ = 1/dt, against its velocity limit) makes
    wqp relax its QP at every step while the hand presses against the ball: the relaxed problem drops that bound
    and keeps the collision damper's rows, so the distance stays ≥ 0 (and near d_s). The QP is infeasible, so the
    relaxation is the documented one: ``relaxed`` names the bound, no fallback."""
    from redundik.tasks import JointValue

    far = BoundSubtask(JointValue("panda_joint1", -10.0, name="far"), lower=13.0**2, priority=0)
    relaxed: list[tuple[str, ...]] = []
    dmin, notes = _press_against_the_ball(make_resolver("wqp"), [far], relaxed)
    assert notes == []
    assert sum(r == ("far",) for r in relaxed) >= 100 and all(r in {(), ("far",)} for r in relaxed)
    assert 0.005 <= dmin < 0.03


class _FailingBackend:
    """A backend that never solves: every QP step falls back to the closed form."""

    name = "failing"

    def solve(self, problem: object, warm: object = None) -> object:
        from redundik.errors import SolverError

        raise SolverError("never solves")

    def reset(self) -> None:
        pass


@pytest.mark.parametrize("resolver", ["wqp", "hqp"])
def test_closed_form_fallback_is_scaled_to_keep_the_collision_rows(resolver: str) -> None:
    from redundik.resolvers.qp.backends import Backend

    backend = type("Failing", (_FailingBackend, Backend), {})()
    dmin, notes = _press_against_the_ball(make_resolver(resolver, backend=backend), [])
    assert notes and any("scaled by" in n and "safety rows" in n for n in notes)
    assert dmin >= 0.0


def test_keep_safe_scales_to_the_tightest_row() -> None:
    from redundik.resolvers.qp.base import keep_safe

    C, d = np.array([[1.0, 0.0], [0.0, 1.0]]), np.array([0.5, 2.0])
    dq, alpha = keep_safe(np.array([1.0, 1.0]), C, d)
    assert alpha == pytest.approx(0.5, abs=1e-5) and np.all(C @ dq <= d + 1e-6 + 1e-12)
    assert keep_safe(np.array([0.1, 0.1]), C, d)[1] == 1.0
    assert keep_safe(np.array([1.0, 0.0]), C, np.array([-0.1, 1.0]))[1] < 1e-5
    assert keep_safe(np.array([1e-7, 0.0]), C, np.array([0.0, 1.0]))[1] == 1.0  # within a backend's tolerance


@lru_cache(maxsize=1)
def _box_world() -> tuple[object, CollisionWorld]:
    robot = load_example_robot("panda")
    urdf = example_robot_data_dir() / "panda_description/urdf/panda.urdf"
    R = pin.rpy.rpyToMatrix(0.3, -0.2, 0.5)
    obstacles = [
        Obstacle("crate", make_shape("box", size=[0.2, 0.3, 0.1]), pin.SE3(R, np.array([0.45, 0.1, 0.3]))),
        Obstacle("floor", make_shape("plane"), pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.05]))),
        Obstacle("post", make_shape("capsule", radius=0.03, length=1.0), pin.SE3(R, np.array([0.3, -0.3, 0.5]))),
    ]
    return robot, CollisionWorld.from_urdf(robot, urdf, obstacles)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_distances_match_coal_and_the_python_end_spheres(seed: int) -> None:
    """The compiled capsule–capsule distances equal coal's (d, witness points, normal) and the compiled end
    spheres equal the per-branch Python reference (``_sphere_to``) on capsules, boxes and a plane."""
    from redundik.collision.world import _sphere_to

    robot, world = _box_world()
    rng = np.random.default_rng(seed)
    q = PANDA_Q0 + rng.normal(0, 0.4, 9)
    q[7:] = 0.02
    robot.update(q)
    world._cache = None
    dist = world.compute(robot)
    assert world._cap.size >= 10 and world._coal.size >= 10  # both routes are exercised
    for k in world._cap.tolist():
        r = pin.computeDistance(world.geometry, world.data, k)  # coal, on the same placements
        assert dist.d[k] == pytest.approx(r.min_distance, abs=1e-9)
        if r.min_distance > 1e-6:
            assert np.allclose(dist.p1[k], r.getNearestPoint1(), atol=1e-7)
            assert np.allclose(dist.p2[k], r.getNearestPoint2(), atol=1e-7)
    info, T = world._shape_info(), world._T
    rows = np.arange(world.n_pairs)
    br = world.end_spheres(dist, rows, np.inf)
    assert br.pair.size > 20
    for r, (k, name) in enumerate(zip(br.pair.tolist(), br.names, strict=True)):
        i, j = world.pairs[k]
        b = i if name.endswith(("@" + world._geom_names[i] + "+", "@" + world._geom_names[i] + "-")) else j
        o = j if b == i else i
        c = T[b, :3, 3] + (1.0 if name.endswith("+") else -1.0) * info[b][2] * T[b, :3, 2]
        ref = _sphere_to(c, info[b][1], info[o], pin.SE3(T[o]))
        assert ref is not None
        assert br.d[r] == pytest.approx(ref[0], abs=1e-12)


@pytest.mark.parametrize(
    ("edit", "path"),
    [
        ({"obstacles/post": {"type": "mesh", "path": "garbage.stl"}}, "obstacles.post.path"),
        ({"obstacles/post/xyz": [0.1, float("nan"), 0.2]}, "obstacles.post.xyz[1]"),
        ({"obstacles/post/radius": -0.03}, "obstacles.post.radius"),
        ({"obstacles/post/motion": {"amplitude": [0.1, 0, 0], "frequency": -1}}, "obstacles.post.motion.frequency"),
        ({"collision": {"obstacle_links": ["hand"]}}, "collision.obstacle_links"),
    ],
)
def test_bad_world_input_exits_3_with_the_key_path(tmp_path: Path, cli: object, edit: dict, path: str) -> None:
    import yaml

    (tmp_path / "garbage.stl").write_bytes(b"not a mesh\x00\x01" * 4)
    file = tmp_path / "task.yaml"
    file.write_text(yaml.safe_dump(_shelf(tmp_path, **edit)))
    code, out, err = cli("validate", file)  # type: ignore[operator]
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 3 and len(lines) == 1 and lines[0].startswith(f"error: {path}: "), err
    assert "Traceback" not in err + out


def _eager_damper(avoid: CollisionAvoidance, robot: object) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """The damper rows (names, h, H, γ) built the long way: pairs, end spheres, point Jacobians, names per row."""
    w = avoid.world
    reach = avoid.influence + avoid.lookahead
    dist = w.compute(robot, reach)  # type: ignore[arg-type]
    rows = dist.near
    br = w.end_spheres(dist, rows, reach)
    names = [w.pair_names[k] for k in rows.tolist()] + br.names
    pairs = np.concatenate([rows, br.pair])
    n, p1, p2 = (np.vstack([a[rows], b]) for a, b in ((dist.n, br.n), (dist.p1, br.p1), (dist.p2, br.p2)))
    d, rate = np.concatenate([dist.d[rows], br.d]), np.concatenate([dist.rate[rows], br.rate])
    H = w.point_jacobian(robot, pairs, n, p1, p2)  # type: ignore[arg-type]
    inside = d < avoid.influence
    h = np.where(inside, d - avoid.safety + rate / avoid.gamma, d - avoid.safety)
    return names, h, H, np.where(inside, avoid.gamma, 1e12)


def test_cached_row_names_and_compiled_rows_equal_the_eager_ones() -> None:
    """The damper's row names are reused while its rows are unchanged and its rows (also as QP rows) come from one
    compiled call; along a motion whose active pairs and end spheres change, and after the pair set changes, names
    and rows equal the ones built row by row (bitwise), also with the placements read through Pinocchio's objects."""
    robot = load_example_robot("panda")
    urdf = example_robot_data_dir() / "panda_description/urdf/panda.urdf"
    world = CollisionWorld.from_urdf(robot, urdf, self_collision=True)
    avoid = CollisionAvoidance(world, influence=0.1, safety=0.01, xi=0.3, lookahead=0.05)
    bound = BoundSubtask(avoid)
    seen: set[tuple[str, ...]] = set()

    def check() -> None:
        world._cache = None
        C, d, names = bound.rows(robot, 0.01)  # distances and QP rows in one call
        term = avoid.evaluate(robot)  # from the cached distances
        world._cache = None
        ref_names, h, H, gamma = _eager_damper(avoid, robot)
        assert term.names == ref_names and names == [f"collision:{n}" for n in ref_names]
        assert np.array_equal(term.h, h) and np.array_equal(term.H, H) and np.array_equal(term.gamma, gamma)
        assert np.array_equal(C, -H) and np.array_equal(d, np.minimum(gamma, 1 / 0.01) * h)
        seen.add(tuple(ref_names))
        for g in world._live:
            assert np.array_equal(world._T[g], world.data.oMg[g].homogeneous)

    for stage in range(3):
        if stage == 1:  # the near pairs permuted among their places: the same row ids, other pairs and labels
            pairs_only = CollisionAvoidance(
                world, influence=0.1, safety=0.01, xi=0.3, lookahead=0.05, end_spheres=False
            )
            before = pairs_only.evaluate(robot).names
            near = world.compute(robot, avoid.influence + avoid.lookahead).near.tolist()
            assert len(near) >= 2
            pairs = list(world.pairs)
            for k, j in zip(near, near[::-1], strict=True):
                pairs[k] = world.pairs[j]
            world._set_pairs(pairs)
            assert pairs_only.evaluate(robot).names == before[::-1]
            check()
        if stage == 2:
            world._poses = None  # the per-geometry route to the placements
        for s in range(40):
            robot.update(PANDA_Q0 + 0.6 * np.sin(0.15 * s + np.arange(9)) * (np.arange(9) < 7))
            check()
    assert len(seen) > 5  # the active set did change


def test_every_new_coal_data_of_a_world_is_read_through_its_placements_view() -> None:
    """A world's coal data is made with its placements set (a fresh ``GeometryData`` leaves them uninitialised: a NaN
    there failed the check of the view on them in a few per cent of worlds), so a static world of capsules always has
    its view and its one-call damper (``capsule_damper``); here 300 new data of the Panda's world of capsules."""
    _robot, world = panda_world()
    fresh = copy.deepcopy(world)  # (its own coal data, made by _new_data)
    for _ in range(300):
        fresh._new_data()
        assert fresh._poses is not None
    fresh._bind_static()
    assert fresh._static is not None

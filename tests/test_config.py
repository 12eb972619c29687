"""Robot configs and task files: what they build, and the one-line errors with YAML key paths."""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from redundik.config import load_task
from redundik.config.robot import load_robot
from redundik.config.runner import run_task, select_runs
from redundik.errors import ConfigError
from redundik.kinematics import DHRow, dh_matrix, from_dh
from tests.conftest import CONFIGS, PLANAR_TASK

# ------------------------------------------------------------------------------------------------ malformed files
#: (id, mutation of the planar task mapping, expected key path, words the message must contain)
MALFORMED: list[tuple[str, Callable[[dict[str, Any]], None], str, list[str]]] = [
    ("unknown_top_key", lambda d: d.update(stepz=500), "stepz", ["unknown key 'stepz'", "allowed keys", "steps"]),
    (
        "unknown_nested_key",
        lambda d: d["runs"]["rank_null"]["subtasks"]["sin2_q3"].update(gian=1),
        "runs.rank_null.subtasks.sin2_q3.gian",
        ["unknown key 'gian'", "gain"],
    ),
    (
        "wrong_type",
        lambda d: d["runs"]["rank_null"]["subtasks"]["sin2_q3"].update(gain="abc"),
        "runs.rank_null.subtasks.sin2_q3.gain",
        ["expected a number, got 'abc'"],
    ),
    ("bool_as_number", lambda d: d.update(dt=True), "dt", ["expected a number, got True"]),
    ("string_steps", lambda d: d.update(steps="500"), "steps", ["expected an integer"]),
    ("q0_length", lambda d: d.update(q0=[110, -40]), "q0", ["expected 3 values", "got 2"]),
    (
        "velocity_length",
        lambda d: d["main"][0]["trajectory"].update(velocity=[0.2]),
        "main[0].trajectory.velocity",
        ["expected 2 to 3 values, got 1"],
    ),
    (
        "unknown_frame",
        lambda d: d["main"][0].update(frame="tipp"),
        "main[0].frame",
        ["frame 'tipp' does not exist", "available: 0, 1, 2, 3"],
    ),
    (
        "unknown_joint",
        lambda d: d["potentials"]["sin2_q3"].update(joint="7"),
        "potentials.sin2_q3.joint",
        ["joint '7' does not exist", "available: 1, 2, 3"],
    ),
    ("nan", lambda d: d.update(dt=float("nan")), "dt", ["finite number"]),
    ("inf_in_vector", lambda d: d.update(q0=[110, float("inf"), -30]), "q0[1]", ["finite number"]),
    (
        "unknown_resolver",
        lambda d: d["runs"]["rank_only"].update(resolver="magic"),
        "runs.rank_only.resolver",
        ["unknown resolver 'magic'", "available:", "pinv", "feedback"],
    ),
    (
        "unknown_potential_type",
        lambda d: d["potentials"]["sin2_q3"].update(type="sine"),
        "potentials.sin2_q3.type",
        ["unknown potential type 'sine'", "sin2", "manipulability"],
    ),
    (
        "unknown_subtask",
        lambda d: d["runs"]["rank_null"].update(subtasks={"sin2_q4": {"gain": 1}}),
        "runs.rank_null.subtasks.sin2_q4",
        ["no potential named 'sin2_q4'", "sin2_q3"],
    ),
    (
        "gain_of_unknown_task",
        lambda d: d["runs"]["closed_loop"].update(gains={"tool": 20}),
        "runs.closed_loop.gains.tool",
        ["no main task named 'tool'", "tip"],
    ),
    ("missing_dt", lambda d: d.pop("dt"), "dt", ["required key is missing"]),
    ("steps_and_duration", lambda d: d.update(duration=5.0), "(top level)", ["exactly one of 'steps'"]),
    (
        "target_mode_on_pinv",
        lambda d: d["runs"]["rank_null"]["subtasks"]["sin2_q3"].update(target=1.0),
        "runs.rank_null.subtasks.sin2_q3",
        ["a target subtask takes", "remove gain"],
    ),
    (
        "bad_axes",
        lambda d: d["main"][0].update(axes="planer"),
        "main[0].axes",
        ["unknown axes 'planer'", "planar"],
    ),
    (
        "bad_resolver_option",
        lambda d: d["runs"]["rank_only"].update(options={"epsilonn": 0.1}),
        "runs.rank_only.options",
        ["epsilonn"],
    ),
    (
        "negative_rate",
        lambda d: d["runs"]["feedback"]["subtasks"]["sin2_q3"].update(rate=-1),
        "runs.feedback.subtasks.sin2_q3.rate",
        ["must be ≥ 0"],
    ),
    ("no_runs", lambda d: d.update(runs={}), "runs", ["must not be empty"]),
    (
        "bad_angle_unit",
        lambda d: d.update(angle_unit="degrees"),
        "angle_unit",
        ["expected one of", "'deg'", "'degrees'"],
    ),
]


def _mutated(data: dict[str, Any], mutate: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
    out = copy.deepcopy(data)
    mutate(out)
    return out


@pytest.mark.parametrize(("mutate", "path", "words"), [m[1:] for m in MALFORMED], ids=[m[0] for m in MALFORMED])
def test_malformed_task_gives_key_path_and_expectation(
    planar_task_data: dict[str, Any], write_yaml: Callable[..., Path], mutate: Any, path: str, words: list[str]
) -> None:
    file = write_yaml(_mutated(planar_task_data, mutate))
    with pytest.raises(ConfigError) as info:
        load_task(file)
    msg = str(info.value)
    assert info.value.path == path, msg
    assert msg.startswith(f"{path}: "), msg
    for w in words:
        assert w in msg, f"{w!r} not in {msg!r}"
    assert "\n" not in msg


def test_good_file_loads_and_validates_every_run() -> None:
    plan = load_task(PLANAR_TASK)
    assert plan.name == "planar3r_line"
    assert (plan.dt, plan.steps) == (0.01, 500)
    np.testing.assert_allclose(plan.q0, np.radians([110, -40, -30]), atol=1e-15)
    assert {n: r.resolver_name for n, r in plan.runs.items()} == {
        "rank_only": "pinv",
        "rank_null": "pinv",
        "feedback": "feedback",
        "closed_loop": "pinv",
        "wqp": "wqp",
        "hqp": "hqp",
    }
    # every run has its own task objects (they carry state: trajectory start, frame ids)
    tasks = [r.stack.tasks[0] for r in plan.runs.values()]
    assert len({id(t) for t in tasks}) == len(tasks)
    assert [t.gain for t in tasks] == [0.0, 0.0, 0.0, 20.0, 0.0, 0.0]


def test_yaml_syntax_error_names_file_and_line(write_yaml: Callable[..., Path]) -> None:
    text = PLANAR_TASK.read_text(encoding="utf-8").replace("steps: 500", "steps: [500")
    line = next(i + 1 for i, s in enumerate(text.splitlines()) if s.startswith("steps: [500"))
    file = write_yaml(text)
    with pytest.raises(ConfigError) as info:
        load_task(file)
    msg = str(info.value)
    assert "invalid YAML" in msg and str(file) in msg
    reported = int(msg.split(f"{file}:")[1].split(":")[0])
    assert abs(reported - line) <= 2, msg


def test_duplicate_keys_are_refused(write_yaml: Callable[..., Path]) -> None:
    text = PLANAR_TASK.read_text(encoding="utf-8").replace("dt: 0.01", "dt: 0.01\ndt: 0.02")
    with pytest.raises(ConfigError, match="duplicate key 'dt'"):
        load_task(write_yaml(text))


def test_missing_files(tmp_path: Path, planar_task_data: dict[str, Any], write_yaml: Callable[..., Path]) -> None:
    with pytest.raises(ConfigError, match="does not exist"):
        load_task(tmp_path / "nope.yaml")
    planar_task_data["robot"] = "nope.yaml"
    with pytest.raises(ConfigError, match=r"^robot: robot config 'nope.yaml' does not exist"):
        load_task(write_yaml(planar_task_data))


def test_errors_inside_a_robot_config_name_the_file(
    planar_task_data: dict[str, Any], write_yaml: Callable[..., Path]
) -> None:
    robot = (CONFIGS / "planar3r.yaml").read_text(encoding="utf-8").replace("a: 1, alpha: 0, lower", "a: x, lower", 1)
    write_yaml(robot, "robot.yaml")
    planar_task_data["robot"] = "robot.yaml"
    with pytest.raises(ConfigError) as info:
        load_task(write_yaml(planar_task_data))
    assert str(info.value).startswith("robot.yaml: dh[0].a: expected a number, got 'x'")


def test_unknown_run_selection() -> None:
    plan = load_task(PLANAR_TASK)
    assert select_runs(plan, ["closed_loop", "rank_only"]) == ["rank_only", "closed_loop"]
    with pytest.raises(ConfigError, match="no run named 'bogus'; runs in the file: rank_only"):
        select_runs(plan, ["bogus"])


# ------------------------------------------------------------------------------------------------ robot configs
def test_planar3r_config_is_the_chapter_arm() -> None:
    robot = load_robot(str(CONFIGS / "planar3r.yaml"), CONFIGS)
    q0 = robot.q0
    assert q0 is not None
    np.testing.assert_allclose(np.degrees(q0), [110, -40, -30])
    robot.model.update(q0)
    # FK against the product of the chapter's A matrices (a = 1, α = d = 0)
    A = np.eye(4)
    for th in q0:
        A = A @ dh_matrix(th, 0.0, 1.0, 0.0)
    np.testing.assert_allclose(robot.model.frame_position("3"), A[:3, 3], atol=1e-12)
    np.testing.assert_allclose(A[:2, 3], [0.7660, 2.5222], atol=5e-5)
    assert [j.kind for j in robot.model.joints] == ["revolute"] * 3
    np.testing.assert_allclose(robot.model.upper_limits, np.pi)
    np.testing.assert_allclose(robot.model.velocity_limits, np.pi)
    assert robot.segments == [("0", "1"), ("1", "2"), ("2", "3")]


def test_angle_units_and_base_and_tool_frames(tmp_path: Path) -> None:
    common = {
        "length_unit": "dm",
        "base": {"xyz": [1, 2, 3], "rpy": [0, 0, 90]},
        "dh": [
            {"name": "1", "type": "prismatic", "theta": 0, "alpha": 90, "a": 1, "lower": 0, "upper": 5},
            {"name": "2", "theta": 30, "d": 2, "alpha": -90, "lower": -90, "upper": 90},
            {"name": "3", "a": 4, "parent": "2"},
        ],
        "frames": {"tool": {"parent": "3", "xyz": [0.5, 0, 0], "rpy": [0, 90, 0]}},
        "q0": [1.5, 45, 10],
    }
    deg = load_robot({**common, "angle_unit": "deg"}, tmp_path)
    rad_spec = copy.deepcopy(common)
    rad_spec["angle_unit"] = "rad"
    rad_spec["base"]["rpy"] = [0, 0, np.pi / 2]
    for row in rad_spec["dh"]:
        for key in ("theta", "alpha"):
            row[key] = np.radians(row.get(key, 0.0)).item()
    rad_spec["dh"][1]["lower"], rad_spec["dh"][1]["upper"] = -np.pi / 2, np.pi / 2
    rad_spec["frames"]["tool"]["rpy"] = [0, np.pi / 2, 0]
    rad_spec["q0"] = [1.5, np.radians(45).item(), np.radians(10).item()]
    rad = load_robot(rad_spec, tmp_path)
    assert deg.q0 is not None and rad.q0 is not None
    np.testing.assert_allclose(deg.q0, rad.q0)
    assert deg.q0[0] == 1.5  # prismatic entry not converted
    np.testing.assert_allclose(deg.model.lower_limits, [0, -np.pi / 2, -np.inf])
    # independent FK: base · A1 · A2 · A3 · tool offset
    base = np.eye(4)
    base[:3, :3] = pin.rpy.rpyToMatrix(0, 0, np.pi / 2)
    base[:3, 3] = [1, 2, 3]
    q = deg.q0
    A = base @ dh_matrix(0, q[0], 1, np.pi / 2) @ dh_matrix(np.radians(30) + q[1], 2, 0, -np.pi / 2)
    A = A @ dh_matrix(q[2], 0, 4, 0)
    tool = np.eye(4)
    tool[:3, :3] = pin.rpy.rpyToMatrix(0, np.pi / 2, 0)
    tool[:3, 3] = [0.5, 0, 0]
    for r in (deg, rad):
        r.model.update(q)
        np.testing.assert_allclose(r.model.frame_pose("3").homogeneous, A, atol=1e-12)
        np.testing.assert_allclose(r.model.frame_pose("tool").homogeneous, A @ tool, atol=1e-12)
    assert deg.model.length_unit == "dm"
    assert ("3", "tool") in deg.segments


def test_inline_robot_and_integer_names(write_yaml: Callable[..., Path]) -> None:
    data = {
        "name": "inline",
        "robot": {"dh": [{"name": 1, "a": 1}, {"name": 2, "a": 1}, {"name": 3, "a": 1}]},
        "dt": 0.01,
        "duration": 0.1,
        "main": [{"type": "frame", "frame": 3, "axes": ["x", "y"], "trajectory": {"type": "hold"}}],
        "potentials": {"c": {"type": "joint_centering", "center": [0, 0, 1]}},
        "runs": {"r": {"subtasks": {"c": {"gain": -1}}}},
    }
    plan = load_task(write_yaml(data))
    assert plan.steps == 10
    assert plan.runs["r"].stack.tasks[0].name == "3"
    np.testing.assert_allclose(plan.q0, 0.0)  # neither the file nor the robot gives q0: neutral
    res = run_task(plan)["r"]
    # the hold task keeps the tip still while the centering potential decreases
    assert res.summary["max_task_error"] < 1e-3
    p = res.log.potentials["c"]
    assert p[-1] < p[0]


def test_urdf_config_with_frames_and_limit_overrides(write_yaml: Callable[..., Path]) -> None:
    cfg = {
        "urdf": "example-robot-data:panda",
        "angle_unit": "deg",
        "q0": [0, -45, 0, -135, 0, 90, 45, 0.02, 0.02],
        "frames": {"pen": {"parent": "panda_hand_tcp", "xyz": [0, 0, 0.1]}},
        "joint_limits": {"panda_joint4": {"lower": -170, "upper": -10}},
    }
    write_yaml(cfg, "panda.yaml")
    loaded = load_robot("panda.yaml", write_yaml({}, "x.yaml").parent)
    robot = loaded.model
    assert loaded.q0 is not None
    np.testing.assert_allclose(loaded.q0[:7], np.radians([0, -45, 0, -135, 0, 90, 45]))
    assert loaded.q0[7] == 0.02
    j4 = robot.joint("panda_joint4")
    assert (j4.lower, j4.upper) == pytest.approx(np.radians([-170, -10]))
    robot.update(loaded.q0)
    tcp = robot.frame_pose("panda_hand_tcp")
    np.testing.assert_allclose(robot.frame_position("pen"), tcp.act(np.array([0.0, 0.0, 0.1])), atol=1e-12)
    with pytest.raises(ConfigError, match=r"joint_limits.panda_joint9: joint 'panda_joint9' does not exist"):
        load_robot({"urdf": "example-robot-data:panda", "joint_limits": {"panda_joint9": {"lower": 0}}}, Path("."))
    with pytest.raises(ConfigError, match=r"^robot: unknown example robot 'pandaa'; available: .*panda"):
        load_robot("example-robot-data:pandaa", Path("."))
    with pytest.raises(ConfigError, match=r"^robot: give exactly one of 'dh'"):
        load_robot({"urdf": "x.urdf", "dh": [{"name": "1"}]}, Path("."))


def test_dh_table_errors_have_paths() -> None:
    with pytest.raises(ConfigError, match=r"^robot.dh\[1\].type: expected one of"):
        load_robot({"dh": [{"name": "1"}, {"name": "2", "type": "spherical"}]}, Path("."))
    with pytest.raises(ConfigError, match=r"^robot.dh: .*parent frame 'x' is not defined"):
        load_robot({"dh": [{"name": "1", "parent": "x"}]}, Path("."))
    with pytest.raises(ConfigError, match=r"^robot.frames.t.parent: parent frame 'q' does not exist"):
        load_robot({"dh": [{"name": "1"}], "frames": {"t": {"parent": "q"}}}, Path("."))


def test_tree_robot_with_coupled_joint_matches_core_builder(tmp_path: Path) -> None:
    spec = {
        "angle_unit": "deg",
        "dh": [
            {"name": "t1", "a": 0.5},
            {"name": "l2", "a": 1},
            {"name": "r2", "parent": "t1", "joint": "l2", "theta": 30, "a": 1},
        ],
    }
    loaded = load_robot(spec, tmp_path)
    ref = from_dh([DHRow("t1", a=0.5), DHRow("l2", a=1), DHRow("r2", parent="t1", joint="l2", theta=np.pi / 6, a=1)])
    q = np.array([0.3, -0.7])
    loaded.model.update(q)
    ref.update(q)
    for f in ("t1", "l2", "r2"):
        np.testing.assert_allclose(loaded.model.frame_position(f), ref.frame_position(f), atol=1e-12)
    assert ("t1", "r2") in loaded.segments


# ------------------------------------------------------------------------------------------------ runs and monitors
def test_modes_overrides_and_monitors(write_yaml: Callable[..., Path], planar_task_data: dict[str, Any]) -> None:
    d = planar_task_data
    d["steps"] = 20
    d["potentials"]["center"] = {"type": "joint_value", "joint": "2", "value": -40}
    d["monitors"] = {
        "post": {"type": "clearance", "frame": "2", "center": [5, 5, 0], "radius": 0.5, "axes": ["x", "y"]},
        "trace_JWJT": {"type": "best_posture", "frames": "3", "axes": "planar", "weights": [1, 2, 3]},
        "tau": {"type": "torques", "frames": ["3"], "axes": "planar", "force": [-1, 2]},
    }
    d["runs"] = {
        "qp_like": {
            "resolver": "feedback",
            "options": {"epsilon": 0.02},
            "subtasks": {"sin2_q3": {"target": 1.0, "rate": 2}},
            "weights": {"tip": 3},
            "extra_main": [],
        },
        "posture": {
            "main": [{"type": "posture", "target": [100, -30, -20], "gain": 2}],
            "q0": [110, -40, -30],
        },
    }
    plan = load_task(write_yaml(d))
    run = plan.runs["qp_like"]
    sub = run.stack.subtasks[0]
    assert (sub.kind, sub.target, sub.rate) == ("target", 1.0, 2.0)
    assert run.resolver.epsilon == 0.02  # type: ignore[attr-defined]
    assert run.stack.tasks[0].weight == 3.0  # type: ignore[attr-defined]
    assert [p.name for p in run.watched] == ["center"]
    jv = run.watched[0]
    plan.robot.model.update(np.radians([110, -40, -30]))
    assert jv.value(plan.robot.model) == pytest.approx(0.0, abs=1e-24)  # value given in degrees, converted
    posture = plan.runs["posture"].stack.tasks[0]
    np.testing.assert_allclose(posture.target, np.radians([100, -30, -20]))  # type: ignore[attr-defined]
    results = run_task(plan)
    s = results["qp_like"].summary
    assert set(s["monitors"]) == {"post", "trace_JWJT", "tau"}
    robot = plan.robot.model
    q_end = results["qp_like"].log.q[-1]
    robot.update(q_end)
    tip2 = robot.frame_position("2")[:2]
    clearance = [np.linalg.norm(results["qp_like"].log.frame_positions["2"][k, :2] - [5, 5]) - 0.5 for k in range(21)]
    assert s["min_clearance"] == pytest.approx(min(clearance))
    assert np.linalg.norm(tip2 - [5, 5]) - 0.5 == pytest.approx(clearance[-1])
    J = robot.frame_jacobian("3")[:2]
    assert s["trace_JWJT"]["final"] == pytest.approx(float(np.trace(J @ np.diag([1, 2, 3]) @ J.T)))
    tau = J.T @ np.array([-1.0, 2.0])
    assert s["monitors"]["tau"]["max"]["final"] == pytest.approx(float(np.max(np.abs(tau))))
    assert s["monitors"]["tau"]["mean"]["final"] == pytest.approx(float(np.mean(np.abs(tau))))
    # a posture is a regularisation task: logged per task, not counted in the main-task error
    posture_err = results["posture"].summary["task_errors"]["posture"]
    assert posture_err["final"] < posture_err["max"]
    assert results["posture"].summary["max_task_error"] == 0.0


def test_feedback_refuses_more_subtasks_than_null_space(
    write_yaml: Callable[..., Path], planar_task_data: dict[str, Any]
) -> None:
    d = planar_task_data
    d["potentials"]["sin2_q2"] = {"type": "sin2", "joint": "2"}
    d["runs"]["feedback"]["subtasks"]["sin2_q2"] = {"target": 1.0}
    with pytest.raises(ConfigError, match=r"^runs.feedback: feedback: 2 target subtasks but the null space"):
        load_task(write_yaml(d))


def test_monitor_torques_force_length(write_yaml: Callable[..., Path], planar_task_data: dict[str, Any]) -> None:
    planar_task_data["monitors"] = {"tau": {"type": "torques", "frames": ["3"], "force": [-1, 2, 0]}}
    with pytest.raises(ConfigError, match=r"^monitors.tau.force: expected 6 values \(6 axes × 1 frames\), got 3"):
        load_task(write_yaml(planar_task_data))


@pytest.mark.parametrize("task_file", sorted(PLANAR_TASK.parent.glob("*.yaml")), ids=lambda p: p.name)
def test_every_task_file_in_the_repository_validates(task_file: Path) -> None:
    plan = load_task(task_file)
    assert plan.runs and plan.steps >= 1

"""Hostile input and misuse, second pass (after issue 9): what an adversarial review still found.

Each test feeds one bad input and asserts the error says what was wrong, where (the option, the key path, the row,
the joint) and never a traceback, a NaN out, a write outside the output folder or a silent wrong answer.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import redundik as rk
from redundik.errors import ConfigError, ModelError, ResolverError, TaskError
from tests.conftest import CONFIGS, TASKS

ROOT = Path(__file__).resolve().parents[1]
TASK = (TASKS / "planar3r_line.yaml").read_text(encoding="utf-8").replace("../configs/", f"{CONFIGS}/")
SWEEP = (
    (ROOT / "sweeps" / "panda_reach.yaml")
    .read_text(encoding="utf-8")
    .replace("../configs/", f"{CONFIGS}/")
    .replace("num: 160", "num: 2")
    .replace("num: 128", "num: 2")
)

Cli = Callable[..., tuple[int, str, str]]


def _one_line_error(code: int, err: str, expected_code: int = 3) -> None:
    assert code == expected_code, err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err


def _task(tmp_path: Path, steps: int = 3) -> Path:
    path = tmp_path / "t.yaml"
    path.write_text(TASK.replace("steps: 500", f"steps: {steps}"), encoding="utf-8")
    return path


# ------------------------------------------------------------------------------------------------ redundik run
@pytest.mark.parametrize("runs", ["", ",,", " , "])
def test_an_empty_run_selection_is_refused(cli: Cli, tmp_path: Path, runs: str) -> None:
    code, _, err = cli("run", _task(tmp_path), "--runs", runs, "--out", tmp_path / "out", "--no-figures", "-q")
    _one_line_error(code, err)
    assert "--runs" in err and "rank_only" in err  # names the option and lists the runs to choose from
    assert not (tmp_path / "out").exists()


def test_an_output_folder_that_is_a_file_is_refused_before_running(cli: Cli, tmp_path: Path) -> None:
    blocker = tmp_path / "out"
    blocker.write_text("not a folder")
    for target in (blocker, blocker / "sub"):
        code, _, err = cli("run", _task(tmp_path), "--out", target, "--no-figures", "-q")
        _one_line_error(code, err)
        assert "exists and is not a folder" in err and "''" not in err
    assert blocker.read_text() == "not a folder"


@pytest.mark.parametrize("option", ["--html", "--gif"])
def test_html_and_gif_outputs_go_through_safe_path(cli: Cli, tmp_path: Path, option: str) -> None:
    out, outside = tmp_path / "out", tmp_path / "outside"
    out.mkdir()
    outside.mkdir()
    suffix = option.lstrip("-")
    (out / f"planar3r_line.{suffix}").symlink_to(outside / f"stolen.{suffix}")
    code, _, err = cli("run", _task(tmp_path), "--out", out, "--no-figures", "-q", "--runs", "rank_only", option)
    _one_line_error(code, err)
    assert "outside the output folder" in err
    assert list(outside.iterdir()) == []


# ------------------------------------------------------------------------------------------------ redundik view
@pytest.fixture(scope="module")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from redundik.cli.main import main

    out = tmp_path_factory.mktemp("view") / "out"
    task = out.parent / "t.yaml"
    task.write_text(TASK.replace("steps: 500", "steps: 5"), encoding="utf-8")
    assert main(["run", str(task), "--out", str(out), "--no-figures", "--quiet", "--runs", "rank_only"]) == 0
    return out


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--speed", "-1"], "--speed"),
        (["--speed", "0"], "--speed"),
        (["--speed", "nan"], "--speed"),
        (["--loops", "0"], "--loops"),
        (["--loops", "-5"], "--loops"),
        (["--t", "nan", "--png", "x.png"], "--t"),
        (["--t", "-1", "--png", "x.png"], "--t"),
        (["--run", "nope", "--html", "x.html"], "--run"),
    ],
)
def test_view_refuses_bad_options_before_starting(cli: Cli, finished_run: Path, args: list[str], named: str) -> None:
    code, _, err = cli("view", finished_run, *args)
    _one_line_error(code, err)
    assert named in err


@pytest.mark.parametrize(
    ("damage", "expected"),
    [
        (lambda out: (out / "summary.json").write_text("{not json"), "not JSON"),
        (lambda out: (out / "summary.json").write_text("[1, 2]"), "expected an object"),
        (lambda out: _edit_csv(out, 2, 1, "abc"), "rank_only.csv:3: column 'q.1'"),
        (lambda out: _edit_csv(out, 2, 2, "nan"), "rank_only.csv:3: column 'q.2': expected a finite number"),
        (lambda out: _edit_csv(out, 1, None, "1,2"), "rank_only.csv:2: expected"),
        (lambda out: _truncate_csv(out), "has no rows"),
    ],
)
def test_view_refuses_a_damaged_output_folder(
    cli: Cli, finished_run: Path, tmp_path: Path, damage: Callable[[Path], object], expected: str
) -> None:
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(finished_run, out)
    damage(out)
    code, _, err = cli("view", out, "--html", tmp_path / "page.html")
    _one_line_error(code, err)
    assert expected in err
    assert not (tmp_path / "page.html").exists()  # no page drawn from NaN or garbage


def _edit_csv(out: Path, row: int, col: int | None, value: str) -> None:
    path = out / "rank_only.csv"
    lines = path.read_text(encoding="utf-8").splitlines()
    if col is None:
        lines[row] = value
    else:
        cells = lines[row].split(",")
        cells[col] = value
        lines[row] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _truncate_csv(out: Path) -> None:
    path = out / "rank_only.csv"
    path.write_text(path.read_text(encoding="utf-8").splitlines()[0] + "\n", encoding="utf-8")


def test_view_html_into_an_unwritable_place_is_one_line(cli: Cli, finished_run: Path, tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code, _, err = cli("view", finished_run, "--html", blocker / "page.html")
    _one_line_error(code, err)
    assert "--html" in err


# ------------------------------------------------------------------------------------------------ sweep files
def test_validate_knows_sweep_files(cli: Cli, tmp_path: Path) -> None:
    code, out, err = cli("validate", ROOT / "sweeps" / "panda_reach.yaml")
    assert code == 0, err
    assert out.startswith("ok ") and "sweep 'panda_reach'" in out and "20480 problems" in out
    bad = tmp_path / "s.yaml"
    bad.write_text(SWEEP.replace("dt: 1.0 ", "dt: .nan "), encoding="utf-8")
    code, _, err = cli("validate", bad)
    _one_line_error(code, err)
    assert err.startswith("error: convergence.dt:"), err  # the sweep's own key path, not "dt: required key"


def test_a_sweep_of_hours_is_refused_at_validation(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    big = SWEEP.replace("num: 2", "num: 1000").replace("max_iterations: 80", "max_iterations: 10000")
    path.write_text(big, encoding="utf-8")
    code, _, err = cli("validate", path)
    _one_line_error(code, err)
    assert "convergence.max_iterations" in err and "problem-steps" in err


def test_a_sweep_on_a_frame_fixed_to_the_world_is_refused(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(SWEEP.replace("frame: panda_hand_tcp", "frame: panda_link0"), encoding="utf-8")
    code, _, err = cli("validate", path)
    _one_line_error(code, err)
    assert "task.frame" in err and "fixed to the world" in err


def test_a_sweep_into_a_file_is_refused_before_the_work(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(SWEEP, encoding="utf-8")
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code, _, err = cli("sweep", path, "--out", blocker, "-q", "--no-figure")
    _one_line_error(code, err)
    assert "exists and is not a folder" in err


# ------------------------------------------------------------------------------------------------ internal errors
def test_an_unexpected_exception_is_one_line_with_its_own_exit_code(
    cli: Cli, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    import redundik.config.anyfile as anyfile

    def broken(path: object) -> str:
        raise ValueError("something a test broke on purpose")

    monkeypatch.setattr(anyfile, "validate_file", broken)
    code, _, err = cli("validate", _task(tmp_path))
    _one_line_error(code, err, expected_code=70)
    assert "internal error" in err and "ValueError: something a test broke on purpose" in err
    monkeypatch.setenv("REDUNDIK_TRACEBACK", "1")
    with pytest.raises(ValueError, match="broke on purpose"):
        cli("validate", _task(tmp_path))


# ------------------------------------------------------------------------------------------------ Resolver.step
def _planar() -> tuple[rk.RobotModel, rk.TaskStack, np.ndarray]:
    robot = rk.from_dh([rk.DHRow("1", a=1), rk.DHRow("2", a=1), rk.DHRow("3", a=1)])
    stack = rk.TaskStack(
        [rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")], [rk.GradientSubtask(rk.JointSine2("3"))]
    )
    q = np.array([0.3, 0.5, -0.4])
    robot.update(q)
    stack.reset(robot)
    return robot, stack, q


@pytest.mark.parametrize("name", ["pinv", "feedback", "wqp", "hqp"])
@pytest.mark.parametrize(
    ("q", "expected"),
    [
        (np.array([True, False, True]), "dtype bool"),
        (np.array([0.3 + 1j, 0.5, -0.4]), "dtype complex"),
        (np.array(["0.3", "0.5", "-0.4"]), "dtype <U"),
        (np.zeros((3, 2)), "shape (3, 2)"),
    ],
)
def test_step_refuses_q_that_is_not_real_numbers(name: str, q: np.ndarray, expected: str) -> None:
    robot, stack, _ = _planar()
    resolver = rk.make_resolver(name)
    with pytest.raises(ResolverError, match="q must be an array of 3 real numbers") as info:
        resolver.step(robot, stack, q, 0.0, 0.01)
    assert expected in str(info.value)
    res = resolver.step(robot, stack, np.array([0.3, 0.5, -0.4]).reshape(3, 1), 0.0, 0.01)  # a column: still q
    assert np.isfinite(res.dq).all()


# ------------------------------------------------------------------------------------------------ trajectories
@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (lambda: rk.Circle(0.1, 1.0, phase=math.nan), "circle phase"),
        (lambda: rk.Circle(0.1, 1e308), "circle omega"),
        (lambda: rk.Circle(1e300, 1.0), "circle radius"),
        (lambda: rk.Circle(1e7, 1e7), "radius × omega"),
        (lambda: rk.Circle(True, 1.0), "circle radius must be a number, got bool"),  # type: ignore[arg-type]
        (lambda: rk.Line([1e300, 0.0]), "line velocity"),
        (lambda: rk.Line(["a", "b"]), "line velocity: expected 2 numbers, got list"),
        (lambda: rk.PoseInterpolation([0, 0, 0], True), "duration must be a number"),  # type: ignore[arg-type]
    ],
)
def test_trajectories_refuse_nan_and_overflowing_parameters(make: Callable[[], object], expected: str) -> None:
    with pytest.raises(TaskError) as info:
        make()
    assert expected in str(info.value)


def test_pose_interpolation_too_fast_to_represent_is_refused_at_reset() -> None:
    robot, _, _ = _planar()
    task = rk.FrameTask("3", rk.PoseInterpolation([1.0, 0.0, 0.0], 1e-300), axes="planar")
    with pytest.raises(TaskError, match="longer duration"):
        task.reset(robot)


# ------------------------------------------------------------------------------------------------ batches
def _batch(name: str = "pinv", **options: object) -> rk.resolvers.BatchResolver:  # type: ignore[name-defined]
    from redundik.resolvers import BatchResolver

    robot = rk.from_dh([rk.DHRow("1", a=1), rk.DHRow("2", a=1), rk.DHRow("3", a=1)])
    return BatchResolver(rk.make_resolver(name), robot, "3", axes="position", **options)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ({"gain": math.nan}, "gain must be a finite number"),
        ({"gain": True}, "gain must be a number"),
        ({"posture_gain": -1.0}, "posture_gain must be a finite number ≥ 0"),
        ({"posture_target": np.array([math.nan, 0.0, 0.0])}, "batch: posture_target"),
    ],
)
def test_batch_refuses_bad_options(options: dict[str, object], expected: str) -> None:
    with pytest.raises((ResolverError, ModelError)) as info:
        _batch(**options)
    assert expected in str(info.value)


def test_batch_refuses_a_frame_fixed_to_the_world() -> None:
    from redundik.resolvers import BatchResolver

    robot = rk.from_dh([rk.DHRow("1", a=1), rk.DHRow("2", a=1)])
    with pytest.raises(ResolverError, match="frame '0' is fixed to the world"):
        BatchResolver(rk.make_resolver("pinv"), robot, "0")


@pytest.mark.parametrize("name", ["pinv", "wqp"])
def test_batch_refuses_bad_arrays_and_accepts_an_empty_batch(name: str) -> None:
    br = _batch(name)
    q = np.zeros((2, 3))
    targets = np.stack([np.eye(4)] * 2)
    targets[:, 0, 3] = 1.5
    cases: list[tuple[object, object, object, str]] = [
        (np.float64(1.0), targets, 0.01, "expected q (N, 3)"),
        (q.astype(bool), targets, 0.01, "q must be an array of real numbers, got dtype bool"),
        (q.astype(complex), targets, 0.01, "dtype complex"),
        (q, targets * 2.0, 0.01, "targets of problems [0, 1] are not rigid transforms"),
        (q, np.where(np.eye(4) > 0, np.nan, targets), 0.01, "targets of problems [0, 1] contain NaN"),
        (q, targets, True, "dt must be a number [s], got bool"),
        (q, targets, "0.01", "dt must be a number [s], got str"),
        (q, targets, 0.0, "dt must be finite and > 0"),
    ]
    for qq, tt, dt, expected in cases:
        with pytest.raises(ResolverError) as info:
            br.solve(qq, tt, dt)  # type: ignore[arg-type]
        assert expected in str(info.value), (expected, str(info.value))
    empty = br.solve(np.zeros((0, 3)), np.zeros((0, 4, 4)), 0.01)
    assert empty.dq.shape == (0, 3)
    assert np.isfinite(br.solve(q, targets, 0.01).dq).all()


# ------------------------------------------------------------------------------------------------ robots
@pytest.mark.parametrize(
    ("rows", "expected"),
    [
        ([rk.DHRow("1", a=1, velocity=-1.0)], "row 1 ('1'): velocity limit must be ≥ 0"),
        ([rk.DHRow("1", a=1, velocity=math.nan)], "velocity limit must be ≥ 0"),
        ([rk.DHRow("1", a=1, lower=math.inf)], "leave no position"),
        ([rk.DHRow("1", a=1, upper=-math.inf)], "leave no position"),
        ([rk.DHRow("", a=1)], "row 1: name must be a non-empty string"),
        ([rk.DHRow(1, a=1)], "row 1: name must be a non-empty string"),  # type: ignore[arg-type]
        ([rk.DHRow("1", a="1")], "row 1 ('1'): a must be a number, got str"),  # type: ignore[arg-type]
        ([rk.DHRow("1", a=True)], "a must be a number, got bool"),
        ([rk.DHRow("1", a=1e308)], "a = 1e+308 is larger than 1e+06"),
        ([rk.DHRow("1", a=1, kind="fixed")], "has no moving joint"),
        ([{"name": "1"}], "row 1: expected a DHRow, got dict"),
        (None, "rows must be a list of DHRow"),
    ],
)
def test_dh_tables_refuse_nonsense_naming_the_row(rows: object, expected: str) -> None:
    with pytest.raises(ModelError) as info:
        rk.from_dh(rows)  # type: ignore[arg-type]
    assert expected in str(info.value)


def test_dh_base_must_be_homogeneous() -> None:
    base = np.eye(4)
    base[3] = (1.0, 1.0, 1.0, 5.0)
    with pytest.raises(ModelError, match="last row must be"):
        rk.from_dh([rk.DHRow("1", a=1)], base=base)


_JOINT = (
    "<robot name='x'><link name='a'/><link name='b'/><joint name='j1' type='revolute'><parent link='a'/>"
    "<child link='b'/><axis xyz='{axis}'/><limit lower='{lower}' upper='{upper}' effort='1' velocity='1'/></joint>"
    "</robot>"
)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (_JOINT.format(axis="0 0 1", lower=2, upper=1), "joint 'j1': limits must satisfy lower ≤ upper"),
        (_JOINT.format(axis="0 0 0", lower=-1, upper=1), "joint 'j1' has a zero axis"),
        ("<robot name='x'><link name='a'/></robot>", "has no moving joint"),
    ],
)
def test_urdf_robots_no_resolver_could_use_are_refused(tmp_path: Path, text: str, expected: str) -> None:
    path = tmp_path / "r.urdf"
    path.write_text(text)
    with pytest.raises(ModelError) as info:
        rk.from_urdf(path)
    assert expected in str(info.value)
    with pytest.raises(ModelError, match="URDF path must be a file path"):
        rk.from_urdf(None)  # type: ignore[arg-type]


def test_update_and_integrate_refuse_nan_and_wrong_sizes() -> None:
    robot = rk.from_dh([rk.DHRow("1", a=1), rk.DHRow("2", a=1)])
    q = np.zeros(2)
    with pytest.raises(ModelError, match=r"update\(q\): q contains NaN"):
        robot.update(np.array([math.nan, 0.0]))
    with pytest.raises(ModelError, match="expected 2 values"):
        robot.update(np.zeros(3))
    with pytest.raises(ModelError, match="dq contains NaN"):
        robot.integrate(q, np.array([math.nan, 0.0]), 0.01)
    with pytest.raises(ModelError, match="dt must be a finite number"):
        robot.integrate(q, np.zeros(2), math.nan)
    with pytest.raises(ModelError, match="dq has 3 entries"):
        robot.integrate(q, np.zeros(3), 0.01)
    with pytest.raises(ModelError, match="q must be 2 real numbers"):
        robot.integrate(np.zeros(3), np.zeros(2), 0.01)
    np.testing.assert_allclose(robot.integrate(q, np.ones(2), 0.5), [0.5, 0.5])


def test_the_config_layer_still_reports_robot_errors_with_the_key_path(tmp_path: Path) -> None:
    from redundik.config import load_task

    path = tmp_path / "t.yaml"
    text = TASK.replace(f"robot: {CONFIGS}/planar3r.yaml", "robot: {dh: [{name: '1', a: 1, type: fixed}]}")
    path.write_text(text, encoding="utf-8")
    with pytest.raises((ConfigError, ModelError), match="no moving joint"):
        load_task(path)


# ------------------------------------------------------------------------------------------------ stacks, resolvers
@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (lambda: rk.TaskStack(None), "stack.tasks: expected a list, got NoneType"),  # type: ignore[arg-type]
        (lambda: rk.TaskStack({"a": rk.PostureTask()}), "stack.tasks: expected a list, got dict"),  # type: ignore[arg-type]
        (lambda: rk.TaskStack(["x"]), "stack.tasks[0]: expected a Task, got str"),  # type: ignore[list-item]
        (
            lambda: rk.TaskStack([rk.GradientSubtask(rk.JointSine2("3"))]),  # type: ignore[list-item]
            "stack.tasks[0]: expected a Task, got GradientSubtask (a subtask belongs in the second list",
        ),
        (
            lambda: rk.TaskStack([], [rk.PostureTask()]),  # type: ignore[list-item]
            "stack.subtasks[0]: expected a Subtask, got PostureTask (a task belongs in the first list",
        ),
        (lambda: rk.TaskStack([rk.PostureTask(), rk.PostureTask()]), "repeated: ['posture']"),
    ],
)
def test_a_stack_refuses_what_it_cannot_hold_when_it_is_made(make: Callable[[], object], expected: str) -> None:
    with pytest.raises(ResolverError) as info:
        make()
    assert expected in str(info.value)


def test_make_resolver_with_a_name_that_is_not_a_string() -> None:
    with pytest.raises(ResolverError, match=r"unknown resolver \['pinv'\]; available"):
        rk.make_resolver(["pinv"])  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({"dt": 0.0, "steps": 3}, "dt must be finite and > 0"),
        ({"dt": True, "steps": 3}, "dt must be a number"),
        ({"dt": 0.01, "steps": -1}, "steps must be ≥ 0"),
        ({"dt": 0.01, "steps": 2.5}, "steps must be a whole number"),
        ({"dt": 0.01, "steps": 10**12}, "GiB"),
    ],
)
def test_simulate_refuses_a_bad_time_grid_before_allocating(kwargs: dict[str, object], expected: str) -> None:
    from redundik.errors import SimulationError

    robot, stack, q = _planar()
    with pytest.raises(SimulationError) as info:
        rk.simulate(robot, stack, rk.make_resolver("pinv"), q, **kwargs)  # type: ignore[arg-type]
    assert expected in str(info.value)
    log = rk.simulate(robot, stack, rk.make_resolver("pinv"), q, dt=0.01, steps=2)
    assert log.q.shape == (3, 3) and np.isfinite(log.q).all()


# ------------------------------------------------------------------------------------------------ parallel commands
_FK = ["stewart", "fk", str(CONFIGS / "stewart33.yaml"), "--legs", *(["1.861", "1.5044"] * 3), "--method", "exact"]
_STATICS = ["stewart", "statics", str(CONFIGS / "stewart66.yaml"), "--p", "0", "0", "1", "--wrench"]
_ANIMATE = ["stewart", "animate", str(CONFIGS / "stewart33.yaml"), "--p", "0", "0", "1.5", "--to-p", "0", "0", "1.6"]


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["stewart", "ik", CONFIGS / "stewart33.yaml", "--p", "0", "0", "1e308", "--json"], "--p: values must be"),
        (["stewart", "ik", CONFIGS / "stewart33.yaml", "--p", "0", "0", "1", "--rpy", "0", "0", "1e308"], "--rpy"),
        ([*_STATICS, "0", "0", "1e308", "0", "0", "1e308", "--json"], "--wrench: values must be"),
        (["delta", "ik", CONFIGS / "delta.yaml", "--top", "0", "0", "1e300"], "--top: values must be"),
        (["hybrid33", "ik", CONFIGS / "hybrid33_rect.yaml", "--p", "0", "0", "1e308", "--json"], "--p"),
    ],
)
def test_parallel_commands_never_print_inf_or_nan(cli: Cli, args: list[object], expected: str) -> None:
    code, out, err = cli(*args)
    _one_line_error(code, err)
    assert expected in err and out == ""  # no "Infinity" / "NaN" in a JSON document on stdout


def test_a_non_finite_parallel_result_is_refused_not_printed() -> None:
    from redundik.cli import parallel_cmds
    from redundik.errors import MechanismError

    with pytest.raises(MechanismError, match=r"not finite at 'lengths\[1\]'"):
        parallel_cmds._emit({"lengths": [1.0, math.inf]}, True, "IK", [])


@pytest.mark.parametrize(
    "args",
    [
        [*_FK, "--starts", "-5"],
        [*_FK, "--starts", "100000000"],
        [*_ANIMATE, "--frames", "100000000", "--out", "x.gif"],
    ],
)
def test_parallel_counts_are_bounded(cli: Cli, args: list[object]) -> None:
    code, _, err = cli(*args)
    assert code == 2 and ("--starts" in err or "--frames" in err), err  # a usage error, before any work


@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (lambda: rk.JointValue("3", True), "value must be a number, got bool"),
        (lambda: rk.JointValue("3", "x"), "value must be a number, got str"),  # type: ignore[arg-type]
        (lambda: rk.JointSine2(3), "JointSine2: joint must be a joint name (a string), got 3"),  # type: ignore[arg-type]
        (lambda: rk.JointSine2(None), "got None"),  # type: ignore[arg-type]
        (lambda: rk.VirtualPoint("3", ["a", "b", "c"]), "point: expected real numbers"),
        (lambda: rk.Clearance(None, [0, 0, 0]), "frame must be a frame name"),  # type: ignore[arg-type]
    ],
)
def test_potentials_refuse_values_that_are_not_numbers_or_names(make: Callable[[], object], expected: str) -> None:
    with pytest.raises(TaskError) as info:
        make()
    assert expected in str(info.value)


# ------------------------------------------------------------------------------------------------ task files
def _mutated(tmp_path: Path, change: Callable[[dict[str, object]], None]) -> Path:
    import yaml

    data = yaml.safe_load(TASK.replace("steps: 500", "steps: 5"))
    change(data)
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(data, allow_unicode=True), encoding="utf-8")
    return path


def _potential_named_tip(d: dict[str, object]) -> None:
    d["potentials"] = {"tip": {"type": "sin2", "joint": "2"}}
    d["runs"] = {"a": {"resolver": "pinv", "subtasks": {"tip": {"gain": 1.0}}}}


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (_potential_named_tip, "error: runs.a.subtasks.tip: potential 'tip' has the name of a main task"),
        (lambda d: d.update(integrator="rk45", rtol=1e-300), "error: rtol: must be ≥ 1e-13"),
        (
            lambda d: d["main"][0].update(  # type: ignore[index]
                trajectory={"type": "pose", "position": [1, 1, 0], "duration": 1e-300}
            ),
            "error: main[0].trajectory.duration: must be ≥ 1e-06",
        ),
    ],
)
def test_task_file_mistakes_are_invalid_input_with_their_key_path(
    cli: Cli, tmp_path: Path, change: Callable[[dict[str, object]], None], expected: str
) -> None:
    path = _mutated(tmp_path, change)
    for command in ("validate", "run"):
        code, _, err = cli(command, path, *(["--out", tmp_path / "out", "--no-figures", "-q"] * (command == "run")))
        _one_line_error(code, err)  # exit 3 (invalid input), not 4 (a run failure) nor a SciPy warning
        assert err.startswith(expected), err
    assert not (tmp_path / "out").exists()


def test_the_schema_and_the_integrator_agree_on_the_smallest_rtol() -> None:
    from redundik.config.schema import RTOL_MIN
    from redundik.simulation.integrators import RTOL_MIN as INTEGRATOR_RTOL_MIN
    from redundik.simulation.integrators import check_tolerances

    assert RTOL_MIN == INTEGRATOR_RTOL_MIN
    with pytest.raises(ValueError, match="rtol must be in"):
        check_tolerances(RTOL_MIN / 10, 1e-12)
    check_tolerances(RTOL_MIN, 1e-300)


# ------------------------------------------------------------------------------------------------ examples copy
@pytest.mark.parametrize("link", ["tasks/planar3r_line.yaml", "configs"])
def test_examples_copy_never_writes_through_a_symlink(cli: Cli, tmp_path: Path, link: str) -> None:
    target, outside = tmp_path / "ex", tmp_path / "outside"
    (target / "tasks").mkdir(parents=True)
    outside.mkdir()
    (target / link).symlink_to(outside / "x" if link.endswith(".yaml") else outside)
    code, _, err = cli("examples", "copy", target)
    _one_line_error(code, err)
    assert "refusing to copy into" in err and "symlink or resolves outside" in err
    assert list(outside.iterdir()) == []
    assert not (target / "tasks" / "rpr_corner.yaml").exists()  # checked before the first write: nothing copied


def test_examples_copy_says_what_it_kept(cli: Cli, tmp_path: Path) -> None:
    assert cli("examples", "copy", tmp_path / "ex")[0] == 0
    mine = tmp_path / "ex" / "tasks" / "planar3r_line.yaml"
    mine.write_text("# my edits\n")
    code, _, err = cli("examples", "copy", tmp_path / "ex")
    assert code == 0 and "copied 0 files" in err and "kept" in err and "--force" in err
    assert mine.read_text() == "# my edits\n"


def test_a_write_the_file_system_refuses_is_one_line(cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A read-only folder or a full disk (simulated: a root user may write anywhere) is exit 3, not a traceback."""
    task = _task(tmp_path)
    real_open = Path.open

    def refuse(path: Path, mode: str = "r", *args: object, **kwargs: object) -> object:
        if "w" in mode and path.suffix == ".csv":
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, mode, *args, **kwargs)  # type: ignore[call-overload]

    monkeypatch.setattr(Path, "open", refuse)
    code, _, err = cli("run", task, "--out", tmp_path / "out", "--no-figures", "-q", "--runs", "rank_only")
    _one_line_error(code, err)
    assert "Permission denied" in err and "rank_only.csv" in err


@pytest.mark.parametrize(
    ("command", "file", "expected"),
    [
        ("sweep", TASKS / "planar3r_line.yaml", "is a task file, not a sweep file: run it with `redundik run"),
        ("run", ROOT / "sweeps" / "panda_reach.yaml", "is a sweep file, not a task file: run it with `redundik sweep"),
        ("run", CONFIGS / "planar3r.yaml", "is a robot file, not a task file"),
        ("run", CONFIGS / "stewart33.yaml", "is a mechanism file, not a task file"),
    ],
)
def test_a_file_of_another_kind_is_named_as_such(
    cli: Cli, tmp_path: Path, command: str, file: Path, expected: str
) -> None:
    code, _, err = cli(command, file, "--out", tmp_path / "out")
    _one_line_error(code, err)
    assert expected in err  # not "task: required key is missing (and 8 more errors)"
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ("sim_dt: 0.001 ", "sim_dt: 0.003 ", "error: plant.sim_dt: sim_dt = 0.003 s must divide the control dt"),
        ("sim_dt: 0.001 ", "sim_dt: 0.01 ", "error: plant.sim_dt: sim_dt = 0.01 s must divide"),
        ("sim_dt: 0.001 ", "sim_dt: 1e-9 ", "error: plant.sim_dt: sim_dt = 1e-09 s gives 5000000 physics steps"),
        ("kp: 2000.0 ", "kp: -5 ", "error: plant.kp: must be ≥ 0"),
    ],
)
def test_plant_rates_and_gains_are_checked_at_validation(
    cli: Cli, tmp_path: Path, old: str, new: str, expected: str
) -> None:
    text = (TASKS / "panda_mujoco.yaml").read_text(encoding="utf-8").replace("../configs/", f"{CONFIGS}/")
    assert old in text
    path = tmp_path / "p.yaml"
    path.write_text(text.replace(old, new), encoding="utf-8")
    code, _, err = cli("validate", path)  # run would fail building the plant (sim_dt) or run for hours (1e-9)
    _one_line_error(code, err)
    assert err.startswith(expected), err


def test_hold_and_pose_interpolation_refuse_what_is_not_a_pose() -> None:
    import pinocchio as pin

    bad = pin.SE3.Identity()
    bad.translation = np.array([math.nan, 0.0, 0.0])
    with pytest.raises(TaskError, match="hold pose: contains NaN"):
        rk.Hold(bad)
    with pytest.raises(TaskError, match="hold pose: expected an SE3 or a 4×4"):
        rk.Hold("x")  # type: ignore[arg-type]
    with pytest.raises(TaskError, match="not a rigid transform"):
        rk.Hold(2.0 * np.eye(4))
    assert rk.Hold(np.eye(4)).pose == pin.SE3.Identity()  # a 4×4 matrix is a pose
    with pytest.raises(TaskError, match="goal rotation must be a 3×3 matrix of numbers"):
        rk.PoseInterpolation([0, 0, 0], 1.0, rotation="x")  # type: ignore[arg-type]


@pytest.mark.parametrize("name", ["pinv", "feedback", "wqp", "hqp"])
def test_step_with_the_wrong_kind_of_robot_or_stack_says_so(name: str) -> None:
    robot, stack, q = _planar()
    resolver = rk.make_resolver(name)
    for bad in (list(stack.tasks), None, stack.tasks[0]):
        with pytest.raises(ResolverError, match=f"{name}: stack must be a TaskStack .*, got {type(bad).__name__}"):
            resolver.step(robot, bad, q, 0.0, 0.01)  # type: ignore[arg-type]
    for bad_robot in (None, robot.model):
        with pytest.raises(ResolverError, match=f"robot must be a RobotModel, got {type(bad_robot).__name__}"):
            resolver.step(bad_robot, stack, q, 0.0, 0.01)  # type: ignore[arg-type]
    assert np.isfinite(resolver.step(robot, stack, q, 0.0, 0.01).dq).all()  # and the loop goes on


def test_simulate_with_the_wrong_kind_of_argument_says_so() -> None:
    from redundik.errors import SimulationError

    robot, stack, q = _planar()
    with pytest.raises(SimulationError, match="stack must be a TaskStack, got list"):
        rk.simulate(robot, list(stack.tasks), rk.make_resolver("pinv"), q, dt=0.01, steps=2)  # type: ignore[arg-type]
    with pytest.raises(SimulationError, match="resolver must be a Resolver"):
        rk.simulate(robot, stack, "pinv", q, dt=0.01, steps=2)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("target", "expected"),
    [
        ([1e308, 0.0, 0.0], "coordinate beyond"),
        ([True, False, True], "got bool values"),
        ([1 + 2j, 0, 0], "got complex128 values"),
        ("abc", "of real numbers"),
    ],
)
def test_frame_target_that_is_absurd_or_not_numbers_is_refused(target: object, expected: str) -> None:
    task = rk.FrameTask("panda_hand")
    with pytest.raises(rk.TaskError, match=expected):
        task.set_target(target)
    far = np.eye(4)
    far[:3, 3] = (0.0, -2e6, 0.0)
    with pytest.raises(rk.TaskError, match="beyond"):
        task.set_target(far)


def test_posture_target_of_booleans_or_strings_is_refused() -> None:
    with pytest.raises(rk.TaskError, match=r"posture task 'posture': target: .*bool"):
        rk.PostureTask(target=[True] * 9)
    with pytest.raises(rk.TaskError, match=r"set_target: .*real numbers"):
        rk.PostureTask().set_target(["a"] * 9)


def test_posture_target_beyond_a_million_is_refused_where_it_is_set() -> None:
    """A posture 1e308 rad away asked wqp (no limits) for ~1e307 rad/s: now refused, naming the coordinate."""
    with pytest.raises(rk.TaskError, match=r"posture task 'posture': target: coordinate 1 = 1e\+308 is beyond"):
        rk.PostureTask(target=[0.0, 1e308, 0.0])
    posture = rk.PostureTask(target=[0.0, 1.0, 0.0])
    with pytest.raises(rk.TaskError, match=r"set_target: coordinate 0 = -2e\+06 is beyond"):
        posture.set_target([-2e6, 0.0, 0.0])
    np.testing.assert_array_equal(posture.target, [0.0, 1.0, 0.0])  # the refused target left the old one in place

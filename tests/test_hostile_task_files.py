"""Hostile task files and robot configs at validation: the first error is the one the user made, named by its key
path (plant gains, resolver options at every depth, monitor and potential names, paths that are not files, union
values, targets a position task would ignore, stall windows, plant rates), with what was expected."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

import redundik as rk
from redundik.errors import ConfigError, ModelError, TaskError
from tests.conftest import CONFIGS, TASKS
from tests.hostile import ROBOT, ROOT, SWEEP, TASK, Cli, _one_line_error, _write


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (SWEEP.replace("num: 2", "num: 1000000000", 1), "error: targets.grid.x.num: must be ≤ 1000000, got 1000000000"),
        (SWEEP.replace("num: 2", "num: 0", 1), "error: targets.grid.x.num: must be ≥ 1, got 0"),
        (SWEEP.replace("start: -1.0", "start: .nan", 1), "error: targets.grid.x.start: expected a finite number"),
        (
            SWEEP.replace("target: home", "target: [.nan, 0, 0, 0, 0, 0, 0, 0, 0]"),
            "error: task.posture.target[0]: expected a finite number, got nan",
        ),
        (SWEEP.replace("plane: [x, z]", "plane: [x, x]"), "error: figure.plane: expected two different axes"),
        (SWEEP.replace(f"robot: {CONFIGS}/panda.yaml", "robot: 5"), "error: robot: expected a config path"),
        (TASK.replace(f"robot: {CONFIGS}/planar3r.yaml", "robot: [a]"), "error: robot: expected a config path"),
        # YAML 1.1 reads an unquoted on/off/yes/no as a boolean: the error says so
        (
            TASK.replace("name: planar3r_line", "name: on"),
            "error: name: expected a string, got True (YAML reads an unquoted yes, no, on, off, true or false as a "
            "boolean: quote the text, e.g. 'on')",
        ),
        (
            TASK.replace("resolver: feedback", "resolver: off"),
            "error: runs.feedback.resolver: expected a string, got False (YAML reads",
        ),
    ],
)
def test_the_error_reported_is_the_one_the_user_made(cli: Cli, tmp_path: Path, text: str, expected: str) -> None:
    """A value checked against a union (a number or a range; 'home' or a list) reported the member it was never
    meant for ("targets.grid.x: expected a number, got {'num': ...} (and 1 more error)"); a check written on the
    whole file reported "(top level): figure.plane" instead of the key."""
    code, _, err = cli("validate", _write(tmp_path, text))
    _one_line_error(code, err)
    assert err.startswith(expected), err
    assert "(and 1 more error)" not in err and "(top level)" not in err


def test_a_plant_gain_mapping_names_the_joint(cli: Cli, tmp_path: Path) -> None:
    text = (TASKS / "panda_mujoco.yaml").read_text(encoding="utf-8").replace("../configs/", f"{CONFIGS}/")
    assert "kp: 2000.0 " in text
    code, _, err = cli("validate", _write(tmp_path, text.replace("kp: 2000.0 ", "kp: {panda_joint1: -5} ")))
    _one_line_error(code, err)
    assert err.startswith("error: plant.kp.panda_joint1: must be ≥ 0"), err


@pytest.mark.parametrize(
    ("urdf", "expected"),
    [
        ("{folder}", "cannot be read: it is a folder, not a file"),
        ("/dev/null", "cannot be read: it is not a regular file"),
        ("''", "urdf: expected a URDF path or 'example-robot-data:NAME', got an empty string"),
        ("/nonexistent/r.urdf", "URDF file '/nonexistent/r.urdf' does not exist"),
    ],
)
def test_a_urdf_path_that_is_not_a_file_says_what_it_is(cli: Cli, tmp_path: Path, urdf: str, expected: str) -> None:
    """A folder, a device or ``''`` (the config's own folder) were all "URDF file ... does not exist"."""
    (tmp_path / "meshes.urdf").mkdir()
    robot = _write(tmp_path, f"name: x\nurdf: {urdf.format(folder=tmp_path / 'meshes.urdf')}\n", "r.yaml")
    code, _, err = cli("validate", robot)
    _one_line_error(code, err)
    assert err.startswith("error: r.yaml: urdf: ") and expected in err, err


@pytest.mark.parametrize(
    ("robot", "expected"),
    [
        (str(CONFIGS), "robot: robot config '" + str(CONFIGS) + "' cannot be read: it is a folder, not a file"),
        ("''", "robot: expected a robot config path, 'example-robot-data:NAME' or an inline mapping, got an empty"),
    ],
)
def test_a_robot_config_path_that_is_not_a_file_says_what_it_is(
    cli: Cli, tmp_path: Path, robot: str, expected: str
) -> None:
    code, _, err = cli("validate", _write(tmp_path, TASK.replace(f"robot: {CONFIGS}/planar3r.yaml", f"robot: {robot}")))
    _one_line_error(code, err)
    assert err.startswith(f"error: {expected}"), err


def test_a_folder_given_as_the_task_file_is_named_a_folder(cli: Cli, tmp_path: Path) -> None:
    code, _, err = cli("validate", tmp_path)
    _one_line_error(code, err)
    assert "it is a folder, not a file" in err


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ('name: "1"', "name: universe", "dh[0].name: 'universe' is the name of Pinocchio's world frame"),
        ('name: "1"', 'name: "a\\0b"', "dh[0].name: 'a\\x00b': a name must be printable text"),
        ('name: "1"', 'name: "a\\nb"', "dh[0].name: 'a\\nb': a name must be printable text"),
        ('base_frame: "0"', 'base_frame: ""', "base_frame: expected a non-empty name"),
        ('base_frame: "0"', "base_frame: universe", "base_frame: 'universe' is the name of Pinocchio's world frame"),
        ("name: planar3r", 'name: "\\e[31mred"', "name: '\\x1b[31mred': a name must be printable text"),
        ("q0: [", "frames: {universe: {parent: '3'}}\nq0: [", "frames.universe: 'universe' is the name of Pinocchio's"),
    ],
)
def test_robot_config_names_are_printable_and_not_pinocchios_world(
    cli: Cli, tmp_path: Path, old: str, new: str, expected: str
) -> None:
    """A D-H row named 'universe' was an internal error (exit 70, "Several frames match the filter"); NUL and
    escape characters went into CSV headers, figures (matplotlib warnings on stderr) and the terminal."""
    assert old in ROBOT
    robot = _write(tmp_path, ROBOT.replace(old, new, 1), "r.yaml")
    code, _, err = cli("validate", robot)
    _one_line_error(code, err)
    assert err.startswith(f"error: r.yaml: {expected}"), err
    task = _write(tmp_path, TASK.replace(f"{CONFIGS}/planar3r.yaml", str(robot)))
    code, _, err = cli("run", task, "--out", tmp_path / "out", "--no-figures", "-q", "--runs", "rank_only")
    _one_line_error(code, err)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        ('monitors:\n  "a\\0b": {type: sin2, joint: "3"}\n', "error: monitors.'a\\x00b': name 'a\\x00b' is not valid"),
        ('monitors:\n  "\\e[2J": {type: sin2, joint: "3"}\n', "error: monitors.'\\x1b[2J': name"),
        ('monitors:\n  "a,b": {type: sin2, joint: "3"}\n', "error: monitors.a,b: name 'a,b' is not valid"),
    ],
)
def test_monitor_and_potential_names_follow_the_name_rule(cli: Cli, tmp_path: Path, extra: str, expected: str) -> None:
    """Uncontrolled potentials and monitors took any name: it became a CSV column and a summary.json key."""
    code, _, err = cli("validate", _write(tmp_path, TASK + extra))
    _one_line_error(code, err)
    assert err.startswith(expected), err
    text = TASK.replace("  sin2_q3: {type: sin2", '  "p\\0": {type: sin2').replace("steps: 500", "steps: 3")
    code, _, err = cli("run", _write(tmp_path, text), "--out", tmp_path / "out", "--no-figures", "-q")
    _one_line_error(code, err)
    assert err.startswith("error: potentials.'p\\x00': name"), err
    assert not (tmp_path / "out").exists()


def test_joint_centering_refuses_negative_weights(cli: Cli, tmp_path: Path) -> None:
    """A negative weight turned centering into pushing that joint away from the centre, silently."""
    with pytest.raises(TaskError, match=r"weights must be ≥ 0 .* got weights\[1\] = -1"):
        rk.JointCentering(weights=[1.0, -1.0, 1.0])
    assert rk.JointCentering(weights=[0.0, 1.0, 1.0]).weights is not None  # 0 = leave the joint out: fine
    text = TASK.replace('sin2_q3: {type: sin2, joint: "3"}', "sin2_q3: {type: joint_centering, weights: [1, -1, 1]}")
    code, _, err = cli("validate", _write(tmp_path, text))
    _one_line_error(code, err)  # was exit 70: the docstring's "≥ 0" became a pydantic bound on a list
    assert err.startswith("error: potentials.sin2_q3: ") and "weights must be ≥ 0" in err, err


def test_no_list_parameter_of_a_yaml_type_gets_a_scalar_bound() -> None:
    import redundik.config.loader  # noqa: F401  (registers every type)
    from redundik.config import registry

    for section in registry.SECTIONS.values():
        for entry in section.values():
            for key, f in entry.model.model_fields.items():
                if not registry._is_scalar(f.annotation):
                    assert not any(hasattr(m, "ge") or hasattr(m, "gt") for m in f.metadata), (entry.name, key)


def test_a_value_refused_by_every_member_of_a_union_counts_as_one_error(cli: Cli, tmp_path: Path) -> None:
    """A union reports one error per member at the same key: they are one mistake, not "(and 1 more error)"."""
    code, _, err = cli("validate", _write(tmp_path, SWEEP.replace("x: {start: -1.0, stop: 1.0, num: 2}", "x: abc")))
    _one_line_error(code, err)
    assert err == "error: targets.grid.x: expected a number, got 'abc'\n", err
    two = SWEEP.replace("x: {start: -1.0, stop: 1.0, num: 2}", "x: abc").replace("y: 0.0", "y: def")
    code, _, err = cli("validate", _write(tmp_path, two))
    assert err == "error: targets.grid.x: expected a number, got 'abc' (and 1 more error)\n", err  # two keys: two


def _with_options(resolver: str, options: str) -> str:
    line = f"    resolver: {resolver}\n"
    assert line in TASK
    return TASK.replace(line, f"{line}    options: {options}\n", 1)


@pytest.mark.parametrize(
    ("resolver", "options", "expected"),
    [
        ("wqp", "{limits: {position: 'no'}}", "runs.wqp.options.limits.position: expected true or false, got 'no'"),
        ("wqp", "{limits: {velocity: .nan}}", "runs.wqp.options.limits.velocity: expected a finite number, got nan"),
        ("wqp", "{limits: {position: 0}}", "runs.wqp.options.limits.position: expected true or false, got 0"),
        (
            "wqp",
            "{limits: {position_gain: true}}",
            "runs.wqp.options.limits.position_gain: expected a number, got True",
        ),
        ("wqp", "{damping: true}", "runs.wqp.options.damping: expected a number, got True"),
        ("wqp", "{damping: [.nan]}", "runs.wqp.options.damping[0]: expected a finite number, got nan"),
        ("wqp", "{limits: {lower: [1]}}", "runs.wqp.options.limits.lower: expected a mapping of joint name → number"),
        ("wqp", "{limits: {acceleration: {'1': true}}}", "runs.wqp.options.limits.acceleration.1: expected a number"),
        ("wqp", "{levels: 5}", "runs.wqp.options.levels: expected a mapping {task or subtask name: level} or a list"),
        ("hqp", "{regularization: true}", "runs.hqp.options.regularization: expected a number, got True"),
        ("feedback", "{d_epsilon: true}", "runs.feedback.options.d_epsilon: expected a number, got True"),
    ],
)
def test_resolver_options_are_checked_for_kind_at_every_depth(
    cli: Cli, tmp_path: Path, resolver: str, options: str, expected: str
) -> None:
    """``limits: {position: "no"}`` was ``bool("no")`` = limits on; ``damping: true`` a damping of 1; a NaN under
    ``limits`` a truthy flag; ``lower: [1]`` "cannot convert dictionary update sequence element #0"."""
    code, _, err = cli("validate", _write(tmp_path, _with_options(resolver, options)))
    _one_line_error(code, err)
    assert err.startswith(f"error: {expected}"), err


def test_well_formed_resolver_options_are_still_accepted(cli: Cli, tmp_path: Path) -> None:
    for resolver, options in (
        ("wqp", "{limits: {position: false, velocity: true, acceleration: 5, lower: {'1': -3}}, damping: 1.0e-6}"),
        ("hqp", "{rcond: 1.0e-9, levels: [[tip]]}"),
    ):
        code, _, err = cli("validate", _write(tmp_path, _with_options(resolver, options)))
        assert code == 0, (options, err)


def test_a_stall_window_that_could_never_fire_is_refused(cli: Cli, tmp_path: Path) -> None:
    """A stall window of max_iterations steps or more compares the error over more steps than a problem runs."""
    text = SWEEP.replace("stall: {window: 10,", "stall: {window: 80,")
    assert text != SWEEP
    code, _, err = cli("validate", _write(tmp_path, text))
    _one_line_error(code, err)
    assert "convergence" in err and "stall.window (80) must be < max_iterations (80)" in err, err
    code, _, err = cli("validate", _write(tmp_path, SWEEP.replace("stall: {window: 10,", "stall: {window: 79,")))
    assert code == 0, err


def test_the_config_layer_still_reports_robot_errors_with_the_key_path(tmp_path: Path) -> None:
    from redundik.config import load_task

    path = tmp_path / "t.yaml"
    text = TASK.replace(f"robot: {CONFIGS}/planar3r.yaml", "robot: {dh: [{name: '1', a: 1, type: fixed}]}")
    path.write_text(text, encoding="utf-8")
    with pytest.raises((ConfigError, ModelError), match="no moving joint"):
        load_task(path)


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

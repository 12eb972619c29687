"""Hostile input, third pass: what a sweep over every option, key and name still found.

Each test feeds one bad input and asserts the error is one line naming what was wrong, where (the option, the key
path, the joint) and what was expected; nothing is written outside the output folder; nothing hangs.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import redundik as rk
from redundik.errors import TaskError
from redundik.reporting.paths import OutputPathError, check_output_folder, safe_path
from tests.conftest import CONFIGS, TASKS

ROOT = Path(__file__).resolve().parents[1]
TASK = (TASKS / "planar3r_line.yaml").read_text(encoding="utf-8").replace("../configs/", f"{CONFIGS}/")
ROBOT = (CONFIGS / "planar3r.yaml").read_text(encoding="utf-8")
SWEEP = (
    (ROOT / "sweeps" / "panda_reach.yaml")
    .read_text(encoding="utf-8")
    .replace("../configs/", f"{CONFIGS}/")
    .replace("num: 160", "num: 2")
    .replace("num: 128", "num: 2")
)
#: Seconds after which a refusal counts as a hang (generous: the machine may be loaded).
HANG_GUARD_S = 10.0

Cli = Callable[..., tuple[int, str, str]]


def _one_line_error(code: int, err: str, expected_code: int = 3) -> None:
    assert code == expected_code, err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err and "internal error" not in err


def _write(tmp_path: Path, text: str, name: str = "f.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# ------------------------------------------------------------------------------------------------ output folders
@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["run", TASKS / "planar3r_line.yaml", "--out", "", "--no-figures", "-q"], "'--out'"),
        (["sweep", ROOT / "sweeps" / "panda_reach.yaml", "--out", "", "-q"], "'--out'"),
        (["hybrid33", "path", CONFIGS / "hybrid33_rect.yaml", "--out", ""], "'--out'"),
        (["examples", "copy", ""], "'target'"),
        (["schema", "--out", " "], "'--out'"),
    ],
)
def test_an_empty_output_path_is_a_usage_error_not_the_current_folder(
    cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[object], option: str
) -> None:
    """``--out ""`` was ``Path("")`` = ``.``: the run's files landed in the current folder."""
    monkeypatch.chdir(tmp_path)
    code, out, err = cli(*args)
    assert code == 2, err  # a usage error: the value of an option
    assert option in err and "an empty path names no file or folder" in err
    assert out == "" and list(tmp_path.iterdir()) == []  # nothing written here


@pytest.mark.parametrize("folder", ["/", "/tmp/..", "//"])
def test_the_file_system_root_is_never_an_output_folder(folder: str) -> None:
    """``--out /`` wrote summary.json and RUN.csv into ``/`` (as root: it could)."""
    with pytest.raises(OutputPathError, match="refusing to use the file-system root"):
        check_output_folder(folder)
    with pytest.raises(OutputPathError, match="file-system root"):
        safe_path(folder, "summary.json")


def test_run_into_the_root_is_refused_before_running(cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import redundik.config.runner as runner

    def never(*args: object, **kwargs: object) -> object:
        raise AssertionError("the run started although its output folder is refused")

    monkeypatch.setattr(runner, "run_task", never)
    code, _, err = cli("run", _write(tmp_path, TASK), "--out", "/", "--no-figures", "-q")
    _one_line_error(code, err)
    assert "file-system root '/'" in err
    assert not Path("/summary.json").exists()


# ------------------------------------------------------------------------------------------------ which error
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


# ------------------------------------------------------------------------------------------------ files that are not
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


# ------------------------------------------------------------------------------------------------ names
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


# ------------------------------------------------------------------------------------------------ bounded work
def test_a_huge_dh_table_is_refused_before_the_model_is_built(cli: Cli, tmp_path: Path) -> None:
    """A 400-row D-H table took 13 s and 6 GB to build (Pinocchio's data grows as n³), 1000 rows were killed."""
    rows = "".join(f'- {{name: "{i}", a: 0.1, alpha: 90}}\n' for i in range(1, 202))
    start = time.perf_counter()
    code, _, err = cli("validate", _write(tmp_path, f"name: big\nangle_unit: deg\ndh:\n{rows}", "r.yaml"))
    assert time.perf_counter() - start < HANG_GUARD_S
    _one_line_error(code, err)
    assert err.startswith("error: r.yaml: dh: at most 200 D-H rows, got 201"), err


def test_a_dense_yaml_file_is_refused_while_it_is_parsed(tmp_path: Path) -> None:
    """480 000 numbers in 0.9 MiB took 15 s of pure-Python parsing before any check; now refused at 100 000."""
    from redundik.config.yamlio import MAX_NODES, read_yaml
    from redundik.errors import ConfigError

    path = _write(tmp_path, "name: x\nq0: [" + ",".join(["0"] * (MAX_NODES + 10)) + "]\n")
    start = time.perf_counter()
    with pytest.raises(ConfigError, match=f"more than {MAX_NODES} values in one file"):
        read_yaml(path)
    assert time.perf_counter() - start < HANG_GUARD_S
    assert read_yaml(_write(tmp_path, "q0: [" + ",".join(["0"] * 1000) + "]\n"))["q0"] == [0] * 1000


def test_yaml_merge_keys_are_refused_in_plain_words(cli: Cli, tmp_path: Path) -> None:
    text = TASK.replace("  rank_only:\n", "  base: &b {resolver: pinv}\n  rank_only:\n    <<: *b\n  xx:\n")
    code, _, err = cli("validate", _write(tmp_path, text))
    _one_line_error(code, err)
    assert "merge keys ('<<: *anchor') are not supported" in err and "tag:yaml.org" not in err


# ------------------------------------------------------------------------------------------------ potentials, tasks
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


@pytest.mark.parametrize("bad", [[math.nan, 0.0, 0.0], [0.0, math.inf, 0.0]])
def test_posture_target_with_nan_is_refused_where_it_is_set(bad: list[float]) -> None:
    """``PostureTask(target=[nan, ...])`` was accepted (``set_target`` refused the same vector)."""
    with pytest.raises(TaskError, match=r"posture task 'posture': target: contains NaN or infinite values"):
        rk.PostureTask(target=bad)
    posture = rk.PostureTask(target=[0.0, 1.0, 0.0])
    np.testing.assert_array_equal(posture.target, [0.0, 1.0, 0.0])


def test_the_cli_parser_keeps_paths_and_defaults() -> None:
    from redundik.cli._params import path_value

    assert path_value("out/x") == Path("out/x")
    assert path_value(".") == Path(".")
    assert path_value(Path("a")) == Path("a")
    assert os.fspath(path_value("/tmp")) == "/tmp"


def test_a_value_refused_by_every_member_of_a_union_counts_as_one_error(cli: Cli, tmp_path: Path) -> None:
    """A union reports one error per member at the same key: they are one mistake, not "(and 1 more error)"."""
    code, _, err = cli("validate", _write(tmp_path, SWEEP.replace("x: {start: -1.0, stop: 1.0, num: 2}", "x: abc")))
    _one_line_error(code, err)
    assert err == "error: targets.grid.x: expected a number, got 'abc'\n", err
    two = SWEEP.replace("x: {start: -1.0, stop: 1.0, num: 2}", "x: abc").replace("y: 0.0", "y: def")
    code, _, err = cli("validate", _write(tmp_path, two))
    assert err == "error: targets.grid.x: expected a number, got 'abc' (and 1 more error)\n", err  # two keys: two

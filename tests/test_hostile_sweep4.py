"""Hostile input, fourth pass: YAML number forms, resolver options, sweep files, Dask options, figure outputs.

Each test feeds one bad input that was accepted silently, read as another number, or reported as an internal error,
and asserts a one-line error naming what was wrong, where (the option, the key path) and what was expected.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from redundik.errors import ConfigError
from tests.conftest import CONFIGS

# the third sweep's inputs and helpers (the same task and sweep files, the same one-line-error rule)
from tests.test_hostile_sweep3 import HANG_GUARD_S, SWEEP, TASK, Cli, _one_line_error, _write

GRID = "  grid:\n    x: {start: -1.0, stop: 1.0, num: 2}\n    y: 0.0\n    z: {start: -0.5, stop: 1.3, num: 2}\n"


def _with_options(resolver: str, options: str) -> str:
    line = f"    resolver: {resolver}\n"
    assert line in TASK
    return TASK.replace(line, f"{line}    options: {options}\n", 1)


# ------------------------------------------------------------------------------------------------ YAML numbers
@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("q0: [010, -040, -030]\n", "'010': YAML reads a number with a leading zero as octal (= 8)"),
        ("steps: 0500\n", "'0500': YAML reads a number with a leading zero as octal (= 320)"),
        ("steps: 1:30\n", "'1:30': YAML reads numbers with ':' as base 60 (= 90)"),
        ("dt: 190:20:30.15\n", "'190:20:30.15': YAML reads numbers with ':' as base 60"),
    ],
)
def test_yaml_1_1_octal_and_base_60_numbers_are_refused(tmp_path: Path, text: str, expected: str) -> None:
    """PyYAML (YAML 1.1) read ``q0: [010, -040, -030]`` as [8, -32, -24] degrees and ``steps: 1:30`` as 90 steps."""
    from redundik.config.yamlio import read_yaml

    with pytest.raises(ConfigError, match=r"f\.yaml:1: invalid YAML: ") as info:
        read_yaml(_write(tmp_path, text))
    assert expected in str(info.value)


def test_ordinary_numbers_still_read_as_numbers(tmp_path: Path) -> None:
    from redundik.config.yamlio import read_yaml

    data = read_yaml(_write(tmp_path, "a: 0\nb: -0\nc: 10\nd: 1_000\ne: 1e3\nf: 0.5\ng: 00.5\nh: '010'\ni: '1:30'\n"))
    assert data == {"a": 0, "b": 0, "c": 10, "d": 1000, "e": 1000.0, "f": 0.5, "g": 0.5, "h": "010", "i": "1:30"}


def test_an_octal_start_configuration_is_refused_at_its_line(cli: Cli, tmp_path: Path) -> None:
    code, _, err = cli("validate", _write(tmp_path, TASK.replace("q0: [110, -40, -30]", "q0: [110, -040, -030]")))
    _one_line_error(code, err)
    line = TASK.splitlines().index("q0: [110, -40, -30]") + 1
    assert err.startswith(f"error: {tmp_path / 'f.yaml'}:{line}: invalid YAML: '-040': YAML reads a number"), err
    assert "leading zero as octal (= -32)" in err


def test_a_key_that_is_not_text_is_named_in_its_mapping(cli: Cli, tmp_path: Path) -> None:
    """Was ``[1]: Keys should be strings`` (pydantic's words, and the key shown as a list index)."""
    code, _, err = cli("validate", _write(tmp_path, TASK.replace("dt: 0.01", "dt: 0.01\n1: 1")))
    _one_line_error(code, err)
    assert err.startswith("error: (top level): key 1 (a number) is not text"), err
    code, _, err = cli("validate", _write(tmp_path, TASK.replace("dt: 0.01", "dt: 0.01\nnull: 1")))
    _one_line_error(code, err)
    assert err.startswith("error: (top level): key null is not text"), err


# ------------------------------------------------------------------------------------------------ resolver options
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


def test_sweep_resolver_options_are_checked_the_same_way(cli: Cli, tmp_path: Path) -> None:
    code, _, err = cli(
        "validate", _write(tmp_path, SWEEP.replace("options: {}", "options: {limits: {velocity: .nan}}"))
    )
    _one_line_error(code, err)
    assert err.startswith("error: resolver.options.limits.velocity: expected a finite number, got nan"), err
    code, _, err = cli("validate", _write(tmp_path, SWEEP.replace("options: {}", "options: {nope: 1}")))
    _one_line_error(code, err)
    assert "resolver 'wqp': resolver 'wqp'" not in err and "resolver 'wqp': bad options ['nope']" in err, err


# ------------------------------------------------------------------------------------------------ sweep files
@pytest.mark.parametrize("axes", ["5", "null", "[[x]]"])
def test_sweep_axes_of_the_wrong_type_are_invalid_input(cli: Cli, tmp_path: Path, axes: str) -> None:
    """Was exit 70: ``TypeError: 'int' object is not iterable`` in ``resolve_axes``."""
    code, _, err = cli("validate", _write(tmp_path, SWEEP.replace("axes: position", f"axes: {axes}")))
    _one_line_error(code, err)
    assert err.startswith("error: task.axes: expected an axis-set name or a list of axis names"), err


def test_a_target_orientation_a_position_task_would_ignore_is_refused(cli: Cli, tmp_path: Path) -> None:
    assert GRID in SWEEP
    text = SWEEP.replace(GRID, "  points: [[0.5, 0.0, 0.4]]\n  orientation: [3.14159, 0, 0]\n")
    code, _, err = cli("validate", _write(tmp_path, text))
    _one_line_error(code, err)
    assert err.startswith("error: targets.orientation: a target orientation is given but task.axes"), err
    code, _, err = cli("validate", _write(tmp_path, text.replace("axes: position", "axes: pose")))
    assert code == 0, err


@pytest.mark.parametrize(
    ("path", "expected"),
    [
        (CONFIGS / "panda.yaml", "panda.yaml is a robot config, not a sweep file"),
        (CONFIGS / "stewart33.yaml", "stewart33.yaml is a mechanism config, not a sweep file"),
    ],
)
def test_a_config_given_as_a_sweep_file_is_named_as_such(cli: Cli, tmp_path: Path, path: Path, expected: str) -> None:
    """Was ``robot: required key is missing (and 5 more errors)``."""
    code, _, err = cli("sweep", path, "--out", tmp_path / "out", "-q")
    _one_line_error(code, err)
    assert err.startswith(f"error: {expected}"), err
    assert not (tmp_path / "out").exists()


def test_a_listed_start_outside_the_limits_is_not_told_to_give_q0(cli: Cli, tmp_path: Path) -> None:
    text = SWEEP.replace("home: true", "home: true\n  configurations: [[9, 0, 0, -1, 0, 1, 0, 0, 0]]")
    code, _, err = cli("validate", _write(tmp_path, text))
    _one_line_error(code, err)
    assert err.startswith("error: starts.configurations[0]: this start configuration is outside the joint limits")
    assert "give one within the limits" in err and "give 'q0'" not in err, err


# ------------------------------------------------------------------------------------------------ Dask options
@pytest.mark.parametrize(
    ("option", "value", "expected"),
    [
        ("--scheduler", "tcp://127.0.0.1:99999", "--scheduler: the port must be 1 to 65535, got 99999"),
        ("--scheduler", "local:2", "--scheduler: 'local:2' is a local cluster size: use --dask local:2"),
        ("--scheduler", "", "--scheduler: expected a scheduler address [SCHEME://]HOST:PORT"),
        ("--scheduler", "inproc://x", "--scheduler: expected a scheduler address"),
        ("--scheduler", "xyz://h:1", "--scheduler: scheme 'xyz' cannot reach a scheduler in another process"),
        ("--scheduler", "a" * 5000 + ":1", "--scheduler: expected a scheduler address"),
        ("--dask", "local:0", "--dask: expected local:N with 1 ≤ N ≤ 64, got 'local:0'"),
        ("--dask", "local:abc", "--dask: expected local:N"),
    ],
)
def test_dask_options_are_refused_before_anything_is_loaded_or_contacted(
    cli: Cli, tmp_path: Path, option: str, value: str, expected: str
) -> None:
    """A port out of range (or ``local:2`` given to --scheduler) waited out the 10 s connect timeout; a 5000-character
    address came back whole in the error; both options were looked at only after the sweep file was loaded."""
    start = time.perf_counter()
    code, _, err = cli("sweep", tmp_path / "missing.yaml", option, value, "--out", tmp_path / "out", "-q")
    assert time.perf_counter() - start < HANG_GUARD_S
    _one_line_error(code, err)
    assert err.startswith(f"error: {expected}"), err
    assert len(err) < 400 and not (tmp_path / "out").exists()


def test_well_formed_scheduler_addresses_pass_the_shape_check() -> None:
    from redundik.sweep.engine import check_scheduler_address

    for address in ("tcp://10.0.0.5:8786", "127.0.0.1:8786", "tls://scheduler.example.org:8786", "tcp://[::1]:8786"):
        assert check_scheduler_address(address) == address


# ------------------------------------------------------------------------------------------------ figure outputs
_DRAW = ["stewart", "draw", CONFIGS / "stewart33.yaml", "--p", "0", "0", "1.5", "--out"]
_ANIMATE = [
    *["stewart", "animate", CONFIGS / "stewart33.yaml", "--p", "0", "0", "1.5", "--to-p", "0", "0", "1.6"],
    *["--frames", "2", "--out"],
]


@pytest.mark.parametrize(
    ("args", "name", "expected"),
    [
        (_DRAW, "pose", "--out: expected a .png file name (this command writes PNG)"),
        (_DRAW, "pose.txt", "--out: expected a .png file name"),
        (_DRAW, "folder", "--out: expected a .png file name"),
        (_ANIMATE, "move.png", "--out: expected a .gif file name (this command writes GIF)"),
    ],
)
def test_figure_outputs_are_written_where_they_are_named(
    cli: Cli, tmp_path: Path, args: list[object], name: str, expected: str
) -> None:
    """``--out DIR`` or ``--out NAME`` wrote ``NAME.png`` beside the path given (matplotlib appends the suffix),
    ``--out pose.txt`` was an internal error, ``animate --out move.png`` a GIF named .png."""
    (tmp_path / "folder").mkdir()
    code, _, err = cli(*args, tmp_path / name)
    _one_line_error(code, err)
    assert err.startswith(f"error: {expected}"), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder"]
    assert list((tmp_path / "folder").iterdir()) == []


def test_a_folder_named_like_a_png_is_refused(cli: Cli, tmp_path: Path) -> None:
    (tmp_path / "pose.png").mkdir()
    code, _, err = cli(*_DRAW, tmp_path / "pose.png")
    _one_line_error(code, err)
    assert "is a folder; give a .png file name" in err


@pytest.mark.parametrize(
    ("value", "expected"), [("nan", "non-finite value"), ("1e308", "values must be at most 1e+06")]
)
def test_hybrid_book_ik_names_a_bad_previous_theta6(cli: Cli, value: str, expected: str) -> None:
    """``--theta6-prev nan`` was reported as "top point: contains a non-finite value"; 1e308 was accepted."""
    args = ["hybrid33", "ik", CONFIGS / "hybrid33_rect.yaml", "--p", "0", "0", "1", "--method", "book"]
    code, out, err = cli(*args, "--theta6-prev", value, "--json")
    _one_line_error(code, err)
    assert err.startswith(f"error: --theta6-prev: {expected}"), err
    assert out == ""


# ------------------------------------------------------------------------------------------------ names in figures
def test_names_the_figure_font_lacks_do_not_flood_stderr(tmp_path: Path) -> None:
    """A CJK joint name printed matplotlib's "Glyph ... missing from font" warnings (two lines each) on stderr."""
    robot = (CONFIGS / "planar3r.yaml").read_text(encoding="utf-8").replace('name: "3"', 'name: "关节3"')
    robot_path = _write(tmp_path, robot, "r.yaml")
    text = (
        TASK.replace(f"{CONFIGS}/planar3r.yaml", str(robot_path))
        .replace('frame: "3"', 'frame: "关节3"')
        .replace('joint: "3"', 'joint: "关节3"')
        .replace('frames: ["0", "1", "2", "3"]', 'frames: ["0", "1", "2", "关节3"]')
        .replace("steps: 500", "steps: 3")
    )
    task = _write(tmp_path, text)
    # a separate process: pytest records warnings itself, so only a real stderr shows what a user would see
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "redundik",
            "run",
            str(task),
            "--out",
            str(tmp_path / "out"),
            "-q",
            "--runs",
            "rank_null",
        ],
        capture_output=True,
        text=True,
        env={k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"},
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert "Glyph" not in proc.stderr and "Warning" not in proc.stderr, proc.stderr
    assert (tmp_path / "out" / "joints.png").is_file()


def test_a_stall_window_that_could_never_fire_is_refused(cli: Cli, tmp_path: Path) -> None:
    """A stall window of max_iterations steps or more compares the error over more steps than a problem runs."""
    text = SWEEP.replace("stall: {window: 10,", "stall: {window: 80,")
    assert text != SWEEP
    code, _, err = cli("validate", _write(tmp_path, text))
    _one_line_error(code, err)
    assert "convergence" in err and "stall.window (80) must be < max_iterations (80)" in err, err
    code, _, err = cli("validate", _write(tmp_path, SWEEP.replace("stall: {window: 10,", "stall: {window: 79,")))
    assert code == 0, err

"""Hostile sweep files and Dask options: axes of the wrong type, resolver options, configs given as sweeps, starts
outside the limits, sweeps of hours or into a file, frames fixed to the world, scheduler addresses: refused at
validation, before anything is loaded or contacted, in one line."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from tests.conftest import CONFIGS
from tests.hostile import HANG_GUARD_S, ROOT, SWEEP, Cli, _one_line_error, _write

GRID = "  grid:\n    x: {start: -1.0, stop: 1.0, num: 2}\n    y: 0.0\n    z: {start: -0.5, stop: 1.3, num: 2}\n"


def test_sweep_resolver_options_are_checked_the_same_way(cli: Cli, tmp_path: Path) -> None:
    code, _, err = cli(
        "validate", _write(tmp_path, SWEEP.replace("options: {}", "options: {limits: {velocity: .nan}}"))
    )
    _one_line_error(code, err)
    assert err.startswith("error: resolver.options.limits.velocity: expected a finite number, got nan"), err
    code, _, err = cli("validate", _write(tmp_path, SWEEP.replace("options: {}", "options: {nope: 1}")))
    _one_line_error(code, err)
    assert "resolver 'wqp': resolver 'wqp'" not in err and "resolver 'wqp': bad options ['nope']" in err, err


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

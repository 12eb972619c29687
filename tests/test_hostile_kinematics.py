"""Hostile input at the kinematics layer: reserved names, paths that are not files, robots too large for Pinocchio's
data — each a ModelError that says what and where, never a raw ValueError, a MemoryError or a hang."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.kinematics.model import MAX_NV
from redundik.kinematics.snake import snake, snake_rows

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    ("rows", "base_frame", "match"),
    [
        ([rk.DHRow("universe", a=1.0), rk.DHRow("2", a=1.0)], "0", "'universe' is Pinocchio's name"),
        ([rk.DHRow("1", a=1.0)], "universe", "base_frame must be a non-empty name other than 'universe'"),
        ([rk.DHRow("1", a=1.0)], "", "base_frame must be a non-empty name"),
        ([rk.DHRow("1", a=1.0)], "  ", "base_frame must be a non-empty name"),
    ],
)
def test_reserved_or_empty_frame_names_are_refused(rows: list[rk.DHRow], base_frame: str, match: str) -> None:
    with pytest.raises(rk.ModelError, match=match):
        rk.from_dh(rows, base_frame=base_frame)


def test_a_legal_table_still_builds_and_resolves_its_frames() -> None:
    robot = rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", a=1.0)], base_frame="base")
    robot.update(np.zeros(2))
    np.testing.assert_allclose(robot.frame_position("2"), [2.0, 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize(
    ("path", "match"),
    [("", "empty string"), ("/tmp", "is a folder, not a file"), ("/dev/null", "not a regular file")],
)
def test_urdf_paths_that_are_not_files_say_what_they_are(path: str, match: str) -> None:
    with pytest.raises(rk.ModelError, match=match):
        rk.from_urdf(path)


def test_a_missing_urdf_still_says_it_does_not_exist(tmp_path: Path) -> None:
    with pytest.raises(rk.ModelError, match="does not exist"):
        rk.from_urdf(tmp_path / "nope.urdf")


def test_a_robot_beyond_the_joint_cap_is_refused_before_its_data_is_built() -> None:
    model = pin.Model()
    parent = 0
    for i in range(MAX_NV + 1):
        parent = model.addJoint(parent, pin.JointModelRZ(), pin.SE3.Identity(), f"j{i}")
    with pytest.raises(rk.ModelError, match=rf"{MAX_NV + 1} velocity coordinates, more than {MAX_NV}"):
        rk.RobotModel(model, name="long")
    with pytest.raises(rk.ModelError, match=f"needs 2 to {MAX_NV} joints, got 100000000"):
        snake_rows(100_000_000)  # refused at once, not built row by row
    with pytest.raises(rk.ModelError, match=f"more than {MAX_NV} joint rows"):
        rk.from_dh([rk.DHRow(str(i + 1), a=0.1) for i in range(MAX_NV + 1)])
    assert snake(MAX_NV // 8).nv == MAX_NV // 8


def test_the_snake_config_script_reports_a_bad_size_in_one_line() -> None:
    out = subprocess.run(
        [sys.executable, str(ROOT / "examples/snake_config.py"), "1"], capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 2
    assert out.stderr.strip() == "snake_config: snake: needs 2 to 256 joints, got 1"
    assert out.stdout == ""

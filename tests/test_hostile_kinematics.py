"""Hostile input at the kinematics layer: reserved names, paths that are not files, robots too large for Pinocchio's
data, D-H tables and bases that are nonsense, URDF robots no resolver could use, NaN or wrong sizes given to
``update`` and ``integrate`` — each a ModelError that says what and where, never a raw ValueError, a MemoryError or
a hang."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.errors import ModelError
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


@pytest.mark.parametrize("frame", [-1, 10**6, 2.0, None, True, [3]])
@pytest.mark.parametrize("query", ["frame_position", "frame_pose", "frame_jacobian"])
def test_a_frame_that_is_neither_a_known_name_nor_an_index_in_range_is_refused(frame: object, query: str) -> None:
    """-1 used to read the last frame (Python's indexing through the bindings), 2.0 or None to end in Boost's
    ``ArgumentError``: now a ModelError naming the robot and what a frame is."""
    robot = rk.load_example_robot("panda")
    robot.update(robot.neutral())
    with pytest.raises(ModelError, match=r"frame index .* outside|a frame is given by its name or its index"):
        getattr(robot, query)(frame)


@pytest.mark.parametrize("name", ["panda", "talos", "ur5"])
def test_frame_lookups_are_pinocchios(name: str) -> None:
    """``frame_id`` (a table made once per model) is ``getFrameId`` for every frame name, a frame added to the model
    afterwards included; ``frame_position`` (read from a view on Pinocchio's placements) is the frame's translation,
    by name or index (numpy's integers and strings too), a copy that follows the next update."""
    robot = rk.load_example_robot(name)
    model = robot.model
    for q in (robot.neutral(), robot.random_configuration(np.random.default_rng(3))):
        robot.update(q)
        for fid, frame in enumerate(model.frames):
            assert robot.frame_id(frame.name) == model.getFrameId(frame.name)
            expected = np.array(robot.data.oMf[fid].translation)
            for key in (frame.name, fid, np.int64(fid), np.str_(frame.name)):
                got = robot.frame_position(key)  # type: ignore[arg-type]
                np.testing.assert_array_equal(got, expected)
            got[0] += 1.0  # (a copy: the robot's data is not touched)
            np.testing.assert_array_equal(robot.frame_position(fid), expected)
    parent = model.frames[model.nframes - 1]
    added = model.addFrame(pin.Frame("added_tip", parent.parentJoint, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    assert robot.frame_id("added_tip") == added


@pytest.mark.parametrize("call", ["update", "check_configuration", "limit_violation", "difference"])
def test_a_configuration_shaped_as_a_matrix_is_refused(call: str) -> None:
    """A (3, 3) array for the Panda's nq = 9 used to be flattened without a word (``Resolver.step`` refuses it): a
    configuration is a vector, or a matrix of one row or one column."""
    robot = rk.load_example_robot("panda")
    q = robot.neutral()
    args = {"difference": (q, q.reshape(3, 3))}.get(call, (q.reshape(3, 3),))
    with pytest.raises(ModelError, match=r"shape \(3, 3\)"):
        getattr(robot, call)(*args)
    robot.update(q.reshape(1, 9))  # (one row, or one column: still a configuration)
    robot.update(q.reshape(9, 1))

"""Hostile and unusual robots: URDFs too deep or too large for Pinocchio's reader (refused before it runs, never a
segfault), and the smallest and largest chains every resolver must step (1, 2 and 200 joints, fixed and free-flyer
bases)."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import redundik as rk
from redundik.kinematics.snake import snake
from redundik.kinematics.urdf import MAX_URDF_DEPTH, MAX_URDF_JOINTS, MAX_URDF_LINKS

ROOT = Path(__file__).resolve().parents[1]


def chain_urdf(n: int, fixed: bool = False, link: float = 0.1) -> str:
    """A URDF of an n-joint serial chain l0 - j1 - l1 - ... - ln (revolute about z, or fixed joints)."""
    parts = ["<robot name='chain'>", "<link name='l0'/>"]
    for i in range(1, n + 1):
        kind = "fixed" if fixed else "revolute"
        axis = "" if fixed else "<axis xyz='0 0 1'/><limit lower='-2' upper='2' effort='1' velocity='3'/>"
        parts.append(
            f"<link name='l{i}'/><joint name='j{i}' type='{kind}'><parent link='l{i - 1}'/><child link='l{i}'/>"
            f"<origin xyz='{link} 0 0' rpy='{1.2 if i % 2 else -1.2} 0 0'/>{axis}</joint>"
        )
    parts.append("</robot>")
    return "".join(parts)


# ---------------------------------------------------------------------------------------------- deep / large URDFs
def test_a_deep_urdf_chain_is_refused_before_pinocchio_reads_it(tmp_path: Path) -> None:
    """(In-process at a size Pinocchio survives; the sizes that crashed it run in a subprocess below.)"""
    path = tmp_path / "deep.urdf"
    path.write_text(chain_urdf(MAX_URDF_LINKS))  # MAX_URDF_LINKS + 1 links with the root
    with pytest.raises(rk.ModelError, match=rf"more than {MAX_URDF_LINKS} <link> elements"):
        rk.from_urdf(path)


@pytest.mark.parametrize("n", [7000, 10_000])
def test_a_deep_urdf_does_not_kill_the_process(tmp_path: Path, n: int) -> None:
    """The defect was a signal 11 in Pinocchio's recursive reader: the process must survive and say why."""
    path = tmp_path / "deep.urdf"
    path.write_text(chain_urdf(n))
    code = "import sys, redundik as rk\ntry:\n    rk.from_urdf(sys.argv[1])\nexcept rk.ModelError as e:\n    print(e)\n"
    proc = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, (proc.returncode, proc.stderr[-500:])
    assert "refused before parsing" in proc.stdout


def test_a_chain_of_fixed_joints_deeper_than_the_bound_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "fixed.urdf"
    path.write_text(chain_urdf(MAX_URDF_DEPTH + 1, fixed=True))
    assert MAX_URDF_DEPTH + 1 <= MAX_URDF_JOINTS  # the depth bound, not the count, is what refuses it
    with pytest.raises(rk.ModelError, match=rf"a chain of more than {MAX_URDF_DEPTH} joints"):
        rk.from_urdf(path)


def test_too_many_joints_and_deep_xml_are_refused(tmp_path: Path) -> None:
    joints = "".join(
        f"<joint name='j{i}' type='fixed'><parent link='a'/><child link='a'/></joint>" for i in range(1100)
    )
    path = tmp_path / "joints.urdf"
    path.write_text(f"<robot name='x'><link name='a'/>{joints}</robot>")
    with pytest.raises(rk.ModelError, match=rf"more than {MAX_URDF_JOINTS} <joint> elements"):
        rk.from_urdf(path)
    path.write_text("<robot name='x'><link name='a'>" + "<g>" * 200 + "</g>" * 200 + "</link></robot>")
    with pytest.raises(rk.ModelError, match="nested deeper than"):
        rk.from_urdf(path)


def test_a_joint_loop_is_refused_with_the_link_named(tmp_path: Path) -> None:
    path = tmp_path / "loop.urdf"
    path.write_text(
        "<robot name='x'><link name='a'/><link name='b'/>"
        "<joint name='j1' type='fixed'><parent link='a'/><child link='b'/></joint>"
        "<joint name='j2' type='fixed'><parent link='b'/><child link='a'/></joint></robot>"
    )
    with pytest.raises(rk.ModelError, match="loop through link"):
        rk.from_urdf(path)


def test_a_legal_urdf_chain_still_loads(tmp_path: Path) -> None:
    path = tmp_path / "ok.urdf"
    path.write_text(chain_urdf(12))
    robot = rk.from_urdf(path)
    assert robot.nv == 12


def test_validate_on_a_deep_urdf_exits_cleanly(tmp_path: Path) -> None:
    (tmp_path / "deep.urdf").write_text(chain_urdf(7000))
    (tmp_path / "robot.yaml").write_text("name: deep\nurdf: deep.urdf\n")
    proc = subprocess.run(
        [sys.executable, "-m", "redundik", "validate", str(tmp_path / "robot.yaml")],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert proc.returncode > 0, proc.returncode  # an error exit, not a signal (a negative return code)
    assert "refused before parsing" in proc.stdout + proc.stderr


# ---------------------------------------------------------------------------------------- every resolver, any size
RESOLVERS = ["pinv", "feedback", "wqp", "hqp"]


def _robot(kind: str) -> tuple[rk.RobotModel, str, str | list[str]]:
    """(robot, tip frame, task axes) for one of the sizes under test."""
    if kind == "1R":
        return rk.from_dh([rk.DHRow("1", a=1.0, lower=-2.0, upper=2.0)], name="one"), "1", ["y"]
    if kind == "2R":
        return rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", a=1.0)], name="two"), "2", "planar"
    if kind == "snake200":
        return snake(200, link=0.01), "200", "position"
    raise AssertionError(kind)


def _free_flyer(n: int, tmp_path: Path) -> rk.RobotModel:
    path = tmp_path / f"chain{n}.urdf"
    path.write_text(chain_urdf(n))
    return rk.from_urdf(path, free_flyer=True)


def _track(robot: rk.RobotModel, frame: str, axes: str | list[str], resolver: str, q: np.ndarray) -> None:
    """Step ``resolver`` 10 times on a moving target and check q̇ is finite and the target is followed."""
    velocity = [0.0, 0.05, 0.0]
    task = rk.FrameTask(frame, rk.Line(velocity), axes=axes, gain=20.0)
    stack = rk.TaskStack([task])
    robot.update(q)
    stack.reset(robot)
    start = robot.frame_position(frame).copy()
    res = rk.make_resolver(resolver)
    dt = 0.01
    for k in range(10):
        dq = res.step(robot, stack, q, k * dt, dt).dq
        assert dq.shape == (robot.nv,) and np.isfinite(dq).all()
        q = robot.integrate(q, dq, dt)
    robot.update(q)
    moved = robot.frame_position(frame) - start
    assert abs(moved[1] - 0.05 * 10 * dt) < 1e-4, moved  # the tip followed the line's y velocity


@pytest.mark.parametrize("resolver", RESOLVERS)
@pytest.mark.parametrize("kind", ["1R", "2R", "snake200"])
def test_every_resolver_steps_fixed_base_chains_of_any_size(kind: str, resolver: str) -> None:
    robot, frame, axes = _robot(kind)
    q = robot.neutral() + 0.3 if kind != "snake200" else np.full(robot.nq, 0.05)
    robot.update(q)
    assert robot.frame_jacobian(frame).shape == (6, robot.nv)
    _track(robot, frame, axes, resolver, q)


@pytest.mark.parametrize("resolver", RESOLVERS)
@pytest.mark.parametrize("n", [1, 2, 200])
def test_every_resolver_steps_free_flyer_chains_of_any_size(tmp_path: Path, n: int, resolver: str) -> None:
    robot = _free_flyer(n, tmp_path)
    assert robot.nv == 6 + n
    q = robot.neutral()
    q[7:] = 0.05
    _track(robot, f"l{n}", "pose", resolver, q)


def test_the_frame_jacobian_of_a_one_joint_robot_is_a_matrix() -> None:
    robot = rk.from_dh([rk.DHRow("1", a=1.0)])
    robot.update(np.array([0.2]))
    J = robot.frame_jacobian("1")
    assert J.shape == (6, 1)
    np.testing.assert_allclose(J[:2, 0], [-np.sin(0.2), np.cos(0.2)], atol=1e-12)


def test_a_one_joint_task_file_runs_with_every_resolver(
    tmp_path: Path, cli: Callable[..., tuple[int, str, str]]
) -> None:
    (tmp_path / "one.yaml").write_text(
        "name: one\nlength_unit: m\nangle_unit: deg\nbase_frame: '0'\n"
        "dh:\n  - {name: '1', type: revolute, theta: 0, d: 0, a: 1, alpha: 0, lower: -180, upper: 180, "
        "velocity: 180}\nq0: [10]\n"
    )
    runs = "".join(f"  {r}: {{resolver: {r}}}\n" for r in RESOLVERS)
    (tmp_path / "task.yaml").write_text(
        "name: t1\nrobot: one.yaml\nangle_unit: deg\nq0: [10]\ndt: 0.01\nsteps: 10\nmain:\n"
        "  - {name: tip, type: frame, frame: '1', axes: [y], trajectory: {type: line, velocity: [0.0, 0.1]}, "
        f"gain: 1}}\nruns:\n{runs}"
    )
    code, out, err = cli("run", tmp_path / "task.yaml", "--out", tmp_path / "out", "--no-figures")
    assert code == 0, (out + err)[-2000:]

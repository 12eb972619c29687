"""The figures' objects (not their pixels): potentials in their units with targets and bounds drawn, runs told apart
where their curves coincide, limit and safety labels off the data, and the arm drawn among the obstacles (issue 32,
item 15)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import redundik as rk

pytest.importorskip("matplotlib")

from redundik.reporting.plots import (
    FigureOptions,
    LoggedRun,
    joints_figure,
    potentials_figure,
    task_errors_figure,
)
from tests.conftest import TASKS


def _close(fig: Any) -> None:
    import matplotlib.pyplot as plt

    plt.close(fig)


def _planar() -> tuple[rk.RobotModel, rk.TaskStack, rk.SimulationLog, rk.TaskStack, rk.SimulationLog]:
    """A 3R arm: (robot, a stack with a sin² gradient and a bounded clearance, its log, a target stack, its log)."""
    robot = rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", a=1.0), rk.DHRow("3", a=1.0)])
    clearance = rk.Clearance("2", center=[1.5, 1.5, 0.0], radius=0.2, axes=["x", "y"])
    stack = rk.TaskStack(
        [rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")],
        [rk.GradientSubtask(rk.JointSine2("3"), gain=1.0), rk.BoundSubtask(clearance, lower=0.1)],
    )
    q0 = np.radians([30.0, 40.0, -60.0])
    log = rk.simulate(robot, stack, rk.WeightedQPResolver(), q0, dt=0.01, steps=60)
    target = rk.TaskStack(
        [rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")],
        [rk.TargetSubtask(rk.JointCentering(), target=0.05, rate=2.0)],
    )
    log2 = rk.simulate(robot, target, rk.WeightedQPResolver(), q0, dt=0.01, steps=60)
    return robot, stack, log, target, log2


def _axis(fig: Any, title_part: str) -> Any:
    return next(ax for ax in fig.axes if title_part in ax.get_title())


def test_potential_axes_carry_units_and_bounds() -> None:
    robot, stack, log, target, log2 = _planar()
    runs = {"qp": LoggedRun(log, stack), "target": LoggedRun(log2, target)}
    fig = potentials_figure(runs, FigureOptions("t"), robot)
    try:
        assert _axis(fig, "'sin2_3'").get_ylabel() == "p [1]"  # sin²θ: dimensionless
        clear = _axis(fig, "'clearance")
        assert clear.get_ylabel() == "p [m]"  # a distance, in the robot's length unit
        bound = [ln for ln in clear.get_lines() if "lower bound" in str(ln.get_label())]
        assert len(bound) == 1 and np.allclose(bound[0].get_ydata(), 0.1)
        centre = _axis(fig, "'joint_centering'")
        assert centre.get_ylabel() == "p [rad²]"  # ½‖q − q_c‖² of three revolute joints
        tgt = [ln for ln in centre.get_lines() if "target p_d" in str(ln.get_label())]
        assert len(tgt) == 1 and np.allclose(tgt[0].get_ydata(), 0.05)
        assert all("value" != ax.get_ylabel() for ax in fig.axes)
    finally:
        _close(fig)


def test_potential_units_follow_the_robot() -> None:
    from redundik.reporting.styles import potential_unit

    dm = rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", d=1.0, kind="prismatic")], length_unit="dm")
    assert potential_unit(rk.Clearance("2", center=[0, 0, 0], radius=0.1), dm) == "dm"
    assert potential_unit(rk.VirtualPoint("2", point=[0, 0, 0]), dm) == "dm²"
    assert potential_unit(rk.JointValue("2", 0.5), dm) == "dm²"  # a prismatic joint
    assert potential_unit(rk.JointValue("1", 0.5), dm) == "rad²"
    assert potential_unit(rk.JointCentering(), dm) == "rad², dm² for prismatic joints"


def test_identical_runs_stay_visible_and_are_named() -> None:
    robot, stack, log, _, _ = _planar()
    runs = {"a": LoggedRun(log, stack), "b": LoggedRun(log, stack), "c": LoggedRun(log, stack)}
    for fig in (joints_figure(runs, robot), potentials_figure(runs, None, robot), task_errors_figure(runs, robot)):
        try:
            ax = fig.axes[0]
            lines = {str(ln.get_label()).split(" ")[0]: ln for ln in ax.get_lines() if ln.get_marker() != "None"}
            assert {"a", "b", "c"} <= set(lines)
            markers = {lines[k].get_marker() for k in "abc"}
            offsets = {lines[k].get_markevery()[0] for k in "abc"}  # type: ignore[index]
            assert len(markers) == 3 and len(offsets) == 3  # a marker each, placed at different samples
            labels = [str(ln.get_label()) for ln in ax.get_lines()]
            assert any(lb.startswith("b") and lb.endswith("(= a)") for lb in labels), labels
            assert any(lb.startswith("c") and lb.endswith("(= a)") for lb in labels), labels
            assert not any(lb.startswith("a") and "(=" in lb for lb in labels)
        finally:
            _close(fig)


def test_far_joint_limits_are_named_in_the_title_not_on_the_curves() -> None:
    robot = rk.from_dh([rk.DHRow("1", a=1.0, lower=-3.0, upper=3.0), rk.DHRow("2", a=1.0, lower=0.4, upper=0.6)])
    stack = rk.TaskStack([rk.FrameTask("2", rk.Line([0.0, -0.01]), axes=["x", "y"])])
    log = rk.simulate(robot, stack, rk.PinvResolver(), np.array([0.0, 0.5]), dt=0.01, steps=30)
    fig = joints_figure({"r": LoggedRun(log, stack)}, robot)
    try:
        for ax in fig.axes:
            assert not ax.texts  # no text inside the plotting area
        assert "limits off the axis" in fig.axes[0].get_title()  # ±172° are far from a motion of a few degrees
        near = [ln for ln in fig.axes[1].get_lines() if ln.get_color() == "tab:red"]
        assert len(near) == 2  # joint 2's limits (23°, 34°) are near its motion: two lines, one legend entry
        assert [ln.get_label() for ln in near].count("joint limit") == 1
    finally:
        _close(fig)


@pytest.fixture(scope="module")
def shelf() -> tuple[Any, Any, FigureOptions]:
    from redundik.cli.view_cmds import figure_inputs
    from redundik.config import load_task
    from redundik.config.runner import run_task

    plan = load_task(TASKS / "panda_shelf.yaml")
    runs, options = figure_inputs(plan, run_task(plan, ["no_avoidance", "wqp"]))
    return plan, runs, options


def test_world_figure_labels_the_safety_distance_outside(shelf: tuple[Any, Any, FigureOptions]) -> None:
    from redundik.reporting.world_plots import world_figure

    plan, runs, options = shelf
    fig = world_figure(runs, plan.robot.model, options)
    try:
        ax = fig.axes[0]
        assert ax.get_ylabel().startswith("smallest signed distance [m]")
        notes = [t for t in ax.texts if "d_s" in t.get_text()]
        assert len(notes) == 1 and notes[0].xy == (1.0, 0.01)  # at the axes' right edge, at d_s = 1 cm
        assert notes[0].get_horizontalalignment() == "left" and notes[0].xycoords[0] == "axes fraction"
        assert any(np.allclose(ln.get_ydata(), 0.01) for ln in ax.get_lines())  # the d_s line itself
    finally:
        _close(fig)


def test_arm_figure_shows_the_arm_obstacles_and_closest_pair(shelf: tuple[Any, Any, FigureOptions]) -> None:
    from redundik.reporting.world_plots import arm_points, arm_world_figure

    plan, runs, options = shelf
    robot = plan.robot.model
    fig = arm_world_figure(runs, robot, options)
    try:
        assert len(fig.axes) == 2
        for ax, (name, run) in zip(fig.axes, runs.items(), strict=True):
            assert name in ax.get_title()
            assert [ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()] == ["x [m]", "y [m]", "z [m]"]
            labels = [str(ln.get_label()) for ln in ax.get_lines()]
            assert "obstacles" in labels
            instants = [lb for lb in labels if lb.startswith("t = ")]
            assert 3 <= len(instants) <= 4 and instants[0] == "t = 0.00 s"
            closest = [lb for lb in labels if lb.startswith("closest: ")]
            dmin = float(np.min(run.series["min_distance"]))
            assert len(closest) == 1 and "panda_link5|post" in closest[0]
            assert f"{dmin:.3g} m" in closest[0]
        # the first instant's sticks are the arm's joint origins at q0
        first = arm_points(robot, runs["wqp"].log.q[0])
        drawn = [ln for ln in fig.axes[1].get_lines() if ln.get_marker() == "o"][: len(first)]
        for seg, ln in zip(first, drawn, strict=True):
            x, y, z = ln.get_data_3d()
            assert np.allclose(np.column_stack([x, y, z]), seg)
    finally:
        _close(fig)


def test_no_arm_figure_without_a_world(tmp_path: Path) -> None:
    from redundik.reporting.world_plots import plot_arm_world

    robot, stack, log, _, _ = _planar()
    assert plot_arm_world({"a": LoggedRun(log, stack)}, robot, tmp_path / "arm_world.png") is None

"""Tutorial 2, write your own task: a custom ``Task`` (J, v, e) and a custom ``Potential`` (p, exact η).

The robot is a planar 4R arm (four unit links, built from a D-H table). Two rows of the main task hold the tip on a
line; a third row is a task written here, ``ToolAngleTask``: the tool's absolute angle φ = θ1 + θ2 + θ3 + θ4 is held
at a set value. That leaves one redundant degree of freedom, which a potential written here, ``ElbowHeight`` (the
height y of the elbow, frame "2"), raises through a gradient subtask (k > 0 climbs p, eq. 5.8).

The potential's gradient is exact (a row of the frame Jacobian); the script checks it against central finite
differences at random configurations before using it. Run: ``python examples/custom_task.py``.
"""

from __future__ import annotations

import numpy as np

import redundik as rk


class ToolAngleTask(rk.Task):
    """Hold the planar tool angle φ = Σθ_i [rad] of a planar arm at ``target``: one row J = (1, …, 1).

    Args:
        target: φ_d [rad].
        gain: Feedback gain K [1/s] on e = φ_d − φ.
        name: Task name in the stack.
    """

    def __init__(self, target: float, *, gain: float = 10.0, name: str = "tool_angle") -> None:
        self._init_task(name, gain=gain)  # validated shared fields: name, weight, gain, priority
        self.target = float(target)

    def evaluate(self, robot: rk.RobotModel, t: float) -> rk.TaskTerm:
        """The row J q̇ = K (φ_d − φ); ``robot`` is already updated at the current q."""
        J = np.ones((1, robot.nv))  # (1, nv): dφ/dq
        error = np.array([self.target - float(np.sum(robot.q))])  # (1,)
        return rk.TaskTerm(self.name, J, self.gain * error, error, self.weight)

    def __repr__(self) -> str:
        return f"ToolAngleTask(target={self.target:.3f}, gain={self.gain:g})"


class ElbowHeight(rk.Potential):
    """Height of a frame origin above the base: p = y_f(q) [m], η = ∂y_f/∂q, the y row of the frame's Jacobian."""

    def __init__(self, frame: str, name: str = "elbow_height") -> None:
        self.frame = frame
        self.name = name

    def check(self, robot: rk.RobotModel) -> None:
        """Fail early, with the list of frames, if the frame does not exist."""
        try:
            robot.frame_id(self.frame)
        except rk.ModelError as exc:
            raise rk.TaskError(f"subtask '{self.name}': {exc}") from exc

    def value(self, robot: rk.RobotModel) -> float:
        return float(robot.frame_position(self.frame)[1])

    def gradient(self, robot: rk.RobotModel) -> np.ndarray:
        return robot.frame_jacobian(self.frame)[1].copy()  # (nv,): the linear-velocity y row, base-aligned


def finite_difference_gradient(
    robot: rk.RobotModel, potential: rk.Potential, q: np.ndarray, h: float = 1e-6
) -> np.ndarray:
    """Central differences (p(q ⊕ h e_i) − p(q ⊕ −h e_i)) / 2h, one joint at a time."""
    grad = np.zeros(robot.nv)
    for i in range(robot.nv):
        step = np.zeros(robot.nv)
        step[i] = h
        robot.update(robot.integrate(q, step, 1.0))
        plus = potential.value(robot)
        robot.update(robot.integrate(q, -step, 1.0))
        grad[i] = (plus - potential.value(robot)) / (2.0 * h)
    robot.update(q)
    return grad


def main() -> int:
    robot = rk.from_dh([rk.DHRow(str(i), a=1.0) for i in range(1, 5)], name="planar4r")
    elbow = ElbowHeight("2")

    # 1. the gradient is exact: compare with finite differences at a few random configurations
    rng = np.random.default_rng(0)
    fd_error = 0.0
    for _ in range(5):
        q = rng.uniform(-np.pi, np.pi, robot.nq)
        robot.update(q)
        fd_error = max(
            fd_error, float(np.max(np.abs(elbow.gradient(robot) - finite_difference_gradient(robot, elbow, q))))
        )
    print(f"ElbowHeight: max |η − η_FD| over 5 configurations = {fd_error:.2e}")

    # 2. use both in a stack: tip on a line (x, y rows) + the tool angle; the elbow climbs in the null space
    q = np.array([0.3, 0.9, 0.9, 0.6])
    robot.update(q)
    tool = ToolAngleTask(target=float(np.sum(q)), gain=10.0)
    tip = rk.FrameTask("4", rk.Line([0.0, -0.2]), axes="planar", gain=10.0)
    raise_elbow = rk.GradientSubtask(elbow, gain=1.0)

    dt, steps = 0.01, 300
    final: dict[str, float] = {}
    runs: list[tuple[str, str, list[rk.Subtask]]] = [
        ("pinv, no subtask", "pinv", []),
        ("pinv + elbow", "pinv", [raise_elbow]),
        ("hqp + elbow", "hqp", [raise_elbow]),
    ]
    for label, resolver_name, subtasks in runs:
        stack = rk.TaskStack([tip, tool], subtasks)
        resolver = rk.make_resolver(resolver_name)
        qk = q.copy()
        robot.update(qk)
        stack.reset(robot)
        worst = 0.0
        for k in range(steps):
            result = resolver.step(robot, stack, qk, k * dt, dt)
            worst = max(worst, result.task_error)
            qk = robot.integrate(qk, result.dq, dt)
        robot.update(qk)
        final[label] = elbow.value(robot)
        print(
            f"{label:17}: elbow height {final[label]:.3f} m after the line, max main-task error {worst:.1e}, "
            f"tool angle error {abs(tool.target - qk.sum()):.1e} rad"
        )

    higher = final["pinv + elbow"] - final["pinv, no subtask"]
    print(f"the gradient subtask keeps the elbow {100 * higher:.1f} cm higher, at no cost to the main tasks")
    ok = fd_error < 1e-6 and higher > 0.0
    print(f"check: analytic vs finite-difference gradient agree to {fd_error:.1e} (< 1e-6): {'OK' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

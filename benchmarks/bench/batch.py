"""The batch case ``panda_batch1000``: 1000 Panda pose problems through :class:`redundik.resolvers.BatchResolver`
(``wqp_batch``, ``pinv_batch``) against the same problems one by one through ``resolver.step``:

* ``wqp_steps``, ``pinv_steps`` — the loop a user writes: one stack (a ``FrameTask`` holding its target, the
  ``PostureTask``) made once, then per problem ``task.set_target(T_i)`` and ``resolver.step(robot, stack, q_i, 0,
  dt)``: ordinary steps, the headline's reference;
* ``wqp_loop``, ``pinv_loop`` — :meth:`BatchResolver.solve_loop`, the batch API's contract reference: it also sets
  the posture's target and calls ``resolver.reset()`` per problem (no rate window, no warm start carried over), so
  it pays more than ordinary steps; kept for the agreement check, not for the speed-up.

Problem i: one control step (dt = 10 ms, frame gain K = 1/dt, posture K_p = 1/s towards q0) from q_i towards the
hand pose at q_i + δ_i, where q_i is uniform in the joint ranges (2 cm/rad inside them) and δ_i uniform in ±0.01
rad per joint — a reachable target, so one dead-beat step lands within a second-order residual. 5 % of the
problems start 1e-5 rad inside ``panda_joint4``'s upper limit (δ moving that joint only, inwards) so wqp's limits
bind there and the batch calls the QP backend for them, as the loop does. Fixed seed: every method solves the
same 1000 problems.

A "step" of these cases is one call resolving all 1000; ``median_us``/``p90_us`` are per call and
``problems_per_s`` = 1000 / median. ``max_task_error`` is the largest pose error after the step over the 1000
problems (tolerance 1 mm), ``limit_violations`` the number of problems whose q_i ⊕ q̇·dt leaves the limits; a batch
case whose q̇ differs from the loop's by more than 1e-9 is failed.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pinocchio as pin

from benchmarks.bench.scenarios import PANDA_Q0, POSTURE_GAIN
from redundik.kinematics.urdf import load_example_robot
from redundik.resolvers.batch import BatchResolver, BatchResult
from redundik.resolvers.registry import make_resolver

ROBOT_KEY = "panda_batch1000"
N_PROBLEMS = 1000
DT = 0.01
#: Largest |q̇_batch − q̇_loop| a batch case may show (the batch API's contract) [rad/s].
AGREEMENT = 1e-9
#: The methods of the case, in report order.
METHODS: tuple[str, ...] = ("wqp_batch", "wqp_steps", "wqp_loop", "pinv_batch", "pinv_steps", "pinv_loop")


def make_problems(robot: Any, n: int = N_PROBLEMS, seed: int = 11) -> tuple[np.ndarray, np.ndarray]:
    """(q (n, nq), targets (n, 4, 4)) as the module docstring says."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.lower_limits, robot.upper_limits
    q = rng.uniform(lo + 0.02, hi - 0.02, (n, robot.nq))
    delta = rng.uniform(-0.01, 0.01, (n, robot.nq))
    at_limit = rng.choice(n, size=max(n // 20, 1), replace=False)
    j4 = robot.joint("panda_joint4").idx_q
    q[at_limit, j4] = hi[j4] - 1e-5
    delta[at_limit] = 0.0
    delta[at_limit, j4] = -rng.uniform(0.002, 0.01, at_limit.size)  # only that joint moves, inwards
    targets = np.empty((n, 4, 4))
    for i in range(n):
        robot.update(np.clip(q[i] + delta[i], lo, hi))
        targets[i] = robot.frame_pose("panda_hand").homogeneous
    return q, targets


class BatchRunner:
    """One of :data:`METHODS`; :meth:`run` makes calls of all problems."""

    def __init__(self, method: str, problems: int = N_PROBLEMS) -> None:
        self.method = method
        self.resolver_name, self.mode = method.split("_")
        self.robot = load_example_robot("panda")
        self.q, self.targets = make_problems(self.robot, problems)
        # a dead-beat step (K = 1/dt) of an ideal problem: pinv without its joint-speed cap, which would scale the
        # problems that ask more than the Panda's velocity limits (wqp keeps those limits as constraints)
        options = {"max_joint_speed": None} if self.resolver_name == "pinv" else {}
        resolver = make_resolver(self.resolver_name, **options)
        used = getattr(resolver, "backend", None)
        self.backend = str(getattr(used, "name", used) or "-")
        self.batch = BatchResolver(
            resolver, self.robot, "panda_hand", gain=1.0 / DT, posture_gain=POSTURE_GAIN, posture_target=PANDA_Q0
        )
        self.step_ns: list[int] = []
        self.result: Any = None
        self.failures = 0
        self.first_failure: str | None = None
        self.resolver = resolver
        self.paths: dict[str, int] = {}
        if self.mode == "steps":  # the user's loop: one stack, made once
            self.stack = self.batch.loop_stack(self.q[0], self.targets[0])
            self.robot.update(self.q[0])
            self.stack.reset(self.robot)

    @property
    def label(self) -> str:
        return f"{ROBOT_KEY}/{self.method}/{self.backend}"

    def steps(self, q: np.ndarray, targets: np.ndarray, dt: float) -> BatchResult:
        """The problems as a user's loop of ordinary steps (module docstring): ``set_target`` + ``step`` each."""
        n = q.shape[0]
        dq = np.empty((n, self.robot.nv))
        err = np.empty(n)
        used = np.zeros(n, dtype=bool)
        notes: list[str | None] = []
        robot, stack, step = self.robot, self.stack, self.resolver.step
        task = stack.tasks[0]
        for i in range(n):
            task.set_target(targets[i])  # type: ignore[attr-defined]
            res = step(robot, stack, q[i], 0.0, dt)
            dq[i] = res.dq
            err[i] = res.terms[0].error_norm
            used[i] = bool(res.info.get("qp", 0))
            notes.append(res.fallback)
        path = str(res.info.get("path", "?")) if n else "?"
        self.paths[path] = self.paths.get(path, 0) + 1  # the last step's path, once per call
        return BatchResult(dq, err, used, notes)

    def run(self, steps: int) -> None:
        solve = {"batch": self.batch.solve, "loop": self.batch.solve_loop, "steps": self.steps}[self.mode]
        for _ in range(steps):
            t0 = time.perf_counter_ns()
            try:
                res = solve(self.q, self.targets, DT)
            except Exception as exc:  # counted, never stops the benchmark
                self.failures += 1
                self.first_failure = self.first_failure or f"{type(exc).__name__}: {exc}"
                self.step_ns.append(0)
                continue
            self.step_ns.append(time.perf_counter_ns() - t0)
            self.result = res

    def close(self) -> None:
        pass

    def measure(self) -> dict[str, Any]:
        """The common ruler on the last answer: pose errors after the step, limit violations, agreement with the
        loop (batch cases), fallbacks and the fraction of problems that called the QP backend."""
        res = self.result
        robot, n = self.robot, self.q.shape[0]
        if res is None:
            return {"max_task_error": float("nan"), "limit_violations": 0, "max_violation": 0.0, "fallbacks": 0}
        errors = np.empty(n)
        viol = np.empty(n)
        for i in range(n):
            qn = robot.integrate(self.q[i], res.dq[i], DT)
            viol[i] = float(np.max(robot.limit_violation(qn), initial=0.0))
            robot.update(qn)
            M = robot.frame_pose("panda_hand")
            T = self.targets[i]
            err = pin.log6(M.inverse() * pin.SE3(T[:3, :3], T[:3, 3])).vector
            errors[i] = float(np.linalg.norm(err))
        out: dict[str, Any] = {
            "max_task_error": float(np.max(errors)),
            "mean_task_error": float(np.mean(errors)),
            "limit_violations": int(np.sum(viol > 0.0)),
            "max_violation": float(np.max(viol, initial=0.0)),
            "fallbacks": sum(f is not None for f in res.fallback),
            "first_fallback": next((f for f in res.fallback if f is not None), None),
            "qp_fraction": float(res.qp_fraction) if self.resolver_name == "wqp" else None,
        }
        if self.mode != "loop":
            ref = self.batch.solve_loop(self.q, self.targets, DT)
            out["loop_agreement"] = float(np.max(np.abs(res.dq - ref.dq)))
        return out

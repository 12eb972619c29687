"""The chapter's closed form: rank solution plus null-space gradient projection, eqs. (5.8) and (5.15).

q̇ = J⁺V + (I − J⁺J) z,   z = Σ_i k_i η_i + Σ_r K_r e_r  (gradient subtasks and identity regularisers such as a
posture: the stack's null-space objective, :mod:`redundik.tasks.stack`).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from redundik._coldstart import ready
from redundik.errors import ResolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import LazyStepResult, Resolver, StepResult, nonfinite_sources
from redundik.resolvers.fused import FusedPlan, FusedStepResult
from redundik.resolvers.layouts import CF_DQ, CF_NULL, CF_RANK, CF_ROWS
from redundik.resolvers.linalg import FK, RCOND, K, contiguous, gram_sigma_min
from redundik.resolvers.result import info_keys
from redundik.resolvers.settings import Setting, flag
from redundik.resolvers.singularity import NO_CAPS, SingularityGuard
from redundik.tasks.base import TaskTerm, stack_terms
from redundik.tasks.stack import StackLayout, TaskStack

_NO_Z = np.zeros(0)


def check_damping_options(who: str, epsilon: float, max_damping: float) -> tuple[float, float]:
    """Validated (ε, λ_max): finite numbers ≥ 0."""
    for key, val in (("epsilon", epsilon), ("max_damping", max_damping)):
        if isinstance(val, bool) or not isinstance(val, (int, float, np.integer, np.floating)):
            raise ResolverError(f"{who}: {key} must be a number, got {type(val).__name__}")
        if not (np.isfinite(val) and val >= 0):
            raise ResolverError(f"{who}: {key} must be a finite number ≥ 0, got {val}")
    return float(epsilon), float(max_damping)


def main_system(
    robot: RobotModel, stack: TaskStack, terms: list[TaskTerm], layout: StackLayout
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(J, V) of every main task stacked (eq. 5.6) and z of the null-space objective (``None`` if empty).

    Every regularisation task without a level adds its J⁺v to z (:meth:`TaskStack.null_target`).
    """
    main_terms = [terms[i] for i in layout.main]
    J, V = stack_terms(main_terms, robot.nv)
    return J, V, stack.null_target(robot, terms, layout)


class PinvResolver(Resolver):
    """Pseudo-inverse resolution with null-space gradient projection (5.8, 5.15).

    Accepts gradient subtasks (and regularisation tasks: a posture), projected on the null space of the stacked
    main-task Jacobian. Near a singularity the small singular directions of J⁺ are damped (see
    :mod:`redundik.resolvers.linalg`) and the step result says so (``damped``, ``damping``, ``sigma_min``).

    Args:
        epsilon: Singular value under which a direction is damped [unit of J].
        max_damping: Damping λ_max as σ → 0.
        max_joint_speed: Cap on every |q̇_i| [rad/s; m/s for a prismatic joint]: ``"auto"`` = the robot's velocity
            limits (10 rad/s where it has none), a number, or ``None`` (no cap); when it acts q̇ is scaled as a whole
            and the step says so (:mod:`redundik.resolvers.singularity`).
        singularity: A :class:`~redundik.resolvers.singularity.SingularityGuard` (or a mapping of its fields,
            ``True`` for its defaults) to decelerate and halt near a singularity of the main tasks; ``None``: none.
    """

    name = "pinv"
    #: Take the fused step (:mod:`redundik.resolvers.fused`) when the stack allows it; the per-task path otherwise
    #: (the same answer: a switch for comparisons and tests).
    fuse = Setting(flag)
    accepts: ClassVar[tuple[str, ...]] = ("gradient",)

    def __init__(
        self,
        epsilon: float = 1e-2,
        max_damping: float = 5e-2,
        max_joint_speed: float | str | None = "auto",
        singularity: SingularityGuard | dict[str, float] | bool | None = None,
    ) -> None:
        self.fuse = True
        self._epsilon, self._max_damping = check_damping_options("pinv", epsilon, max_damping)
        self._tail = (self._epsilon, self._max_damping, RCOND)  # the fused step's coefficients of the resolver
        self.max_joint_speed, self.singularity = max_joint_speed, singularity  # (validated on assignment)
        self._layout: tuple[tuple[int, ...], StackLayout] | None = None
        self._fused: tuple[StackLayout, FusedPlan | str | bool] | None = None

    @property
    def epsilon(self) -> float:
        """Singular value under which a direction is damped [unit of J] (validated on assignment)."""
        return self._epsilon

    @epsilon.setter
    def epsilon(self, value: float) -> None:
        self._epsilon, _ = check_damping_options("pinv", value, self._max_damping)
        self._tail = (self._epsilon, self._max_damping, RCOND)

    @property
    def max_damping(self) -> float:
        """Damping λ_max as σ → 0 (validated on assignment)."""
        return self._max_damping

    @max_damping.setter
    def max_damping(self, value: float) -> None:
        _, self._max_damping = check_damping_options("pinv", self._epsilon, value)
        self._tail = (self._epsilon, self._max_damping, RCOND)

    def _stack_layout(self, stack: TaskStack) -> StackLayout:
        sig = self.stack_key(stack)
        cached = self._layout
        if cached is None or (cached[0] is not sig and cached[0] != sig):
            self._layout = cached = (sig, stack.layout())
        return cached[1]

    def solve(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> StepResult:
        t0 = time.perf_counter()
        cached = self._layout
        if cached is not None and stack is self._stepping and cached[0] is self._checked:  # the step's layout
            layout = cached[1]
        else:
            layout = self._stack_layout(stack)
        main = layout.main
        if self.fuse:
            fused = self._fused
            if fused is None or fused[0] is not layout or fused[1] == FusedPlan.NOT_YET:
                # (while its kernels compile in the background: the per-task path, planned again at the next step)
                built = (
                    FusedPlan.build(robot, stack, layout, None, 1.0, mixed=True) if ready("pinv") else FusedPlan.NOT_YET
                )
                fused = self._fused = (layout, built if built is not None else False)
            plan = fused[1]
            if isinstance(plan, FusedPlan):
                if plan.current(robot):
                    res = self._fused_solve(robot, plan, main, t, t0)
                    if res is not None:
                        # (Resolver.step reports the path: compiled, or mixed naming the Python-written members)
                        res.__dict__["_compiled"] = plan.external_names or True
                        return res
                else:
                    self._fused = None  # a member changed: planned again at the next step
        terms = stack.evaluate(robot, t)
        if len(main) == 1:  # main_system's stacking, for the common single main task
            term = terms[main[0]]
            J, V = term.J, term.v
            z = stack.null_target(robot, terms, layout)
        else:
            J, V, z = main_system(robot, stack, terms, layout)
        t1 = time.perf_counter()
        has_z = z is not None
        out = np.empty((CF_ROWS, robot._nv))
        rank, sigma_min, damping = K.closed_form_into(  # one compiled call: J⁺V, (I − J⁺J) z (5.8) and their sum
            contiguous(J),
            contiguous(V),
            _NO_Z if z is None else contiguous(z),
            has_z,
            self.epsilon,
            self.max_damping,
            RCOND,
            out,
            True,  # σ_min left to be computed on request when J is well conditioned (a Cholesky solve instead)
        )
        dq_r, dq_n, dq = out[CF_RANK], out[CF_NULL], out[CF_DQ]
        fallback = None
        if not math.isfinite(dq.dot(dq)) and not np.isfinite(dq).all():  # the dot first: one call when all is well
            bad = nonfinite_sources(terms, robot, stack, z=z)
            fallback = f"non-finite q̇ (from {', '.join(bad) or 'the pseudo-inverse'}): q̇ = 0 this step"
            dq = np.zeros(robot.nv)
        t2 = time.perf_counter()
        if sigma_min != sigma_min:  # NaN: J well conditioned and undamped, σ_min computed on first read
            diagnostics = functools.partial(_closed_form_sigma, J)
            return LazyStepResult.make(
                dq, terms, fallback, {"rank": int(rank)}, t1 - t0, t2 - t1, layout.main, diagnostics, dq_r, dq_n
            )
        return StepResult(
            dq=dq,
            terms=terms,
            dq_rank=dq_r,
            dq_null=dq_n,
            damped=damping > 0.0,
            damping=float(damping),
            sigma_min=float(sigma_min),
            fallback=fallback,
            info={"sigma_min": float(sigma_min), "rank": int(rank)},
            build_time=t1 - t0,
            solve_time=t2 - t1,
            main=layout.main,
        )

    def _fused_solve(
        self, robot: RobotModel, plan: FusedPlan, main: list[int], t: float, t0: float
    ) -> StepResult | None:
        """The step of a fused stack (:mod:`redundik.resolvers.fused`) in one compiled call; ``None`` when this step
        needs the per-task path (a rotation error beyond the compiled log3's range, a non-finite q̇ to diagnose)."""
        coef = plan.coefficients(self._tail)
        refs = plan.given_references(t) if plan.given else plan.refs
        external: list[TaskTerm | None] | tuple[()] = ()
        if plan.plain_rows:  # a user's own tasks only: evaluated and put straight into work, in one walk
            work = np.empty(plan.pinv_work)  # q̇'s parts, J, e and v, the frames' Jacobians: one allocation
            taken = plan.take_plain_rows(robot, t, work, _plain_at(plan, robot._nv))
            if taken is None:
                return None
            if plan.repacked:  # a row count moved: the plan was packed again, and work is sized anew
                work = np.empty(plan.pinv_work)
                plan.put_plain_rows(robot, taken, work, _plain_at(plan, robot._nv))
            external = taken
        elif plan.direct_main and plan.direct_rows == plan.external_rows:  # compiled writers of tasks only: run
            # straight into work (their rows laid out as the writers give them)
            work = np.empty(plan.pinv_work)
            external = plan.take_direct_rows(robot, t, work, _plain_at(plan, robot._nv))
        elif plan.external:  # the members without a compiled form: their evaluate, written into the step's rows
            evaluated = plan.evaluate_external(robot, t, direct=True)
            if evaluated is None:
                return None
            external = evaluated
            work = np.empty(plan.pinv_work)
            n, m = robot._nv, plan.m
            a, _, b, _, _ = _plain_at(plan, n)
            end = work.shape[0]  # work's tail: the Python writers' null-space terms (n,), then z (n,)
            Jm, ev = work[a:b].reshape(m, n), work[b : b + 2 * m].reshape(2, m)
            plan.write_external(robot, external, Jm, 0, ev, None, work[end - 2 * n : end - n], t)
        else:
            work = np.empty(plan.pinv_work)
        q = robot.q
        speed = self._limiter
        status, rank, sigma_min, damping, err2, dq2, over = FK.fused_pinv_step(
            plan.jw, plan.poses, float(t), refs, q, plan.ints, plan.floats, coef, work,
            NO_CAPS if speed is None else speed.folded_caps(robot),
        )  # fmt: skip
        if status < 0.0 or not math.isfinite(dq2):  # a non-finite q̇: the per-task path diagnoses it
            return None
        return FusedPinvResult.of(
            work, plan, q, robot, (rank, sigma_min, damping, err2, dq2, over), time.perf_counter() - t0, main, external
        )

    def __repr__(self) -> str:
        return f"PinvResolver(epsilon={self.epsilon}, max_damping={self.max_damping})"


def _plain_at(plan: FusedPlan, n: int) -> tuple[int, int, int, int, int]:
    """Where a ``pinv`` step's work array takes the main rows' J, e and v (``PythonWriters.put_plain_rows``' ``at``;
    ``FK.pinv_work_views``' layout, sliced here: a compiled call returning views costs more)."""
    a = CF_ROWS * n
    b = a + plan.m * n
    return (a, 0, b, b + plan.m, -1)


@info_keys("sigma_min")
def _closed_form_sigma(J: np.ndarray) -> tuple[float, bool, dict[str, object]]:
    """σ_min of a closed-form step's J (well conditioned and undamped: its Cholesky route), on first read."""
    smin = gram_sigma_min(J)
    return smin, False, {"sigma_min": smin}


@info_keys("sigma_min")
def _fused_sigma(step: tuple[Any, ...]) -> tuple[float, bool, dict[str, object]]:
    """σ_min of a fused ``pinv`` step's main Jacobian (read from its work array; the step was undamped)."""
    work, plan, _, robot, _ = step
    Jm = FK.pinv_work_views(work, len(plan.frames), plan.m, robot._nv)[1]
    smin = gram_sigma_min(Jm)
    return smin, False, {"sigma_min": smin}


class FusedPinvResult(FusedStepResult):
    """The result of a fused ``pinv`` step: q̇ a view on the step's work array, and what a control loop seldom reads
    — J⁺V, (I − J⁺J) z, the task terms, σ_min when the Cholesky route left it — read from that array when asked."""

    @classmethod
    def of(
        cls,
        work: np.ndarray,
        plan: FusedPlan,
        q: np.ndarray,
        robot: RobotModel,
        outputs: tuple[int, float, float, float, float, float],
        build_time: float,
        main: list[int],
        external: list[TaskTerm | None] | tuple[()] = (),
    ) -> FusedPinvResult:
        """The result of ``fused_pinv_step``'s ``outputs`` (rank, σ_min — NaN: J well conditioned and undamped,
        computed on first read —, damping, Σ e², ‖q̇‖², the cap ratio)."""
        rank, sigma_min, damping, err2, dq2, over = outputs
        n = robot._nv
        res = cls.__new__(cls)
        lazy = sigma_min != sigma_min
        res.__dict__ = {
            "dq": work[CF_DQ * n : (CF_DQ + 1) * n],
            "gains": None,
            "damping": damping,
            "fallback": None,
            "_info": {"rank": rank} if lazy else {"sigma_min": sigma_min, "rank": rank},
            "build_time": build_time,
            "solve_time": 0.0,
            "main": main,
            "pending": True if lazy else None,  # ``_resolve`` computes σ_min from the step's J
            "_task_error": math.sqrt(err2),
            "_dq_norm": math.sqrt(dq2),  # ‖q̇‖ from the compiled call (the divergence watch reads it)
            "_cap_ratio": over,  # max_i |q̇_i| / c_i from the compiled call (−1: not computed)
            "_step": (work, plan, q, robot, external),
        }
        if not lazy:
            res.__dict__["_sigma_min"], res.__dict__["_damped"] = sigma_min, damping > 0.0
        return res

    def _views(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        work, plan, _, robot, _ = self.__dict__["_step"]
        return FK.pinv_work_views(work, len(plan.frames), plan.m, robot._nv)

    def _pending_fn(self) -> Callable[[], tuple[float, bool, dict[str, object]]]:
        d = self.__dict__
        if d.get("pending") is True:  # σ_min from the step's J (the step's arrays, not this result)
            return functools.partial(_fused_sigma, d["_step"])
        return super()._pending_fn()

    def _build_terms(self) -> list[TaskTerm]:
        _, plan, q, robot, external = self.__dict__["_step"]
        _, _, ev, Jf = self._views()
        return plan.terms(Jf, ev, q, robot, external)

    @property
    def dq_rank(self) -> np.ndarray | None:
        d = self.__dict__
        if "_dq_rank" not in d:
            n = d["_step"][3]._nv
            d["_dq_rank"] = d["_step"][0][CF_RANK * n : (CF_RANK + 1) * n]
        return d["_dq_rank"]

    @dq_rank.setter
    def dq_rank(self, value: np.ndarray | None) -> None:
        self.__dict__["_dq_rank"] = value

    @property
    def dq_null(self) -> np.ndarray | None:
        d = self.__dict__
        if "_dq_null" not in d:
            n = d["_step"][3]._nv
            d["_dq_null"] = d["_step"][0][CF_NULL * n : (CF_NULL + 1) * n]
        return d["_dq_null"]

    @dq_null.setter
    def dq_null(self, value: np.ndarray | None) -> None:
        self.__dict__["_dq_null"] = value

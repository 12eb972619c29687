"""The fused step: a stack whose members all have a compiled form is evaluated, accumulated and solved in one call.

A control tick of the per-task path calls every task's ``evaluate`` (a ``TaskTerm``
each), then the resolver's kernels on them: some sixty Python-level calls, which on a 9-dof arm cost more than the
arithmetic. Most stacks are made of a few kinds of member whose rows are known formulas:

* ``FrameTask`` — the rows of its frame's Jacobian and the error
  (p_d − p, log3(R_d Rᵀ)), its trajectory sampled inside the compiled call for ``Hold``, ``Line`` and ``Circle``
  (in Python for any other);
* a joint-space task that declares ``joint_form`` — J = I[sel],
  e = (q_ref ⊖ q)[sel], v = K e (a posture);
* terms of the null-space objective z (eq. 5.8): identity regularisers (a posture: z += v) and gradient subtasks
  of a potential that declares ``linear_gradient`` (a joint centering:
  z += k w ⊙ (q ⊖ q_c)).

For such a stack, ``FusedPlan`` (built once per stack membership) packs their static data; each step it checks
that the array-valued members are the same objects (trajectory, targets, centres), re-reads gains and weights when
one was set (``Edits``), and hands Pinocchio's Jacobians and poses to one kernel of
``redundik.resolvers.fused_kernels`` — the composition of the per-task kernels, not a second implementation. The
step's terms are built only when read (``FusedStepResult``). Whatever the plan cannot take — another task
type, a frame target set as a position, a rotation error beyond the compiled log3's range, a coordinate without a
1-dof position — goes the per-task way, for that stack or that step: the answer is the same (tested to 1e-12).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from redundik.kinematics.memory import jacobian_view, se3_vector_view
from redundik.kinematics.model import RobotModel
from redundik.resolvers.fused_external import GRADIENT as GRADIENT
from redundik.resolvers.fused_external import LIE_NULL as LIE_NULL
from redundik.resolvers.fused_external import NULL as NULL
from redundik.resolvers.fused_external import ROW as ROW
from redundik.resolvers.fused_external import ROWS as ROWS
from redundik.resolvers.fused_external import TARGET as TARGET
from redundik.resolvers.fused_external import TERM as TERM
from redundik.resolvers.fused_external import PythonWriters
from redundik.resolvers.fused_result import FusedStepResult as FusedStepResult
from redundik.resolvers.layouts import FLOAT_PARTS as FLOAT_PARTS
from redundik.resolvers.layouts import GIVEN_ERROR as GIVEN_ERROR
from redundik.resolvers.layouts import H_EXTERNAL_ROWS as H_EXTERNAL_ROWS
from redundik.resolvers.layouts import H_EXTERNAL_Z as H_EXTERNAL_Z
from redundik.resolvers.layouts import H_FRAME_PARAMS as H_FRAME_PARAMS
from redundik.resolvers.layouts import H_JOINT_TARGETS, H_NULL_CENTRES
from redundik.resolvers.layouts import HEADER as HEADER
from redundik.resolvers.layouts import IDENTITY as IDENTITY
from redundik.resolvers.layouts import INT_PARTS as INT_PARTS
from redundik.resolvers.layouts import REF as REF
from redundik.resolvers.linalg import FK
from redundik.tasks.base import NOT_READY, CompiledGradient, CompiledRows, Edits, FrameForm, Task, TaskTerm
from redundik.tasks.conform import check_linear_gradient, conform_reference
from redundik.tasks.frame import FrameTask
from redundik.tasks.layouts import PARAMS, REF_P, REF_R, REF_TWIST
from redundik.tasks.potential_rows import compiled_writer
from redundik.tasks.rows import check_form
from redundik.tasks.stack import StackLayout, TaskStack
from redundik.tasks.subtasks import GradientSubtask
from redundik.tasks.trajectory import GIVEN

Form = tuple[np.ndarray, np.ndarray]


class FusedPlan(PythonWriters):
    """The packed static data of a fused stack (module docstring); ``build`` makes one or says why not.

    Attributes:
        frames: The frame tasks, in stack order; ``level_joints``: the joint-space tasks of a level (``wqp``);
            ``nulls``: the regularisation tasks of the null-space objective; ``gradients``: its gradient subtasks.
        ints, floats: The static data in the layout of ``HEADER``.
        coef: The step's coefficients (gains, weights × ρ^k, …), re-read when ``Edits`` moved.
        m: Rows of e (frame rows, then joint-task rows).
    """

    #: ``build``'s answer when a frame task has not been evaluated on this robot yet (try at the next step).
    NOT_YET: ClassVar[str] = "not yet"

    def __init__(self) -> None:
        self.frames: list[FrameTask] = []
        self.level_joints: list[Task] = []
        self.nulls: list[Task] = []
        self.gradients: list[GradientSubtask] = []
        self.order: list[tuple[str, int]] = []  # per stack task: ("f", k), ("j", k) a level task, ("n", k) a null one
        self.fids: list[int] = []
        self.trajs: list[Any] = []
        self.kparams: list[Any] = []
        self.targets: list[np.ndarray] = []
        self.null_targets: list[np.ndarray] = []
        self.null_masks: list[np.ndarray] = []  # per null task: 1 on the coordinates it covers (its joint form's)
        self.gradient_forms: list[Form] = []
        self.scales: list[float] = []  # ρ^k per frame task, then per level joint task
        self.null_scale = 0.0
        self.given: list[int] = []
        self.ints = np.zeros(HEADER, np.int64)
        self.floats = np.zeros(0)
        self.coef = np.zeros(0)
        self.weights: list[float] = []
        self.edits = -1
        self.m = 0
        self.pinv_work = self.wqp_work = 0
        self.data: Any = None
        self.refs = np.zeros((0, REF))
        self.limit_args: tuple[Any, ...] | None = None
        self.lim = np.zeros((4, 0))
        self.tail: tuple[float, ...] = ()
        self.jw = np.zeros((6, 0))  # data.J: the joint Jacobians, world frame (a view on Pinocchio's memory)
        self.poses = np.zeros((0, 12))  # data.oMf: the frames' placements (a view on Pinocchio's memory)
        self.forms: list[FrameForm] = []
        #: per frame member: its task, its form revision when packed, its trajectory, and the trajectory's
        #: parameter row in ``floats`` (a view)
        self.frame_checks: list[tuple[Any, int, Any, np.ndarray]] = []
        self.revisions: list[int] = []  # the trajectories' revisions as last copied into ``floats``
        self.param_offset = 0  # where the trajectories' parameter rows (K × PARAMS) start in ``floats``
        self.joint_checks: list[tuple[Task, np.ndarray]] = []
        #: per ``joint_checks`` entry, where its q_ref lies in ``floats`` (a view): a new target is written there
        self.target_rows: list[np.ndarray] = []
        self.gradient_checks: list[tuple[GradientSubtask, Form]] = []
        self.slots: list[tuple[int, Any, int, int, int, Any]] = []  # per stack task, for ``terms``
        self.qp = False  # built for wqp (weights, joint tasks at a level) rather than pinv
        #: the members written from Python, in stack order (tasks) then the gradient subtasks: (role, member, ρ^k)
        self.external: list[tuple[int, Any, float]] = []
        self.external_rows: list[int] = []  # rows each ``ROW`` member wrote at the last packing
        self.external_starts: list[int] = []  # where they start among the step's rows
        self.lie_joints: list[int] = []  # the level joint tasks on Lie-group coordinates (their error given)
        self.repacked = False  # the last ``evaluate_external`` packed the plan again (a row count moved)
        #: terms evaluated when the plan was made (``hqp`` sizes its buffers from them), for that step to use
        self.pending_external: list[TaskTerm | None] | None = None
        self.joint_spans: list[tuple[int, int]] = []  # each level joint task's rows among the step's rows
        self.external_names: tuple[str, ...] = ()
        #: per external member, its compiled writer (``Task.compiled_rows``) or ``None`` (its ``evaluate`` runs)
        self.writers: list[CompiledRows | CompiledGradient | None] = []
        #: the writers' tasks and potentials, with their form revisions when planned
        self.writer_checks: list[tuple[Any, int]] = []
        self.mx = 0  # rows written from Python (after the compiled rows)
        self.index: dict[int, int] = {}
        self.level_forms: list[Form] = []
        self.identity: list[bool] = []
        self.main_set: set[int] = set()
        self.robot: RobotModel | None = None

    # ------------------------------------------------------------------ building
    @classmethod
    def build(
        cls,
        robot: RobotModel,
        stack: TaskStack,
        layout: StackLayout,
        scales: dict[int, tuple[float, bool]] | None,
        null_scale: float,
        mixed: bool | str = False,
        targets: list[tuple[Any, float]] | None = None,
    ) -> FusedPlan | str | None:
        """The plan of ``stack``; ``None`` when a member has no compiled form and ``mixed`` is off (the per-task
        path then runs), or ``NOT_YET`` when a frame task has not been evaluated on this robot yet.

        Args:
            scales: Per task index, (ρ^k of its level, identity Jacobian) for ``wqp``; ``None`` for ``pinv``.
            null_scale: ρ^k of the null-space objective's level (``wqp``; 1 for ``pinv``).
            mixed: Members without a compiled form are written from Python (their ``evaluate``, a subtask's
                ``direction``) into the step's buffers before the compiled call (:attr:`external`), instead of
                sending the whole stack down the per-task path; ``"null"``: only terms of the null-space objective
                (a resolver whose compiled step takes no Python-written rows: ``hqp``).
            targets: (target subtask, ρ^k of its level): each a row ηᵀq̇ = ṗ_d + K e written from Python.
        """
        plan = cls()
        iq = np.array([j.idx_q for j in robot.joints], dtype=np.int64)
        null_tasks = set(layout.null_tasks)
        main_set = set(layout.main)
        identity: list[bool] = []
        level_forms: list[Form] = []
        forms: list[FrameForm] = []
        for i, task in enumerate(stack.tasks):
            frame_form = task.frame_form(robot)
            if frame_form is not None and i not in null_tasks:
                if frame_form == NOT_READY:
                    return cls.NOT_YET
                assert isinstance(frame_form, FrameForm)
                plan.order.append(("f", len(plan.frames)))
                plan.frames.append(task)  # type: ignore[arg-type]  # (a task with a frame form)
                forms.append(frame_form)
                continue
            form = task.joint_form(robot) if frame_form is None else None
            lie = form is not None and bool((iq[form[0]] < 0).any())  # a coordinate that is not a subtraction
            if i in null_tasks:
                if not plan.add_null(task, form, lie, robot.nv, bool(mixed)):
                    return None
            elif scales is None:  # pinv: a main task without a frame form; a task below it is only evaluated
                if not mixed:
                    return None
                plan.add_external(task, ROW if i in main_set else TERM, 1.0)
            elif form is not None and (not lie or mixed):
                if lie:
                    plan.lie_joints.append(len(plan.level_joints))
                plan.order.append(("j", len(plan.level_joints)))
                plan.level_joints.append(task)
                plan.targets.append(form[1])
                level_forms.append(form)
                identity.append(bool(scales.get(i, (1.0, False))[1]))
            elif not mixed or scales.get(i, (1.0, False))[1]:  # (an identity task is a diagonal shift: per-task)
                return None
            else:
                plan.add_external(task, ROW, scales.get(i, (1.0, False))[0])
        for sub in layout.gradients:
            lin = check_linear_gradient(sub.potential.linear_gradient(robot), robot._nv, robot._nq, sub.name)
            if lin is None or (iq[np.flatnonzero(lin[0])] < 0).any():
                if not mixed:
                    return None
                plan.add_external(sub, GRADIENT, 1.0)
                continue
            plan.gradients.append(sub)
            plan.gradient_forms.append(lin)
        if targets and not mixed:
            return None
        for sub, rho in targets or ():
            plan.add_external(sub, TARGET, rho)
        if mixed == "null" and any(role in (ROW, TERM, TARGET) for role, _, _ in plan.external):
            return None
        plan.find_compiled_writers(robot)
        jw, poses = jacobian_view(robot.data), se3_vector_view(robot.data.oMf)
        if jw is None or poses is None:  # Pinocchio's memory not laid out as checked: the per-task path
            return None
        plan.jw, plan.poses, plan.eta = jw, poses, np.zeros(robot.nv)
        index = {id(t): i for i, t in enumerate(stack.tasks)}
        plan.index = index
        scale = scales or {}
        plan.scales = [scale.get(index[id(t)], (1.0, False))[0] for t in plan.frames + plan.level_joints]
        has_null = plan.nulls or plan.gradients or any(r in (NULL, LIE_NULL, GRADIENT) for r, _, _ in plan.external)
        plan.null_scale = float(null_scale) if has_null else 0.0
        plan.qp = scales is not None
        plan.forms = forms
        plan.level_forms, plan.identity, plan.main_set = level_forms, identity, main_set
        plan._pack(robot, iq, level_forms, identity, main_set, index)
        plan.data = robot.data
        plan.joint_checks = list(zip(plan.level_joints + plan.nulls, plan.targets + plan.null_targets, strict=True))
        plan.gradient_checks = list(zip(plan.gradients, plan.gradient_forms, strict=True))
        return plan

    def find_compiled_writers(self, robot: RobotModel) -> None:
        """The compiled writers of the Python-placed members — a task's ``Task.compiled_rows``, a gradient
        subtask's ``Potential.compiled_gradient`` (``potential_rows.compiled_writer``) —: called, not evaluated."""
        writers: list[CompiledRows | CompiledGradient | None] = []
        checks: list[tuple[Any, int]] = []
        for role, member, _ in self.external:
            form: CompiledRows | CompiledGradient | None = None
            owner = member
            if role in (ROW, NULL, TERM):
                form = member.compiled_rows(robot)
                form = None if form is None else check_form(member, form)
            elif role == GRADIENT or role == TARGET:
                owner = getattr(member, "potential", None)
                form = compiled_writer(owner, robot)
            writers.append(form)
            if form is not None:
                checks.append((owner, owner.form_revision))
        self.writers, self.writer_checks = writers, checks

    def _frame_checks(self) -> None:
        """Per frame member: its task, its form revision when packed, its trajectory, and a view of its packed
        parameter row (after every packing: the views are into the new ``floats``)."""
        start = self.param_offset
        self.frame_checks = [
            (f.task, f.revision, f.trajectory, self.floats[start + k * PARAMS : start + (k + 1) * PARAMS])
            for k, f in enumerate(self.forms)
        ]
        self.revisions = [f.trajectory.revision for f in self.forms]
        for _, _, traj, packed in self.frame_checks:  # a new target is then written straight into ``floats``
            traj.share_parameters(packed)

    def add_external(self, member: Any, role: int, scale: float) -> None:
        """Register a member written from Python (role ``ROW``, ``NULL``, ``LIE_NULL``, ``GRADIENT``, ``TERM`` or
        ``TARGET``); a gradient or a target subtask has no task term of its own (it is not in :attr:`order`)."""
        if role != GRADIENT and role != TARGET:
            self.order.append(("x", len(self.external)))
        self.external.append((role, member, scale))

    def _pack(
        self,
        robot: RobotModel,
        iq: np.ndarray,
        level_forms: list[Form],
        identity: list[bool],
        main: set[int],
        index: dict[int, int],
    ) -> None:
        """Write ``ints`` and ``floats`` in the layout of ``fused_kernels.HEADER``."""
        nv, nq = robot.nv, robot.nq
        K, J = len(self.frames), len(self.level_joints)
        self.robot = robot
        rows_of = [r for r in self.external_rows]
        if len(rows_of) != sum(1 for role, _, _ in self.external if role in ROWS):
            rows_of = self.external_rows = [0] * sum(1 for role, _, _ in self.external if role in ROWS)
        self.mx = sum(rows_of)
        writers = self.writers if len(self.writers) == len(self.external) else [None] * len(self.external)
        self.external_names = tuple(
            str(getattr(member, "name", type(member).__name__))
            for (role, member, _), writer in zip(self.external, writers, strict=True)
            if role != LIE_NULL and writer is None
        )
        nulls = self.gradient_forms + list(zip(self.null_masks, self.null_targets, strict=True))
        N = len(nulls)
        forms = self.forms
        self.fids = [int(f.fid) for f in forms]
        self.trajs = [f.trajectory for f in forms]
        self.kparams = [f.trajectory.parameters for f in forms]
        kinds = [int(f.trajectory.kind) if f.trajectory.parameters is not None else GIVEN for f in forms]
        self.given = [k for k in range(K) if kinds[k] == GIVEN]
        frows = [int(r) for f in forms for r in f.rows]
        starts = np.cumsum([0] + [len(f.rows) for f in forms]).tolist()
        jsel = [int(s) for f in level_forms for s in f[0]]
        jstarts = np.cumsum([0] + [f[0].shape[0] for f in level_forms]).tolist()
        mf = int(starts[-1])
        self.m = mf + int(jstarts[-1]) + self.mx
        self.pinv_work = FK.pinv_work_size(K, self.m, nv)  # a pinv step's flat work array
        self.wqp_work = FK.wqp_work_size(K, self.m, nv, self.mx)  # a wqp step's
        main_rows = [0] * self.m
        for k, task in enumerate(self.frames):
            if index[id(task)] in main:
                main_rows[starts[k] : starts[k + 1]] = [1] * (starts[k + 1] - starts[k])
        for k, joint in enumerate(self.level_joints):
            if index[id(joint)] in main:
                main_rows[mf + jstarts[k] : mf + jstarts[k + 1]] = [1] * (jstarts[k + 1] - jstarts[k])
        self.joint_spans = [(mf + int(jstarts[k]), mf + int(jstarts[k + 1])) for k in range(J)]
        a = mf + int(jstarts[-1])
        self.external_starts.clear()
        for (role, member, _), rows in zip([x for x in self.external if x[0] in ROWS], rows_of, strict=True):
            self.external_starts.append(a)
            if role == ROW and index[id(member)] in main:
                main_rows[a : a + rows] = [1] * rows
            a += rows
        parts: list[list[int]] = [
            kinds,
            frows,
            starts,
            [int(f.rotation_rows) for f in forms],
            jsel,
            jstarts,
            [
                (IDENTITY if ident else 0) | (GIVEN_ERROR if k in self.lie_joints else 0)
                for k, ident in enumerate(identity)
            ],
            np.maximum(iq, 0).tolist(),
            main_rows,
        ]
        columns = _frame_columns(robot, self.fids)
        ints = [K, J, N, self.m, nv, nq] + [0] * (HEADER - 6)
        ints[H_EXTERNAL_ROWS] = self.mx
        ints[H_EXTERNAL_Z] = int(any(role in (NULL, LIE_NULL, GRADIENT) for role, _, _ in self.external))
        for slot, part in zip(INT_PARTS, [*parts, self.fids, columns], strict=True):
            ints[slot] = len(ints)
            ints += part
        floats: list[float] = []
        chunks = [
            [float(x) for row in self.kparams for x in (row if row is not None else np.zeros(PARAMS))],
            [float(x) for target in self.targets for x in target],
            [float(x) for w, _ in nulls for x in w],
            [float(x) for _, c in nulls for x in c],
        ]
        for slot, chunk in zip(FLOAT_PARTS, chunks, strict=True):
            ints[slot] = len(floats)
            floats += chunk
        self.param_offset = int(ints[H_FRAME_PARAMS])
        self._slots(robot, level_forms, [int(x) for x in starts], [int(x) for x in jstarts])
        self.ints = np.array(ints, dtype=np.int64)
        self.floats = np.array(floats, dtype=float)
        self.target_rows = self._target_rows()
        self.refs = np.zeros((K, REF))
        self._frame_checks()
        self.lay_out_writes()

    def _target_rows(self) -> list[np.ndarray]:
        """Views of ``floats`` where each joint task's q_ref lies, in ``joint_checks`` order (the level joint tasks'
        targets, then the null ones' after the gradients' centres)."""
        rows = []
        a = int(self.ints[H_JOINT_TARGETS])
        for target in self.targets:
            rows.append(self.floats[a : a + target.shape[0]])
            a += target.shape[0]
        a = int(self.ints[H_NULL_CENTRES]) + sum(c.shape[0] for _, c in self.gradient_forms)
        for target in self.null_targets:
            rows.append(self.floats[a : a + target.shape[0]])
            a += target.shape[0]
        return rows

    # ------------------------------------------------------------------ per step
    def current(self, robot: RobotModel) -> bool:
        """The array-valued members are the objects packed (trajectories, targets, centres, a frame task's id and
        rows: a new ``frame`` or ``axes``) and the robot's data the same; False: the stack must be planned again.

        A trajectory whose parameter row was rewritten in place (a new target of a hold: its ``revision`` moved)
        is copied into ``floats`` again here: a target is data, not a reason to plan again."""
        if robot.data is not self.data:
            return False
        for task, revision in self.writer_checks:
            if task.form_revision != revision:
                return False
        revisions = self.revisions
        for k, (task, revision, traj, packed) in enumerate(self.frame_checks):
            if task.form_revision != revision:  # (another trajectory moves it too: ``traj`` is still the task's)
                return False
            now = traj.revision
            if now != revisions[k]:
                row = traj.parameters
                if row is None:
                    return False
                if row is not packed:  # (shared with the plan: written there already)
                    packed[:] = row
                revisions[k] = now
        for k, (joint, target) in enumerate(self.joint_checks):
            form = joint.joint_form(robot)
            if form is None:
                return False
            if form[1] is not target and not self._new_target(k, form):
                return False
        for sub, (w, c) in self.gradient_checks:
            lin = sub.potential.linear_gradient(robot)
            if type(lin) is not tuple or len(lin) != 2 or lin[0] is not w or lin[1] is not c:
                return False
        return True

    def _new_target(self, k: int, form: Form) -> bool:
        """A joint task's new q_ref (a new array: ``set_target``) written in place into its row of ``floats``, as
        data (no new plan); False when it does not fit that row (another size: the stack is planned again)."""
        row = self.target_rows[k]
        target = form[1]
        if target.shape != row.shape:
            return False
        row[:] = target
        joint = self.joint_checks[k][0]
        self.joint_checks[k] = (joint, target)
        J = len(self.level_joints)
        if k < J:
            self.targets[k] = target
            self.level_forms[k] = (self.level_forms[k][0], target)
        else:
            self.null_targets[k - J] = target
        return True

    def coefficients(self, tail: tuple[float, ...]) -> np.ndarray:
        """``coef`` of this step: re-read from the members when a gain or weight was set since (``Edits``) or
        ``tail`` (the resolver's own numbers) changed."""
        if Edits.count == self.edits and tail == self.tail:
            return self.coef
        frames, joints = self.frames, self.level_joints
        weights = [t.weight for t in frames] + [t.weight for t in joints]
        scaled = [w * s for w, s in zip(weights, self.scales, strict=True)]
        K = len(frames)
        values = [t.gain for t in frames]
        if self.qp:  # wqp: the weights, the joint tasks and the null objective's ρ
            values += scaled[:K] + [t.gain for t in joints] + scaled[K:] + [self.null_scale]
        values += [s.gain for s in self.gradients] + [-t.gain for t in self.nulls]
        self.coef = np.array(values + list(tail), dtype=float)
        self.weights = weights
        self.edits, self.tail = Edits.count, tail
        return self.coef

    def limits(self, args: tuple[Any, ...]) -> np.ndarray:
        """The (4, nv) limit rows (lower, upper, velocity, acceleration) of ``JointLimits.kernel_args``."""
        if args is not self.limit_args:
            self.lim = np.array([args[1], args[2], args[3], args[4]], dtype=float)
            self.limit_args = args
        return self.lim

    def given_references(self, t: float) -> np.ndarray:
        """The reference rows of trajectories without a compiled form, sampled here in Python (the others are
        sampled in the compiled call)."""
        refs = self.refs
        for k in self.given:  # (checked as the task's evaluate checks them: conform_reference)
            p_d, R_d, twist = conform_reference(self.trajs[k].reference(t), f"task '{self.frames[k].name}'")
            refs[k, REF_P : REF_P + 3] = p_d
            refs[k, REF_R : REF_R + 9] = R_d.reshape(-1)
            refs[k, REF_TWIST : REF_TWIST + 6] = twist
            self.frames[k].reference_sampled(np.array(R_d))
        return refs

    # ------------------------------------------------------------------ results
    def terms(
        self,
        Jf: np.ndarray,
        ev: np.ndarray,
        q: np.ndarray,
        robot: RobotModel,
        external: list[TaskTerm | None] | tuple[()] = (),
    ) -> list[TaskTerm]:
        """The step's task terms in stack order: what every task's ``evaluate`` would have returned (``external``:
        the terms the Python-written members gave at this step, :meth:`evaluate_external`)."""
        out: list[TaskTerm] = []
        e_all, v_all = ev[0], ev[1]
        weights = self.weights
        for kind, task, k, a, b, extra in self.slots:
            if kind == 0:  # a frame task: its rows of the frame Jacobian (``extra``: the selected rows, or None)
                Jk = Jf[k] if extra is None else Jf[k][extra]
                out.append(TaskTerm(task.name, Jk, v_all[a:b], e_all[a:b], weights[k]))
            elif kind == 1:  # a joint-space task of a level (``extra``: its rows of the identity)
                out.append(TaskTerm(task.name, extra, v_all[a:b], e_all[a:b], weights[k]))
            elif kind == 3:  # a member written from Python: the term its evaluate gave at this step
                term = external[k]
                assert term is not None  # (a task's: only gradients and Lie-group null terms have none)
                out.append(term)
            else:  # a regularisation task: its e from the step's q, as its evaluate computes it
                sel, target = task.joint_form(robot)
                e = robot.difference(q, target)[sel]
                if extra is None:
                    extra = _identity_rows(robot.nv, sel)
                out.append(TaskTerm(task.name, extra, task.gain * e, e, task.weight))
        return out

    def terms_once(
        self,
        Jf: np.ndarray | Callable[[], tuple[np.ndarray, np.ndarray]],
        ev: np.ndarray | None,
        q: np.ndarray,
        robot: RobotModel,
        external: list[TaskTerm | None] | tuple[()] = (),
    ) -> Callable[[], list[TaskTerm]]:
        """A callable giving the step's :meth:`terms`, built on its first call: the result and its lazy
        diagnostics share them without holding each other (no reference cycle keeps a step's result alive).
        ``Jf`` may be a callable giving (Jf, ev) then (views of a step's work array, made only if asked)."""
        cell: list[list[TaskTerm]] = []

        def make() -> list[TaskTerm]:
            if not cell:
                if callable(Jf):
                    J, e = Jf()
                    cell.append(self.terms(J, e, q, robot, external))
                else:
                    assert ev is not None
                    cell.append(self.terms(Jf, ev, q, robot, external))
            return cell[0]

        return make

    def add_null(self, task: Task, form: Form | None, lie: bool, nv: int, mixed: bool) -> bool:
        """A null-space objective's task: z += Sᵀ K S (q_ref ⊖ q) in the compiled call (a joint form, rows S of the
        identity, on coordinates that subtract); else from Python (``mixed``); False: the per-task path (J⁺v)."""
        if form is not None and not lie:
            self.order.append(("n", len(self.nulls)))
            self.nulls.append(task)
            self.null_targets.append(form[1])
            self.null_masks.append(np.isin(np.arange(nv), form[0]).astype(float))  # (1 on the coordinates of S)
            return True
        if not mixed or (form is None and not task.identity_jacobian):
            return False
        self.add_external(task, LIE_NULL if form is not None else NULL, 1.0)
        return True

    def _slots(self, robot: RobotModel, level_forms: list[Form], starts: list[int], jstarts: list[int]) -> None:
        """What ``terms`` needs per stack task, laid out once: (kind, task, weight index, first row, end row,
        rows or identity rows)."""
        mf = starts[-1]
        K = len(self.frames)
        null_forms = [task.joint_form(robot) for task in self.nulls]
        slots: list[tuple[int, Any, int, int, int, Any]] = []
        for kind, k in self.order:
            if kind == "f":
                form = self.forms[k]
                slots.append((0, form.task, k, starts[k], starts[k + 1], None if form.all_rows else form.rows))
            elif kind == "j":
                rows = _identity_rows(robot.nv, level_forms[k][0])
                slots.append((1, self.level_joints[k], K + k, mf + jstarts[k], mf + jstarts[k + 1], rows))
            elif kind == "x":
                role, member, _ = self.external[k]
                slots.append((2, member, -1, 0, 0, None) if role == LIE_NULL else (3, member, k, 0, 0, None))
            else:
                rows = _identity_rows(robot.nv, null_forms[k][0])  # type: ignore[index]
                slots.append((2, self.nulls[k], -1, 0, 0, rows))
        self.slots = slots


def _frame_columns(robot: RobotModel, fids: list[int]) -> list[int]:
    """Per frame, flattened: 1 on the velocity columns of the joints that move it (its supporting joints), else 0."""
    columns: list[int] = []
    model, nv = robot.model, robot.nv
    for fid in fids:
        col = [0] * nv
        for j in model.supports[model.frames[fid].parentJoint]:
            if j > 0:
                jm = model.joints[j]
                col[jm.idx_v : jm.idx_v + jm.nv] = [1] * jm.nv
        columns += col
    return columns


def _identity_rows(n: int, sel: np.ndarray) -> np.ndarray:
    """I[sel] (read-only, built once per plan): the Jacobian of a joint-space task."""
    rows = np.eye(n)[sel]
    rows.setflags(write=False)
    return rows


def plan_of(resolver: object) -> FusedPlan | None:
    """The fused plan a ``wqp`` or ``pinv`` resolver used at its last step (``None``: the per-task path)."""
    plan = getattr(resolver, "_plan", None)
    fused = getattr(plan, "fused", None) if plan is not None else None
    if fused is None:
        pair = getattr(resolver, "_fused", None)
        fused = pair[1] if isinstance(pair, tuple) else None
    return fused if isinstance(fused, FusedPlan) else None

"""The resolvers know tasks through their public protocol only (issue 31): no module under ``redundik/resolvers``
tests a task's class (``isinstance(x, FrameTask)``, ``type(x) is Clearance``) or touches a private attribute of a
task object.

Read from the syntax tree of every resolver module. The task classes are found, not listed: every class of redundik
derived from ``Task``, ``Subtask``, ``Potential`` or ``Barrier`` (those bases included). A private attribute
(``x._name``, read or written) is refused on anything but ``self``, ``cls``, ``super()`` and imported modules,
unless its receiver and name are in :data:`ALLOWED` — objects that are not tasks, each with the reason.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import redundik

from .helpers import import_every_module

RESOLVERS = Path(redundik.__file__).resolve().parent / "resolvers"

#: (receiver as written, private attribute) → why the receiver is not a task object.
ALLOWED: dict[tuple[str, str], str] = {
    # RobotModel (kinematics): its sizes and update check read without the property call on the hot path
    ("robot", "_nv"): "RobotModel's velocity size",
    ("robot", "_nq"): "RobotModel's configuration size",
    ("robot", "_update_checked"): "RobotModel's unchecked update",
    ("d['_step'][3]", "_nv"): "pinv's lazy info: the step record's 4th field is the RobotModel",
    # the resolvers' own objects (defined in redundik/resolvers)
    ("info", "_pending"): "LazyInfo (resolvers/result.py)",
    ("value", "_pending"): "LazyInfo (resolvers/result.py)",
    ("value", "_keys"): "LazyInfo (resolvers/result.py)",
    ("plan", "_pack"): "FusedPlan (resolvers/fused.py)",
    ("plan", "_dims"): "hqp's level plan (resolvers/qp/hqp.py)",
    ("backend", "_split_min_n"): "DaqpBackend (resolvers/qp/daqp_backend.py)",
    ("r", "_solve_qp"): "a WeightedQPResolver (resolvers/qp/wqp.py), in the batch API",
    ("resolver", "_diagnose_terms"): "a WeightedQPResolver (resolvers/qp/wqp.py), in its fused result's diagnostics",
    ("limits", "_limit_args"): "JointLimits (resolvers/qp/limits.py), read by its module's jerk box",
    ("limits", "_lo"): "JointLimits (resolvers/qp/limits.py), read by its module's jerk box",
    ("limits", "_hi"): "JointLimits (resolvers/qp/limits.py), read by its module's jerk box",
    ("limits", "_vmax"): "JointLimits (resolvers/qp/limits.py), read by its module's jerk box",
    ("limits", "_amax"): "JointLimits (resolvers/qp/limits.py), read by its module's jerk box",
    ("limits", "_jmax"): "JointLimits (resolvers/qp/limits.py), read by its module's jerk box",
    ("limits", "_has_rate"): "JointLimits (resolvers/qp/limits.py), read by its module's jerk box",
    ("limits", "_no_prev"): "JointLimits (resolvers/qp/limits.py), read by its module's jerk box",
    ("limits", "_iq"): "JointLimits (resolvers/qp/limits.py), read by its module's jerk box",
    ("r", "_limiter"): "a Resolver's joint-speed cap (resolvers/singularity.py), in the batch API",
    # qp/direction.py and singularity.py act as a QP resolver's own step (they are its scaling and guard modes)
    ("resolver", "_members"): "a Resolver's checked membership (resolvers/base.py), read by its command watchdog",
    ("resolver", "_dq_prev"): "a QP resolver's kept q̇ (its rate window), read and set by its own step modes",
    ("resolver", "_safety_rows"): "a QP resolver's template (resolvers/qp/base.py), in its direction mode",
    ("resolver", "_finish"): "a QP resolver's template (resolvers/qp/base.py), in its direction mode",
    ("resolver", "_resolve"): "a QP resolver's template (resolvers/qp/base.py), in its direction mode",
    ("resolver", "_diagnose"): "an hqp resolver's diagnostics (resolvers/qp/hqp.py), in its direction mode",
    ("resolver", "_solve_qp"): "a QP resolver's backend call (resolvers/qp/base.py), in its direction mode",
    ("resolver", "_P"): "a WeightedQPResolver's Hessian, solved by its native box step (resolvers/qp/wqp_native.py)",
    ("resolver", "_q"): "a WeightedQPResolver's gradient, solved by its native box step (resolvers/qp/wqp_native.py)",
    ("resolver", "_diag"): "a WeightedQPResolver's Hessian diagonal (a view of _P), tested by its Gram factor "
    "(resolvers/qp/wqp_gram.py)",
    ("resolver", "_dq_hist"): "a QP resolver's last two q̇ (its jerk window), kept by its native box step as by its "
    "template",
}


def _task_class_names() -> set[str]:
    """Names of redundik's task-side classes: the protocol bases and every subclass defined in redundik (every
    module imported first, so that a new class is found without being listed)."""
    import_every_module()
    from redundik.tasks.base import Barrier, Potential, Task
    from redundik.tasks.subtasks import Subtask

    names: set[str] = set()
    todo: list[type] = [Task, Subtask, Potential, Barrier]
    while todo:
        cls = todo.pop()
        if cls.__module__.startswith("redundik.") and cls.__name__ not in names:
            names.add(cls.__name__)
            todo.extend(cls.__subclasses__())
    return names


def _class_name(node: ast.expr) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return None


def _classes_in(node: ast.expr) -> list[str]:
    """The class names of an ``isinstance`` second argument or a comparison operand (a tuple: each)."""
    items = node.elts if isinstance(node, (ast.Tuple, ast.List, ast.Set)) else [node]
    return [n for n in (_class_name(i) for i in items) if n is not None]


def _is_type_call(node: ast.expr) -> bool:
    return isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "type"


def _of_type(node: ast.expr) -> bool:
    """``type(x)`` or an attribute of it (``type(x).gain``: a test of what the class overrides)."""
    return _is_type_call(node) or (isinstance(node, ast.Attribute) and _is_type_call(node.value))


def _names_in(node: ast.expr) -> set[str]:
    """Every name and attribute name in an expression (``Task.gain``: Task and gain; a tuple: each item's)."""
    out: set[str] = set()
    for sub in ast.walk(node):
        if isinstance(sub, ast.Name):
            out.add(sub.id)
        elif isinstance(sub, ast.Attribute):
            out.add(sub.attr)
    return out


def _module_names(tree: ast.Module) -> set[str]:
    """Names bound to modules by ``import`` statements (``import numpy as np``, ``from redundik import errors``)."""
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            for a in node.names:
                try:
                    importlib.import_module(f"{node.module}.{a.name}")
                except ImportError:
                    continue
                out.add(a.asname or a.name)
    return out


def findings(source: str, where: str, task_classes: set[str]) -> list[str]:
    """Every class test of a task class and every private attribute access on a non-``self`` object in
    ``source``."""
    tree = ast.parse(source)
    modules = _module_names(tree)
    out: list[str] = []
    for node in ast.walk(tree):
        line = f"{where}:{getattr(node, 'lineno', 0)}"
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and node.func.id in ("isinstance", "issubclass")
        ):
            if len(node.args) == 2 and set(_classes_in(node.args[1])) & task_classes:
                out.append(f"{line}: class test {ast.unparse(node)}")
        elif isinstance(node, ast.Compare):
            operands = [node.left, *node.comparators]
            typed = [o for o in operands if _of_type(o)]
            if typed and any(_names_in(o) & task_classes for o in operands if o not in typed):
                out.append(f"{line}: class test {ast.unparse(node)}")
        elif isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
            receiver = node.value
            if isinstance(receiver, ast.Name) and (receiver.id in ("self", "cls") or receiver.id in modules):
                continue
            if isinstance(receiver, ast.Call) and isinstance(receiver.func, ast.Name) and receiver.func.id == "super":
                continue
            key = (ast.unparse(receiver), node.attr)
            if key not in ALLOWED:
                out.append(f"{line}: private attribute {ast.unparse(node)}")
    return out


def test_no_resolver_tests_a_task_class_or_reads_its_private_state() -> None:
    task_classes = _task_class_names()
    found = []
    for path in sorted(RESOLVERS.rglob("*.py")):
        found += findings(path.read_text(encoding="utf-8"), path.relative_to(RESOLVERS).as_posix(), task_classes)
    assert not found, "resolver code that depends on a task's class or private state:\n" + "\n".join(found)


def test_the_task_classes_are_found_without_a_list() -> None:
    names = _task_class_names()
    assert {"Task", "FrameTask", "PostureTask", "Clearance", "BoundSubtask", "CollisionAvoidance"} <= names
    assert "TaskStack" not in names and "RobotModel" not in names


def test_the_check_sees_each_kind_of_finding() -> None:
    """The forms the resolvers used to have (``qp/hqp.py``'s ``type(bsub.source) is not Clearance`` and
    ``src._views``, ``fused.py``'s write of a frame task's ``_last_R``) are found; ``self``, modules and the
    allow-list are not."""
    source = (
        "import numpy as np\n"
        "def f(self, bsub, frames, robot, x):\n"
        "    if type(bsub.source) is not Clearance or isinstance(x, (int, FrameTask)):\n"
        "        return bsub.source._views\n"
        "    frames[0]._last_R = 1\n"
        "    ok = all(type(m).gain is FrameTask.gain for m in x)\n"
        "    return self._cache, np._NoValue, robot._nv, super()._pending_fn, type(x) is dict\n"
    )
    found = findings(source, "m.py", {"Clearance", "FrameTask"})
    kinds = ["class", "class", "class", "private", "private"]
    assert sorted(f.split(": ", 1)[1].split(" ", 1)[0] for f in found) == kinds, found
    assert any("bsub.source._views" in f for f in found) and any("frames[0]._last_R" in f for f in found)

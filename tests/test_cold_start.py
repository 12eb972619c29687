"""No cold-start stall (issue 31 item 5): on an empty kernel cache a resolver's first steps run interpreted while a
thread compiles its kernels, then it goes compiled with the same answers; the cache lives in the user's cache folder,
in a subfolder named by a stamp of every kernel source. Subprocesses: each starts with an empty cache folder."""

from __future__ import annotations

import json
import logging
import os
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import redundik as rk
from redundik import _coldstart
from redundik import _kernel_cache as kc
from redundik.collision import world as collision_world
from redundik.config.loader import TaskPlan, load_task
from redundik.tasks import frame
from tests.compile_events import LISTENER as _LISTENER

SRC = kc.PACKAGE_ROOT.parent

_PROBLEM = """
import numpy as np
import redundik as rk

robot = rk.from_dh([rk.DHRow(str(k), a=0.3, alpha=np.pi / 2 if k % 2 else -np.pi / 2) for k in range(1, 8)])
q = np.full(robot.nq, 0.3)

def stack():
    task = rk.FrameTask("7", rk.Circle(0.02, np.pi, plane=("y", "z")), gain=5.0)
    s = rk.TaskStack([task, rk.PostureTask(gain=1.0)], [rk.GradientSubtask(rk.JointCentering(), gain=-1.0)])
    robot.update(q)
    s.reset(robot)
    return s
"""


def _run(code: str, env: dict[str, str], timeout: float = 900, prelude: str = _PROBLEM) -> dict[str, object]:
    """Run ``code`` (after ``prelude``: the test problem's definitions) in a fresh interpreter; its last stdout line
    as JSON (with its stderr under ``"stderr"``)."""
    full = {**os.environ, "PYTHONPATH": str(SRC), **env}
    if "REDUNDIK_COLD_START" not in env:
        full.pop("REDUNDIK_COLD_START", None)  # (the suite's conftest waits; the default compiles in the background)
    out = subprocess.run(
        [sys.executable, "-c", prelude + f"_LISTENER = {_LISTENER!r}\n" + textwrap.dedent(code)],
        env=full,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    return {**json.loads(out.stdout.strip().splitlines()[-1]), "stderr": out.stderr}


def test_first_step_interpreted_while_compiling_then_compiled_same_answer(tmp_path: Path) -> None:
    got = _run(
        """
        import json, logging, sys
        from redundik import _coldstart, _kernel_cache
        logging.basicConfig(level=logging.WARNING)
        s, res = stack(), rk.make_resolver("pinv")
        first = res.step(robot, s, q, 0.0, 0.01)
        numba_first = "numba" in sys.modules  # (imported by the thread that compiles: not before the first q̇)
        second = res.step(robot, s, q, 0.01, 0.01)  # (the thread starts at the second step)
        busy = _coldstart._worker is not None and _coldstart._worker.is_alive()
        assert _coldstart.wait(900)
        again = res.step(robot, s, q, 0.0, 0.01)
        exec(_LISTENER)  # found: the kernels numba compiles in this (the caller's) thread from now on

        class Height(rk.Task):  # a user's own task: the stack then runs mixed
            def __init__(self):
                self._init_task("height", gain=1.0)

            def evaluate(self, robot, t):
                e = np.array([0.2 - robot.frame_position("5")[2]])
                return rk.TaskTerm(self.name, robot.frame_jacobian("5")[2:3], self.gain * e, e, self.weight)

            def __repr__(self):
                return "Height()"

        mixed = rk.TaskStack([rk.FrameTask("7", gain=5.0, axes="position"), Height(), rk.PostureTask(gain=1.0)])
        robot.update(q)
        mixed.reset(robot)
        user_paths = [res.step(robot, mixed, q, 0.01 * k, 0.01).info["path"] for k in range(3)]
        print(json.dumps({"first": first.info["path"], "second": second.info["path"], "busy": busy,
                          "numba_first": numba_first,
                          "dq1": first.dq.tolist(), "later": again.info["path"], "dq2": again.dq.tolist(),
                          "cache": str(_kernel_cache.cache_dir()), "user": user_paths, "found": found}))
        """,
        {"REDUNDIK_CACHE_DIR": str(tmp_path)},
    )
    assert got["first"] == got["second"] == "interpreted" and got["busy"]
    assert got["numba_first"] is False
    assert got["later"] == "compiled"
    # a user's task afterwards: the mixed step's kernels were compiled by the thread too (none in this one)
    assert got["user"] == ["mixed"] * 3 and got["found"] == [], got["found"]
    dq1, dq2 = np.array(got["dq1"]), np.array(got["dq2"])
    assert np.isfinite(dq1).all() and np.abs(dq1).max() > 0
    np.testing.assert_allclose(dq1, dq2, rtol=0, atol=1e-12)
    assert Path(str(got["cache"])).parent == tmp_path and any(Path(str(got["cache"])).rglob("*.nbi"))
    assert f"compiling the kernels of pinv in the background (cache: {got['cache']})" in str(got["stderr"])


def test_no_kernel_compiles_in_the_callers_thread_during_a_cold_start(tmp_path: Path) -> None:
    """On an empty cache, the first steps of every resolver — a frame task moved by ``set_target`` (a pose and a
    position), a posture, a clearance gradient and a centering — compile nothing in the caller's thread (numba's
    compile events, by thread): a kernel reached other than through a namespace would stall the first step."""
    got = _run(
        """
        import json
        import pinocchio as pin
        exec(_LISTENER)  # found: the kernels numba compiles in this (the caller's) thread from now on
        paths = []
        for name in ("pinv", "feedback", "wqp", "hqp"):
            task = rk.FrameTask("7", gain=5.0)
            near = rk.Clearance("7", [0.4, 0.0, 0.3], radius=0.05)
            s = rk.TaskStack([task, rk.PostureTask(gain=1.0)],
                             [rk.GradientSubtask(near, gain=0.5), rk.GradientSubtask(rk.JointCentering(), gain=-1.0)])
            robot.update(q)
            s.reset(robot)
            home, res = robot.frame_pose("7"), rk.make_resolver(name)
            for k in range(3):
                task.set_target(pin.SE3(home.rotation, home.translation + 0.001 * k) if k % 2 else
                                home.translation - 0.001 * k)
                paths.append(res.step(robot, s, q, 0.01 * k, 0.01).info["path"])
        print(json.dumps({"found": sorted(set(found)), "paths": paths}))
        """,
        {"REDUNDIK_CACHE_DIR": str(tmp_path)},
    )
    assert got["found"] == [], got["found"]
    assert set(got["paths"]) == {"interpreted"}  # (all the steps ran before the thread finished: on the twins)


def test_loading_the_shipped_collision_and_relative_task_files_compiles_nothing_in_the_callers_thread(
    tmp_path: Path,
) -> None:
    """On an empty cache, loading ``panda_shelf.yaml`` (a collision world with boxes: ``load_poses``,
    ``capsule_pairs``; relative poses: ``relative_rows``, ``log3``) and ``humanoid_balance.yaml`` (TALOS's capsules:
    ``capsule_distances``), then resetting and stepping one run of each, compiles nothing in the caller's thread:
    the kernel namespaces hand out twins before the first step. Numba is imported before redundik, so that every
    kernel is numba's from the start (with numba deferred, a load compiled only if it outlasted
    ``_coldstart.ADOPT_DELAY``)."""
    got = _run(
        f"""
        exec(_LISTENER)  # found: the kernels numba compiles in this (the caller's) thread from now on
        import json
        import numpy as np
        from redundik import _kernel_cache
        from redundik.config.loader import load_task
        plans = [(load_task({str(SRC.parent / "tasks")!r} + f"/{{name}}.yaml"), run)
                 for name, run in (("panda_shelf", "wqp"), ("humanoid_balance", "hqp"))]
        firsts = []
        for plan, name in plans:
            run, robot = plan.runs[name], plan.robot.model
            run.stack.reset(robot)
            r = run.resolver.step(robot, run.stack, run.q0.copy(), 0.0, plan.dt)
            firsts.append([bool(np.isfinite(r.dq).all() and np.abs(r.dq).max() > 0), r.info["path"]])
        print(json.dumps({{"found": sorted(set(found)), "firsts": firsts, "deferred": _kernel_cache.deferred()}}))
        """,
        {"REDUNDIK_CACHE_DIR": str(tmp_path)},
        timeout=300,
        prelude="",
    )
    assert got["deferred"] is False  # (numba imported first: the kernels are dispatchers)
    assert got["found"] == [], got["found"]
    assert got["firsts"] == [[True, "interpreted"]] * 2, got["firsts"]


def _fresh_namespaces(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every kernel namespace of redundik's loaded modules replaced by an empty one (this test's only), and the
    namespaces told to hand out twins: what a background cold start does before its first step."""
    for name, module in list(sys.modules.items()):
        if not name.startswith("redundik."):
            continue
        for key, value in list(vars(module).items()):
            if isinstance(value, kc.KernelNamespace):
                fresh = object.__new__(type(value))
                fresh.__dict__["_module"] = value.__dict__["_module"]
                monkeypatch.setattr(module, key, fresh)
    monkeypatch.setattr(kc, "SERVE_TWINS", lambda: True)


def _rows(plan: TaskPlan) -> list[np.ndarray]:
    """Each run's task rows (J, v, e) at q0 and t = 0.1 s, and the collision world's distances and witness points."""
    out: list[np.ndarray] = []
    robot = plan.robot.model
    for run in plan.runs.values():
        robot.update(run.q0)
        run.stack.reset(robot)
        for term in run.stack.evaluate(robot, 0.1):
            out += [np.array(term.J), np.array(term.v), np.array(term.error)]
    world = plan.world
    if world is not None:
        dist = world.compute(robot)
        out += [np.array(dist.d), np.array(dist.p1), np.array(dist.p2)]
    return out


@pytest.mark.parametrize("name", ["panda_shelf", "humanoid_balance", "dualarm17"])
def test_a_task_file_loaded_on_twins_gives_the_compiled_rows(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """A task file loaded and evaluated through the kernels' twins (a cold start before its first step: the
    collision world's pairs and distances, the frame and relative-pose rows, the feedback resolver's check) gives
    the rows and distances of the compiled kernels."""
    path = SRC.parent / "tasks" / f"{name}.yaml"
    compiled = _rows(load_task(path))
    _fresh_namespaces(monkeypatch)
    twins = _rows(load_task(path))
    assert "frame_error" not in vars(frame._K) and "load_poses" not in vars(collision_world.KC)  # (twins handed out)
    assert len(twins) == len(compiled) > 0
    for a, b in zip(twins, compiled, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


def test_read_only_package_folder_caches_to_the_user_folder(tmp_path: Path) -> None:
    pkg = tmp_path / "site"
    cache = tmp_path / "cache"
    import shutil

    shutil.copytree(SRC / "redundik", pkg / "redundik", ignore=shutil.ignore_patterns("__pycache__", "*.nb*"))
    for path in [pkg, *pkg.rglob("*")]:
        path.chmod(path.stat().st_mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    try:
        got = _run(
            """
            import json
            from redundik import _kernel_cache
            from redundik.resolvers import kernels
            x = np.arange(3.0)
            assert kernels.squares_below(x, 100.0)
            print(json.dumps({"file": rk.__file__, "cache": str(_kernel_cache.cache_dir())}))
            """,
            # (kernels called directly, ahead of any step: numba is not deferred for the first steps)
            {
                "PYTHONPATH": str(pkg),
                "XDG_CACHE_HOME": str(cache),
                "REDUNDIK_CACHE_DIR": "",
                "REDUNDIK_COLD_START": "wait",
            },
        )
    finally:
        for path in [pkg, *pkg.rglob("*")]:
            path.chmod(path.stat().st_mode | stat.S_IWUSR)
    assert str(got["file"]).startswith(str(pkg))
    assert Path(str(got["cache"])).parent == cache / "redundik"
    assert list(Path(str(got["cache"])).rglob("box_kernels.squares_below*.nbc"))
    assert not list(pkg.rglob("*.nbi")) and not list(pkg.rglob("*.nbc"))


def test_a_kernel_source_edit_gets_a_new_cache_folder(tmp_path: Path) -> None:
    for rel in kc.KERNEL_SOURCES:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_bytes((kc.PACKAGE_ROOT / rel).read_bytes())
    before = kc.sources_stamp(tmp_path)
    assert before == kc.sources_stamp(kc.PACKAGE_ROOT)
    kc._stamps.clear()
    dep = tmp_path / "resolvers/hqp_kernels.py"  # compiled into hqp_fused's step, not hqp_fused itself
    dep.write_text(dep.read_text() + "\n# edited\n")
    assert kc.sources_stamp(tmp_path) != before


def test_the_users_numba_cache_setting_is_left_alone(tmp_path: Path) -> None:
    got = _run(
        """
        import json, numba
        from redundik.resolvers import kernels
        print(json.dumps({"dir": numba.config.CACHE_DIR,
                          "ours": kernels.squares_below._cache._impl.locator.get_cache_path()}))
        """,
        {
            "REDUNDIK_CACHE_DIR": str(tmp_path / "ours"),
            "NUMBA_CACHE_DIR": str(tmp_path / "theirs"),
            "REDUNDIK_COLD_START": "wait",
        },
    )
    assert got["dir"] == str(tmp_path / "theirs")
    assert str(got["ours"]).startswith(str(tmp_path / "ours"))


@pytest.mark.parametrize("name", ["pinv", "feedback", "wqp", "hqp"])
def test_twins_give_the_compiled_answer(name: str) -> None:
    """The interpreted path on the kernels' twins (the cold start's) against the compiled kernels, in this process."""
    robot = rk.from_dh([rk.DHRow(str(k), a=0.3, alpha=np.pi / 2 if k % 2 else -np.pi / 2) for k in range(1, 8)])
    q = np.full(robot.nq, 0.3)
    answers = []
    for twins in (False, True, None):  # None: the compiled step
        task = rk.FrameTask("7", rk.Circle(0.02, np.pi, plane=("y", "z")), gain=5.0)
        subs: list[rk.Subtask] = [rk.GradientSubtask(rk.JointCentering(), gain=-1.0)]
        if name == "feedback":  # (a target subtask: the law's gains, not only its pinv part)
            subs.append(rk.TargetSubtask(rk.JointSine2("4"), target=0.5, rate=1.0))
        stack = rk.TaskStack([task, rk.PostureTask(gain=1.0)], subs)
        robot.update(q)
        stack.reset(robot)
        res = rk.make_resolver(name)
        res.fuse = twins is None
        if twins:
            _coldstart._install(compiled_too=True)
            assert _coldstart._saved  # the kernels' namespaces hold their switches to the twins
        try:
            out = res.step(robot, stack, q, 0.1, 0.01)
        finally:
            _coldstart._restore()
        assert out.info["path"] == ("compiled" if twins is None else "interpreted")
        answers.append(out.dq.copy())
    np.testing.assert_allclose(answers[1], answers[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(answers[1], answers[2], rtol=0, atol=1e-12)


def test_compiling_thread_survives_imports_in_the_callers_thread() -> None:
    """The compiling thread walks redundik's modules while the caller's thread may import: a walk of ``sys.modules``
    itself raised "dictionary changed size during iteration" there, the thread died and its kernels were never
    adopted (a script that imported a module about a second after its first task evaluation)."""
    import threading
    import types

    errors: list[BaseException] = []
    stop = threading.Event()

    def walk() -> None:
        while not stop.is_set():
            try:
                _coldstart._spaces()
            except BaseException as exc:  # (what the thread would die of)
                errors.append(exc)
                return

    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    walker = threading.Thread(target=walk)
    walker.start()
    try:
        for k in range(20000):  # the caller's thread importing meanwhile
            name = f"redundik._import_race_{k % 64}"
            if name in sys.modules:
                del sys.modules[name]
            else:
                sys.modules[name] = types.ModuleType(name)
            if errors:
                break
    finally:
        stop.set()
        walker.join()
        sys.setswitchinterval(interval)
        for k in range(64):
            sys.modules.pop(f"redundik._import_race_{k}", None)
    assert not errors, f"the walk of redundik's modules failed while another thread imported: {errors[0]!r}"


def test_a_binding_limit_during_a_cold_start_solves_its_qp_without_the_native_call(tmp_path: Path) -> None:
    """``wqp`` and ``hqp`` steps whose limits bind while their kernels compile in the background — the first kernels
    of the process, or after another resolver's were loaded (every namespace then holds the kernels' twins) — solve
    their QPs through the backend's own solve: daqp's C entry is called by compiled kernels only (their
    interpreted twins cannot: ``RuntimeError`` or ``NotImplementedError`` here before). Once the kernels are loaded
    the native call is decided and used, and the constrained steps compile nothing more in the caller's thread (the
    warm-up steps a binding bound: ``hqp``'s cascade was compiled at the loop's first constrained step before), nor
    do a target set as an SE3 or a 4×4 matrix, the centre of mass and the support polygon."""
    got = _run(
        """
        import json
        import pinocchio as pin
        from redundik import _coldstart
        from redundik.kinematics.urdf import load_example_robot
        from redundik.resolvers.qp import daqp_native
        panda = load_example_robot("panda")
        qp0 = pin.neutral(panda.model)
        qp0[:7] = [0.0, -0.4, 0.0, -2.0, 0.0, 1.6, 0.8]

        def run(name):
            qp = pin.neutral(panda.model)
            qp[:7] = [0.0, -0.4, 0.0, -2.0, 0.0, 1.6, 0.8]
            panda.update(qp)
            circle = rk.FrameTask("panda_hand", rk.Circle(0.12, 2.0 * np.pi, plane=("y", "z")), gain=50.0)
            s = rk.TaskStack([circle, rk.PostureTask(gain=1.0, weight=1e-2, priority=2 if name == "hqp" else 1)])
            s.reset(panda)
            res = rk.make_resolver(name, max_joint_speed=None)
            rows = []
            for k in range(40):
                twins = bool(_coldstart._saved)
                r = res.step(panda, s, qp, 0.01 * k, 0.01)
                rows.append((twins, int(r.info.get("qp", 0)), bool(np.isfinite(r.dq).all())))
                qp = panda.integrate(qp, r.dq, 0.01)
            return rows

        out = {"wqp": run("wqp")}  # (the first kernels of the process compiling: nothing loaded yet)
        out["decided_cold"] = daqp_native._decided
        assert _coldstart.wait(900)
        out["hqp"] = run("hqp")  # (wqp's kernels loaded; hqp's compiling: every namespace holds twins)
        assert _coldstart.wait(900)
        out["native_after"] = daqp_native.status()
        exec(_LISTENER)  # found: the kernels numba compiles in this (the caller's) thread from now on
        out["hot"] = run("hqp")  # (its constrained cascade: compiled by the warm-up, not here)
        panda.update(qp0)
        near = panda.frame_position("panda_link4") + np.array([0.0, 0.05, 0.0])
        rel = rk.RelativePoseTask("panda_hand", "panda_link4", axes="position", gain=1.0)
        s = rk.TaskStack([rk.FrameTask("panda_hand", rk.Circle(0.05, 2.0, plane=("y", "z")), gain=10.0), rel],
                         [rk.BoundSubtask(rk.Clearance("panda_link4", near, 0.0), lower=0.2, priority=0),
                          rk.TargetSubtask(rk.JointCentering(), target=0.5, rate=1.0)])
        s.reset(panda)
        res, q1, bound = rk.make_resolver("hqp"), qp0.copy(), []
        for k in range(20):
            r = res.step(panda, s, q1, 0.01 * k, 0.01)
            bound.append((r.info["path"], int(r.info["qp"])))
            q1 = panda.integrate(q1, r.dq, 0.01)
        # a teleop target in each form, the centre of mass and the support polygon's barrier (their writers)
        from redundik.tasks.balance import CoMTask, SupportPolygon
        panda.update(qp0)
        hand = rk.FrameTask("panda_hand", gain=10.0)
        s = rk.TaskStack([hand, CoMTask(axes=("x", "y"), weight=0.1), rk.PostureTask(gain=1.0)],
                         [rk.BoundSubtask(SupportPolygon(["panda_link0"], size=(1.0, 1.0)))])
        s.reset(panda)
        home, res, q1 = panda.frame_pose("panda_hand"), rk.make_resolver("wqp"), qp0.copy()
        for k in range(6):
            target = [home, home, np.array(home.homogeneous), home.translation][min(k, 3)]
            hand.set_target(target)
            q1 = panda.integrate(q1, res.step(panda, s, q1, 0.01 * k, 0.01).dq, 0.01)
        out["balance"] = list(res.step(panda, s, q1, 0.06, 0.01).info["interpreted"])
        out["bound"], out["found"] = bound, sorted(set(found))
        print(json.dumps(out))
        """,
        {"REDUNDIK_CACHE_DIR": str(tmp_path)},
    )
    for case in ("wqp", "hqp"):
        rows = got[case]
        assert all(finite for _, _, finite in rows), case
        cold = [qp for twins, qp, _ in rows if twins]
        assert cold and any(qp > 0 for qp in cold), f"{case}: no QP solved on the twins: {rows}"
    assert got["decided_cold"] is False
    assert str(got["native_after"]).startswith("on"), got["native_after"]
    assert any(qp > 0 for _, qp, _ in got["hot"])
    # after the warm-up: hqp's constrained cascade (a binding limit; a binding clearance bound with a relative pose
    # and a target subtask) on the compiled step, and nothing compiled in the caller's thread
    assert sum(qp for _, qp in got["bound"]) >= 5 and got["bound"][-1][0] == "compiled", got["bound"]
    assert got["balance"] == [], got["balance"]  # (the CoM's and the support polygon's writers ran)
    assert got["found"] == [], got["found"]


_SHIPPED_WORLDS = """
import json
from redundik.config.loader import load_task
rk.warm_up(["wqp"], ik=False)
exec(_LISTENER)  # found: the kernels numba compiles in this (the caller's) thread from now on
paths = []
for name in ("humanoid_balance", "panda_shelf"):
    plan = load_task(TASKS / f"{name}.yaml")
    run, model = plan.runs["wqp"], plan.robot.model
    q1 = run.q0.copy()
    model.update(q1)
    run.stack.reset(model)
    for k in range(3):
        r = run.resolver.step(model, run.stack, q1, k * plan.dt, plan.dt)
        paths.append(r.info["path"])
        q1 = model.integrate(q1, r.dq, plan.dt)
    plan.world.compute(model, 0.1)  # (a run summary's distances)
    for run in plan.runs.values():  # (the repulsive potentials' gradients)
        for sub in run.stack.subtasks:
            if sub.kind == "gradient" and type(sub.potential).__name__ == "CollisionAvoidance":
                sub.potential.gradient(model)
print(json.dumps({"found": sorted(set(found)), "paths": paths}))
"""


def test_the_shipped_collision_worlds_compile_nothing_in_the_callers_thread_after_the_warm_up(tmp_path: Path) -> None:
    """After ``rk.warm_up`` on an empty cache (``wqp``: its collision worlds are a capsule-only one, one with a box
    and a capsule obstacle, one with a moving obstacle), loading the shipped collision task files and stepping their
    ``wqp`` runs — TALOS's self-collision damper (capsules only: ``capsule_damper``), the Panda's shelf (a capsule
    post and boxes, the boxes through coal: ``load_poses``, ``capsule_pairs``, ``barrier_rows``) — then their
    worlds' distances (``capsule_distances``) and the repulsive potentials' gradients (``distance_rows``) compile
    nothing in the caller's thread (numba's compile events, by thread)."""
    got = _run(
        f"from pathlib import Path\nTASKS = Path({str(SRC.parent / 'tasks')!r})\n" + _SHIPPED_WORLDS,
        {"REDUNDIK_CACHE_DIR": str(tmp_path), "REDUNDIK_COLD_START": "wait"},
    )
    assert got["found"] == [], got["found"]
    assert set(got["paths"]) == {"mixed"}, got["paths"]  # (the compiled solve; the damper rows from Python)


def test_wait_chosen_after_import_compiles_the_kernels_before_the_first_step() -> None:
    """``REDUNDIK_COLD_START=wait`` set after ``import redundik`` (which deferred numba in the default mode): the
    first step decorates the kernels and runs them compiled, in the caller's thread. Before, the steps ran the
    kernels' plain functions while reporting the compiled path, and a ``wqp`` step whose limit binds raised
    ``RuntimeError`` from daqp's C entry (its intrinsic was never made)."""
    got = _run(
        """
        import json, os
        import pinocchio as pin
        from redundik import _kernel_cache
        from redundik.kinematics.urdf import load_example_robot
        from redundik.resolvers.linalg import FK
        from redundik.resolvers.qp import daqp_native
        deferred_at_import = _kernel_cache.deferred()
        os.environ["REDUNDIK_COLD_START"] = "wait"
        panda = load_example_robot("panda")
        qp = pin.neutral(panda.model)
        qp[:7] = [0.0, -0.4, 0.0, -2.0, 0.0, 1.6, 0.8]
        panda.update(qp)
        circle = rk.FrameTask("panda_hand", rk.Circle(0.12, 2.0 * np.pi, plane=("y", "z")), gain=50.0)
        s = rk.TaskStack([circle, rk.PostureTask(gain=1.0, weight=1e-2)])
        s.reset(panda)
        res = rk.make_resolver("wqp", max_joint_speed=None)
        rows = []
        for k in range(40):
            r = res.step(panda, s, qp, 0.01 * k, 0.01)
            rows.append((r.info["path"], int(r.info.get("qp", 0)), bool(np.isfinite(r.dq).all())))
            qp = panda.integrate(qp, r.dq, 0.01)
        print(json.dumps({"deferred_at_import": deferred_at_import, "rows": rows,
                          "dispatcher": hasattr(FK.fused_wqp_step, "py_func"),
                          "native": daqp_native.status()}))
        """,
        {},  # (the suite's cache: what matters is numba deferred at the import, not an empty cache)
    )
    assert got["deferred_at_import"] is True  # (the situation under test: numba deferred by the default mode)
    rows = got["rows"]
    assert all(finite for _, _, finite in rows)
    assert {path for path, _, _ in rows} == {"compiled"}, rows
    assert any(qp > 0 for _, qp, _ in rows), rows  # (a limit bound: the box QP was solved)
    assert got["dispatcher"] is True
    assert str(got["native"]).startswith("on"), got["native"]


def test_a_fork_during_the_background_compile_does_not_hang_the_child(tmp_path: Path) -> None:
    """``multiprocessing`` (fork) while the kernels compile in the background: the children step instead of waiting
    forever on numba's compiler lock, which the parent's compiling thread held at the fork (a pool made a few
    seconds into a cold start hung: ``_coldstart._before_fork``)."""
    got = _run(
        """
        import json, multiprocessing as mp, time
        import pinocchio as pin
        from redundik import _coldstart
        from redundik.kinematics.urdf import load_example_robot

        def work(k):
            panda = load_example_robot("panda")
            qp = pin.neutral(panda.model)
            qp[:7] = [0.0, -0.4, 0.0, -2.0, 0.0, 1.6, 0.8]
            panda.update(qp)
            circle = rk.FrameTask("panda_hand", rk.Circle(0.05, 1.0, plane=("y", "z")), gain=20.0)
            s = rk.TaskStack([circle, rk.PostureTask(gain=1.0, weight=1e-2)])
            s.reset(panda)
            res = rk.make_resolver("wqp")
            for i in range(400):
                qp = panda.integrate(qp, res.step(panda, s, qp, 0.01 * i, 0.01).dq, 0.01)
            return bool(np.isfinite(qp).all())

        work(-1)  # (the thread compiling wqp's kernels starts at its second step)
        time.sleep(2.0)
        busy = _coldstart._worker is not None and _coldstart._worker.is_alive()
        with mp.get_context("fork").Pool(2) as pool:
            done = pool.map_async(work, range(4)).get(timeout=200)
        print(json.dumps({"busy": busy, "done": done}))
        """,
        {"REDUNDIK_CACHE_DIR": str(tmp_path)},
        timeout=400,
    )
    assert got["busy"] and got["done"] == [True] * 4
    assert "in the background failed" not in str(got["stderr"])  # (the children's own compiling threads too)


def test_a_cache_folder_that_cannot_be_written_is_said_once(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """``$REDUNDIK_CACHE_DIR`` under a file (or anywhere not writable): the kernels compile uncached — in every
    process, tens of seconds — and a warning says so once, naming the folder and the variable."""
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    folder = blocker / "kernels-x"
    with caplog.at_level(logging.WARNING, logger="redundik"):
        assert kc._writable(folder) is False and kc._writable(folder) is False
    said = [r.getMessage() for r in caplog.records if "cannot be created or written" in r.getMessage()]
    assert len(said) == 1 and str(folder) in said[0] and "REDUNDIK_CACHE_DIR" in said[0]
    assert kc._writable(tmp_path / "fine") is True

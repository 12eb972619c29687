"""The product around the library: a small core, extras with actionable errors, shipped examples, the CLI contract.

Slow checks (a fresh venv per install flavour) are in ``.ci/run``; here the wheel is built once and inspected.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from redundik.errors import MissingDependencyError
from tests.conftest import CONFIGS, ROOT, TASKS

#: Modules a core install does not have: a subprocess refuses to import them.
OPTIONAL = (
    "matplotlib",
    "PIL",
    "typer",
    "rich",
    "click",
    "pydantic",
    "yaml",
    "example_robot_data",
    "osqp",
    "proxsuite",
    "quadprog",
    "mujoco",
    "mink",
    "pink",
    "meshcat",
)

BLOCKER = f"""
import sys, importlib.abc
BLOCKED = {OPTIONAL!r}
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ImportError(f"blocked: {{name}}")
        return None
sys.meta_path.insert(0, Block())
"""

URDF = """<robot name="rr">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="2"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="1 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="2"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="tip"/><origin xyz="1 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="2"/></joint>
</robot>
"""


def _python(code: str, *args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=cwd, timeout=120)


def test_core_control_loop_runs_without_any_optional_module(tmp_path: Path) -> None:
    (tmp_path / "rr.urdf").write_text(URDF, encoding="utf-8")
    code = (
        BLOCKER
        + """
import numpy as np, redundik as rk
dh = rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", a=1.0), rk.DHRow("3", a=1.0)])
urdf = rk.from_urdf(sys.argv[1])
out = {}
for robot, frame in ((dh, "3"), (urdf, "tip")):
    for name in ("pinv", "feedback", "wqp", "hqp"):
        stack = rk.TaskStack([rk.FrameTask(frame, rk.Line([0.1, -0.2]), axes="planar", gain=1.0)],
                             [rk.GradientSubtask(rk.JointSine2(robot.joint_names[-1]), gain=1.0)])
        resolver, q, dt = rk.make_resolver(name), np.array([0.3, 1.2, -0.9]), 0.01
        robot.update(q); stack.reset(robot)
        p0 = robot.frame_position(frame)[:2].copy()
        for k in range(50):
            q = robot.integrate(q, resolver.step(robot, stack, q, k * dt, dt).dq, dt)
        robot.update(q)
        out[f"{robot.name}/{name}"] = float(np.linalg.norm(robot.frame_position(frame)[:2] - p0 - [0.05, -0.1]))
loaded = sorted(m for m in BLOCKED if m in sys.modules)
print(__import__("json").dumps({"errors": out, "loaded": loaded}))
"""
    )
    proc = _python(code, str(tmp_path / "rr.urdf"))
    assert proc.returncode == 0, proc.stderr[-2000:]
    res = json.loads(proc.stdout)
    assert res["loaded"] == []
    assert len(res["errors"]) == 8 and max(res["errors"].values()) < 5e-3, res["errors"]


@pytest.fixture
def no_example_robot_data(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """example-robot-data's URDFs cannot be found (the module's view of sys.path and sys.prefix is empty)."""
    import types

    from redundik.kinematics import urdf

    monkeypatch.setattr(
        urdf, "sys", types.SimpleNamespace(path=[str(tmp_path)], prefix=str(tmp_path), stderr=sys.stderr)
    )
    monkeypatch.delenv("EXAMPLE_ROBOT_DATA_MODEL_DIR", raising=False)


@pytest.mark.usefixtures("no_example_robot_data")
def test_missing_example_robot_data_says_which_extra(cli) -> None:  # type: ignore[no-untyped-def]
    from redundik.kinematics import urdf

    with pytest.raises(MissingDependencyError, match=r"pip install 'redundik\[robots\]'"):
        urdf.load_example_robot("panda")
    code, _, err = cli("validate", TASKS / "panda_circle.yaml")  # through the config layer: still exit code 5
    assert code == 5 and err.startswith("error: loading an example robot") and "redundik[robots]" in err, err


def test_missing_matplotlib_says_which_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    from redundik.reporting import plots

    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib → ImportError
    with pytest.raises(MissingDependencyError, match=r"plotting needs matplotlib.*pip install 'redundik\[plots\]'"):
        plots._plt()


def test_cli_without_its_extra_is_one_actionable_line() -> None:
    proc = _python(BLOCKER + "from redundik.cli.main import main\nsys.exit(main(['--version']))")
    assert proc.returncode == 5, proc.stderr
    assert proc.stdout == ""
    assert proc.stderr.strip() == (
        "error: the redundik command needs typer, which is not installed: pip install 'redundik[cli]'"
    )


def test_validate_of_a_malformed_file_imports_nothing_numerical(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nrobot: ../configs/planar3r.yaml\ndt: -1\nsteps: 3\nruns: {a: {}}\n", encoding="utf-8")
    code = (
        "import sys\nfrom redundik.cli.main import main\ncode = main(['validate', sys.argv[1]])\n"
        "heavy = ('numpy', 'scipy', 'pinocchio', 'qpsolvers', 'matplotlib', 'mujoco')\n"
        "print(code, sorted(m for m in heavy if m in sys.modules))"
    )
    proc = _python(code, str(bad))
    assert proc.stdout.strip() == "3 []", proc.stdout + proc.stderr
    assert proc.stderr.strip() == "error: dt: must be ≥ 1e-06, got -1"


# ------------------------------------------------------------------------------------------------ the CLI contract
def test_version(cli) -> None:  # type: ignore[no-untyped-def]
    import redundik

    code, out, err = cli("--version")
    assert (code, out, err) == (0, f"redundik {redundik.__version__}\n", "")


def test_python_dash_m_is_the_command(tmp_path: Path) -> None:
    """``python -m redundik`` runs the CLI (its exit codes, its errors) where the scripts folder is not on PATH."""
    import redundik

    ok = subprocess.run([sys.executable, "-m", "redundik", "--version"], capture_output=True, text=True, cwd=tmp_path)
    assert (ok.returncode, ok.stdout) == (0, f"redundik {redundik.__version__}\n"), ok.stderr
    bad = subprocess.run([sys.executable, "-m", "redundik", "run", "no_such_task"], capture_output=True, text=True)
    assert bad.returncode == 3 and bad.stderr.startswith("error: ") and "no_such_task" in bad.stderr, bad.stderr


def test_exit_codes_are_distinct_and_documented(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    from redundik.cli.main import EXIT_CODES

    assert cli("run", "--no-such-option", "x")[0] == 2  # usage
    assert cli("validate", tmp_path / "missing.yaml")[0] == 3  # invalid input
    assert cli("run", "no_such_task")[0] == 3
    code, out, _ = cli("--help")
    assert code == 0 and "Exit codes:" in out and all(f"{k} " in out for k in EXIT_CODES)
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert all(f"| {k} |" in readme for k in EXIT_CODES), "README lists every exit code"


def test_help_shows_bracketed_units() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "redundik.cli.main", "stewart", "ik", "--help"], capture_output=True, text=True
    )
    assert proc.returncode == 0 and "Roll pitch yaw [deg]" in proc.stdout, proc.stdout


def test_validate_json_is_one_document(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    code, out, err = cli("validate", TASKS / "planar3r_line.yaml", "--json")
    doc = json.loads(out)
    assert code == 0 and doc["ok"] is True and doc["kind"] == "task" and err == ""
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\n", encoding="utf-8")
    code, out, err = cli("validate", bad, "--json")
    doc = json.loads(out)
    assert code == 3 and doc == {"ok": False, "error": doc["error"], "exit_code": 3, "kind": "ConfigError"}
    assert err == f"error: {doc['error']}\n"


def test_run_by_name_from_anywhere_with_json(cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.chdir(tmp_path)
    code, out, err = cli("run", "planar3r_line", "--json", "--no-figures", "--runs", "rank_null")
    assert code == 0, err
    doc = json.loads(out)  # exactly one JSON document on stdout
    assert doc["ok"] and doc["task"] == "planar3r_line" and doc["files"] == ["summary.json", "rank_null.csv"]
    assert doc["summary"]["runs"]["rank_null"]["max_task_error"] < 5e-3
    assert (tmp_path / "out" / "planar3r_line" / "summary.json").is_file()
    assert "rank_null" in err  # the table went to stderr


def test_examples_list_and_copy(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    code, out, _ = cli("examples", "list", "--json")
    names = {(e["kind"], e["name"]) for e in json.loads(out)["examples"]}
    assert code == 0
    assert names == {("task", p.stem) for p in TASKS.glob("*.yaml")} | {
        ("config", p.stem) for p in CONFIGS.glob("*.yaml")
    } | {("sweep", p.stem) for p in (ROOT / "sweeps").glob("*.yaml")}
    code, _, err = cli("examples", "copy", tmp_path / "ex")
    assert code == 0 and "copied" in err
    assert cli("validate", tmp_path / "ex" / "tasks" / "planar3r_line.yaml")[0] == 0  # ../configs resolves
    assert cli("examples", "copy", tmp_path / "ex")[2].startswith("copied 0 files")  # nothing overwritten


def test_piped_output_is_not_cut_at_80_columns() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "redundik.cli.main", "examples", "list"], capture_output=True, text=True
    )
    from redundik.shipped import examples

    longest = max((e.description for e in examples("tasks")), key=len)
    assert len(longest) > 80 and longest in proc.stdout


def test_osqp_prints_nothing_on_stdout() -> None:
    code = """
import numpy as np
from redundik.resolvers.qp.backends import make_backend
from redundik.resolvers.qp.problem import QPProblem
n = 3  # the optimum -0.1 leaves every constraint inactive: OSQP's polishing would print "Polishing not needed"
problem = QPProblem(np.eye(n), np.full(n, 0.1), np.eye(n), np.ones(n), np.zeros((0, n)), np.zeros(0),
                    np.full(n, -1.0), np.ones(n), "t")
x = make_backend("osqp").solve(problem).x
assert np.allclose(x, -0.1, atol=1e-4), x
"""
    proc = _python(code)  # a subprocess: its fd 1 is the pipe, so C-level printf is caught too
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == ""


# ------------------------------------------------------------------------------------------------ the wheel
@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(ROOT)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    (found,) = out.glob("redundik-*.whl")
    return found


def test_wheel_ships_the_examples_license_and_metadata(wheel: Path) -> None:
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
        meta = next(zf.read(n).decode() for n in names if n.endswith(".dist-info/METADATA"))
        task = zf.read("redundik/_data/tasks/planar3r_line.yaml").decode()
    for folder, src in (("tasks", TASKS), ("configs", CONFIGS), ("sweeps", ROOT / "sweeps")):
        assert {f"redundik/_data/{folder}/{p.name}" for p in src.glob("*.yaml")} <= names
    assert "robot: ../configs/planar3r.yaml" in task and "redundik/_data/configs/planar3r.yaml" in names
    assert {"redundik/_data/sweeps/panda_reach.yaml", "redundik/_data/configs/arm4.urdf"} <= names  # issue 32
    assert any(n.endswith("licenses/LICENSE") for n in names) and "redundik/py.typed" in names
    assert "License-Expression: BSD-3-Clause" in meta
    core = sorted(
        re.split(r"[<>=!~; ]", line.removeprefix("Requires-Dist:").strip())[0]
        for line in meta.splitlines()
        if line.startswith("Requires-Dist:") and "extra ==" not in line
    )
    assert core == ["daqp", "numba", "numpy", "pin", "qpsolvers", "scipy", "threadpoolctl"]

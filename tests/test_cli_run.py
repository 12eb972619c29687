"""``redundik run`` / ``redundik validate``: the files written, and one-line errors for malformed task files."""

from __future__ import annotations

import copy
import csv
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import PLANAR_TASK
from tests.test_config import MALFORMED

SUMMARY_RUN_KEYS = {
    "resolver",
    "final_q",
    "max_task_error",
    "final_task_error",
    "subtasks",
    "step_time_us",
    "limit_violations",
    "damped_steps",
    "fallbacks",
}
FIGURES = ["joints.png", "task_error.png", "potentials.png", "configurations.png"]


@pytest.fixture(scope="module")
def planar_out(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int]:
    """One full ``redundik run tasks/planar3r_line.yaml`` (all runs, figures): (output folder, exit code)."""
    from redundik.cli.main import main

    out = tmp_path_factory.mktemp("planar_out")
    return out, main(["run", str(PLANAR_TASK), "--out", str(out), "--quiet"])


def _read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open(encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    data = np.array([[float(v) if v else np.nan for v in r] for r in rows[1:]])
    return rows[0], data


def test_run_writes_summary_with_the_agreed_keys(planar_out: tuple[Path, int]) -> None:
    out, code = planar_out
    assert code == 0
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert {"task", "robot", "dt", "steps", "runs"} <= set(summary)
    assert (summary["task"], summary["robot"], summary["dt"], summary["steps"]) == (
        "planar3r_line",
        "planar3r",
        0.01,
        500,
    )
    assert list(summary["runs"])[:4] == ["rank_only", "rank_null", "feedback", "closed_loop"]
    for name, run in summary["runs"].items():
        assert SUMMARY_RUN_KEYS <= set(run), name
        assert len(run["final_q"]) == 3
        assert set(run["step_time_us"]) == {"median", "p90"}
        assert run["limit_violations"] == 0
    assert set(summary["runs"]["rank_null"]["subtasks"]["sin2_q3"]) >= {"initial", "final"}
    # final_q is in model units (rad): θ3 of rank_null near −π/2
    assert summary["runs"]["rank_null"]["final_q"][2] == pytest.approx(-np.pi / 2, abs=np.radians(5))


def test_run_writes_csvs_consistent_with_the_summary(planar_out: tuple[Path, int]) -> None:
    out, _ = planar_out
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    for name, run in summary["runs"].items():
        header, data = _read_csv(out / f"{name}.csv")
        assert header[:7] == ["t", "q.1", "q.2", "q.3", "dq.1", "dq.2", "dq.3"]
        assert {"e.tip", "p.sin2_q3", "limit_violation", "step_time_us", "damped", "x.3", "y.3"} <= set(header)
        assert data.shape == (501, len(header))
        col = {h: data[:, i] for i, h in enumerate(header)}
        np.testing.assert_allclose(col["t"], np.arange(501) * 0.01, atol=1e-12)
        np.testing.assert_allclose(data[-1, 1:4], run["final_q"], rtol=1e-9)
        assert np.max(col["e.tip"]) == pytest.approx(run["max_task_error"], rel=1e-8)
        # sin²θ3 column is sin² of the q.3 column
        np.testing.assert_allclose(col["p.sin2_q3"], np.sin(col["q.3"]) ** 2, atol=1e-9)
        # q̇ of a row integrates to the next row's q (open-loop Euler q ← q + q̇·dt)
        np.testing.assert_allclose(data[1:, 1:4], data[:-1, 1:4] + 0.01 * data[:-1, 4:7], atol=1e-8)
        assert np.isnan(col["step_time_us"][-1]) and np.all(col["step_time_us"][:-1] > 0)


def test_run_writes_figures(planar_out: tuple[Path, int]) -> None:
    out, _ = planar_out
    for name in FIGURES:
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n", name
        assert len(data) > 20_000, f"{name} is suspiciously small ({len(data)} bytes)"


def test_run_subset_quiet_no_figures(tmp_path: Path, cli: Callable[..., tuple[int, str, str]]) -> None:
    code, out, err = cli("run", PLANAR_TASK, "--out", tmp_path, "--runs", "rank_only", "--quiet", "--no-figures")
    assert code == 0, err
    assert out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rank_only.csv", "summary.json"]
    assert list(json.loads((tmp_path / "summary.json").read_text())["runs"]) == ["rank_only"]


def test_run_prints_a_table(tmp_path: Path, cli: Callable[..., tuple[int, str, str]]) -> None:
    code, out, err = cli("run", PLANAR_TASK, "--out", tmp_path, "--runs", "rank_only,rank_null", "--no-figures")
    assert code == 0, err
    assert "rank_only" in out and "rank_null" in out and "summary.json" in out


def test_unknown_run_is_a_clear_error(tmp_path: Path, cli: Callable[..., tuple[int, str, str]]) -> None:
    code, out, err = cli("run", PLANAR_TASK, "--out", tmp_path, "--runs", "bogus")
    assert code != 0
    assert "no run named 'bogus'" in err and "Traceback" not in err + out


def test_validate_good_file(cli: Callable[..., tuple[int, str, str]]) -> None:
    code, out, err = cli("validate", PLANAR_TASK)
    assert code == 0, err
    assert "ok" in out and "rank_null" in out


@pytest.mark.parametrize("command", ["validate", "run"])
@pytest.mark.parametrize(("mutate", "path", "words"), [m[1:] for m in MALFORMED], ids=[m[0] for m in MALFORMED])
def test_malformed_file_exits_with_one_line(
    planar_task_data: dict[str, Any],
    write_yaml: Callable[..., Path],
    cli: Callable[..., tuple[int, str, str]],
    tmp_path: Path,
    command: str,
    mutate: Any,
    path: str,
    words: list[str],
) -> None:
    data = copy.deepcopy(planar_task_data)
    mutate(data)
    file = write_yaml(data)
    args = [command, file] + (["--out", tmp_path / "out"] if command == "run" else [])
    code, out, err = cli(*args)
    assert code != 0
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"error: {path}: "), lines[0]
    for w in words:
        assert w in lines[0]
    assert "Traceback" not in err + out
    assert not (tmp_path / "out").exists()  # nothing runs or is written before the whole file is valid


def test_bad_yaml_syntax_in_a_real_process(write_yaml: Callable[..., Path]) -> None:
    file = write_yaml(PLANAR_TASK.read_text(encoding="utf-8").replace("dt: 0.01", "dt: [0.01"))
    proc = subprocess.run(
        [sys.executable, "-m", "redundik.cli.main", "validate", str(file)], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode != 0
    assert "Traceback" not in proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and f"{file}:" in lines[0] and "invalid YAML" in lines[0], proc.stderr


@pytest.mark.parametrize("json_mode", [False, True], ids=["text", "json"])
def test_ctrl_c_during_a_run_exits_aborted_and_says_so(
    tmp_path: Path, cli: Callable[..., tuple[int, str, str]], monkeypatch: pytest.MonkeyPatch, json_mode: bool
) -> None:
    """Ctrl-C inside a command: typer turns it into its Exit(130), which the non-standalone call returned and the
    CLI dropped — `redundik run` exited 0 and silent, its outputs half written. Now: exit 1 (aborted) and one line
    (a JSON record with --json)."""
    import redundik.reporting.outputs as outputs

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(outputs, "write_outputs", interrupted)
    extra = ["--json"] if json_mode else []
    code, out, err = cli("run", PLANAR_TASK, "--out", tmp_path / "o", "--quiet", *extra)
    assert code == 1, (code, out, err)
    assert "aborted (Ctrl-C)" in err
    if json_mode:
        record = json.loads(out)
        assert record["ok"] is False and record["exit_code"] == 1 and record["kind"] == "KeyboardInterrupt"

"""Hostile input to ``redundik view``: bad options refused before the viewer starts, a damaged output folder (edited
or truncated CSV files) and an HTML replay into an unwritable place, each a one-line error."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from tests.hostile import TASK, Cli, _one_line_error


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from redundik.cli.main import main

    out = tmp_path_factory.mktemp("view") / "out"
    task = out.parent / "t.yaml"
    task.write_text(TASK.replace("steps: 500", "steps: 5"), encoding="utf-8")
    assert main(["run", str(task), "--out", str(out), "--no-figures", "--quiet", "--runs", "rank_only"]) == 0
    return out


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--speed", "-1"], "--speed"),
        (["--speed", "0"], "--speed"),
        (["--speed", "nan"], "--speed"),
        (["--loops", "0"], "--loops"),
        (["--loops", "-5"], "--loops"),
        (["--t", "nan", "--png", "x.png"], "--t"),
        (["--t", "-1", "--png", "x.png"], "--t"),
        (["--run", "nope", "--html", "x.html"], "--run"),
    ],
)
def test_view_refuses_bad_options_before_starting(cli: Cli, finished_run: Path, args: list[str], named: str) -> None:
    code, _, err = cli("view", finished_run, *args)
    _one_line_error(code, err)
    assert named in err


@pytest.mark.parametrize(
    ("damage", "expected"),
    [
        (lambda out: (out / "summary.json").write_text("{not json"), "not JSON"),
        (lambda out: (out / "summary.json").write_text("[1, 2]"), "expected an object"),
        (lambda out: _edit_csv(out, 2, 1, "abc"), "rank_only.csv:3: column 'q.1'"),
        (lambda out: _edit_csv(out, 2, 2, "nan"), "rank_only.csv:3: column 'q.2': expected a finite number"),
        (lambda out: _edit_csv(out, 1, None, "1,2"), "rank_only.csv:2: expected"),
        (lambda out: _truncate_csv(out), "has no rows"),
    ],
)
def test_view_refuses_a_damaged_output_folder(
    cli: Cli, finished_run: Path, tmp_path: Path, damage: Callable[[Path], object], expected: str
) -> None:
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(finished_run, out)
    damage(out)
    code, _, err = cli("view", out, "--html", tmp_path / "page.html")
    _one_line_error(code, err)
    assert expected in err
    assert not (tmp_path / "page.html").exists()  # no page drawn from NaN or garbage


def _edit_csv(out: Path, row: int, col: int | None, value: str) -> None:
    path = out / "rank_only.csv"
    lines = path.read_text(encoding="utf-8").splitlines()
    if col is None:
        lines[row] = value
    else:
        cells = lines[row].split(",")
        cells[col] = value
        lines[row] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _truncate_csv(out: Path) -> None:
    path = out / "rank_only.csv"
    path.write_text(path.read_text(encoding="utf-8").splitlines()[0] + "\n", encoding="utf-8")


def test_view_html_into_an_unwritable_place_is_one_line(cli: Cli, finished_run: Path, tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code, _, err = cli("view", finished_run, "--html", blocker / "page.html")
    _one_line_error(code, err)
    assert "--html" in err

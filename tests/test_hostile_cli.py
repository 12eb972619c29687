"""Hostile input to the command line: options (an empty ``--out``, the file-system root, an empty run selection),
output paths (a file where a folder is expected, HTML/GIF/PNG outputs through ``safe_path``, ``examples copy`` and
symlinks, a write the file system refuses, figure outputs) and unexpected exceptions: each a one-line error naming
the option and what was expected, nothing written outside the output folder."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from redundik.reporting.paths import OutputPathError, check_output_folder, safe_path
from tests.conftest import CONFIGS, TASKS
from tests.hostile import ROOT, TASK, Cli, _one_line_error, _write


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["run", TASKS / "planar3r_line.yaml", "--out", "", "--no-figures", "-q"], "'--out'"),
        (["sweep", ROOT / "sweeps" / "panda_reach.yaml", "--out", "", "-q"], "'--out'"),
        (["hybrid33", "path", CONFIGS / "hybrid33_rect.yaml", "--out", ""], "'--out'"),
        (["examples", "copy", ""], "'target'"),
        (["schema", "--out", " "], "'--out'"),
    ],
)
def test_an_empty_output_path_is_a_usage_error_not_the_current_folder(
    cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[object], option: str
) -> None:
    """``--out ""`` was ``Path("")`` = ``.``: the run's files landed in the current folder."""
    monkeypatch.chdir(tmp_path)
    code, out, err = cli(*args)
    assert code == 2, err  # a usage error: the value of an option
    assert option in err and "an empty path names no file or folder" in err
    assert out == "" and list(tmp_path.iterdir()) == []  # nothing written here


@pytest.mark.parametrize("folder", ["/", "/tmp/..", "//"])
def test_the_file_system_root_is_never_an_output_folder(folder: str) -> None:
    """``--out /`` wrote summary.json and RUN.csv into ``/`` (as root: it could)."""
    with pytest.raises(OutputPathError, match="refusing to use the file-system root"):
        check_output_folder(folder)
    with pytest.raises(OutputPathError, match="file-system root"):
        safe_path(folder, "summary.json")


def test_run_into_the_root_is_refused_before_running(cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import redundik.config.runner as runner

    def never(*args: object, **kwargs: object) -> object:
        raise AssertionError("the run started although its output folder is refused")

    monkeypatch.setattr(runner, "run_task", never)
    code, _, err = cli("run", _write(tmp_path, TASK), "--out", "/", "--no-figures", "-q")
    _one_line_error(code, err)
    assert "file-system root '/'" in err
    assert not Path("/summary.json").exists()


def test_the_cli_parser_keeps_paths_and_defaults() -> None:
    from redundik.cli._params import path_value

    assert path_value("out/x") == Path("out/x")
    assert path_value(".") == Path(".")
    assert path_value(Path("a")) == Path("a")
    assert os.fspath(path_value("/tmp")) == "/tmp"


_DRAW = ["stewart", "draw", CONFIGS / "stewart33.yaml", "--p", "0", "0", "1.5", "--out"]


_ANIMATE = [
    *["stewart", "animate", CONFIGS / "stewart33.yaml", "--p", "0", "0", "1.5", "--to-p", "0", "0", "1.6"],
    *["--frames", "2", "--out"],
]


@pytest.mark.parametrize(
    ("args", "name", "expected"),
    [
        (_DRAW, "pose", "--out: expected a .png file name (this command writes PNG)"),
        (_DRAW, "pose.txt", "--out: expected a .png file name"),
        (_DRAW, "folder", "--out: expected a .png file name"),
        (_ANIMATE, "move.png", "--out: expected a .gif file name (this command writes GIF)"),
    ],
)
def test_figure_outputs_are_written_where_they_are_named(
    cli: Cli, tmp_path: Path, args: list[object], name: str, expected: str
) -> None:
    """``--out DIR`` or ``--out NAME`` wrote ``NAME.png`` beside the path given (matplotlib appends the suffix),
    ``--out pose.txt`` was an internal error, ``animate --out move.png`` a GIF named .png."""
    (tmp_path / "folder").mkdir()
    code, _, err = cli(*args, tmp_path / name)
    _one_line_error(code, err)
    assert err.startswith(f"error: {expected}"), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder"]
    assert list((tmp_path / "folder").iterdir()) == []


def test_a_folder_named_like_a_png_is_refused(cli: Cli, tmp_path: Path) -> None:
    (tmp_path / "pose.png").mkdir()
    code, _, err = cli(*_DRAW, tmp_path / "pose.png")
    _one_line_error(code, err)
    assert "is a folder; give a .png file name" in err


def test_names_the_figure_font_lacks_do_not_flood_stderr(tmp_path: Path) -> None:
    """A CJK joint name printed matplotlib's "Glyph ... missing from font" warnings (two lines each) on stderr."""
    robot = (CONFIGS / "planar3r.yaml").read_text(encoding="utf-8").replace('name: "3"', 'name: "关节3"')
    robot_path = _write(tmp_path, robot, "r.yaml")
    text = (
        TASK.replace(f"{CONFIGS}/planar3r.yaml", str(robot_path))
        .replace('frame: "3"', 'frame: "关节3"')
        .replace('joint: "3"', 'joint: "关节3"')
        .replace('frames: ["0", "1", "2", "3"]', 'frames: ["0", "1", "2", "关节3"]')
        .replace("steps: 500", "steps: 3")
    )
    task = _write(tmp_path, text)
    # a separate process: pytest records warnings itself, so only a real stderr shows what a user would see
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "redundik",
            "run",
            str(task),
            "--out",
            str(tmp_path / "out"),
            "-q",
            "--runs",
            "rank_null",
        ],
        capture_output=True,
        text=True,
        env={k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"},
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert "Glyph" not in proc.stderr and "Warning" not in proc.stderr, proc.stderr
    assert (tmp_path / "out" / "joints.png").is_file()


def _task(tmp_path: Path, steps: int = 3) -> Path:
    path = tmp_path / "t.yaml"
    path.write_text(TASK.replace("steps: 500", f"steps: {steps}"), encoding="utf-8")
    return path


@pytest.mark.parametrize("runs", ["", ",,", " , "])
def test_an_empty_run_selection_is_refused(cli: Cli, tmp_path: Path, runs: str) -> None:
    code, _, err = cli("run", _task(tmp_path), "--runs", runs, "--out", tmp_path / "out", "--no-figures", "-q")
    _one_line_error(code, err)
    assert "--runs" in err and "rank_only" in err  # names the option and lists the runs to choose from
    assert not (tmp_path / "out").exists()


def test_an_output_folder_that_is_a_file_is_refused_before_running(cli: Cli, tmp_path: Path) -> None:
    blocker = tmp_path / "out"
    blocker.write_text("not a folder")
    for target in (blocker, blocker / "sub"):
        code, _, err = cli("run", _task(tmp_path), "--out", target, "--no-figures", "-q")
        _one_line_error(code, err)
        assert "exists and is not a folder" in err and "''" not in err
    assert blocker.read_text() == "not a folder"


@pytest.mark.parametrize("option", ["--html", "--gif"])
def test_html_and_gif_outputs_go_through_safe_path(cli: Cli, tmp_path: Path, option: str) -> None:
    out, outside = tmp_path / "out", tmp_path / "outside"
    out.mkdir()
    outside.mkdir()
    suffix = option.lstrip("-")
    (out / f"planar3r_line.{suffix}").symlink_to(outside / f"stolen.{suffix}")
    code, _, err = cli("run", _task(tmp_path), "--out", out, "--no-figures", "-q", "--runs", "rank_only", option)
    _one_line_error(code, err)
    assert "outside the output folder" in err
    assert list(outside.iterdir()) == []


def test_an_unexpected_exception_is_one_line_with_its_own_exit_code(
    cli: Cli, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    import redundik.config.anyfile as anyfile

    def broken(path: object) -> str:
        raise ValueError("something a test broke on purpose")

    monkeypatch.setattr(anyfile, "validate_file", broken)
    code, _, err = cli("validate", _task(tmp_path))
    _one_line_error(code, err, expected_code=70)
    assert "internal error" in err and "ValueError: something a test broke on purpose" in err
    monkeypatch.setenv("REDUNDIK_TRACEBACK", "1")
    with pytest.raises(ValueError, match="broke on purpose"):
        cli("validate", _task(tmp_path))


@pytest.mark.parametrize("link", ["tasks/planar3r_line.yaml", "configs"])
def test_examples_copy_never_writes_through_a_symlink(cli: Cli, tmp_path: Path, link: str) -> None:
    target, outside = tmp_path / "ex", tmp_path / "outside"
    (target / "tasks").mkdir(parents=True)
    outside.mkdir()
    (target / link).symlink_to(outside / "x" if link.endswith(".yaml") else outside)
    code, _, err = cli("examples", "copy", target)
    _one_line_error(code, err)
    assert "refusing to copy into" in err and "symlink or resolves outside" in err
    assert list(outside.iterdir()) == []
    assert not (target / "tasks" / "rpr_corner.yaml").exists()  # checked before the first write: nothing copied


def test_examples_copy_says_what_it_kept(cli: Cli, tmp_path: Path) -> None:
    assert cli("examples", "copy", tmp_path / "ex")[0] == 0
    mine = tmp_path / "ex" / "tasks" / "planar3r_line.yaml"
    mine.write_text("# my edits\n")
    code, _, err = cli("examples", "copy", tmp_path / "ex")
    assert code == 0 and "copied 0 files" in err and "kept" in err and "--force" in err
    assert mine.read_text() == "# my edits\n"


def test_a_write_the_file_system_refuses_is_one_line(cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A read-only folder or a full disk (simulated: a root user may write anywhere) is exit 3, not a traceback."""
    task = _task(tmp_path)
    real_open = Path.open

    def refuse(path: Path, mode: str = "r", *args: object, **kwargs: object) -> object:
        if "w" in mode and path.suffix == ".csv":
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, mode, *args, **kwargs)  # type: ignore[call-overload]

    monkeypatch.setattr(Path, "open", refuse)
    code, _, err = cli("run", task, "--out", tmp_path / "out", "--no-figures", "-q", "--runs", "rank_only")
    _one_line_error(code, err)
    assert "Permission denied" in err and "rank_only.csv" in err

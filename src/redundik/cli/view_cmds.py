"""Pictures of a task run from the command line: ``redundik run FILE --html/--gif/--view`` and ``redundik view DIR``.

Heavy imports (Pinocchio, matplotlib, meshcat) happen inside the functions, so ``redundik --help`` stays fast.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from redundik.cli._params import path_value
from redundik.errors import ConfigError

if TYPE_CHECKING:
    import numpy as np

    from redundik.config.loader import TaskPlan
    from redundik.config.runner import RunResult
    from redundik.reporting.plots import FigureOptions, LoggedRun


def figure_inputs(plan: TaskPlan, results: dict[str, RunResult]) -> tuple[dict[str, LoggedRun], FigureOptions]:
    """What the figures take of a task run: each run's log with its stack and labels, and the file's options."""
    from redundik.reporting.plots import FigureOptions, LoggedRun

    runs = {
        name: LoggedRun(
            r.log,
            r.plan.stack,
            label=r.plan.resolver_name,
            watched=[*r.plan.watched, *r.plan.monitors],
            monitors=frozenset(m.name for m in r.plan.monitors),
            torque_monitors=[m.name for m in r.plan.torque_monitors],
            series=r.series,
        )
        for name, r in results.items()
    }
    draw = plan.draw
    options = FigureOptions(plan.name, draw.segments, draw.plane, draw.every, draw.path_frame, plan.potential_types)
    return runs, options


def output_steps(figures: bool, html: bool, gif: bool) -> list[str]:
    """The names of the output steps after the simulation, in the order :func:`write_pictures` runs them."""
    return [n for n, on in (("figures", figures), ("html", html), ("gif", gif)) if on]


def write_pictures(
    plan: TaskPlan,
    results: dict[str, RunResult],
    out_dir: Path,
    steps: list[str],
    done: Callable[[str], None] | None = None,
) -> list[Path]:
    """Write the selected pictures (``figures``, ``html``, ``gif``) of a task run into ``out_dir``.

    Args:
        plan: The task file.
        results: The runs.
        out_dir: Output folder.
        steps: From :func:`output_steps`.
        done: Called with each step's name once written (for a progress bar).
    """
    from redundik.reporting.paths import safe_path

    written: list[Path] = []
    runs, options = figure_inputs(plan, results) if {"figures", "gif"} & set(steps) else ({}, None)
    for step in steps:
        if step == "figures":
            from redundik.reporting.plots import write_figures

            written += write_figures(runs, plan.robot.model, out_dir, options)
        elif step == "html":
            from redundik.viewer.html import write_html

            written.append(write_html(safe_path(out_dir, f"{plan.name}.html"), plan, results))
        elif step == "gif":
            from redundik.reporting.gif import write_gif

            written.append(write_gif(runs, plan.robot.model, safe_path(out_dir, f"{plan.name}.gif"), options))
        if done is not None:
            done(step)
    return written


# ---------------------------------------------------------------------------------------------------- redundik view
def read_run_csv(path: Path, nq: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Times [s] (N,) and configurations (N, nq) from a ``RUN.csv`` (columns ``t`` and ``q.*``/``q[i]``).

    Raises:
        ConfigError: not a run table, a cell that is not a finite number (file:line and column named), no rows,
            times that do not increase, or (``nq`` given) a number of ``q`` columns other than ``nq``.
    """
    import numpy as np

    from redundik.errors import short_repr

    try:
        with path.open(encoding="utf-8", newline="") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ConfigError(f"cannot read run table '{path}': {exc}") from None
    if not rows or "t" not in rows[0]:
        raise ConfigError(f"'{path}' is not a run table (no 't' column)")
    header = rows[0]
    qcols = [i for i, h in enumerate(header) if h.startswith("q.") or h.startswith("q[")]
    if not qcols:
        raise ConfigError(f"'{path}' is not a run table (no 'q.*' columns)")
    if nq is not None and len(qcols) != nq:
        raise ConfigError(f"'{path}' has {len(qcols)} joint columns, the task's robot has nq = {nq}")
    if len(rows) < 2:
        raise ConfigError(f"run table '{path}' has no rows")
    ti = header.index("t")
    wanted = [ti, *qcols]
    data = np.empty((len(rows) - 1, len(wanted)))
    for r, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise ConfigError(f"{path}:{r + 2}: expected {len(header)} cells, got {len(row)}")
        for c, i in enumerate(wanted):
            try:
                value = float(row[i])
            except ValueError:
                value = float("nan")
            if not np.isfinite(value):
                raise ConfigError(
                    f"{path}:{r + 2}: column '{header[i]}': expected a finite number, got {short_repr(row[i])}"
                )
            data[r, c] = value
    if np.any(np.diff(data[:, 0]) < 0):
        raise ConfigError(f"run table '{path}': the times in column 't' must not decrease")
    return data[:, 0], data[:, 1:]


def load_output(
    out_dir: Path, task: Path | None
) -> tuple[TaskPlan, dict[str, tuple[np.ndarray, np.ndarray, dict[str, Any]]]]:
    """The task plan and the logged runs of an output folder of ``redundik run``.

    Raises:
        ConfigError: no ``summary.json`` (or one that is not a summary), no task file recorded and none given, or a
            missing or malformed run table.
    """
    from redundik.config import load_task

    summary_path = out_dir / "summary.json"
    if not summary_path.is_file():
        raise ConfigError(f"'{out_dir}' has no summary.json: give the output folder of `redundik run`")
    try:
        summary: Any = json.loads(summary_path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ConfigError(f"'{summary_path}' is not a summary of `redundik run` (not JSON: {exc})") from None
    if not isinstance(summary, dict) or not isinstance(summary.get("runs", {}), dict):
        raise ConfigError(f"'{summary_path}' is not a summary of `redundik run` (expected an object with 'runs')")
    if task is None:
        recorded = summary.get("task_file")
        if not recorded or not isinstance(recorded, str):
            raise ConfigError(f"'{summary_path}' does not name its task file: pass --task FILE")
        task = Path(recorded)
    plan = load_task(task)
    runs = {}
    for name, entry in summary.get("runs", {}).items():
        if name not in plan.runs:
            continue
        csv_path = out_dir / f"{name}.csv"
        if not csv_path.is_file():
            raise ConfigError(f"run table '{csv_path}' is missing")
        t, q = read_run_csv(csv_path, plan.robot.model.nq)
        entry = entry if isinstance(entry, dict) else {}
        runs[name] = (t, q, {"resolver": entry.get("resolver", ""), "max task error": entry.get("max_task_error")})
    if not runs:
        raise ConfigError(f"no run of '{task}' found in '{out_dir}'")
    return plan, runs


def _check_view_options(at: float, speed: float, loops: int) -> None:
    """Refuse a non-finite or negative time, a speed that is not a finite positive factor, fewer than one loop."""
    import math

    if not (math.isfinite(at) and at >= 0):
        raise ConfigError(f"--t: expected a finite time ≥ 0 [s], got {at}")
    if not (math.isfinite(speed) and 1e-3 <= speed <= 1e3):
        raise ConfigError(f"--speed: expected a playback factor in [0.001, 1000], got {speed}")
    if not 1 <= loops <= 1000:
        raise ConfigError(f"--loops: expected 1 to 1000 loops, got {loops}")


def view(
    out_dir: Annotated[Path, typer.Argument(help="Output folder of `redundik run`.", show_default=False)],
    task: Annotated[Path | None, typer.Option("--task", help="Task file [default: the one in summary.json].")] = None,
    html: Annotated[
        Path | None, typer.Option("--html", parser=path_value, help="Write an offline HTML replay here instead.")
    ] = None,
    png: Annotated[
        Path | None, typer.Option("--png", parser=path_value, help="Screenshot the HTML replay (headless Chromium).")
    ] = None,
    at: Annotated[float, typer.Option("--t", help="Time shown in the screenshot [s].")] = 0.0,
    run: Annotated[str | None, typer.Option("--run", help="Run to replay in meshcat [default: the first].")] = None,
    speed: Annotated[float, typer.Option("--speed", help="Playback speed factor.")] = 1.0,
    loops: Annotated[int, typer.Option("--loops", help="Times to play the run in meshcat.")] = 1,
) -> None:
    """Replay a finished run: in meshcat (live viewer, extra `viewer`) or as an offline HTML file."""
    from rich.console import Console

    _check_view_options(at, speed, loops)
    if html is None and png is None:  # the live replay: meshcat is checked before the folder is read
        from redundik._extras import require

        require("meshcat", "the live replay (redundik view without --html/--png)")
    plan, runs = load_output(out_dir, task)
    if run is not None and run not in runs:
        raise ConfigError(f"--run: no run named '{run}' in '{out_dir}'; runs: {', '.join(runs)}")
    console = Console()
    if html is not None or png is not None:
        import tempfile

        from redundik.viewer.html import build_task_replay, render_page

        with tempfile.TemporaryDirectory(prefix="redundik-view-") as tmp:
            page = html if html is not None else Path(tmp) / f"{plan.name}.html"
            text = render_page(build_task_replay(plan, runs))
            try:
                page.parent.mkdir(parents=True, exist_ok=True)
                page.write_text(text, encoding="utf-8")
            except OSError as exc:
                raise ConfigError(f"--html: cannot write '{page}': {exc.strerror or exc}") from None
            console.print(f"wrote {page}" if html is not None else f"replay of {', '.join(runs)}")
            if png is not None:
                from redundik.viewer.snapshot import screenshot

                query = f"?t={at}" + (f"&run={run}" if run else "")
                console.print(f"wrote {screenshot(page.resolve().as_uri() + query, png)}")
        return
    from redundik.viewer.live import replay_meshcat

    name = run or next(iter(runs))
    if name not in runs:
        raise ConfigError(f"no run named '{name}' in '{out_dir}'; runs: {', '.join(runs)}")
    t, q, _ = runs[name]
    replay_meshcat(plan, name, t, q, speed=speed, loops=loops, console=console)


def register(app: typer.Typer) -> None:
    """Add ``view`` to the ``redundik`` command."""
    app.command("view")(view)

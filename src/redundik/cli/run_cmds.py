"""``redundik run FILE`` and ``redundik validate FILE``: YAML task runs from the command line.

Heavy imports (Pinocchio, matplotlib) happen inside the commands, so ``redundik --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def validate(
    file: Annotated[
        Path, typer.Argument(help="Task file, robot config or mechanism config (YAML).", show_default=False)
    ],
) -> None:
    """Check a task file (robot, tasks, potentials, every run), a robot config or a mechanism config."""
    from rich.console import Console
    from rich.markup import escape

    from redundik.config.anyfile import validate_file

    what = validate_file(file)
    Console(soft_wrap=True).print(f"[green]ok[/green] {escape(str(file))}: {escape(what)}")


def run(
    file: Annotated[Path, typer.Argument(help="Task file (YAML).", show_default=False)],
    out: Annotated[Path | None, typer.Option("--out", "-o", help="Output folder [default: out/<task name>].")] = None,
    runs: Annotated[str | None, typer.Option("--runs", help="Comma-separated run names (default: all).")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No table, no progress bar.")] = False,
    figures: Annotated[bool, typer.Option("--figures/--no-figures", help="Write PNG figures.")] = True,
) -> None:
    """Simulate every run of a task file; write summary.json, RUN.csv per run and PNG figures."""
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from redundik.config import load_task
    from redundik.config.runner import run_task, select_runs
    from redundik.reporting.outputs import write_outputs
    from redundik.reporting.terminal import print_summary

    plan = load_task(file)
    names = select_runs(plan, None if runs is None else runs.split(","))
    out_dir = out if out is not None else Path("out") / plan.name
    console = Console(stderr=True)
    total = plan.steps * len(names)
    if quiet or total < 2000:
        results = run_task(plan, names)
    else:
        with Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TextColumn("{task.completed}/{task.total} steps"),
            TimeRemainingColumn(),
            console=console,
            transient=True,
        ) as bar:
            task_id = bar.add_task(plan.name, total=total)
            done = dict.fromkeys(names, 0)

            def progress(run_name: str, k: int) -> None:
                done[run_name] = k
                if k % 20 == 0 or k == plan.steps:
                    bar.update(task_id, completed=sum(done.values()), description=f"{plan.name}: {run_name}")

            results = run_task(plan, names, progress)
    summary = write_outputs(plan, results, out_dir)
    written = ["summary.json", *(f"{n}.csv" for n in results)]
    if figures:
        from redundik.reporting.plots import write_figures

        written += [p.name for p in write_figures(plan, results, out_dir)]
    if not quiet:
        print_summary(summary, Console())
        Console().print(f"wrote {out_dir}/: {', '.join(written)}")


def register(app: typer.Typer) -> None:
    """Add ``run`` and ``validate`` to the ``redundik`` command."""
    app.command("run")(run)
    app.command("validate")(validate)

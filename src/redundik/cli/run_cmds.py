"""``redundik run FILE`` and ``redundik validate FILE``: YAML task runs from the command line.

Heavy imports (Pinocchio, matplotlib) happen inside the commands, so ``redundik --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from redundik.cli._params import path_value


def validate(
    file: Annotated[
        Path,
        typer.Argument(
            help="Task file, robot config or mechanism config (YAML), or the name of a shipped task.",
            show_default=False,
        ),
    ],
    json_out: Annotated[
        bool, typer.Option("--json", help="One JSON document on stdout: {ok, file, kind, description}.")
    ] = False,
) -> None:
    """Check a task file (robot, tasks, potentials, every run), a robot config, a mechanism config or a sweep file."""
    from redundik.cli._console import JSON_MODE, console, emit_json
    from redundik.cli.example_cmds import resolve_file
    from redundik.config.anyfile import validate_file

    JSON_MODE["on"] = json_out
    path = resolve_file(file)
    what = validate_file(path)
    if json_out:
        emit_json({"ok": True, "file": str(path), "kind": what.split(" ", 1)[0], "description": what})
        return
    from rich.markup import escape

    console().print(f"[green]ok[/green] {escape(str(file))}: {escape(what)}", highlight=False)


def run(
    file: Annotated[
        Path, typer.Argument(help="Task file (YAML), or the name of a shipped task (`redundik examples list`).")
    ],
    out: Annotated[
        Path | None, typer.Option("--out", "-o", parser=path_value, help="Output folder [default: out/<task name>].")
    ] = None,
    runs: Annotated[str | None, typer.Option("--runs", help="Comma-separated run names [default: all].")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No table, no progress bar.")] = False,
    figures: Annotated[bool, typer.Option("--figures/--no-figures", help="Write PNG figures.")] = True,
    html: Annotated[bool, typer.Option("--html", help="Write an offline 3-D replay, TASK.html.")] = False,
    gif: Annotated[bool, typer.Option("--gif", help="Write an animation of the runs, TASK.gif.")] = False,
    view: Annotated[bool, typer.Option("--view", help="Replay the first run in meshcat (extra `viewer`).")] = False,
    json_out: Annotated[
        bool,
        typer.Option("--json", help="One JSON document on stdout (the summary, the files written); tables on stderr."),
    ] = False,
) -> None:
    """Simulate every run of a task file; write summary.json, RUN.csv per run, PNG figures (and HTML, GIF)."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from redundik.cli._console import JSON_MODE, console, emit_json
    from redundik.cli.example_cmds import resolve_file
    from redundik.cli.view_cmds import output_steps, write_pictures
    from redundik.config import load_task
    from redundik.config.runner import run_task, select_runs
    from redundik.reporting.outputs import write_outputs
    from redundik.reporting.paths import check_output_folder
    from redundik.reporting.terminal import print_summary

    JSON_MODE["on"] = json_out
    if view:  # refused before any work: the run would otherwise finish and only then find meshcat missing
        from redundik._extras import require

        require("meshcat", "--view (the live meshcat replay)")
    file = resolve_file(file)
    plan = load_task(file)
    names = select_runs(plan, None if runs is None else runs.split(","))
    out_dir = check_output_folder(out if out is not None else Path("out") / plan.name)
    human = console(stderr=json_out)  # tables and messages: stdout, or stderr when stdout carries the JSON
    bar_console = console(stderr=True)
    pictures = output_steps(figures, html, gif)
    unit = max(plan.steps // 4, 1)  # progress units of one output step (figures, html, gif)
    total = plan.steps * len(names) + unit * len(pictures)
    if not quiet:  # the first run after an install compiles the kernels: say so, rather than a bar sitting at 0
        from redundik._kernel_cache import cache_dir
        from redundik.warmup import RESOLVERS, warm_up

        used = sorted({plan.runs[n].resolver_name for n in names} & set(RESOLVERS))
        with bar_console.status(
            f"loading compiled kernels from {cache_dir()} (the first run after an install compiles them, up to a "
            "minute; `redundik compile` does it ahead)"
        ):
            warm_up(used)
    if quiet or total < 2000:
        results = run_task(plan, names)
        summary = write_outputs(plan, results, out_dir)
        pictures_written = write_pictures(plan, results, out_dir, pictures)
    else:
        with Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TextColumn("{task.completed}/{task.total} steps"),
            TimeRemainingColumn(),
            console=bar_console,
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
            finished: list[str] = []

            def picture_done(step: str) -> None:
                finished.append(step)
                bar.update(task_id, completed=plan.steps * len(names) + unit * len(finished))

            bar.update(task_id, description=f"{plan.name}: {', '.join(pictures) or 'outputs'}")
            pictures_written = write_pictures(plan, results, out_dir, pictures, picture_done)
    written = ["summary.json", *(f"{n}.csv" for n in results), *(p.name for p in pictures_written)]
    if not quiet:
        print_summary(summary, human)
        human.print(f"wrote {out_dir}/: {', '.join(written)}", highlight=False, markup=False)
    if json_out:
        emit_json({"ok": True, "task": plan.name, "out": str(out_dir), "files": written, "summary": summary})
    if view:
        from redundik.viewer.live import replay_meshcat

        first = next(iter(results.values()))
        replay_meshcat(plan, first.name, first.log.t, first.log.q, console=human)


def schema(
    robot: Annotated[bool, typer.Option("--robot", help="Schema of a robot config instead of a task file.")] = False,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", parser=path_value, help="Write it to this file [default: stdout].")
    ] = None,
) -> None:
    """Print the JSON Schema of task files (or robot configs), for editors: every type, key, default and unit."""
    import json

    from redundik.config.jsonschema import robot_schema, task_schema

    text = json.dumps(robot_schema() if robot else task_schema(), indent=2, ensure_ascii=False) + "\n"
    if out is None:
        typer.echo(text, nl=False)
        return
    from redundik.errors import ConfigError

    try:
        out.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot write '{out}': {exc.strerror or exc}") from None


def compile_kernels() -> None:
    """Compile the resolvers' and ``solve_ik``'s kernels into numba's on-disk cache now (a first run on an empty cache
    spends up to a minute there; a container image can bake this in), then print how long each took."""
    import typer

    from redundik._kernel_cache import cache_dir
    from redundik.warmup import warm_up

    typer.echo(f"compiling redundik's kernels (or loading them from the cache {cache_dir()}) ...", err=True)
    for name, seconds in warm_up().items():
        typer.echo(f"{name}: {seconds:.1f} s")


def register(app: typer.Typer) -> None:
    """Add ``run`` and ``validate`` to the ``redundik`` command."""
    from redundik.cli.main import EPILOG

    app.command("run", epilog=EPILOG)(run)
    app.command("compile", epilog=EPILOG)(compile_kernels)
    app.command("validate", epilog=EPILOG)(validate)
    app.command("schema")(schema)

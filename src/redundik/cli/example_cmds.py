"""``redundik examples list`` / ``redundik examples copy DIR``: the task, config and sweep files shipped with redundik.

``redundik run NAME`` (and ``validate NAME``) find a shipped task by its name, ``redundik sweep NAME`` a shipped sweep
file, so both run from any folder once the package is installed: ``redundik run planar3r_line``,
``redundik sweep panda_reach``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from redundik.cli._params import path_value
from redundik.errors import ConfigError


def resolve_file(file: Path, folder: str = "tasks") -> Path:
    """``file`` if it exists, else the shipped ``folder/NAME.yaml`` when ``file`` is a bare name.

    Raises:
        ConfigError: neither exists (the message lists the shipped names).
    """
    if file.exists():
        return file
    from redundik.shipped import examples, find_example

    found = find_example(str(file), folder)
    if found is not None:
        return found
    if file.suffix or len(file.parts) > 1:
        return file  # a path: let the reader say it does not exist
    import difflib

    shipped = [e.name for e in examples(folder)]
    close = difflib.get_close_matches(str(file), shipped, n=3)
    hint = f"did you mean {' or '.join(repr(c) for c in close)}? " if close else ""
    raise ConfigError(f"'{file}' is neither a file nor a shipped {folder[:-1]}; {hint}shipped: {', '.join(shipped)}")


def list_examples(
    json_out: Annotated[bool, typer.Option("--json", help="One JSON document on stdout.")] = False,
) -> None:
    """List the shipped task files (`redundik run NAME`), robot configs and sweep files (`redundik sweep NAME`)."""
    from redundik.cli._console import console, emit_json
    from redundik.shipped import data_dir, examples

    items = examples()
    if json_out:
        emit_json(
            {
                "data_dir": str(data_dir()),
                "examples": [
                    {"name": e.name, "kind": e.folder[:-1], "path": str(e.path), "description": e.description}
                    for e in items
                ],
            }
        )
        return
    from rich.markup import escape
    from rich.table import Table

    out = console()
    for folder, title in (
        ("tasks", "task files (redundik run NAME)"),
        ("configs", "robot and mechanism configs"),
        ("sweeps", "sweep files (redundik sweep NAME)"),
    ):
        table = Table(title=title, title_justify="left", padding=(0, 1))
        table.add_column("name", no_wrap=True)
        table.add_column("description")
        for e in items:
            if e.folder == folder:
                table.add_row(escape(e.name), escape(e.description))
        out.print(table)
    out.print(f"shipped in {escape(str(data_dir()))}; copy them with `redundik examples copy DIR`", highlight=False)


def copy(
    target: Annotated[
        Path,
        typer.Argument(help="Folder to copy tasks/, configs/ and sweeps/ into.", show_default=False, parser=path_value),
    ],
    force: Annotated[bool, typer.Option("--force", help="Overwrite files that exist.")] = False,
) -> None:
    """Copy the shipped tasks/, configs/ and sweeps/ into a folder (same layout: their robot paths still resolve)."""
    from redundik.cli._console import console
    from redundik.shipped import copy_examples, shipped_files

    written = copy_examples(target, overwrite=force)
    kept = len(shipped_files()) - len(written)
    note = f"; kept {kept} that were already there (--force overwrites them)" if kept else ""
    console(stderr=True).print(
        f"copied {len(written)} files into {target}/ (tasks/, configs/, sweeps/){note}; run one with "
        f"`redundik run {target}/tasks/planar3r_line.yaml`",
        highlight=False,
        markup=False,
    )


def register(app: typer.Typer) -> None:
    """Add the ``examples`` group."""
    group = typer.Typer(
        help="The task files, robot configs and sweep files shipped with redundik.",
        no_args_is_help=True,
        rich_markup_mode=None,
    )
    group.command("list")(list_examples)
    group.command("copy")(copy)
    app.add_typer(group, name="examples")

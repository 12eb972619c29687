"""``redundik examples list`` / ``redundik examples copy DIR``: the task files and robot configs shipped with redundik.

``redundik run NAME`` (and ``validate NAME``) find a shipped task by its name, so the main job runs from any
folder once the package is installed: ``redundik run planar3r_line``.
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
    names = ", ".join(e.name for e in examples(folder))
    raise ConfigError(f"'{file}' is neither a file nor a shipped {folder[:-1]}; shipped: {names}")


def list_examples(
    json_out: Annotated[bool, typer.Option("--json", help="One JSON document on stdout.")] = False,
) -> None:
    """List the shipped task files (run one with `redundik run NAME`) and robot configs."""
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
    for folder, title in (("tasks", "task files (redundik run NAME)"), ("configs", "robot and mechanism configs")):
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
        Path, typer.Argument(help="Folder to copy tasks/ and configs/ into.", show_default=False, parser=path_value)
    ],
    force: Annotated[bool, typer.Option("--force", help="Overwrite files that exist.")] = False,
) -> None:
    """Copy the shipped tasks/ and configs/ into a folder (same layout: the tasks' robot paths still resolve)."""
    from redundik.cli._console import console
    from redundik.shipped import copy_examples, examples

    written = copy_examples(target, overwrite=force)
    kept = len(examples()) - len(written)
    note = f"; kept {kept} that were already there (--force overwrites them)" if kept else ""
    console(stderr=True).print(
        f"copied {len(written)} files into {target}/ (tasks/, configs/){note}; run one with "
        f"`redundik run {target}/tasks/planar3r_line.yaml`",
        highlight=False,
        markup=False,
    )


def register(app: typer.Typer) -> None:
    """Add the ``examples`` group."""
    group = typer.Typer(
        help="The task files and robot configs shipped with redundik.", no_args_is_help=True, rich_markup_mode=None
    )
    group.command("list")(list_examples)
    group.command("copy")(copy)
    app.add_typer(group, name="examples")

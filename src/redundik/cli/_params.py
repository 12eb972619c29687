"""Parsers of command-line values shared by the commands (typer ``parser=`` callbacks)."""

from __future__ import annotations

from pathlib import Path

import typer


def path_value(value: str | Path) -> Path:
    """A path given on the command line; an empty string is refused (``Path("")`` would silently be ``.``).

    Raises:
        typer.BadParameter: ``value`` is empty or blank (a usage error, exit code 2, naming the option).
    """
    if isinstance(value, Path):  # a default, or a value typer already converted
        return value
    if not value.strip():
        raise typer.BadParameter(
            "an empty path names no file or folder: give one (e.g. out/NAME, or '.' for the current folder)"
        )
    return Path(value)

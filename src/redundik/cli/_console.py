"""Consoles of the ``redundik`` command: human output, JSON mode and the width used when piped."""

from __future__ import annotations

import json
import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rich.console import Console

#: Width of rich output when it does not go to a terminal [columns]: wide enough that tables are never cut.
PIPE_WIDTH = 1000

#: Set by a command given ``--json``: errors are then also reported as one JSON document on stdout.
JSON_MODE = {"on": False}


def console(stderr: bool = False) -> Console:
    """A rich console on stdout (or stderr): the terminal's width, or :data:`PIPE_WIDTH` when piped."""
    from rich.console import Console

    stream = sys.stderr if stderr else sys.stdout
    try:
        tty = stream.isatty()
    except (AttributeError, ValueError):
        tty = False
    if tty:
        return Console(stderr=stderr)
    return Console(stderr=stderr, width=PIPE_WIDTH, soft_wrap=True)


def emit_json(document: Any) -> None:
    """Write one JSON document (and a newline) on stdout: the only thing ``--json`` puts there."""
    sys.stdout.write(json.dumps(document, indent=2, allow_nan=False, default=str) + "\n")
    sys.stdout.flush()

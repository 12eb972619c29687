"""``redundik bench``: explains where the resolver benchmark went (see ``docs/benchmark.md``).

The benchmark's harness is not part of the installed package (issue 10: it lives in the checkout's
``benchmarks/`` with the peers it drives); the command stays so that a user who types it learns how to run it. It
exits with the CLI's "missing" code (5), as for an optional part that is not installed.
"""

from __future__ import annotations

from typing import Annotated

import typer

from redundik.errors import MissingDependencyError

#: What ``redundik bench`` reports (one line, exit code 5).
MESSAGE = (
    "the resolver benchmark is not part of the installed package: it runs from a checkout of redundik, "
    "'pip install -e \".[test,peers]\"' then 'python benchmarks/compare_resolvers.py --quick' "
    "(PlaCo in its own venv; see docs/benchmark.md)"
)


def bench(
    args: Annotated[list[str] | None, typer.Argument(help="Ignored: the benchmark runs from a checkout.")] = None,
) -> None:
    """Moved: run `python benchmarks/compare_resolvers.py` from a checkout (exit code 5; docs/benchmark.md)."""
    raise MissingDependencyError(MESSAGE)


def register(app: typer.Typer) -> None:
    """Add the ``bench`` command to the CLI (it accepts and ignores any options, and explains)."""
    app.command("bench", context_settings={"allow_extra_args": True, "ignore_unknown_options": True})(bench)

"""Entry point of the ``redundik`` command.

Each command group lives in its own module and registers itself on :data:`app` through a ``register``
function, so this file only lists them. Errors derived from :class:`~redundik.errors.RedundikError` are printed
as one line on stderr with exit code 2, never as a traceback.
"""

from __future__ import annotations

import sys

import typer

from redundik.errors import RedundikError

app = typer.Typer(
    name="redundik",
    help="Differential inverse kinematics of redundant robots.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _register_all() -> None:
    # main() can be called many times in one process (tests): register the commands once, or typer keeps
    # appending duplicates and every call rebuilds all of them (calls grew slower, O(calls²) overall).
    if app.registered_commands:
        return
    from redundik.cli import bench_cmds, parallel_cmds, run_cmds, view_cmds

    run_cmds.register(app)
    parallel_cmds.register(app)
    bench_cmds.register(app)
    view_cmds.register(app)


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the process exit code."""
    _register_all()
    try:
        app(args=argv, standalone_mode=False)
    except RedundikError as exc:
        text = " ".join(str(exc).split())  # always one line, and bounded
        typer.secho(f"error: {text if len(text) <= 1000 else text[:997] + '...'}", err=True, fg=typer.colors.RED)
        return 2
    except typer.Exit as exc:
        return int(exc.exit_code or 0)
    except typer.Abort:
        typer.secho("aborted", err=True)
        return 1
    except Exception as exc:
        # Usage errors (missing option, bad value): typer raises click's ClickException, from the click package or
        # from the copy typer vendors (typer ≥ 0.2x), so recognise it by its interface rather than by import.
        show, code = getattr(exc, "show", None), getattr(exc, "exit_code", None)
        if callable(show) and isinstance(code, int):
            show()
            return code
        raise
    return 0


if __name__ == "__main__":
    sys.exit(main())
